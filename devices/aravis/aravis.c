/* GigE Vision and USB3 Vision cameras through Aravis 0.8 (driver table:
 * camera_driver.h). GLib and Aravis stay inside this file.
 *
 *   aravis:<IPv4 address>[?options]   a GigE Vision camera opened directly: no
 *                                     discovery, every packet goes to that address
 *   aravis:<device id>[?options]      any camera Aravis can find by id (GigE Vision,
 *                                     USB3 Vision, or Fake_1, Aravis' in-process fake)
 *   options: packet_size=BYTES (GigE; default: negotiated by Aravis),
 *            socket_buffer=BYTES (GigE receive buffer; default: sized by Aravis)
 *
 * Discovery broadcasts on every network interface, so it is gated by the environment
 * variable KOGEI_CAMERA_DISCOVERY: unset or "all" searches every interface, "usb" only
 * USB3 Vision, "none" nothing (only addresses and Fake_1 open).
 *
 * Frames move through a fixed pool of ArvBuffers: pop waits for a filled buffer, push
 * gives it back to the stream. Each buffer carries its slot number as user data. */
#include <arpa/inet.h>
#include <errno.h>
#include <math.h>
#include <netinet/in.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include <arv.h>

#include "aravis_hook.h"
#include "camera_driver.h"

#define DEFAULT_BUFFERS 8
#define GVCP_PORT 3956

static kg_aravis_open_hook open_hook;
static void *open_hook_user;

void kg_aravis_set_open_hook(kg_aravis_open_hook hook, void *user)
{
	open_hook = hook;
	open_hook_user = user;
}

/* ---- pixel formats ------------------------------------------------------------ */

static const struct {
	ArvPixelFormat arv;
	const char *name; /* GenICam name, for messages */
	kg_pixfmt f;
	int bits;
	const char *cfa;
} pixfmts[] = {
	{ARV_PIXEL_FORMAT_MONO_8, "Mono8", KG_PIX_MONO8, 8, ""},
	{ARV_PIXEL_FORMAT_MONO_10, "Mono10", KG_PIX_MONO16, 10, ""},
	{ARV_PIXEL_FORMAT_MONO_12, "Mono12", KG_PIX_MONO16, 12, ""},
	{ARV_PIXEL_FORMAT_MONO_14, "Mono14", KG_PIX_MONO16, 14, ""},
	{ARV_PIXEL_FORMAT_MONO_16, "Mono16", KG_PIX_MONO16, 16, ""},
	{ARV_PIXEL_FORMAT_BAYER_RG_8, "BayerRG8", KG_PIX_BAYER8, 8, "RGGB"},
	{ARV_PIXEL_FORMAT_BAYER_GR_8, "BayerGR8", KG_PIX_BAYER8, 8, "GRBG"},
	{ARV_PIXEL_FORMAT_BAYER_GB_8, "BayerGB8", KG_PIX_BAYER8, 8, "GBRG"},
	{ARV_PIXEL_FORMAT_BAYER_BG_8, "BayerBG8", KG_PIX_BAYER8, 8, "BGGR"},
	{ARV_PIXEL_FORMAT_BAYER_RG_10, "BayerRG10", KG_PIX_BAYER16, 10, "RGGB"},
	{ARV_PIXEL_FORMAT_BAYER_GR_10, "BayerGR10", KG_PIX_BAYER16, 10, "GRBG"},
	{ARV_PIXEL_FORMAT_BAYER_GB_10, "BayerGB10", KG_PIX_BAYER16, 10, "GBRG"},
	{ARV_PIXEL_FORMAT_BAYER_BG_10, "BayerBG10", KG_PIX_BAYER16, 10, "BGGR"},
	{ARV_PIXEL_FORMAT_BAYER_RG_12, "BayerRG12", KG_PIX_BAYER16, 12, "RGGB"},
	{ARV_PIXEL_FORMAT_BAYER_GR_12, "BayerGR12", KG_PIX_BAYER16, 12, "GRBG"},
	{ARV_PIXEL_FORMAT_BAYER_GB_12, "BayerGB12", KG_PIX_BAYER16, 12, "GBRG"},
	{ARV_PIXEL_FORMAT_BAYER_BG_12, "BayerBG12", KG_PIX_BAYER16, 12, "BGGR"},
	{ARV_PIXEL_FORMAT_BAYER_RG_16, "BayerRG16", KG_PIX_BAYER16, 16, "RGGB"},
	{ARV_PIXEL_FORMAT_BAYER_GR_16, "BayerGR16", KG_PIX_BAYER16, 16, "GRBG"},
	{ARV_PIXEL_FORMAT_BAYER_GB_16, "BayerGB16", KG_PIX_BAYER16, 16, "GBRG"},
	{ARV_PIXEL_FORMAT_BAYER_BG_16, "BayerBG16", KG_PIX_BAYER16, 16, "BGGR"},
	{ARV_PIXEL_FORMAT_RGB_8_PACKED, "RGB8", KG_PIX_RGB8, 8, ""},
};
#define NPIXFMTS ((int)(sizeof(pixfmts) / sizeof(pixfmts[0])))

static int pixfmt_index(ArvPixelFormat pf)
{
	for (int i = 0; i < NPIXFMTS; i++)
		if (pixfmts[i].arv == pf)
			return i;
	return -1;
}

