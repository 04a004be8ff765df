/* kogei console: the command line of the operator's web console (docs/console.md).
 * Without libmicrohttpd the command is there but says it was left out. */
#include <getopt.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "kg_config.h"

const char kg_console_usage[] =
	"kogei console --session DIR [--camera URI]... [--spectro URI] [--layout L]\n"
	"              [--listen ADDRESS:PORT] [--out OUTDIR] [--spectra-out FILE]\n"
	"              [--reference REF.json] [--frames N] [--header-timeout S]\n"
	"              [--send-timeout S]\n"
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
	"  --header-timeout S  seconds a connection has to send its request in full, from\n"
	"                      its start or its previous answer (default 10, 0.1..3600)\n"
	"  --send-timeout S    seconds an answer has to move 64 KiB on to the client: one\n"
	"                      the client stopped reading is cut off (default 10,\n"
	"                      0.1..3600); at most 16 connections per client address, 256\n"
	"                      in all, the stalest waiting or stalled one closed for a new\n"
	"                      one\n"
	"  Stops on Ctrl-C (SIGINT) or SIGTERM, after the job that is running.\n"
	"  Exit 0 stopped, 1 bad input (a session in use, a layout that does not load),\n"
	"  2 bad usage or a kogei built without the console, 3 the camera failed at start.";

#if HAVE_CONSOLE
#include "kg_console.h"

typedef struct listen_addr {
	char host[64];
	int port;
} listen_addr;

static int parse_listen(const char *text, listen_addr *c)
{
	const char *colon;
	size_t hn;
	if (text[0] == '[') {
		const char *close = strchr(text, ']');
		if (!close || close[1] != ':')
			return -1;
		hn = (size_t)(close - text - 1);
		text++;
		colon = close + 1;
	} else {
		colon = strrchr(text, ':');
		if (!colon)
			return -1;
		hn = (size_t)(colon - text);
	}
	if (hn == 0 || hn >= sizeof(c->host))
		return -1;
	memcpy(c->host, text, hn);
	c->host[hn] = 0;
	char *end;
	long port = strtol(colon + 1, &end, 10);
	if (*end || colon[1] == 0 || port < 0 || port > 65535)
		return -1;
	c->port = (int)port;
	return 0;
}

/* A deadline in seconds, 0.1..3600. */
static int parse_timeout(const char *text, double *out)
{
	char *end;
	*out = strtod(text, &end);
	return end == text || *end || !(*out >= 0.1 && *out <= 3600) ? -1 : 0;
}

/* The sibling of the session directory: DIR + suffix (a trailing slash dropped). */
static int sibling(const char *dir, const char *suffix, char *out, size_t n)
{
	size_t len = strlen(dir);
	while (len > 1 && dir[len - 1] == '/')
		len--;
	return snprintf(out, n, "%.*s%s", (int)len, dir, suffix) >= (int)n ? -1 : 0;
}

