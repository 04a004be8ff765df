/* Tethered photographic cameras (DSLRs, mirrorless, medium format) through libgphoto2
 * (driver table: camera_driver.h). libgphoto2 stays inside this file; the pure parts
 * (choice strings, raw formats) are in gp_choices.c.
 *
 *   gphoto2:<model>[?options]   a camera by its model name as libgphoto2 lists it
 *                               ("Canon EOS 5D Mark IV", "USB PTP Class Camera")
 *   gphoto2:<port>[?options]    the camera at a port: usb:BBB,DDD (bus, device),
 *                               ptpip:<address>
 *   options: delete=1   delete each file from the camera after downloading it
 *                       (default 0: the card keeps every capture)
 *            save=DIR   keep each downloaded file in DIR (an existing folder) under its
 *                       name on the camera (KG00001.DNG, or KG00001-2.DNG when taken);
 *                       frames then name it as their source (the manifest of
 *                       `kogei acquire` lists the originals with their sha256)
 *
 * The live view (kg_camera_preview, the console's) is the camera's own: libgphoto2's
 * capture preview, a JPEG from the viewfinder, never an exposure; a camera without one
 * says so.
 *
 * Each pop is one exposure: capture (gp_camera_capture), the raw file downloaded to
 * memory, decoded linearly by core/raw.c (LibRaw) and delivered as BAYER16 (the
 * decoded (raw-black)/(white-black) on 0..1 times 65535). The file's own metadata
 * gives the frame's exposure time (the ISO is the iso feature). The frame size
 * is the raw's, known only from a capture: the first get_format or start takes one
 * capture to learn it (kept as the last file, not delivered as a frame).
 *
 * Features come from the camera's configuration (radio/menu choices): shutterspeed,
 * iso, aperture, focallength, exposure program. Set picks exactly one of the camera's
 * choices or fails naming the nearest ones.
 *
 * Enumeration is libgphoto2's autodetection over the ports its I/O libraries list (USB
 * devices' descriptors and serial port names; nothing is sent to a device until one is
 * opened). Debian's ptpip I/O library lists fixed entries only; a libgphoto2 built with
 * Bonjour links its ptpip library with libdns_sd and browses mDNS while listing ports,
 * so with KOGEI_CAMERA_DISCOVERY=none enumeration is skipped when that library names
 * libdns_sd (looked for in the file before anything is loaded). */
#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <gphoto2/gphoto2.h>

#include "camera_driver.h"
#include "gp_choices.h"
#include "gphoto2_private.h"
#include "raw.h"

/* How long to wait, after a capture that delivered a non-raw file, for the raw of a
 * RAW+JPEG pair to be announced (ms). */
#define PAIR_WAIT_MS 5000

typedef enum { K_NONE = 0, K_CHOICE, K_RANGE, K_TEXT, K_PROGRAM } feat_kind;

typedef struct feat {
	feat_kind kind;
	const char *name; /* configuration name */
} feat;

typedef struct gp_state {
	GPContext *ctx;
	Camera *cam;
	char model[128];
	char port[256];
	int delete_after;
	char *save_dir; /* save=DIR, or NULL */
	char saved[4096]; /* where the last file was saved, "" when not */
	char note[512];   /* how the last file was decoded */
	char gp_error[512]; /* the last error libgphoto2 reported through the context */
	feat feats[KG_FEAT_COUNT];

	kg_frame_format fmt;
	int have_fmt;
	int streaming;
	uint8_t *frame; /* the frame delivered, BAYER16 */
	size_t frame_cap;
	int held;
	uint64_t seq;
	uint64_t failed;

	char *file; /* the last file downloaded */
	size_t file_size;
	/* folder "/" name of a CameraFilePath: its two arrays' NULs make room for the "/"
	 * and the NUL here */
	char file_name[sizeof(((CameraFilePath *)0)->folder) +
	               sizeof(((CameraFilePath *)0)->name)];
	kg_raw_meta meta;
	int have_file;

	CameraFile *preview;   /* the last live-view image (its data is the frame's) */
	uint64_t previews;     /* gp_camera_capture_preview calls that gave an image */
	uint64_t captures;     /* gp_camera_capture calls (full exposures) */
} gp_state;

/* ---- errors ------------------------------------------------------------------- */

static void on_gp_error(GPContext *ctx, const char *text, void *data)
{
	(void)ctx;
	gp_state *s = data;
	snprintf(s->gp_error, sizeof(s->gp_error), "%s", text);
}

/* kg_fail with libgphoto2's code and its last message appended. */
static int gpfail(gp_state *s, kg_err *err, int code, int gpret, const char *fmt, ...)
	KG_PRINTF(5, 6);

static int gpfail(gp_state *s, kg_err *err, int code, int gpret, const char *fmt, ...)
{
	char what[512];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(what, sizeof(what), fmt, ap);
	va_end(ap);
	const char *detail = s->gp_error[0] ? s->gp_error : NULL;
	int ret = kg_fail(err, code, "%s: %s%s%s", what, gp_result_as_string(gpret),
	                  detail ? ": " : "", detail ? detail : "");
	s->gp_error[0] = 0;
	return ret;
}

/* /dev/bus/usb/BBB/DDD of a usb:BBB,DDD port, "" for others. */
static void usb_node(const char *port, char *node, size_t n)
{
	unsigned bus, dev;
	node[0] = 0;
	if (sscanf(port, "usb:%u,%u", &bus, &dev) == 2)
		snprintf(node, n, "/dev/bus/usb/%03u/%03u", bus, dev);
}

/* The error of a failed gp_camera_init (or of another call that opens the port). */
static int open_error(gp_state *s, int gpret, kg_err *err)
{
	char node[64];
	usb_node(s->port, node, sizeof(node));
	int denied = node[0] && access(node, R_OK | W_OK) && errno == EACCES;
	const char *port_msg = s->cam && s->cam->port ? gp_port_get_error(s->cam->port) : NULL;
	const char *detail = s->gp_error[0] ? s->gp_error : NULL;
	if (!detail && port_msg && *port_msg && strcmp(port_msg, "No error description available"))
		detail = port_msg;
	int ret = kg_gp_open_error(s->model, s->port, node, denied, gpret,
	                           gp_result_as_string(gpret), detail, err);
	s->gp_error[0] = 0;
	return ret;
}

