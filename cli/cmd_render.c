#include <errno.h>
#include <getopt.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "kg_render.h"
#include "kg_sim.h"

static const char usage_render[] =
	"kogei render --scene SCENE.json -o IMAGE.png [--linear XYZ.tif] [--spp N]\n"
	"             [--wavelengths N|all] [--bounces N] [--threads N] [--seed N]\n"
	"             [--width N] [--height N] [--material NAME] [--preview] [--quiet]\n"
	"             [--camera CSS.csv [--white-level W] [--noise FULLWELL:READ:BITS]]\n"
	"             [--truth-labels LABELS.hdr] [--truth-angle ANGLE.hdr]\n"
	"kogei render --scene SCENE.json --mitsuba SCENE.xml [--material NAME]\n"
	"  Render a scene (docs/render.md, \"format\": \"kogei-scene/1\") spectrally with\n"
	"  Embree: an 8-bit sRGB PNG (white-balanced to the scene's light) and, with\n"
	"  --linear, a 32-bit float TIFF of CIE 1931 XYZ (Y = 1 for a white diffuser lit by\n"
	"  a light of intensity 1). The options override the scene's camera and sampling:\n"
	"  samples per pixel, bands per path (hero wavelengths; 'all' = 61), surface\n"
	"  interactions per path, the seed (same seed, same image, any thread count).\n"
	"  --threads defaults to every core. --material renders the whole mesh in one\n"
	"  library material. --preview traces camera rays only, shaded grey by N.V.\n"
	"  --camera CSS.csv: a camera photograph: --linear holds linear camera RGB, the\n"
	"  radiance weighted by the sensitivities (CSV wavelength_nm,r,g,b covering\n"
	"  400-700 nm) instead of the CIE observer, scaled so a white diffuser lit by the\n"
	"  scene's light at intensity 1 reads W (--white-level, default 0.9) in its\n"
	"  brightest channel; the PNG stays the sRGB preview. --noise adds sim's sensor\n"
	"  noise to it (Poisson shot noise for FULLWELL electrons at full scale, Gaussian\n"
	"  read noise of READ electrons rms, clipping to 0..1, quantisation to BITS = 8, 10,\n"
	"  12, 14 or 16), drawn from --seed. --truth-labels: an ENVI classification map\n"
	"  (uint8) of the library material each pixel's camera rays hit first (class 0\n"
	"  background: nothing, or a mesh part marked \"background\": true; then the\n"
	"  library's materials in its order; a pixel takes its samples' majority).\n"
	"  --truth-angle: an ENVI float32 band of the incidence angle there (degrees\n"
	"  between surface normal and view direction, mean over the pixel's samples of\n"
	"  its class; NaN on background).\n"
	"  --mitsuba SCENE.xml: write the scene for Mitsuba 3 (a spectral variant) instead\n"
	"  of rendering: spectral conductors from the library's n, k, alloys as blends of\n"
	"  their metals, dielectrics as rough plastic, one binary PLY per material in the\n"
	"  folder SCENE/ beside it, the scene's camera, lights and sampling (docs/render.md;\n"
	"  untested by a Mitsuba render).";

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
	const char *camera = NULL, *noise_text = NULL, *white_text = NULL;
	const char *truth_labels = NULL, *truth_angle = NULL, *mitsuba = NULL;
	double white_level = 0.9;
	kg_render_options opt = {0};
	int quiet = 0;
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
		{"camera", required_argument, NULL, 'c'},
		{"white-level", required_argument, NULL, 'L'},
		{"noise", required_argument, NULL, 'N'},
		{"truth-labels", required_argument, NULL, 'T'},
		{"truth-angle", required_argument, NULL, 'A'},
		{"quiet", no_argument, NULL, 'q'},
		{"mitsuba", required_argument, NULL, 'M'},
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
		case 'c': camera = optarg; break;
		case 'L':
			white_text = optarg;
			bad = kg_cli_number_option(usage_render, "--white-level", optarg, 1e-6, 1e6,
			                           &white_level);
			break;
		case 'N': noise_text = optarg; break;
		case 'T': truth_labels = optarg; break;
		case 'A': truth_angle = optarg; break;
		case 'p': opt.mode = KG_RENDER_PREVIEW; break;
		case 'q': quiet = 1; break;
		case 'M': mitsuba = optarg; break;
		case 'n':
			bad = kg_cli_int_option(usage_render, "--spp", optarg, 1, 1000000,
			                        &opt.spp);
			break;
		case 'w':
			if (strcmp(optarg, "all") == 0)
				opt.wavelengths = KG_RENDER_ALL_BANDS;
			else
				bad = kg_cli_int_option(usage_render, "--wavelengths", optarg, 1,
				                        KG_RENDER_ALL_BANDS, &opt.wavelengths);
			break;
		case 'b':
			bad = kg_cli_int_option(usage_render, "--bounces", optarg, 1, 64,
			                        &opt.bounces);
			break;
		case 't':
			bad = kg_cli_int_option(usage_render, "--threads", optarg, 1, 256,
			                        &opt.threads);
			break;
		case 'S':
			bad = kg_cli_seed_option(usage_render, optarg, &opt.seed);
			opt.seed_set = !bad;
			break;
		case 'W':
			bad = kg_cli_int_option(usage_render, "--width", optarg, 1, 16384,
			                        &opt.width);
			break;
		case 'H':
			bad = kg_cli_int_option(usage_render, "--height", optarg, 1, 16384,
			                        &opt.height);
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
	if (mitsuba) {
		if (out || linear || camera || truth_labels || truth_angle || opt.mode || opt.spp ||
		    opt.wavelengths || opt.bounces || opt.seed_set || opt.width || opt.height)
			return kg_cli_usage_error(usage_render, "--mitsuba writes the scene as it is "
			                          "(its camera and sampling; --material and --threads "
			                          "apply): no other option goes with it");
		kg_err err = {{0}};
		kg_scene *scene = NULL;
		int ret = check_output_dir(mitsuba, &err);
		if (!ret)
			ret = kg_scene_load(scene_path, &scene, &err);
		if (!ret && material)
			ret = kg_scene_set_material(scene, material, &err);
		if (!ret)
			ret = kg_scene_write_mitsuba(scene, mitsuba, opt.threads, &err);
		if (!ret && !quiet)
			printf("kogei render: wrote %s (Mitsuba 3)\n", mitsuba);
		kg_scene_free(&scene);
		return ret ? kg_cli_error(&err, ret) : KG_EXIT_OK;
	}
	if (!out)
		return kg_cli_usage_error(usage_render, "-o IMAGE.png is required");
	if (noise_text && !camera)
		return kg_cli_usage_error(usage_render, "--noise: only with --camera (the noise is "
		                          "a camera's)");
	if (white_text && !camera)
		return kg_cli_usage_error(usage_render, "--white-level: only with --camera");

	kg_err err = {{0}};
	kg_sim_noise noise = {0};
	if (noise_text && kg_sim_noise_parse(noise_text, &noise, &err) != 0)
		return kg_cli_usage_error(usage_render, "--noise: %s", err.msg);
	kg_scene *scene = NULL;
	kg_render_result res = {0};
	kg_sim_camera cam;
	kg_sim_capture cap;
	kg_render_stats st;
	progress_state ps = {.last = -1, .tty = isatty(STDERR_FILENO)};
	if (!quiet) {
		opt.progress = progress;
		opt.progress_user = &ps;
	}
	int ret = check_output_dir(out, &err);
	if (!ret && linear)
		ret = check_output_dir(linear, &err);
	if (!ret && truth_labels)
		ret = check_output_dir(truth_labels, &err);
	if (!ret && truth_angle)
		ret = check_output_dir(truth_angle, &err);
	if (!ret)
		ret = kg_scene_load(scene_path, &scene, &err);
	if (!ret && material)
		ret = kg_scene_set_material(scene, material, &err);
	if (!ret && camera) {
		/* sim/'s camera and exposure: the weights k S_c(lambda) dlambda with k set so
		 * the scene's light on a white diffuser reads white_level */
		kg_spectrum light;
		kg_scene_light_spectrum(scene, &light);
		ret = kg_sim_camera_load(camera, 0, &cam, &err);
		if (!ret && (ret = kg_sim_capture_init(&cap, &cam, &light, white_level, &noise, &err)))
			kg_err_prefix(&err, "--camera %s", camera);
		opt.observer = cap.signal_weight;
		opt.want_xyz = 1;
	}
	opt.want_truth = truth_labels || truth_angle;
	if (!ret)
		ret = kg_render_full(scene, &opt, &res, &st, &err);
	if (!ret && camera)
		kg_sim_noise_image(&noise, res.image, st.seed);
	/* every output or none: a failure removes those already written */
	int wrote_linear = 0, wrote_labels = 0, wrote_angle = 0;
	if (!ret && linear && !(ret = kg_render_write_xyz_tiff(res.image, linear, &err)))
		wrote_linear = 1;
	if (!ret && truth_labels &&
	    !(ret = kg_render_truth_write_labels(res.truth, truth_labels, &err)))
		wrote_labels = 1;
	if (!ret && truth_angle &&
	    !(ret = kg_render_truth_write_angle(res.truth, truth_angle, &err)))
		wrote_angle = 1;
	if (!ret)
		ret = kg_render_write_png(res.xyz ? res.xyz : res.image, kg_scene_white(scene), out,
		                          &err);
	if (ret) {
		if (wrote_linear)
			kg_envi_remove_output(linear, 0);
		if (wrote_labels)
			kg_envi_remove_output(truth_labels, 1);
		if (wrote_angle)
			kg_envi_remove_output(truth_angle, 1);
	}
	if (!ret && !quiet) {
		double mrays = (double)(st.rays + st.shadow_rays) / st.render_s / 1e6;
		printf("kogei render: %d x %d, %d spp, %d wavelength%s per path, %d bounce%s, "
		       "%d thread%s: BVH %.3f s, render %.2f s (%.2f Mrays/s)\n", st.width,
		       st.height, st.spp, st.wavelengths, st.wavelengths == 1 ? "" : "s",
		       st.bounces, st.bounces == 1 ? "" : "s", st.threads,
		       st.threads == 1 ? "" : "s", st.build_s, st.render_s, mrays);
		if (camera) {
			char ntext[128];
			kg_sim_noise_format(&noise, ntext, sizeof(ntext));
			printf("kogei render: camera %s, white level %g, noise %s, seed %" PRIu64 "\n",
			       cam.name, white_level, ntext, st.seed);
		}
		printf("kogei render: wrote %s%s%s (white: %s)\n", out, linear ? " and " : "",
		       linear ? linear : "", kg_scene_white_name(scene));
		if (truth_labels || truth_angle)
			printf("kogei render: truth %s%s%s\n", truth_labels ? truth_labels : "",
			       truth_labels && truth_angle ? " and " : "", truth_angle ? truth_angle : "");
	}
	kg_render_result_clear(&res);
	kg_scene_free(&scene);
	return ret ? kg_cli_error(&err, ret) : KG_EXIT_OK;
}
