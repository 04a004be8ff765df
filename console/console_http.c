/* kogei console: the HTTP server (libmicrohttpd), its security rules and the files it
 * serves (docs/console.md, "Security"). */
#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <microhttpd.h>

#include "console.h"

#define MAX_BODY 65536
#define CSP                                                                                 \
	"default-src 'self'; img-src 'self' data: blob:; style-src 'self' 'unsafe-inline'; "     \
	"frame-ancestors 'self'"

double console_now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- responses ------------------------------------------------------------------ */

static enum MHD_Result send_buf(struct MHD_Connection *conn, unsigned status, const char *type,
                                const void *data, size_t size, int copy)
{
	struct MHD_Response *r = MHD_create_response_from_buffer(
		size, (void *)data, copy ? MHD_RESPMEM_MUST_COPY : MHD_RESPMEM_MUST_FREE);
	if (!r)
		return MHD_NO;
	MHD_add_response_header(r, "Content-Type", type);
	MHD_add_response_header(r, "Cache-Control", "no-store");
	MHD_add_response_header(r, "X-Content-Type-Options", "nosniff");
	MHD_add_response_header(r, "Referrer-Policy", "no-referrer");
	MHD_add_response_header(r, "Content-Security-Policy", CSP);
	enum MHD_Result ret = MHD_queue_response(conn, status, r);
	MHD_destroy_response(r);
	return ret;
}

static enum MHD_Result send_json(struct MHD_Connection *conn, unsigned status, json_t *j)
{
	char *text = j ? json_dumps(j, JSON_COMPACT) : NULL;
	json_decref(j);
	if (!text)
		return send_buf(conn, 500, "text/plain", "out of memory\n", 14, 1);
	return send_buf(conn, status, "application/json", text, strlen(text), 0);
}

static enum MHD_Result send_error(struct MHD_Connection *conn, unsigned status,
                                  const char *fmt, ...) KG_PRINTF(3, 4);
static enum MHD_Result send_error(struct MHD_Connection *conn, unsigned status,
                                  const char *fmt, ...)
{
	char msg[1024];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	return send_json(conn, status, json_pack("{s:o}", "error", kg_json_message(msg)));
}

/* ---- files ---------------------------------------------------------------------- */

static const char *type_of(const char *path)
{
	static const char *const types[][2] = {
		{".html", "text/html; charset=utf-8"}, {".json", "application/json"},
		{".png", "image/png"}, {".css", "text/css"}, {".js", "text/javascript"},
		{".tif", "image/tiff"}, {".txt", "text/plain; charset=utf-8"},
		{".cgats", "text/plain; charset=utf-8"}, {".jsonl", "text/plain; charset=utf-8"},
	};
	const char *dot = strrchr(path, '.');
	for (size_t i = 0; dot && i < sizeof(types) / sizeof(types[0]); i++)
		if (!strcmp(dot, types[i][0]))
			return types[i][1];
	return "application/octet-stream";
}

/* A relative path the console may serve from below a directory: components of
 * [A-Za-z0-9._+-] only, none empty, "." or "..", none starting with a dot. */