/* ---- configuration ------------------------------------------------------------ */

static int widget_is_choice(CameraWidget *w)
{
	CameraWidgetType t;
	return !gp_widget_get_type(w, &t) && (t == GP_WIDGET_RADIO || t == GP_WIDGET_MENU);
}

/* The widget of a configuration name, NULL when the camera has none. */
static CameraWidget *get_widget(gp_state *s, const char *name)
{
	CameraWidget *w = NULL;
	if (gp_camera_get_single_config(s->cam, name, &w, s->ctx) < GP_OK)
		w = NULL;
	s->gp_error[0] = 0;
	return w;
}

/* The choices of a radio/menu widget (pointers into it). *out is set on every path,
 * NULL with none or out of memory (-1), so callers can always free it. */
static int widget_choices(CameraWidget *w, const char ***out)
{
	*out = NULL;
	int n = gp_widget_count_choices(w);
	if (n <= 0)
		return 0;
	const char **c = calloc((size_t)n, sizeof(*c));
	if (!c)
		return -1;
	for (int i = 0; i < n; i++)
		if (gp_widget_get_choice(w, i, &c[i]) < GP_OK || !c[i])
			c[i] = "";
	*out = c;
	return n;
}

static const char *widget_text(CameraWidget *w)
{
	const char *v = NULL;
	if (gp_widget_get_value(w, &v) < GP_OK)
		return NULL;
	return v;
}

static void resolve_features(gp_state *s)
{
	static const struct {
		kg_feature f;
		feat_kind kind;
		const char *names[4];
	} table[] = {
		{KG_FEAT_EXPOSURE_US, K_CHOICE, {"shutterspeed", "shutterspeed2", "exposuretime", NULL}},
		{KG_FEAT_ISO, K_CHOICE, {"iso", "isospeed", NULL}},
		{KG_FEAT_APERTURE, K_CHOICE, {"aperture", "f-number", NULL}},
		{KG_FEAT_FOCAL_LENGTH, K_RANGE, {"focallength", NULL}},
		{KG_FEAT_AUTO_EXPOSURE, K_PROGRAM,
		 {"expprogram", "autoexposuremode", "autoexposuremodedial", NULL}},
	};
	memset(s->feats, 0, sizeof(s->feats));
	for (size_t i = 0; i < sizeof(table) / sizeof(table[0]); i++) {
		for (int k = 0; table[i].names[k]; k++) {
			CameraWidget *w = get_widget(s, table[i].names[k]);
			if (!w)
				continue;
			CameraWidgetType t;
			gp_widget_get_type(w, &t);
			feat_kind kind = K_NONE;
			if (table[i].kind == K_PROGRAM)
				kind = widget_is_choice(w) || t == GP_WIDGET_TEXT ? K_PROGRAM : K_NONE;
			else if (t == GP_WIDGET_RADIO || t == GP_WIDGET_MENU)
				kind = K_CHOICE;
			else if (t == GP_WIDGET_RANGE)
				kind = K_RANGE;
			else if (t == GP_WIDGET_TEXT)
				kind = K_TEXT;
			gp_widget_free(w);
			if (kind != K_NONE) {
				s->feats[table[i].f] = (feat){.kind = kind, .name = table[i].names[k]};
				break;
			}
		}
	}
}

static int gp2_feature_info(void *state, kg_feature kf, kg_feature_info *out, kg_err *err)
{
	gp_state *s = state;
	const feat *f = &s->feats[kf];
	if (f->kind == K_NONE)
		return 0;
	CameraWidget *w = get_widget(s, f->name);
	if (!w)
		return 0; /* gone with a mode change */
	int ro = 0;
	gp_widget_get_readonly(w, &ro);
	out->available = 1;
	out->writable = !ro && f->kind != K_TEXT && f->kind != K_RANGE;
	if (kf == KG_FEAT_FOCAL_LENGTH)
		out->writable = 0; /* a zoom ring is turned by hand */
	snprintf(out->unit, sizeof(out->unit), "%s", kg_gp_unit(kf));
	snprintf(out->native, sizeof(out->native), "%s", f->name);
	out->step = 0;
	int ret = 0;
	if (f->kind == K_PROGRAM) {
		out->min = 0;
		out->max = 1;
		out->step = 1;
		out->writable = out->writable && widget_is_choice(w);
	} else if (f->kind == K_CHOICE) {
		const char **c = NULL;
		int n = widget_choices(w, &c);
		if (n < 0)
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
		else if (!kg_gp_choice_range(kf, c, n, &out->min, &out->max))
			out->writable = 0; /* only Auto / Bulb: nothing a number selects */
		free(c);
	} else if (f->kind == K_RANGE) {
		float lo = 0, hi = 0, inc = 0;
		gp_widget_get_range(w, &lo, &hi, &inc);
		out->min = lo;
		out->max = hi;
	}
	gp_widget_free(w);
	return ret;
}

/* The widget of feature f, which the camera has: 0, or KG_EIO when it cannot be read. */
static int feature_widget(gp_state *s, const feat *f, CameraWidget **w, kg_err *err)
{
	*w = NULL;
	int gpret = gp_camera_get_single_config(s->cam, f->name, w, s->ctx);
	if (gpret < GP_OK)
		return gpfail(s, err, KG_EIO, gpret, "camera %s: cannot read %s", s->model, f->name);
	return 0;
}