/* ---- features ----------------------------------------------------------------- */

typedef enum { K_NONE = 0, K_FLOAT, K_INT, K_AUTO } feat_kind;

/* A kogei feature as this camera offers it: a GenICam feature, maybe behind a
 * selector (BalanceRatioSelector=Red), maybe with a companion set together with it
 * (GainAuto beside ExposureAuto). */
typedef struct feat {
	feat_kind kind;
	const char *name;
	const char *selector, *entry;
	const char *companion; /* another auto feature, K_AUTO only */
	const char *unit;
} feat;

typedef struct arv_state {
	ArvCamera *cam;
	ArvDevice *dev; /* owned by cam */
	int is_gv;
	int packet_size;   /* 0: negotiated */
	int socket_buffer; /* 0: Aravis' automatic size */
	feat feats[KG_FEAT_COUNT];
	gulong lost_handler;
	int control_lost; /* set from Aravis' heartbeat thread */

	/* stream */
	ArvStream *stream;
	ArvBuffer **held; /* buffers popped and not yet pushed back, by slot */
	int nbuf;
	kg_frame_format fmt;
	int have_id;
	guint64 last_id, seq;
	uint64_t incomplete, corrupt; /* frames delivered with that status */
} arv_state;

static int gfail(kg_err *err, int code, GError **e, const char *fmt, ...) KG_PRINTF(4, 5);

/* kg_fail with the GError's message appended; frees the GError. */
static int gfail(kg_err *err, int code, GError **e, const char *fmt, ...)
{
	char what[512];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(what, sizeof(what), fmt, ap);
	va_end(ap);
	int ret = kg_fail(err, code, "%s: %s", what, e && *e ? (*e)->message : "failed");
	if (e)
		g_clear_error(e);
	return ret;
}

static int available(arv_state *s, const char *name)
{
	GError *e = NULL;
	int ok = arv_camera_is_feature_available(s->cam, name, &e);
	g_clear_error(&e);
	return ok;
}

static feat_kind numeric_kind(arv_state *s, const char *name)
{
	ArvGcNode *node = arv_device_get_feature(s->dev, name);
	if (!node || !available(s, name))
		return K_NONE;
	if (ARV_IS_GC_FLOAT(node))
		return K_FLOAT;
	if (ARV_IS_GC_INTEGER(node))
		return K_INT;
	return K_NONE;
}

/* The first of names the camera offers as a number. */
static void resolve_numeric(arv_state *s, feat *f, const char *const *names,
                            const char *const *units)
{
	for (int i = 0; names[i]; i++) {
		feat_kind k = numeric_kind(s, names[i]);
		if (k != K_NONE) {
			f->kind = k;
			f->name = names[i];
			f->unit = units[i];
			return;
		}
	}
}

static int has_enum_entry(arv_state *s, const char *feature, const char *entry)
{
	GError *e = NULL;
	int ok = available(s, feature) &&
	         arv_camera_is_enumeration_entry_available(s->cam, feature, entry, &e);
	g_clear_error(&e);
	return ok;
}

static void resolve_features(arv_state *s)
{
	memset(s->feats, 0, sizeof(s->feats));
	resolve_numeric(s, &s->feats[KG_FEAT_EXPOSURE_US],
	                (const char *const[]){"ExposureTime", "ExposureTimeAbs", NULL},
	                (const char *const[]){"us", "us"});
	resolve_numeric(s, &s->feats[KG_FEAT_GAIN],
	                (const char *const[]){"Gain", "GainRaw", NULL},
	                (const char *const[]){"dB", "raw"});
	resolve_numeric(s, &s->feats[KG_FEAT_FRAME_RATE],
	                (const char *const[]){"AcquisitionFrameRate",
	                                      "AcquisitionFrameRateAbs", NULL},
	                (const char *const[]){"fps", "fps"});
	/* Auto exposure covers automatic gain too: either one changes the signal level. */
	feat *ae = &s->feats[KG_FEAT_AUTO_EXPOSURE];
	int has_ea = has_enum_entry(s, "ExposureAuto", "Off");
	int has_ga = has_enum_entry(s, "GainAuto", "Off");
	if (has_ea || has_ga) {
		ae->kind = K_AUTO;
		ae->name = has_ea ? "ExposureAuto" : "GainAuto";
		ae->companion = has_ea && has_ga ? "GainAuto" : NULL;
		ae->unit = "bool";
	}
	if (has_enum_entry(s, "BalanceWhiteAuto", "Off"))
		s->feats[KG_FEAT_AUTO_WHITE_BALANCE] =
			(feat){.kind = K_AUTO, .name = "BalanceWhiteAuto", .unit = "bool"};
	static const char *const ratio[] = {"BalanceRatio", "BalanceRatioAbs", NULL};
	static const char *const ratio_unit[] = {"x", "x"};
	for (int k = 0; k < 2; k++) {
		const char *entry = k ? "Blue" : "Red";
		feat *f = &s->feats[k ? KG_FEAT_WB_BLUE : KG_FEAT_WB_RED];
		if (!has_enum_entry(s, "BalanceRatioSelector", entry))
			continue;
		resolve_numeric(s, f, ratio, ratio_unit);
		f->selector = "BalanceRatioSelector";
		f->entry = entry;
	}
}

