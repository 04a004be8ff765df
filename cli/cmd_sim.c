/* kogei sim patches / kogei sim image: argument parsing for the simulator (sim/). */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "kg_sim.h"

static const char patches_usage[] =
    "kogei sim patches --spectra S.cgats|S.csv --camera CSS.csv --illuminant NAME|FILE\n"
    "                  [--noise none|FULLWELL:READ:BITS] [--white-level 0.9] [--seed N]\n"
    "                  [--flare F] [--extrapolate] -o P.cgats";

static const char image_usage[] =
    "kogei sim image [--spectra S.cgats|S.csv] --materials LIB.json [--only a,b,c]\n"
    "                --camera CSS.csv --illuminant NAME|FILE [--angle DEG]\n"
    "                [--patch-size PX] [--gap PX] [--columns N] [--background R]\n"
    "                [--size WxH]\n"
    "                [--depth 8|16|float] [--noise none|FULLWELL:READ:BITS]\n"
    "                [--white-level 0.9] [--seed N] [--extrapolate] -o SCENE.tif\n"
    "                [--truth-cube TRUTH.hdr] [--truth-labels LABELS.hdr]";

static const char common_help[] =
    "  --camera CSS.csv      camera sensitivities, CSV wavelength_nm,r,g,b\n"
    "                        (or demo-site, demo-reference: the demo's cameras)\n"
    "  --illuminant SPEC     D65, D50, A, E, Dnn, <T>K, or a CGATS spectrum, or a CSV\n"
    "                        wavelength_nm,<relative power>\n"
    "  --noise SPEC          'none' (default: exact values) or FULLWELL:READ:BITS:\n"
    "                        Poisson shot noise for a full well of FULLWELL electrons,\n"
    "                        Gaussian read noise of READ electrons rms, clipping at\n"
    "                        full scale and quantisation to BITS (8, 10, 12, 14, 16)\n"
    "  --white-level W       exposure: the perfect diffuser's brightest channel reads\n"
    "                        W on the 0..1 scale (default 0.9)\n"
    "  --seed N              seed of the noise (default 1); same seed, same output\n"
    "  --extrapolate         hold end values of data not covering 400-700 nm\n"
    "                        (refused otherwise)\n";

static void patches_help(void)
{
	printf("usage: %s\n\n"
	       "Simulate a camera's linear readings of reflectance spectra:\n"
	       "rho_c = k sum E(l) R(l) S_c(l) dl over 400-700 nm in 5 nm bands, with k set by\n"
	       "--white-level, then the noise model. Writes CGATS SAMPLE_ID RGB_R RGB_G RGB_B\n"
	       "(0..1 scale) with keywords CAMERA, ILLUMINANT, NOISE, SEED, WHITE_LEVEL.\n\n"
	       "  --spectra FILE        CGATS with SPEC_<nm> fields, or CSV patch,name,<nm>...\n"
	       "%s"
	       "  --flare F             veiling glare: F (0..1) of each channel's reading of the\n"
	       "                        perfect diffuser added to every reading, before the noise\n"
	       "                        (default 0; recorded as keyword FLARE)\n"
	       "  -o P.cgats            output ('-' for standard output)\n",
	       patches_usage, common_help);
}