static int gp2_get(void *state, kg_feature kf, double *value, kg_err *err)
{
	gp_state *s = state;
	const feat *f = &s->feats[kf];
	if (f->kind == K_NONE)
		return kg_fail(err, KG_ENOTSUP, "camera %s has no control for %s", s->model,
		               kg_feature_name(kf));
	CameraWidget *w;
	int ret = feature_widget(s, f, &w, err);
	if (ret)
		return ret;
	if (f->kind == K_RANGE) {
		float v = 0;
		if (gp_widget_get_value(w, &v) < GP_OK)
			ret = kg_fail(err, KG_EIO, "camera %s: %s: cannot read its value", s->model,
			              f->name);
		*value = v;
	} else {
		const char *t = widget_text(w);
		if (!t)
			ret = kg_fail(err, KG_EIO, "camera %s: %s: cannot read its value", s->model,
			              f->name);
		else if (f->kind == K_PROGRAM)
			*value = kg_gp_program_is_manual(t) ? 0 : 1;
		else if (kf == KG_FEAT_ISO && !strncasecmp(t, "Auto", 4))
			*value = 0; /* documented: 0 is automatic ISO */
		else if (!kg_gp_choice_value(kf, t, value))
			ret = kg_fail(err, KG_ENOTSUP, "camera %s: %s is '%s', not a %s value", s->model,
			              f->name, t, kg_feature_name(kf));
	}
	gp_widget_free(w);
	return ret;
}

/* Set the widget to choice and write it to the camera. */
static int set_choice(gp_state *s, CameraWidget *w, const char *name, const char *choice,
                      kg_err *err)
{
	int gpret = gp_widget_set_value(w, choice);
	if (gpret >= GP_OK)
		gpret = gp_camera_set_single_config(s->cam, name, w, s->ctx);
	if (gpret < GP_OK)
		return gpfail(s, err, KG_EIO, gpret, "camera %s: cannot set %s to %s", s->model, name,
		              choice);
	return 0;
}

static int gp2_set(void *state, kg_feature kf, double value, kg_err *err)
{
	gp_state *s = state;
	const feat *f = &s->feats[kf];
	if (f->kind != K_CHOICE && f->kind != K_PROGRAM)
		return kg_fail(err, KG_ENOTSUP, "camera %s: %s cannot be set", s->model,
		               kg_feature_name(kf));
	CameraWidget *w;
	int ret = feature_widget(s, f, &w, err);
	if (ret)
		return ret;
	const char **c = NULL;
	int n = widget_choices(w, &c), idx = -1;
	if (n < 0)
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	else if (f->kind == K_PROGRAM) {
		for (int i = 0; i < n && idx < 0; i++)
			if (value == 0 ? kg_gp_program_is_manual(c[i])
			               : (!strcasecmp(c[i], "P") || !strcasecmp(c[i], "Program") ||
			                  !strcasecmp(c[i], "Auto")))
				idx = i;
		if (idx < 0)
			ret = kg_fail(err, KG_ENOTSUP,
			              "camera %s: %s offers no %s choice (set the mode dial by hand)",
			              s->model, f->name, value == 0 ? "manual (M)" : "program (P)");
	} else {
		ret = kg_gp_choice_pick(kf, f->name, c, n, value, &idx, err);
		if (ret)
			kg_err_prefix(err, "camera %s", s->model);
	}
	if (!ret)
		ret = set_choice(s, w, f->name, c[idx], err);
	free(c);
	gp_widget_free(w);
	return ret;
}

/* A text setting ("serialnumber", "lensname", ...) into out, "" when absent. */
static void config_text(gp_state *s, const char *name, char *out, size_t n)
{
	CameraWidget *w = get_widget(s, name);
	const char *t = w ? widget_text(w) : NULL;
	if (t && *t)
		snprintf(out, n, "%s", t);
	if (w)
		gp_widget_free(w);
}

/* The image format setting: KG_ENOTSUP when it has no raw choice at all (cannot
 * deliver raw), or (strict) when the current choice is not raw. Cameras without such
 * a setting pass: the captured file is checked instead. */
static int check_raw_format(gp_state *s, int strict, kg_err *err)
{
	static const char *const names[] = {"imageformat", "imagequality", "imageformatsd", NULL};
	for (int k = 0; names[k]; k++) {
		CameraWidget *w = get_widget(s, names[k]);
		if (!w)
			continue;
		const char **c = NULL;
		int n = widget_is_choice(w) ? widget_choices(w, &c) : 0;
		const char *cur = widget_text(w);
		char raws[256] = "";
		size_t len = 0;
		for (int i = 0; i < n && len < sizeof(raws); i++)
			if (kg_gp_is_raw_choice(c[i]))
				len += (size_t)snprintf(raws + len, sizeof(raws) - len, "%s'%s'",
				                        len ? ", " : "", c[i]);
		int ret = 0;
		if (n > 0 && !raws[0])
			ret = kg_fail(err, KG_ENOTSUP,
			              "camera %s cannot capture raw: its %s offers no raw choice (is it "
			              "in a video, scene or JPEG-only mode?)",
			              s->model, names[k]);
		else if (strict && cur && !kg_gp_is_raw_choice(cur))
			ret = kg_fail(err, KG_ENOTSUP,
			              "camera %s: %s is '%s', which is not raw; measurement needs the "
			              "linear raw data: set the image quality to raw (one of %s) on the "
			              "camera",
			              s->model, names[k], cur, raws[0] ? raws : "its raw choices");
		free(c);
		gp_widget_free(w);
		return ret;
	}
	return 0;
}

/* ---- open and close ----------------------------------------------------------- */

static int gp_option(void *user, const char *key, const char *value, kg_err *err)
{
	gp_state *s = user;
	if (value && !strcmp(key, "delete") && (!strcmp(value, "0") || !strcmp(value, "1"))) {
		s->delete_after = value[0] == '1';
		return 0;
	}
	if (value && !strcmp(key, "save") && value[0]) {
		free(s->save_dir);
		s->save_dir = strdup(value);
		if (!s->save_dir)
			return kg_fail(err, KG_ENOMEM, "out of memory");
		struct stat st;
		if (stat(s->save_dir, &st) || !S_ISDIR(st.st_mode) || access(s->save_dir, W_OK))
			return kg_fail(err, KG_EINVAL,
			               "option save=%s: expected an existing folder kogei may write to",
			               s->save_dir);
		return 0;
	}
	return kg_fail(err, KG_EINVAL, "option '%s%s%s': expected delete=0, delete=1 or save=DIR",
	               key, value ? "=" : "", value ? value : "");
}