static int select_entry(arv_state *s, const feat *f, kg_err *err)
{
	if (!f->selector)
		return 0;
	GError *e = NULL;
	arv_camera_set_string(s->cam, f->selector, f->entry, &e);
	return e ? gfail(err, KG_EIO, &e, "%s: cannot select %s", f->selector, f->entry) : 0;
}

static int arv_feature_info(void *state, kg_feature kf, kg_feature_info *out, kg_err *err)
{
	arv_state *s = state;
	const feat *f = &s->feats[kf];
	if (f->kind == K_NONE)
		return 0;
	int ret = select_entry(s, f, err);
	if (ret)
		return ret;
	out->available = 1;
	ArvGcAccessMode mode = arv_device_get_feature_access_mode(s->dev, f->name);
	out->writable = mode == ARV_GC_ACCESS_MODE_RW || mode == ARV_GC_ACCESS_MODE_WO;
	snprintf(out->unit, sizeof(out->unit), "%s", f->unit);
	if (f->companion)
		snprintf(out->native, sizeof(out->native), "%s+%s", f->name, f->companion);
	else if (f->selector)
		snprintf(out->native, sizeof(out->native), "%s[%s]", f->name, f->entry);
	else
		snprintf(out->native, sizeof(out->native), "%s", f->name);
	GError *e = NULL;
	switch (f->kind) {
	case K_FLOAT: {
		arv_camera_get_float_bounds(s->cam, f->name, &out->min, &out->max, &e);
		/* Cameras without an increment report 0 or the smallest double: continuous. */
		double inc = e ? 0 : arv_camera_get_float_increment(s->cam, f->name, NULL);
		out->step = inc > 1e-9 && isfinite(inc) ? inc : 0;
		break;
	}
	case K_INT: {
		gint64 lo = 0, hi = 0;
		arv_camera_get_integer_bounds(s->cam, f->name, &lo, &hi, &e);
		gint64 inc = e ? 1 : arv_camera_get_integer_increment(s->cam, f->name, NULL);
		out->min = (double)lo;
		out->max = (double)hi;
		out->step = inc > 0 ? (double)inc : 1;
		break;
	}
	default:
		out->min = 0;
		out->max = 1;
		out->step = 1;
		break;
	}
	return e ? gfail(err, KG_EIO, &e, "%s: cannot read its bounds", f->name) : 0;
}

/* Before reading or setting feature kf: refused when the camera has no control for it;
 * its selector entry chosen when it has one. */
static int control_of(arv_state *s, kg_feature kf, kg_err *err)
{
	if (s->feats[kf].kind == K_NONE)
		return kg_fail(err, KG_ENOTSUP, "the camera has no control for %s",
		               kg_feature_name(kf));
	return select_entry(s, &s->feats[kf], err);
}

static int arv_get(void *state, kg_feature kf, double *value, kg_err *err)
{
	arv_state *s = state;
	const feat *f = &s->feats[kf];
	int ret = control_of(s, kf, err);
	if (ret)
		return ret;
	GError *e = NULL;
	switch (f->kind) {
	case K_FLOAT:
		*value = arv_camera_get_float(s->cam, f->name, &e);
		break;
	case K_INT:
		*value = (double)arv_camera_get_integer(s->cam, f->name, &e);
		break;
	default: {
		/* On when any of the pair is not Off. */
		const char *names[2] = {f->name, f->companion};
		*value = 0;
		for (int i = 0; i < 2 && names[i] && !e; i++) {
			const char *v = arv_camera_get_string(s->cam, names[i], &e);
			if (!e && v && strcmp(v, "Off"))
				*value = 1;
		}
		break;
	}
	}
	return e ? gfail(err, KG_EIO, &e, "%s: cannot read", f->name) : 0;
}

static int arv_set(void *state, kg_feature kf, double value, kg_err *err)
{
	arv_state *s = state;
	const feat *f = &s->feats[kf];
	int ret = control_of(s, kf, err);
	if (ret)
		return ret;
	GError *e = NULL;
	switch (f->kind) {
	case K_FLOAT:
		/* Some cameras ignore AcquisitionFrameRate until it is enabled. */
		if (kf == KG_FEAT_FRAME_RATE && available(s, "AcquisitionFrameRateEnable"))
			arv_camera_set_boolean(s->cam, "AcquisitionFrameRateEnable", TRUE, &e);
		if (!e)
			arv_camera_set_float(s->cam, f->name, value, &e);
		break;
	case K_INT:
		arv_camera_set_integer(s->cam, f->name, (gint64)llround(value), &e);
		break;
	default: {
		const char *v = value != 0 ? "Continuous" : "Off";
		const char *names[2] = {f->name, f->companion};
		for (int i = 0; i < 2 && names[i] && !e; i++)
			arv_camera_set_string(s->cam, names[i], v, &e);
		break;
	}
	}
	return e ? gfail(err, KG_EIO, &e, "%s: cannot set %g", f->name, value) : 0;
}

/* ---- format ------------------------------------------------------------------- */

