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
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "console.h"
#include "kg_config.h"

#if HAVE_JPEG
#include <jpeglib.h>
#endif

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

/* Row y of the frame as samples 0..1 (W x channels) and their full-scale flags. */
static void frame_row(const sampler *s, int W, int y, float *out, unsigned char *cl)
{
	size_t n = (size_t)W * (size_t)s->channels;
	if (s->img) {
		const float *r = s->img->data + (size_t)y * n;
		for (size_t i = 0; i < n; i++) {
			out[i] = r[i];
			cl[i] = r[i] >= 1.0f;
		}
		return;
	}
	const unsigned char *row = (const unsigned char *)s->f->data + (size_t)y * s->f->fmt.stride;
	float scale = (float)s->scale;
	if (s->wide) {
		for (size_t i = 0; i < n; i++) {
			unsigned v = (unsigned)(row[2 * i] | row[2 * i + 1] << 8);
			out[i] = (float)v * scale;
			cl[i] = v >= s->full;
		}
	} else {
		for (size_t i = 0; i < n; i++) {
			out[i] = (float)row[i] * scale;
			cl[i] = row[i] >= s->full;
		}
	}
}

static void preview_hist(preview *p, const float *o)
{
	for (int q = 0; q < (p->mono ? 1 : 3); q++) {
		int b = (int)(o[q] * CONSOLE_HIST_BINS);
		b = b < 0 ? 0 : b >= CONSOLE_HIST_BINS ? CONSOLE_HIST_BINS - 1 : b;
		p->hist[q][b]++;
	}
}

/* A Bayer mosaic that fits the preview at full size: every pixel from the 2 x 2 window
 * at it (clamped inside the frame), which holds one R, two G and one B. */
static int preview_bayer_full(const sampler *s, int W, int H, const char *cfa, preview *p)
{
	float *r0 = malloc(sizeof(float) * 2 * (size_t)W);
	unsigned char *c0 = malloc(2 * (size_t)W);
	if (!r0 || !c0) {
		free(r0);
		free(c0);
		return -1;
	}
	float *r1 = r0 + W;
	unsigned char *c1 = c0 + W;
	long nclip = 0;
	int have = -1; /* the frame row in r0 (r1 holds the next) */
	for (int y = 0; y < H; y++) {
		int y0 = y < H - 1 ? y : H - 2;
		if (have != y0) {
			if (have >= 0 && have == y0 - 1) {
				memcpy(r0, r1, sizeof(float) * (size_t)W);
				memcpy(c0, c1, (size_t)W);
			} else {
				frame_row(s, W, y0, r0, c0);
			}
			frame_row(s, W, y0 + 1, r1, c1);
			have = y0;
			for (int x = 0; x < W; x++)
				nclip += c0[x];
		}
		/* Where R, B and the two G of the window are, for an even and an odd window
		 * column: rows r0/r1 and a column offset of 0 or 1. */
		const float *rp[2], *bp[2], *g1[2], *g2[2];
		for (int px = 0; px < 2; px++) {
			int ng = 0;
			for (int q = 0; q < 4; q++) {
				int dx = q & 1, dy = q >> 1;
				const float *src = (dy ? r1 : r0) + dx;
				int col = cfa_colour(cfa, px + dx, y0 + dy);
				if (col == 0)
					rp[px] = src;
				else if (col == 2)
					bp[px] = src;
				else if (ng++)
					g2[px] = src;
				else
					g1[px] = src;
			}
		}
		float *o = p->rgb + (size_t)y * (size_t)W * 3;
		unsigned char *oc = p->clip + (size_t)y * (size_t)W;
		const float *re = rp[0], *ro = rp[1], *be = bp[0], *bo = bp[1];
		const float *ge1 = g1[0], *ge2 = g2[0], *go1 = g1[1], *go2 = g2[1];
		int x = 0;
		for (; x + 1 < W - 1; x += 2) {
			o[3 * x] = re[x];
			o[3 * x + 1] = 0.5f * (ge1[x] + ge2[x]);
			o[3 * x + 2] = be[x];
			o[3 * x + 3] = ro[x + 1];
			o[3 * x + 4] = 0.5f * (go1[x + 1] + go2[x + 1]);
			o[3 * x + 5] = bo[x + 1];
		}
		for (; x < W - 1; x++) {
			int px = x & 1;
			o[3 * x] = rp[px][x];
			o[3 * x + 1] = 0.5f * (g1[px][x] + g2[px][x]);
			o[3 * x + 2] = bp[px][x];
		}
		for (x = 0; x < W - 1; x++)
			oc[x] = (unsigned char)(c0[x] | c0[x + 1] | c1[x] | c1[x + 1]);
		/* the last column repeats the window of the one before */
		memcpy(o + 3 * (size_t)(W - 1), o + 3 * (size_t)(W - 2), 3 * sizeof(float));
		oc[W - 1] = oc[W - 2];
		for (x = 0; x < W; x++)
			preview_hist(p, o + 3 * x);
	}
	for (int x = 0; x < W; x++) /* the last row, never in r0 */
		nclip += c1[x];
	p->clipped_fraction = (double)nclip / ((double)W * (double)H);
	free(r0);
	free(c0);
	return 0;
}