static int parse_target(gp_state *s, const char *target, char *name, size_t n, kg_err *err)
{
	return kg_camera_target_split(target, name, n,
	                              "gphoto2:<model or port>[?delete=0|1&save=DIR] (see "
	                              "`kogei devices`)",
	                              gp_option, s, err);
}

static int is_port(const char *name)
{
	static const char *const types[] = {"usb:", "ptpip:", "ip:", "serial:", "disk:",
	                                    "usbdiskdirect:", "usbscsi:"};
	for (size_t i = 0; i < sizeof(types) / sizeof(types[0]); i++)
		if (!strncmp(name, types[i], strlen(types[i])))
			return 1;
	return 0;
}

/* The port and abilities lists, and the cameras attached (model, port pairs). */
typedef struct lists {
	GPPortInfoList *ports;
	CameraAbilitiesList *abilities;
	CameraList *found;
} lists;

static void lists_free(lists *l)
{
	if (l->found)
		gp_list_free(l->found);
	if (l->abilities)
		gp_abilities_list_free(l->abilities);
	if (l->ports)
		gp_port_info_list_free(l->ports);
	memset(l, 0, sizeof(*l));
}

static int lists_load(gp_state *s, lists *l, kg_err *err)
{
	int gpret;
	memset(l, 0, sizeof(*l));
	if ((gpret = gp_port_info_list_new(&l->ports)) < GP_OK ||
	    (gpret = gp_port_info_list_load(l->ports)) < GP_OK ||
	    (gpret = gp_abilities_list_new(&l->abilities)) < GP_OK ||
	    (gpret = gp_abilities_list_load(l->abilities, s->ctx)) < GP_OK ||
	    (gpret = gp_list_new(&l->found)) < GP_OK ||
	    (gpret = gp_abilities_list_detect(l->abilities, l->ports, l->found, s->ctx)) < GP_OK) {
		lists_free(l);
		return gpfail(s, err, KG_EIO, gpret,
		              "libgphoto2 cannot list its ports and camera drivers");
	}
	return 0;
}

/* "none" or "A at usb:001,002, B at usb:001,005" */
static void attached_names(lists *l, char *out, size_t n)
{
	size_t len = 0;
	int count = gp_list_count(l->found);
	out[0] = 0;
	for (int i = 0; i < count && len < n; i++) {
		const char *m = NULL, *p = NULL;
		gp_list_get_name(l->found, i, &m);
		gp_list_get_value(l->found, i, &p);
		len += (size_t)snprintf(out + len, n - len, "%s%s at %s", i ? ", " : "", m ? m : "?",
		                        p ? p : "?");
	}
	if (!count)
		snprintf(out, n, "none");
}

static const char *transport_of(GPPortType t, const CameraAbilities *a)
{
	int ptp = strstr(a->library, "ptp2") != NULL;
	switch (t) {
	case GP_PORT_USB:
		return ptp ? "USB PTP" : "USB";
	case GP_PORT_PTPIP:
		return "PTP/IP";
	case GP_PORT_IP:
		return "IP";
	case GP_PORT_SERIAL:
		return "serial";
	case GP_PORT_USB_DISK_DIRECT:
	case GP_PORT_USB_SCSI:
	case GP_PORT_DISK:
		return "USB mass storage";
	default:
		return "gphoto2";
	}
}

/* Find the model and port for name (a model or a port) among the cameras attached. */
static int locate(gp_state *s, lists *l, const char *name, kg_err *err)
{
	char seen[512];
	attached_names(l, seen, sizeof(seen));
	int count = gp_list_count(l->found), hit = -1, hits = 0;
	for (int i = 0; i < count; i++) {
		const char *m = NULL, *p = NULL;
		gp_list_get_name(l->found, i, &m);
		gp_list_get_value(l->found, i, &p);
		int match = is_port(name) ? p && !strcmp(p, name) : m && !strcasecmp(m, name);
		if (match && !hits++)
			hit = i;
	}
	if (hits > 1)
		return kg_fail(err, KG_EINVAL,
		               "%d cameras '%s' are attached (%s): open one by its port, e.g. "
		               "gphoto2:usb:BBB,DDD",
		               hits, name, seen);
	if (hit >= 0) {
		const char *m = NULL, *p = NULL;
		gp_list_get_name(l->found, hit, &m);
		gp_list_get_value(l->found, hit, &p);
		snprintf(s->model, sizeof(s->model), "%s", m);
		snprintf(s->port, sizeof(s->port), "%s", p);
		return 0;
	}
	if (is_port(name)) {
		/* A port autodetection does not list (ptpip:ADDRESS): open it if libgphoto2
		 * has an I/O library for it, with the generic PTP driver. */
		if (!strncmp(name, "usb:", 4) || gp_port_info_list_lookup_path(l->ports, name) < 0)
			return kg_fail(err, KG_ENODEV,
			               "no camera at port %s (cameras attached: %s; see `kogei "
			               "devices`)",
			               name, seen);
		snprintf(s->model, sizeof(s->model), "%s",
		         !strncmp(name, "ptpip:", 6) ? "PTP/IP Camera" : "");
		snprintf(s->port, sizeof(s->port), "%s", name);
		if (!s->model[0])
			return kg_fail(err, KG_ENODEV,
			               "no camera detected at port %s (cameras attached: %s)", name,
			               seen);
		return 0;
	}
	if (gp_abilities_list_lookup_model(l->abilities, name) < GP_OK)
		return kg_fail(err, KG_ENODEV,
		               "no camera '%s': libgphoto2 knows no such model and no attached "
		               "camera has that name (cameras attached: %s; see `kogei devices`)",
		               name, seen);
	return kg_fail(err, KG_ENODEV,
	               "camera '%s' is not attached, switched on and awake (cameras attached: "
	               "%s; a camera in USB mass-storage mode is not seen: set its USB mode to "
	               "PTP / PC remote)",
	               name, seen);
}

