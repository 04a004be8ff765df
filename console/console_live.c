/* kogei console: the live view and the chart check (docs/console.md, "Live view").
 *
 * A thread pulls frames from the camera while the page asks for previews (it idles
 * when nobody has asked for 3 s, and pauses while a capture owns the camera). Each
 * frame becomes a preview of at most CONSOLE_PREVIEW_SIDE px on its long side: Bayer
 * mosaics binned 2x2 into RGB, then box-averaged by an integer factor; linear values
 * times 2^ev, sRGB-encoded; samples at full scale painted red; in the focus region the
 * sharpness (variance of the Laplacian of the green or grey plane at the sensor's
 * resolution, over the squared mean) and, when asked, edges painted green. */
#include <math.h>
#include <png.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "console.h"

/* ---- the camera ------------------------------------------------------------------ */

void console_camera_take(console *c)
{
	pthread_mutex_lock(&c->lock);
	c->camera_owned++;
	pthread_mutex_unlock(&c->lock);
	pthread_mutex_lock(&c->cam_lock);
	if (c->cam && c->streaming)
		kg_camera_stop(c->cam, NULL);
	c->streaming = 0;
}

void console_camera_give(console *c)
{
	pthread_mutex_unlock(&c->cam_lock);
	pthread_mutex_lock(&c->lock);
	c->camera_owned--;
	pthread_cond_broadcast(&c->cond);
	pthread_mutex_unlock(&c->lock);
}

const kg_feature console_feats[3] = {KG_FEAT_EXPOSURE_US, KG_FEAT_GAIN, KG_FEAT_ISO};
const char *const console_feat_keys[3] = {"exposure_us", "gain", "iso"};

int console_camera_select(console *c, int i, kg_err *err)
{
	if (i == c->cam_index && c->cam)
		return 0;
	kg_camera_free(&c->cam);
	c->cam_index = -1;
	int ret = kg_camera_open(c->cameras[i], &c->cam, err);
	if (!ret)
		ret = kg_camera_manual(c->cam, err);
	if (ret) {
		kg_camera_free(&c->cam);
		return ret;
	}
	c->cam_index = i;
	kg_feature_info fi[3];
	for (int k = 0; k < 3; k++)
		if (kg_camera_feature_info(c->cam, console_feats[k], &fi[k], NULL))
			memset(&fi[k], 0, sizeof(fi[k]));
	pthread_mutex_lock(&c->lock);
	memcpy(c->feat[i], fi, sizeof(fi));
	c->feat_known[i] = 1;
	pthread_mutex_unlock(&c->lock);
	return 0;
}

static json_t *jnum(double v) { return isfinite(v) ? json_real(v) : json_null(); }

json_t *console_settings_json(console *c)
{
	json_t *j = json_object();
	if (!c->cam)
		return j;
	const kg_camera_info *info = kg_camera_get_info(c->cam);
	json_object_set_new(j, "uri", json_string(info->uri));
	json_object_set_new(j, "model", json_string(info->model));
	json_object_set_new(j, "serial", json_string(info->serial));
	static const kg_feature feats[] = {KG_FEAT_EXPOSURE_US, KG_FEAT_GAIN, KG_FEAT_ISO,
	                                   KG_FEAT_APERTURE};
	for (size_t k = 0; k < sizeof(feats) / sizeof(feats[0]); k++) {
		kg_feature_info fi;
		double v;
		if (kg_camera_feature_info(c->cam, feats[k], &fi, NULL) || !fi.available ||
		    kg_camera_get(c->cam, feats[k], &v, NULL))
			continue;
		json_object_set_new(j, kg_feature_name(feats[k]),
		                    json_pack("{s:o, s:s, s:o, s:o, s:b}", "value", jnum(v), "unit",
		                              fi.unit, "min", jnum(fi.min), "max", jnum(fi.max),
		                              "writable", fi.writable));
	}
	kg_frame_format f;
	if (!kg_camera_get_format(c->cam, &f, NULL))
		json_object_set_new(j, "format",
		                    json_pack("{s:s, s:i, s:s, s:i, s:i}", "pixfmt",
		                              kg_pixfmt_name(f.pixfmt), "bits", f.bits, "cfa", f.cfa,
		                              "width", f.width, "height", f.height));
	return j;
}

/* ---- the preview ------------------------------------------------------------------ */

typedef struct sampler {
	const kg_frame *f;
	const kg_image *img; /* a decoded frame (formats read through kg_frame_to_image) */
	int wide;            /* 16-bit words */
	int channels;        /* per pixel in the data: 1 or 3 */
	double scale;        /* 1 / full scale */
	unsigned full;       /* full scale in DN */
} sampler;

