/* kogei sim chart: a photograph of a chart layout (calib/) rendered by sim/'s chart
 * scene renderer. The layout becomes the plain geometry sim/ draws in
 * chart_scene_glue.c; this file poses the card, renders
 * and writes the image and the truth. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_scene_glue.h"
#include "cli.h"

static const char usage[] =
    "kogei sim chart --layout L [--spectra S.cgats|S.csv] --camera CSS.csv\n"
    "                --illuminant NAME|FILE [--tilt DEG] [--tilt-axis DEG] [--rotate DEG]\n"
    "                [--width W --height H] [--fov DEG] [--fill F] [--blur SIGMA]\n"
    "                [--vignetting V] [--glare] [--occlude tags|patches] [--decoy]\n"
    "                [--paper R] [--ink R] [--background R] [--supersample N]\n"
    "                [--cfa RGGB|BGGR|GRBG|GBRG] [--noise none|FULLWELL:READ:BITS]\n"
    "                [--white-level 0.9] [--depth 8|16|float] [--seed N] [--threads N]\n"
    "                [--extrapolate] -o IMAGE.tif [--truth TRUTH.cgats]";

static void help(void)
{
	printf("usage: %s\n\n"
	       "Render a camera photograph of a printed chart frame: white card, black AprilTags,\n"
	       "the chart's patches, seen through a pinhole camera at a pose, with anti-aliased\n"
	       "edges, lens blur, vignetting, optional glare and occlusion, and sensor noise.\n"
	       "The truth is each patch's noise-free value times the vignetting at its centre:\n"
	       "what a perfect sampler of the patch's inner region reads.\n\n"
	       "  --layout L            chart layout (kogei-chart/1 JSON, ArgyllCMS .cht, or a\n"
	       "                        bundled layout's name, e.g. colorchecker24-frame)\n"
	       "  --spectra FILE        patch reflectances (CGATS SPEC_<nm> or CSV patch,name,<nm>)\n"
	       "                        matched by SAMPLE_ID to the layout's patch ids (or\n"
	       "                        aliases); without it, built-in test colours\n"
	       "  --camera CSS.csv      camera sensitivities, CSV wavelength_nm,r,g,b\n"
	       "                        (or demo-site, demo-reference: the demo's cameras)\n"
	       "  --illuminant SPEC     D65, D50, A, E, Dnn, <T>K, or a CGATS or CSV spectrum\n"
	       "  --tilt DEG            angle between the card's normal and the optical axis,\n"
	       "                        0-75 (default 0)\n"
	       "  --tilt-axis DEG       direction of the tilt axis from the image x axis (30)\n"
	       "  --rotate DEG          in-plane rotation, clockwise (default 0)\n"
	       "  --width W --height H  image size (default 4000 x 3000, 12 Mpix)\n"
	       "  --fov DEG             horizontal field of view (default 40)\n"
	       "  --fill F              the card fills F of the image (tighter side; 0.85)\n"
	       "  --blur SIGMA          Gaussian lens blur in pixels (default 0.7)\n"
	       "  --vignetting V        light lost at the image corners, cos^4 law (0)\n"
	       "  --glare               a specular highlight over part of one patch\n"
	       "  --occlude WHAT        'tags': dark rectangles over two tags; 'patches': one\n"
	       "                        over the first two patches\n"
	       "  --decoy               a second frame with other tag ids beside the chart\n"
	       "  --paper R --ink R     flat reflectances of card and tag black (0.85, 0.03)\n"
	       "  --background R        flat reflectance around the card (0.2)\n"
	       "  --supersample N       samples per side on edge pixels (default 4)\n"
	       "  --cfa PATTERN         write a one-sample raw Bayer mosaic with this pattern\n"
	       "  --noise SPEC          'none' (default) or FULLWELL:READ:BITS (see sim patches)\n"
	       "  --white-level W       the perfect diffuser's brightest channel (0.9)\n"
	       "  --depth D             TIFF samples: 8, 16 (default) or float\n"
	       "  --seed N              noise seed (default 1); same seed, same image\n"
	       "  --threads N           rendering threads (default: all CPUs)\n"
	       "  -o IMAGE.tif          the image (linear, 0..1 scale; .png for 8/16 bit)\n"
	       "  --truth T.cgats       SAMPLE_ID RGB_R RGB_G RGB_B (truth), FLAT_R/G/B (without\n"
	       "                        vignetting), VIGNETTING, PIXEL_X/Y (patch centre),\n"
	       "                        OCCLUDED, GLARE; keyword HOMOGRAPHY (mm -> pixel)\n",
	       usage);
}

typedef struct args {
	const char *layout, *spectra, *camera, *illuminant, *noise, *out, *truth;
	const char *depth, *occlude, *cfa, *white_text;
	double tilt, tilt_axis, rotate, fov, fill, blur, vignetting;
	double paper, ink, background, white_level;
	int width, height, supersample, threads, glare, decoy;
	uint64_t seed;
	unsigned flags;
} args;

static int parse_args(int argc, char **argv, args *a)
{
	memset(a, 0, sizeof(*a));
	a->noise = "none";
	a->depth = "16";
	a->white_text = "0.9";
	a->tilt_axis = 30;
	a->fov = 40;
	a->fill = 0.85;
	a->blur = 0.7;
	a->paper = 0.85;
	a->ink = 0.03;
	a->background = 0.2;
	a->width = 4000;
	a->height = 3000;
	a->supersample = 4;
	a->seed = 1;
	for (int i = 1; i < argc; i++) {
		const char *o = argv[i];
		if (strcmp(o, "--glare") == 0) {
			a->glare = 1;
			continue;
		}
		if (strcmp(o, "--decoy") == 0) {
			a->decoy = 1;
			continue;
		}
		if (strcmp(o, "--extrapolate") == 0) {
			a->flags |= KG_RESAMPLE_EXTRAPOLATE;
			continue;
		}
		if (o[0] != '-' || i + 1 >= argc)
			return kg_cli_usage_error(usage, o[0] == '-' ? "%s: expected a value"
			                                             : "unexpected argument '%s'", o);
		const char *v = argv[++i];
		int st = 0;
		if (!strcmp(o, "--layout"))
			a->layout = v;
		else if (!strcmp(o, "--spectra"))
			a->spectra = v;
		else if (!strcmp(o, "--camera"))
			a->camera = v;
		else if (!strcmp(o, "--illuminant"))
			a->illuminant = v;
		else if (!strcmp(o, "--noise"))
			a->noise = v;
		else if (!strcmp(o, "-o") || !strcmp(o, "--output"))
			a->out = v;
		else if (!strcmp(o, "--truth"))
			a->truth = v;
		else if (!strcmp(o, "--depth"))
			a->depth = v;
		else if (!strcmp(o, "--cfa"))
			a->cfa = v;
		else if (!strcmp(o, "--white-level"))
			st = kg_cli_number_option(usage, o, a->white_text = v, 1e-6, 1e6,
			                          &a->white_level);
		else if (!strcmp(o, "--occlude")) {
			a->occlude = v;
			if (strcmp(v, "tags") && strcmp(v, "patches"))
				return kg_cli_usage_error(usage, "--occlude '%s': expected tags or patches", v);
		} else if (!strcmp(o, "--tilt"))
			st = kg_cli_number_option(usage, o, v, 0, 75, &a->tilt);
		else if (!strcmp(o, "--tilt-axis"))
			st = kg_cli_number_option(usage, o, v, -360, 360, &a->tilt_axis);
		else if (!strcmp(o, "--rotate"))
			st = kg_cli_number_option(usage, o, v, -360, 360, &a->rotate);
		else if (!strcmp(o, "--fov"))
			st = kg_cli_number_option(usage, o, v, 1, 150, &a->fov);
		else if (!strcmp(o, "--fill"))
			st = kg_cli_number_option(usage, o, v, 0.05, 1, &a->fill);
		else if (!strcmp(o, "--blur"))
			st = kg_cli_number_option(usage, o, v, 0, 50, &a->blur);
		else if (!strcmp(o, "--vignetting"))
			st = kg_cli_number_option(usage, o, v, 0, 0.95, &a->vignetting);
		else if (!strcmp(o, "--paper"))
			st = kg_cli_number_option(usage, o, v, 0, 1, &a->paper);
		else if (!strcmp(o, "--ink"))
			st = kg_cli_number_option(usage, o, v, 0, 1, &a->ink);
		else if (!strcmp(o, "--background"))
			st = kg_cli_number_option(usage, o, v, 0, 1, &a->background);
		else if (!strcmp(o, "--width"))
			st = kg_cli_int_option(usage, o, v, 16, 32768, &a->width);
		else if (!strcmp(o, "--height"))
			st = kg_cli_int_option(usage, o, v, 16, 32768, &a->height);
		else if (!strcmp(o, "--supersample"))
			st = kg_cli_int_option(usage, o, v, 1, 16, &a->supersample);
		else if (!strcmp(o, "--threads"))
			st = kg_cli_int_option(usage, o, v, 0, 64, &a->threads);
		else if (!strcmp(o, "--seed"))
			st = kg_cli_seed_option(usage, v, &a->seed);
		else
			return kg_cli_usage_error(usage, "unexpected argument '%s'", o);
		if (st)
			return st;
	}
	if (!a->white_level)
		a->white_level = 0.9;
	return kg_cli_required(usage, "--layout", a->layout, "--camera", a->camera, "--illuminant",
	                       a->illuminant, "-o", a->out, NULL);
}

int kg_cmd_sim_chart(int argc, char **argv)
{
	if (kg_cli_wants_help(argc, argv)) {
		help();
		return KG_EXIT_OK;
	}
	args a;
	int status = parse_args(argc, argv, &a);
	if (status)
		return status;
	kg_err err = {{0}};
	kg_sim_noise noise;
	enum kg_sim_depth depth;
	if (kg_sim_noise_parse(a.noise, &noise, &err) || kg_sim_depth_parse(a.depth, &depth, &err))
		return kg_cli_usage_error(usage, "%s", err.msg);

	kg_chart_layout *layout = NULL;
	kg_patchset *spectra = NULL;
	kg_sim_chart_result *res = NULL;
	kg_sim_chart_card cards[2];
	kg_cli_card_parts parts[2];
	memset(parts, 0, sizeof(parts));
	int ncards = 1 + a.decoy;
	kg_sim_capture capture;
	int ret = kg_sim_capture_load(&capture, a.camera, a.illuminant, a.white_level, &noise,
	                              a.flags, &err);
	if (!ret)
		ret = kg_chart_layout_load(a.layout, &layout, &err);
	if (!ret && a.spectra)
		ret = kg_sim_read_spectra(a.spectra, a.flags, &spectra, &err);
	for (int c = 0; !ret && c < ncards; c++) {
		kg_cli_card_options co = {
		    .paper = a.paper,
		    .ink = a.ink,
		    .white_level = a.white_level,
		    .spectra_name = a.spectra,
		    .decoy = c == 1,
		    .occlude = a.occlude,
		    .glare = a.glare,
		};
		ret = kg_cli_chart_card(layout, spectra, &co, &cards[c], &parts[c], &err);
	}
	kg_sim_chart_desc d = {
	    .width = a.width,
	    .height = a.height,
	    .focal_px = kg_sim_chart_focal_px(a.width, a.fov),
	    .cards = cards,
	    .ncards = ncards,
	    .background = a.background,
	    .supersample = a.supersample,
	    .blur_sigma = a.blur,
	    .vignetting = a.vignetting,
	    .cfa = a.cfa,
	    .threads = a.threads,
	    .seed = a.seed,
	};
	for (int c = 0; !ret && c < ncards; c++) {
		/* Alone: the whole image. With the decoy: the chart on the right half, the
		 * decoy on the left. */
		double box[4] = {0, 0, a.width, a.height};
		if (ncards == 2) {
			box[0] = c == 0 ? 0.5 * a.width : 0;
			box[2] = c == 0 ? a.width : 0.5 * a.width;
		}
		cards[c].pose = (kg_sim_chart_pose){.rotate_deg = a.rotate, .tilt_deg = a.tilt,
		                                    .tilt_axis_deg = a.tilt_axis};
		ret = kg_sim_chart_pose_fit(&cards[c].pose, cards[c].size_mm, d.focal_px, a.width,
		                            a.height, box, ncards == 2 ? 0.9 * a.fill : a.fill, &err);
	}
	if (!ret)
		ret = kg_sim_chart_render(&d, &capture, &res, &err);
	if (!ret)
		ret = kg_image_write(res->image, a.out, (int)depth, &err);
	if (!ret && a.truth) {
		char noise_text[128], seed_text[32], pose_text[128];
		kg_sim_noise_format(&noise, noise_text, sizeof(noise_text));
		snprintf(seed_text, sizeof(seed_text), "%" PRIu64, a.seed);
		snprintf(pose_text, sizeof(pose_text), "tilt %g axis %g rotate %g distance %.6g mm",
		         a.tilt, a.tilt_axis, a.rotate, cards[0].pose.distance_mm);
		const char *keywords[] = {
		    "ORIGINATOR", "kogei sim chart",
		    "LAYOUT", layout->name,
		    "CAMERA", a.camera,
		    "ILLUMINANT", a.illuminant,
		    "NOISE", noise_text,
		    "SEED", seed_text,
		    "POSE", pose_text,
		    NULL,
		};
		ret = kg_sim_chart_write_truth(res, &d, 0, a.truth, keywords, &err);
		if (ret)
			remove(a.out);
	}
	for (int c = 0; c < 2; c++)
		kg_cli_card_parts_free(&parts[c]);
	kg_sim_chart_result_free(&res);
	kg_patchset_free(&spectra);
	kg_chart_layout_free(&layout);
	if (ret)
		return kg_cli_error(&err, ret);
	return KG_EXIT_OK;
}