static void gp2_close(void *state);

static int gp2_open(const char *target, void **state, kg_camera_info *info, kg_err *err)
{
	gp_state *s = calloc(1, sizeof(*s));
	if (!s)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	char name[256];
	lists l = {0};
	int ret = parse_target(s, target, name, sizeof(name), err);
	if (ret)
		goto error;
	s->ctx = gp_context_new();
	if (!s->ctx) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto error;
	}
	gp_context_set_error_func(s->ctx, on_gp_error, s);
	if ((ret = lists_load(s, &l, err)) || (ret = locate(s, &l, name, err)))
		goto error;
	CameraAbilities a;
	int ai = gp_abilities_list_lookup_model(l.abilities, s->model);
	int pi = gp_port_info_list_lookup_path(l.ports, s->port);
	GPPortInfo pinfo;
	int gpret;
	if (ai < GP_OK || (gpret = gp_abilities_list_get_abilities(l.abilities, ai, &a)) < GP_OK) {
		ret = kg_fail(err, KG_ENODEV, "camera %s: libgphoto2 has no driver for this model",
		              s->model);
		goto error;
	}
	if (pi < GP_OK || (gpret = gp_port_info_list_get_info(l.ports, pi, &pinfo)) < GP_OK) {
		ret = kg_fail(err, KG_ENODEV, "camera %s: no port %s", s->model, s->port);
		goto error;
	}
	GPPortType ptype = GP_PORT_NONE;
	gp_port_info_get_type(pinfo, &ptype);
	if ((gpret = gp_camera_new(&s->cam)) < GP_OK ||
	    (gpret = gp_camera_set_abilities(s->cam, a)) < GP_OK ||
	    (gpret = gp_camera_set_port_info(s->cam, pinfo)) < GP_OK) {
		ret = gpfail(s, err, KG_EIO, gpret, "camera %s at %s: cannot set it up", s->model,
		             s->port);
		goto error;
	}
	gpret = gp_camera_init(s->cam, s->ctx);
	if (gpret < GP_OK) {
		ret = open_error(s, gpret, err);
		gp_camera_free(s->cam);
		s->cam = NULL;
		goto error;
	}
	lists_free(&l);
	resolve_features(s);
	if ((ret = check_raw_format(s, 0, err)))
		goto error;
	config_text(s, "manufacturer", info->vendor, sizeof(info->vendor));
	snprintf(info->model, sizeof(info->model), "%.63s", s->model);
	config_text(s, "cameramodel", info->model, sizeof(info->model));
	config_text(s, "serialnumber", info->serial, sizeof(info->serial));
	config_text(s, "lensname", info->lens, sizeof(info->lens));
	snprintf(info->transport, sizeof(info->transport), "%s", transport_of(ptype, &a));
	/* The sensor's raw size is known after the first capture (get_format). */
	*state = s;
	return 0;
error:
	lists_free(&l);
	gp2_close(s);
	return ret;
}

static void gp2_close(void *state)
{
	gp_state *s = state;
	if (!s)
		return;
	if (s->cam) {
		gp_camera_exit(s->cam, s->ctx);
		gp_camera_free(s->cam);
	}
	if (s->preview)
		gp_file_unref(s->preview);
	if (s->ctx)
		gp_context_unref(s->ctx);
	free(s->frame);
	free(s->file);
	free(s->save_dir);
	free(s);
}

/* ---- capture ------------------------------------------------------------------ */

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

/* Download folder/name into s->file; delete it from the camera when asked. */
static int download(gp_state *s, const char *folder, const char *name, kg_err *err)
{
	CameraFile *file = NULL;
	int gpret = gp_file_new(&file);
	if (gpret >= GP_OK)
		gpret = gp_camera_file_get(s->cam, folder, name, GP_FILE_TYPE_NORMAL, file, s->ctx);
	const char *data = NULL;
	unsigned long size = 0;
	if (gpret >= GP_OK)
		gpret = gp_file_get_data_and_size(file, &data, &size);
	if (gpret < GP_OK) {
		if (file)
			gp_file_unref(file);
		return gpfail(s, err, KG_EIO, gpret, "camera %s: cannot download %s/%s", s->model,
		              folder, name);
	}
	char *copy = malloc(size ? size : 1);
	if (!copy) {
		gp_file_unref(file);
		return kg_fail(err, KG_ENOMEM, "out of memory for %s/%s (%lu bytes)", folder, name,
		               size);
	}
	memcpy(copy, data, size);
	gp_file_unref(file);
	free(s->file);
	s->file = copy;
	s->file_size = size;
	s->have_file = 1;
	snprintf(s->file_name, sizeof(s->file_name), "%s%s%s", folder,
	         folder[0] && folder[strlen(folder) - 1] == '/' ? "" : "/", name);
	if (s->delete_after && (gpret = gp_camera_file_delete(s->cam, folder, name, s->ctx)) < GP_OK)
		return gpfail(s, err, KG_EIO, gpret, "camera %s: cannot delete %s after downloading it",
		              s->model, s->file_name);
	return 0;
}

/* Write the last file into save_dir under its camera name (never over another file). */
static int save_file(gp_state *s, const char *name, kg_err *err)
{
	s->saved[0] = 0;
	if (!s->save_dir)
		return 0;
	const char *dot = strrchr(name, '.');
	int stem = dot ? (int)(dot - name) : (int)strlen(name);
	for (int k = 1; k < 1000; k++) {
		char path[sizeof(s->saved)];
		if (k == 1)
			snprintf(path, sizeof(path), "%s/%s", s->save_dir, name);
		else
			snprintf(path, sizeof(path), "%s/%.*s-%d%s", s->save_dir, stem, name, k,
			         dot ? dot : "");
		FILE *f = fopen(path, "wbx"); /* x: fails when the name is taken */
		if (!f && errno == EEXIST)
			continue;
		int ok = f && fwrite(s->file, 1, s->file_size, f) == s->file_size;
		int e = errno;
		if (f && fclose(f))
			ok = 0, e = errno;
		if (!ok) {
			if (f)
				remove(path);
			return kg_fail(err, e == ENOSPC ? KG_ENOSPC : KG_EIO, "%s: cannot save: %s",
			               path, strerror(e));
		}
		snprintf(s->saved, sizeof(s->saved), "%s", path);
		return 0;
	}
	return kg_fail(err, KG_EIO, "%s: no free name for %s (999 taken)", s->save_dir, name);
}

