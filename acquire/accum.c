/* Frame averaging: per-sample running mean and variance (Welford's update in double
 * precision, so long runs of nearly equal 16-bit values lose nothing to cancellation),
 * each sample's largest value, and per channel (CFA position for a Bayer mosaic) a
 * histogram of every value seen, from which the saturation level is found
 * (core/saturation.h): a sensor that stops at 4092 of 4095 clips there. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <stdint.h>

#include "kg_acquire.h"

struct kg_frame_accum {
	kg_frame_format fmt;
	int channels;
	int allow_nonlinear;
	size_t nsamples;  /* width * height * channels */
	long n;           /* frames added */
	double fullscale; /* DN of full scale (1 for YUYV, converted to 0..1) */
	double *mean;     /* running mean, DN */
	double *m2;       /* sum of squared deviations, DN^2 */
	unsigned char *clipped; /* YUYV/MJPEG: reached full scale */
	uint16_t *peak;         /* integer formats: the largest value of each sample, DN */
	int hist_channels;      /* 4 CFA positions for Bayer, else the channels */
	uint64_t *hist[KG_SAT_MAX_CHANNELS]; /* fullscale + 1 bins each, DN */
};

static int same_format(const kg_frame_format *a, const kg_frame_format *b)
{
	return a->pixfmt == b->pixfmt && a->width == b->width && a->height == b->height &&
	       a->bits == b->bits && a->stride == b->stride && !strcmp(a->cfa, b->cfa);
}

int kg_frame_accum_new(const kg_frame_format *fmt, int allow_nonlinear, kg_frame_accum **out,
                       kg_err *err)
{
	kg_check_arg(fmt && out, err);
	*out = NULL;
	if (!kg_pixfmt_is_linear(fmt->pixfmt) && !allow_nonlinear)
		return kg_fail(err, KG_EINVAL,
		               "format %s: not linear sensor data; refused for measurement unless "
		               "forced (--force-nonlinear)",
		               kg_pixfmt_name(fmt->pixfmt));
	int bpp = kg_pixfmt_bytes_per_pixel(fmt->pixfmt);
	int ch = kg_pixfmt_channels(fmt->pixfmt);
	int wide = fmt->pixfmt == KG_PIX_MONO16 || fmt->pixfmt == KG_PIX_BAYER16 ||
	           fmt->pixfmt == KG_PIX_RGB16;
	int mjpeg = fmt->pixfmt == KG_PIX_MJPEG; /* decoded frame by frame, no fixed stride */
	if ((!bpp && !mjpeg) || fmt->width <= 0 || fmt->height <= 0 ||
	    (long)fmt->width * fmt->height > KG_IMAGE_MAX_PIXELS ||
	    (!mjpeg && fmt->stride < (size_t)fmt->width * (size_t)bpp) || fmt->bits < 1 ||
	    fmt->bits > (wide ? 16 : 8))
		return kg_fail(err, KG_EINVAL,
		               "format %s %dx%d, %d bits, stride %zu: expected a positive size, a "
		               "stride of at least a row and %s bits",
		               kg_pixfmt_name(fmt->pixfmt), fmt->width, fmt->height, fmt->bits,
		               fmt->stride, wide ? "1..16" : "1..8");
	kg_frame_accum *a = calloc(1, sizeof(*a));
	if (!a)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	a->fmt = *fmt;
	a->channels = ch;
	a->allow_nonlinear = allow_nonlinear;
	a->nsamples = (size_t)fmt->width * (size_t)fmt->height * (size_t)ch;
	a->fullscale = !kg_pixfmt_is_linear(fmt->pixfmt) ? 1.0 : (double)((1u << fmt->bits) - 1u);
	a->mean = calloc(a->nsamples, sizeof(double));
	a->m2 = calloc(a->nsamples, sizeof(double));
	a->clipped = calloc(a->nsamples, 1);
	int bayer = fmt->pixfmt == KG_PIX_BAYER8 || fmt->pixfmt == KG_PIX_BAYER16;
	int hist_ok = 1;
	if (kg_pixfmt_is_linear(fmt->pixfmt) && fmt->bits >= 4) {
		a->peak = calloc(a->nsamples, sizeof(uint16_t));
		a->hist_channels = bayer ? 4 : ch;
		for (int c = 0; c < a->hist_channels && c < KG_SAT_MAX_CHANNELS; c++)
			hist_ok &= (a->hist[c] = calloc((size_t)a->fullscale + 1, sizeof(uint64_t))) != NULL;
		hist_ok &= a->peak != NULL && a->hist_channels <= KG_SAT_MAX_CHANNELS;
	}
	if (!a->mean || !a->m2 || !a->clipped || !hist_ok) {
		kg_frame_accum_free(&a);
		return kg_fail(err, KG_ENOMEM, "out of memory for %dx%d x %d samples", fmt->width,
		               fmt->height, ch);
	}
	*out = a;
	return 0;
}

