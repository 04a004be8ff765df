#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "kg_render.h"

static const char usage_render[] =
	"kogei render --scene SCENE.json -o IMAGE.png [--linear XYZ.tif] [--spp N]\n"
	"             [--wavelengths N|all] [--bounces N] [--threads N] [--seed N]\n"
	"             [--width N] [--height N] [--material NAME] [--preview] [--quiet]\n"
	"  Render a scene (docs/render.md, \"format\": \"kogei-scene/1\") spectrally with\n"
	"  Embree: an 8-bit sRGB PNG (white-balanced to the scene's light) and, with\n"
	"  --linear, a 32-bit float TIFF of CIE 1931 XYZ (Y = 1 for a white diffuser lit by\n"
	"  a light of intensity 1). The options override the scene's camera and sampling:\n"
	"  samples per pixel, bands per path (hero wavelengths; 'all' = 61), surface\n"
	"  interactions per path, the seed (same seed, same image, any thread count).\n"
	"  --threads defaults to every core. --material renders the whole mesh in one\n"
	"  library material. --preview traces camera rays only, shaded grey by N.V.";

typedef struct progress_state {
	int last;
	int tty;
} progress_state;

static void progress(void *user, int done, int total)
{
	progress_state *p = user;
	int pct = (int)(100.0 * done / total);
	if (p->tty) {
		fprintf(stderr, "\rkogei render: %3d%% (%d/%d tiles)", pct, done, total);
		if (done == total)
			fputc('\n', stderr);
	} else if (pct / 10 > p->last / 10 || done == total) {
		fprintf(stderr, "kogei render: %d%% (%d/%d tiles)\n", pct, done, total);
	}
	p->last = pct;
}

static int parse_count(const char *text, const char *what, long min, long max, long *out)
{
	char *end;
	long v = strtol(text, &end, 10);
	if (!*text || *end || v < min || v > max)
		return kg_cli_usage_error(usage_render, "%s %s: expected an integer from %ld to %ld",
		                          what, text, min, max);
	*out = v;
	return 0;
}

/* The folder of an output file must exist before hours of rendering. */
static int check_output_dir(const char *path, kg_err *err)
{
	char *dir = strdup(path);
	if (!dir)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	char *slash = strrchr(dir, '/');
	struct stat st;
	int ret = 0;
	if (slash) {
		*slash = '\0';
		if (*dir && (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode)))
			ret = kg_fail(err, KG_ENOENT, "%s: the folder %s does not exist", path, dir);
	}
	free(dir);
	return ret;
}

int kg_cmd_render(int argc, char **argv)
{
	const char *scene_path = NULL, *out = NULL, *linear = NULL, *material = NULL;
	kg_render_options opt = {0};
	int quiet = 0;
	long v;
	static const struct option opts[] = {
		{"scene", required_argument, NULL, 's'},
		{"output", required_argument, NULL, 'o'},
		{"linear", required_argument, NULL, 'l'},
		{"spp", required_argument, NULL, 'n'},
		{"wavelengths", required_argument, NULL, 'w'},
		{"bounces", required_argument, NULL, 'b'},
		{"threads", required_argument, NULL, 't'},
		{"seed", required_argument, NULL, 'S'},
		{"width", required_argument, NULL, 'W'},
		{"height", required_argument, NULL, 'H'},
		{"material", required_argument, NULL, 'm'},
		{"preview", no_argument, NULL, 'p'},
		{"quiet", no_argument, NULL, 'q'},
		{"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "s:o:qh", opts, NULL)) != -1) {
		int bad = 0;
		switch (c) {
		case 's': scene_path = optarg; break;
		case 'o': out = optarg; break;
		case 'l': linear = optarg; break;
		case 'm': material = optarg; break;
		case 'p': opt.mode = KG_RENDER_PREVIEW; break;
		case 'q': quiet = 1; break;
		case 'n':
			bad = parse_count(optarg, "--spp", 1, 1000000, &v);
			opt.spp = (int)v;
			break;
		case 'w':
			if (strcmp(optarg, "all") == 0)
				opt.wavelengths = KG_RENDER_ALL_BANDS;
			else if (!(bad = parse_count(optarg, "--wavelengths", 1, KG_RENDER_ALL_BANDS, &v)))
				opt.wavelengths = (int)v;
			break;
		case 'b':
			bad = parse_count(optarg, "--bounces", 1, 64, &v);
			opt.bounces = (int)v;
			break;
		case 't':
			bad = parse_count(optarg, "--threads", 1, 256, &v);
			opt.threads = (int)v;
			break;
		case 'S': {
			char *end;
			unsigned long long seed = strtoull(optarg, &end, 10);
			if (!*optarg || *end || optarg[0] == '-')
				return kg_cli_usage_error(usage_render, "--seed %s: expected a whole number "
				                          ">= 0", optarg);
			opt.seed = seed;
			opt.seed_set = 1;
			break;
		}
		case 'W':
			bad = parse_count(optarg, "--width", 1, 16384, &v);
			opt.width = (int)v;
			break;
		case 'H':
			bad = parse_count(optarg, "--height", 1, 16384, &v);
			opt.height = (int)v;
			break;
		case 'h': puts(usage_render); return KG_EXIT_OK;
		default: return kg_cli_usage_error(usage_render, "bad option");
		}
		if (bad)
			return bad;
	}
	if (optind != argc)
		return kg_cli_usage_error(usage_render, "unexpected argument '%s'", argv[optind]);
	if (!scene_path)
		return kg_cli_usage_error(usage_render, "--scene is required");
	if (!out)
		return kg_cli_usage_error(usage_render, "-o IMAGE.png is required");

	kg_err err = {{0}};
	kg_scene *scene = NULL;
	kg_image *xyz = NULL;
	kg_render_stats st;
	progress_state ps = {.last = -1, .tty = isatty(STDERR_FILENO)};
	if (!quiet) {
		opt.progress = progress;
		opt.progress_user = &ps;
	}
	int ret = check_output_dir(out, &err);
	if (!ret && linear)
		ret = check_output_dir(linear, &err);
	if (!ret)
		ret = kg_scene_load(scene_path, &scene, &err);
	if (!ret && material)
		ret = kg_scene_set_material(scene, material, &err);
	if (!ret)
		ret = kg_render(scene, &opt, &xyz, &st, &err);
	if (!ret && linear)
		ret = kg_render_write_xyz_tiff(xyz, linear, &err);
	if (!ret && (ret = kg_render_write_png(xyz, kg_scene_white(scene), out, &err)) && linear)
		unlink(linear); /* both outputs or neither */
	if (!ret && !quiet) {
		double mrays = (double)(st.rays + st.shadow_rays) / st.render_s / 1e6;
		printf("kogei render: %d x %d, %d spp, %d wavelength%s per path, %d bounce%s, "
		       "%d thread%s: BVH %.3f s, render %.2f s (%.2f Mrays/s)\n", st.width,
		       st.height, st.spp, st.wavelengths, st.wavelengths == 1 ? "" : "s",
		       st.bounces, st.bounces == 1 ? "" : "s", st.threads,
		       st.threads == 1 ? "" : "s", st.build_s, st.render_s, mrays);
		printf("kogei render: wrote %s%s%s (white: %s)\n", out, linear ? " and " : "",
		       linear ? linear : "", kg_scene_white_name(scene));
	}
	kg_image_free(&xyz);
	kg_scene_free(&scene);
	return ret ? kg_cli_error(&err, ret) : KG_EXIT_OK;
}
