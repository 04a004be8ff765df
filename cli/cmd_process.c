/* kogei process: a recorded session to calibration, maps, scenes and the report
 * (pipeline/ does the work; this file parses the command line). */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "kg_pipeline.h"

static const char usage_process[] =
	"kogei process SESSION (--reference REF.json | --spectra CHART.cgats) -o OUTDIR\n"
	"              [--spectra CHART.cgats] [--materials LIB] [--only a,b,c] [--layout L]\n"
	"              [--chart CAPTURE] [--verify CAPTURE] [--mesh M.ply] [--mask MASK.png]\n"
	"              [--method camera|eq11] [--angles A:B[:STEP]] [--intensity LO:HI]\n"
	"              [--angle DEG]\n"
	"              [--min-tags N]\n"
	"              [--max-residual R] [--force] [--assume-same-exposure] [--no-render]\n"
	"              [--skip NAME[,NAME...]]\n"
	"              [--cube f32|f16|weights|none]\n"
	"              [--master-space ecirgb-v2|adobe-rgb|prophoto|none]\n"
	"              [--master-illuminant NAME|FILE]\n"
	"              [--access-compression jpeg|deflate] [--access-quality Q]\n"
	"              [--iiif-base URL] [--iiif-image-api 3|2] [--files-base URL]\n"
	"              [--meta KEY=VALUE]... [--threads N] [--quiet]";