static int rel_path_ok(const char *rel)
{
	if (!*rel || strlen(rel) > 1024)
		return 0;
	const char *p = rel;
	while (*p) {
		const char *end = strchr(p, '/');
		size_t n = end ? (size_t)(end - p) : strlen(p);
		if (n == 0 || p[0] == '.')
			return 0;
		for (size_t i = 0; i < n; i++) {
			char ch = p[i];
			if (!((ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
			      (ch >= '0' && ch <= '9') || ch == '.' || ch == '_' || ch == '-' ||
			      ch == '+'))
				return 0;
		}
		p += n;
		if (*p == '/')
			p++;
		else
			break;
	}
	return rel[strlen(rel) - 1] != '/';
}

/* Serve base/rel when it resolves (symbolic links followed) to a regular file inside
 * base resolved. */
/* 503 with Retry-After: the results are being put in place. */
static enum MHD_Result send_busy(struct MHD_Connection *conn, const char *why)
{
	struct MHD_Response *r = NULL;
	json_t *j = json_pack("{s:s}", "error", why);
	char *body = j ? json_dumps(j, JSON_COMPACT) : NULL;
	json_decref(j);
	if (body)
		r = MHD_create_response_from_buffer(strlen(body), body, MHD_RESPMEM_MUST_FREE);
	else
		return MHD_NO;
	if (!r) {
		free(body);
		return MHD_NO;
	}
	MHD_add_response_header(r, "Content-Type", "application/json");
	MHD_add_response_header(r, "Retry-After", "1");
	MHD_add_response_header(r, "Cache-Control", "no-store");
	enum MHD_Result ret = MHD_queue_response(conn, 503, r);
	MHD_destroy_response(r);
	return ret;
}

/* A file below base; with results (OUTDIR), refused while a commit is under way there,
 * checked after the file is opened. */
static enum MHD_Result send_file(struct MHD_Connection *conn, const char *base,
                                 const char *rel, const char *results)
{
	if (!rel_path_ok(rel))
		return send_error(conn, 403, "'%s': refused (only plain relative paths inside the "
		                  "directory are served)", rel);
	char root[PATH_MAX], path[PATH_MAX * 2], real[PATH_MAX];
	if (!realpath(base, root))
		return send_error(conn, 404, "'%s': not there yet", rel);
	snprintf(path, sizeof(path), "%s/%s", root, rel);
	if (!realpath(path, real))
		return send_error(conn, 404, "'%s': no such file", rel);
	size_t n = strlen(root);
	if (strncmp(real, root, n) || real[n] != '/')
		return send_error(conn, 403, "'%s': refused (it leads outside the directory)", rel);
	int fd = open(real, O_RDONLY | O_CLOEXEC);
	struct stat st;
	if (fd < 0 || fstat(fd, &st) || !S_ISREG(st.st_mode)) {
		if (fd >= 0)
			close(fd);
		return send_error(conn, 404, "'%s': not a readable file", rel);
	}
	if (results && kg_outdir_in_commit(results)) {
		close(fd);
		return send_busy(conn, "the results are being put in place: retry in a moment");
	}
	struct MHD_Response *r = MHD_create_response_from_fd((uint64_t)st.st_size, fd);
	if (!r) {
		close(fd);
		return MHD_NO;
	}
	MHD_add_response_header(r, "Content-Type", type_of(real));
	MHD_add_response_header(r, "Cache-Control", "no-store");
	MHD_add_response_header(r, "X-Content-Type-Options", "nosniff");
	enum MHD_Result ret = MHD_queue_response(conn, 200, r);
	MHD_destroy_response(r);
	return ret;
}

/* A file of the results: OUTDIR settled first (a commit a killed run left half-done
 * completed, a live run's commit waited for), and the file served only when no commit
 * began while it was opened, so the page never mixes two runs' results. */
static enum MHD_Result send_result(struct MHD_Connection *conn, const char *outdir,
                                   const char *rel)
{
	kg_err err = {{0}};
	int ret = kg_outdir_settle(outdir, "kogei console", NULL, 2000, NULL, &err);
	if (ret && ret != KG_ENOENT)
		return send_busy(conn, err.msg);
	return send_file(conn, outdir, rel, outdir);
}

/* ---- security -------------------------------------------------------------------- */

static int token_ok(const console *c, const char *given)
{
	if (!given || strlen(given) != strlen(c->token))
		return 0;
	unsigned char d = 0;
	for (size_t i = 0; c->token[i]; i++)
		d |= (unsigned char)(given[i] ^ c->token[i]);
	return d == 0;
}

/* The Host header names this server: the listen address and port (or localhost for a
 * loopback address); a wildcard address accepts any host (the token is required). */
static int host_ok(const console *c, const char *host)
{
	if (!host)
		return 0;
	if (!strcmp(c->host, "0.0.0.0") || !strcmp(c->host, "::"))
		return 1;
	char want[128];
	if (strchr(c->host, ':'))
		snprintf(want, sizeof(want), "[%s]:%d", c->host, c->port);
	else
		snprintf(want, sizeof(want), "%s:%d", c->host, c->port);
	if (!strcmp(host, want))
		return 1;
	snprintf(want, sizeof(want), "localhost:%d", c->port);
	return (!strcmp(c->host, "127.0.0.1") || !strcmp(c->host, "::1")) && !strcmp(host, want);
}

/* ---- requests --------------------------------------------------------------------- */

typedef struct request {
	char *body;
	size_t size;
	int too_big;
	int answered; /* received in full: its answer is queued */
} request;

/* ---- connections (console_conn.c) ------------------------------------------------ */

static void on_connection(void *cls, struct MHD_Connection *conn, void **socket_context,
                          enum MHD_ConnectionNotificationCode code)
{
	console *c = cls;
	if (code == MHD_CONNECTION_NOTIFY_STARTED) {
		const union MHD_ConnectionInfo *fd =
			MHD_get_connection_info(conn, MHD_CONNECTION_INFO_CONNECTION_FD);
		const union MHD_ConnectionInfo *client =
			MHD_get_connection_info(conn, MHD_CONNECTION_INFO_CLIENT_ADDRESS);
		*socket_context =
			fd && client ? console_conn_admit(c, fd->connect_fd, client->client_addr) : NULL;
	} else if (*socket_context) {
		/* the server closes the socket after this */
		console_conn_release(c, *socket_context);
		*socket_context = NULL;
	}
}

static console_conn *conn_of(struct MHD_Connection *conn)
{
	const union MHD_ConnectionInfo *ci =
		MHD_get_connection_info(conn, MHD_CONNECTION_INFO_SOCKET_CONTEXT);
	return ci ? ci->socket_context : NULL;
}

static double qnum(struct MHD_Connection *conn, const char *key, double dflt)
{
	const char *v = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, key);
	char *end;
	double x = v ? strtod(v, &end) : dflt;
	return v && (*end || !isfinite(x)) ? dflt : x;
}