void kg_frame_accum_free(kg_frame_accum **pa)
{
	if (!pa || !*pa)
		return;
	free((*pa)->mean);
	free((*pa)->m2);
	free((*pa)->clipped);
	free((*pa)->peak);
	for (int c = 0; c < KG_SAT_MAX_CHANNELS; c++)
		free((*pa)->hist[c]);
	free(*pa);
	*pa = NULL;
}

long kg_frame_accum_count(const kg_frame_accum *a) { return a ? a->n : 0; }

/* Welford's update of sample i with the value x of frame n (inv_n = 1 / n). */
static inline void welford(kg_frame_accum *a, size_t i, double x, double inv_n)
{
	double d = x - a->mean[i];
	a->mean[i] += d * inv_n;
	a->m2[i] += d * (x - a->mean[i]);
	if (x >= a->fullscale)
		a->clipped[i] = 1;
}

int kg_frame_accum_add(kg_frame_accum *a, const kg_frame *f, kg_err *err)
{
	kg_check_arg(a && f && f->data, err);
	const kg_frame_format *fmt = &f->fmt;
	if (!same_format(fmt, &a->fmt))
		return kg_fail(err, KG_EINVAL,
		               "frame %llu: format %s %dx%d %d bits (stride %zu) differs from the "
		               "capture's %s %dx%d %d bits (stride %zu)",
		               (unsigned long long)f->sequence, kg_pixfmt_name(fmt->pixfmt),
		               fmt->width, fmt->height, fmt->bits, fmt->stride,
		               kg_pixfmt_name(a->fmt.pixfmt), a->fmt.width, a->fmt.height,
		               a->fmt.bits, a->fmt.stride);
	if (!kg_pixfmt_is_linear(fmt->pixfmt)) { /* YUYV, MJPEG: through the decoder */
		kg_image *img = NULL;
		int ret = kg_frame_to_image(f, a->allow_nonlinear, &img, err);
		if (ret)
			return ret;
		a->n++;
		double inv_n = 1.0 / (double)a->n;
		for (size_t i = 0; i < a->nsamples; i++)
			welford(a, i, img->data[i], inv_n);
		kg_image_free(&img);
		return 0;
	}
	size_t row_bytes = (size_t)fmt->width * (size_t)kg_pixfmt_bytes_per_pixel(fmt->pixfmt);
	if (f->size < fmt->stride * (size_t)(fmt->height - 1) + row_bytes)
		return kg_fail(err, KG_EINVAL, "frame %llu: %zu bytes do not hold %dx%d %s",
		               (unsigned long long)f->sequence, f->size, fmt->width, fmt->height,
		               kg_pixfmt_name(fmt->pixfmt));
	a->n++;
	double inv_n = 1.0 / (double)a->n;
	size_t row_samples = (size_t)fmt->width * (size_t)a->channels;
	int wide = kg_pixfmt_bytes_per_pixel(fmt->pixfmt) / a->channels == 2;
	for (int y = 0; y < fmt->height; y++) {
		const uint8_t *row = (const uint8_t *)f->data + fmt->stride * (size_t)y;
		size_t i0 = (size_t)y * row_samples;
		int bayer = a->hist_channels == 4 && a->channels == 1;
		for (size_t x = 0; x < row_samples; x++) {
			unsigned v = wide ? (unsigned)(row[2 * x] | row[2 * x + 1] << 8) : row[x];
			welford(a, i0 + x, (double)v, inv_n);
			if (!a->peak)
				continue;
			if (v > a->peak[i0 + x])
				a->peak[i0 + x] = (uint16_t)v;
			int c = bayer ? (y & 1) * 2 + (int)(x & 1) : (int)(x % (size_t)a->channels);
			a->hist[c][v < a->fullscale ? v : (unsigned)a->fullscale]++;
		}
	}
	return 0;
}

