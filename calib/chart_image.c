/* The image as the detection stages see it: interleaved linear floats, a raw CFA frame
 * demosaiced (bilinearly) only where a stage reads it; and the stages' threads. Raw
 * CFA frames are demosaiced bilinearly here. */
#include <pthread.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

/* ---- threads ----------------------------------------------------------------- */

/* fn(arg, t, n) for t = 0..n-1, t = 0 on the caller's thread. Every caller splits its
 * work by t into pieces whose results do not depend on n, so any thread count gives
 * the same numbers. A thread that cannot be started has its share run here. */


typedef struct par_job {
	par_fn fn;
	void *arg;
	int t, n;
} par_job;

static void *par_main(void *p)
{
	par_job *j = p;
	j->fn(j->arg, j->t, j->n);
	return NULL;
}


int chart_clamp_threads(int threads)
{
	return threads < 1 ? 1 : threads > MAX_THREADS ? MAX_THREADS : threads;
}

void chart_run_parallel(par_fn fn, void *arg, int threads)
{
	int n = chart_clamp_threads(threads);
	pthread_t tid[MAX_THREADS];
	par_job job[MAX_THREADS];
	int started[MAX_THREADS] = {0};
	for (int t = 1; t < n; t++) {
		job[t] = (par_job){fn, arg, t, n};
		started[t] = pthread_create(&tid[t], NULL, par_main, &job[t]) == 0;
	}
	fn(arg, 0, n);
	for (int t = 1; t < n; t++) {
		if (started[t])
			pthread_join(tid[t], NULL);
		else
			fn(arg, t, n);
	}
}

/* Bilinear demosaic: each missing colour is the mean of the 3 x 3 neighbours that
 * carry it, edges clamped. This is one pixel (x, y) anywhere, into o (RGB). */
static void demosaic_clamped(const work_image *wi, int y, int x, float *o)
{
	const kg_image *raw = wi->raw;
	int W = raw->width, Hh = raw->height, cr = wi->cfa_rows, cc = wi->cfa_cols;
	const float *d = raw->data;
	double sum[3] = {0, 0, 0};
	int cnt[3] = {0, 0, 0};
	for (int dy = -1; dy <= 1; dy++) {
		int yy = y + dy < 0 ? 0 : y + dy >= Hh ? Hh - 1 : y + dy;
		for (int dx = -1; dx <= 1; dx++) {
			int xx = x + dx < 0 ? 0 : x + dx >= W ? W - 1 : x + dx;
			int c = wi->colour[(yy % cr) * cc + xx % cc];
			sum[c] += d[(size_t)yy * W + xx];
			cnt[c]++;
		}
	}
	int own = wi->colour[(y % cr) * cc + x % cc];
	for (int c = 0; c < 3; c++)
		o[c] = c == own ? d[(size_t)y * W + x] : (cnt[c] ? (float)(sum[c] / cnt[c]) : 0.0f);
}

/* Interior pixels x, x + step, ... (n of them, all with a neighbour on each side) of
 * row y: the phase's neighbour lists, summed in the clamped loop's order, so both give
 * the same values. A mean of 1, 2, 4 or 8 (every 2 x 2 pattern's) is a multiply by
 * the exact reciprocal, equal to the division. */
static void demosaic_interior(const work_image *wi, int y, int x, int n, int step, float *o)
{
	static const double recip[9] = {0, 1, 0.5, 0, 0.25, 0, 0, 0, 0.125};
	const float *row = wi->raw->data + (size_t)y * wi->raw->width;
	int cc = wi->cfa_cols, base = (y % wi->cfa_rows) * cc, px = x % cc, dpx = step % cc;
	for (int i = 0; i < n; i++, x += step, o += 3) {
		int phase = base + px, own = wi->colour[phase];
		const float *p = row + x;
		for (int c = 0; c < 3; c++) {
			int k = wi->nbn[phase][c];
			const ptrdiff_t *off = wi->nb[phase][c];
			if (c == own) {
				o[c] = *p;
				continue;
			}
			double sum = 0;
			switch (k) {
			case 4:
				sum += p[off[0]];
				sum += p[off[1]];
				sum += p[off[2]];
				sum += p[off[3]];
				break;
			case 2:
				sum += p[off[0]];
				sum += p[off[1]];
				break;
			default:
				for (int j = 0; j < k; j++)
					sum += p[off[j]];
			}
			o[c] = !k ? 0.0f : recip[k] != 0 ? (float)(sum * recip[k]) : (float)(sum / k);
		}
		px += dpx;
		if (px >= cc)
			px -= cc;
	}
}

