/* kogei estimate / kogei classify: argument parsing; the camera file becomes a kernel
 * through calib/ (kg_camera_kernel) and estimate/ does the rest (kg_estimate_image,
 * kg_classify_image). */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "raw.h"
#include "cli.h"
#include "kg_calib.h"

static const char usage_estimate[] =
	"kogei estimate --calib CAM.json IMAGE -o CUBE.hdr [--format f32|f16|weights]\n"
	"               [--interleave bsq|bip] [--method NAME|lut|auto] [--lut-size N]\n"
	"               [--threads N] [--block-rows N] [--clip-level V] [--force] [--quiet]\n"
	"               [--encoding srgb|linear|gamma:G]";

static const char help_estimate[] =
	"\n"
	"Per-pixel spectral reflectance (the paper's eq. 10): s = A x(rho) with the\n"
	"site camera's calibration (kogei calib camera), 61 bands 400-700 nm every 5 nm.\n"
	"IMAGE is a linear 3-channel TIFF or PNG (0..1 scale; raw Bayer frames must be\n"
	"demosaiced first). Rows are processed in blocks and streamed to the file, so\n"
	"memory stays bounded whatever the image size.\n"
	"\n"
	"  --calib CAM.json     site calibration (kogei-camera/1)\n"
	"  -o CUBE.hdr          ENVI cube (CUBE.hdr + CUBE.img) and its pixel flags\n"
	"                       CUBE_mask.hdr (uint8: 1 non-finite input, 2 clipped,\n"
	"                       4 negative reflectance clamped to 0)\n"
	"  --format F           f32 (default): float32, with the wavelengths;\n"
	"                       f16: IEEE half floats stored as ENVI data type 12 with\n"
	"                       'kogei sample format = ieee-half' (other tools read the\n"
	"                       bit patterns as uint16: use f32 for them);\n"
	"                       weights: the K basis weights (pca only), with the basis B\n"
	"                       ('kogei basis', 61 x K row-major) and 'kogei mean' in the\n"
	"                       header: s = mean + B w\n"
	"  --interleave I       bsq (default) or bip\n"
	"  --method M           pca, linear, wiener, rootpoly2, rootpoly3, lut (a 3-D lookup\n"
	"                       table of the camera's default method, trilinear), or auto\n"
	"                       (default): the camera file's method\n"
	"  --lut-size N         nodes per axis of the lookup table, 2-65 (default 33)\n"
	"  --threads N          worker threads (default: online CPUs)\n"
	"  --block-rows N       rows per block (default: about 4 MiB of output)\n"
	"  --clip-level V       pixels with a channel >= V are flagged clipped and not\n"
	"                       estimated (default 0.999, lower per channel where the\n"
	"                       image's values pile up below it: saturation found from\n"
	"                       the data; 'none' disables)\n"
	"  --force              apply the calibration to an image of another camera\n"
	"                       (a warning instead of the refusal)\n"
	"  --quiet              no summary line or progress on standard error\n"
	"  --encoding E         how a JPEG IMAGE was encoded: srgb, linear, or gamma:G\n"
	"                       (linear = code^G). A JPEG is gamma-encoded and white-\n"
	"                       balanced by the camera, so without it a JPEG is refused\n"
	"\n"
	"An IMAGE inside a kogei session (SESSION/captures/NAME/rgb.tif) names its camera;\n"
	"when it is not the one CAM.json calibrates (backend, model and serial), nothing is\n"
	"written and the exit status is 1, unless --force. An image from outside a session,\n"
	"or a calibration that records no camera, is processed with a note that the camera\n"
	"was not checked.\n"
	"\n"
	"Flagged pixels (NaN/Inf input, clipped) are NaN in the cube. A summary line on\n"
	"standard error counts pixels, clipped, non-finite and clamped ones; images of\n"
	"4 Mpix or more also report progress. Exit status 1 on bad input (nothing is\n"
	"written), 2 on bad usage.";

static const char usage_classify[] =
	"kogei classify --calib CAM.json --materials LIB.json IMAGE -o LABELS.hdr\n"
	"               [--only a,b,c] [--method camera|eq11] [--angles A:B[:STEP]]\n"
	"               [--intensity LO:HI] [--merge-distance D|none] [--regions MAP.png]\n"
	"               [--no-regions] [--composition COMP.hdr]\n"
	"               [--distance plain|scale-free] [--angle DEG]\n"
	"               [--variance VAR.tif] [--frames N] [--mask MASK.png]\n"
	"               [--background-level L|none] [--unknown-threshold T|none]\n"
	"               [--threads N] [--block-rows N] [--clip-level V] [--force] [--quiet]\n"
	"               [--encoding srgb|linear|gamma:G]";

