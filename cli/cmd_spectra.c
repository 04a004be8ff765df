#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

static const char usage_xyz[] =
	"kogei spectra xyz FILE.cgats [--illuminant NAME|FILE]\n"
	"                  [--range file|paper|observer|LO-HI] [-o OUT.cgats]\n"
	"  CIE 1931 2-degree XYZ and CIELAB of every reflectance spectrum in FILE under the\n"
	"  illuminant (default D65; names D65, D50, A, E, D<nn>, <T>K, or a CGATS .sp file).\n"
	"  The perfect diffuser has Y = 100; CIELAB refers to it over the same range.\n"
	"  --range file   (default) integrate at 1 nm over all the wavelengths FILE gives\n"
	"                 (within the observer's 360-830 nm), the illuminant interpolated\n"
	"                 to them, as CIE 15 does (spec2cie agrees on 360-830 nm data);\n"
	"  --range paper  the station's 61 bands, 400-700 nm every 5 nm (eq. 12 of the\n"
	"                 method, what calibration and rendering use);\n"
	"  --range observer  at 1 nm over 360-830 nm, data held at their end values\n"
	"                 beyond their range (what spec2cie does with shorter data);\n"
	"  --range LO-HI  integrate at 1 nm over LO..HI nm, inside the data.\n"
	"  Output CGATS fields: SAMPLE_ID XYZ_X XYZ_Y XYZ_Z LAB_L LAB_A LAB_B, keywords\n"
	"  INTEGRATION_RANGE_NM (e.g. \"360-830\") and INTEGRATION_STEP_NM (default:\n"
	"  standard output).";

/* The --range argument. */
enum range_kind { RANGE_FILE, RANGE_PAPER, RANGE_OBSERVER, RANGE_LIMITS };

static int parse_range(const char *arg, enum range_kind *kind, double *lo, double *hi)
{
	static const struct {
		const char *name;
		enum range_kind kind;
		double lo, hi;
	} named[] = {
		{"file", RANGE_FILE, NAN, NAN},
		{"paper", RANGE_PAPER, KG_LAMBDA_MIN, KG_LAMBDA_MAX},
		{"observer", RANGE_OBSERVER, KG_CMF_FIRST_NM, KG_CMF_LAST_NM},
	};
	for (size_t i = 0; i < sizeof(named) / sizeof(named[0]); i++)
		if (strcmp(arg, named[i].name) == 0) {
			*kind = named[i].kind;
			*lo = named[i].lo;
			*hi = named[i].hi;
			return 0;
		}
	*kind = RANGE_LIMITS;
	const char *dash = strchr(arg, '-');
	char low[32];
	if (!dash || dash == arg || (size_t)(dash - arg) >= sizeof(low))
		return -1;
	memcpy(low, arg, (size_t)(dash - arg));
	low[dash - arg] = '\0';
	if (kg_cgats_parse_number(low, lo) != 0 || kg_cgats_parse_number(dash + 1, hi) != 0 ||
	    !(*lo < *hi))
		return -1;
	return 0;
}

/* XYZ of every set of the file's first table over lo..hi at the file's own
 * wavelengths: RANGE_FILE sets the limits to the data's range (within the
 * observer's), RANGE_LIMITS must lie inside it, RANGE_OBSERVER holds the end values. */
static int xyz_over_range(const kg_cgats *cg, const char *path, const kg_illuminant *ill,
                          enum range_kind kind, double *lo, double *hi, kg_patchset *res,
                          kg_err *err)
{
	double *wl = NULL, *v = NULL;
	int n = 0;
	int ret = kg_cgats_spectra(cg->tables[0], KG_PATCH_REFLECTANCE, &wl, &v, &n, NULL, err);
	if (!ret && n < 2)
		ret = kg_fail(err, KG_EINVAL, "%s: expected at least 2 SPEC_<nm> fields", path);
	if (!ret && kind == RANGE_FILE) {
		*lo = fmax(wl[0], KG_CMF_FIRST_NM);
		*hi = fmin(wl[n - 1], KG_CMF_LAST_NM);
	} else if (!ret && kind == RANGE_LIMITS &&
	           (*lo < wl[0] - 1e-9 || *hi > wl[n - 1] + 1e-9))
		ret = kg_fail(err, KG_ERANGE, "%s: --range %g-%g: the data cover %g-%g nm: "
		              "expected limits inside them", path, *lo, *hi, wl[0], wl[n - 1]);
	kg_xyz white = kg_illuminant_white_range(ill, *lo, *hi);
	for (int i = 0; !ret && i < res->n; i++) {
		kg_xyz x;
		ret = kg_samples_to_xyz_range(wl, v + (size_t)i * n, n, ill, *lo, *hi, &x, err);
		if (ret) {
			kg_err_prefix(err, "%s: sample %s", path, res->ids[i]);
			break;
		}
		kg_lab l = kg_xyz_to_lab(x, white);
		double row[6] = {x.X, x.Y, x.Z, l.L, l.a, l.b};
		memcpy(res->xyz[i], row, sizeof(res->xyz[i]));
		memcpy(res->lab[i], row + 3, sizeof(res->lab[i]));
	}
	free(wl);
	free(v);
	return ret;
}

