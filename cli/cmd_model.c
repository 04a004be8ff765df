#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "kg_optics.h"

static const char usage_model[] =
	"kogei model --material NAME [--materials LIB.json] [--angles START:STOP:STEP]\n"
	"            -o TABLE.csv [--plot FIG.png] [--illuminant NAME|FILE]\n"
	"  The reflectance of a library material over wavelength (400-700 nm, 5 nm) and\n"
	"  incidence angle (degrees, default 0:85:5): the paper's Fig. 7. The CSV has the\n"
	"  header wavelength_nm,<angle>,... and one row per band ('-o -' = standard output).\n"
	"  --plot draws it as a heat map with the sRGB colour of the reflected light\n"
	"  (default D65) at each angle. --materials defaults to the bundled library.";

int kg_cmd_model(int argc, char **argv)
{
	const char *name = NULL, *lib_path = NULL, *angles_text = "0:85:5", *out = NULL,
	           *plot = NULL, *ill_name = "D65";
	static const struct option opts[] = {
		{"material", required_argument, NULL, 'm'},
		{"materials", required_argument, NULL, 'l'},
		{"angles", required_argument, NULL, 'a'},
		{"output", required_argument, NULL, 'o'},
		{"plot", required_argument, NULL, 'p'},
		{"illuminant", required_argument, NULL, 'i'},
		{"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "m:l:a:o:p:i:h", opts, NULL)) != -1) {
		switch (c) {
		case 'm': name = optarg; break;
		case 'l': lib_path = optarg; break;
		case 'a': angles_text = optarg; break;
		case 'o': out = optarg; break;
		case 'p': plot = optarg; break;
		case 'i': ill_name = optarg; break;
		case 'h': puts(usage_model); return KG_EXIT_OK;
		default: return kg_cli_usage_error(usage_model, "bad option");
		}
	}
	if (optind != argc)
		return kg_cli_usage_error(usage_model, "unexpected argument '%s'", argv[optind]);
	if (!name)
		return kg_cli_usage_error(usage_model, "--material is required");
	if (!out && !plot)
		return kg_cli_usage_error(usage_model, "expected -o TABLE.csv and/or --plot FIG.png");

	kg_err err = {{0}};
	char *lib_file = NULL;
	kg_material_library *lib = NULL;
	kg_illuminant *ill = NULL;
	double *angles = NULL, *table = NULL;
	int nangles = 0;
	int ret = kg_cli_parse_range(angles_text, &angles, &nangles, &err);
	if (!ret && (angles[0] < 0 || angles[nangles - 1] > 90))
		ret = kg_fail(&err, KG_EINVAL, "--angles %s: expected angles within 0..90 degrees",
		              angles_text);
	if (!ret)
		ret = kg_material_library_resolve(lib_path ? lib_path : "default", &lib_file, &err);
	if (!ret)
		ret = kg_material_library_load(lib_file, &lib, &err);
	const kg_material *mat = NULL;
	if (!ret && !(mat = kg_material_library_find(lib, name))) {
		char known[512] = "";
		for (int i = 0; i < kg_material_library_count(lib); i++) {
			size_t len = strlen(known);
			snprintf(known + len, sizeof(known) - len, "%s%s", i ? ", " : "",
			         kg_material_library_get(lib, i)->name);
		}
		ret = kg_fail(&err, KG_EINVAL, "%s: no material named '%s' (the library has: %s)",
		              lib_file, name, known);
	}
	if (!ret && !(table = malloc(sizeof(double) * KG_NBANDS * nangles)))
		ret = kg_fail(&err, KG_ENOMEM, "out of memory");
	if (!ret)
		ret = kg_model_table(mat, angles, nangles, table, &err);
	if (!ret && out && plot) /* neither output written when the other is an input */
		ret = kg_inputs_check_output(plot, &err);
	if (!ret && out)
		ret = kg_model_table_write_csv(out, angles, nangles, table, &err);
	if (!ret && plot)
		ret = kg_illuminant_lookup(ill_name, &ill, &err);
	if (!ret && plot) {
		char title[160];
		snprintf(title, sizeof(title), "%s: reflectance against wavelength and incidence",
		         mat->name);
		ret = kg_model_figure(plot, title, angles, nangles, table, ill, &err);
	}
	free(angles);
	free(table);
	free(lib_file);
	kg_illuminant_free(&ill);
	kg_material_library_free(&lib);
	return ret ? kg_cli_error(&err, ret) : KG_EXIT_OK;
}
