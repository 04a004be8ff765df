/* kogei estimate / kogei classify: argument parsing; the camera file becomes a kernel
 * through calib/ (kg_camera_kernel) and estimate/ does the rest (kg_estimate_image,
 * kg_classify_image). */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "kg_calib.h"

static const char usage_estimate[] =
	"kogei estimate --calib CAM.json IMAGE -o CUBE.hdr [--format f32|f16|weights]\n"
	"               [--interleave bsq|bip] [--method NAME|lut|auto] [--lut-size N]\n"
	"               [--threads N] [--block-rows N] [--clip-level V] [--quiet]";

static const char help_estimate[] =
	"\n"
	"Per-pixel spectral reflectance (docs/estimate.md): s = A x(rho) with the\n"
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
	"                       estimated (default 0.999; 'none' disables)\n"
	"  --quiet              no summary line or progress on standard error\n"
	"\n"
	"Flagged pixels (NaN/Inf input, clipped) are NaN in the cube. A summary line on\n"
	"standard error counts pixels, clipped, non-finite and clamped ones; images of\n"
	"4 Mpix or more also report progress. Exit status 1 on bad input (nothing is\n"
	"written), 2 on bad usage.";

static const char usage_classify[] =
	"kogei classify --calib CAM.json --materials LIB.json IMAGE -o LABELS.hdr\n"
	"               [--only a,b,c] [--distance plain|scale-free] [--angle DEG]\n"
	"               [--method pca] [--threads N] [--block-rows N] [--clip-level V]\n"
	"               [--quiet]";

static const char help_classify[] =
	"\n"
	"Material labels (docs/estimate.md, the paper's eq. 11): each pixel\n"
	"gets the material j minimising ||C_j - s||^2 over the declared materials, where\n"
	"C_j is the library reflectance at --angle. Because s = mean + B w lies in the\n"
	"span of the pca basis, this is computed from the K weights w alone:\n"
	"||C_j - s||^2 = ||B^T (C_j - mean) - w||^2 + ||(I - B B^T)(C_j - mean)||^2.\n"
	"\n"
	"  --calib CAM.json     site calibration; its pca map is used (other methods have\n"
	"                       no K-dimensional basis and are refused)\n"
	"  --materials LIB      material library (kogei-materials/1 JSON, or \"default\",\n"
	"                       the bundled library)\n"
	"  --only a,b,c         classify among these library materials only (the scene's\n"
	"                       declared set), in this order; default: all of them\n"
	"  --distance D         plain (default) or scale-free: min over a >= 0 of\n"
	"                       ||a C_j - s||^2, for specular levels that vary with geometry\n"
	"  --angle DEG          incidence angle of the material spectra, 0-90 (default 0)\n"
	"  -o LABELS.hdr        ENVI classification file (LABELS.hdr + LABELS.img;\n"
	"                       class 0 'unclassified' = flagged pixels, then the\n"
	"                       materials), and beside it LABELS.json (classes, pixel\n"
	"                       counts, mean spectra, confidence), LABELS.png (preview;\n"
	"                       flagged pixels grey), LABELS_confidence.hdr (float32: the\n"
	"                       margin to the runner-up) and LABELS_mask.hdr (pixel flags)\n"
	"  --threads, --block-rows, --clip-level, --quiet   as for kogei estimate\n"
	"\n"
	"Prints the classes with their pixel counts and median margins. Exit status 1 on\n"
	"bad input (nothing is written), 2 on bad usage.";

static int parse_int(const char *text, int lo, int hi, int *out)
{
	char *end = NULL;
	long v = strtol(text, &end, 10);
	if (!end || end == text || *end || v < lo || v > hi)
		return -1;
	*out = (int)v;
	return 0;
}

static int parse_clip(const char *text, float *out)
{
	if (strcmp(text, "none") == 0) {
		*out = INFINITY;
		return 0;
	}
	char *end = NULL;
	double v = strtod(text, &end);
	if (!end || end == text || *end || !(v > 0) || !isfinite(v))
		return -1;
	*out = (float)v;
	return 0;
}

/* Options both commands take. Returns 1 when the option was one of them, 0 when not,
 * and KG_EXIT_USAGE (after the message) when its value is bad. */