int kg_cmd_spectra_xyz(int argc, char **argv)
{
	const char *ill_name = "D65", *out = "-", *range = "file";
	static const struct option opts[] = {
		{"illuminant", required_argument, NULL, 'i'},
		{"range", required_argument, NULL, 'r'},
		{"output", required_argument, NULL, 'o'},
		{"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "i:r:o:h", opts, NULL)) != -1) {
		switch (c) {
		case 'i': ill_name = optarg; break;
		case 'r': range = optarg; break;
		case 'o': out = optarg; break;
		case 'h': puts(usage_xyz); return KG_EXIT_OK;
		default: return kg_cli_usage_error(usage_xyz, "bad option");
		}
	}
	if (optind != argc - 1)
		return kg_cli_usage_error(usage_xyz, "expected one spectra file");
	const char *path = argv[optind];
	enum range_kind kind;
	double lo, hi;
	if (parse_range(range, &kind, &lo, &hi) != 0)
		return kg_cli_usage_error(usage_xyz, "--range: expected file, paper, observer or "
		                          "LO-HI in nm with LO < HI (e.g. 380-780)");
	int grid = kind == RANGE_PAPER;

	kg_err err = {{0}};
	kg_illuminant *ill = NULL;
	kg_cgats *cg = NULL;
	kg_patchset *ps = NULL, *res = NULL;
	int ret = kg_illuminant_lookup(ill_name, &ill, &err);
	if (!ret)
		ret = kg_cgats_read(path, &cg, &err);
	if (!ret)
		ret = kg_patchset_from_cgats(cg, KG_PATCH_REFLECTANCE, &ps, &err);
	if (!ret && !ps->spectra)
		ret = kg_fail(&err, KG_EINVAL, "%s: no spectral fields: expected SPEC_<nm> columns",
		              path);
	if (!ret)
		ret = kg_patchset_new(ps->n, KG_PATCH_XYZ | KG_PATCH_LAB, &res, &err);
	for (int i = 0; !ret && i < ps->n; i++)
		ret = kg_patchset_set_id(res, i, ps->ids[i], &err);
	if (!ret && grid) {
		kg_xyz white = kg_illuminant_white(ill);
		for (int i = 0; i < ps->n; i++) {
			kg_xyz x = kg_reflectance_to_xyz(&ps->spectra[i], ill);
			kg_lab l = kg_xyz_to_lab(x, white);
			double row[6] = {x.X, x.Y, x.Z, l.L, l.a, l.b};
			memcpy(res->xyz[i], row, sizeof(res->xyz[i]));
			memcpy(res->lab[i], row + 3, sizeof(res->lab[i]));
		}
	} else if (!ret)
		ret = xyz_over_range(cg, path, ill, kind, &lo, &hi, res, &err);
	if (!ret) {
		char span[64];
		snprintf(span, sizeof(span), "%g-%g", lo, hi);
		const char *kw[] = {"ILLUMINANT", ill->name, "OBSERVER", "CIE 1931 2 degree",
		                    "INTEGRATION_RANGE_NM", span,
		                    "INTEGRATION_STEP_NM", grid ? "5" : "1",
		                    "ORIGINATOR", "kogei spectra xyz", NULL};
		ret = kg_patchset_write(out, res, KG_PATCH_XYZ | KG_PATCH_LAB, kw, &err);
	}
	kg_cgats_free(&cg);
	kg_patchset_free(&ps);
	kg_patchset_free(&res);
	kg_illuminant_free(&ill);
	return ret ? kg_cli_error(&err, ret) : KG_EXIT_OK;
}