static const char help_classify[] =
	"\n"
	"Material labels. The default method, camera, matches each pixel where the camera\n"
	"measured it: its reading mapped through M2 into the reference camera's space is\n"
	"compared with every declared material's predicted reading (the reference camera's\n"
	"spectral response times the material's reflectance at each incidence angle of\n"
	"--angles, times any intensity in --intensity: the unknown geometry), weighted by\n"
	"the pixel's own noise (its variance, or the noise model, through M2, plus the\n"
	"calibration's residual covariance). Before classifying, every pair of materials\n"
	"is measured at the capture's noise; a pair that a single pixel cannot tell apart\n"
	"(closer than --merge-distance, default 2 noise sigmas: a pixel confuses them\n"
	"more than one time in six) becomes one compound class 'a|b': the label map\n"
	"holds no distinction the data cannot support. Pixels are then grouped into\n"
	"regions (connected pixels of one class, or --regions) and each region is\n"
	"decided on its pixels' pooled likelihood, which resolves a compound class where\n"
	"the region has enough pixels, or refuses it as unknown.\n"
	"\n"
	"  --method M           camera (default) or eq11 (the paper's eq. 11 on the pca\n"
	"                       estimate, for comparison; 'pca' is the same)\n"
	"  --angles A:B[:STEP]  incidence angles searched, degrees (default 0:70:5)\n"
	"  --intensity LO:HI    intensities searched, relative to the material seen at\n"
	"                       the chart's exposure (default 0.3:1)\n"
	"  --merge-distance D   join pairs closer than D noise sigmas (default 2); 'none':\n"
	"                       keep every material apart\n"
	"  --regions MAP.png    grey map of region numbers (0 = none, 1-65535) of the\n"
	"                       image's size: decide these regions instead of connected\n"
	"                       components\n"
	"  --no-regions         per-pixel labels only\n"
	"  --composition COMP.hdr  ENVI cube (float32, 6 bands: ag, cu, au fractions and\n"
	"                       their Cramer-Rao standard deviations) of the pixels whose\n"
	"                       best material is made of the library's silver, copper and\n"
	"                       gold, fitted in camera space (fractions >= 0, summing to\n"
	"                       1); gold only where its sd is below the declared\n"
	"                       materials' range of gold fractions. Regions and\n"
	"                       LABELS.json get the composition whenever the library\n"
	"                       holds the three metals\n"
	"\n"
	"With --method eq11 each pixel gets the material j minimising\n"
	"||C_j - s||^2 over the declared materials, where C_j is the library reflectance\n"
	"at --angle. Because s = mean + B w lies in the span of the pca basis, this is\n"
	"computed from the K weights w alone:\n"
	"||C_j - s||^2 = ||B^T (C_j - mean) - w||^2 + ||(I - B B^T)(C_j - mean)||^2.\n"
	"A pixel that j does not explain within the noise is 'unknown', and a dark or\n"
	"masked-out one 'background', rather than the nearest material.\n"
	"\n"
	"  --calib CAM.json     site calibration (with the reference camera's response for\n"
	"                       the camera method); eq11 uses its pca map\n"
	"  --materials LIB      material library (kogei-materials/1 JSON, or \"default\",\n"
	"                       the bundled library)\n"
	"  --only a,b,c         classify among these library materials only (the scene's\n"
	"                       declared set), in this order; default: all of them\n"
	"  --distance D         eq11: plain (default) or scale-free: min over a >= 0 of\n"
	"                       ||a C_j - s||^2, for specular levels that vary with geometry\n"
	"  --angle DEG          eq11: incidence angle of the material spectra, 0-90\n"
	"                       (default 0)\n"
	"  --variance VAR.tif   per-pixel variance of the single frames (3 channels, the\n"
	"                       image's size; acquire records it as variance.tif)\n"
	"  --frames N           frames averaged into IMAGE (default 1): the mean's\n"
	"                       variance is VAR / N\n"
	"  --unknown-threshold T  a pixel whose best material does not explain it is\n"
	"                       'unknown'. camera: its d2 > T, default the 99.9 % point of\n"
	"                       chi-square with 2 degrees of freedom (13.82; 3, 16.27, when\n"
	"                       --intensity fixes the intensity). eq11:\n"
	"                       chi2 > T, where chi2 weighs its residual in\n"
	"                       the K weights by the noise (VAR / N, or without --variance\n"
	"                       a model: sigma = 0.002 + 1 % of the level, in quadrature)\n"
	"                       plus the calibration's relative residual times the level\n"
	"                       and the material's part outside the basis, all propagated\n"
	"                       through the weight matrix M M2. Default: the 99.9 % point\n"
	"                       of chi-square with K (scale-free: K - 1) degrees of\n"
	"                       freedom (16.27 for K = 3); 'none': no unknown test\n"
	"  --background-level L pixels whose largest channel is below L (0..1 of full\n"
	"                       scale; default 0.01) are 'background'; 'none' or 0: off\n"
	"  --mask MASK.png      grey PNG or TIFF of the image's size: 0 = background,\n"
	"                       non-zero = object; background wins over every other label\n"
	"  -o LABELS.hdr        ENVI classification file (LABELS.hdr + LABELS.img;\n"
	"                       class 0 'unclassified' = flagged pixels, then the\n"
	"                       classes, then 'unknown' and 'background'), and beside\n"
	"                       it LABELS.json (classes, pixel counts, mean spectra,\n"
	"                       confidence, the noise model and bounds used), LABELS.png\n"
	"                       (preview; flagged grey, unknown magenta, background dark),\n"
	"                       LABELS_confidence.hdr (float32: the margin to the\n"
	"                       runner-up; camera: 4 bands, margin, posterior, fitted\n"
	"                       angle and intensity; NaN for unknown and background),\n"
	"                       LABELS_mask.hdr (pixel flags), and with regions\n"
	"                       LABELS_regions.hdr (uint32 region numbers) and\n"
	"                       LABELS_regions.csv (region, pixels, class, decided\n"
	"                       label, posterior), LABELS_materials.hdr (each region's\n"
	"                       decided label on its pixels, the class elsewhere; not\n"
	"                       with --regions); LABELS.json also holds the\n"
	"                       separability table and the merges\n"
	"  --threads, --block-rows, --clip-level, --force, --quiet, --encoding   as for\n"
	"                       kogei estimate (a JPEG only with --encoding)\n"
	"                       (an image of another camera is refused unless --force)\n"
	"\n"
	"Prints the classes with their pixel counts and median margins. Exit status 1 on\n"
	"bad input (nothing is written), 2 on bad usage.";

