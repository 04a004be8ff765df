#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "kg_calib.h"
#include "kg_sim.h"

static const char usage_reference[] =
	"kogei calib reference --spectra S.cgats|S.csv --rgb P.cgats -o REF.json\n"
	"                      [--field-rgb F.cgats] [--basis K|auto] [--centred]\n"
	"                      [--ridge L] [--noise SIGMA] [--method NAME|auto]\n"
	"                      [--max-cond C] [--exclude ID[,ID...]]\n"
	"                      [--camera CSS.csv --illuminant NAME|FILE]\n"
	"                      [--id-pairing PAIRING] [--max-flare PCT|none] [--keep-flare]\n"
	"                      [--no-neutral-prior]\n"
	"  Reference calibration (docs/architecture.md, step 1). The chart's spectra S\n"
	"  (CGATS SPEC_* fields, or a patch,name,<nm>... CSV table) and the reference\n"
	"  camera's linear RGB rho (RGB_R RGB_G RGB_B) are matched by SAMPLE_ID and\n"
	"  checked by colour: the spectra's XYZ under D65 must fit the RGB through one\n"
	"  3 x 3 matrix (misfit under 35 %), and no patch may fit another's colour far\n"
	"  better than its own; a pairing that does not fit is refused, saying how each\n"
	"  file names its patches and which other pairing fits. --id-pairing states one:\n"
	"  names (default), file-order, grid-order (both files' ids sorted by letter,\n"
	"  then number: A00..D05 with A01..D06), spectra-by-number or rgb-by-number\n"
	"  (that file's ids sorted by number, then letter: A1, B1, .., A2, ..),\n"
	"  number+1, number-1 (the spectra's X<n> with the RGB's X<n+1>, X<n-1>),\n"
	"  letter+1, letter-1. Patches without a partner are listed in a note. Fitted:\n"
	"    pca        B = the K leading right singular vectors of S (--centred: about\n"
	"               the mean spectrum, with an affine M), M = W^T rho (rho^T rho + L I)^-1\n"
	"    linear     A = S^T rho (rho^T rho + L I)^-1 (61 x 3)\n"
	"    wiener     A = E[s rho^T] (E[rho rho^T] + SIGMA^2 I)^-1 over the chart\n"
	"    rootpoly2, rootpoly3  root-polynomial regression (Finlayson et al. 2015)\n"
	"  --basis K (1-8, default 3) or auto: the K with the lowest leave-one-out\n"
	"  spectral RMSE (the smallest within 1 %). --method (default pca) sets the\n"
	"  method estimate uses by default; auto takes the method with the lowest mean\n"
	"  leave-one-out dE00 (CIEDE2000 under D65, the LOO dE00 column); of the methods\n"
	"  within 1 % of it, the first in the order above (the simplest).\n"
	"  --ridge L >= 0 (default 0), --noise SIGMA > 0 (camera noise, 0..1 scale,\n"
	"  default 0.01). rho0, the reference camera's values of the field chart, come\n"
	"  from --field-rgb, else from --rgb. --exclude leaves patches out of both, and so\n"
	"  are the patches chart detection flagged (the field file's FLAGS column: clipped,\n"
	"  glare, a colour that is not the layout's, ...), listed in a note.\n"
	"  Flare (light scattered in the lens): the line through the chart's neutral\n"
	"  patches (chroma under 5) meets zero above the origin; it is measured per\n"
	"  channel as a fraction of white, refused above --max-flare (default 8 %; none:\n"
	"  no limit), and removed from the values before the fit when the chosen\n"
	"  method's leave-one-out dE00 is lower without it (--keep-flare: never).\n"
	"  Neutral prior: when the chosen method estimates a flat grey with more than 5 %\n"
	"  of shape (its neutral tilt) and the chart holds fewer than three neutral\n"
	"  patches, flat greys read through the learned response join the fit\n"
	"  (--no-neutral-prior: never); the chart's patches still validate it.\n"
	"  Refused: clipped (CLIPPED_FRACTION > 0, judged on the sensor's codes, so a value\n"
	"  above 1 after the light field is not clipped; in a file without that column, a\n"
	"  channel >= 0.98) or non-finite patches, near-black field patches (< 0.01),\n"
	"  nearly collinear RGB (as in calib camera; limit C, default 100). Writes\n"
	"  kogei-reference/1 JSON and prints the leave-one-out table.\n"
	"  The file also holds the reference camera's spectral response (for camera-space\n"
	"  material labels): with --camera (its sensitivities, CSV wavelength_nm,r,g,b) and\n"
	"  --illuminant (the chart's light), their product with each channel's exposure\n"
	"  fitted to the chart; without, the smoothest response that fits the chart.";