/* Sample of channel ch at (x, y), 0..1; *clip set when at full scale. */
static inline double sample_at(const sampler *s, int x, int y, int ch, int *clip)
{
	if (s->img) {
		double v = s->img->data[((size_t)y * (size_t)s->img->width + (size_t)x) *
		                             (size_t)s->img->channels + (size_t)ch];
		if (v >= 1.0)
			*clip = 1;
		return v;
	}
	const unsigned char *row = (const unsigned char *)s->f->data + (size_t)y * s->f->fmt.stride;
	size_t i = (size_t)x * (size_t)s->channels + (size_t)ch;
	unsigned v = s->wide ? (unsigned)(row[2 * i] | row[2 * i + 1] << 8) : row[i];
	if (v >= s->full)
		*clip = 1;
	return v * s->scale;
}

/* The colour (0 R, 1 G, 2 B) of mosaic site (x, y). */
static int cfa_colour(const char *cfa, int x, int y)
{
	char l = cfa[(y & 1) * 2 + (x & 1)];
	return l == 'R' ? 0 : l == 'B' ? 2 : 1;
}

typedef struct preview {
	int w, h, k, cell;      /* output size, binning factor, mosaic cell (1 or 2) */
	float *rgb;             /* linear, w x h x 3 */
	unsigned char *clip;    /* w x h: some sample reached full scale */
	double clipped_fraction;
	long hist[3][CONSOLE_HIST_BINS];
	int mono;
	double focus, focus_mean;
} preview;

static void preview_free(preview *p)
{
	free(p->rgb);
	free(p->clip);
	memset(p, 0, sizeof(*p));
}

/* Bin the frame into p (rgb, clip, histograms, clipped fraction). */
static int preview_bin(const sampler *s, int W, int H, const char *cfa, preview *p)
{
	int bayer = cfa && cfa[0];
	p->cell = bayer ? 2 : 1;
	int cw = W / p->cell, ch = H / p->cell;
	int lng = cw > ch ? cw : ch;
	p->k = (lng + CONSOLE_PREVIEW_SIDE - 1) / CONSOLE_PREVIEW_SIDE;
	if (p->k < 1)
		p->k = 1;
	p->w = cw / p->k;
	p->h = ch / p->k;
	if (p->w < 1 || p->h < 1)
		return -1;
	p->rgb = malloc(sizeof(float) * 3 * (size_t)p->w * (size_t)p->h);
	p->clip = calloc((size_t)p->w * (size_t)p->h, 1);
	if (!p->rgb || !p->clip)
		return -1;
	p->mono = !bayer && s->channels == 1;
	long nclip = 0, nsamples = 0;
	for (int oy = 0; oy < p->h; oy++)
		for (int ox = 0; ox < p->w; ox++) {
			double sum[3] = {0, 0, 0}, cnt[3] = {0, 0, 0};
			int clip = 0;
			for (int yy = 0; yy < p->k * p->cell; yy++) {
				int y = oy * p->k * p->cell + yy;
				for (int xx = 0; xx < p->k * p->cell; xx++) {
					int x = ox * p->k * p->cell + xx;
					int cl = 0;
					if (bayer) {
						int col = cfa_colour(cfa, x, y);
						sum[col] += sample_at(s, x, y, 0, &cl);
						cnt[col]++;
						nsamples++;
					} else {
						for (int q = 0; q < s->channels; q++) {
							int c1 = 0;
							sum[q] += sample_at(s, x, y, q, &c1);
							cnt[q]++;
							nsamples++;
							nclip += c1;
							cl |= c1;
						}
						clip |= cl;
						continue;
					}
					nclip += cl;
					clip |= cl;
				}
			}
			float *o = p->rgb + 3 * ((size_t)oy * (size_t)p->w + (size_t)ox);
			for (int q = 0; q < 3; q++) {
				int src = s->channels == 1 && !bayer ? 0 : q;
				o[q] = cnt[src] > 0 ? (float)(sum[src] / cnt[src]) : 0;
			}
			p->clip[(size_t)oy * (size_t)p->w + (size_t)ox] = (unsigned char)clip;
			for (int q = 0; q < (p->mono ? 1 : 3); q++) {
				int b = (int)(o[q] * CONSOLE_HIST_BINS);
				b = b < 0 ? 0 : b >= CONSOLE_HIST_BINS ? CONSOLE_HIST_BINS - 1 : b;
				p->hist[q][b]++;
			}
		}
	p->clipped_fraction = nsamples ? (double)nclip / (double)nsamples : 0;
	return 0;
}