/* After a capture that gave a non-raw file: the raw of a RAW+JPEG pair is announced as
 * a file added. 1 with path set when it came. */
static int wait_for_raw(gp_state *s, int wait_ms, CameraFilePath *path)
{
	double end = now_s() + wait_ms * 1e-3;
	while (now_s() < end) {
		CameraEventType type;
		void *data = NULL;
		int left = (int)((end - now_s()) * 1e3);
		if (gp_camera_wait_for_event(s->cam, left > 0 ? left : 1, &type, &data, s->ctx) < GP_OK)
			return 0;
		int got = 0;
		if (type == GP_EVENT_FILE_ADDED && data) {
			CameraFilePath *p = data;
			if (kg_gp_is_raw_name(p->name)) {
				*path = *p;
				got = 1;
			}
		}
		free(data);
		if (got)
			return 1;
		if (type == GP_EVENT_TIMEOUT)
			return 0;
	}
	return 0;
}

/* One exposure: capture, download, decode into img and s->meta. */
static int capture_one(gp_state *s, int timeout_ms, kg_image **img, kg_err *err)
{
	double t0 = now_s();
	CameraFilePath path;
	memset(&path, 0, sizeof(path));
	int gpret = gp_camera_capture(s->cam, GP_CAPTURE_IMAGE, &path, s->ctx);
	s->captures++;
	if (gpret < GP_OK)
		return gpfail(s, err, gpret == GP_ERROR_TIMEOUT ? KG_ETIMEDOUT : KG_EIO, gpret,
		              "camera %s: the capture failed (autofocus that cannot lock, a full "
		              "card or a lens cap can cause this)",
		              s->model);
	int ret;
	if (!kg_gp_is_raw_name(path.name)) {
		/* RAW+JPEG: the other file follows as an event; take the raw, leave the JPEG
		 * (delete it too when asked). */
		CameraFilePath raw;
		int wait = timeout_ms > 0 && timeout_ms < PAIR_WAIT_MS ? timeout_ms : PAIR_WAIT_MS;
		if (wait_for_raw(s, wait, &raw)) {
			if (s->delete_after)
				gp_camera_file_delete(s->cam, path.folder, path.name, s->ctx);
			path = raw;
		}
	}
	if ((ret = download(s, path.folder, path.name, err)) || (ret = save_file(s, path.name, err)))
		return ret;
	double t1 = now_s();
	if (s->streaming)
		fprintf(stderr, "gphoto2: %s: frame %llu: %s, %.1f MB, %.1f s\n", s->model,
		        (unsigned long long)s->seq, s->file_name, (double)s->file_size / 1e6, t1 - t0);
	else
		fprintf(stderr, "gphoto2: %s: format capture: %s, %.1f MB, %.1f s\n", s->model,
		        s->file_name, (double)s->file_size / 1e6, t1 - t0);
	memset(&s->meta, 0, sizeof(s->meta));
	ret = kg_raw_read_memory(s->file, s->file_size, s->file_name, img, &s->meta, err);
	if (ret && !kg_gp_is_raw_name(s->file_name))
		return kg_fail(err, KG_ENOTSUP,
		               "camera %s delivered %s, not a raw file: measurement needs the linear "
		               "raw data; set the camera's image quality to raw (RAW or RAW+JPEG)",
		               s->model, s->file_name);
	if (ret) {
		kg_err_prefix(err, "camera %s", s->model);
		return ret;
	}
	if ((*img)->channels != 1 || !s->meta.cfa[0]) {
		kg_image_free(img);
		return kg_fail(err, KG_ENOTSUP, "camera %s: %s has no Bayer colour filter array",
		               s->model, s->file_name);
	}
	const kg_raw_meta *m = &s->meta;
	snprintf(s->note, sizeof(s->note),
	         "%s from %.64s by LibRaw %s: black %g/%g/%g/%g, white %g/%g/%g/%g, CFA %s", m->format,
	         s->model, kg_raw_version() ? kg_raw_version() : "", m->black[0], m->black[1],
	         m->black[2], m->black[3], m->white[0], m->white[1], m->white[2], m->white[3],
	         m->cfa);
	return 0;
}

static void format_of(const kg_image *img, const kg_raw_meta *meta, kg_frame_format *f)
{
	memset(f, 0, sizeof(*f));
	f->pixfmt = KG_PIX_BAYER16;
	f->bits = 16;
	snprintf(f->cfa, sizeof(f->cfa), "%s", meta->cfa);
	f->width = img->width;
	f->height = img->height;
	kg_frame_format_fill(f);
}

/* The format, learnt from one capture when not known yet. */
static int learn_format(gp_state *s, kg_err *err)
{
	if (s->have_fmt)
		return 0;
	int ret = check_raw_format(s, 1, err);
	if (ret)
		return ret;
	fprintf(stderr, "gphoto2: %s: one capture to learn the raw format\n", s->model);
	kg_image *img = NULL;
	if ((ret = capture_one(s, 0, &img, err)))
		return ret;
	format_of(img, &s->meta, &s->fmt);
	kg_image_free(&img);
	s->have_fmt = 1;
	return 0;
}

static int gp2_get_format(void *state, kg_frame_format *out, kg_err *err)
{
	gp_state *s = state;
	int ret = learn_format(s, err);
	if (!ret)
		*out = s->fmt;
	return ret;
}