static const char usage_camera[] =
	"kogei calib camera --reference REF.json --rgb P.cgats -o CAM.json\n"
	"                   [--method NAME] [--max-cond C] [--max-residual R] [--force]\n"
	"                   [--clip-level V] [--black-level V] [--exclude ID[,ID...]]\n"
	"                   [--id-pairing PAIRING]\n"
	"  Site calibration: the site camera's values rho_r of the field chart, matched to\n"
	"  the reference's rho0 by SAMPLE_ID, give M2 = rho0 pinv(rho_r) (SVD). The pairing\n"
	"  is checked by colour as in calib reference (--id-pairing: the same names, with\n"
	"  reference-by-number for rho0's ids; number+1 pairs rho0's X<n> with the site\n"
	"  file's X<n+1>); reference patches the site file lacks are listed. Patches\n"
	"  chart detection flagged (FLAGS: clipped, glare, too few pixels, out of frame,\n"
	"  non-uniform, a colour that is not the layout's) are left out and listed.\n"
	"  Refused, naming the patches: site ids not on the reference's chart, fewer than\n"
	"  3 patches in common or left after the flagged ones, clipped patches (a clipped-\n"
	"  fraction column > 0 when the file has one, judged on the sensor's codes; else a\n"
	"  channel >= V, default 0.98), near-black patches (brightest channel < V,\n"
	"  default 0.01), nearly collinear charts (condition number of rho_r with each\n"
	"  channel scaled to unit RMS above C, default 100: e.g. neutral patches only), a\n"
	"  relative residual ||rho0 - M2 rho_r|| / ||rho0|| above R (default 0.10: good\n"
	"  charts of another camera leave 1.5-3.4 %, patches read in the wrong order or no\n"
	"  chart in view 55 % and more), and a chart of exactly 3 usable patches, whose\n"
	"  residual is 0 whatever was photographed, unless --force. --exclude leaves\n"
	"  patches out.\n"
	"  --method sets the default method of CAM.json (default: the reference's).\n"
	"  The camera that photographed the chart (patch file keywords CAMERA_*, written by\n"
	"  kogei chart detect on a session's capture) is recorded in CAM.json; estimate\n"
	"  and classify refuse images of another camera. Writes kogei-camera/1 JSON (B, M,\n"
	"  M2, A = B M M2, every method's map) and prints the condition number and\n"
	"  residuals.";

/* Split "a,b,c" (--exclude; NULL for none) into a NULL-terminated list (one allocation
 * for the pointers, one for the text). */