/* The green (or grey) value of cell (x, y). */
static inline double green_at(const sampler *s, const char *cfa, int bayer, int gch, int x,
                              int y)
{
	int cl = 0;
	if (!bayer)
		return sample_at(s, x, y, gch, &cl);
	double g = 0;
	int n = 0;
	for (int dy = 0; dy < 2; dy++)
		for (int dx = 0; dx < 2; dx++)
			if (cfa_colour(cfa, 2 * x + dx, 2 * y + dy) == 1) {
				g += sample_at(s, 2 * x + dx, 2 * y + dy, 0, &cl);
				n++;
			}
	return n ? g / n : 0;
}

/* Variance of the Laplacian over the squared mean, of the green (Bayer: the mean of a
 * cell's greens; RGB: G; mono: the grey) plane at full resolution, inside roi (0..1
 * of the frame). */
static void preview_focus(const sampler *s, int W, int H, const char *cfa, const double roi[4],
                          preview *p)
{
	int bayer = cfa && cfa[0], cell = bayer ? 2 : 1;
	int cw = W / cell, chh = H / cell;
	int x0 = (int)(roi[0] * cw), x1 = (int)(roi[2] * cw);
	int y0 = (int)(roi[1] * chh), y1 = (int)(roi[3] * chh);
	x0 = x0 < 1 ? 1 : x0;
	y0 = y0 < 1 ? 1 : y0;
	x1 = x1 > cw - 1 ? cw - 1 : x1;
	y1 = y1 > chh - 1 ? chh - 1 : y1;
	p->focus = NAN;
	p->focus_mean = NAN;
	if (x1 - x0 < 3 || y1 - y0 < 3)
		return;
	int gch = s->channels == 3 ? 1 : 0;
	/* a step keeps the work bounded on a large region: at most ~4 Mpix visited */
	long area = (long)(x1 - x0) * (long)(y1 - y0);
	int step = 1;
	while (area / ((long)step * step) > 4000000L)
		step++;
	double sum = 0, sum2 = 0, mean = 0;
	long n = 0;
#define GREEN(X, Y) green_at(s, cfa, bayer, gch, (X), (Y))
	for (int y = y0; y < y1; y += step)
		for (int x = x0; x < x1; x += step) {
			double v = GREEN(x, y);
			double lap = GREEN(x - 1, y) + GREEN(x + 1, y) + GREEN(x, y - 1) + GREEN(x, y + 1) -
			             4 * v;
			sum += lap;
			sum2 += lap * lap;
			mean += v;
			n++;
		}
#undef GREEN
	if (n < 2)
		return;
	mean /= (double)n;
	double var = (sum2 - sum * sum / (double)n) / (double)(n - 1);
	p->focus_mean = mean;
	p->focus = mean > 0 ? var / (mean * mean) : NAN;
}

/* ---- display and PNG ------------------------------------------------------------- */

typedef struct membuf {
	unsigned char *data;
	size_t size, cap;
	int failed;
} membuf;

static void png_write_mem(png_structp png, png_bytep data, png_size_t n)
{
	membuf *m = png_get_io_ptr(png);
	if (m->failed)
		return;
	if (m->size + n > m->cap) {
		size_t cap = m->cap ? m->cap * 2 : 65536;
		while (cap < m->size + n)
			cap *= 2;
		unsigned char *d = realloc(m->data, cap);
		if (!d) {
			m->failed = 1;
			return;
		}
		m->data = d;
		m->cap = cap;
	}
	memcpy(m->data + m->size, data, n);
	m->size += n;
}

static void png_flush_mem(png_structp png) { (void)png; }

/* 8-bit RGB rows into a PNG in memory (fast compression: it is a preview). */
static int encode_png(const unsigned char *rgb, int w, int h, membuf *m)
{
	png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
	png_infop info = png ? png_create_info_struct(png) : NULL;
	if (!info) {
		png_destroy_write_struct(&png, NULL);
		return -1;
	}
	png_bytep *rows = malloc(sizeof(png_bytep) * (size_t)h);
	if (!rows || setjmp(png_jmpbuf(png))) {
		free(rows);
		png_destroy_write_struct(&png, &info);
		return -1;
	}
	png_set_write_fn(png, m, png_write_mem, png_flush_mem);
	png_set_compression_level(png, 1);
	png_set_filter(png, 0, PNG_FILTER_SUB);
	png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 8, PNG_COLOR_TYPE_RGB,
	             PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
	for (int y = 0; y < h; y++)
		rows[y] = (png_bytep)(rgb + (size_t)y * (size_t)w * 3);
	png_write_info(png, info);
	png_write_image(png, rows);
	png_write_end(png, NULL);
	png_destroy_write_struct(&png, &info);
	free(rows);
	return m->failed ? -1 : 0;
}