int kg_frame_accum_result(const kg_frame_accum *a, kg_image **mean, kg_image **variance,
                          kg_err *err)
{
	kg_check_arg(a, err);
	if (!a->n)
		return kg_fail(err, KG_EINVAL, "no frames were averaged");
	kg_image *m = NULL, *v = NULL;
	int ret = 0;
	if (mean)
		ret = kg_image_new(a->fmt.width, a->fmt.height, a->channels, &m, err);
	if (!ret && variance)
		ret = kg_image_new(a->fmt.width, a->fmt.height, a->channels, &v, err);
	int bayer = a->fmt.pixfmt == KG_PIX_BAYER8 || a->fmt.pixfmt == KG_PIX_BAYER16;
	if (!ret && bayer && a->fmt.cfa[0]) {
		if (m)
			ret = kg_image_set_cfa(m, a->fmt.cfa, 2, 2, err);
		if (!ret && v)
			ret = kg_image_set_cfa(v, a->fmt.cfa, 2, 2, err);
	}
	if (ret) {
		kg_image_free(&m);
		kg_image_free(&v);
		return ret;
	}
	double scale = 1.0 / a->fullscale;
	double vscale = a->n > 1 ? scale * scale / (double)(a->n - 1) : 0.0;
	for (size_t i = 0; i < a->nsamples; i++) {
		if (m)
			m->data[i] = (float)(a->mean[i] * scale);
		if (v)
			v->data[i] = (float)(a->m2[i] * vscale);
	}
	if (mean)
		*mean = m;
	if (variance)
		*variance = v;
	return 0;
}

/* Samples whose largest value reached clip[channel] (0..1): per channel, and pixels
 * with any channel there (the return value). */
static size_t count_clipped(const kg_frame_accum *a, const double *clip, size_t *per,
                            size_t *tot)
{
	size_t any = 0;
	int W = a->fmt.width, C = a->channels, bayer = a->hist_channels == 4 && C == 1;
	double lim[KG_SAT_MAX_CHANNELS];
	for (int c = 0; c < a->hist_channels; c++)
		lim[c] = clip[c] * a->fullscale;
	for (size_t i = 0, px = 0; i < a->nsamples; px++) {
		int hit = 0;
		for (int k = 0; k < C; k++, i++) {
			int c = bayer ? (int)((px / (size_t)W) & 1) * 2 + (int)((px % (size_t)W) & 1) : k;
			int h = a->peak[i] >= lim[c];
			per[c] += (size_t)h;
			tot[c]++;
			hit |= h;
		}
		any += (size_t)hit;
	}
	return any;
}

int kg_frame_accum_saturation(const kg_frame_accum *a, kg_saturation *out)
{
	memset(out, 0, sizeof(*out));
	if (!a || !a->peak || !a->n)
		return -1;
	int steps = (int)a->fullscale;
	out->channels = a->hist_channels;
	out->steps = steps;
	for (int c = 0; c < a->hist_channels; c++) {
		int b = kg_saturation_detect(a->hist[c], steps + 1);
		out->level[c] = b >= 0 ? (double)b / steps : NAN;
		out->found[c] = b >= 0;
		out->clip[c] = b >= 0 ? ((double)b - 0.5) / steps : 1.0;
	}
	/* fractions of samples whose largest value reached the level */
	size_t per[KG_SAT_MAX_CHANNELS] = {0}, tot[KG_SAT_MAX_CHANNELS] = {0};
	size_t any = count_clipped(a, out->clip, per, tot);
	for (int c = 0; c < a->hist_channels; c++)
		out->fraction[c] = tot[c] ? (double)per[c] / (double)tot[c] : 0;
	int C = a->channels;
	size_t npx = a->nsamples / (size_t)C;
	out->fraction_any = npx ? (double)any / (double)npx : 0;
	return 0;
}

double kg_frame_accum_clipped_fraction(const kg_frame_accum *a)
{
	if (!a || !a->nsamples)
		return 0;
	kg_saturation s;
	if (!kg_frame_accum_saturation(a, &s)) {
		/* samples at the saturation level found from the data, or at full scale */
		size_t per[KG_SAT_MAX_CHANNELS] = {0}, tot[KG_SAT_MAX_CHANNELS] = {0}, n = 0;
		count_clipped(a, s.clip, per, tot);
		for (int c = 0; c < s.channels; c++)
			n += per[c];
		return (double)n / (double)a->nsamples;
	}
	size_t n = 0;
	for (size_t i = 0; i < a->nsamples; i++)
		n += a->clipped[i];
	return (double)n / (double)a->nsamples;
}
