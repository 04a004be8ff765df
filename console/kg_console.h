/* console/: the operator's web console (docs/console.md): an HTTP server
 * (libmicrohttpd) serving one page built into the binary, over the library calls of
 * kogei acquire (kg_capture_run), kogei measure --chart (kg_measure_flow_chart) and
 * kogei process (kg_process_run). */
#ifndef KG_CONSOLE_H_PUBLIC
#define KG_CONSOLE_H_PUBLIC

#include <stdio.h>

#include "kg_pipeline.h"

#define KG_CONSOLE_MAX_CAMERAS 8

typedef struct kg_console_options {
	const char *session;      /* the session directory (opened and locked) */
	const char *outdir;       /* kogei process output, served under /out/ */
	const char *spectra_out;  /* the spectrometer chart's CGATS */
	const char *reference;    /* kogei process --reference, or NULL */
	const char *layout;       /* chart layout; NULL: the session's latest chart's */
	const char *spectro;      /* spectrometer URI, or NULL */
	const char *cameras[KG_CONSOLE_MAX_CAMERAS];
	int ncameras;
	int frames;               /* frames per capture offered (0: 10) */
	const char *host;         /* numeric IPv4 or IPv6 address; any but 127.0.0.1 gets a
	                           * token */
	int port;                 /* 0: a free one */
	double header_timeout;    /* s a connection has to send a request in full, from its
	                           * start or its previous answer (0: 10) */
	double send_timeout;      /* s an answer has to move 64 KiB on to the client, else it
	                           * is cut off (0: 10) */
	FILE *announce;           /* the address to open is printed here (NULL: stdout) */
} kg_console_options;

/* Serve until SIGINT or SIGTERM (blocked in every thread; the calling thread waits for
 * them), then stop after the running job. 0, or a KG_E* code with err set; a camera
 * that fails at start sets *device_failure. */
int kg_console_run(const kg_console_options *o, int *device_failure, kg_err *err);

#endif
