#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "kg_calib.h"
#include "kg_config.h"

static const char usage_chart_print[] =
	"kogei chart print --layout L -o TARGET.svg|pdf|png [--dpi N] [--width MM]\n"
	"  The printable frame of a chart layout at true size: its AprilTags, cut marks,\n"
	"  the outline of where the chart goes, the patch ids, a 50 mm scale bar and the\n"
	"  layout's name, on a page 10 mm larger than the frame on every side. L is a\n"
	"  layout file (kogei-chart/1 JSON or an ArgyllCMS .cht) or the name of a bundled\n"
	"  layout (colorchecker24-frame, colorchecker-passport-frame, colorchecker-sg-frame,\n"
	"  cie-tcs-frame).\n"
	"  --dpi sets a PNG's resolution (default 300); --width gives a .cht template's\n"
	"  physical chart width in mm (templates are in scan pixels). Print at 100 %.";

int kg_cmd_chart_print(int argc, char **argv)
{
	const char *layout_arg = NULL, *out = NULL;
	double dpi = 300, width = 0;
	static const struct option opts[] = {
		{"layout", required_argument, NULL, 'l'},
		{"output", required_argument, NULL, 'o'},
		{"dpi", required_argument, NULL, 'd'},
		{"width", required_argument, NULL, 'w'},
		{"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	int c;
	char *end;
	optind = 1;
	while ((c = getopt_long(argc, argv, "l:o:d:w:h", opts, NULL)) != -1) {
		switch (c) {
		case 'l': layout_arg = optarg; break;
		case 'o': out = optarg; break;
		case 'd':
			dpi = strtod(optarg, &end);
			if (end == optarg || *end || !(dpi >= 10 && dpi <= 2400))
				return kg_cli_usage_error(usage_chart_print,
				                          "--dpi %s: expected a number in 10..2400", optarg);
			break;
		case 'w':
			width = strtod(optarg, &end);
			if (end == optarg || *end || !(width > 0 && width < 1e5))
				return kg_cli_usage_error(usage_chart_print,
				                          "--width %s: expected a width in mm", optarg);
			break;
		case 'h': puts(usage_chart_print); return KG_EXIT_OK;
		default: return kg_cli_usage_error(usage_chart_print, "bad option");
		}
	}
	if (optind != argc)
		return kg_cli_usage_error(usage_chart_print, "unexpected argument '%s'", argv[optind]);
	if (!layout_arg)
		return kg_cli_usage_error(usage_chart_print, "--layout is required");
	if (!out)
		return kg_cli_usage_error(usage_chart_print, "-o TARGET.svg|pdf|png is required");
	if (strcmp(out, "-") == 0)
		return kg_cli_usage_error(usage_chart_print,
		                          "-o -: the frame is not text; name a .svg, .pdf or .png file");
	if (!HAVE_APRILTAG) {
		fprintf(stderr, "kogei: chart print needs libapriltag for the frame's tags; this "
		                "kogei was built without it (install libapriltag-dev and rebuild)\n");
		return KG_EXIT_INPUT;
	}

	kg_err err = {{0}};
	char *path = NULL;
	kg_chart_layout *layout = NULL;
	int ret = kg_chart_layout_resolve(layout_arg, &path, &err);
	size_t n = path ? strlen(path) : 0;
	int cht = n >= 4 && strcasecmp(path + n - 4, ".cht") == 0;
	if (!ret && width > 0 && !cht)
		ret = kg_fail(&err, KG_EINVAL, "--width applies to .cht templates only, not %s",
		              path);
	else if (!ret)
		ret = width > 0 ? kg_chart_layout_load_cht(path, width, &layout, &err)
		                : kg_chart_layout_load(path, &layout, &err);
	if (!ret)
		ret = kg_chart_print(layout, out, dpi, &err);
	kg_chart_layout_free(&layout);
	free(path);
	if (ret)
		return kg_cli_error(&err, ret);
	return KG_EXIT_OK;
}