static unsigned char srgb_lut[4097];

static void srgb_lut_init(void)
{
	for (int i = 0; i <= 4096; i++) {
		double v = i / 4096.0;
		double e = v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
		srgb_lut[i] = (unsigned char)lrint(255 * e);
	}
}

static inline unsigned char encode(double v)
{
	int i = (int)(v * 4096 + 0.5);
	return srgb_lut[i < 0 ? 0 : i > 4096 ? 4096 : i];
}

/* The display image: sRGB of rgb x 2^ev, red where clipped, green edges in the focus
 * region when peaking. */
static unsigned char *display(const preview *p, double ev, const double roi[4], int peaking)
{
	size_t n = (size_t)p->w * (size_t)p->h;
	unsigned char *out = malloc(3 * n);
	if (!out)
		return NULL;
	double gain = pow(2, ev);
	for (size_t i = 0; i < n; i++) {
		if (p->clip[i]) {
			out[3 * i] = 255;
			out[3 * i + 1] = 0;
			out[3 * i + 2] = 0;
			continue;
		}
		for (int q = 0; q < 3; q++)
			out[3 * i + q] = encode(p->rgb[3 * i + q] * gain);
	}
	if (peaking) {
		int x0 = (int)(roi[0] * p->w), x1 = (int)(roi[2] * p->w);
		int y0 = (int)(roi[1] * p->h), y1 = (int)(roi[3] * p->h);
		x0 = x0 < 1 ? 1 : x0;
		y0 = y0 < 1 ? 1 : y0;
		x1 = x1 > p->w - 1 ? p->w - 1 : x1;
		y1 = y1 > p->h - 1 ? p->h - 1 : y1;
		/* on the display-encoded green: edges a viewer sees */
#define G(X, Y) ((double)out[3 * ((size_t)(Y) * (size_t)p->w + (size_t)(X)) + 1])
		unsigned char *mark = calloc(n, 1);
		for (int y = y0; mark && y < y1; y++)
			for (int x = x0; x < x1; x++) {
				double lap = G(x - 1, y) + G(x + 1, y) + G(x, y - 1) + G(x, y + 1) - 4 * G(x, y);
				mark[(size_t)y * (size_t)p->w + (size_t)x] = fabs(lap) > 40;
			}
#undef G
		for (size_t i = 0; mark && i < n; i++)
			if (mark[i] && !p->clip[i]) {
				out[3 * i] = 0;
				out[3 * i + 1] = 255;
				out[3 * i + 2] = 0;
			}
		free(mark);
	}
	return out;
}

/* ---- the thread -------------------------------------------------------------------- */

static void live_set_error(console *c, const char *msg)
{
	pthread_mutex_lock(&c->lock);
	snprintf(c->live_error, sizeof(c->live_error), "%s", msg);
	pthread_mutex_unlock(&c->lock);
}