static int arv_get_format(void *state, kg_frame_format *out, kg_err *err)
{
	arv_state *s = state;
	GError *e = NULL;
	ArvPixelFormat pf = arv_camera_get_pixel_format(s->cam, &e);
	if (e)
		return gfail(err, KG_EIO, &e, "PixelFormat: cannot read");
	int i = pixfmt_index(pf);
	if (i < 0) {
		const char *name = arv_camera_get_pixel_format_as_string(s->cam, NULL);
		return kg_fail(err, KG_ENOTSUP,
		               "PixelFormat %s (0x%08x) is not one kogei reads: expected Mono8, "
		               "Mono10/12/14/16, Bayer RG/GR/GB/BG 8/10/12/16 or RGB8 (set one "
		               "with the pixel format option)",
		               name ? name : "?", (unsigned)pf);
	}
	int x = 0, y = 0, w = 0, h = 0;
	arv_camera_get_region(s->cam, &x, &y, &w, &h, &e);
	if (e)
		return gfail(err, KG_EIO, &e, "OffsetX/OffsetY/Width/Height: cannot read");
	memset(out, 0, sizeof(*out));
	out->pixfmt = pixfmts[i].f;
	out->bits = pixfmts[i].bits;
	snprintf(out->cfa, sizeof(out->cfa), "%s", pixfmts[i].cfa);
	out->width = w;
	out->height = h;
	out->offset_x = x;
	out->offset_y = y;
	kg_frame_format_fill(out);
	return 0;
}

/* The camera's pixel format for a request: the family must match, bits and CFA when
 * given; otherwise the deepest format, preferring the current CFA. */
static int choose_pixfmt(arv_state *s, const kg_frame_format *want, ArvPixelFormat *out,
                         kg_err *err)
{
	GError *e = NULL;
	guint n = 0;
	gint64 *have = arv_camera_dup_available_pixel_formats(s->cam, &n, &e);
	if (e)
		return gfail(err, KG_EIO, &e, "PixelFormat: cannot list the formats offered");
	ArvPixelFormat cur = arv_camera_get_pixel_format(s->cam, NULL);
	int cur_i = pixfmt_index(cur);
	const char *cur_cfa = cur_i >= 0 ? pixfmts[cur_i].cfa : "";
	int best = -1, best_rank = 0;
	for (guint k = 0; k < n; k++) {
		int i = pixfmt_index((ArvPixelFormat)have[k]);
		if (i < 0 || pixfmts[i].f != want->pixfmt)
			continue;
		if (want->bits && pixfmts[i].bits != want->bits)
			continue;
		if (want->cfa[0] && strcmp(want->cfa, pixfmts[i].cfa))
			continue;
		/* Among equally deep formats: the current one, then one with its CFA. */
		int rank = 0;
		if (pixfmts[i].arv == cur)
			rank = 2;
		else if (pixfmts[i].cfa[0] && !strcmp(pixfmts[i].cfa, cur_cfa))
			rank = 1;
		if (best < 0 || pixfmts[i].bits > pixfmts[best].bits ||
		    (pixfmts[i].bits == pixfmts[best].bits && rank > best_rank)) {
			best = i;
			best_rank = rank;
		}
	}
	if (best >= 0) {
		*out = pixfmts[best].arv;
		g_free(have);
		return 0;
	}
	g_free(have);
	char offered[512] = "";
	size_t len = 0;
	const char **names = arv_camera_dup_available_pixel_formats_as_strings(s->cam, &n, NULL);
	for (guint k = 0; names && k < n && len < sizeof(offered); k++)
		len += (size_t)snprintf(offered + len, sizeof(offered) - len, "%s%s", len ? ", " : "",
		                        names[k]);
	g_free(names);
	char asked[64];
	int len_asked = snprintf(asked, sizeof(asked), "%s", kg_pixfmt_name(want->pixfmt));
	if (want->bits)
		len_asked += snprintf(asked + len_asked, sizeof(asked) - (size_t)len_asked,
		                      " with %d bits", want->bits);
	if (want->cfa[0])
		snprintf(asked + len_asked, sizeof(asked) - (size_t)len_asked, " %s", want->cfa);
	return kg_fail(err, KG_ENOTSUP, "PixelFormat: no %s format among those offered (%s)",
	               asked, offered);
}

static int arv_set_format(void *state, const kg_frame_format *want, kg_frame_format *got,
                          kg_err *err)
{
	arv_state *s = state;
	GError *e = NULL;
	int ret;
	if (want->pixfmt != KG_PIX_NONE) {
		ArvPixelFormat pf;
		if ((ret = choose_pixfmt(s, want, &pf, err)))
			return ret;
		arv_camera_set_pixel_format(s->cam, pf, &e);
		if (e)
			return gfail(err, KG_EIO, &e, "PixelFormat: cannot set %s",
			             pixfmts[pixfmt_index(pf)].name);
	}
	if (want->width || want->height || want->offset_x || want->offset_y) {
		int x = 0, y = 0, w = 0, h = 0, sw = 0, sh = 0;
		arv_camera_get_region(s->cam, &x, &y, &w, &h, &e);
		if (!e)
			arv_camera_get_sensor_size(s->cam, &sw, &sh, &e);
		if (e)
			return gfail(err, KG_EIO, &e, "region: cannot read");
		/* A new size places the region at the offsets given (0 included); offsets
		 * alone move the current region. */
		int resize = want->width || want->height;
		int nx = resize || want->offset_x ? want->offset_x : x;
		int ny = resize || want->offset_y ? want->offset_y : y;
		int nw = want->width ? want->width : w, nh = want->height ? want->height : h;
		if (nx < 0 || ny < 0 || nw <= 0 || nh <= 0 || nx + nw > sw || ny + nh > sh)
			return kg_fail(err, KG_ERANGE,
			               "region %dx%d at (%d,%d): expected a region inside the %dx%d "
			               "sensor",
			               nw, nh, nx, ny, sw, sh);
		arv_camera_set_region(s->cam, nx, ny, nw, nh, &e);
		if (e)
			return gfail(err, KG_EIO, &e, "region %dx%d at (%d,%d): cannot set", nw, nh, nx,
			             ny);
	}
	/* Some features exist only in some formats (white balance in colour ones). */
	resolve_features(s);
	return arv_get_format(s, got, err);
}