static int gp2_set_format(void *state, const kg_frame_format *want, kg_frame_format *got,
                          kg_err *err)
{
	gp_state *s = state;
	int ret = learn_format(s, err);
	if (ret)
		return ret;
	if ((want->pixfmt && want->pixfmt != KG_PIX_BAYER16) || (want->bits && want->bits != 16) ||
	    (want->cfa[0] && strcmp(want->cfa, s->fmt.cfa)) ||
	    (want->width && want->width != s->fmt.width) ||
	    (want->height && want->height != s->fmt.height) || want->offset_x || want->offset_y)
		return kg_fail(err, KG_ENOTSUP,
		               "camera %s delivers its raw as bayer16 %s %dx%d (the whole visible "
		               "area) only",
		               s->model, s->fmt.cfa, s->fmt.width, s->fmt.height);
	*got = s->fmt;
	return 0;
}

static int gp2_start(void *state, int nbuffers, kg_err *err)
{
	gp_state *s = state;
	(void)nbuffers; /* one frame at a time: each pop is a capture */
	int ret = learn_format(s, err);
	if (ret)
		return ret;
	if (s->frame_cap < s->fmt.size) {
		uint8_t *b = realloc(s->frame, s->fmt.size);
		if (!b)
			return kg_fail(err, KG_ENOMEM, "out of memory for a %dx%d frame", s->fmt.width,
			               s->fmt.height);
		s->frame = b;
		s->frame_cap = s->fmt.size;
	}
	s->streaming = 1;
	s->held = 0;
	s->failed = 0;
	return 0;
}

static int gp2_stop(void *state, kg_err *err)
{
	gp_state *s = state;
	(void)err;
	s->streaming = 0;
	s->held = 0;
	return 0;
}

static int gp2_pop(void *state, int timeout_ms, kg_frame *frame, kg_err *err)
{
	gp_state *s = state;
	if (s->held)
		return kg_fail(err, KG_EINVAL,
		               "camera %s: frame %llu is still held (push it back before the next "
		               "capture)",
		               s->model, (unsigned long long)s->seq);
	kg_image *img = NULL;
	s->seq++;
	double ts = now_s();
	int ret = capture_one(s, timeout_ms, &img, err);
	if (ret) {
		s->failed++;
		return ret;
	}
	if (img->width != s->fmt.width || img->height != s->fmt.height ||
	    strcmp(s->meta.cfa, s->fmt.cfa)) {
		ret = kg_fail(err, KG_EIO,
		              "camera %s: capture %llu (%s) is %dx%d %s, the stream is %dx%d %s (the "
		              "image size or crop changed on the camera)",
		              s->model, (unsigned long long)s->seq, s->file_name, img->width,
		              img->height, s->meta.cfa, s->fmt.width, s->fmt.height, s->fmt.cfa);
		kg_image_free(&img);
		s->failed++;
		return ret;
	}
	kg_gp_to_bayer16(img->data, (size_t)img->width * (size_t)img->height, s->frame);
	kg_image_free(&img);
	frame->fmt = s->fmt;
	frame->data = s->frame;
	frame->size = s->fmt.size;
	frame->sequence = s->seq;
	frame->timestamp = ts;
	frame->status = KG_FRAME_OK;
	frame->slot = 0;
	if (isfinite(s->meta.exposure_s) && s->meta.exposure_s > 0)
		frame->exposure_us = s->meta.exposure_s * 1e6;
	/* frame->gain stays unknown: a DSLR's sensor gain is its ISO speed, a feature of
	 * its own (KG_FEAT_ISO); the file's ISO is in kg_gphoto2_last_file's metadata. */
	frame->source = s->saved[0] ? s->saved : NULL;
	frame->source_note = s->note;
	s->held = 1;
	return 0;
}

static int gp2_push(void *state, kg_frame *frame, kg_err *err)
{
	gp_state *s = state;
	if (!s->held || frame->slot != 0)
		return kg_fail(err, KG_EINVAL, "frame %llu is not held",
		               (unsigned long long)frame->sequence);
	s->held = 0;
	frame->data = NULL;
	return 0;
}

static void gp2_stats(void *state, kg_stream_stats *out)
{
	gp_state *s = state;
	out->failed = s->failed;
}

/* ---- live view ---------------------------------------------------------------- */

/* The width and height in the first SOF marker of a JPEG; -1 when there is none. */
static int jpeg_size(const unsigned char *d, size_t n, int *w, int *h)
{
	size_t i = 2;
	if (n < 4 || d[0] != 0xFF || d[1] != 0xD8)
		return -1;
	while (i + 9 < n) {
		if (d[i] != 0xFF) {
			i++;
			continue;
		}
		unsigned m = d[i + 1];
		if (m == 0xFF || m == 0x01 || (m >= 0xD0 && m <= 0xD7)) {
			i += m == 0xFF ? 1 : 2;
			continue;
		}
		size_t len = (size_t)(d[i + 2] << 8 | d[i + 3]);
		if (m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC) {
			*h = d[i + 5] << 8 | d[i + 6];
			*w = d[i + 7] << 8 | d[i + 8];
			return *w > 0 && *h > 0 ? 0 : -1;
		}
		i += 2 + len;
	}
	return -1;
}

/* The camera's live view (libgphoto2's capture preview: the viewfinder image the
 * camera streams, never an exposure to the card), delivered as an MJPEG frame. */
static int gp2_preview(void *state, int timeout_ms, kg_frame *frame, kg_err *err)
{
	gp_state *s = state;
	(void)timeout_ms; /* libgphoto2's own timeouts apply */
	if (s->preview) {
		gp_file_unref(s->preview);
		s->preview = NULL;
	}
	int gpret = gp_file_new(&s->preview);
	if (gpret < GP_OK)
		return gpfail(s, err, KG_ENOMEM, gpret, "camera %s: live view", s->model);
	gpret = gp_camera_capture_preview(s->cam, s->preview, s->ctx);
	if (gpret < GP_OK)
		return gpfail(s, err, gpret == GP_ERROR_NOT_SUPPORTED ? KG_ENOTSUP : KG_EIO, gpret,
		              "camera %s: no live view image (libgphoto2's capture preview; the "
		              "live view never falls back to full exposures)",
		              s->model);
	const char *data = NULL;
	unsigned long size = 0;
	int w = 0, h = 0;
	gp_file_get_data_and_size(s->preview, &data, &size);
	if (!data || jpeg_size((const unsigned char *)data, size, &w, &h))
		return kg_fail(err, KG_EIO, "camera %s: the live view image (%lu bytes) is not a "
		               "JPEG", s->model, size);
	s->previews++;
	memset(&frame->fmt, 0, sizeof(frame->fmt));
	frame->fmt.pixfmt = KG_PIX_MJPEG;
	frame->fmt.width = w;
	frame->fmt.height = h;
	frame->fmt.bits = 8;
	frame->fmt.size = size;
	frame->data = data;
	frame->size = size;
	frame->sequence = s->previews;
	frame->timestamp = now_s();
	frame->status = KG_FRAME_OK;
	frame->slot = -1;
	return 0;
}