/* One preview from one frame (camera held). */
static int live_frame(console *c, double ev, const double roi[4], int peaking)
{
	kg_err err = {{0}};
	int ret;
	if (!c->streaming) {
		if ((ret = kg_camera_start(c->cam, 0, &err))) {
			live_set_error(c, err.msg);
			return ret;
		}
		c->streaming = 1;
	}
	double exp_us = 0;
	kg_camera_get(c->cam, KG_FEAT_EXPOSURE_US, &exp_us, NULL);
	kg_frame f;
	if ((ret = kg_camera_pop(c->cam, 1000 + (int)(2 * exp_us / 1000), &f, &err))) {
		live_set_error(c, err.msg);
		kg_camera_stop(c->cam, NULL);
		c->streaming = 0;
		return ret;
	}
	double t0 = console_now();
	sampler s = {.f = &f};
	kg_image *img = NULL;
	const char *cfa = NULL;
	switch (f.fmt.pixfmt) {
	case KG_PIX_MONO8: case KG_PIX_BAYER8: case KG_PIX_RGB8:
	case KG_PIX_MONO16: case KG_PIX_BAYER16: case KG_PIX_RGB16:
		s.wide = kg_pixfmt_bytes_per_pixel(f.fmt.pixfmt) > 1 + 2 * (f.fmt.pixfmt == KG_PIX_RGB8);
		s.wide = f.fmt.pixfmt == KG_PIX_MONO16 || f.fmt.pixfmt == KG_PIX_BAYER16 ||
		         f.fmt.pixfmt == KG_PIX_RGB16;
		s.channels = f.fmt.pixfmt == KG_PIX_RGB8 || f.fmt.pixfmt == KG_PIX_RGB16 ? 3 : 1;
		s.full = (1u << f.fmt.bits) - 1;
		s.scale = 1.0 / s.full;
		cfa = f.fmt.pixfmt == KG_PIX_BAYER8 || f.fmt.pixfmt == KG_PIX_BAYER16 ? f.fmt.cfa : NULL;
		break;
	default:
		ret = kg_frame_to_image(&f, 1, &img, &err);
		s.img = img;
		s.channels = img ? img->channels : 1;
		break;
	}
	preview p = {0};
	if (!ret && preview_bin(&s, f.fmt.width, f.fmt.height, cfa, &p))
		ret = kg_fail(&err, KG_ENOMEM, "live view: out of memory");
	if (!ret)
		preview_focus(&s, f.fmt.width, f.fmt.height, cfa, roi, &p);
	uint64_t seq = f.sequence;
	double ts = f.timestamp, fexp = f.exposure_us, fgain = f.gain;
	int fw = f.fmt.width, fh = f.fmt.height;
	kg_image_free(&img);
	kg_camera_push(c->cam, &f, NULL);
	if (ret) {
		live_set_error(c, err.msg);
		preview_free(&p);
		return ret;
	}
	unsigned char *rgb = display(&p, ev, roi, peaking);
	membuf m = {0};
	if (!rgb || encode_png(rgb, p.w, p.h, &m)) {
		free(rgb);
		free(m.data);
		preview_free(&p);
		live_set_error(c, "live view: the preview could not be encoded");
		return KG_ENOMEM;
	}
	free(rgb);
	double ms = 1000 * (console_now() - t0);
	json_t *hist = json_array();
	for (int q = 0; q < (p.mono ? 1 : 3); q++) {
		json_t *h = json_array();
		for (int b = 0; b < CONSOLE_HIST_BINS; b++)
			json_array_append_new(h, json_integer(p.hist[q][b]));
		json_array_append_new(hist, h);
	}
	json_t *settings = console_settings_json(c);
	pthread_mutex_lock(&c->lock);
	c->live_seq++;
	free(c->png);
	c->png = m.data;
	c->png_size = m.size;
	c->preview_ms = ms;
	c->preview_ms_mean = (c->preview_ms_mean * (double)c->previews + ms) / (double)(c->previews + 1);
	c->previews++;
	c->live_error[0] = 0;
	json_decref(c->live);
	c->live = json_pack("{s:I, s:I, s:f, s:o, s:o, s:i, s:i, s:i, s:i, s:i, s:o, s:f, s:o, s:o, "
	                    "s:[f,f,f,f], s:f, s:b, s:o, s:f, s:f}",
	                    "preview", (json_int_t)c->live_seq, "sequence", (json_int_t)seq,
	                    "timestamp", ts, "exposure_us", jnum(fexp), "gain", jnum(fgain),
	                    "width", fw, "height", fh, "preview_width", p.w, "preview_height", p.h,
	                    "binning", p.k * p.cell, "histograms", hist, "clipped_fraction",
	                    p.clipped_fraction, "focus", jnum(p.focus), "focus_mean",
	                    jnum(p.focus_mean), "roi", roi[0], roi[1], roi[2], roi[3], "ev", ev,
	                    "peaking", peaking, "settings",
	                    settings, "server_ms", ms, "server_ms_mean", c->preview_ms_mean);
	pthread_cond_broadcast(&c->cond);
	pthread_mutex_unlock(&c->lock);
	preview_free(&p);
	return 0;
}

static void *live_main(void *arg)
{
	console *c = arg;
	for (;;) {
		pthread_mutex_lock(&c->lock);
		while (!c->stop && (c->camera_owned || console_now() - c->last_request > 3)) {
			struct timespec ts;
			clock_gettime(CLOCK_REALTIME, &ts);
			ts.tv_nsec += 200000000L;
			if (ts.tv_nsec >= 1000000000L) {
				ts.tv_sec++;
				ts.tv_nsec -= 1000000000L;
			}
			pthread_cond_timedwait(&c->cond, &c->lock, &ts);
		}
		int stop = c->stop;
		double ev = c->ev, roi[4];
		memcpy(roi, c->roi, sizeof(roi));
		int peaking = c->peaking;
		pthread_mutex_unlock(&c->lock);
		if (stop)
			break;
		pthread_mutex_lock(&c->cam_lock);
		int ret = c->cam ? live_frame(c, ev, roi, peaking) : -1;
		if (!c->cam)
			live_set_error(c, "no camera (start the console with --camera URI)");
		pthread_mutex_unlock(&c->cam_lock);
		if (ret) /* wait before trying again */
			nanosleep(&(struct timespec){0, 500000000L}, NULL);
	}
	return NULL;
}

