#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "kg_pipeline.h"

static const char usage_report[] =
	"kogei report OUTDIR\n"
	"  Write OUTDIR/report.html again from OUTDIR/process.json (the record `kogei process`\n"
	"  leaves) and the images it names: one self-contained page (inline style, images\n"
	"  embedded, no network) with the summary and verdicts, the calibration, the colour\n"
	"  accuracy graded against FADGI 4-star and ISO 19264-1 level A, every object\n"
	"  capture, the provenance and the warnings (docs/report.md).";

int kg_cmd_report(int argc, char **argv)
{
	if (kg_cli_wants_help(argc, argv)) {
		puts(usage_report);
		return KG_EXIT_OK;
	}
	const char *outdir = NULL;
	for (int i = 1; i < argc; i++) {
		if (strcmp(argv[i], "--") == 0 && i + 1 < argc && !outdir) {
			outdir = argv[++i];
		} else if (argv[i][0] == '-' && argv[i][1]) {
			return kg_cli_usage_error(usage_report, "unknown option '%s'", argv[i]);
		} else if (outdir) {
			return kg_cli_usage_error(usage_report, "unexpected argument '%s'", argv[i]);
		} else {
			outdir = argv[i];
		}
	}
	if (!outdir)
		return kg_cli_usage_error(usage_report, "expected the output folder OUTDIR");
	kg_err err = {{0}};
	int ret = kg_report_write(outdir, &err);
	if (ret)
		return kg_cli_error(&err, ret);
	printf("%s/report.html\n", outdir);
	return KG_EXIT_OK;
}
