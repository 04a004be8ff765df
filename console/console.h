/* kogei console: the operator's web console (docs/console.md). Private to console/:
 * console_http.c (the server, security, files), console_live.c (the live view and
 * the chart check), console_jobs.c (captures, the spectrometer chart, processing). */
#ifndef KG_CONSOLE_H
#define KG_CONSOLE_H

#include <limits.h>
#include <pthread.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/socket.h>

#include <jansson.h>

#include "kg_console.h"

#define CONSOLE_MAX_CAMERAS KG_CONSOLE_MAX_CAMERAS
#define CONSOLE_PREVIEW_SIDE 1024 /* long side of the live preview, at most */
#define CONSOLE_HIST_BINS 64
#define CONSOLE_PER_CLIENT_MAX 16   /* connections from one address */
#define CONSOLE_CONNECTIONS_MAX 256 /* connections in all */
/* slots: also for connections closed but not yet reported closed by the server */
#define CONSOLE_CONN_SLOTS (CONSOLE_CONNECTIONS_MAX + 64)
#define CONSOLE_SEND_FLOOR 65536    /* bytes an answer moves per --send-timeout, at least */

/* A connection, from its start to its close (console_conn.c; docs/console.md,
 * "Security"): waiting for a request (from its start or its last answer), being
 * handled (our code runs), or being sent its answer. */
enum { CONSOLE_CONN_WAIT, CONSOLE_CONN_HANDLE, CONSOLE_CONN_SEND };
typedef struct console_conn {
	int used;
	int closing;            /* shut down: it is served no more */
	int fd;
	unsigned char addr[16]; /* the client's (IPv4 as ::ffff:a.b.c.d) */
	int phase;              /* CONSOLE_CONN_* */
	double since;           /* monotonic: the wait's start, or when the answer last
	                         * moved CONSOLE_SEND_FLOOR bytes on */
	uint64_t acked;         /* bytes the client had acknowledged at that moment */
} console_conn;

typedef struct console {
	/* configuration (read-only once the server runs) */
	char session_dir[PATH_MAX];  /* as given */
	char outdir[PATH_MAX];       /* kogei process output (default DIR.processed) */
	char spectra_out[PATH_MAX];  /* the spectrometer chart (default DIR.chart.cgats) */
	const char *reference;       /* kogei process --reference, or NULL */
	const char *layout;          /* the chart layout (name or file), or NULL */
	const char *spectro_uri;     /* or NULL */
	const char *cameras[CONSOLE_MAX_CAMERAS];
	int ncameras;
	int frames;                  /* default frames per capture */
	char host[64];               /* listen address as written (no brackets) */
	int port;
	int need_token;
	char token[33];
	kg_chart_layout *chart_layout; /* loaded from layout, or NULL */
	double header_timeout;       /* s from a connection's start (or its last answer) to
	                              * its next request received in full */
	double send_timeout;         /* s an answer has to move CONSOLE_SEND_FLOOR bytes on */

	/* connections and their deadlines: conn_lock */
	pthread_mutex_t conn_lock;
	console_conn conns[CONSOLE_CONN_SLOTS];
	int conn_stop;
	long conns_timed_out;        /* at the request deadline */
	long conns_send_timed_out;   /* at the send deadline */
	long conns_evicted;          /* closed for a newcomer */
	long conns_refused;
	pthread_t reaper_thread;

	kg_session *session;         /* open (and locked) for the console's lifetime */

	/* the camera: one at a time, owned by whoever holds cam_lock */
	pthread_mutex_t cam_lock;
	kg_camera *cam;
	int cam_index;
	int streaming;
	/* ranges of exposure_us, gain and iso per camera of the list, once it was opened
	 * (lock) */
	kg_feature_info feat[CONSOLE_MAX_CAMERAS][3];
	int feat_known[CONSOLE_MAX_CAMERAS];

	/* everything below: lock */
	pthread_mutex_t lock;
	pthread_cond_t cond;
	int stop;
	int camera_owned;            /* a capture owns the camera: the live view pauses */
	double last_request;         /* monotonic time the page last asked for a preview */
	/* live view */
	uint64_t live_seq;
	unsigned char *img;          /* the preview as sent: JPEG (PNG without libjpeg) */
	size_t img_size;
	const char *img_type;        /* its Content-Type */
	unsigned char *disp;         /* the preview's 8-bit sRGB pixels (for PNG) */
	int disp_w, disp_h;
	double captured_ms;          /* wall clock (ms since 1970) the frame came from the
	                              * camera driver */
	json_t *live;                /* the preview's numbers */
	char *live_text;             /* the same as compact ASCII JSON (a response header) */
	char live_error[1100];
	double ev;                   /* display exposure scale, stops */
	double roi[4];               /* focus region x0 y0 x1 y1, 0..1 of the frame */
	int have_roi;
	int peaking;
	double preview_ms;           /* server time of the last preview (pop to PNG) */
	double preview_ms_mean;
	long previews;
	/* the manifest as of the last capture (a copy) */
	json_t *manifest;
	/* the job: one at a time */
	pthread_t job_thread;
	int job_joinable;
	int job_running;
	char job_kind[32];           /* "capture", "measure", "process", "deposit" */
	char job_title[128];
	json_t *job_log;             /* lines */
	json_t *job_result;          /* the summary when it ended, or NULL */
	char job_error[1200];
	int job_i, job_n;
	double job_fps;
	/* the spectrometer's prompt while a measurement waits for the operator */
	char prompt[512];
	char allowed[8];
	int waiting;
	int answer;
	/* captures requested by the page */
	pthread_t live_thread;
	pthread_t encode_thread;     /* the live view's second stage (console_live.c) */
	struct live_job *live_job;   /* a binned frame waiting for it (lock) */
} console;