/* ---- open and close ----------------------------------------------------------- */

typedef enum { DISCOVER_ALL, DISCOVER_USB, DISCOVER_NONE } discovery;

static int discovery_policy(discovery *d, kg_err *err)
{
	const char *v = getenv("KOGEI_CAMERA_DISCOVERY");
	if (!v || !*v || !strcmp(v, "all"))
		*d = DISCOVER_ALL;
	else if (!strcmp(v, "usb"))
		*d = DISCOVER_USB;
	else if (!strcmp(v, "none"))
		*d = DISCOVER_NONE;
	else
		return kg_fail(err, KG_EINVAL,
		               "KOGEI_CAMERA_DISCOVERY '%s': expected all, usb or none", v);
	return 0;
}

/* Aravis keeps one process-wide list of enabled interfaces: set it to the policy
 * before anything that may search. */
static void apply_discovery(discovery d, int fake)
{
	for (unsigned i = 0; i < arv_get_n_interfaces(); i++) {
		const char *id = arv_get_interface_id(i);
		int on;
		if (!strcmp(id, "GigEVision"))
			on = d == DISCOVER_ALL;
		else if (!strcmp(id, "USB3Vision"))
			on = d != DISCOVER_NONE;
		else if (!strcmp(id, "Fake"))
			on = fake;
		else
			on = d == DISCOVER_ALL;
		if (on)
			arv_enable_interface(id);
		else
			arv_disable_interface(id);
	}
}

static int parse_bytes(const char *key, const char *v, long lo, long hi, int *out, kg_err *err)
{
	char *end;
	long n = strtol(v, &end, 10);
	if (end == v || *end || n < lo || n > hi)
		return kg_fail(err, KG_EINVAL, "option %s=%s: expected a whole number of bytes %ld..%ld",
		               key, v, lo, hi);
	*out = (int)n;
	return 0;
}

static int arv_option(void *user, const char *key, const char *value, kg_err *err)
{
	arv_state *s = user;
	if (value && !strcmp(key, "packet_size"))
		return parse_bytes(key, value, 576, 65500, &s->packet_size, err);
	if (value && !strcmp(key, "socket_buffer"))
		return parse_bytes(key, value, 4096, 1L << 30, &s->socket_buffer, err);
	return kg_fail(err, KG_EINVAL,
	               "option '%s': expected packet_size=BYTES or socket_buffer=BYTES", key);
}

/* target = NAME[?key=value&...]; name is copied into name (size n). */
static int parse_target(arv_state *s, const char *target, char *name, size_t n, kg_err *err)
{
	return kg_camera_target_split(target, name, n,
	                              "aravis:<IPv4 address or device id>[?packet_size=N&"
	                              "socket_buffer=N]",
	                              arv_option, s, err);
}

/* The local address the kernel would send from to reach addr. connect() on a UDP
 * socket only looks up the route: nothing is sent. */
static int local_address_for(const struct in_addr *addr, struct in_addr *local, kg_err *err)
{
	int fd = socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
	struct sockaddr_in sa = {.sin_family = AF_INET, .sin_port = htons(GVCP_PORT),
	                         .sin_addr = *addr};
	socklen_t sl = sizeof(sa);
	int ok = fd >= 0 && connect(fd, (struct sockaddr *)&sa, sizeof(sa)) == 0 &&
	         getsockname(fd, (struct sockaddr *)&sa, &sl) == 0;
	int e = errno;
	if (fd >= 0)
		close(fd);
	if (!ok)
		return kg_fail(err, KG_ENODEV, "no route to the camera: %s", strerror(e));
	*local = sa.sin_addr;
	return 0;
}

static void on_control_lost(ArvDevice *dev, gpointer user)
{
	arv_state *s = user;
	__atomic_store_n(&s->control_lost, 1, __ATOMIC_RELEASE);
}

static int open_by_address(arv_state *s, const struct in_addr *addr, kg_err *err)
{
	struct in_addr local;
	int ret = local_address_for(addr, &local, err);
	if (ret)
		return ret;
	GInetAddress *dev_addr = g_inet_address_new_from_bytes((const guint8 *)addr,
	                                                       G_SOCKET_FAMILY_IPV4);
	GInetAddress *if_addr = g_inet_address_new_from_bytes((const guint8 *)&local,
	                                                      G_SOCKET_FAMILY_IPV4);
	GError *e = NULL;
	ArvDevice *dev = arv_gv_device_new(if_addr, dev_addr, &e);
	g_object_unref(dev_addr);
	g_object_unref(if_addr);
	if (!dev)
		return gfail(err, KG_ENODEV, &e, "no GigE Vision camera answers");
	s->cam = arv_camera_new_with_device(dev, &e);
	g_object_unref(dev);
	if (!s->cam)
		return gfail(err, KG_ENODEV, &e, "cannot open the GigE Vision camera");
	return 0;
}