static void image_help(void)
{
	printf("usage: %s\n\n"
	       "Simulate a camera image of a scene: a grid of square tiles, first the chart\n"
	       "patches of --spectra, then (from a new row) one sample of each material of\n"
	       "the library (or of --only), each pixel read independently through the noise\n"
	       "model. Metals and alloys show their specular reflectance at --angle degrees\n"
	       "of incidence (default 0), i.e. the camera sees the colour signal E R(l, angle).\n\n"
	       "  --spectra FILE        chart patches (CGATS or CSV patch,name,<nm>...)\n"
	       "  --materials LIB       material library (kind metal, alloy, dielectric), a\n"
	       "                        file or \"default\", the bundled library\n"
	       "  --only a,b,c          only these materials, in this order\n"
	       "  --angle DEG           incidence angle for the materials, 0-89 (default 0)\n"
	       "  --patch-size PX       tile side in pixels (default 32)\n"
	       "  --gap PX              background between tiles (default patch-size / 4)\n"
	       "  --columns N           tiles per row (default 6)\n"
	       "  --size WxH            image size, the grid of tiles centred in it (default:\n"
	       "                        the grid's own size)\n"
	       "  --background R        flat reflectance of the background (default 0)\n"
	       "  --depth D             TIFF sample format: 8, 16 (default) or float\n"
	       "%s"
	       "  -o SCENE.tif          the camera image (3 samples, linear, 0..1 scale)\n"
	       "  --truth-cube H.hdr    ENVI float32 cube of each pixel's true reflectance\n"
	       "                        (61 bands 400-700 nm, BSQ)\n"
	       "  --truth-labels H.hdr  ENVI classification map: class 0 'unclassified'\n"
	       "                        (background), then one class per material named as\n"
	       "                        in the library, then one class 'chart' for all\n"
	       "                        patches (when --spectra is given)\n",
	       image_usage, common_help);
}

/* Options both commands share. */
typedef struct sim_args {
	const char *spectra, *camera, *illuminant, *noise, *out;
	const char *white_text; /* as given, for the record */
	double white_level;
	uint64_t seed;
	unsigned flags;
} sim_args;

/* The value of an option, from "--opt VALUE" or "--opt=VALUE"; NULL if argv[*i] is
 * not that option. Sets *missing when the value is absent. */
static const char *option_value(int argc, char **argv, int *i, const char *name,
                                int *missing)
{
	size_t n = strlen(name);
	const char *a = argv[*i];
	if (strncmp(a, name, n) != 0)
		return NULL;
	if (a[n] == '=')
		return a + n + 1;
	if (a[n] != '\0')
		return NULL;
	if (*i + 1 >= argc) {
		*missing = 1;
		return NULL;
	}
	return argv[++*i];
}

/* Take one of the options both commands share at argv[*i] (advancing *i past its
 * value): returns 1 if it was one, else 0. *status is 0, or the exit code of a usage
 * error in it. */
static int shared_option(int argc, char **argv, int *i, const char *usage, sim_args *a,
                         int *status)
{
	int missing = 0;
	const char *v;
	*status = 0;
	if (strcmp(argv[*i], "--extrapolate") == 0) {
		a->flags |= KG_RESAMPLE_EXTRAPOLATE;
		return 1;
	}
	if ((v = option_value(argc, argv, i, "--spectra", &missing)))
		a->spectra = v;
	else if ((v = option_value(argc, argv, i, "--camera", &missing)))
		a->camera = v;
	else if ((v = option_value(argc, argv, i, "--illuminant", &missing)))
		a->illuminant = v;
	else if ((v = option_value(argc, argv, i, "--noise", &missing)))
		a->noise = v;
	else if ((v = option_value(argc, argv, i, "-o", &missing)) ||
	         (!missing && (v = option_value(argc, argv, i, "--output", &missing))))
		a->out = v;
	else if ((v = option_value(argc, argv, i, "--white-level", &missing)))
		a->white_text = v;
	else if ((v = option_value(argc, argv, i, "--seed", &missing)))
		*status = kg_cli_seed_option(usage, v, &a->seed);
	if (missing) {
		*status = kg_cli_usage_error(usage, "%s: expected a value", argv[*i]);
		return 1;
	}
	return v != NULL;
}

/* Check what is required and convert what needs converting. */
static int finish_args(const char *usage, sim_args *a, int need_spectra)
{
	int status = kg_cli_number_option(usage, "--white-level", a->white_text, 1e-6, 1e6,
	                                  &a->white_level);
	if (status)
		return status;
	if (need_spectra && !a->spectra)
		return kg_cli_usage_error(usage, "--spectra is required");
	return kg_cli_required(usage, "--camera", a->camera, "--illuminant", a->illuminant, "-o",
	                       a->out, NULL);
}