double console_now(void);

/* console_conn.c: a connection that starts (fd, the client's address) gets a slot, or
 * NULL when it is refused (its socket shut down): every connection of its address
 * (CONSOLE_PER_CLIENT_MAX), or of all (CONSOLE_CONNECTIONS_MAX), being handled. At
 * a limit the stalest connection waiting or sending makes room. */
console_conn *console_conn_admit(console *c, int fd, const struct sockaddr *client);
void console_conn_release(console *c, console_conn *k); /* it closed */
/* A request's part comes in: 0 when the connection was closed (serve it no more). */
int console_conn_begin(console *c, console_conn *k);
/* ... handled: `answered` (an answer queued) or its request continues. */
void console_conn_end(console *c, console_conn *k, int answered);
void console_conn_answered(console *c, console_conn *k); /* the answer went out */
/* The reaper: it closes connections past their deadline; stopping it reports what
 * was closed. */
int console_conn_start(console *c);
void console_conn_stop(console *c);

void console_log(console *c, const char *fmt, ...) KG_PRINTF(2, 3); /* with c->lock held */

/* console_live.c */
int console_live_start(console *c, kg_err *err);
void console_live_stop(console *c);
/* The live JSON (a new reference), waiting up to 2 s for a preview after `after`. */
json_t *console_live_json(console *c, uint64_t after);
/* POST /api/view: {"ev", "peaking", "roi"} (each optional), all checked before any is
 * applied; 0, or 400 with *why naming the field. */
int console_view_set(console *c, const json_t *req, char *why, size_t n);
json_t *console_view_json(console *c);
/* The latest preview as a PNG (made on demand, malloc'd), or NULL. */
unsigned char *console_live_png(console *c, size_t *size);
/* A preview newer than `after`, waiting up to 2 s: the image (a copy, malloc'd), its
 * type, number, capture time (ms since 1970) and numbers (compact JSON, malloc'd);
 * NULL when none came. */
typedef struct console_preview {
	unsigned char *data;
	size_t size;
	const char *type;
	uint64_t seq;
	double captured_ms;
	char *live;
} console_preview;
int console_live_preview(console *c, uint64_t after, console_preview *out);
/* Find the chart on a fresh decimated frame: JSON with the overlay and go/no-go. */
json_t *console_chart_check(console *c);
/* Take the camera from the live view (blocks until it is free), give it back. */
void console_camera_take(console *c);
void console_camera_give(console *c);
/* Open camera i of the list (with the camera taken). */
int console_camera_select(console *c, int i, kg_err *err);
json_t *console_settings_json(console *c); /* with the camera taken */
/* The features the page may set, in the order of console.feat. */
extern const kg_feature console_feats[3];
extern const char *const console_feat_keys[3];

/* console_jobs.c */
json_t *console_state_json(console *c);
json_t *console_session_json(console *c);
/* Start a job from the page's request; 0, or an HTTP status with *why set. */
int console_job_capture(console *c, const json_t *req, char *why, size_t n);
int console_job_measure(console *c, const json_t *req, char *why, size_t n);
int console_job_answer(console *c, const json_t *req, char *why, size_t n);
int console_job_process(console *c, const json_t *req, char *why, size_t n);
/* OUTDIR into the bag OUTDIR.bag beside it (kogei deposit's options as JSON keys). */
int console_job_deposit(console *c, const json_t *req, char *why, size_t n);
int console_settings_set(console *c, const json_t *req, char *why, size_t n);
void console_jobs_stop(console *c);
void console_manifest_refresh(console *c); /* with c->lock held */

#include "console_assets.h"

#endif