static int open_by_id(arv_state *s, const char *id, kg_err *err)
{
	discovery d;
	int ret = discovery_policy(&d, err);
	if (ret)
		return ret;
	apply_discovery(d, !strncmp(id, "Fake_", 5));
	GError *e = NULL;
	s->cam = arv_camera_new(id, &e);
	if (s->cam)
		return 0;
	if (d == DISCOVER_NONE)
		return gfail(err, KG_ENODEV, &e,
		             "no camera '%s' (discovery is off: KOGEI_CAMERA_DISCOVERY=none; open a "
		             "GigE Vision camera by its IPv4 address)",
		             id);
	return gfail(err, KG_ENODEV, &e, "no camera '%s' (see `kogei devices`)", id);
}

static void arv_close(void *state);

static int arv_open(const char *target, void **state, kg_camera_info *info, kg_err *err)
{
	arv_state *s = calloc(1, sizeof(*s));
	if (!s)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	char name[128];
	int ret = parse_target(s, target, name, sizeof(name), err);
	if (ret)
		goto error;
	struct in_addr addr;
	if (inet_pton(AF_INET, name, &addr) == 1)
		ret = open_by_address(s, &addr, err);
	else
		ret = open_by_id(s, name, err);
	if (ret)
		goto error;
	if (open_hook)
		open_hook(open_hook_user, s->cam);
	s->dev = arv_camera_get_device(s->cam);
	s->is_gv = arv_camera_is_gv_device(s->cam);
	if ((s->packet_size || s->socket_buffer) && !s->is_gv) {
		ret = kg_fail(err, KG_EINVAL,
		              "packet_size and socket_buffer apply to GigE Vision cameras only");
		goto error;
	}
	s->lost_handler = g_signal_connect(s->dev, "control-lost", G_CALLBACK(on_control_lost), s);
	resolve_features(s);

	GError *e = NULL;
	const char *v = arv_camera_get_vendor_name(s->cam, NULL);
	const char *m = arv_camera_get_model_name(s->cam, NULL);
	const char *sn = arv_camera_get_device_serial_number(s->cam, NULL);
	snprintf(info->vendor, sizeof(info->vendor), "%s", v ? v : "");
	snprintf(info->model, sizeof(info->model), "%s", m ? m : "");
	snprintf(info->serial, sizeof(info->serial), "%s", sn ? sn : "");
	snprintf(info->transport, sizeof(info->transport), "%s",
	         s->is_gv                        ? "GigE Vision"
	         : arv_camera_is_uv_device(s->cam) ? "USB3 Vision"
	         : ARV_IS_FAKE_DEVICE(s->dev)      ? "Aravis fake"
	                                           : "Aravis");
	arv_camera_get_sensor_size(s->cam, &info->sensor_width, &info->sensor_height, &e);
	g_clear_error(&e);
	*state = s;
	return 0;
error:
	arv_close(s);
	return ret;
}

static int arv_stop(void *state, kg_err *err);

static void arv_close(void *state)
{
	arv_state *s = state;
	if (!s)
		return;
	if (s->stream)
		arv_stop(s, NULL);
	if (s->lost_handler)
		g_signal_handler_disconnect(s->dev, s->lost_handler);
	if (s->cam)
		g_object_unref(s->cam);
	free(s);
}

/* ---- stream ------------------------------------------------------------------- */

static int gv_configure(arv_state *s, kg_err *err)
{
	GError *e = NULL;
	if (s->packet_size) {
		arv_camera_gv_set_packet_size_adjustment(s->cam, ARV_GV_PACKET_SIZE_ADJUSTMENT_NEVER);
		arv_camera_gv_set_packet_size(s->cam, s->packet_size, &e);
		if (e)
			return gfail(err, KG_EIO, &e, "GevSCPSPacketSize: cannot set %d",
			             s->packet_size);
	}
	return 0;
}

static void gv_stream_options(arv_state *s)
{
	g_object_set(s->stream, "packet-resend", ARV_GV_STREAM_PACKET_RESEND_ALWAYS, NULL);
	if (s->socket_buffer)
		g_object_set(s->stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_FIXED,
		             "socket-buffer-size", s->socket_buffer, NULL);
	else
		g_object_set(s->stream, "socket-buffer", ARV_GV_STREAM_SOCKET_BUFFER_AUTO, NULL);
}