/* 1 once --clip-level was given: the user's level is kept as it is. */
static int clip_given;

static int parse_clip(const char *text, float *out)
{
	if (strcmp(text, "none") == 0) {
		*out = INFINITY;
		return 0;
	}
	double v;
	if (kg_cli_number(text, &v) || !(v > 0))
		return -1;
	*out = (float)v;
	return 0;
}

/* Options both commands take. Returns 1 when the option was one of them, 0 when not,
 * and KG_EXIT_USAGE (after the message) when its value is bad. */
/* A JPEG's encoding as the user states it (--encoding); UNSTATED: refused. */
static kg_image_encoding stated_encoding;

static int common_option(int c, const char *usage, kg_apply_options *opt, int *quiet,
                         int *force)
{
	kg_err local = {{0}};
	switch (c) {
	case 't':
		if (kg_cli_int(optarg, 1, 256, &opt->threads))
			return -kg_cli_usage_error(usage, "--threads %s: expected 1 to 256", optarg);
		return 1;
	case 'b':
		if (kg_cli_int(optarg, 1, 1 << 20, &opt->block_rows))
			return -kg_cli_usage_error(usage, "--block-rows %s: expected a positive integer",
			                           optarg);
		return 1;
	case 'c':
		clip_given = 1;
		if (parse_clip(optarg, &opt->clip_level))
			return -kg_cli_usage_error(usage, "--clip-level %s: expected a number > 0 or none",
			                           optarg);
		return 1;
	case 'q': *quiet = 1; return 1;
	case 'F': *force = 1; return 1;
	case 'E':
		if (kg_image_encoding_parse(optarg, &stated_encoding, &local))
			return -kg_cli_usage_error(usage, "%s", local.msg);
		return 1;
	default: return 0;
	}
}

#define COMMON_LONG_OPTIONS                                                          \
	{"calib", required_argument, NULL, 'C'}, {"threads", required_argument, NULL, 't'}, \
	{"block-rows", required_argument, NULL, 'b'},                                    \
	{"clip-level", required_argument, NULL, 'c'}, {"quiet", no_argument, NULL, 'q'},  \
	{"force", no_argument, NULL, 'F'}, {"encoding", required_argument, NULL, 'E'},    \
	{"output", required_argument, NULL, 'o'}, {"help", no_argument, NULL, 'h'}

/* An input image opened to be read a band of rows at a time (memory stays bounded
 * whatever its size), with the channels the command needs: 3 for the photograph and
 * its variance, 1 for a mask. */
/* Camera raw photographs demosaiced whole (as chart detect and process do), held until
 * the command ends. */
static kg_image *demosaiced[4];

static void free_demosaiced(void)
{
	for (int i = 0; i < 4; i++)
		kg_image_free(&demosaiced[i]);
}

static int open_raw_photograph(const char *path, kg_row_source *src, kg_err *err)
{
	int slot = 0;
	while (slot < 4 && demosaiced[slot])
		slot++;
	int rc = slot == 4 ? kg_fail(err, KG_EINVAL, "%s: too many raw images", path)
	                   : kg_cli_read_photograph(path, &demosaiced[slot], err);
	if (rc)
		return rc;
	kg_row_source_of_image(demosaiced[slot], src);
	return 0;
}