int console_live_start(console *c, kg_err *err)
{
	srgb_lut_init();
	c->roi[0] = c->roi[1] = 0.4;
	c->roi[2] = c->roi[3] = 0.6;
	if (pthread_create(&c->live_thread, NULL, live_main, c))
		return kg_fail(err, KG_EIO, "console: cannot start the live view thread");
	return 0;
}

void console_live_stop(console *c)
{
	pthread_mutex_lock(&c->lock);
	c->stop = 1;
	pthread_cond_broadcast(&c->cond);
	pthread_mutex_unlock(&c->lock);
	pthread_join(c->live_thread, NULL);
	pthread_mutex_lock(&c->cam_lock);
	if (c->cam && c->streaming)
		kg_camera_stop(c->cam, NULL);
	c->streaming = 0;
	pthread_mutex_unlock(&c->cam_lock);
}

/* A number field of the view: absent (0), a finite number in lo..hi (1), else -1. */
static int view_num(const json_t *req, const char *key, double lo, double hi, double *out)
{
	const json_t *v = json_object_get(req, key);
	if (!v)
		return 0;
	if (!json_is_number(v) || !isfinite(json_number_value(v)) || json_number_value(v) < lo ||
	    json_number_value(v) > hi)
		return -1;
	*out = json_number_value(v);
	return 1;
}

int console_view_set(console *c, const json_t *req, char *why, size_t n)
{
	static const char *const known[] = {"ev", "peaking", "roi"};
	const char *key;
	const json_t *val;
	json_object_foreach((json_t *)req, key, val)
	{
		size_t k = 0;
		while (k < 3 && strcmp(key, known[k]))
			k++;
		if (k == 3) {
			snprintf(why, n, "view: '%s': unknown field (expected ev, peaking, roi)", key);
			return 400;
		}
	}
	double ev = 0;
	int has_ev = view_num(req, "ev", -8, 8, &ev);
	if (has_ev < 0) {
		snprintf(why, n, "view: 'ev': expected a number of stops -8..8");
		return 400;
	}
	const json_t *pk = json_object_get(req, "peaking");
	if (pk && !json_is_boolean(pk)) {
		snprintf(why, n, "view: 'peaking': expected true or false");
		return 400;
	}
	const json_t *r = json_object_get(req, "roi");
	double roi[4] = {0, 0, 0, 0};
	if (r) {
		int ok = json_is_array(r) && json_array_size(r) == 4;
		for (size_t i = 0; ok && i < 4; i++) {
			const json_t *x = json_array_get(r, i);
			ok = json_is_number(x) && isfinite(json_number_value(x)) &&
			     json_number_value(x) >= 0 && json_number_value(x) <= 1;
			if (ok)
				roi[i] = json_number_value(x);
		}
		if (!ok || !(roi[2] > roi[0] && roi[3] > roi[1])) {
			snprintf(why, n, "view: 'roi': expected [x0, y0, x1, y1], fractions 0..1 of the "
			         "frame with x0 < x1 and y0 < y1");
			return 400;
		}
	}
	pthread_mutex_lock(&c->lock);
	if (has_ev)
		c->ev = ev;
	if (pk)
		c->peaking = json_is_true(pk);
	if (r)
		memcpy(c->roi, roi, sizeof(c->roi));
	pthread_cond_broadcast(&c->cond);
	pthread_mutex_unlock(&c->lock);
	return 0;
}

json_t *console_view_json(console *c)
{
	pthread_mutex_lock(&c->lock);
	json_t *j = json_pack("{s:f, s:b, s:[f,f,f,f]}", "ev", c->ev, "peaking", c->peaking, "roi",
	                      c->roi[0], c->roi[1], c->roi[2], c->roi[3]);
	pthread_mutex_unlock(&c->lock);
	return j;
}

