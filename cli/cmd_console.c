/* kogei console: the command line of the operator's web console (docs/console.md).
 * Without libmicrohttpd the command is there but says it was left out. */
#include <stdio.h>

#include "cli.h"
#include "kg_config.h"

const char kg_console_usage[] =
	"kogei console --session DIR [--camera URI]... [--spectro URI] [--layout L]\n"
	"              [--listen ADDRESS:PORT] [--out OUTDIR] [--spectra-out FILE]\n"
	"              [--reference REF.json] [--frames N]\n"
	"  The operator's console: a web page served on ADDRESS:PORT (default\n"
	"  127.0.0.1:8080) with the live view of the camera (clipping, histograms, focus\n"
	"  and exposure aids), the chart check, guided dark, flat, chart and object\n"
	"  captures into the session DIR, the spectrometer's guided chart measurement,\n"
	"  kogei process of the session and its report. Open the address printed at start\n"
	"  in a browser on the same machine.\n"
	"  --session DIR       the session (created when absent; locked while the console\n"
	"                      runs: a second console or kogei acquire on it is refused)\n"
	"  --camera URI        a camera (as kogei acquire --camera); repeat it to offer\n"
	"                      several (up to 8), the page switches between them\n"
	"  --spectro URI       the spectrophotometer (as kogei measure --spectro)\n"
	"  --layout L          the chart layout (name or file) for the chart check, chart\n"
	"                      captures and the spectrometer chart (default: the layout of\n"
	"                      the session's latest chart capture)\n"
	"  --listen A:P        address and port; 127.0.0.1 needs no token, any other\n"
	"                      address (::1, 127.0.0.2, a network interface) requires the\n"
	"                      token printed at start on every request; port 0 picks a free\n"
	"                      one\n"
	"  --out OUTDIR        kogei process output, served to the page (default\n"
	"                      DIR.processed next to the session)\n"
	"  --spectra-out FILE  the spectrometer chart's CGATS (default DIR.chart.cgats)\n"
	"  --reference REF     kogei process --reference (a site session); without it the\n"
	"                      measured chart spectra make it a lab session\n"
	"  --frames N          frames per capture offered by the page (default 10)\n"
	"  Stops on Ctrl-C (SIGINT) or SIGTERM, after the job that is running.\n"
	"  Exit 0 stopped, 1 bad input (a session in use, a layout that does not load),\n"
	"  2 bad usage or a kogei built without the console, 3 the camera failed at start.";

#if !HAVE_CONSOLE
int kg_cmd_console(int argc, char **argv)
{
	if (kg_cli_wants_help(argc, argv)) {
		printf("usage: %s\n", kg_console_usage);
		return KG_EXIT_OK;
	}
	fprintf(stderr, "kogei: console: this kogei was built without the console "
	                "(libmicrohttpd was not found: install libmicrohttpd-dev and "
	                "reconfigure with -Dconsole=enabled)\n");
	return KG_EXIT_USAGE;
}
#endif