static int open_image(const char *path, int channels, kg_image_rows **rows,
                      kg_row_source *src, kg_err *err)
{
	if (channels == 3 && kg_raw_is_raw(path))
		return open_raw_photograph(path, src, err);
	if (kg_image_is_jpeg(path) && stated_encoding.curve == KG_ENCODING_UNSTATED)
		return kg_fail(err, KG_EINVAL, "%s: a JPEG: gamma-encoded and white-balanced by the "
		               "camera, so its values are not the linear camera responses the "
		               "calibration maps; expected a raw, TIFF or PNG capture, or --encoding "
		               "srgb|linear|gamma:G stating how the JPEG was encoded", path);
	int rc = kg_image_rows_open_as(path, &stated_encoding, rows, err);
	if (rc)
		return rc;
	const kg_image *h = kg_image_rows_header(*rows);
	if (channels == 3 && h->channels != 3) {
		rc = kg_fail(err, KG_EINVAL,
		             "%s: %d channel%s%s: expected a 3-channel linear RGB image%s", path,
		             h->channels, h->channels == 1 ? "" : "s", h->cfa ? " (a raw CFA frame)" : "",
		             h->channels == 1 ? "; a raw Bayer frame must be demosaiced to RGB first"
		                              : "");
		kg_image_rows_free(rows);
		return rc;
	}
	kg_row_source_of_rows(*rows, src);
	return 0;
}

/* Saturation from the data: a pile-up of the photograph's values below the clip level
 * (a sensor that stops short of full scale) becomes each channel's clip level, so
 * pixels at it are flagged clipped (core/saturation.h). The photograph is read once
 * more for its histogram (a file through a second row reader; a raw file's demosaiced
 * image in memory). */
static int data_saturation(const char *cmd, const char *path, const kg_row_source *src,
                           kg_apply_options *opt, int quiet, kg_err *err)
{
	if (clip_given || !isfinite(opt->clip_level))
		return 0;
	kg_saturation sat;
	int rc;
	const kg_image *mem = NULL;
	for (int i = 3; i >= 0 && !mem; i--)
		if (demosaiced[i] && src->user == demosaiced[i])
			mem = demosaiced[i];
	if (mem) {
		rc = kg_saturation_of_image(mem, opt->clip_level, &sat, err);
	} else {
		kg_image_rows *rows = NULL;
		if ((rc = kg_image_rows_open(path, &rows, err)))
			return rc;
		kg_row_source again;
		kg_row_source_of_rows(rows, &again);
		rc = kg_saturation_of_rows(&again, kg_saturation_steps(kg_image_rows_header(rows)),
		                           opt->clip_level, &sat, err);
		kg_image_rows_free(&rows);
		/* the flat-object guard needs the pixels: once more, in bands */
		if (!rc && sat.channels == 3 && kg_saturation_below(&sat, opt->clip_level) &&
		    !(rc = kg_image_rows_open(path, &rows, err))) {
			kg_row_source_of_rows(rows, &again);
			kg_sat_flat f;
			kg_sat_flat_init(&f, &sat);
			float *buf = malloc(sizeof(float) * 3 * 64 * (size_t)again.width);
			rc = buf ? 0 : kg_fail(err, KG_ENOMEM, "out of memory");
			for (int y = 0; y < again.height && !rc; y += 64) {
				int n = again.height - y < 64 ? again.height - y : 64;
				if (!(rc = again.read(again.user, y, n, buf, err)))
					kg_sat_flat_add(&f, buf, (size_t)n * (size_t)again.width);
			}
			free(buf);
			kg_image_rows_free(&rows);
			if (!rc)
				kg_sat_flat_result(&f, &sat);
		}
	}
	if (rc || !kg_saturation_below(&sat, opt->clip_level))
		return rc;
	for (int c = 0; c < 3 && c < sat.channels; c++)
		if (sat.found[c])
			opt->clip_rgb[c] = (float)sat.clip[c];
	if (!quiet) {
		char line[256];
		kg_saturation_format(&sat, "RGB", line, sizeof(line));
		fprintf(stderr, "%s: %s: saturation found from the data below full scale: %s; pixels "
		        "there are flagged clipped\n", cmd, path, line);
	}
	return 0;
}