json_t *console_live_json(console *c, uint64_t after)
{
	pthread_mutex_lock(&c->lock);
	c->last_request = console_now();
	pthread_cond_broadcast(&c->cond);
	double deadline = console_now() + 2;
	while (!c->stop && c->live_seq <= after && console_now() < deadline) {
		struct timespec ts;
		clock_gettime(CLOCK_REALTIME, &ts);
		ts.tv_nsec += 50000000L;
		if (ts.tv_nsec >= 1000000000L) {
			ts.tv_sec++;
			ts.tv_nsec -= 1000000000L;
		}
		pthread_cond_timedwait(&c->cond, &c->lock, &ts);
	}
	json_t *j = c->live ? json_deep_copy(c->live) : json_object();
	json_object_set_new(j, "paused", json_boolean(c->camera_owned));
	json_object_set_new(j, "error", c->live_error[0] ? json_string(c->live_error) : json_null());
	pthread_mutex_unlock(&c->lock);
	return j;
}

unsigned char *console_live_png(console *c, size_t *size)
{
	pthread_mutex_lock(&c->lock);
	unsigned char *copy = c->png ? malloc(c->png_size) : NULL;
	if (copy) {
		memcpy(copy, c->png, c->png_size);
		*size = c->png_size;
	}
	pthread_mutex_unlock(&c->lock);
	return copy;
}

/* ---- the chart check ---------------------------------------------------------------- */

/* A frame as a linear image for the detector: demosaiced (OpenCV) or binned 2x2 when
 * a mosaic, then box-averaged so its long side is at most 2048 px. *scale: frame px
 * per image px. */
static int chart_image(console *c, kg_image **out, double *scale, kg_err *err)
{
	int ret;
	if (!c->streaming) {
		if ((ret = kg_camera_start(c->cam, 0, err)))
			return ret;
		c->streaming = 1;
	}
	double exp_us = 0;
	kg_camera_get(c->cam, KG_FEAT_EXPOSURE_US, &exp_us, NULL);
	kg_frame f;
	if ((ret = kg_camera_pop(c->cam, 1000 + (int)(2 * exp_us / 1000), &f, err)))
		return ret;
	kg_image *img = NULL, *rgb = NULL;
	ret = kg_frame_to_image(&f, 1, &img, err);
	kg_camera_push(c->cam, &f, NULL);
	if (ret)
		return ret;
	*scale = 1;
	if (img->cfa) {
		double step;
		if (kg_demosaic_algorithm() && !kg_demosaic(img, &rgb, &step, NULL)) {
			kg_image_free(&img);
			img = rgb;
		} else {
			/* no OpenCV: 2x2 cells */
			int w = img->width / 2, h = img->height / 2;
			if ((ret = kg_image_new(w, h, 3, &rgb, err))) {
				kg_image_free(&img);
				return ret;
			}
			for (int y = 0; y < h; y++)
				for (int x = 0; x < w; x++) {
					float *o = rgb->data + 3 * ((size_t)y * (size_t)w + (size_t)x);
					float sum[3] = {0, 0, 0};
					int n[3] = {0, 0, 0};
					for (int d = 0; d < 4; d++) {
						int X = 2 * x + (d & 1), Y = 2 * y + (d >> 1);
						int col = cfa_colour(img->cfa, X, Y);
						sum[col] += img->data[(size_t)Y * (size_t)img->width + (size_t)X];
						n[col]++;
					}
					for (int q = 0; q < 3; q++)
						o[q] = n[q] ? sum[q] / (float)n[q] : 0;
				}
			kg_image_free(&img);
			img = rgb;
			*scale = 2;
		}
	}
	int lng = img->width > img->height ? img->width : img->height;
	int k = (lng + 2047) / 2048;
	if (k > 1) {
		kg_image *small = NULL;
		int w = img->width / k, h = img->height / k, ch = img->channels;
		if ((ret = kg_image_new(w, h, ch, &small, err))) {
			kg_image_free(&img);
			return ret;
		}
		for (int y = 0; y < h; y++)
			for (int x = 0; x < w; x++)
				for (int q = 0; q < ch; q++) {
					double sum = 0;
					for (int yy = 0; yy < k; yy++)
						for (int xx = 0; xx < k; xx++)
							sum += img->data[((size_t)(y * k + yy) * (size_t)img->width +
							                  (size_t)(x * k + xx)) * (size_t)ch + (size_t)q];
					small->data[((size_t)y * (size_t)w + (size_t)x) * (size_t)ch + (size_t)q] =
						(float)(sum / (k * k));
				}
		kg_image_free(&img);
		img = small;
		*scale *= k;
	}
	*out = img;
	return 0;
}