static int split_ids(const char *text, char ***out, int *n, kg_err *err)
{
	*out = NULL;
	*n = 0;
	if (!text)
		return 0;
	char *copy = strdup(text);
	int count = 1;
	for (const char *p = text; *p; p++)
		count += *p == ',';
	char **v = calloc((size_t)count + 1, sizeof(char *));
	if (!copy || !v) {
		free(copy);
		free(v);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	int k = 0;
	for (char *save = NULL, *tok = strtok_r(copy, ",", &save); tok;
	     tok = strtok_r(NULL, ",", &save))
		v[k++] = tok;
	if (k == 0)
		free(copy);
	*out = v;
	*n = k;
	return 0;
}

static void free_ids(char ***v)
{
	if (*v && (*v)[0])
		free((*v)[0]);
	free(*v);
	*v = NULL;
}

/* The report goes to standard output, or to standard error when the calibration
 * itself is written there. */
static FILE *report_stream(const char *out)
{
	return strcmp(out, "-") == 0 ? stderr : stdout;
}

/* The patches of either file that found no partner, left out. */
static void note_unpaired(const kg_pairing_record *rec, const char *first,
                          const char *second)
{
	const char *file[2] = {first, second};
	for (int s = 0; s < 2; s++) {
		if (!rec->nunpaired[s])
			continue;
		fprintf(stderr, "kogei: note: %s: %d patch%s paired with nothing in %s, left out:",
		        file[s], rec->nunpaired[s], rec->nunpaired[s] == 1 ? "" : "es",
		        file[1 - s]);
		for (int i = 0; i < rec->nunpaired[s]; i++)
			fprintf(stderr, "%s %s", i ? "," : "", rec->unpaired[s][i]);
		fputc('\n', stderr);
	}
}

/* How the patches were paired and how well their colours agree. */
static void print_pairing(FILE *fp, const kg_pairing_record *rec, const char *first,
                          const char *second)
{
	char name[64];
	kg_id_pairing_name(rec->rule, first, second, name, sizeof(name));
	fprintf(fp, "patch pairing: %d pairs by %s; ", rec->pairs, name);
	if (isnan(rec->misfit))
		fprintf(fp, "%d with usable values, too few to check by colour\n", rec->checked);
	else
		fprintf(fp, "colour misfit %.1f %% over %d (limit %.0f %%)\n", 100 * rec->misfit,
		        rec->checked, 100 * KG_CALIB_PAIR_MAX_MISFIT);
}

/* The training chart's flare and whether removing it validated better. */
static void print_flare(FILE *fp, const kg_reference *ref)
{
	const kg_flare *f = &ref->flare;
	if (!f->found) {
		fprintf(fp, "flare: not measured (%d neutral patches with spectra, from dark to "
		        "light, needed: 3)\n", f->n);
		return;
	}
	fprintf(fp, "flare: the %d neutral patches meet zero at %.2f %% (R), %.2f %% (G), "
	        "%.2f %% (B) of white; ", f->n, 100 * f->white_fraction[0],
	        100 * f->white_fraction[1], 100 * f->white_fraction[2]);
	if (ref->flare_removed)
		fprintf(fp, "removed (leave-one-out dE00 %.3f, kept: %.3f)\n", ref->flare_loo_removed,
		        ref->flare_loo_kept);
	else if (isfinite(ref->flare_loo_removed))
		fprintf(fp, "kept (leave-one-out dE00 %.3f, removed: %.3f, not better)\n",
		        ref->flare_loo_kept, ref->flare_loo_removed);
	else
		fprintf(fp, "kept\n");
}

static void print_reference(FILE *fp, const kg_reference *ref, const char *out)
{
	fprintf(fp, "reference calibration: %d training patches, %d field patches\n", ref->m,
	        ref->k);
	fprintf(fp, "PCA: K = %d (%s), %s; energy %.4f; cond(rho) %.3g, cond(rho0) %.3g\n", ref->K,
	        ref->basis_auto ? "leave-one-out" : "--basis", ref->centred ? "centred" : "uncentred",
	        ref->energy[ref->K - 1], ref->cond_rho, ref->cond_rho0);
	if (ref->nK) {
		fprintf(fp, "leave-one-out spectral RMSE by K:");
		for (int K = 0; K < ref->nK; K++)
			fprintf(fp, " %d:%.5f", K + 1, ref->loo_by_K[K]);
		fputc('\n', fp);
	}
	fprintf(fp, "%-10s %10s %10s %10s %12s\n", "method", "fit RMSE", "LOO RMSE", "LOO dE00",
	        "cond");
	for (int j = 0; j < KG_METHOD_COUNT; j++) {
		const kg_spectral_map *m = &ref->maps[j];
		if (!m->available) {
			fprintf(fp, "%-10s unavailable: %s\n", kg_method_name((kg_method)j), m->note);
			continue;
		}
		fprintf(fp, "%-10s %10.5f %10.5f %10.3f %12.4g%s\n", kg_method_name((kg_method)j),
		        m->fit_rmse, m->loo_rmse, m->loo_de00, m->cond,
		        (kg_method)j == ref->method ? "  <- default" : "");
	}
	double rm = 0, de = 0, demax = 0;
	for (int i = 0; i < ref->m; i++) {
		rm += ref->rmse[i];
		de += ref->de00[i];
		demax = fmax(demax, ref->de00[i]);
	}
	fprintf(fp, "%s on the chart: mean RMSE %.5f, mean dE00 %.3f (max %.3f) under D65\n",
	        kg_method_name(ref->method), rm / ref->m, de / ref->m, demax);
	if (ref->pairing.pairs)
		print_pairing(fp, &ref->pairing, "spectra", "rgb");
	print_flare(fp, ref);
	if (ref->response.available)
		fprintf(fp, "camera response (camera-space labels): from the %s, leave-one-out error "
		        "%.4f relative\n", strcmp(ref->response.source, "camera") ? "chart"
		        : "camera's sensitivities", ref->response.loo_relative);
	if (strcmp(out, "-") != 0)
		fprintf(fp, "wrote %s\n", out);
}

/* What both commands take: --method, --max-cond, --exclude and -o. */
typedef struct shared_args {
	const char *out, *exclude;
	kg_method *method;
	double *max_cond;
} shared_args;

/* 1 when option c is one of the shared ones (*bad: 0, or the usage error's exit code),
 * 0 when not. */
static int shared_option(int c, const char *usage, shared_args *a, int *bad)
{
	kg_err err = {{0}};
	switch (c) {
	case 'o': a->out = optarg; return 1;
	case 'x': a->exclude = optarg; return 1;
	case 'C': *bad = kg_cli_min_option(usage, "--max-cond", optarg, 1, 0, a->max_cond); return 1;
	case 'm':
		if (kg_method_parse(optarg, a->method, &err))
			*bad = kg_cli_usage_error(usage, "--%s", err.msg);
		return 1;
	default: return 0;
	}
}

/* The patches chart detection flagged, left out of a fit (what: "M2", "the fit"). */
static void note_flagged(int n, char *const *ids, const unsigned *flags, const char *rgb,
                         const char *what)
{
	fprintf(stderr, "kogei: note: %s: %d patch%s flagged by chart detection left out of %s:",
	        rgb, n, n == 1 ? "" : "es", what);
	for (int i = 0; i < n; i++)
		fprintf(stderr, "%s %s (flags %u)", i ? "," : "", ids[i], flags[i]);
	fputc('\n', stderr);
}

int kg_cmd_calib_reference(int argc, char **argv)
{
	const char *u = usage_reference;
	const char *spectra = NULL, *rgb = NULL, *field = NULL;
	kg_reference_options opt;
	kg_reference_options_default(&opt);
	shared_args a = {NULL, NULL, &opt.method, &opt.max_cond};
	static const struct option opts[] = {
		{"spectra", required_argument, NULL, 's'},
		{"rgb", required_argument, NULL, 'r'},
		{"field-rgb", required_argument, NULL, 'f'},
		{"basis", required_argument, NULL, 'K'},
		{"centred", no_argument, NULL, 'c'},
		{"ridge", required_argument, NULL, 'l'},
		{"noise", required_argument, NULL, 'n'},
		{"method", required_argument, NULL, 'm'},
		{"max-cond", required_argument, NULL, 'C'},
		{"exclude", required_argument, NULL, 'x'},
		{"camera", required_argument, NULL, 'S'},
		{"illuminant", required_argument, NULL, 'I'},
		{"id-pairing", required_argument, NULL, 'P'},
		{"max-flare", required_argument, NULL, 'F'},
		{"keep-flare", no_argument, NULL, 'k'},
		{"no-neutral-prior", no_argument, NULL, 'N'},
		{"output", required_argument, NULL, 'o'},
		{"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	kg_err err = {{0}};
	const char *camera = NULL, *illuminant = NULL;
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
		double v;
		int bad = 0;
		if (shared_option(c, u, &a, &bad)) {
			if (bad)
				return bad;
			continue;
		}
		switch (c) {
		case 'S': camera = optarg; break;
		case 'I': illuminant = optarg; break;
		case 'P':
			if (kg_id_pairing_parse(optarg, "spectra", "rgb", &opt.id_pairing, &err))
				return kg_cli_usage_error(u, "--id-pairing: %s", err.msg);
			break;
		case 's': spectra = optarg; break;
		case 'r': rgb = optarg; break;
		case 'f': field = optarg; break;
		case 'c': opt.centred = 1; break;
		case 'k': opt.no_flare = 1; break;
		case 'N': opt.no_neutral_prior = 1; break;
		case 'F':
			if (strcmp(optarg, "none") == 0)
				opt.max_flare = INFINITY;
			else if (kg_cli_number(optarg, &v) || !(v > 0) || !(v <= 100))
				return kg_cli_usage_error(u, "--max-flare %s: expected a percentage of white "
				                          "above 0 and at most 100, or none", optarg);
			else
				opt.max_flare = v / 100;
			break;
		case 'K':
			if (strcmp(optarg, "auto") == 0)
				opt.basis = 0;
			else if (kg_cli_number(optarg, &v) || v != floor(v) || v < 1 ||
			         v > KG_CALIB_MAX_BASIS)
				return kg_cli_usage_error(u, "--basis %s: expected an integer 1-%d or auto",
				                          optarg, KG_CALIB_MAX_BASIS);
			else
				opt.basis = (int)v;
			break;
		case 'l': bad = kg_cli_min_option(u, "--ridge", optarg, 0, 0, &opt.ridge); break;
		case 'n': bad = kg_cli_min_option(u, "--noise", optarg, 0, 1, &opt.noise_sigma); break;
		case 'h': puts(u); return KG_EXIT_OK;
		default: return kg_cli_usage_error(u, "bad option");
		}
		if (bad)
			return bad;
	}
	if (optind != argc)
		return kg_cli_usage_error(u, "unexpected argument '%s'", argv[optind]);
	if (!spectra || !rgb || !a.out)
		return kg_cli_usage_error(u, "--spectra, --rgb and -o are required");
	if (!camera != !illuminant)
		return kg_cli_usage_error(u, "--camera and --illuminant go together "
		                          "(the sensitivities and the chart's light)");
	kg_spectrum weights[3];
	if (camera) {
		kg_sim_camera css;
		kg_illuminant *ill = NULL;
		int r = kg_sim_camera_load(camera, 0, &css, &err);
		if (!r)
			r = kg_illuminant_lookup(illuminant, &ill, &err);
		if (r)
			return kg_cli_error(&err, r);
		for (int ch = 0; ch < 3; ch++)
			weights[ch] = kg_spectrum_mul(&css.sens[ch], &ill->spd);
		kg_illuminant_free(&ill);
		opt.camera_weights = weights;
	}

	char **ids;
	if (split_ids(a.exclude, &ids, &opt.nexclude, &err))
		return kg_cli_error(&err, KG_ENOMEM);
	opt.exclude = (const char *const *)ids;
	opt.id_pairing_option = "--id-pairing";
	kg_reference *ref = NULL;
	int ret = kg_reference_fit_files(spectra, rgb, field, &opt, &ref, &err);
	if (!ret)
		ret = kg_reference_save(ref, a.out, &err);
	if (!ret && ref->id_rule[0])
		fprintf(stderr, "kogei: note: %s and %s: patch ids paired as %s\n", spectra, rgb,
		        ref->id_rule);
	if (!ret && ref->nflagged)
		note_flagged(ref->nflagged, ref->flagged_ids, ref->flagged_flags,
		             field ? field : rgb, "the fit");
	if (!ret)
		note_unpaired(&ref->pairing, spectra, rgb);
	if (!ret)
		print_reference(report_stream(a.out), ref, a.out);
	kg_reference_free(&ref);
	free_ids(&ids);
	return ret ? kg_cli_error(&err, ret) : KG_EXIT_OK;
}

static void print_camera(FILE *fp, const kg_camera_calib *cam, const char *out)
{
	fprintf(fp, "site calibration: %d patches; condition number %.4g (unit-RMS channels %.4g), "
	            "rank %d\n",
	        cam->k, cam->cond, cam->cond_equilibrated, cam->rank);
	fprintf(fp, "M2 = [%.6f %.6f %.6f; %.6f %.6f %.6f; %.6f %.6f %.6f]\n", cam->M2[0], cam->M2[1],
	        cam->M2[2], cam->M2[3], cam->M2[4], cam->M2[5], cam->M2[6], cam->M2[7], cam->M2[8]);
	fprintf(fp, "residual rho0 - M2 rho_r: RMS %.5f, relative %.4f\n", cam->residual_rms,
	        cam->residual_relative);
	int worst = 0;
	double wv = -1;
	for (int i = 0; i < cam->k; i++) {
		double v = sqrt(cam->residual[i][0] * cam->residual[i][0] +
		                cam->residual[i][1] * cam->residual[i][1] +
		                cam->residual[i][2] * cam->residual[i][2]);
		if (v > wv) {
			wv = v;
			worst = i;
		}
	}
	fprintf(fp, "largest residual: patch %s (%.5f)\n", cam->ids[worst], wv);
	if (cam->pairing.pairs)
		print_pairing(fp, &cam->pairing, "reference", "rgb");
	fprintf(fp, "default method: %s\n", kg_method_name(cam->method));
	char id[512];
	kg_camera_identity_describe(&cam->identity, id, sizeof(id));
	fprintf(fp, "camera: %s\n", id);
	if (strcmp(out, "-") != 0)
		fprintf(fp, "wrote %s\n", out);
}

int kg_cmd_calib_camera(int argc, char **argv)
{
	const char *u = usage_camera;
	const char *refpath = NULL, *rgb = NULL;
	kg_method method = KG_METHOD_AUTO;
	kg_camera_options opt;
	kg_camera_options_default(&opt);
	shared_args a = {NULL, NULL, &method, &opt.max_cond};
	static const struct option opts[] = {
		{"reference", required_argument, NULL, 'R'},
		{"rgb", required_argument, NULL, 'r'},
		{"method", required_argument, NULL, 'm'},
		{"max-cond", required_argument, NULL, 'C'},
		{"clip-level", required_argument, NULL, 'L'},
		{"black-level", required_argument, NULL, 'B'},
		{"max-residual", required_argument, NULL, 'X'},
		{"force", no_argument, NULL, 'f'},
		{"exclude", required_argument, NULL, 'x'},
		{"id-pairing", required_argument, NULL, 'P'},
		{"output", required_argument, NULL, 'o'},
		{"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	kg_err err = {{0}};
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
		int bad = 0;
		if (shared_option(c, u, &a, &bad)) {
			if (bad)
				return bad;
			continue;
		}
		switch (c) {
		case 'R': refpath = optarg; break;
		case 'r': rgb = optarg; break;
		case 'L':
			bad = kg_cli_min_option(u, "--clip-level", optarg, 0, 1,
			                        &opt.clip_level);
			break;
		case 'B':
			bad = kg_cli_min_option(u, "--black-level", optarg, 0, 0,
			                        &opt.black_level);
			break;
		case 'X':
			bad = kg_cli_min_option(u, "--max-residual", optarg, 0, 1,
			                        &opt.max_residual);
			break;
		case 'f': opt.force = 1; break;
		case 'P':
			if (kg_id_pairing_parse(optarg, "reference", "rgb", &opt.id_pairing, &err))
				return kg_cli_usage_error(u, "--id-pairing: %s", err.msg);
			break;
		case 'h': puts(u); return KG_EXIT_OK;
		default: return kg_cli_usage_error(u, "bad option");
		}
		if (bad)
			return bad;
	}
	if (optind != argc)
		return kg_cli_usage_error(u, "unexpected argument '%s'", argv[optind]);
	if (!refpath || !rgb || !a.out)
		return kg_cli_usage_error(u, "--reference, --rgb and -o are required");

	char **ids;
	if (split_ids(a.exclude, &ids, &opt.nexclude, &err))
		return kg_cli_error(&err, KG_ENOMEM);
	opt.exclude = (const char *const *)ids;
	opt.id_pairing_option = "--id-pairing";
	kg_camera_calib *cam = NULL;
	int ret = kg_camera_fit_files(refpath, rgb, &opt, &cam, &err);
	if (!ret && method != KG_METHOD_AUTO)
		ret = kg_camera_set_method(cam, method, &err);
	if (!ret && cam->id_rule[0])
		fprintf(stderr, "kogei: note: %s: patch ids matched with the reference's as %s\n",
		        rgb, cam->id_rule);
	if (!ret)
		note_unpaired(&cam->pairing, refpath, rgb);
	if (!ret && cam->nflagged)
		note_flagged(cam->nflagged, cam->flagged_ids, cam->flagged_flags, rgb, "M2");
	if (!ret && cam->k == 3)
		fprintf(stderr, "kogei: warning: --force: M2 from exactly 3 patches; its residual is "
		                "0 by construction, so the fit was not checked\n");
	if (!ret)
		ret = kg_camera_save(cam, a.out, &err);
	if (!ret)
		print_camera(report_stream(a.out), cam, a.out);
	kg_camera_calib_free(&cam);
	free_ids(&ids);
	return ret ? kg_cli_error(&err, ret) : KG_EXIT_OK;
}