static const char help_process[] =
	"\n"
	"Runs a session recorded by `kogei acquire` end to end: the chart capture (the latest\n"
	"of kind chart, or --chart) dark- and flat-corrected where acquire did not, the chart\n"
	"found and sampled, flagged patches left out, M2 fitted and checked; then every\n"
	"object capture from the same camera, normalised by exposure time x gain to the\n"
	"chart capture's, estimated into a 61-band cube, classified among the declared\n"
	"materials, and given a render scene. Writes into OUTDIR:\n"
	"  camera.json, reference.json (lab session), chart_overlay.png, process.json,\n"
	"  conformance.json, camera.icc + camera.ti3, report.html, and per object capture\n"
	"  <capture>/cube.hdr, labels.hdr (+ .json, .png, _confidence), master.tif,\n"
	"  master_linear.tif (float, linear, diffuse white 1.0), highlights.png,\n"
	"  photo.png, confidence.png, scene.json (renders with `kogei render --scene`),\n"
	"  render.png, object.glb and object_mitsuba.xml (+ PLYs), access.tif (the IIIF\n"
	"  access copy, with libvips) and manifest.json (IIIF Presentation 3).\n"
	"Running it again keeps the objects whose inputs and parameters are unchanged.\n"
	"OUTDIR must be new, empty or this session's earlier output (its process.json), and\n"
	"not inside the session; nothing there that kogei process did not write is replaced,\n"
	"and no input may lie inside what a run replaces. A run is staged in\n"
	"OUTDIR/.kogei-run.PID and put in place only when complete: a failed, interrupted\n"
	"(SIGINT, SIGTERM, SIGHUP: it says what OUTDIR keeps) or killed run leaves OUTDIR's\n"
	"earlier results as they were, and the next run removes its leftovers.\n"
	"\n"
	"  --reference REF.json  the reference calibration (kogei calib reference)\n"
	"  --spectra CHART       the chart's measured spectra (kogei measure --chart): without\n"
	"                        --reference a lab session, whose chart capture gives the\n"
	"                        reference (OUTDIR/reference.json); with it, the colour\n"
	"                        accuracy of the report (else the reference's own spectra)\n"
	"  --materials LIB       material library file or bundled name (default: default)\n"
	"  --only a,b,c          the materials declared for the scene (default: all)\n"
	"  --layout L            chart layout file or bundled name (default: the one the chart\n"
	"                        capture records, acquire --layout)\n"
	"  --chart CAPTURE       the capture that shows the chart (default: the latest chart)\n"
	"  --verify CAPTURE      a second capture of the chart: its patches through the\n"
	"                        calibration grade the colour accuracy (default: leave-one-out)\n"
	"  --mesh M.ply          the object's mesh in the chart's frame (metres) for the\n"
	"                        scenes (default: a plane in the chart's plane)\n"
	"  --mask MASK.png       grey PNG or TIFF of the objects' size: 0 = background\n"
	"                        (kept out of the labels), non-zero = object\n"
	"  --method M            labels by camera-space matching (camera, the default: the\n"
	"                        materials the noise cannot split merged as 'a|b', regions,\n"
	"                        composition, kogei classify --help) or by the paper's\n"
	"                        eq. 11 (eq11)\n"
	"  --angles A:B[:STEP]   camera: incidence angles searched (default 0:70:5)\n"
	"  --intensity LO:HI     camera: intensities searched (default 0.3:1)\n"
	"  --angle DEG           eq11: incidence of the library's spectra (default 30)\n"
	"  --min-tags N          at least N tags place the chart, and no tagless fallback\n"
	"                        (default: 2 tags, or OpenCV mcc for a ColorChecker 24)\n"
	"  --max-residual R      refuse an M2 whose relative residual exceeds R (default\n"
	"                        0.10: good charts leave 1.5-3.4 %, wrong readings 55 % and\n"
	"                        more)\n"
	"  --force               accept a 3-patch chart (uncheckable) and objects from\n"
	"                        another camera than the chart's, with warnings\n"
	"  --assume-same-exposure  an exposure time or gain not recorded for an object or\n"
	"                        the chart is taken as equal (else refused); what is\n"
	"                        recorded still scales the values, with a warning\n"
	"  --meta KEY=VALUE      object record for the run, repeatable (accession, title,\n"
	"                        operator, lighting, notes or a free key of\n"
	"                        [A-Za-z0-9_.-]{1,64}; UTF-8 value up to 4096 bytes, no\n"
	"                        control or invisible/bidirectional format characters):\n"
	"                        process.json \"meta\" is the\n"
	"                        captures' records with these over them; shown at the top\n"
	"                        of report.html\n"
	"  --skip NAME[,NAME]    leave these captures out, as if not in the session (a\n"
	"                        foreign or failed capture; listed in process.json)\n"
	"  --no-render           write scene.json but do not render it\n"
	"  --cube FORMAT         each object's cube.hdr: f32 (default), f16 (half the size),\n"
	"                        weights (the K PCA weights with their basis: s = mean + B w,\n"
	"                        1/20 of f32) or none (labels only)\n"
	"  --master-space SPACE  each object's master.tif, 16-bit RGB with its ICC profile:\n"
	"                        ecirgb-v2 (default), adobe-rgb, prophoto, or none (not\n"
	"                        written); needs LittleCMS and an f32 or f16 cube\n"
	"  --master-illuminant I the master's illuminant: D50 (default), D65, A, D<nn>,\n"
	"                        <T>K or a CGATS spectrum file\n"
	"  --icc-version 2|4     the ICC version of the master's profile and camera.icc:\n"
	"                        2 (default: ArgyllCMS and older software read it) or 4\n"
	"  --threads N           worker threads (default: all)\n"
	"  --quiet               no progress on standard error\n";

/* after the access table's options */
static const char help_process_end[] =
	"\n"
	"Exit status 1 when the session cannot give a trustworthy result (no chart, too few\n"
	"usable patches, M2 residual above the limit, another camera, unknown exposure); the\n"
	"message names the capture or file and the cause, and nothing is written. Warnings\n"
	"(also in process.json and the report) follow the summary line on standard output:\n"
	"an object without a matching dark, a flat applied here that acquire did not, an\n"
	"object under-exposed by more than half, all black, or with over 1 % of its pixels\n"
	"clipped or clamped.";