static json_t *points(const double (*pt)[2], int n, double sx, double sy)
{
	json_t *a = json_array();
	for (int i = 0; i < n; i++)
		json_array_append_new(a, json_pack("[f,f]", pt[i][0] * sx, pt[i][1] * sy));
	return a;
}

json_t *console_chart_check(console *c)
{
	if (!c->chart_layout)
		return json_pack("{s:b, s:s}", "go", 0, "error",
		                 "no chart layout: start the console with --layout L (or record a "
		                 "chart capture with one)");
	pthread_mutex_lock(&c->lock);
	int owned = c->camera_owned;
	pthread_mutex_unlock(&c->lock);
	if (owned)
		return json_pack("{s:b, s:s}", "go", 0, "error", "a capture owns the camera");
	kg_err err = {{0}};
	kg_image *img = NULL;
	double scale = 1;
	pthread_mutex_lock(&c->cam_lock);
	int ret = c->cam ? chart_image(c, &img, &scale, &err)
	                 : kg_fail(&err, KG_EINVAL, "no camera");
	pthread_mutex_unlock(&c->cam_lock);
	if (ret)
		return json_pack("{s:b, s:s}", "go", 0, "error", err.msg);
	kg_chart_detect_options opt;
	kg_chart_detect_options_default(&opt);
	kg_chart_result *r = NULL;
	double t0 = console_now();
	ret = kg_chart_detect(c->chart_layout, img, &opt, &r, &err);
	double sx = 1.0 / img->width, sy = 1.0 / img->height;
	json_t *j = json_pack("{s:s, s:i, s:i, s:f}", "layout", c->chart_layout->name, "width",
	                      img->width, "height", img->height, "frame_scale", scale);
	kg_image_free(&img);
	if (ret) {
		json_object_set_new(j, "go", json_false());
		json_object_set_new(j, "found", json_false());
		json_object_set_new(j, "error", json_string(err.msg));
		json_object_set_new(j, "reasons", json_pack("[s]", "the chart was not found"));
		return j;
	}
	json_t *tags = json_array(), *patches = json_array(), *warnings = json_array(),
	       *reasons = json_array();
	for (int i = 0; i < r->ntags; i++)
		json_array_append_new(tags, json_pack("{s:i, s:b, s:o}", "id", r->tags[i].id, "used",
		                                       r->tags[i].used,
		                                       "corners", points(r->tags[i].corners, 4, sx, sy)));
	int nbad = 0, nflag = 0;
	for (int i = 0; i < r->npatches; i++) {
		const kg_chart_sample *p = &r->patches[i];
		unsigned hard = KG_CHART_FLAG_CLIPPED | KG_CHART_FLAG_REJECTED |
		                KG_CHART_FLAG_OUT_OF_FRAME | KG_CHART_FLAG_GLARE;
		nbad += (p->flags & hard) != 0;
		nflag += p->flags != 0;
		json_array_append_new(patches,
		                      json_pack("{s:s, s:i, s:s, s:o, s:[f,f,f]}", "id", p->id, "flags",
		                                p->flags, "warning", p->warning, "quad",
		                                points(p->quad, 4, sx, sy), "rgb",
		                                isfinite(p->rgb[0]) ? p->rgb[0] : -1,
		                                isfinite(p->rgb[1]) ? p->rgb[1] : -1,
		                                isfinite(p->rgb[2]) ? p->rgb[2] : -1));
		if (p->flags & hard) {
			char why[320];
			snprintf(why, sizeof(why), "patch %s: %s", p->id, p->warning);
			json_array_append_new(reasons, json_string(why));
		}
	}
	for (int i = 0; i < r->nwarnings; i++)
		json_array_append_new(warnings, json_string(r->warnings[i]));
	int go = nbad == 0;
	json_object_set_new(j, "found", json_true());
	json_object_set_new(j, "go", json_boolean(go));
	json_object_set_new(j, "tagless", json_boolean(r->tagless));
	json_object_set_new(j, "tags_used", json_integer(r->ntags_used));
	json_object_set_new(j, "rms_px", jnum(r->rms_px));
	json_object_set_new(j, "outline", points(r->outline, 4, sx, sy));
	json_object_set_new(j, "tags", tags);
	json_object_set_new(j, "patches", patches);
	json_object_set_new(j, "flagged", json_integer(nflag));
	json_object_set_new(j, "warnings", warnings);
	json_object_set_new(j, "reasons", reasons);
	json_object_set_new(j, "seconds", json_real(console_now() - t0));
	kg_chart_result_free(&r);
	return j;
}