int kg_cmd_console(int argc, char **argv)
{
	if (kg_cli_wants_help(argc, argv)) {
		printf("usage: %s\n", kg_console_usage);
		return KG_EXIT_OK;
	}
	kg_console_options o = {0};
	listen_addr la = {{0}, 0};
	const char *session = NULL, *out = NULL, *spectra_out = NULL, *listen = "127.0.0.1:8080";
	o.frames = 10;
	enum { O_SESSION = 256, O_CAMERA, O_SPECTRO, O_LAYOUT, O_LISTEN, O_OUT, O_SPECTRA_OUT,
	       O_REFERENCE, O_FRAMES, O_HEADER_TIMEOUT, O_SEND_TIMEOUT };
	static const struct option opts[] = {
		{"session", required_argument, NULL, O_SESSION},
		{"camera", required_argument, NULL, O_CAMERA},
		{"spectro", required_argument, NULL, O_SPECTRO},
		{"layout", required_argument, NULL, O_LAYOUT},
		{"listen", required_argument, NULL, O_LISTEN},
		{"out", required_argument, NULL, O_OUT},
		{"spectra-out", required_argument, NULL, O_SPECTRA_OUT},
		{"reference", required_argument, NULL, O_REFERENCE},
		{"frames", required_argument, NULL, O_FRAMES},
		{"header-timeout", required_argument, NULL, O_HEADER_TIMEOUT},
		{"send-timeout", required_argument, NULL, O_SEND_TIMEOUT},
		{NULL, 0, NULL, 0},
	};
	optind = 1;
	opterr = 0;
	int opt;
	while ((opt = getopt_long(argc, argv, ":", opts, NULL)) != -1) {
		char *end;
		switch (opt) {
		case O_SESSION: session = optarg; break;
		case O_CAMERA:
			if (o.ncameras == KG_CONSOLE_MAX_CAMERAS)
				return kg_cli_usage_error(kg_console_usage, "--camera: at most %d cameras",
				                          KG_CONSOLE_MAX_CAMERAS);
			o.cameras[o.ncameras++] = optarg;
			break;
		case O_SPECTRO: o.spectro = optarg; break;
		case O_LAYOUT: o.layout = optarg; break;
		case O_LISTEN: listen = optarg; break;
		case O_OUT: out = optarg; break;
		case O_SPECTRA_OUT: spectra_out = optarg; break;
		case O_REFERENCE: o.reference = optarg; break;
		case O_FRAMES:
			o.frames = (int)strtol(optarg, &end, 10);
			if (*end || o.frames < 1 || o.frames > 10000)
				return kg_cli_usage_error(kg_console_usage, "--frames '%s': expected 1..10000",
				                          optarg);
			break;
		case O_HEADER_TIMEOUT:
		case O_SEND_TIMEOUT:
			if (parse_timeout(optarg, opt == O_SEND_TIMEOUT ? &o.send_timeout
			                                                : &o.header_timeout))
				return kg_cli_usage_error(kg_console_usage, "--%s '%s': expected seconds "
				                          "0.1..3600", opt == O_SEND_TIMEOUT ? "send-timeout"
				                                                             : "header-timeout",
				                          optarg);
			break;
		case ':':
			return kg_cli_usage_error(kg_console_usage, "option %s needs a value",
			                          argv[optind - 1]);
		default:
			return kg_cli_usage_error(kg_console_usage, "unknown option '%s'",
			                          argv[optind - 1]);
		}
	}
	if (optind < argc)
		return kg_cli_usage_error(kg_console_usage, "unexpected argument '%s'", argv[optind]);
	if (!session)
		return kg_cli_usage_error(kg_console_usage, "--session DIR is required");
	if (parse_listen(listen, &la))
		return kg_cli_usage_error(kg_console_usage,
		                          "--listen '%s': expected ADDRESS:PORT (e.g. 127.0.0.1:8080 "
		                          "or [::1]:8080)", listen);
	/* Defaults: siblings of the session directory. */
	char outdir[PATH_MAX], spectra[PATH_MAX];
	if (out ? snprintf(outdir, sizeof(outdir), "%s", out) >= (int)sizeof(outdir)
	        : sibling(session, ".processed", outdir, sizeof(outdir)))
		return kg_cli_usage_error(kg_console_usage, "--out: path too long");
	if (spectra_out ? snprintf(spectra, sizeof(spectra), "%s", spectra_out) >= (int)sizeof(spectra)
	                : sibling(session, ".chart.cgats", spectra, sizeof(spectra)))
		return kg_cli_usage_error(kg_console_usage, "--spectra-out: path too long");
	o.session = session;
	o.outdir = outdir;
	o.spectra_out = spectra;
	o.host = la.host;
	o.port = la.port;
	o.announce = stdout;
	kg_err err = {{0}};
	int device = 0;
	int code = kg_console_run(&o, &device, &err);
	if (code) {
		fprintf(stderr, "kogei: %s\n", err.msg[0] ? err.msg : "console failed");
		return device ? KG_EXIT_DEVICE : KG_EXIT_INPUT;
	}
	return KG_EXIT_OK;
}
#else
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