/* The page's own files. With a token, the page's response also sets it as a cookie
 * (per port, SameSite=Strict, HttpOnly), so the files the page loads (its script,
 * style sheet, the report in its frame) carry it too. */
static enum MHD_Result send_asset(const console *c, struct MHD_Connection *conn,
                                  const kg_console_asset *a)
{
	struct MHD_Response *r =
		MHD_create_response_from_buffer(a->size, (void *)a->data, MHD_RESPMEM_PERSISTENT);
	if (!r)
		return MHD_NO;
	MHD_add_response_header(r, "Content-Type", a->type);
	MHD_add_response_header(r, "Cache-Control", "no-store");
	MHD_add_response_header(r, "X-Content-Type-Options", "nosniff");
	MHD_add_response_header(r, "Referrer-Policy", "no-referrer");
	MHD_add_response_header(r, "Content-Security-Policy", CSP);
	if (c->need_token) {
		char cookie[160];
		snprintf(cookie, sizeof(cookie), "kogei_token_%d=%s; Path=/; HttpOnly; SameSite=Strict",
		         c->port, c->token);
		MHD_add_response_header(r, "Set-Cookie", cookie);
	}
	enum MHD_Result ret = MHD_queue_response(conn, 200, r);
	MHD_destroy_response(r);
	return ret;
}