int kg_cmd_estimate(int argc, char **argv)
{
	const char *calib = NULL, *out = NULL;
	const char *format = "f32", *interleave = "bsq", *method = "auto";
	int lut_size = 33, quiet = 0, force = 0;
	kg_apply_options opt;
	kg_apply_options_init(&opt);
	static const struct option opts[] = {
		COMMON_LONG_OPTIONS,
		{"format", required_argument, NULL, 'f'},
		{"interleave", required_argument, NULL, 'i'},
		{"method", required_argument, NULL, 'm'},
		{"lut-size", required_argument, NULL, 'L'},
		{0, 0, 0, 0},
	};
	int c;
	optind = 1;
	memset(&stated_encoding, 0, sizeof(stated_encoding));
	while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
		int r = common_option(c, usage_estimate, &opt, &quiet, &force);
		if (r < 0)
			return -r;
		if (r)
			continue;
		switch (c) {
		case 'C': calib = optarg; break;
		case 'o': out = optarg; break;
		case 'f': format = optarg; break;
		case 'i': interleave = optarg; break;
		case 'm': method = optarg; break;
		case 'L':
			if (kg_cli_int(optarg, 2, KG_EST_LUT_MAX_N, &lut_size))
				return kg_cli_usage_error(usage_estimate, "--lut-size %s: expected 2 to %d",
				                          optarg, KG_EST_LUT_MAX_N);
			break;
		case 'h': printf("usage: %s\n%s\n", usage_estimate, help_estimate); return KG_EXIT_OK;
		default: return kg_cli_usage_error(usage_estimate, "bad option");
		}
	}
	if (optind == argc)
		return kg_cli_usage_error(usage_estimate, "IMAGE is missing");
	if (optind + 1 != argc)
		return kg_cli_usage_error(usage_estimate, "expected one IMAGE, got %d", argc - optind);
	if (!calib || !out)
		return kg_cli_usage_error(usage_estimate, "--calib and -o are required");
	if (strcmp(out, "-") == 0)
		return kg_cli_usage_error(usage_estimate,
		                          "-o -: a cube cannot go to standard output; name a .hdr file");
	int bsq;
	if (strcmp(interleave, "bsq") == 0)
		bsq = 1;
	else if (strcmp(interleave, "bip") == 0)
		bsq = 0;
	else
		return kg_cli_usage_error(usage_estimate, "--interleave %s: expected bsq or bip",
		                          interleave);
	kg_est_format fmt;
	if (strcmp(format, "f32") == 0)
		fmt = bsq ? KG_EST_F32_BSQ : KG_EST_F32_BIP;
	else if (strcmp(format, "f16") == 0)
		fmt = bsq ? KG_EST_F16_BSQ : KG_EST_F16_BIP;
	else if (strcmp(format, "weights") == 0)
		fmt = KG_EST_WEIGHTS;
	else
		return kg_cli_usage_error(usage_estimate, "--format %s: expected f32, f16 or weights",
		                          format);
	kg_err err = {{0}};
	kg_method m = KG_METHOD_AUTO;
	int lut = strcmp(method, "lut") == 0;
	if (!lut && kg_method_parse(method, &m, &err))
		return kg_cli_usage_error(usage_estimate, "--method: %s, or lut", err.msg);

	const char *image = argv[optind];
	kg_camera_calib *cam = NULL;
	kg_image_rows *img = NULL;
	kg_row_source src;
	kg_est_kernel *k = NULL;
	double pre[9];
	int pre_needed = 0;
	kg_est_stats stats;
	int rc = kg_camera_load(calib, &cam, &err);
	if (!rc)
		rc = kg_cli_check_camera(cam, calib, image, force, &err);
	if (!rc && (rc = kg_camera_kernel(cam, m, lut ? lut_size : 0, &k, pre, &pre_needed, &err)))
		kg_err_prefix(&err, "%s: ", calib);
	if (!rc && fmt == KG_EST_WEIGHTS && kg_est_kernel_k(k) == 0)
		rc = kg_fail(&err, KG_EINVAL,
		             "%s: --format weights needs the pca method (a K-dimensional basis); "
		             "method %s gives spectra only",
		             calib, lut ? "lut" : kg_method_name(m == KG_METHOD_AUTO ? cam->method : m));
	if (!rc)
		rc = open_image(image, 3, &img, &src, &err);
	if (!rc)
		rc = data_saturation("estimate", image, &src, &opt, quiet, &err);
	/* the header's description names the calibration, whose path must fit in it */
	char *desc = NULL;
	if (!rc && asprintf(&desc, "kogei estimate: %s, method %s%s, calibration %s", format,
	                    lut ? "lut of " : "",
	                    kg_method_name(m == KG_METHOD_AUTO ? cam->method : m), calib) < 0)
		rc = kg_fail(&err, KG_ENOMEM, "out of memory"), desc = NULL;
	if (!rc)
		rc = kg_envi_check("--calib: its path, written into the output header's description",
		                   desc, 0, &err);
	if (!rc) {
		opt.description = desc;
		opt.pre = pre_needed ? pre : NULL;
		opt.progress = quiet ? NULL : stderr;
		rc = kg_estimate_rows(k, &src, fmt, &opt, out, &stats, &err);
	}
	if (!rc) {
		if (!quiet) {
			char line[256];
			kg_est_stats_format(&stats, line, sizeof(line));
			fprintf(stderr, "estimate: %s\n", line);
		}
		char *mask = NULL;
		if (kg_apply_side_path(out, "_mask.hdr", &mask, &err) == 0)
			printf("wrote %s (%d bands, %s %s) and %s\n", out, kg_est_format_bands(k, fmt),
			       format, fmt == KG_EST_WEIGHTS ? "bip" : interleave, mask);
		free(mask);
	}
	free(desc);
	kg_est_kernel_free(&k);
	kg_image_rows_free(&img);
	free_demosaiced();
	kg_camera_calib_free(&cam);
	return rc ? kg_cli_error(&err, rc) : KG_EXIT_OK;
}