int kg_gphoto2_counts(kg_camera *c, uint64_t *captures, uint64_t *previews)
{
	gp_state *s = kg_camera_driver_state(c, &kg_camera_gphoto2_driver);
	if (!s)
		return KG_EINVAL;
	*captures = s->captures;
	*previews = s->previews;
	return 0;
}

int kg_gphoto2_last_file(kg_camera *c, const void **data, size_t *size, const char **name,
                         kg_raw_meta *meta, kg_err *err)
{
	gp_state *s = kg_camera_driver_state(c, &kg_camera_gphoto2_driver);
	if (!s)
		return kg_fail(err, KG_EINVAL, "not a gphoto2: camera");
	if (!s->have_file)
		return kg_fail(err, KG_ENOENT, "camera %s: nothing captured yet", s->model);
	*data = s->file;
	*size = s->file_size;
	if (name)
		*name = s->file_name;
	if (meta)
		*meta = s->meta;
	return 0;
}

/* ---- enumeration -------------------------------------------------------------- */

/* 1 when libgphoto2_port's ptpip I/O library links libdns_sd (Bonjour: it browses the
 * network while listing ports). The library's folder: $IOLIBS as libgphoto2_port reads
 * it, else where it was built to look. */
static int ptpip_browses(void)
{
	const char *dir = getenv("IOLIBS");
	if (!dir || !*dir)
		dir = KG_GP_IOLIB_DIR;
	char path[1024];
	snprintf(path, sizeof(path), "%s/ptpip.so", dir);
	FILE *f = fopen(path, "rb");
	if (!f)
		return 0;
	static const char needle[] = "libdns_sd";
	size_t k = sizeof(needle) - 1, have = 0;
	char buf[65536 + sizeof(needle)];
	int hit = 0;
	for (;;) {
		size_t n = fread(buf + have, 1, sizeof(buf) - have, f);
		if (!n)
			break;
		have += n;
		for (size_t i = 0; i + k <= have && !hit; i++)
			hit = !memcmp(buf + i, needle, k);
		if (hit)
			break;
		/* keep the tail: a match may straddle two reads */
		memmove(buf, buf + have - (k - 1), k - 1);
		have = k - 1;
	}
	fclose(f);
	return hit;
}

static int gp2_enumerate(kg_camera_found_fn found, void *user, kg_err *err)
{
	const char *disc = getenv("KOGEI_CAMERA_DISCOVERY");
	if (disc && !strcmp(disc, "none") && ptpip_browses())
		return kg_fail(err, KG_ENOTSUP,
		               "not scanned: this libgphoto2 browses the network (mDNS) for PTP/IP "
		               "cameras and network discovery is off (KOGEI_CAMERA_DISCOVERY=none); "
		               "open USB cameras by port: gphoto2:usb:BBB,DDD");
	gp_state s;
	memset(&s, 0, sizeof(s));
	s.ctx = gp_context_new();
	if (!s.ctx)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	gp_context_set_error_func(s.ctx, on_gp_error, &s);
	lists l;
	int ret = lists_load(&s, &l, err);
	if (ret) {
		gp_context_unref(s.ctx);
		return ret;
	}
	int count = gp_list_count(l.found);
	for (int i = 0; i < count; i++) {
		const char *m = NULL, *p = NULL;
		gp_list_get_name(l.found, i, &m);
		gp_list_get_value(l.found, i, &p);
		if (!m || !p)
			continue;
		/* by model, or by port when another attached camera has the same model */
		int same = 0;
		for (int j = 0; j < count; j++) {
			const char *o = NULL;
			gp_list_get_name(l.found, j, &o);
			same += o && !strcasecmp(o, m);
		}
		char uri[300];
		snprintf(uri, sizeof(uri), "gphoto2:%s", same > 1 ? p : m);
		CameraAbilities a;
		memset(&a, 0, sizeof(a));
		int ai = gp_abilities_list_lookup_model(l.abilities, m);
		if (ai >= GP_OK)
			gp_abilities_list_get_abilities(l.abilities, ai, &a);
		GPPortType t = GP_PORT_NONE;
		GPPortInfo pi;
		int k = gp_port_info_list_lookup_path(l.ports, p);
		if (k >= GP_OK && gp_port_info_list_get_info(l.ports, k, &pi) >= GP_OK)
			gp_port_info_get_type(pi, &t);
		char transport[64];
		snprintf(transport, sizeof(transport), "%s at %s", transport_of(t, &a), p);
		found(user, uri, m, "", transport);
	}
	lists_free(&l);
	gp_context_unref(s.ctx);
	return 0;
}

const kg_camera_driver kg_camera_gphoto2_driver = {
	.scheme = "gphoto2",
	.description = "tethered DSLR / mirrorless cameras through libgphoto2, raw captures "
	               "(gphoto2:<model> or gphoto2:usb:BBB,DDD[?delete=1])",
	.enumerate = gp2_enumerate,
	.open = gp2_open,
	.close = gp2_close,
	.feature_info = gp2_feature_info,
	.get = gp2_get,
	.set = gp2_set,
	.set_format = gp2_set_format,
	.get_format = gp2_get_format,
	.start = gp2_start,
	.stop = gp2_stop,
	.pop = gp2_pop,
	.push = gp2_push,
	.stats = gp2_stats,
	.preview = gp2_preview,
};