static enum MHD_Result handle_get(console *c, struct MHD_Connection *conn, const char *url)
{
	if (!strcmp(url, "/"))
		url = "/index.html";
	for (const kg_console_asset *a = kg_console_assets; a->path; a++)
		if (!strcmp(url, a->path))
			return send_asset(c, conn, a);
	if (!strcmp(url, "/api/live")) {
		static const char *const view_keys[] = {"ev", "peaking", "x0", "y0", "x1", "y1", "roi"};
		for (size_t i = 0; i < sizeof(view_keys) / sizeof(view_keys[0]); i++)
			if (MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, view_keys[i]))
				return send_error(conn, 405, "/api/live: '%s': the view is changed with POST "
				                  "/api/view only", view_keys[i]);
		double after = qnum(conn, "after", -1);
		if (MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "after") &&
		    !(after >= 0 && after <= 9e15 && after == floor(after)))
			return send_error(conn, 400, "/api/live: 'after': expected a preview count, a "
			                  "whole number >= 0");
		return send_json(conn, 200, console_live_json(c, after > 0 ? (uint64_t)after : 0));
	}
	if (!strcmp(url, "/api/preview")) {
		/* the page's live view: the next preview itself, its numbers in headers */
		double after = qnum(conn, "after", -1);
		if (!MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "after"))
			after = 0;
		if (!(after >= 0 && after <= 9e15 && after == floor(after)))
			return send_error(conn, 400, "/api/preview: 'after': expected a preview count, "
			                  "a whole number >= 0");
		console_preview pv;
		if (console_live_preview(c, (uint64_t)after, &pv))
			return send_error(conn, 503, "no new preview within 2 s (is the camera "
			                  "delivering?)");
		struct MHD_Response *r = MHD_create_response_from_buffer(pv.size, pv.data,
		                                                         MHD_RESPMEM_MUST_FREE);
		if (!r) {
			free(pv.data);
			free(pv.live);
			return MHD_NO;
		}
		char num[64];
		MHD_add_response_header(r, "Content-Type", pv.type);
		MHD_add_response_header(r, "Cache-Control", "no-store");
		MHD_add_response_header(r, "X-Content-Type-Options", "nosniff");
		MHD_add_response_header(r, "Referrer-Policy", "no-referrer");
		MHD_add_response_header(r, "Content-Security-Policy", CSP);
		snprintf(num, sizeof(num), "%llu", (unsigned long long)pv.seq);
		MHD_add_response_header(r, "X-Kogei-Preview", num);
		snprintf(num, sizeof(num), "%.3f", pv.captured_ms);
		MHD_add_response_header(r, "X-Kogei-Captured-Ms", num);
		if (pv.live)
			MHD_add_response_header(r, "X-Kogei-Live", pv.live);
		free(pv.live);
		enum MHD_Result ret = MHD_queue_response(conn, 200, r);
		MHD_destroy_response(r);
		return ret;
	}
	if (!strcmp(url, "/api/live.png")) {
		size_t n = 0;
		unsigned char *png = console_live_png(c, &n);
		if (!png)
			return send_error(conn, 503, "no preview yet");
		return send_buf(conn, 200, "image/png", png, n, 0);
	}
	if (!strcmp(url, "/api/state"))
		return send_json(conn, 200, console_state_json(c));
	if (!strcmp(url, "/api/session"))
		return send_json(conn, 200, console_session_json(c));
	if (!strcmp(url, "/api/chart"))
		return send_json(conn, 200, console_chart_check(c));
	if (!strncmp(url, "/session/", 9))
		return send_file(conn, c->session_dir, url + 9, NULL);
	if (!strncmp(url, "/out/", 5))
		return send_result(conn, c->outdir, url + 5);
	return send_error(conn, 404, "%s: no such page", url);
}

static enum MHD_Result handle_post(console *c, struct MHD_Connection *conn, const char *url,
                                   const request *rq)
{
	json_error_t je;
	json_t *req = rq->size ? json_loadb(rq->body, rq->size, 0, &je) : json_object();
	if (!req || !json_is_object(req)) {
		json_decref(req);
		return send_error(conn, 400, "%s: the request body: expected a JSON object", url);
	}
	char why[1024] = "";
	int status;
	if (!strcmp(url, "/api/view")) {
		status = console_view_set(c, req, why, sizeof(why));
		json_decref(req);
		if (status)
			return send_error(conn, (unsigned)status, "%s", why);
		return send_json(conn, 200, console_view_json(c));
	}
	if (!strcmp(url, "/api/capture"))
		status = console_job_capture(c, req, why, sizeof(why));
	else if (!strcmp(url, "/api/measure"))
		status = console_job_measure(c, req, why, sizeof(why));
	else if (!strcmp(url, "/api/measure/answer"))
		status = console_job_answer(c, req, why, sizeof(why));
	else if (!strcmp(url, "/api/process"))
		status = console_job_process(c, req, why, sizeof(why));
	else if (!strcmp(url, "/api/deposit"))
		status = console_job_deposit(c, req, why, sizeof(why));
	else if (!strcmp(url, "/api/settings"))
		status = console_settings_set(c, req, why, sizeof(why));
	else {
		status = 404;
		snprintf(why, sizeof(why), "%s: no such action", url);
	}
	json_decref(req);
	if (status)
		return send_error(conn, (unsigned)status, "%s", why);
	return send_json(conn, 200, console_state_json(c));
}

