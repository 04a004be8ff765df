/* Images to files, the input side: the apply options, the feed that pulls each block's
 * rows from the row sources (pre-matrix, clip, variance, mask) and the progress line. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "apply_private.h"

void kg_apply_options_init(kg_apply_options *o)
{
	memset(o, 0, sizeof(*o));
	o->clip_level = 0.999f;
	o->isa = KG_EST_ISA_AUTO;
}

int kg_apply_side_path(const char *out_path, const char *suffix, char **out, kg_err *err)
{
	kg_check_arg(out_path && suffix && out, err);
	const char *base = strrchr(out_path, '/');
	base = base ? base + 1 : out_path;
	const char *dot = strrchr(base, '.');
	size_t stem = dot && dot != base ? (size_t)(dot - out_path) : strlen(out_path);
	char *p = malloc(stem + strlen(suffix) + 1);
	if (!p)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	memcpy(p, out_path, stem);
	strcpy(p + stem, suffix);
	*out = p;
	return 0;
}

void kg_est_stats_format(const kg_est_stats *s, char *buf, size_t size)
{
	double n = s->pixels ? (double)s->pixels : 1.0;
	snprintf(buf, size,
	         "pixels %llu, clipped %llu (%.3f %%), non-finite %llu (%.3f %%), "
	         "clamped %llu (%.3f %%), flagged %llu (%.3f %%)",
	         (unsigned long long)s->pixels, (unsigned long long)s->clipped,
	         100.0 * (double)s->clipped / n, (unsigned long long)s->nonfinite,
	         100.0 * (double)s->nonfinite / n, (unsigned long long)s->clamped_pixels,
	         100.0 * (double)s->clamped_pixels / n,
	         (unsigned long long)(s->clipped + s->nonfinite),
	         100.0 * (double)(s->clipped + s->nonfinite) / n);
}

/* ---- input ----------------------------------------------------------------------- */

/* Each block's input is pulled from row sources as the run reaches it (the job's
 * fill), so no image is ever held whole. Per block of n pixels the slot holds planes:
 *   kin   3n  what the kernel sees
 *   raw   3n  the image's own values, when a pre map makes kin differ from them
 *   var   3n  the variance of single frames (classify, when given)
 *   mask   n  0 = background (classify, when given)
 * With pre the clip test belongs to the camera's values, so a pixel clipped before
 * the transform is marked with FLT_MAX (finite, and at the job's clip level FLT_MAX)
 * and NaN/Inf inputs stay non-finite. */
static size_t feed_floats_per_pixel(const feed *f)
{
	return 3 + (f->has_pre ? 3 : 0) + (f->var ? 3 : 0) + (f->mask ? 1 : 0);
}

planes ap_feed_planes(const feed *f, const void *in, size_t n)
{
	const float *p = in;
	planes pl = {p, p, NULL, NULL};
	p += 3 * n;
	if (f->has_pre) {
		pl.raw = p;
		p += 3 * n;
	}
	if (f->var) {
		pl.var = p;
		p += 3 * n;
	}
	if (f->mask)
		pl.mask = p;
	return pl;
}

static int is_identity(const double *m)
{
	for (int i = 0; i < 9; i++)
		if (m[i] != (i % 4 == 0 ? 1.0 : 0.0))
			return 0;
	return 1;
}

