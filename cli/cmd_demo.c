/* kogei demo: the bundled session replayed, then the same job as kogei process
 * (demo/ does the work over pipeline/; this file parses the command line). */
#include <getopt.h>
#include <stdio.h>

#include "cli.h"
#include "kg_demo.h"

static const char usage_demo[] =
	"kogei demo [-o DIR]\n"
	"  Replays the bundled session (fixtures/demo/session: the CIE test colour chart in\n"
	"  its AprilTag frame photographed by a reference camera under D65 and by a site\n"
	"  camera under A, and the object, a tsuba with inlays in all ten materials of the\n"
	"  library, rendered in a studio under A) into DIR/lab-session and\n"
	"  DIR/site-session, measures the chart's spectra with the simulated\n"
	"  spectrophotometer (DIR/chart_spectra.cgats), then runs kogei process on both:\n"
	"  DIR/lab (the reference calibration) and DIR/site (the site calibration, the\n"
	"  object's cube, labels, scene, render and the operator's report.html). Then it\n"
	"  judges the cube, the labels and their regions against the object's truth\n"
	"  recorded from its render (summary.md, spectra_by_material.png, confusion.png,\n"
	"  object_d65.png), re-renders the object under D65 from the estimated labels\n"
	"  beside its render from the truth with the CIEDE2000 between them\n"
	"  (truth_vs_estimate.png, DIR/rerender), and draws the paper's Fig. 7 for\n"
	"  nami-shibuichi, a swatch sheet of the library under D65 and the object in each\n"
	"  material of Fig. 13 (render_fig13.png); the renders need Embree and are skipped\n"
	"  with a message without it. Default DIR: out/demo.\n"
	"  Needs /usr/share/colord/ref/CIE-TCS.sp (package colord-data).";

int kg_cmd_demo(int argc, char **argv)
{
	static const struct option opts[] = {
		{"output", required_argument, NULL, 'o'},
		{"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	const char *dir = "out/demo";
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
		switch (c) {
		case 'o': dir = optarg; break;
		case 'h': puts(usage_demo); return KG_EXIT_OK;
		default: return kg_cli_usage_error(usage_demo, "bad option");
		}
	}
	if (optind != argc)
		return kg_cli_usage_error(usage_demo, "unexpected argument '%s'", argv[optind]);
	kg_err err = {{0}};
	int ret = kg_demo_run(dir, &err);
	return ret ? kg_cli_error(&err, ret) : KG_EXIT_OK;
}