static enum MHD_Result serve_request(void *cls, struct MHD_Connection *conn, const char *url,
                                     const char *method, const char *version,
                                     const char *upload, size_t *upload_size, void **state)
{
	console *c = cls;
	(void)version;
	request *rq = *state;
	if (!rq) {
		/* First call: the headers. Everything is checked before a body is read. */
		const char *host = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, "Host");
		if (!host_ok(c, host))
			return send_error(conn, 403, "Host '%s': this console answers to %s:%d only",
			                  host ? host : "(none)", c->host, c->port);
		if (c->need_token) {
			const char *t = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, "X-Kogei-Token");
			if (!t)
				t = MHD_lookup_connection_value(conn, MHD_GET_ARGUMENT_KIND, "token");
			char name[32];
			snprintf(name, sizeof(name), "kogei_token_%d", c->port);
			if (!t)
				t = MHD_lookup_connection_value(conn, MHD_COOKIE_KIND, name);
			if (!token_ok(c, t))
				return send_error(conn, 403, "this console listens on %s: every request needs "
				                  "its token (?token=... or the X-Kogei-Token header), printed "
				                  "when it started", c->host);
		}
		if (!strcmp(method, "POST")) {
			const char *origin = MHD_lookup_connection_value(conn, MHD_HEADER_KIND, "Origin");
			char want[160];
			snprintf(want, sizeof(want), "http://%s", host);
			if (!origin || strcmp(origin, want))
				return send_error(conn, 403, "actions need the Origin header of this console's "
				                  "page (%s), got '%s'", want, origin ? origin : "(none)");
		} else if (strcmp(method, "GET") && strcmp(method, "HEAD")) {
			return send_error(conn, 405, "%s: only GET and POST (actions) are served", method);
		}
		if (!strcmp(method, "GET") && !strncmp(url, "/api/", 5) &&
		    (!strcmp(url, "/api/capture") || !strncmp(url, "/api/measure", 12) ||
		     !strcmp(url, "/api/process") || !strcmp(url, "/api/deposit") ||
		     !strcmp(url, "/api/settings") ||
		     !strcmp(url, "/api/view")))
			return send_error(conn, 405, "%s: an action: POST only", url);
		rq = calloc(1, sizeof(*rq));
		if (!rq)
			return MHD_NO;
		*state = rq;
		return MHD_YES;
	}
	if (*upload_size) {
		if (rq->size + *upload_size > MAX_BODY) {
			rq->too_big = 1;
		} else {
			char *b = realloc(rq->body, rq->size + *upload_size + 1);
			if (!b)
				return MHD_NO;
			rq->body = b;
			memcpy(rq->body + rq->size, upload, *upload_size);
			rq->size += *upload_size;
			rq->body[rq->size] = 0;
		}
		*upload_size = 0;
		return MHD_YES;
	}
	rq->answered = 1;
	if (rq->too_big)
		return send_error(conn, 413, "request body larger than %d bytes", MAX_BODY);
	if (!strcmp(method, "POST"))
		return handle_post(c, conn, url, rq);
	return handle_get(c, conn, url);
}

/* A request's part is handled only on a connection still open (one closed for a
 * newcomer may have sent it); then its answer, queued when the request is in or was
 * refused at its headers, is sent under the send deadline. */
static enum MHD_Result on_request(void *cls, struct MHD_Connection *conn, const char *url,
                                  const char *method, const char *version,
                                  const char *upload, size_t *upload_size, void **state)
{
	console_conn *k = conn_of(conn);
	if (!console_conn_begin(cls, k))
		return MHD_NO;
	enum MHD_Result ret =
		serve_request(cls, conn, url, method, version, upload, upload_size, state);
	const request *rq = *state;
	console_conn_end(cls, k, !rq || rq->answered);
	return ret;
}

/* A request answered: the connection waits for its next one. */
static void on_completed(void *cls, struct MHD_Connection *conn, void **state,
                         enum MHD_RequestTerminationCode toe)
{
	(void)toe;
	console_conn *k = conn_of(conn);
	if (k)
		console_conn_answered(cls, k);
	request *rq = *state;
	if (rq) {
		free(rq->body);
		free(rq);
		*state = NULL;
	}
}

/* ---- running it ------------------------------------------------------------------ */

static int make_token(char token[33])
{
	unsigned char b[16];
	size_t got = 0;
	while (got < sizeof(b)) {
		ssize_t n = getrandom(b + got, sizeof(b) - got, 0);
		if (n < 0 && errno == EINTR)
			continue;
		if (n <= 0)
			return -1;
		got += (size_t)n;
	}
	for (int i = 0; i < 16; i++)
		sprintf(token + 2 * i, "%02x", b[i]);
	return 0;
}

