/* `kogei demo`: the whole pipeline on the bundled default, writing everything a
 * person would look at into one folder. */
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>

#include "cli.h"
#include "kg_optics.h"

static const char usage_demo[] =
	"kogei demo [-o DIR]\n"
	"  Runs the bundled demonstration and writes its outputs to DIR (default out/demo):\n"
	"  the paper's Fig. 7 for nami-shibuichi (table and heat map) and a swatch sheet of\n"
	"  the default material library under D65.";

typedef struct demo_ctx {
	const char *dir;
	kg_err err;
	int nwritten;
} demo_ctx;

static char *demo_path(demo_ctx *d, const char *name)
{
	return kg_path_join(d->dir, name);
}

static void wrote(demo_ctx *d, const char *path, const char *what)
{
	printf("  wrote %-40s %s\n", path, what);
	d->nwritten++;
}

/* The paper's Fig. 7 and the swatch sheet of the library. */
static int demo_materials(demo_ctx *d)
{
	char *lib_path = kg_cli_data_path("materials/default.json");
	char *csv = demo_path(d, "fig7_shibuichi-nami.csv");
	char *png = demo_path(d, "fig7_shibuichi-nami.png");
	char *swatch = demo_path(d, "materials_d65.png");
	kg_material_library *lib = NULL;
	kg_illuminant *d65 = NULL;
	double angles[18], table[KG_NBANDS * 18];
	for (int j = 0; j < 18; j++)
		angles[j] = 5.0 * j;
	int ret = kg_material_library_load(lib_path, &lib, &d->err);
	if (!ret)
		ret = kg_illuminant_by_name("D65", &d65, &d->err);
	const kg_material *m = NULL;
	if (!ret && !(m = kg_material_library_find(lib, "shibuichi-nami")))
		ret = kg_fail(&d->err, KG_EINVAL, "%s: no material 'shibuichi-nami'", lib_path);
	if (!ret)
		ret = kg_model_table(m, angles, 18, table, &d->err);
	if (!ret && !(ret = kg_model_table_write_csv(csv, angles, 18, table, &d->err)))
		wrote(d, csv, "Fig. 7 table: reflectance by wavelength x incidence");
	if (!ret && !(ret = kg_model_figure(png, "shibuichi-nami (Ag 25.0 / Cu 74.9 / Au 0.1)",
	                                    angles, 18, table, d65, &d->err)))
		wrote(d, png, "Fig. 7 heat map with the reflected D65 colour");
	if (!ret && !(ret = kg_swatch_sheet(swatch, lib, d65, &d->err)))
		wrote(d, swatch, "swatches of every library material, normal incidence, D65");
	kg_material_library_free(&lib);
	kg_illuminant_free(&d65);
	free(lib_path);
	free(csv);
	free(png);
	free(swatch);
	return ret;
}

int kg_cmd_demo(int argc, char **argv)
{
	demo_ctx d = {.dir = "out/demo"};
	static const struct option opts[] = {
		{"output", required_argument, NULL, 'o'},
		{"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
		switch (c) {
		case 'o': d.dir = optarg; break;
		case 'h': puts(usage_demo); return KG_EXIT_OK;
		default: return kg_cli_usage_error(usage_demo, "bad option");
		}
	}
	if (optind != argc)
		return kg_cli_usage_error(usage_demo, "unexpected argument '%s'", argv[optind]);
	int ret = kg_mkdir_p(d.dir, &d.err);
	if (!ret) {
		printf("kogei demo: writing to %s/\n", d.dir);
		printf("[1/1] reflection models of the material library\n");
		ret = demo_materials(&d);
	}
	if (ret)
		return kg_cli_error(&d.err, ret);
	printf("kogei demo: done, %d files in %s/\n", d.nwritten, d.dir);
	return KG_EXIT_OK;
}