static void sim_args_init(sim_args *a)
{
	memset(a, 0, sizeof(*a));
	a->noise = "none";
	a->white_text = "0.9";
	a->seed = 1;
}

int kg_cmd_sim_patches(int argc, char **argv)
{
	if (kg_cli_wants_help(argc, argv)) {
		patches_help();
		return KG_EXIT_OK;
	}
	sim_args a;
	sim_args_init(&a);
	const char *flare_text = "0";
	for (int i = 1; i < argc; i++) {
		int status, missing = 0;
		const char *v;
		if (shared_option(argc, argv, &i, patches_usage, &a, &status)) {
			if (status)
				return status;
			continue;
		}
		if ((v = option_value(argc, argv, &i, "--flare", &missing))) {
			flare_text = v;
			continue;
		}
		if (missing)
			return kg_cli_usage_error(patches_usage, "%s: expected a value", argv[i]);
		return kg_cli_usage_error(patches_usage, "unexpected argument '%s'", argv[i]);
	}
	int status = finish_args(patches_usage, &a, 1);
	double flare = 0;
	if (!status)
		status = kg_cli_number_option(patches_usage, "--flare", flare_text, 0, 1, &flare);
	if (status)
		return status;

	kg_err err = {{0}};
	kg_sim_noise noise;
	int ret = kg_sim_noise_parse(a.noise, &noise, &err);
	if (ret)
		return kg_cli_usage_error(patches_usage, "%s", err.msg);
	kg_sim_capture capture;
	ret = kg_sim_capture_load(&capture, a.camera, a.illuminant, a.white_level, &noise,
	                          a.flags, &err);
	if (ret)
		return kg_cli_error(&err, ret);
	capture.flare = flare;
	kg_patchset *spectra = NULL;
	ret = kg_sim_read_spectra(a.spectra, a.flags, &spectra, &err);
	if (ret)
		return kg_cli_error(&err, ret);

	char noise_text[128], seed_text[32];
	kg_sim_noise_format(&noise, noise_text, sizeof(noise_text));
	snprintf(seed_text, sizeof(seed_text), "%" PRIu64, a.seed);
	const char *keywords[] = {
	    "ORIGINATOR", "kogei sim patches",
	    "DESCRIPTOR", "simulated camera readings (linear, 0..1)",
	    "CAMERA", a.camera,
	    "ILLUMINANT", a.illuminant,
	    "NOISE", noise_text,
	    "SEED", seed_text,
	    "WHITE_LEVEL", a.white_text,
	    "SPECTRA", a.spectra,
	    "FLARE", flare_text,
	    NULL,
	};
	ret = kg_sim_write_patches(a.out, spectra, &capture, a.seed, keywords, &err);
	kg_patchset_free(&spectra);
	if (ret)
		return kg_cli_error(&err, ret);
	return KG_EXIT_OK;
}