static int common_option(int c, const char *usage, kg_apply_options *opt, int *quiet)
{
	switch (c) {
	case 't':
		if (parse_int(optarg, 1, 256, &opt->threads))
			return -kg_cli_usage_error(usage, "--threads %s: expected 1 to 256", optarg);
		return 1;
	case 'b':
		if (parse_int(optarg, 1, 1 << 20, &opt->block_rows))
			return -kg_cli_usage_error(usage, "--block-rows %s: expected a positive integer",
			                           optarg);
		return 1;
	case 'c':
		if (parse_clip(optarg, &opt->clip_level))
			return -kg_cli_usage_error(usage, "--clip-level %s: expected a number > 0 or none",
			                           optarg);
		return 1;
	case 'q': *quiet = 1; return 1;
	default: return 0;
	}
}

#define COMMON_LONG_OPTIONS                                                          \
	{"calib", required_argument, NULL, 'C'}, {"threads", required_argument, NULL, 't'}, \
	{"block-rows", required_argument, NULL, 'b'},                                    \
	{"clip-level", required_argument, NULL, 'c'}, {"quiet", no_argument, NULL, 'q'},  \
	{"output", required_argument, NULL, 'o'}, {"help", no_argument, NULL, 'h'}

static int load_image(const char *path, kg_image **img, kg_err *err)
{
	int rc = kg_image_read(path, img, err);
	if (rc)
		return rc;
	if ((*img)->channels != 3) {
		rc = kg_fail(err, KG_EINVAL,
		             "%s: %d channel%s%s: expected a 3-channel linear RGB image%s", path,
		             (*img)->channels, (*img)->channels == 1 ? "" : "s",
		             (*img)->cfa ? " (a raw CFA frame)" : "",
		             (*img)->channels == 1
		                 ? "; a raw Bayer frame must be demosaiced to RGB first"
		                 : "");
		kg_image_free(img);
	}
	return rc;
}