/* "a,b,c" into a list (the strings point into text, which is modified). */
static int split_names(char *text, const char ***out, int *n)
{
	int cap = 1;
	for (const char *s = text; *s; s++)
		cap += *s == ',';
	const char **v = calloc((size_t)cap, sizeof(*v));
	if (!v)
		return -1;
	int k = 0;
	for (char *tok = strtok(text, ","); tok; tok = strtok(NULL, ","))
		v[k++] = tok;
	*out = v;
	*n = k;
	return 0;
}

/* The run's warnings, as process.json records them (the session's, then each object's,
 * an unchanged object's included), one a line after the summary. */
static void print_warnings(const char *outdir)
{
	char *path = kg_path_join(outdir, "process.json");
	json_t *pj = NULL;
	kg_err e = {{0}};
	if (path && kg_json_load(path, &pj, &e) == 0) {
		const json_t *w;
		size_t i;
		json_array_foreach(json_object_get(pj, "warnings"), i, w)
			if (json_is_string(w))
				printf("kogei process: warning: %s\n", json_string_value(w));
		const json_t *obj;
		size_t k;
		json_array_foreach(json_object_get(pj, "objects"), k, obj)
			json_array_foreach(json_object_get(obj, "warnings"), i, w)
				if (json_is_string(w))
					printf("kogei process: warning: %s\n", json_string_value(w));
	}
	json_decref(pj);
	free(path);
}

static void decref_p(json_t **p) { json_decref(*p); }

