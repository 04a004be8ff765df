/* kogei chart detect: find a chart of a layout in a photograph and write its patch
 * values (calib/chart_detect.c does the work). */
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "kg_calib.h"

static const char usage_detect[] =
	"kogei chart detect --layout L IMAGE -o P.cgats [--overlay O.png] [--decimate N]\n"
	"                   [--threads N] [--sample-fraction F] [--statistic median|trimmed-mean]\n"
	"                   [--family NAME] [--min-tags N] [--clip-level V] [--tagless]\n"
	"                   [--light-field on|off] [--max-light-variation F] [--quiet]\n"
	"                   [--encoding srgb|linear|gamma:G]";

static const char help_detect[] =
	"\n"
	"Finds the chart of layout L in IMAGE by its AprilTag frame, fits the homography\n"
	"from the layout's millimetres to the image's pixels over every tag corner found\n"
	"(a consensus over pairs of tags rejects tags of other charts and misreads, then\n"
	"Levenberg-Marquardt on the reprojection error), and samples each patch over its\n"
	"inner region with robust statistics. IMAGE is a TIFF or PNG: 8/16-bit or float,\n"
	"grey (patch values come out grey), RGB, or a raw frame with a CFA pattern\n"
	"(demosaiced bilinearly), a camera raw file, or a JPEG (builds with libjpeg).\n"
	"Values are linear on the 0..1 scale of the image.\n"
	"A JPEG is gamma-encoded and white-balanced by the camera: without --encoding it\n"
	"is read as sRGB for detection and the overlay, and its patch file says\n"
	"IMAGE_ENCODING \"jpeg-unstated\", which kogei calib refuses. --encoding states how\n"
	"it was encoded (srgb, linear, or gamma:G meaning linear = code^G) and makes the\n"
	"patches usable for calibration (IMAGE_ENCODING jpeg-srgb, ...).\n"
	"\n"
	"  --layout L           chart layout (kogei-chart/1 JSON, an ArgyllCMS .cht, or a\n"
	"                       bundled layout's name: colorchecker24-frame,\n"
	"                       colorchecker-passport-frame, colorchecker-sg-frame,\n"
	"                       cie-tcs-frame)\n"
	"  -o P.cgats           patch file: SAMPLE_ID RGB_R RGB_G RGB_B RGB_R_SD RGB_G_SD\n"
	"                       RGB_B_SD CLIPPED_FRACTION NONUNIFORMITY PIXELS FLAGS\n"
	"                       ('-' for standard output); SD is 1.4826 x MAD of the\n"
	"                       pixels; FLAGS: 1 clipped, 2 glare, 4 too few pixels,\n"
	"                       8 partly out of frame, 16 non-uniform\n"
	"  --overlay O.png      what an operator checks: tags (green used, orange ignored),\n"
	"                       the chart outline, each sampled region with its id, flagged\n"
	"                       patches in red with the reason; written also when the chart\n"
	"                       is not found: the region searched (dashed yellow), the tags\n"
	"                       and candidates seen (magenta: the tagless detector's box and\n"
	"                       A01 of each of its turns) with why each failed, the reason\n"
	"                       at the top (the exit status is still 1)\n"
	"  --decimate N         tag search on an image N times smaller (corners are refined\n"
	"                       at full resolution); default 2 below 4 Mpix, else 4\n"
	"  --threads N          threads for the grey picture, mcc and the patch sampling,\n"
	"                       and for tag detection with libapriltag 3.4.3 or newer (older\n"
	"                       releases can crash with threads); default 2, the results do\n"
	"                       not depend on it\n"
	"  --sample-fraction F  inner fraction of each patch side to sample (default: the\n"
	"                       layout's)\n"
	"  --statistic S        median (default; interpolated between integer codes) or\n"
	"                       trimmed-mean (10 % cut at each end)\n"
	"  --family NAME        tag family (default: the layout's)\n"
	"  --min-tags N         fewest tags that may place the chart; without it 2, and a\n"
	"                       ColorChecker 24 layout with no tag in view falls back to\n"
	"                       the tagless detector; N given: N tags, no fallback\n"
	"  --clip-level V       a channel at or above V is clipped (default: full scale, or\n"
	"                       per colour where the image's values pile up below it:\n"
	"                       saturation found from the data)\n"
	"  --tagless            find an unframed ColorChecker with OpenCV mcc; its turn is\n"
	"                       the one whose patch colours fit the layout's best through\n"
	"                       one 3 x 3 matrix (any camera and white balance; each patch's\n"
	"                       level free, so uneven light and exposure do not matter); a\n"
	"                       box with no turn fitting, or two fitting about as well, is\n"
	"                       refused, and mcc's next box (of up to 3) is tried\n"
	"  --light-field on|off on (default): estimate the light over the chart from each\n"
	"                       patch's own gradient (ln L a polynomial of degree <= 4),\n"
	"                       divide the patch values by it and flag non-uniform only\n"
	"                       what it does not explain; keywords LIGHT_FIELD_*; off: the\n"
	"                       values as sampled\n"
	"  --max-light-variation F  refuse a chart whose light field varies by more than F\n"
	"                       (peak to peak over the patches / mean; default 1)\n"
	"  --quiet              no summary on standard error (warnings still shown)\n"
	"\n"
	"IMAGE inside a kogei session (SESSION/captures/NAME/rgb.tif, mean.tif) also gives\n"
	"the patch file the camera that took it: keywords CAMERA_BACKEND, CAMERA_MODEL,\n"
	"CAMERA_SERIAL, CAMERA_PIXFMT, CAMERA_WHITE_LEVEL, CAMERA_DEMOSAIC and CAPTURE,\n"
	"which kogei calib camera records in the calibration.\n"
	"\n"
	"Warnings go to standard error. Exit status 1 when the chart is not found (the\n"
	"message says what was seen), 2 on bad usage.";