int kg_cmd_estimate(int argc, char **argv)
{
	const char *calib = NULL, *out = NULL;
	const char *format = "f32", *interleave = "bsq", *method = "auto";
	int lut_size = 33, quiet = 0;
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
	while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
		int r = common_option(c, usage_estimate, &opt, &quiet);
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
			if (parse_int(optarg, 2, KG_EST_LUT_MAX_N, &lut_size))
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
	kg_image *img = NULL;
	kg_est_kernel *k = NULL;
	double pre[9];
	int pre_needed = 0;
	kg_est_stats stats;
	int rc = kg_camera_load(calib, &cam, &err);
	if (!rc && (rc = kg_camera_kernel(cam, m, lut ? lut_size : 0, &k, pre, &pre_needed, &err)))
		kg_err_prefix(&err, "%s: ", calib);
	if (!rc && fmt == KG_EST_WEIGHTS && kg_est_kernel_k(k) == 0)
		rc = kg_fail(&err, KG_EINVAL,
		             "%s: --format weights needs the pca method (a K-dimensional basis); "
		             "method %s gives spectra only",
		             calib, lut ? "lut" : kg_method_name(m == KG_METHOD_AUTO ? cam->method : m));
	if (!rc)
		rc = load_image(image, &img, &err);
	if (!rc) {
		char desc[256];
		snprintf(desc, sizeof(desc), "kogei estimate: %s, method %s%s, calibration %s",
		         format, lut ? "lut of " : "",
		         kg_method_name(m == KG_METHOD_AUTO ? cam->method : m), calib);
		for (char *p = desc; *p; p++)
			if (*p == '{' || *p == '}')
				*p = '_';
		opt.description = desc;
		opt.pre = pre_needed ? pre : NULL;
		opt.progress = quiet ? NULL : stderr;
		rc = kg_estimate_image(k, img, fmt, &opt, out, &stats, &err);
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
	kg_est_kernel_free(&k);
	kg_image_free(&img);
	kg_camera_calib_free(&cam);
	return rc ? kg_cli_error(&err, rc) : KG_EXIT_OK;
}

/* Split "a,b,c" in place into at most max names; empty names are refused. */
static int split_names(char *text, char **names, int max, int *n)
{
	*n = 0;
	for (char *p = text;;) {
		char *comma = strchr(p, ',');
		if (comma)
			*comma = '\0';
		if (!*p || *n == max)
			return -1;
		names[(*n)++] = p;
		if (!comma)
			return 0;
		p = comma + 1;
	}
}

int kg_cmd_classify(int argc, char **argv)
{
	const char *calib = NULL, *out = NULL, *library = NULL, *distance = "plain";
	const char *method = "pca";
	char *only = NULL;
	double angle = 0;
	int quiet = 0;
	kg_apply_options opt;
	kg_apply_options_init(&opt);
	static const struct option opts[] = {
		COMMON_LONG_OPTIONS,
		{"materials", required_argument, NULL, 'M'},
		{"only", required_argument, NULL, 'y'},
		{"distance", required_argument, NULL, 'd'},
		{"angle", required_argument, NULL, 'a'},
		{"method", required_argument, NULL, 'm'},
		{0, 0, 0, 0},
	};
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
		int r = common_option(c, usage_classify, &opt, &quiet);
		if (r < 0)
			return -r;
		if (r)
			continue;
		char *end = NULL;
		switch (c) {
		case 'C': calib = optarg; break;
		case 'o': out = optarg; break;
		case 'M': library = optarg; break;
		case 'y': only = optarg; break;
		case 'd': distance = optarg; break;
		case 'm': method = optarg; break;
		case 'a':
			angle = strtod(optarg, &end);
			if (!end || end == optarg || *end || !(angle >= 0 && angle <= 90))
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
	kg_est_distance dist;
	if (strcmp(distance, "plain") == 0)
		dist = KG_EST_DIST_PLAIN;
	else if (strcmp(distance, "scale-free") == 0)
		dist = KG_EST_DIST_SCALE_FREE;
	else
		return kg_cli_usage_error(usage_classify, "--distance %s: expected plain or scale-free",
		                          distance);
	kg_err err = {{0}};
	kg_method m;
	if (kg_method_parse(method, &m, &err))
		return kg_cli_usage_error(usage_classify, "--method: %s", err.msg);
	if (m != KG_METHOD_PCA)
		return kg_cli_error(&err, kg_fail(&err, KG_EINVAL,
		                                  "--method %s: classification works on the K weights of "
		                                  "a basis and only pca has "
		                                  "one; use --method pca",
		                                  method));
	char *only_copy = only ? strdup(only) : NULL;
	char *names[KG_EST_MAX_MATERIALS + 1];
	int nnames = 0;
	if (only && (!only_copy || split_names(only_copy, names, KG_EST_MAX_MATERIALS + 1, &nnames))) {
		free(only_copy);
		return kg_cli_usage_error(usage_classify,
		                          "--only %s: expected material names separated by commas",
		                          only);
	}

	const char *image = argv[optind];
	kg_camera_calib *cam = NULL;
	kg_material_library *lib = NULL;
	kg_est_material_set *set = NULL;
	kg_image *img = NULL;
	kg_est_kernel *k = NULL;
	double pre[9];
	kg_classify_result res = {0};
	int rc = kg_camera_load(calib, &cam, &err);
	if (!rc && (rc = kg_camera_kernel(cam, m, 0, &k, pre, NULL, &err)))
		kg_err_prefix(&err, "%s: ", calib);
	if (!rc)
		rc = kg_material_library_load(library, &lib, &err);
	if (!rc)
		rc = kg_est_material_set_new(lib, library, (const char *const *)names, nnames, angle,
		                             &set, &err);
	if (!rc)
		rc = load_image(image, &img, &err);
	if (!rc) {
		kg_classify_info info = {calib, library, kg_method_name(m), image};
		opt.progress = quiet ? NULL : stderr;
		rc = kg_classify_image(k, set, dist, img, &opt, &info, out, &res, &err);
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
		char *json = NULL, *png = NULL, *conf = NULL;
		if (kg_apply_side_path(out, ".json", &json, &err) == 0 &&
		    kg_apply_side_path(out, ".png", &png, &err) == 0 &&
		    kg_apply_side_path(out, "_confidence.hdr", &conf, &err) == 0)
			printf("wrote %s, %s, %s and %s (%s distance, %d materials at %g degrees)\n", out,
			       json, png, conf, distance, set->n, angle);
		free(json);
		free(png);
		free(conf);
	}
	kg_classify_result_free(&res);
	kg_est_kernel_free(&k);
	kg_image_free(&img);
	kg_est_material_set_free(&set);
	kg_material_library_free(&lib);
	kg_camera_calib_free(&cam);
	free(only_copy);
	return rc ? kg_cli_error(&err, rc) : KG_EXIT_OK;
}