static int arv_start(void *state, int nbuffers, kg_err *err)
{
	arv_state *s = state;
	int ret = arv_get_format(s, &s->fmt, err);
	if (ret)
		return ret;
	if (s->is_gv && (ret = gv_configure(s, err)))
		return ret;
	GError *e = NULL;
	guint payload = arv_camera_get_payload(s->cam, &e);
	if (e)
		return gfail(err, KG_EIO, &e, "PayloadSize: cannot read");
	if (payload < s->fmt.size)
		return kg_fail(err, KG_EIO,
		               "PayloadSize %u bytes cannot hold a %dx%d %s frame (%zu bytes)",
		               payload, s->fmt.width, s->fmt.height,
		               kg_pixfmt_name(s->fmt.pixfmt), s->fmt.size);
	s->nbuf = nbuffers > 0 ? nbuffers : DEFAULT_BUFFERS;
	s->held = calloc((size_t)s->nbuf, sizeof(*s->held));
	if (!s->held)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	s->stream = arv_camera_create_stream(s->cam, NULL, NULL, &e);
	if (!s->stream) {
		ret = gfail(err, KG_EIO, &e, "cannot create the stream");
		goto error;
	}
	if (ARV_IS_GV_STREAM(s->stream))
		gv_stream_options(s);
	for (int i = 0; i < s->nbuf; i++)
		arv_stream_push_buffer(s->stream,
		                       arv_buffer_new_full(payload, NULL, GINT_TO_POINTER(i + 1), NULL));
	s->have_id = 0;
	s->seq = 0;
	s->incomplete = s->corrupt = 0;
	__atomic_store_n(&s->control_lost, 0, __ATOMIC_RELEASE);
	arv_camera_set_acquisition_mode(s->cam, ARV_ACQUISITION_MODE_CONTINUOUS, &e);
	if (!e)
		arv_camera_start_acquisition(s->cam, &e);
	if (e) {
		ret = gfail(err, KG_EIO, &e, "cannot start the acquisition");
		goto error;
	}
	return 0;
error:
	if (s->stream)
		g_object_unref(s->stream);
	s->stream = NULL;
	free(s->held);
	s->held = NULL;
	return ret;
}

static int arv_stop(void *state, kg_err *err)
{
	arv_state *s = state;
	if (!s->stream)
		return 0;
	GError *e = NULL;
	/* A camera that no longer answers would only make each command wait out its
	 * retries. */
	if (!__atomic_load_n(&s->control_lost, __ATOMIC_ACQUIRE))
		arv_camera_stop_acquisition(s->cam, &e);
	/* Unreferencing the stream stops its thread and frees the buffers it holds; the
	 * ones the caller still holds are freed here. */
	g_object_unref(s->stream);
	s->stream = NULL;
	for (int i = 0; i < s->nbuf; i++)
		if (s->held[i])
			g_object_unref(s->held[i]);
	free(s->held);
	s->held = NULL;
	return e ? gfail(err, KG_EIO, &e, "cannot stop the acquisition") : 0;
}

static void aravis_counts(arv_state *s, guint64 *completed, guint64 *failures,
                          guint64 *underruns, guint64 *resent, guint64 *missing)
{
	*completed = *failures = *underruns = *resent = *missing = 0;
	if (!s->stream)
		return;
	arv_stream_get_statistics(s->stream, completed, failures, underruns);
	if (ARV_IS_GV_STREAM(s->stream))
		arv_gv_stream_get_statistics(ARV_GV_STREAM(s->stream), resent, missing);
}

/* Frame ids count 1..65535 and wrap to 1 (0 is invalid) on GigE Vision without
 * extended ids and on the fake camera; make them a monotonic sequence. */
static void advance_sequence(arv_state *s, guint64 id)
{
	if (!s->have_id)
		s->seq = id;
	else if (id > s->last_id)
		s->seq += id - s->last_id;
	else if (s->last_id <= 0xffff && s->last_id - id > 0x8000)
		s->seq += id + 0xffff - s->last_id;
	else
		s->seq += 1; /* a restarted counter: no gap can be told */
	s->have_id = 1;
	s->last_id = id;
}

static int buffer_status(arv_state *s, ArvBuffer *b)
{
	switch (arv_buffer_get_status(b)) {
	case ARV_BUFFER_STATUS_SUCCESS:
		break;
	case ARV_BUFFER_STATUS_TIMEOUT:
	case ARV_BUFFER_STATUS_MISSING_PACKETS:
	case ARV_BUFFER_STATUS_ABORTED:
	case ARV_BUFFER_STATUS_CLEARED:
		return KG_FRAME_INCOMPLETE;
	default:
		return KG_FRAME_CORRUPT;
	}
	ArvBufferPayloadType pt = arv_buffer_get_payload_type(b);
	if (pt != ARV_BUFFER_PAYLOAD_TYPE_IMAGE && pt != ARV_BUFFER_PAYLOAD_TYPE_EXTENDED_CHUNK_DATA)
		return KG_FRAME_CORRUPT;
	int i = pixfmt_index(arv_buffer_get_image_pixel_format(b));
	if (i < 0 || pixfmts[i].f != s->fmt.pixfmt || pixfmts[i].bits != s->fmt.bits ||
	    arv_buffer_get_image_width(b) != s->fmt.width ||
	    arv_buffer_get_image_height(b) != s->fmt.height)
		return KG_FRAME_CORRUPT;
	return KG_FRAME_OK;
}

