#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>

#include "cli.h"

static const char usage_xyz[] =
	"kogei spectra xyz FILE.cgats [--illuminant NAME|FILE] [-o OUT.cgats]\n"
	"  CIE 1931 2-degree XYZ and CIELAB of every reflectance spectrum in FILE under the\n"
	"  illuminant (default D65; names D65, D50, A, E, D<nn>, <T>K, or a CGATS .sp file).\n"
	"  The perfect diffuser has Y = 100. Output CGATS fields:\n"
	"  SAMPLE_ID XYZ_X XYZ_Y XYZ_Z LAB_L LAB_A LAB_B (default: standard output).";

int kg_cmd_spectra_xyz(int argc, char **argv)
{
	const char *ill_name = "D65", *out = "-";
	static const struct option opts[] = {
		{"illuminant", required_argument, NULL, 'i'},
		{"output", required_argument, NULL, 'o'},
		{"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "i:o:h", opts, NULL)) != -1) {
		switch (c) {
		case 'i': ill_name = optarg; break;
		case 'o': out = optarg; break;
		case 'h': puts(usage_xyz); return KG_EXIT_OK;
		default: return kg_cli_usage_error(usage_xyz, "bad option");
		}
	}
	if (optind != argc - 1)
		return kg_cli_usage_error(usage_xyz, "expected one spectra file");
	const char *path = argv[optind];

	kg_err err = {{0}};
	kg_illuminant *ill = NULL;
	kg_patchset *ps = NULL, *res = NULL;
	int ret = kg_illuminant_lookup(ill_name, &ill, &err);
	if (!ret)
		ret = kg_patchset_read(path, 0, &ps, &err);
	if (!ret && !ps->spectra)
		ret = kg_fail(&err, KG_EINVAL, "%s: no spectral fields: expected SPEC_<nm> columns",
		              path);
	if (!ret)
		ret = kg_patchset_new(ps->n, KG_PATCH_XYZ | KG_PATCH_LAB, &res, &err);
	kg_xyz white = ill ? kg_illuminant_white(ill) : (kg_xyz){0, 0, 0};
	for (int i = 0; !ret && i < ps->n; i++) {
		kg_xyz x = kg_reflectance_to_xyz(&ps->spectra[i], ill);
		kg_lab l = kg_xyz_to_lab(x, white);
		res->xyz[i][0] = x.X;
		res->xyz[i][1] = x.Y;
		res->xyz[i][2] = x.Z;
		res->lab[i][0] = l.L;
		res->lab[i][1] = l.a;
		res->lab[i][2] = l.b;
		ret = kg_patchset_set_id(res, i, ps->ids[i], &err);
	}
	if (!ret) {
		const char *kw[] = {"ILLUMINANT", ill->name, "OBSERVER", "CIE 1931 2 degree",
		                    "ORIGINATOR", "kogei spectra xyz", NULL};
		ret = kg_patchset_write(out, res, KG_PATCH_XYZ | KG_PATCH_LAB, kw, &err);
	}
	kg_patchset_free(&ps);
	kg_patchset_free(&res);
	kg_illuminant_free(&ill);
	return ret ? kg_cli_error(&err, ret) : KG_EXIT_OK;
}