int kg_cmd_classify(int argc, char **argv)
{
	const char *calib = NULL, *out = NULL, *library = NULL, *distance = "plain";
	const char *method = "camera", *variance = NULL, *mask = NULL, *regions = NULL;
	const char *composition = NULL;
	char *only = NULL;
	double angle = 0;
	int no_regions = 0, distance_given = 0, angle_given = 0;
	kg_classify_camera ccam;
	kg_classify_camera_init(&ccam);
	int quiet = 0, force = 0;
	kg_apply_options opt;
	kg_apply_options_init(&opt);
	kg_classify_options copt;
	kg_classify_options_init(&copt);
	static const struct option opts[] = {
		COMMON_LONG_OPTIONS,
		{"materials", required_argument, NULL, 'M'},
		{"only", required_argument, NULL, 'y'},
		{"distance", required_argument, NULL, 'd'},
		{"angle", required_argument, NULL, 'a'},
		{"method", required_argument, NULL, 'm'},
		{"variance", required_argument, NULL, 'V'},
		{"frames", required_argument, NULL, 'N'},
		{"mask", required_argument, NULL, 'K'},
		{"background-level", required_argument, NULL, 'L'},
		{"unknown-threshold", required_argument, NULL, 'U'},
		{"angles", required_argument, NULL, 'A'},
		{"intensity", required_argument, NULL, 'I'},
		{"merge-distance", required_argument, NULL, 'D'},
		{"regions", required_argument, NULL, 'R'},
		{"no-regions", no_argument, NULL, 'n'},
		{"composition", required_argument, NULL, 'P'},
		{0, 0, 0, 0},
	};
	int c;
	optind = 1;
	memset(&stated_encoding, 0, sizeof(stated_encoding));
	while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
		int r = common_option(c, usage_classify, &opt, &quiet, &force);
		if (r < 0)
			return -r;
		if (r)
			continue;
		switch (c) {
		case 'C': calib = optarg; break;
		case 'o': out = optarg; break;
		case 'M': library = optarg; break;
		case 'y': only = optarg; break;
		case 'd': distance = optarg; distance_given = 1; break;
		case 'm': method = optarg; break;
		case 'V': variance = optarg; break;
		case 'R': regions = optarg; break;
		case 'n': no_regions = 1; break;
		case 'P': composition = optarg; break;
		case 'A': {
			double v[3] = {0, 0, 5};
			int nv = kg_cli_parse_numbers(optarg, v, 3);
			if (nv < 2 || !(v[0] >= 0 && v[1] >= v[0] && v[1] < 90 && v[2] > 0))
				return kg_cli_usage_error(usage_classify, "--angles %s: expected FROM:TO[:STEP] "
				                          "degrees, 0 <= FROM <= TO < 90, STEP > 0", optarg);
			ccam.angle_from = v[0];
			ccam.angle_to = v[1];
			ccam.angle_step = v[2];
			break;
		}
		case 'I': {
			double v[2];
			if (kg_cli_parse_numbers(optarg, v, 2) != 2 || !(v[0] > 0 && v[1] >= v[0] && isfinite(v[1])))
				return kg_cli_usage_error(usage_classify, "--intensity %s: expected LO:HI with "
				                          "0 < LO <= HI", optarg);
			ccam.intensity_lo = v[0];
			ccam.intensity_hi = v[1];
			break;
		}
		case 'D':
			if (strcmp(optarg, "none") == 0) {
				ccam.merge_distance = -1;
				break;
			}
			if (kg_cli_number(optarg, &ccam.merge_distance) || !(ccam.merge_distance > 0))
				return kg_cli_usage_error(usage_classify, "--merge-distance %s: expected a "
				                          "number > 0 or none", optarg);
			break;
		case 'K': mask = optarg; break;
		case 'N':
			if (kg_cli_int(optarg, 1, 1 << 20, &copt.frames))
				return kg_cli_usage_error(usage_classify, "--frames %s: expected 1 or more",
				                          optarg);
			break;
		case 'L':
			if (strcmp(optarg, "none") == 0) {
				copt.background_level = 0;
				break;
			}
			if (kg_cli_number(optarg, &copt.background_level) ||
			    !(copt.background_level >= 0 && copt.background_level <= 1))
				return kg_cli_usage_error(usage_classify,
				                          "--background-level %s: expected 0 to 1 (of full "
				                          "scale) or none",
				                          optarg);
			break;
		case 'U':
			if (strcmp(optarg, "none") == 0) {
				copt.unknown_threshold = INFINITY;
				break;
			}
			if (kg_cli_number(optarg, &copt.unknown_threshold) || !(copt.unknown_threshold > 0))
				return kg_cli_usage_error(usage_classify,
				                          "--unknown-threshold %s: expected a number > 0 or "
				                          "none",
				                          optarg);
			break;
		case 'a':
			angle_given = 1;
			if (kg_cli_number(optarg, &angle) || !(angle >= 0 && angle <= 90))
				return kg_cli_usage_error(usage_classify, "--angle %s: expected 0 to 90 degrees",
				                          optarg);
			break;
		case 'h': printf("usage: %s\n%s\n", usage_classify, help_classify); return KG_EXIT_OK;
		default: return kg_cli_usage_error(usage_classify, "bad option");
		}
	}
	if (optind == argc)
		return kg_cli_usage_error(usage_classify, "IMAGE is missing");
	if (optind + 1 != argc)
		return kg_cli_usage_error(usage_classify, "expected one IMAGE, got %d", argc - optind);
	if (!calib || !library || !out)
		return kg_cli_usage_error(usage_classify, "--calib, --materials and -o are required");
	if (strcmp(out, "-") == 0)
		return kg_cli_usage_error(usage_classify,
		                          "-o -: a label map cannot go to standard output; name a "
		                          ".hdr file");
	if (strcmp(distance, "plain") == 0)
		copt.distance = KG_EST_DIST_PLAIN;
	else if (strcmp(distance, "scale-free") == 0)
		copt.distance = KG_EST_DIST_SCALE_FREE;
	else
		return kg_cli_usage_error(usage_classify, "--distance %s: expected plain or scale-free",
		                          distance);
	kg_err err = {{0}};
	kg_method m = KG_METHOD_PCA;
	int camera = strcmp(method, "camera") == 0;
	if (!camera && strcmp(method, "eq11") != 0) {
		if (kg_method_parse(method, &m, &err))
			return kg_cli_usage_error(usage_classify, "--method %s: expected camera or eq11",
			                          method);
		if (m != KG_METHOD_PCA)
			return kg_cli_error(&err, kg_fail(&err, KG_EINVAL,
			                                  "--method %s: expected camera (the default) or "
			                                  "eq11 (the paper's eq. 11 on the K weights of the "
			                                  "pca map; 'pca' is the same)",
			                                  method));
	}
	if (camera && (distance_given || angle_given))
		return kg_cli_usage_error(usage_classify, "--distance and --angle belong to --method "
		                          "eq11; the camera method fits the angle and the intensity "
		                          "(--angles, --intensity)");
	if (!camera && (regions || no_regions || composition))
		return kg_cli_usage_error(usage_classify, "--regions, --no-regions and --composition "
		                          "belong to the camera method");
	char *only_copy = only ? strdup(only) : NULL;
	char *names[KG_EST_MAX_MATERIALS + 1];
	int nnames = 0;
	if (only && (!only_copy || kg_cli_split_names(only_copy, names, KG_EST_MAX_MATERIALS + 1, &nnames))) {
		free(only_copy);
		return kg_cli_usage_error(usage_classify,
		                          "--only %s: expected material names separated by commas",
		                          only);
	}

	const char *image = argv[optind];
	kg_camera_calib *cam = NULL;
	kg_material_library *lib = NULL;
	kg_est_material_set *set = NULL;
	kg_image_rows *img = NULL, *var_img = NULL, *mask_img = NULL;
	kg_image_rows *survey_img = NULL, *survey_var = NULL, *region_img = NULL;
	kg_row_source src, var_src, mask_src, survey_src, survey_var_src, region_src;
	kg_est_kernel *k = NULL;
	double pre[9];
	kg_classify_result res = {0};
	int rc = kg_camera_load(calib, &cam, &err);
	if (!rc)
		rc = kg_cli_check_camera(cam, calib, image, force, &err);
	if (!rc && (rc = kg_camera_kernel(cam, m, 0, &k, pre, NULL, &err)))
		kg_err_prefix(&err, "%s: ", calib);
	if (!rc)
		rc = kg_material_library_load(library, &lib, &err);
	if (!rc)
		rc = kg_est_material_set_new(lib, library, (const char *const *)names, nnames, angle,
		                             &set, &err);
	if (!rc)
		rc = open_image(image, 3, &img, &src, &err);
	if (!rc)
		rc = data_saturation("classify", image, &src, &opt, quiet, &err);
	if (!rc && variance && (rc = open_image(variance, 0, &var_img, &var_src, &err)) == 0)
		copt.variance = &var_src;
	if (!rc && mask && (rc = open_image(mask, 0, &mask_img, &mask_src, &err)) == 0)
		copt.mask = &mask_src;
	if (!rc && camera && !cam->response.available)
		rc = kg_fail(&err, KG_EINVAL,
		             "%s: response: the calibration holds no reference camera response, which "
		             "the camera method needs (recalibrate the reference and the site with "
		             "this version), or classify with --method eq11",
		             calib);
	if (!rc && camera) {
		rc = open_image(image, 3, &survey_img, &survey_src, &err);
		if (!rc && variance && !(rc = open_image(variance, 0, &survey_var, &survey_var_src, &err)))
			ccam.survey_variance = &survey_var_src;
		ccam.survey = &survey_src;
		if (!rc && regions && !(rc = open_image(regions, 0, &region_img, &region_src, &err))) {
			const kg_image *h = kg_image_rows_header(region_img);
			ccam.region_map = &region_src;
			ccam.region_map_name = regions;
			ccam.region_scale = h->is_float || h->bits >= 32 ? 1.0 : (double)((1u << h->bits) - 1);
		}
		ccam.regions = !no_regions;
		static const char *const metal_names[3] = {"silver", "copper", "gold"};
		for (int q = 0; !rc && q < 3; q++) {
			const kg_material *mt = kg_material_library_find(lib, metal_names[q]);
			ccam.metals[q] = mt && mt->kind == KG_MATERIAL_METAL ? mt : NULL;
		}
		if (!rc && composition && !(ccam.metals[0] && ccam.metals[1] && ccam.metals[2]))
			rc = kg_fail(&err, KG_EINVAL, "%s: --composition needs the library's metals "
			             "silver, copper and gold (kind metal)", library);
		ccam.composition_hdr = composition;
	}
	if (!rc && camera) {
		kg_classify_info info = {calib, library, "camera", image, variance, mask, NULL, NULL};
		opt.progress = quiet ? NULL : stderr;
		ccam.response = &cam->response.F[0][0];
		snprintf(ccam.response_source, sizeof(ccam.response_source), "%s",
		         cam->response.source);
		memcpy(ccam.site_to_ref, cam->M2, sizeof(ccam.site_to_ref));
		kg_camera_residual_cov(cam, ccam.calib_cov);
		ccam.reference_sha256 = kg_camera_reference_sha256(cam);
		rc = kg_classify_camera_rows(k, set, &ccam, &src, &opt, &copt, &info, out, &res, &err);
	} else if (!rc) {
		kg_classify_info info = {calib, library, kg_method_name(m), image, variance, mask,
		                         NULL, NULL};
		opt.progress = quiet ? NULL : stderr;
		copt.residual_relative = isinf(copt.unknown_threshold) ? 0 : cam->residual_relative;
		if (!(copt.residual_relative >= 0 && isfinite(copt.residual_relative)))
			rc = kg_fail(&err, KG_EINVAL,
			             "%s: site.residual_relative is %g: the unknown test needs the "
			             "calibration's relative residual (recalibrate, or classify with "
			             "--unknown-threshold none)",
			             calib, cam->residual_relative);
		else
			rc = kg_classify_rows(k, set, &src, &opt, &copt, &info, out, &res, &err);
	}
	if (!rc) {
		if (!quiet) {
			char line[256];
			kg_est_stats_format(&res.stats, line, sizeof(line));
			fprintf(stderr, "classify: %s\n", line);
		}
		printf("%-28s %12s %9s %14s\n", "class", "pixels", "fraction", "median margin");
		printf("%-28s %12llu %8.3f%% %14s\n", "unclassified (flagged)",
		       (unsigned long long)res.unclassified,
		       res.stats.pixels ? 100.0 * (double)res.unclassified / (double)res.stats.pixels
		                        : 0.0,
		       "-");
		for (int j = 0; j < res.nclasses; j++)
			printf("%-28s %12llu %8.3f%% %14.4g\n", res.classes[j].name,
			       (unsigned long long)res.classes[j].pixels, 100.0 * res.classes[j].fraction,
			       res.classes[j].margin_median);
		const uint64_t refused[2] = {res.unknown, res.background};
		const char *refused_name[2] = {"unknown", "background"};
		for (int j = 0; j < 2; j++)
			printf("%-28s %12llu %8.3f%% %14s\n", refused_name[j], (unsigned long long)refused[j],
			       res.stats.pixels ? 100.0 * (double)refused[j] / (double)res.stats.pixels : 0.0,
			       "-");
		char *json = NULL, *png = NULL, *conf = NULL;
		if (kg_apply_side_path(out, ".json", &json, &err) == 0 &&
		    kg_apply_side_path(out, ".png", &png, &err) == 0 &&
		    kg_apply_side_path(out, "_confidence.hdr", &conf, &err) == 0)
		{
			if (camera)
				printf("wrote %s, %s, %s and %s (camera space, %d materials in %d classes, "
				       "%d regions)\n", out, json, png, conf, set->n, res.nclasses,
				       res.nregions);
			else
				printf("wrote %s, %s, %s and %s (%s distance, %d materials at %g degrees)\n",
				       out, json, png, conf, distance, set->n, angle);
		}
		if (!quiet && isfinite(res.unknown_threshold))
			fprintf(stderr,
			        "classify: unknown above %s %.4g (%d degrees of freedom), noise from %s, "
			        "calibration residual %.4g relative\n",
			        camera ? "d2" : "chi2", res.unknown_threshold, res.dof,
			        variance ? variance : "the default model (no --variance)",
			        cam->residual_relative);
		free(json);
		free(png);
		free(conf);
	}
	kg_classify_result_free(&res);
	kg_est_kernel_free(&k);
	kg_image_rows_free(&img);
	free_demosaiced();
	kg_image_rows_free(&var_img);
	kg_image_rows_free(&mask_img);
	kg_image_rows_free(&survey_img);
	kg_image_rows_free(&survey_var);
	kg_image_rows_free(&region_img);
	kg_est_material_set_free(&set);
	kg_material_library_free(&lib);
	kg_camera_calib_free(&cam);
	free(only_copy);
	return rc ? kg_cli_error(&err, rc) : KG_EXIT_OK;
}