int kg_cmd_chart_detect(int argc, char **argv)
{
	if (kg_cli_wants_help(argc, argv)) {
		printf("usage: %s\n%s\n", usage_detect, help_detect);
		return KG_EXIT_OK;
	}
	static const struct option longopts[] = {
		{"layout", required_argument, NULL, 'l'},
		{"output", required_argument, NULL, 'o'},
		{"overlay", required_argument, NULL, 'O'},
		{"decimate", required_argument, NULL, 'd'},
		{"threads", required_argument, NULL, 't'},
		{"sample-fraction", required_argument, NULL, 'f'},
		{"statistic", required_argument, NULL, 's'},
		{"family", required_argument, NULL, 'F'},
		{"min-tags", required_argument, NULL, 'm'},
		{"clip-level", required_argument, NULL, 'c'},
		{"tagless", no_argument, NULL, 'T'},
		{"quiet", no_argument, NULL, 'q'},
		{"light-field", required_argument, NULL, 'L'},
		{"max-light-variation", required_argument, NULL, 'V'},
		{"encoding", required_argument, NULL, 'E'},
		{NULL, 0, NULL, 0},
	};
	const char *layout_path = NULL, *out_path = NULL, *overlay = NULL;
	int quiet = 0;
	kg_image_encoding enc = {KG_ENCODING_UNSTATED, 0};
	kg_chart_detect_options opt;
	kg_chart_detect_options_default(&opt);
	kg_err err = {{0}};
	optind = 1;
	int ch;
	while ((ch = getopt_long(argc, argv, "o:", longopts, NULL)) != -1) {
		char *end;
		switch (ch) {
		case 'l':
			layout_path = optarg;
			break;
		case 'o':
			out_path = optarg;
			break;
		case 'O':
			overlay = optarg;
			break;
		case 'd':
			if (kg_cli_int(optarg, 1, 64, &opt.decimate))
				return kg_cli_usage_error(usage_detect, "--decimate %s: expected 1..64", optarg);
			break;
		case 't':
			if (kg_cli_int(optarg, 1, 256, &opt.threads))
				return kg_cli_usage_error(usage_detect, "--threads %s: expected 1..256", optarg);
			break;
		case 'm':
			if (kg_cli_int(optarg, 1, 1000, &opt.min_tags))
				return kg_cli_usage_error(usage_detect, "--min-tags %s: expected 1..1000",
				                          optarg);
			break;
		case 'f':
			opt.sample_fraction = strtod(optarg, &end);
			if (*end || !(opt.sample_fraction > 0 && opt.sample_fraction <= 1))
				return kg_cli_usage_error(usage_detect,
				                          "--sample-fraction %s: expected a number in (0, 1]",
				                          optarg);
			break;
		case 'c':
			opt.clip_level = strtod(optarg, &end);
			if (*end || !(opt.clip_level > 0))
				return kg_cli_usage_error(usage_detect, "--clip-level %s: expected a number > 0",
				                          optarg);
			break;
		case 's':
			if (kg_chart_statistic_parse(optarg, &opt.statistic, &err))
				return kg_cli_usage_error(usage_detect, "--statistic: %s", err.msg);
			break;
		case 'F':
			opt.family = optarg;
			break;
		case 'T':
			opt.tagless = 1;
			break;
		case 'E':
			if (kg_image_encoding_parse(optarg, &enc, &err))
				return kg_cli_usage_error(usage_detect, "%s", err.msg);
			break;
		case 'q':
			quiet = 1;
			break;
		case 'L':
			if (strcmp(optarg, "on") && strcmp(optarg, "off"))
				return kg_cli_usage_error(usage_detect, "--light-field %s: expected on or off",
				                          optarg);
			opt.light_field = strcmp(optarg, "on") == 0;
			break;
		case 'V':
			opt.max_light_variation = strtod(optarg, &end);
			if (*end || !(opt.max_light_variation > 0))
				return kg_cli_usage_error(usage_detect,
				                          "--max-light-variation %s: expected a number > 0",
				                          optarg);
			break;
		default:
			return kg_cli_usage_error(usage_detect, "unknown option");
		}
	}
	if (!layout_path || !out_path)
		return kg_cli_usage_error(usage_detect, "--layout and -o are required");
	if (optind != argc - 1)
		return kg_cli_usage_error(usage_detect, "expected one IMAGE");
	const char *image_path = argv[optind];

	kg_chart_layout *layout = NULL;
	kg_image *img = NULL;
	kg_chart_result *res = NULL;
	kg_patchset *ps = NULL;
	int code = 0;
	char *layout_file = NULL;
	if ((code = kg_chart_layout_resolve(layout_path, &layout_file, &err)) ||
	    (code = kg_chart_layout_load(layout_file, &layout, &err)))
		goto fail;
	/* an uncompressed 16-bit TIFF is mapped, not decoded into floats, unless the
	 * overlay (which draws from floats) is asked for */
	code = overlay ? KG_ENOTSUP : kg_image_map(image_path, &img, &err);
	if (code == KG_ENOTSUP)
		code = kg_image_read_as(image_path, &enc, &img, &err);
	if (code)
		goto fail;
	char encoding[32];
	kg_image_encoding_name(img, encoding, sizeof(encoding));
	if (img->jpeg && enc.curve == KG_ENCODING_UNSTATED && !quiet)
		fprintf(stderr, "kogei: note: %s: a JPEG, read as sRGB for detection; its patch "
		        "values are not for calibration unless --encoding states how it was "
		        "encoded\n", image_path);
	kg_camera_identity id;
	if ((code = kg_cli_image_identity(image_path, &id, &err)))
		goto fail;
	/* a refusal keeps what was searched, for the overlay */
	opt.keep_refused = overlay != NULL;
	code = kg_chart_detect(layout, img, &opt, &res, &err);
	/* a mapped file cut short or changed during the detection: that is the cause,
	 * whatever the detection made of the pixels */
	kg_err merr = {{0}};
	if (kg_image_map_check(img, &merr)) {
		err = merr;
		code = KG_EIO;
		goto fail;
	}
	if (code) {
		kg_err_prefix(&err, "%s: chart %s %s", image_path, layout->name,
		              code == KG_ENOENT ? "not found" : "refused");
		if (res && overlay) {
			kg_err oerr = {{0}};
			int oc = kg_inputs_check_output(overlay, &oerr);
			if (!oc)
				oc = kg_chart_overlay_write(res, img, overlay, 0, &oerr);
			if (oc)
				fprintf(stderr, "kogei: %s: overlay not written: %s\n", overlay, oerr.msg);
			else
				fprintf(stderr, "kogei: the overlay %s shows where the chart was looked "
				        "for and why each candidate failed\n", overlay);
		}
		goto fail;
	}
	for (int i = 0; i < res->nwarnings; i++)
		fprintf(stderr, "kogei: warning: %s\n", res->warnings[i]);
	if ((code = kg_chart_result_patchset(res, &ps, &err)))
		goto fail;
	char rms[32], used[512] = "", decim[16];
	snprintf(rms, sizeof(rms), "%.4f", res->rms_px);
	snprintf(decim, sizeof(decim), "%d", res->decimate);
	size_t at = 0;
	for (int i = 0; i < res->ntags && at < sizeof(used) - 1; i++)
		if (res->tags[i].used)
			at += (size_t)snprintf(used + at, sizeof(used) - at, "%s%d", at ? "," : "",
			                       res->tags[i].id);
	char white[24];
	snprintf(white, sizeof(white), "%ld", id.white_level);
	/* the light field removed from the values */
	const kg_chart_light *lf = &res->light;
	char lf_kind[24], lf_var[24] = "none", lf_range[48] = "none", lf_coef[400] = "none",
	     lf_frame[64] = "none";
	if (!opt.light_field || !lf->fitted)
		snprintf(lf_kind, sizeof(lf_kind), "%s", !opt.light_field ? "off" : "none");
	else
		snprintf(lf_kind, sizeof(lf_kind), "polynomial %d", lf->degree);
	if (lf->fitted) {
		snprintf(lf_var, sizeof(lf_var), "%.2f", 100 * lf->variation);
		snprintf(lf_range, sizeof(lf_range), "%.4f %.4f", lf->min, lf->max);
		size_t len = 0;
		for (int k = 0; k < 15 && len < sizeof(lf_coef); k++)
			len += (size_t)snprintf(lf_coef + len, sizeof(lf_coef) - len, "%s%.6g", k ? " " : "",
			                       lf->coef[k]);
		snprintf(lf_frame, sizeof(lf_frame), "%.3f %.3f %.3f", lf->origin_mm[0],
		         lf->origin_mm[1], lf->scale_mm);
	}
	/* the patches against the layout's colours */
	const kg_chart_colour_check *cc = &res->colours;
	char colours[200] = "none (the layout has no expected colours)";
	if (cc->note[0])
		snprintf(colours, sizeof(colours), "%s", cc->note);
	else if (cc->checked)
		snprintf(colours, sizeof(colours), "%d patches judged, %d flagged; worst of the others "
		         "%s at %.2f of its threshold (level %.2f, hue %.2f tolerances)", cc->used,
		         cc->flagged, cc->worst_id[0] ? cc->worst_id : "none", cc->worst,
		         cc->threshold_level, cc->threshold_hue);
	const char *keywords[] = {
		"ORIGINATOR", "kogei chart detect",
		"CHART_LAYOUT", layout->name,
		"CHART_LAYOUT_FILE", layout_file,
		"IMAGE", image_path,
		"DETECTOR", !res->tagless ? "apriltag" : res->tagless_grid ? "patch-grid" : "opencv-mcc",
		"TAG_FAMILY", opt.family ? opt.family : layout->family,
		"TAG_DECIMATE", decim,
		"TAGS_USED", used[0] ? used : "none",
		"HOMOGRAPHY_RMS_PX", rms,
		"PATCH_STATISTIC", kg_chart_statistic_name(opt.statistic),
		/* ln L = c0 + c1 u + c2 v + c3 u^2 + ... (kg_chart_light), u = (x - x0) / s,
		 * v = (y - y0) / s in chart mm (docs/chart-detect.md) */
		"LIGHT_FIELD", lf_kind,
		"LIGHT_FIELD_VARIATION_PERCENT", lf_var,
		"LIGHT_FIELD_RANGE", lf_range,
		"LIGHT_FIELD_COEFFICIENTS", lf_coef,
		"LIGHT_FIELD_ORIGIN_SCALE_MM", lf_frame,
		"COLOUR_CHECK", colours,
		"IMAGE_ENCODING", encoding,
		/* the camera, when the image is a session's capture */
		"CAMERA_BACKEND", id.backend,
		"CAMERA_MODEL", id.model,
		"CAMERA_SERIAL", id.serial,
		"CAMERA_PIXFMT", id.pixfmt,
		"CAMERA_WHITE_LEVEL", white,
		"CAMERA_DEMOSAIC", id.demosaic,
		"CAPTURE", id.capture,
		NULL,
	};
	for (int i = 0; !id.known && keywords[i]; i += 2)
		if (strcmp(keywords[i], "CAMERA_BACKEND") == 0)
			keywords[i] = NULL;
	/* both outputs checked against the inputs before the first is written */
	if ((overlay && (code = kg_inputs_check_output(overlay, &err))) ||
	    (code = kg_patchset_write(out_path, ps, KG_PATCH_RGB | KG_PATCH_EXTRA, keywords, &err)))
		goto fail;
	if (overlay && (code = kg_chart_overlay_write(res, img, overlay, 0, &err)))
		goto fail;
	if (!quiet)
		fprintf(stderr, "kogei: chart %s: %d tag%s used, homography RMS %.2f px, %d of %d "
		        "patches, %.0f ms (tags %.0f ms, decimate %d)\n", layout->name,
		        res->ntags_used, res->ntags_used == 1 ? "" : "s", res->rms_px, ps->n,
		        res->npatches, 1e3 * res->total_seconds, 1e3 * res->tag_seconds,
		        res->decimate);
	if (!quiet && lf->fitted)
		fprintf(stderr, "kogei: the light over the chart varies by %.1f %% (%.3f to %.3f of "
		        "its mean; degree %d from %d patches): removed from the patch values\n",
		        100 * lf->variation, lf->min, lf->max, lf->degree, lf->used);
	if (!quiet && cc->checked)
		fprintf(stderr, "kogei: the patches against the layout's colours: %s\n", colours);
fail:
	kg_chart_warm_wait();
	kg_patchset_free(&ps);
	kg_chart_result_free(&res);
	kg_image_free(&img);
	kg_chart_layout_free(&layout);
	free(layout_file);
	return code ? kg_cli_error(&err, code) : KG_EXIT_OK;
}