/* Bilinear demosaic of pixels x0, x0 + step, ... (n of them) of row y into out (RGB):
 * the runs of interior pixels through demosaic_interior, the edges clamped. */
static void demosaic_span(const work_image *wi, int y, int x0, int n, int step, float *out)
{
	int W = wi->raw->width, Hh = wi->raw->height;
	int inner_row = y > 0 && y < Hh - 1;
	for (int i = 0; i < n;) {
		int x = x0 + i * step;
		if (!inner_row || x == 0 || x >= W - 1) {
			demosaic_clamped(wi, y, x, out + (size_t)i * 3);
			i++;
			continue;
		}
		int m = (W - 2 - x) / step + 1;
		if (m > n - i)
			m = n - i;
		demosaic_interior(wi, y, x, m, step, out + (size_t)i * 3);
		i += m;
	}
}

/* Pixels x0, x0 + step, ... (n of them) of row y, interleaved: a pointer into the
 * image, or into scratch (n * 3 floats) where they had to be gathered or demosaiced. */
const float *chart_image_span(const work_image *wi, int y, int x0, int n, int step,
                               float *scratch)
{
	int C = wi->channels;
	if (wi->data && step == 1)
		return wi->data + ((size_t)y * wi->width + x0) * C;
	if (!wi->data && wi->u16) {
		const uint16_t *row = wi->u16 + ((size_t)y * wi->width + x0) * C;
		const float *lut = wi->lut;
		if (step == 1)
			for (size_t i = 0; i < (size_t)n * C; i++)
				scratch[i] = lut[row[i]];
		else
			for (int i = 0; i < n; i++)
				for (int c = 0; c < C; c++)
					scratch[(size_t)i * C + c] = lut[row[(size_t)i * step * C + c]];
		return scratch;
	}
	if (!wi->data) {
		demosaic_span(wi, y, x0, n, step, scratch);
		return scratch;
	}
	for (int i = 0; i < n; i++)
		for (int c = 0; c < C; c++)
			scratch[(size_t)i * C + c] = wi->data[((size_t)y * wi->width + x0 + i * step) * C + c];
	return scratch;
}

typedef struct demosaic_job {
	work_image *wi;
	float *out;
} demosaic_job;

static void demosaic_rows(void *arg, int t, int n)
{
	demosaic_job *j = arg;
	int H = j->wi->height, W = j->wi->width, C = j->wi->channels;
	for (int y = (int)((long)H * t / n); y < (int)((long)H * (t + 1) / n); y++)
		if (j->wi->u16)
			chart_image_span(j->wi, y, 0, W, 1, j->out + (size_t)y * W * C);
		else
			demosaic_span(j->wi, y, 0, W, 1, j->out + (size_t)y * W * 3);
}

/* The whole frame demosaiced (or a mapped image's floats), for the stages that need
 * every pixel (mcc at full resolution). */
int chart_demosaic_all(work_image *wi, kg_err *err)
{
	if (wi->data)
		return 0;
	wi->owned = malloc((size_t)wi->width * wi->height * wi->channels * sizeof(float));
	if (!wi->owned)
		return kg_fail(err, KG_ENOMEM, "demosaic: out of memory");
	demosaic_job j = {wi, wi->owned};
	chart_run_parallel(demosaic_rows, &j, wi->threads);
	wi->data = wi->owned;
	return 0;
}

/* The saturation scan of the whole image (core/saturation.h): where each colour
 * clips, found from the data when below full scale. */
static void *saturation_main(void *arg)
{
	work_image *wi = arg;
	wi->sat_ret = kg_saturation_of_image(wi->sat_src, wi->clip_level, &wi->sat, &wi->sat_err);
	wi->sat_done = 1;
	return NULL;
}