int kg_cmd_sim_image(int argc, char **argv)
{
	if (kg_cli_wants_help(argc, argv)) {
		image_help();
		return KG_EXIT_OK;
	}
	sim_args a;
	sim_args_init(&a);
	const char *materials = NULL, *only = NULL, *truth_cube = NULL, *truth_labels = NULL;
	const char *depth_text = "16";
	double angle = 0.0, background = 0.0;
	int tile = 32, gap = -1, columns = 6, width = 0, height = 0;
	for (int i = 1; i < argc; i++) {
		int status = 0, missing = 0;
		const char *v;
		if (shared_option(argc, argv, &i, image_usage, &a, &status)) {
			if (status)
				return status;
			continue;
		}
		if ((v = option_value(argc, argv, &i, "--materials", &missing)))
			materials = v;
		else if ((v = option_value(argc, argv, &i, "--only", &missing)))
			only = v;
		else if ((v = option_value(argc, argv, &i, "--truth-cube", &missing)))
			truth_cube = v;
		else if ((v = option_value(argc, argv, &i, "--truth-labels", &missing)))
			truth_labels = v;
		else if ((v = option_value(argc, argv, &i, "--depth", &missing)))
			depth_text = v;
		else if ((v = option_value(argc, argv, &i, "--angle", &missing)))
			status = kg_cli_number_option(image_usage, "--angle", v, 0.0, 89.0, &angle);
		else if ((v = option_value(argc, argv, &i, "--background", &missing)))
			status = kg_cli_number_option(image_usage, "--background", v, 0.0, 1.0,
			                              &background);
		else if ((v = option_value(argc, argv, &i, "--patch-size", &missing)))
			status = kg_cli_int_option(image_usage, "--patch-size", v, 1, 4096, &tile);
		else if ((v = option_value(argc, argv, &i, "--gap", &missing)))
			status = kg_cli_int_option(image_usage, "--gap", v, 0, 4096, &gap);
		else if ((v = option_value(argc, argv, &i, "--columns", &missing)))
			status = kg_cli_int_option(image_usage, "--columns", v, 1, 1024, &columns);
		else if ((v = option_value(argc, argv, &i, "--size", &missing))) {
			char tail;
			if (sscanf(v, "%dx%d%c", &width, &height, &tail) != 2 || width < 1 ||
			    height < 1 || width > 16384 || height > 16384)
				return kg_cli_usage_error(image_usage, "--size %s: expected WxH, e.g. "
				                          "800x600", v);
		} else if (!missing)
			return kg_cli_usage_error(image_usage, "unexpected argument '%s'", argv[i]);
		if (missing)
			return kg_cli_usage_error(image_usage, "%s: expected a value", argv[i]);
		if (status)
			return status;
	}
	int status = finish_args(image_usage, &a, 0);
	if (status)
		return status;
	if (!a.spectra && !materials)
		return kg_cli_usage_error(image_usage, "expected --materials, --spectra or both");
	if (only && !materials)
		return kg_cli_usage_error(image_usage, "--only needs --materials");
	if (gap < 0)
		gap = tile / 4;

	kg_err err = {{0}};
	kg_sim_noise noise;
	enum kg_sim_depth depth;
	if (kg_sim_noise_parse(a.noise, &noise, &err) != 0 ||
	    kg_sim_depth_parse(depth_text, &depth, &err) != 0)
		return kg_cli_usage_error(image_usage, "%s", err.msg);

	int ret;
	kg_sim_capture capture;
	kg_patchset *chart = NULL;
	kg_sim_material_set *set = NULL;
	kg_sim_scene *scene = NULL;
	ret = kg_sim_capture_load(&capture, a.camera, a.illuminant, a.white_level, &noise,
	                          a.flags, &err);
	if (!ret && a.spectra)
		ret = kg_sim_read_spectra(a.spectra, a.flags, &chart, &err);
	if (!ret && materials)
		ret = kg_sim_material_set_load(materials, only, angle, &set, &err);
	if (!ret) {
		kg_sim_scene_desc d = {
		    .patches = chart ? chart->spectra : NULL,
		    .patch_names = chart ? (const char *const *)chart->ids : NULL,
		    .npatches = chart ? chart->n : 0,
		    .materials = set ? set->reflectance : NULL,
		    .material_names = set ? (const char *const *)set->names : NULL,
		    .nmaterials = set ? set->n : 0,
		    .tile = tile,
		    .gap = gap,
		    .columns = columns,
		    .background = background,
		    .width = width,
		    .height = height,
		};
		ret = kg_sim_scene_new(&d, &capture, a.seed, &scene, &err);
	}
	kg_patchset_free(&chart);
	kg_sim_material_set_free(&set);
	if (ret)
		return kg_cli_error(&err, ret);

	ret = kg_sim_scene_write(scene, a.out, depth, truth_cube, truth_labels, &err);
	kg_sim_scene_free(&scene);
	if (ret)
		return kg_cli_error(&err, ret);
	return KG_EXIT_OK;
}