static int arv_pop(void *state, int timeout_ms, kg_frame *frame, kg_err *err)
{
	arv_state *s = state;
	ArvBuffer *b = timeout_ms < 0
	                   ? arv_stream_pop_buffer(s->stream)
	                   : arv_stream_timeout_pop_buffer(s->stream, (guint64)timeout_ms * 1000u);
	if (!b) {
		guint64 c, f, u, r, m;
		aravis_counts(s, &c, &f, &u, &r, &m);
		if (__atomic_load_n(&s->control_lost, __ATOMIC_ACQUIRE))
			return kg_fail(err, KG_EIO,
			               "the camera stopped answering (control lost: no heartbeat "
			               "reply) after %llu complete frames; %llu failed, %llu underruns, "
			               "%llu packets missing",
			               (unsigned long long)c, (unsigned long long)f,
			               (unsigned long long)u, (unsigned long long)m);
		return kg_fail(err, KG_ETIMEDOUT,
		               "no frame within %d ms; so far %llu complete frames, %llu failed, "
		               "%llu underruns (no free buffer), %llu packets missing, %llu resent",
		               timeout_ms, (unsigned long long)c, (unsigned long long)f,
		               (unsigned long long)u, (unsigned long long)m, (unsigned long long)r);
	}
	int slot = GPOINTER_TO_INT(arv_buffer_get_user_data(b)) - 1;
	if (slot < 0 || slot >= s->nbuf || s->held[slot]) {
		g_object_unref(b);
		return kg_fail(err, KG_EIO, "Aravis returned a buffer that is not ours");
	}
	s->held[slot] = b;
	size_t size = 0;
	const void *data = arv_buffer_get_image_data(b, &size);
	if (!data)
		data = arv_buffer_get_data(b, &size);
	frame->fmt = s->fmt;
	frame->data = data;
	frame->size = s->fmt.size;
	frame->slot = slot;
	frame->status = buffer_status(s, b);
	/* The fake camera reports 0 bytes received; a real one that delivered fewer bytes
	 * than a frame gave an incomplete frame whatever its status. */
	if (frame->status == KG_FRAME_OK && size && size < s->fmt.size)
		frame->status = KG_FRAME_INCOMPLETE;
	advance_sequence(s, arv_buffer_get_frame_id(b));
	frame->sequence = s->seq;
	guint64 ts = arv_buffer_get_timestamp(b);
	if (!ts)
		ts = arv_buffer_get_system_timestamp(b);
	frame->timestamp = (double)ts * 1e-9;
	if (frame->status == KG_FRAME_INCOMPLETE)
		s->incomplete++;
	else if (frame->status == KG_FRAME_CORRUPT)
		s->corrupt++;
	return 0;
}

static int arv_push(void *state, kg_frame *frame, kg_err *err)
{
	arv_state *s = state;
	if (!s->held || frame->slot < 0 || frame->slot >= s->nbuf || !s->held[frame->slot])
		return kg_fail(err, KG_EINVAL, "frame %llu (slot %d) is not held",
		               (unsigned long long)frame->sequence, frame->slot);
	arv_stream_push_buffer(s->stream, s->held[frame->slot]);
	s->held[frame->slot] = NULL;
	frame->data = NULL;
	return 0;
}

static void arv_stats(void *state, kg_stream_stats *out)
{
	arv_state *s = state;
	guint64 c, f, u, r, m;
	aravis_counts(s, &c, &f, &u, &r, &m);
	/* Aravis counts every buffer completed with an error as a failure; the ones that
	 * were delivered as incomplete are counted there instead. Frames lost for want of
	 * a free buffer (underruns) leave gaps in the frame ids: camera.c counts them as
	 * dropped. */
	out->incomplete = s->incomplete;
	out->failed = f > s->incomplete ? f - s->incomplete : 0;
	if (out->failed < s->corrupt)
		out->failed = s->corrupt;
	out->resent = r;
	out->missing_packets = m;
}

/* ---- enumeration -------------------------------------------------------------- */

static int arv_enumerate(kg_camera_found_fn found, void *user, kg_err *err)
{
	discovery d;
	int ret = discovery_policy(&d, err);
	if (ret)
		return ret;
	if (d == DISCOVER_NONE)
		return kg_fail(err, KG_ENOTSUP,
		               "not searched: KOGEI_CAMERA_DISCOVERY=none (GigE Vision cameras "
		               "still open by address: aravis:<IPv4 address>)");
	apply_discovery(d, 0);
	arv_update_device_list();
	unsigned n = arv_get_n_devices();
	for (unsigned i = 0; i < n; i++) {
		const char *id = arv_get_device_id(i);
		const char *proto = arv_get_device_protocol(i);
		if (!id)
			continue;
		char uri[256];
		snprintf(uri, sizeof(uri), "aravis:%s", id);
		const char *transport = proto && !strcmp(proto, "GigEVision")   ? "GigE Vision"
		                        : proto && !strcmp(proto, "USB3Vision") ? "USB3 Vision"
		                                                                : proto ? proto : "";
		found(user, uri, arv_get_device_model(i) ? arv_get_device_model(i) : "",
		      arv_get_device_serial_nbr(i) ? arv_get_device_serial_nbr(i) : "", transport);
	}
	return 0;
}

const kg_camera_driver kg_camera_aravis_driver = {
	.scheme = "aravis",
	.description = "GigE Vision and USB3 Vision cameras through Aravis "
	               "(aravis:<IPv4 address> or aravis:<device id>)",
	.enumerate = arv_enumerate,
	.open = arv_open,
	.close = arv_close,
	.feature_info = arv_feature_info,
	.get = arv_get,
	.set = arv_set,
	.set_format = arv_set_format,
	.get_format = arv_get_format,
	.start = arv_start,
	.stop = arv_stop,
	.pop = arv_pop,
	.push = arv_push,
	.stats = arv_stats,
};
