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
	"                   [--family NAME] [--min-tags N] [--clip-level V] [--tagless] [--quiet]";

static const char help_detect[] =
	"\n"
	"Finds the chart of layout L in IMAGE by its AprilTag frame, fits the homography\n"
	"from the layout's millimetres to the image's pixels over every tag corner found\n"
	"(a consensus over pairs of tags rejects tags of other charts and misreads, then\n"
	"Levenberg-Marquardt on the reprojection error), and samples each patch over its\n"
	"inner region with robust statistics. IMAGE is a TIFF or PNG: 8/16-bit or float,\n"
	"grey (patch values come out grey), RGB, or a raw frame with a CFA pattern\n"
	"(demosaiced bilinearly). Values are linear on the 0..1 scale of the image.\n"
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
	"                       patches in red with the reason\n"
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
	"  --tagless            find an unframed ColorChecker with OpenCV mcc; a box whose\n"
	"                       patches do not read as the layout in any turn is refused\n"
	"  --quiet              no summary on standard error (warnings still shown)\n"
	"\n"
	"IMAGE inside a kogei session (SESSION/captures/NAME/rgb.tif, mean.tif) also gives\n"
	"the patch file the camera that took it: keywords CAMERA_BACKEND, CAMERA_MODEL,\n"
	"CAMERA_SERIAL, CAMERA_PIXFMT, CAMERA_WHITE_LEVEL, CAMERA_DEMOSAIC and CAPTURE,\n"
	"which kogei calib camera records in the calibration.\n"
	"\n"
	"Warnings go to standard error. Exit status 1 when the chart is not found (the\n"
	"message says what was seen), 2 on bad usage.";

static int parse_int(const char *text, int lo, int hi, int *out)
{
	char *end;
	long v = strtol(text, &end, 10);
	if (*text == '\0' || *end || v < lo || v > hi)
		return -1;
	*out = (int)v;
	return 0;
}

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
		{NULL, 0, NULL, 0},
	};
	const char *layout_path = NULL, *out_path = NULL, *overlay = NULL;
	int quiet = 0;
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
			if (parse_int(optarg, 1, 64, &opt.decimate))
				return kg_cli_usage_error(usage_detect, "--decimate %s: expected 1..64", optarg);
			break;
		case 't':
			if (parse_int(optarg, 1, 256, &opt.threads))
				return kg_cli_usage_error(usage_detect, "--threads %s: expected 1..256", optarg);
			break;
		case 'm':
			if (parse_int(optarg, 1, 1000, &opt.min_tags))
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
		case 'q':
			quiet = 1;
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
	if ((code = kg_image_read(image_path, &img, &err)))
		goto fail;
	kg_camera_identity id;
	if ((code = kg_cli_image_identity(image_path, &id, &err)))
		goto fail;
	if ((code = kg_chart_detect(layout, img, &opt, &res, &err))) {
		kg_err_prefix(&err, "%s: chart %s not found", image_path, layout->name);
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
	const char *keywords[] = {
		"ORIGINATOR", "kogei chart detect",
		"CHART_LAYOUT", layout->name,
		"CHART_LAYOUT_FILE", layout_file,
		"IMAGE", image_path,
		"DETECTOR", res->tagless ? "opencv-mcc" : "apriltag",
		"TAG_FAMILY", opt.family ? opt.family : layout->family,
		"TAG_DECIMATE", decim,
		"TAGS_USED", used[0] ? used : "none",
		"HOMOGRAPHY_RMS_PX", rms,
		"PATCH_STATISTIC", kg_chart_statistic_name(opt.statistic),
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
fail:
	kg_patchset_free(&ps);
	kg_chart_result_free(&res);
	kg_image_free(&img);
	kg_chart_layout_free(&layout);
	free(layout_file);
	return code ? kg_cli_error(&err, code) : KG_EXIT_OK;
}