int chart_prepare_image(const kg_image *img, const kg_chart_detect_options *opt,
                         work_image *wi, kg_err *err)
{
	memset(wi, 0, sizeof(*wi));
	wi->width = img->width;
	wi->height = img->height;
	wi->channels = img->channels;
	wi->data = img->data;
	if (!img->data && img->u16 && !img->cfa) {
		wi->u16 = img->u16;
		wi->lut = kg_image_u16_lut();
	}
	wi->threads = chart_clamp_threads(opt->threads);
	if (opt->clip_level > 0)
		wi->clip_level = opt->clip_level;
	else if (img->is_float || img->bits <= 0 || img->bits > 16)
		wi->clip_level = 1.0;
	else
		wi->clip_level = 1.0 - 0.5 / (double)((1L << img->bits) - 1);
	for (int c = 0; c < 3; c++)
		wi->clip_ch[c] = wi->clip_level;
	/* the saturation scan (chart_image_levels) reads the whole image: on a thread of
	 * its own while the detectors run, done before anything is sampled */
	wi->sat_src = !(opt->clip_level > 0) && (img->channels == 3 || img->channels == 1) ? img
	                                                                                  : NULL;
	if (!img->is_float && img->bits > 0 && img->bits <= 16) {
		wi->quantum = 1.0 / (double)((1L << img->bits) - 1);
		wi->count_scale = (float)((1L << img->bits) - 1);
	}
	if (img->channels == 1 && img->cfa) {
		int cr = img->cfa_rows, cc = img->cfa_cols;
		if (cr < 1 || cc < 1 || cr * cc > 64)
			return kg_fail(err, KG_ENOTSUP, "CFA repeat of %dx%d is too large", cr, cc);
		for (int k = 0; k < cr * cc; k++) {
			const char *p = strchr("RGB", img->cfa[k]);
			if (!p || !img->cfa[k])
				return kg_fail(err, KG_ENOTSUP,
				               "CFA pattern %.*s: only R, G and B filters can be demosaiced",
				               cr * cc, img->cfa);
			wi->colour[k] = (int)(p - "RGB");
		}
		for (int py = 0; py < cr; py++)
			for (int px = 0; px < cc; px++) {
				int phase = py * cc + px;
				for (int dy = -1; dy <= 1; dy++)
					for (int dx = -1; dx <= 1; dx++) {
						int c = wi->colour[((py + dy + cr) % cr) * cc + (px + dx + cc) % cc];
						wi->nb[phase][c][wi->nbn[phase][c]++] =
						    (ptrdiff_t)dy * img->width + dx;
					}
			}
		wi->raw = img;
		wi->cfa_rows = cr;
		wi->cfa_cols = cc;
		wi->channels = 3;
		wi->data = NULL;
		wi->quantum = 0;
		wi->count_scale *= 4;
	} else if (img->channels != 1 && img->channels != 3) {
		return kg_fail(err, KG_EINVAL, "image has %d channels: expected 1 or 3",
		               img->channels);
	}
	if (wi->sat_src && wi->threads > 1)
		wi->sat_running = pthread_create(&wi->sat_tid, NULL, saturation_main, wi) == 0;
	return 0;
}

int chart_image_levels(work_image *wi, kg_err *err)
{
	if (wi->sat_running) {
		pthread_join(wi->sat_tid, NULL);
		wi->sat_running = 0;
	} else if (wi->sat_src && !wi->sat_done) {
		saturation_main(wi);
	}
	if (!wi->sat_src)
		return 0;
	if (wi->sat_ret)
		return kg_fail(err, wi->sat_ret, "%s", wi->sat_err.msg);
	if (wi->sat_applied)
		return 0;
	wi->sat_applied = 1;
	const kg_image *img = wi->sat_src;
	const kg_saturation *sat = &wi->sat;
	if (kg_saturation_below(sat, wi->clip_level)) {
		/* each colour clips where its samples pile up (a mosaic's sites by colour) */
		int mosaic = sat->channels == 4 && img->cfa && strlen(img->cfa) >= 4;
		for (int k = 0; k < sat->channels; k++) {
			int c = !mosaic ? (img->channels == 1 ? -1 : k)
			        : img->cfa[k] == 'R' ? 0 : img->cfa[k] == 'G' ? 1 : img->cfa[k] == 'B' ? 2 : -1;
			for (int cc = 0; cc < 3; cc++)
				if ((c < 0 || cc == c) && sat->clip[k] < wi->clip_ch[cc])
					wi->clip_ch[cc] = sat->clip[k];
		}
		kg_saturation_format(sat, mosaic ? img->cfa : img->channels == 1 ? "Y" : "RGB",
		                     wi->sat_note, sizeof(wi->sat_note));
	}
	return 0;
}

void chart_image_free(work_image *wi)
{
	if (wi->sat_running) {
		pthread_join(wi->sat_tid, NULL);
		wi->sat_running = 0;
	}
	free(wi->owned);
	wi->owned = NULL;
	free(wi->grey);
	wi->grey = NULL;
	for (int t = 0; t < MAX_THREADS; t++) {
		chart_buffers_free(&wi->sample_bufs[t]);
		memset(&wi->sample_bufs[t], 0, sizeof(wi->sample_bufs[t]));
	}
}