int ap_feed_init(feed *f, const kg_row_source *src, const kg_apply_options *opt,
                     const char *what, kg_err *err)
{
	memset(f, 0, sizeof(*f));
	if (!src || !src->read || src->width < 1 || src->height < 1)
		return kg_fail(err, KG_EINVAL, "%s: no image data", what);
	if (src->channels != 3)
		return kg_fail(err, KG_EINVAL,
		               "%s: the image has %d channel%s: expected 3 (linear RGB)%s", what,
		               src->channels, src->channels == 1 ? "" : "s",
		               src->channels == 1 ? "; a raw Bayer frame must be demosaiced first" : "");
	if (isnan(opt->clip_level))
		return kg_fail(err, KG_EINVAL, "%s: clip level: expected a number, not NaN", what);
	f->src = src;
	f->what = what;
	f->clip = f->job_clip = opt->clip_level;
	int per_channel = 0;
	for (int c = 0; c < 3; c++) {
		f->clip3[c] = f->clip;
		if (opt->clip_rgb[c] > 0 && opt->clip_rgb[c] < f->clip) {
			f->clip3[c] = opt->clip_rgb[c];
			per_channel = 1;
		}
	}
	static const double identity[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
	/* per-channel levels go through the pre path's test on the image's own values */
	if ((!opt->pre || is_identity(opt->pre)) && !per_channel)
		return 0;
	const double *P = opt->pre ? opt->pre : identity;
	for (int i = 0; i < 9; i++)
		if (!isfinite(P[i]))
			return kg_fail(err, KG_EINVAL, "%s: pre-transform: expected finite values", what);
	memcpy(f->pre, P, sizeof(f->pre));
	f->has_pre = 1;
	f->job_clip = isinf(opt->clip_level) ? INFINITY : FLT_MAX;
	return 0;
}

/* The job's fill: the block's rows from each source, the pre map, and the variance
 * checked as it arrives (the outputs are not yet in place, so a bad value still
 * leaves nothing written). */
int ap_feed_fill(void *user, int y0, int rows, void *in, kg_err *err)
{
	const feed *f = user;
	size_t W = (size_t)f->src->width, n = (size_t)rows * W;
	planes pl = ap_feed_planes(f, in, n);
	float *kin = (float *)pl.kin;
	int rc = f->src->read(f->src->user, y0, rows, (float *)pl.raw, err);
	if (!rc && f->var)
		rc = f->var->read(f->var->user, y0, rows, (float *)pl.var, err);
	if (!rc && f->mask)
		rc = f->mask->read(f->mask->user, y0, rows, (float *)pl.mask, err);
	if (rc)
		return rc;
	if (f->var)
		for (size_t i = 0; i < 3 * n; i++)
			if (!(pl.var[i] >= 0 && isfinite(pl.var[i])))
				return kg_fail(err, KG_EINVAL,
				               "%s: %s: pixel (%zu, %zu) channel %zu is %g: expected a "
				               "finite variance >= 0",
				               f->what, f->var_name, i / 3 % W, (size_t)y0 + i / 3 / W, i % 3,
				               pl.var[i]);
	if (!f->has_pre)
		return 0;
	const double *P = f->pre;
	const float c0 = f->clip3[0], c1 = f->clip3[1], c2 = f->clip3[2];
	for (size_t i = 0; i < n; i++) {
		const float *p = pl.raw + 3 * i;
		float *q = kin + 3 * i;
		int finite = isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
		if (finite && (p[0] >= c0 || p[1] >= c1 || p[2] >= c2)) {
			q[0] = q[1] = q[2] = FLT_MAX;
			continue;
		}
		for (int r = 0; r < 3; r++)
			q[r] = (float)(P[3 * r] * p[0] + P[3 * r + 1] * p[1] + P[3 * r + 2] * p[2]);
	}
	return 0;
}

void ap_feed_job(feed *f, kg_est_job *job)
{
	job->clip_level = f->job_clip;
	job->fill = ap_feed_fill;
	job->fill_user = f;
	job->in_bytes = feed_floats_per_pixel(f) * sizeof(float);
}

/* An image of which no pixel can be estimated (every one flagged: clipped or
 * non-finite, on the camera's own values) is refused: a cube of NaN is not a result.
 * The run's counts tell, and the outputs, not yet in place, are dropped. */
int ap_check_estimable(const kg_est_stats *st, const feed *f, const char *what,
                           kg_err *err)
{
	if (st->clipped + st->nonfinite < st->pixels)
		return 0;
	return kg_fail(err, KG_EINVAL,
	               "%s: no pixel can be estimated: all %llu pixels of the %d x %d image are "
	               "flagged (%llu clipped, a channel >= the clip level %g; %llu non-finite, a "
	               "channel NaN or Inf); nothing written",
	               what, (unsigned long long)st->pixels, f->src->width, f->src->height,
	               (unsigned long long)st->clipped, (double)f->clip,
	               (unsigned long long)st->nonfinite);
}

/* ---- progress -------------------------------------------------------------------- */

double ap_now_seconds(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void ap_progress_init(progress *p, const kg_apply_options *opt, const char *what,
                          int width, int height)
{
	memset(p, 0, sizeof(*p));
	if (opt->progress && (long)width * height >= KG_APPLY_PROGRESS_PIXELS)
		p->fp = opt->progress;
	p->what = what;
	p->width = width;
	p->height = height;
	p->start = p->last = ap_now_seconds();
}

void ap_progress_rows(progress *p, int rows_done)
{
	if (!p->fp)
		return;
	double t = ap_now_seconds();
	if (rows_done < p->height && t - p->last < 1.0)
		return;
	p->last = t;
	double el = t - p->start;
	double mpix = (double)rows_done * p->width / 1e6;
	fprintf(p->fp, "%s: rows %d / %d (%.0f %%), %.1f Mpix/s\n", p->what, rows_done, p->height,
	        100.0 * rows_done / p->height, el > 0 ? mpix / el : 0.0);
	fflush(p->fp);
}

/* An image in memory: its CFA, if any, makes the message about channels clearer. */
int ap_check_image(const kg_image *img, const char *what, kg_err *err)
{
	if (img && img->data && img->channels == 1 && img->cfa)
		return kg_fail(err, KG_EINVAL,
		               "%s: the image has 1 channel (a raw CFA frame): expected 3 (linear "
		               "RGB); a raw Bayer frame must be demosaiced first", what);
	if (!img || !img->data || img->width < 1 || img->height < 1)
		return kg_fail(err, KG_EINVAL, "%s: no image data", what);
	return 0;
}