int kg_cmd_process(int argc, char **argv)
{
	if (kg_cli_wants_help(argc, argv)) {
		printf("usage: %s\n%s", usage_process, help_process);
		kg_opt_print_options(stdout, &kg_process_access_table);
		printf("%s\n", help_process_end);
		return KG_EXIT_OK;
	}
	enum { O_REF = 256, O_SPECTRA, O_MAT, O_ONLY, O_LAYOUT, O_CHART, O_VERIFY, O_MESH, O_ANGLE,
	       O_MINTAGS, O_MAXRES, O_FORCE, O_SAME, O_NORENDER, O_THREADS, O_QUIET, O_MASK, O_CUBE,
	       O_METHOD, O_ANGLES, O_INTENSITY, O_SKIP, O_META, O_MSPACE, O_MILL, O_ICCV };
	static const struct option baseopts[] = {
		{"reference", required_argument, NULL, O_REF},
		{"spectra", required_argument, NULL, O_SPECTRA},
		{"materials", required_argument, NULL, O_MAT},
		{"only", required_argument, NULL, O_ONLY},
		{"layout", required_argument, NULL, O_LAYOUT},
		{"chart", required_argument, NULL, O_CHART},
		{"verify", required_argument, NULL, O_VERIFY},
		{"mesh", required_argument, NULL, O_MESH},
		{"mask", required_argument, NULL, O_MASK},
		{"cube", required_argument, NULL, O_CUBE},
		{"master-space", required_argument, NULL, O_MSPACE},
		{"icc-version", required_argument, NULL, O_ICCV},
		{"master-illuminant", required_argument, NULL, O_MILL},
		{"angle", required_argument, NULL, O_ANGLE},
		{"method", required_argument, NULL, O_METHOD},
		{"angles", required_argument, NULL, O_ANGLES},
		{"intensity", required_argument, NULL, O_INTENSITY},
		{"min-tags", required_argument, NULL, O_MINTAGS},
		{"max-residual", required_argument, NULL, O_MAXRES},
		{"force", no_argument, NULL, O_FORCE},
		{"assume-same-exposure", no_argument, NULL, O_SAME},
		{"no-render", no_argument, NULL, O_NORENDER},
		{"threads", required_argument, NULL, O_THREADS},
		{"quiet", no_argument, NULL, O_QUIET},
		{"skip", required_argument, NULL, O_SKIP},
		{"meta", required_argument, NULL, O_META},
		{"output", required_argument, NULL, 'o'},
	};
	/* the access copy's and the manifests' options: pipeline/'s table */
	enum { O_TABLE = 1024 };
	const kg_opt_table *at = &kg_process_access_table;
	size_t nbase = sizeof(baseopts) / sizeof(baseopts[0]);
	struct option longopts[sizeof(baseopts) / sizeof(baseopts[0]) + 16];
	if (at->nspecs > 15)
		return kg_cli_usage_error(usage_process, "too many options");
	memcpy(longopts, baseopts, sizeof(baseopts));
	for (int i = 0; i < at->nspecs; i++)
		longopts[nbase + (size_t)i] = (struct option){
			at->specs[i].name,
			at->specs[i].type == KG_OPT_FLAG ? no_argument : required_argument, NULL,
			O_TABLE + i};
	longopts[nbase + (size_t)at->nspecs] = (struct option){NULL, 0, NULL, 0};
	kg_process_options o;
	kg_process_options_default(&o);
	o.progress = stderr;
	json_t *meta __attribute__((cleanup(decref_p))) = json_object();
	o.meta = meta;
	char *only = NULL, *skip = NULL;
	const char **names = NULL, **skips = NULL;
	int quiet = 0, ch;
	optind = 1;
	while ((ch = getopt_long(argc, argv, "o:", longopts, NULL)) != -1) {
		switch (ch) {
		case 'o': o.outdir = optarg; break;
		case O_REF: o.reference = optarg; break;
		case O_SPECTRA: o.spectra = optarg; break;
		case O_MAT: o.materials = optarg; break;
		case O_ONLY: only = optarg; break;
		case O_LAYOUT: o.layout = optarg; break;
		case O_CHART: o.chart = optarg; break;
		case O_VERIFY: o.verify = optarg; break;
		case O_MESH: o.mesh = optarg; break;
		case O_MASK: o.mask = optarg; break;
		case O_CUBE:
			if (strcmp(optarg, "f32") && strcmp(optarg, "f16") && strcmp(optarg, "weights") &&
			    strcmp(optarg, "none"))
				return kg_cli_usage_error(usage_process,
				                          "--cube %s: expected f32, f16, weights or none", optarg);
			o.cube = optarg;
			break;
		case O_MSPACE:
			if (strcmp(optarg, "ecirgb-v2") && strcmp(optarg, "adobe-rgb") &&
			    strcmp(optarg, "prophoto") && strcmp(optarg, "none"))
				return kg_cli_usage_error(usage_process, "--master-space %s: expected ecirgb-v2, "
				                          "adobe-rgb, prophoto or none", optarg);
			o.master_space = optarg;
			break;
		case O_MILL: o.master_illuminant = optarg; break;
		case O_ICCV: {
			kg_icc_version v;
			kg_err verr = {{0}};
			if (kg_icc_version_parse(optarg, &v, &verr))
				return kg_cli_usage_error(usage_process, "--icc-version: %s", verr.msg);
			o.icc_version = optarg;
			break;
		}
		case O_METHOD:
			if (strcmp(optarg, "camera") && strcmp(optarg, "eq11"))
				return kg_cli_usage_error(usage_process, "--method %s: expected camera or eq11",
				                          optarg);
			o.method = optarg;
			break;
		case O_ANGLES: {
			double a[3] = {0, 0, 5};
			int n = kg_cli_parse_numbers(optarg, a, 3);
			if (n < 2 || !(a[0] >= 0 && a[1] >= a[0] && a[1] < 90 && a[2] > 0))
				return kg_cli_usage_error(usage_process, "--angles %s: expected FROM:TO[:STEP] "
				                          "degrees, 0 <= FROM <= TO < 90, STEP > 0", optarg);
			memcpy(o.angles, a, sizeof(a));
			break;
		}
		case O_INTENSITY: {
			double iv[2];
			if (kg_cli_parse_numbers(optarg, iv, 2) != 2 || !(iv[0] > 0 && iv[1] >= iv[0]))
				return kg_cli_usage_error(usage_process, "--intensity %s: expected LO:HI with "
				                          "0 < LO <= HI", optarg);
			o.intensity[0] = iv[0];
			o.intensity[1] = iv[1];
			break;
		}
		case O_ANGLE:
			if (kg_cli_number(optarg, &o.angle_deg) || !(o.angle_deg >= 0 && o.angle_deg < 90))
				return kg_cli_usage_error(usage_process, "--angle %s: expected degrees in "
				                          "0..90", optarg);
			break;
		case O_MINTAGS:
			if (kg_cli_int(optarg, 1, 1000, &o.min_tags))
				return kg_cli_usage_error(usage_process, "--min-tags %s: expected 1..1000",
				                          optarg);
			break;
		case O_MAXRES:
			if (kg_cli_number(optarg, &o.max_residual) ||
			    !(o.max_residual > 0 && o.max_residual < 1))
				return kg_cli_usage_error(usage_process, "--max-residual %s: expected a "
				                          "fraction in (0, 1)", optarg);
			break;
		case O_FORCE: o.force = 1; break;
		case O_SAME: o.assume_same_exposure = 1; break;
		case O_NORENDER: o.render = 0; break;
		case O_THREADS:
			if (kg_cli_int(optarg, 1, 256, &o.threads))
				return kg_cli_usage_error(usage_process, "--threads %s: expected 1..256",
				                          optarg);
			break;
		case O_QUIET: quiet = 1; break;
		case O_META: {
			kg_err me = {{0}};
			if (kg_meta_parse_arg(meta, "--meta", optarg, &me))
				return kg_cli_usage_error(usage_process, "%s", me.msg);
			break;
		}
		case O_SKIP:
			if (!*optarg || strspn(optarg, ",") == strlen(optarg))
				return kg_cli_usage_error(usage_process, "--skip %s: expected capture "
				                          "names, NAME[,NAME...]", optarg);
			skip = optarg;
			break;
		default:
			if (ch >= O_TABLE && ch < O_TABLE + at->nspecs) {
				kg_opt_set(&at->specs[ch - O_TABLE], &o, optarg);
				break;
			}
			return kg_cli_usage_error(usage_process, "bad option");
		}
	}
	if (optind != argc - 1)
		return kg_cli_usage_error(usage_process, optind >= argc ? "expected SESSION"
		                                                        : "expected one SESSION");
	o.session = argv[optind];
	if (!o.outdir)
		return kg_cli_usage_error(usage_process, "-o OUTDIR is required");
	if (!o.reference && !o.spectra)
		return kg_cli_usage_error(usage_process, "--reference REF.json (a site session) or "
		                          "--spectra CHART.cgats (a lab session) is required");
	kg_err aerr = {{0}};
	if (kg_process_access_check(&o, &aerr))
		return kg_cli_usage_error(usage_process, "%s", aerr.msg);
	if (quiet)
		o.progress = NULL;
	if (only && split_names(only, &names, &o.nonly))
		return kg_cli_usage_error(usage_process, "out of memory");
	o.only = names;
	if (skip && split_names(skip, &skips, &o.nskip)) {
		free(names);
		return kg_cli_usage_error(usage_process, "out of memory");
	}
	o.skip = skips;
	kg_err err = {{0}};
	kg_process_summary sum;
	if (kg_process_watch_signals() != 0)
		fprintf(stderr, "kogei process: warning: cannot watch for signals: an interrupted "
		        "run leaves its staging folder to the next run\n");
	int ret = kg_process_run(&o, &sum, &err);
	free(names);
	free(skips);
	if (ret)
		return kg_cli_error(&err, ret);
	printf("kogei process: %s -> %s: %d object(s), %d processed, %d unchanged; M2 residual "
	       "%.2f %%; %d warning(s); %.1f s\n",
	       o.session, o.outdir, sum.objects, sum.processed, sum.skipped, 100 * sum.residual,
	       sum.warnings, sum.seconds);
	print_warnings(o.outdir);
	return KG_EXIT_OK;
}