/* Bin the frame into p (rgb, clip, histograms, clipped fraction): a Bayer mosaic that
 * fits at full size is interpolated (preview_bayer_full); otherwise blocks of k x k
 * pixels, or of k x k 2 x 2 cells of a mosaic, are averaged. */
static int preview_bin(const sampler *s, int W, int H, const char *cfa, preview *p)
{
	int bayer = cfa && cfa[0];
	p->mono = !bayer && s->channels == 1;
	if (bayer && W >= 2 && H >= 2 && W <= CONSOLE_PREVIEW_SIDE && H <= CONSOLE_PREVIEW_SIDE) {
		p->cell = 1;
		p->k = 1;
		p->w = W;
		p->h = H;
		p->rgb = malloc(sizeof(float) * 3 * (size_t)W * (size_t)H);
		p->clip = malloc((size_t)W * (size_t)H);
		if (!p->rgb || !p->clip)
			return -1;
		return preview_bayer_full(s, W, H, cfa, p);
	}
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
	int bs = p->k * p->cell; /* block side in frame pixels */
	int nch = s->channels;
	p->rgb = calloc(3 * (size_t)p->w * (size_t)p->h, sizeof(float));
	p->clip = calloc((size_t)p->w * (size_t)p->h, 1);
	float *row = malloc(sizeof(float) * (size_t)W * (size_t)nch);
	unsigned char *cl = malloc((size_t)W * (size_t)nch);
	if (!p->rgb || !p->clip || !row || !cl) {
		free(row);
		free(cl);
		return -1;
	}
	/* samples per colour in a block: a mosaic's cells hold 1 R, 2 G, 1 B */
	float inv[3];
	for (int q = 0; q < 3; q++)
		inv[q] = 1.0f / (float)(bayer ? (q == 1 ? 2 : 1) * p->k * p->k : p->k * p->k);
	long nclip = 0;
	for (int oy = 0; oy < p->h; oy++) {
		float *o = p->rgb + (size_t)oy * (size_t)p->w * 3;
		unsigned char *oc = p->clip + (size_t)oy * (size_t)p->w;
		for (int yy = 0; yy < bs; yy++) {
			int y = oy * bs + yy;
			frame_row(s, W, y, row, cl);
			int c0 = bayer ? cfa_colour(cfa, 0, y) : 0, c1 = bayer ? cfa_colour(cfa, 1, y) : 0;
			for (int ox = 0; ox < p->w; ox++) {
				float *op = o + 3 * (size_t)ox;
				int x = ox * bs, any = 0;
				if (bayer) {
					for (int xx = 0; xx < bs; xx += 2) {
						op[c0] += row[x + xx];
						op[c1] += row[x + xx + 1];
						any |= cl[x + xx] | cl[x + xx + 1];
						nclip += cl[x + xx] + cl[x + xx + 1];
					}
				} else {
					const float *r = row + (size_t)x * (size_t)nch;
					const unsigned char *c = cl + (size_t)x * (size_t)nch;
					for (int xx = 0; xx < bs; xx++)
						for (int q = 0; q < nch; q++) {
							op[q] += r[xx * nch + q];
							any |= c[xx * nch + q];
							nclip += c[xx * nch + q];
						}
				}
				oc[ox] |= (unsigned char)any;
			}
		}
		for (int ox = 0; ox < p->w; ox++) {
			float *op = o + 3 * (size_t)ox;
			if (nch == 1 && !bayer)
				op[0] *= inv[0], op[1] = op[2] = op[0];
			else
				for (int q = 0; q < 3; q++)
					op[q] *= inv[q];
			preview_hist(p, op);
		}
	}
	long nsamples = (long)p->w * p->h * bs * bs * (bayer ? 1 : nch);
	p->clipped_fraction = nsamples ? (double)nclip / (double)nsamples : 0;
	free(row);
	free(cl);
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

#if HAVE_JPEG
typedef struct jpeg_fail {
	struct jpeg_error_mgr mgr;
	jmp_buf jb;
	unsigned char *buf; /* the output, grown by libjpeg (in memory across longjmp) */
	unsigned long size;
} jpeg_fail;

static void jpeg_fail_exit(j_common_ptr j) { longjmp(((jpeg_fail *)j->err)->jb, 1); }
static void jpeg_quiet(j_common_ptr j, int level) { (void)j; (void)level; }

/* 8-bit RGB rows into a JPEG in memory: quality 90, no chroma subsampling (the red
 * clipping and green peaking marks stay one pixel wide), the fast DCT. */
static int encode_jpeg(const unsigned char *rgb, int w, int h, membuf *m)
{
	struct jpeg_compress_struct j;
	jpeg_fail jf = {.buf = NULL, .size = 0};
	j.err = jpeg_std_error(&jf.mgr);
	jf.mgr.error_exit = jpeg_fail_exit;
	jf.mgr.emit_message = jpeg_quiet;
	if (setjmp(jf.jb)) {
		jpeg_destroy_compress(&j);
		free(jf.buf);
		return -1;
	}
	jpeg_create_compress(&j);
	jpeg_mem_dest(&j, &jf.buf, &jf.size);
	j.image_width = (JDIMENSION)w;
	j.image_height = (JDIMENSION)h;
	j.input_components = 3;
	j.in_color_space = JCS_RGB;
	jpeg_set_defaults(&j);
	jpeg_set_quality(&j, 90, TRUE);
	j.dct_method = JDCT_IFAST;
	for (int c = 0; c < 3; c++)
		j.comp_info[c].h_samp_factor = j.comp_info[c].v_samp_factor = 1;
	jpeg_start_compress(&j, TRUE);
	while (j.next_scanline < j.image_height) {
		JSAMPROW row = (JSAMPROW)(rgb + (size_t)j.next_scanline * (size_t)w * 3);
		jpeg_write_scanlines(&j, &row, 1);
	}
	jpeg_finish_compress(&j);
	jpeg_destroy_compress(&j);
	m->data = jf.buf;
	m->size = jf.size;
	return jf.buf ? 0 : -1;
}
#endif

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
	float g = (float)(4096 * pow(2, ev));
	for (size_t i = 0; i < 3 * n; i++) {
		float v = p->rgb[i] * g + 0.5f;
		out[i] = srgb_lut[!(v > 0) ? 0 : v >= 4096 ? 4096 : (int)v];
	}
	for (size_t i = 0; i < n; i++)
		if (p->clip[i]) {
			out[3 * i] = 255;
			out[3 * i + 1] = 0;
			out[3 * i + 2] = 0;
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

static double cpu_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
	return 1e3 * (double)ts.tv_sec + 1e-6 * (double)ts.tv_nsec;
}

static double wall_ms(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	return 1e3 * (double)ts.tv_sec + 1e-6 * (double)ts.tv_nsec;
}

/* A frame binned, waiting for the second stage (display and encoding). */
struct live_job {
	preview p;
	double ev, roi[4];
	int peaking, own, fw, fh;
	uint64_t seq;
	double ts, fexp, fgain, captured;
	double t_camera, t_bin, t_focus; /* ms */
	double cpu_camera, cpu_capture;  /* ms of this thread's CPU time */
	json_t *settings;
};
typedef struct live_job live_job;

/* The first stage (camera held): one frame, the camera's own preview where its driver
 * has one (kg_camera_preview), else a frame of the stream; binned, with its focus
 * measure, into *out. */
static int live_capture(console *c, double ev, const double roi[4], int peaking, live_job **out)
{
	kg_err err = {{0}};
	int ret, own = 0;
	double exp_us = 0;
	kg_camera_get(c->cam, KG_FEAT_EXPOSURE_US, &exp_us, NULL);
	kg_frame f;
	if (!kg_camera_has_preview(c->cam))
		c->streaming = 1; /* kg_camera_preview starts the stream */
	double tc = console_now(), cpu0 = cpu_ms();
	if ((ret = kg_camera_preview(c->cam, 1000 + (int)(2 * exp_us / 1000), &f, &own, &err))) {
		live_set_error(c, err.msg);
		kg_camera_stop(c->cam, NULL);
		c->streaming = 0;
		return ret;
	}
	live_job *j = calloc(1, sizeof(*j));
	if (!j) {
		if (!own)
			kg_camera_push(c->cam, &f, NULL);
		live_set_error(c, "live view: out of memory");
		return KG_ENOMEM;
	}
	j->captured = wall_ms();
	j->cpu_camera = cpu_ms() - cpu0;
	double t0 = console_now();
	sampler s = {.f = &f};
	kg_image *img = NULL;
	const char *cfa = NULL;
	switch (f.fmt.pixfmt) {
	case KG_PIX_MONO8: case KG_PIX_BAYER8: case KG_PIX_RGB8:
	case KG_PIX_MONO16: case KG_PIX_BAYER16: case KG_PIX_RGB16:
		s.wide = f.fmt.pixfmt == KG_PIX_MONO16 || f.fmt.pixfmt == KG_PIX_BAYER16 ||
		         f.fmt.pixfmt == KG_PIX_RGB16;
		s.channels = f.fmt.pixfmt == KG_PIX_RGB8 || f.fmt.pixfmt == KG_PIX_RGB16 ? 3 : 1;
		s.full = (1u << f.fmt.bits) - 1;
		s.scale = 1.0 / s.full;
		cfa = f.fmt.pixfmt == KG_PIX_BAYER8 || f.fmt.pixfmt == KG_PIX_BAYER16 ? f.fmt.cfa : NULL;
		break;
	default: /* MJPEG (a camera's viewfinder), YUYV: display-encoded, shown as they are */
		ret = kg_frame_to_image(&f, 1, &img, &err);
		s.img = img;
		s.channels = img ? img->channels : 1;
		break;
	}
	if (!ret && preview_bin(&s, f.fmt.width, f.fmt.height, cfa, &j->p))
		ret = kg_fail(&err, KG_ENOMEM, "live view: out of memory");
	double t_bin = console_now();
	if (!ret)
		preview_focus(&s, f.fmt.width, f.fmt.height, cfa, roi, &j->p);
	j->t_camera = 1000 * (t0 - tc);
	j->t_bin = 1000 * (t_bin - t0);
	j->t_focus = 1000 * (console_now() - t_bin);
	j->cpu_capture = cpu_ms() - cpu0;
	j->seq = f.sequence;
	j->ts = f.timestamp;
	j->fexp = f.exposure_us;
	j->fgain = f.gain;
	j->fw = f.fmt.width;
	j->fh = f.fmt.height;
	j->own = own;
	j->ev = ev;
	memcpy(j->roi, roi, sizeof(j->roi));
	j->peaking = peaking;
	kg_image_free(&img);
	if (!own)
		kg_camera_push(c->cam, &f, NULL);
	if (ret) {
		live_set_error(c, err.msg);
		preview_free(&j->p);
		free(j);
		return ret;
	}
	j->settings = console_settings_json(c);
	*out = j;
	return 0;
}

/* The second stage: the display image, encoded, published with its numbers. */
static void live_publish(console *c, live_job *j)
{
	double t0 = console_now(), cpu0 = cpu_ms();
	preview *p = &j->p;
	unsigned char *rgb = display(p, j->ev, j->roi, j->peaking);
	double t_disp = console_now();
	membuf m = {0};
	const char *type = "image/png";
#if HAVE_JPEG
	type = "image/jpeg";
	if (!rgb || encode_jpeg(rgb, p->w, p->h, &m)) {
#else
	if (!rgb || encode_png(rgb, p->w, p->h, &m)) {
#endif
		free(rgb);
		free(m.data);
		json_decref(j->settings);
		live_set_error(c, "live view: the preview could not be encoded");
		return;
	}
	double t_end = console_now();
	double ms = j->t_bin + j->t_focus + 1000 * (t_end - t0);
	json_t *parts = json_pack("{s:f, s:f, s:f, s:f, s:f, s:f, s:f, s:f}", "camera", j->t_camera,
	                          "bin", j->t_bin, "focus", j->t_focus, "display",
	                          1000 * (t_disp - t0), "encode", 1000 * (t_end - t_disp),
	                          "cpu_camera", j->cpu_camera, "cpu_capture", j->cpu_capture,
	                          "cpu_publish", cpu_ms() - cpu0);
	json_t *hist = json_array();
	for (int q = 0; q < (p->mono ? 1 : 3); q++) {
		json_t *h = json_array();
		for (int b = 0; b < CONSOLE_HIST_BINS; b++)
			json_array_append_new(h, json_integer(p->hist[q][b]));
		json_array_append_new(hist, h);
	}
	pthread_mutex_lock(&c->lock);
	c->live_seq++;
	free(c->img);
	c->img = m.data;
	c->img_size = m.size;
	c->img_type = type;
	free(c->disp);
	c->disp = rgb;
	c->disp_w = p->w;
	c->disp_h = p->h;
	c->captured_ms = j->captured;
	c->preview_ms = ms;
	c->preview_ms_mean = (c->preview_ms_mean * (double)c->previews + ms) / (double)(c->previews + 1);
	c->previews++;
	c->live_error[0] = 0;
	json_decref(c->live);
	c->live = json_pack("{s:I, s:I, s:f, s:o, s:o, s:i, s:i, s:i, s:i, s:i, s:o, s:f, s:o, s:o, "
	                    "s:[f,f,f,f], s:f, s:b, s:o, s:f, s:f, s:f, s:s, s:b, s:o}",
	                    "preview", (json_int_t)c->live_seq, "sequence", (json_int_t)j->seq,
	                    "timestamp", j->ts, "exposure_us", jnum(j->fexp), "gain", jnum(j->fgain),
	                    "width", j->fw, "height", j->fh, "preview_width", p->w,
	                    "preview_height", p->h, "binning", p->k * p->cell, "histograms", hist,
	                    "clipped_fraction", p->clipped_fraction, "focus", jnum(p->focus),
	                    "focus_mean", jnum(p->focus_mean), "roi", j->roi[0], j->roi[1],
	                    j->roi[2], j->roi[3], "ev", j->ev, "peaking", j->peaking, "settings",
	                    j->settings, "server_ms", ms, "server_ms_mean", c->preview_ms_mean,
	                    "captured_ms", j->captured, "image_type", type, "camera_preview",
	                    j->own, "server_parts_ms", parts);
	free(c->live_text);
	c->live_text = json_dumps(c->live, JSON_COMPACT | JSON_ENSURE_ASCII);
	pthread_cond_broadcast(&c->cond);
	pthread_mutex_unlock(&c->lock);
}

static void live_job_free(live_job *j)
{
	if (j) {
		preview_free(&j->p);
		free(j);
	}
}

/* Wait on c->cond (c->lock held) for at most ns nanoseconds (< 1 s). */
static void wait_ns(console *c, long ns)
{
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	ts.tv_nsec += ns;
	if (ts.tv_nsec >= 1000000000L) {
		ts.tv_sec++;
		ts.tv_nsec -= 1000000000L;
	}
	pthread_cond_timedwait(&c->cond, &c->lock, &ts);
}

/* The live view runs in two threads so that one frame is binned while the one before
 * is encoded: live_main (the camera, binning, focus) hands each frame to encode_main
 * (display, JPEG, publishing) through c->live_job, waiting while it is taken. */
static void *live_main(void *arg)
{
	console *c = arg;
	for (;;) {
		pthread_mutex_lock(&c->lock);
		while (!c->stop && (c->camera_owned || console_now() - c->last_request > 3)) {
			wait_ns(c, 200000000L);
		}
		int stop = c->stop;
		double ev = c->ev, roi[4];
		memcpy(roi, c->roi, sizeof(roi));
		int peaking = c->peaking;
		pthread_mutex_unlock(&c->lock);
		if (stop)
			break;
		live_job *j = NULL;
		pthread_mutex_lock(&c->cam_lock);
		int ret = c->cam ? live_capture(c, ev, roi, peaking, &j) : -1;
		if (!c->cam)
			live_set_error(c, "no camera (start the console with --camera URI)");
		pthread_mutex_unlock(&c->cam_lock);
		if (ret) { /* wait before trying again */
			nanosleep(&(struct timespec){0, 500000000L}, NULL);
			continue;
		}
		pthread_mutex_lock(&c->lock);
		while (c->live_job && !c->stop)
			pthread_cond_wait(&c->cond, &c->lock);
		if (c->stop) {
			pthread_mutex_unlock(&c->lock);
			json_decref(j->settings);
			live_job_free(j);
			break;
		}
		c->live_job = j;
		pthread_cond_broadcast(&c->cond);
		pthread_mutex_unlock(&c->lock);
	}
	return NULL;
}

static void *encode_main(void *arg)
{
	console *c = arg;
	for (;;) {
		pthread_mutex_lock(&c->lock);
		while (!c->live_job && !c->stop)
			pthread_cond_wait(&c->cond, &c->lock);
		live_job *j = c->live_job;
		c->live_job = NULL;
		pthread_cond_broadcast(&c->cond);
		pthread_mutex_unlock(&c->lock);
		if (!j)
			break; /* stopping */
		live_publish(c, j);
		live_job_free(j);
	}
	return NULL;
}

static void console_live_stop_encoder(console *c)
{
	pthread_mutex_lock(&c->lock);
	c->stop = 1;
	pthread_cond_broadcast(&c->cond);
	pthread_mutex_unlock(&c->lock);
	pthread_join(c->encode_thread, NULL);
	live_job *j = c->live_job; /* taken by nobody once both threads stopped */
	c->live_job = NULL;
	if (j)
		json_decref(j->settings);
	live_job_free(j);
}

int console_live_start(console *c, kg_err *err)
{
	srgb_lut_init();
	c->roi[0] = c->roi[1] = 0.4;
	c->roi[2] = c->roi[3] = 0.6;
	if (pthread_create(&c->encode_thread, NULL, encode_main, c))
		return kg_fail(err, KG_EIO, "console: cannot start the live view's encoding thread");
	if (pthread_create(&c->live_thread, NULL, live_main, c)) {
		console_live_stop_encoder(c);
		return kg_fail(err, KG_EIO, "console: cannot start the live view thread");
	}
	return 0;
}

void console_live_stop(console *c)
{
	pthread_mutex_lock(&c->lock);
	c->stop = 1;
	pthread_cond_broadcast(&c->cond);
	pthread_mutex_unlock(&c->lock);
	pthread_join(c->live_thread, NULL);
	console_live_stop_encoder(c);
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
		wait_ns(c, 50000000L);
	}
	json_t *j = c->live ? json_deep_copy(c->live) : json_object();
	json_object_set_new(j, "paused", json_boolean(c->camera_owned));
	json_object_set_new(j, "error",
	                    c->live_error[0] ? kg_json_message(c->live_error) : json_null());
	pthread_mutex_unlock(&c->lock);
	return j;
}

unsigned char *console_live_png(console *c, size_t *size)
{
	pthread_mutex_lock(&c->lock);
	int w = c->disp_w, h = c->disp_h;
	unsigned char *copy = c->disp ? malloc(3 * (size_t)w * (size_t)h) : NULL;
	if (copy)
		memcpy(copy, c->disp, 3 * (size_t)w * (size_t)h);
	pthread_mutex_unlock(&c->lock);
	membuf m = {0};
	if (copy && encode_png(copy, w, h, &m)) {
		free(m.data);
		m.data = NULL;
	}
	free(copy);
	*size = m.size;
	return m.data;
}

int console_live_preview(console *c, uint64_t after, console_preview *out)
{
	memset(out, 0, sizeof(*out));
	struct timespec dl;
	clock_gettime(CLOCK_REALTIME, &dl);
	dl.tv_sec += 2;
	pthread_mutex_lock(&c->lock);
	c->last_request = console_now();
	pthread_cond_broadcast(&c->cond);
	int timed_out = 0;
	while (!c->stop && (c->live_seq <= after || !c->img) && !timed_out)
		timed_out = pthread_cond_timedwait(&c->cond, &c->lock, &dl) != 0;
	int ret = -1;
	if (c->img && c->live_seq > after && (out->data = malloc(c->img_size))) {
		memcpy(out->data, c->img, c->img_size);
		out->size = c->img_size;
		out->type = c->img_type;
		out->seq = c->live_seq;
		out->captured_ms = c->captured_ms;
		out->live = c->live_text ? strdup(c->live_text) : NULL;
		ret = 0;
	}
	pthread_mutex_unlock(&c->lock);
	return ret;
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
		return json_pack("{s:b, s:o}", "go", 0, "error", kg_json_message(err.msg));
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
		json_object_set_new(j, "error", kg_json_message(err.msg));
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
		                KG_CHART_FLAG_OUT_OF_FRAME | KG_CHART_FLAG_GLARE |
		                KG_CHART_FLAG_MISFIT;
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
			json_array_append_new(reasons, kg_json_message(why));
		}
	}
	for (int i = 0; i < r->nwarnings; i++)
		json_array_append_new(warnings, kg_json_message(r->warnings[i]));
	int go = nbad == 0;
	json_object_set_new(j, "found", json_true());
	json_object_set_new(j, "go", json_boolean(go));
	json_object_set_new(j, "tagless", json_boolean(r->tagless));
	json_object_set_new(j, "detector", json_string(!r->tagless ? "apriltag"
	                                                : r->tagless_grid ? "patch-grid"
	                                                                  : "opencv-mcc"));
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