/* The layout of the session's latest chart capture, or NULL. */
static const char *session_layout(const kg_session *s)
{
	const json_t *caps = json_object_get(kg_session_manifest(s), "captures");
	const char *found = NULL;
	size_t i;
	const json_t *cap;
	json_array_foreach(caps, i, cap)
	{
		const char *kind = json_string_value(json_object_get(cap, "kind"));
		const char *lay = json_string_value(json_object_get(cap, "chart_layout"));
		if (kind && !strcmp(kind, "chart") && lay)
			found = lay;
	}
	return found;
}

int kg_console_run(const kg_console_options *o, int *device_failure, kg_err *err)
{
	static console con;
	console *c = &con;
	memset(c, 0, sizeof(*c));
	*device_failure = 0;
	FILE *announce = o->announce ? o->announce : stdout;
	kg_check_arg(o->session && o->outdir && o->spectra_out && o->host, err);
	if (o->ncameras > CONSOLE_MAX_CAMERAS || o->port < 0 || o->port > 65535 ||
	    snprintf(c->host, sizeof(c->host), "%s", o->host) >= (int)sizeof(c->host) ||
	    snprintf(c->session_dir, sizeof(c->session_dir), "%s", o->session) >=
	        (int)sizeof(c->session_dir) ||
	    snprintf(c->outdir, sizeof(c->outdir), "%s", o->outdir) >= (int)sizeof(c->outdir) ||
	    snprintf(c->spectra_out, sizeof(c->spectra_out), "%s", o->spectra_out) >=
	        (int)sizeof(c->spectra_out))
		return kg_fail(err, KG_EINVAL, "console: an option is out of range or too long");
	c->port = o->port;
	c->ncameras = o->ncameras;
	for (int i = 0; i < o->ncameras; i++)
		c->cameras[i] = o->cameras[i];
	c->spectro_uri = o->spectro;
	c->layout = o->layout;
	c->reference = o->reference;
	c->frames = o->frames > 0 ? o->frames : 10;
	c->header_timeout = o->header_timeout > 0 ? o->header_timeout : 10;
	c->send_timeout = o->send_timeout > 0 ? o->send_timeout : 10;
	if (!(c->header_timeout >= 0.1 && c->header_timeout <= 3600) ||
	    !(c->send_timeout >= 0.1 && c->send_timeout <= 3600))
		return kg_fail(err, KG_EINVAL, "console: header timeout %g s, send timeout %g s: "
		               "expected 0.1..3600", c->header_timeout, c->send_timeout);
	struct in6_addr a6;
	struct in_addr a4;
	int v6 = inet_pton(AF_INET6, c->host, &a6) == 1;
	if (!v6 && inet_pton(AF_INET, c->host, &a4) != 1)
		return kg_fail(err, KG_EINVAL, "console: listen address '%s': expected a numeric IPv4 "
		               "or IPv6 address", c->host);
	c->need_token = strcmp(c->host, "127.0.0.1") != 0;
	if (c->need_token && make_token(c->token))
		return kg_fail(err, KG_EIO, "console: cannot read random bytes for the token: %s",
		               strerror(errno));
	int code = kg_session_open(c->session_dir, &c->session, err);
	if (code)
		return code;
	static char layout_copy[PATH_MAX];
	if (!c->layout && session_layout(c->session)) {
		/* the manifest's: a bundled name, or a file inside the session (never elsewhere) */
		const char *lay = session_layout(c->session);
		char *lp = NULL, *mf = kg_path_join(c->session_dir, KG_SESSION_MANIFEST);
		if (mf && !kg_chart_layout_is_bundled(lay) &&
		    (code = kg_chart_layout_resolve_session(c->session_dir, mf, "chart_layout", lay,
		                                            &lp, err))) {
			free(mf);
			kg_session_free(&c->session);
			return code;
		}
		snprintf(layout_copy, sizeof(layout_copy), "%s", lp ? lp : lay);
		free(lp);
		free(mf);
		c->layout = layout_copy;
	}
	int rc = 0;
	if (c->layout && (code = kg_chart_layout_load(c->layout, &c->chart_layout, err))) {
		kg_session_free(&c->session);
		return code;
	}
	pthread_mutex_init(&c->lock, NULL);
	pthread_mutex_init(&c->cam_lock, NULL);
	pthread_mutex_init(&c->conn_lock, NULL);
	pthread_cond_init(&c->cond, NULL);
	c->job_log = json_array();
	c->manifest = json_deep_copy(kg_session_manifest(c->session));
	c->cam_index = -1;
	if (c->ncameras && (code = console_camera_select(c, 0, err))) {
		*device_failure = 1;
		rc = code;
		goto done;
	}
	/* Signals go to sigwait below only: every thread started from here blocks them. */
	sigset_t sigs;
	sigemptyset(&sigs);
	sigaddset(&sigs, SIGINT);
	sigaddset(&sigs, SIGTERM);
	pthread_sigmask(SIG_BLOCK, &sigs, NULL);
	signal(SIGPIPE, SIG_IGN);
	if (c->chart_layout) {
		/* the chart check's first tagless detection finds OpenCV's tables built */
		kg_chart_detect_options wopt;
		kg_chart_detect_options_default(&wopt);
		kg_chart_warm_up(c->chart_layout, &wopt);
	}

	struct sockaddr_in sa4 = {0};
	struct sockaddr_in6 sa6 = {0};
	if (v6) {
		sa6.sin6_family = AF_INET6;
		sa6.sin6_port = htons((uint16_t)c->port);
		sa6.sin6_addr = a6;
	} else {
		sa4.sin_family = AF_INET;
		sa4.sin_port = htons((uint16_t)c->port);
		sa4.sin_addr = a4;
	}
	/* The limits per address and in all are console_conn.c's (libmicrohttpd's would
	 * refuse a newcomer where a stalled connection can make room); its own timeout,
	 * of idleness, only backs up the deadlines. */
	unsigned idle_timeout = (unsigned)ceil(fmax(c->header_timeout, c->send_timeout)) + 5;
	struct MHD_Daemon *d = MHD_start_daemon(
		MHD_USE_THREAD_PER_CONNECTION | MHD_USE_INTERNAL_POLLING_THREAD |
			(v6 ? MHD_USE_IPv6 : 0),
		(uint16_t)c->port, NULL, NULL, on_request, c, MHD_OPTION_SOCK_ADDR,
		v6 ? (struct sockaddr *)&sa6 : (struct sockaddr *)&sa4, MHD_OPTION_CONNECTION_LIMIT,
		(unsigned)CONSOLE_CONN_SLOTS, MHD_OPTION_CONNECTION_TIMEOUT, idle_timeout,
		MHD_OPTION_NOTIFY_CONNECTION, on_connection, c, MHD_OPTION_NOTIFY_COMPLETED,
		on_completed, c, MHD_OPTION_END);
	if (d && console_conn_start(c)) {
		MHD_stop_daemon(d);
		rc = kg_fail(err, KG_EIO, "console: cannot start the connection reaper thread");
		goto done;
	}
	if (!d) {
		rc = kg_fail(err, KG_EINVAL, "console: cannot listen on %s port %d: %s (address in "
		             "use or not this machine's?)", c->host, c->port, strerror(errno));
		goto done;
	}
	const union MHD_DaemonInfo *info = MHD_get_daemon_info(d, MHD_DAEMON_INFO_BIND_PORT);
	if (info && info->port)
		c->port = info->port;
	if ((rc = console_live_start(c, err))) {
		MHD_stop_daemon(d);
		console_conn_stop(c);
		goto done;
	}
	fprintf(announce, "kogei console: session %s, output %s\n", c->session_dir, c->outdir);
	if (strchr(c->host, ':'))
		fprintf(announce, "open http://[%s]:%d/%s%s\n", c->host, c->port, c->need_token ? "?token=" : "",
		       c->need_token ? c->token : "");
	else
		fprintf(announce, "open http://%s:%d/%s%s\n", c->host, c->port, c->need_token ? "?token=" : "",
		       c->need_token ? c->token : "");
	fflush(announce);
	int sig = 0;
	sigwait(&sigs, &sig);
	fprintf(stderr, "kogei console: stopping (signal %d)\n", sig);
	console_jobs_stop(c);
	console_live_stop(c);
	MHD_stop_daemon(d);
	console_conn_stop(c);
done:
	kg_chart_warm_wait();
	kg_camera_free(&c->cam);
	kg_chart_layout_free(&c->chart_layout);
	kg_session_free(&c->session);
	json_decref(c->job_log);
	json_decref(c->job_result);
	json_decref(c->manifest);
	json_decref(c->live);
	free(c->img);
	free(c->disp);
	free(c->live_text);
	return rc;
}
