/* Images to files: a kernel's output streamed into ENVI cubes, masks and label maps
 * (the declarations and the list of files are at the end of kg_estimate.h).
 *
 * The cube never exists in memory: kg_est_run_stream hands finished row blocks, in
 * row order, to a sink that passes them to the ENVI writers. Every file goes to a
 * temporary name first; the final names appear only once all of a call's files are
 * complete, and a failure after that point removes the ones already renamed. */
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

/* ---- files written by a call ----------------------------------------------------- */

/* Final names of files already in place, removed again if a later step fails. */
void ap_written_add(written *w, const char *path)
{
	if (w->n < 16)
		w->paths[w->n++] = strdup(path);
}

void ap_written_add_envi(written *w, const char *path)
{
	char *hdr = NULL, *data = NULL;
	if (kg_envi_paths(path, &hdr, &data, NULL) == 0) {
		ap_written_add(w, data);
		ap_written_add(w, hdr);
	}
	free(hdr);
	free(data);
}

void ap_written_clear(written *w, int remove)
{
	for (int i = 0; i < w->n; i++) {
		if (remove && w->paths[i])
			unlink(w->paths[i]);
		free(w->paths[i]);
	}
	w->n = 0;
}

/* Finish the writers in order; any failure removes what was finished before. */
int ap_finish_all(kg_envi_writer **ws, const char *const *paths, int n, written *done,
                      kg_err *err)
{
	int rc = 0;
	for (int i = 0; i < n; i++) {
		if (rc) {
			kg_envi_writer_abort(&ws[i]);
			continue;
		}
		rc = kg_envi_writer_finish(&ws[i], err);
		if (rc)
			kg_err_prefix(err, "%s: ", paths[i]);
		else
			ap_written_add_envi(done, paths[i]);
	}
	return rc;
}

/* A float staging buffer for blocks that are not float32 (f16 bits, masks, labels);
 * the ENVI writer converts the values (exact integers) to the file's type. */
float *ap_staging_get(staging *s, size_t n, kg_err *err)
{
	if (n > s->cap) {
		float *v = realloc(s->v, n * sizeof(float));
		if (!v) {
			kg_fail(err, KG_ENOMEM, "out of memory for a block of %zu values", n);
			return NULL;
		}
		s->v = v;
		s->cap = n;
	}
	return s->v;
}

int ap_put_bytes(kg_envi_writer *w, staging *s, const kg_est_block *b, const uint8_t *src,
                     kg_err *err)
{
	size_t n = (size_t)b->rows * b->width;
	float *v = ap_staging_get(s, n, err);
	if (!v)
		return KG_ENOMEM;
	for (size_t i = 0; i < n; i++)
		v[i] = src[i];
	return kg_envi_writer_put(w, b->y0, b->y0 + b->rows, KG_LAYOUT_BIP, v, err);
}

static const char mask_description[] =
	"kogei pixel flags (bits): 1 = an input channel is NaN or Inf; 2 = clipped: a "
	"channel >= the clip level; 4 = negative reflectance clamped to 0. A pixel with "
	"bit 1 or 2 set was not estimated (NaN in the cube; unclassified in a label map)";

int ap_open_mask(const char *out_hdr, int width, int height, char **mask_path,
                     kg_envi_writer **w, kg_err *err)
{
	int rc = kg_apply_side_path(out_hdr, "_mask.hdr", mask_path, err);
	if (rc)
		return rc;
	kg_envi_meta m = {0};
	m.samples = width;
	m.lines = height;
	m.bands = 1;
	m.data_type = KG_ENVI_U8;
	m.interleave = KG_ENVI_BSQ;
	m.description = mask_description;
	return kg_envi_writer_open(*mask_path, &m, w, err); /* its messages name the file */
}

int ap_open_floats(const char *path, int width, int height, int bands,
                   const char *description, const char *const *band_names,
                   kg_envi_writer **w, kg_err *err)
{
	kg_envi_meta m = {0};
	m.samples = width;
	m.lines = height;
	m.bands = bands;
	m.data_type = KG_ENVI_F32;
	m.interleave = KG_ENVI_BIP;
	m.description = description;
	m.band_names = band_names;
	return kg_envi_writer_open(path, &m, w, err);
}

int ap_open_label_map(const char *path, int width, int height,
                      const kg_est_material_set *classes, const char *description,
                      kg_envi_writer **w, kg_err *err)
{
	const int nlabels = classes->n + 3;
	const char **names = calloc((size_t)nlabels, sizeof(char *));
	unsigned char *lookup = malloc(3 * (size_t)nlabels);
	int rc = names && lookup ? 0 : kg_fail(err, KG_ENOMEM, "out of memory");
	for (int l = 0; !rc && l < nlabels; l++) {
		names[l] = ap_label_name(classes, l);
		ap_label_colour(classes, l, lookup + 3 * l);
	}
	if (!rc) {
		kg_envi_meta m = {0};
		m.samples = width;
		m.lines = height;
		m.bands = 1;
		m.data_type = KG_ENVI_U8;
		m.interleave = KG_ENVI_BSQ;
		m.description = description;
		m.classes = nlabels;
		m.class_names = names;
		m.class_lookup = lookup;
		rc = kg_envi_writer_open(path, &m, w, err);
	}
	free(names);
	free(lookup);
	return rc;
}

/* ---- estimate ---------------------------------------------------------------------- */

typedef struct est_sink {
	kg_envi_writer *cube, *mask;
	staging stage;
	progress prog;
	const feed *in;
	const kg_apply_options *opt;
} est_sink;

static int est_sink_fn(void *user, const kg_est_block *b, kg_err *err)
{
	est_sink *s = user;
	size_t n = (size_t)b->rows * b->width * b->bands;
	int rc;
	if (s->opt->observe) {
		planes pl = ap_feed_planes(s->in, b->input, (size_t)b->rows * b->width);
		if ((rc = s->opt->observe(s->opt->observe_user, b, pl.raw, err)))
			return rc;
	}
	switch (b->format) {
	case KG_EST_F32_BSQ:
		rc = kg_envi_writer_put(s->cube, b->y0, b->y0 + b->rows, KG_LAYOUT_PLANAR, b->data, err);
		break;
	case KG_EST_F32_BIP:
	case KG_EST_WEIGHTS:
		rc = kg_envi_writer_put(s->cube, b->y0, b->y0 + b->rows, KG_LAYOUT_BIP, b->data, err);
		break;
	default: { /* f16: the bit patterns, as exact integers */
		float *v = ap_staging_get(&s->stage, n, err);
		if (!v)
			return KG_ENOMEM;
		const uint16_t *h = b->data;
		for (size_t i = 0; i < n; i++)
			v[i] = h[i];
		rc = kg_envi_writer_put(s->cube, b->y0, b->y0 + b->rows,
		                        b->format == KG_EST_F16_BSQ ? KG_LAYOUT_PLANAR : KG_LAYOUT_BIP,
		                        v, err);
	}
	}
	if (!rc)
		rc = ap_put_bytes(s->mask, &s->stage, b, b->mask, err);
	ap_progress_rows(&s->prog, b->y0 + b->rows);
	return rc;
}

int kg_est_kernel_basis(const kg_est_kernel *k, double *basis, double *mean, kg_err *err)
{
	kg_check_arg(k && basis && mean, err);
	if (!k->k || !k->basis)
		return kg_fail(err, KG_EINVAL, "kernel: it has no basis (a pca kernel has one)");
	memcpy(basis, k->basis, sizeof(double) * KG_NBANDS * k->k);
	for (int l = 0; l < KG_NBANDS; l++)
		mean[l] = k->mean ? k->mean[l] : 0.0;
	return 0;
}

static int basis_keys(const kg_est_kernel *k, kg_envi_pair *extra, char **owned, kg_err *err)
{
	int K = kg_est_kernel_k(k);
	double *basis = malloc(sizeof(double) * KG_NBANDS * K);
	double mean[KG_NBANDS], wl[KG_NBANDS];
	if (!basis)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	int rc = kg_est_kernel_basis(k, basis, mean, err);
	for (int l = 0; l < KG_NBANDS; l++)
		wl[l] = kg_band_nm(l);
	if (!rc)
		rc = kg_envi_format_list(basis, KG_NBANDS * K, &owned[0], err);
	if (!rc)
		rc = kg_envi_format_list(mean, KG_NBANDS, &owned[1], err);
	if (!rc)
		rc = kg_envi_format_list(wl, KG_NBANDS, &owned[2], err);
	free(basis);
	if (rc)
		return rc;
	extra[0] = (kg_envi_pair){"kogei basis", owned[0]};
	extra[1] = (kg_envi_pair){"kogei mean", owned[1]};
	extra[2] = (kg_envi_pair){"kogei basis wavelength", owned[2]};
	return 0;
}

static const char *format_name(kg_est_format f)
{
	switch (f) {
	case KG_EST_F32_BSQ:
	case KG_EST_F32_BIP: return "f32";
	case KG_EST_F16_BSQ:
	case KG_EST_F16_BIP: return "f16";
	case KG_EST_WEIGHTS: return "weights";
	default: return "labels";
	}
}

/* An image in memory: its CFA, if any, makes the message about channels clearer. */
static int check_image(const kg_image *img, const char *what, kg_err *err)
{
	if (img && img->data && img->channels == 1 && img->cfa)
		return kg_fail(err, KG_EINVAL,
		               "%s: the image has 1 channel (a raw CFA frame): expected 3 (linear "
		               "RGB); a raw Bayer frame must be demosaiced first", what);
	if (!img || !img->data || img->width < 1 || img->height < 1)
		return kg_fail(err, KG_EINVAL, "%s: no image data", what);
	return 0;
}

int kg_estimate_image(const kg_est_kernel *k, const kg_image *img, kg_est_format format,
                      const kg_apply_options *opt, const char *out_hdr, kg_est_stats *stats,
                      kg_err *err)
{
	kg_check_arg(k && img && out_hdr, err);
	int rc = check_image(img, "estimate", err);
	if (rc)
		return rc;
	kg_row_source src;
	kg_row_source_of_image(img, &src);
	return kg_estimate_rows(k, &src, format, opt, out_hdr, stats, err);
}

int kg_estimate_rows(const kg_est_kernel *k, const kg_row_source *src, kg_est_format format,
                     const kg_apply_options *opt, const char *out_hdr, kg_est_stats *stats,
                     kg_err *err)
{
	kg_check_arg(k && src && out_hdr, err);
	kg_apply_options dflt;
	if (!opt) {
		kg_apply_options_init(&dflt);
		opt = &dflt;
	}
	if (format != KG_EST_F32_BSQ && format != KG_EST_F32_BIP && format != KG_EST_F16_BSQ &&
	    format != KG_EST_F16_BIP && format != KG_EST_WEIGHTS)
		return kg_fail(err, KG_EINVAL, "%s: output format %d: expected f32, f16 or weights",
		               out_hdr, (int)format);
	int K = kg_est_kernel_k(k);
	if (format == KG_EST_WEIGHTS && K == 0)
		return kg_fail(err, KG_EINVAL,
		               "%s: weights output needs a method with a K-dimensional basis (pca); "
		               "this kernel gives spectra only",
		               out_hdr);

	feed in;
	int rc = ap_feed_init(&in, src, opt, "estimate", err);
	if (rc)
		return rc;
	kg_est_stats local;
	if (!stats)
		stats = &local;

	char *owned[3] = {NULL, NULL, NULL};
	char *mask_path = NULL;
	kg_envi_writer *ws[2] = {NULL, NULL};
	const char *paths[2] = {out_hdr, NULL};
	est_sink sink = {0};
	written done = {0};
	double wl[KG_NBANDS];
	const char *band_names[KG_EST_MAX_K];
	char band_text[KG_EST_MAX_K][16];
	kg_envi_pair extra[4];
	kg_envi_meta m = {0};
	m.samples = src->width;
	m.lines = src->height;
	m.bands = kg_est_format_bands(k, format);
	m.interleave = (format == KG_EST_F32_BSQ || format == KG_EST_F16_BSQ) ? KG_ENVI_BSQ
	                                                                      : KG_ENVI_BIP;
	m.data_type = (format == KG_EST_F16_BSQ || format == KG_EST_F16_BIP) ? KG_ENVI_U16
	                                                                     : KG_ENVI_F32;
	m.description = opt->description;
	m.extra = extra;
	if (format == KG_EST_WEIGHTS) {
		if ((rc = basis_keys(k, extra, owned, err)))
			goto out;
		m.n_extra = 3;
		for (int i = 0; i < K; i++) {
			snprintf(band_text[i], sizeof(band_text[i]), "w%d", i + 1);
			band_names[i] = band_text[i];
		}
		m.band_names = band_names;
	} else {
		for (int l = 0; l < KG_NBANDS; l++)
			wl[l] = kg_band_nm(l);
		m.wavelength = wl;
	}
	if (m.data_type == KG_ENVI_U16)
		extra[m.n_extra++] = (kg_envi_pair){"kogei sample format", "ieee-half"};

	if ((rc = kg_envi_writer_open(out_hdr, &m, &ws[0], err)))
		goto out;
	if ((rc = ap_open_mask(out_hdr, src->width, src->height, &mask_path, &ws[1], err)))
		goto out;
	paths[1] = mask_path;

	kg_est_job job;
	kg_est_job_init(&job, k, format);
	ap_feed_job(&in, &job);
	job.threads = opt->threads;
	job.block_rows = opt->block_rows;
	job.isa = opt->isa;
	sink.cube = ws[0];
	sink.mask = ws[1];
	sink.in = &in;
	sink.opt = opt;
	ap_progress_init(&sink.prog, opt, "estimate", src->width, src->height);
	rc = kg_est_run_stream(&job, NULL, src->width, src->height, est_sink_fn, &sink, stats,
	                       err);
	if (rc) {
		kg_err_prefix(err, "%s (%s): ", out_hdr, format_name(format));
		goto out;
	}
	if ((rc = ap_check_estimable(stats, &in, "estimate", err)))
		goto out;
	rc = ap_finish_all(ws, paths, 2, &done, err);

out:
	for (int i = 0; i < 2; i++)
		if (ws[i])
			kg_envi_writer_abort(&ws[i]);
	ap_written_clear(&done, rc != 0);
	free(sink.stage.v);
	free(mask_path);
	for (int i = 0; i < 3; i++)
		free(owned[i]);
	return rc;
}

/* ---- the declared materials ------------------------------------------------------ */

void kg_est_material_set_free(kg_est_material_set **pset)
{
	if (!pset || !*pset)
		return;
	kg_est_material_set *s = *pset;
	free(s->materials);
	free(s->spectra);
	free(s->names);
	free(s->mats);
	free(s);
	*pset = NULL;
}

static void list_library(const kg_material_library *lib, char *buf, size_t size)
{
	size_t used = 0;
	buf[0] = '\0';
	for (int i = 0; i < kg_material_library_count(lib) && used + 1 < size; i++) {
		int w = snprintf(buf + used, size - used, "%s%s", i ? ", " : "",
		                 kg_material_library_get(lib, i)->name);
		if (w < 0)
			break;
		used += (size_t)w;
	}
}

int kg_est_material_set_new(const kg_material_library *lib, const char *library,
                            const char *const *only, int nonly, double angle_deg,
                            kg_est_material_set **out, kg_err *err)
{
	kg_check_arg(lib && out && nonly >= 0 && (nonly == 0 || only), err);
	if (!library)
		library = "material library";
	if (!(angle_deg >= 0 && angle_deg <= 90))
		return kg_fail(err, KG_EINVAL, "%s: incidence angle %g: expected 0 to 90 degrees",
		               library, angle_deg);
	int n = nonly ? nonly : kg_material_library_count(lib);
	char known[1024];
	list_library(lib, known, sizeof(known));
	if (n < 1)
		return kg_fail(err, KG_EINVAL, "%s: no materials to classify among", library);
	if (n > KG_EST_MAX_MATERIALS)
		return kg_fail(err, KG_EINVAL, "%s: %d materials: at most %d fit a label map", library,
		               n, KG_EST_MAX_MATERIALS);
	for (int i = 0; i < nonly; i++) {
		if (!kg_material_library_find(lib, only[i]))
			return kg_fail(err, KG_EINVAL, "%s: no material named '%s'; it has: %s", library,
			               only[i], known);
		for (int j = 0; j < i; j++)
			if (strcmp(only[i], only[j]) == 0)
				return kg_fail(err, KG_EINVAL, "%s: material '%s' is named twice", library,
				               only[i]);
	}
	kg_est_material_set *s = calloc(1, sizeof(*s));
	if (!s)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	s->n = n;
	s->angle_deg = angle_deg;
	s->materials = calloc((size_t)n, sizeof(*s->materials));
	s->spectra = calloc((size_t)n, sizeof(*s->spectra));
	s->names = calloc((size_t)n, sizeof(*s->names));
	s->mats = calloc((size_t)n, sizeof(*s->mats));
	if (!s->materials || !s->spectra || !s->names || !s->mats) {
		kg_est_material_set_free(&s);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	double theta = angle_deg * M_PI / 180.0;
	for (int i = 0; i < n; i++) {
		const kg_material *mat =
			nonly ? kg_material_library_find(lib, only[i]) : kg_material_library_get(lib, i);
		int rc = kg_material_reflectance(mat, theta, &s->spectra[i], err);
		if (rc) {
			kg_err_prefix(err, "%s: material '%s': ", library, mat->name);
			kg_est_material_set_free(&s);
			return rc;
		}
		snprintf(s->names[i], sizeof(s->names[i]), "%s", mat->name);
		s->mats[i] = mat;
		s->materials[i].name = s->names[i];
		s->materials[i].spectrum = s->spectra[i].v;
	}
	*out = s;
	return 0;
}

/* ---- classify -------------------------------------------------------------------- */

void kg_classify_result_free(kg_classify_result *r)
{
	if (!r)
		return;
	free(r->classes);
	memset(r, 0, sizeof(*r));
}

/* Distinct colours for the classes: K. L. Kelly's (1965) colours of maximum
 * contrast without white, black and grey (grey marks flagged pixels), then hues
 * spaced by the golden angle. */
void ap_class_colour(int j, unsigned char rgb[3])
{
	/* Kelly's 22 colours of maximum contrast less white, black and grey, ordered so
	 * that every leading run keeps its colours apart (greedy: each next colour the
	 * farthest in CIELAB from those before it and from the flagged grey, the unknown
	 * magenta and the background's near-black; the least distance of the first 10 is
	 * 34 Delta E*ab, of all 19 is 15) */
	static const unsigned char kelly[19][3] = {
		{0xF3, 0xC3, 0x00}, {0xBE, 0x00, 0x32}, {0x60, 0x4E, 0x97}, {0x00, 0x88, 0x56},
		{0xF9, 0x93, 0x79}, {0x8D, 0xB6, 0x00}, {0xF3, 0x84, 0x00}, {0xA1, 0xCA, 0xF1},
		{0x65, 0x45, 0x22}, {0xB3, 0x44, 0x6C}, {0xC2, 0xB2, 0x80}, {0x88, 0x2D, 0x17},
		{0xE6, 0x8F, 0xAC}, {0x00, 0x67, 0xA5}, {0xE2, 0x58, 0x22}, {0x2B, 0x3D, 0x26},
		{0xF6, 0xA6, 0x00}, {0xDC, 0xD3, 0x00}, {0x87, 0x56, 0x92},
	};
	if (j < 19) {
		memcpy(rgb, kelly[j], 3);
		return;
	}
	double h = fmod(j * 0.618033988749895, 1.0) * 6.0, v = j % 2 ? 0.75 : 0.95, s = 0.8;
	int i = (int)h;
	double f = h - i, p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
	double c[6][3] = {{v, t, p}, {q, v, p}, {p, v, t}, {p, q, v}, {t, p, v}, {v, p, q}};
	for (int k = 0; k < 3; k++)
		rgb[k] = (unsigned char)lround(255.0 * c[i % 6][k]);
}

static const unsigned char flagged_grey[3] = {128, 128, 128};
static const unsigned char unknown_magenta[3] = {255, 0, 255};
static const unsigned char background_dark[3] = {24, 24, 24};

/* Labels of the two refusal classes after the n materials. */
int ap_label_unknown(const kg_est_material_set *set) { return set->n + 1; }
int ap_label_background(const kg_est_material_set *set) { return set->n + 2; }

const char *ap_label_name(const kg_est_material_set *set, int label)
{
	if (label == KG_EST_LABEL_NONE)
		return "unclassified";
	if (label == ap_label_unknown(set))
		return "unknown";
	if (label == ap_label_background(set))
		return "background";
	return set->names[label - 1];
}

void ap_label_colour(const kg_est_material_set *set, int label, unsigned char rgb[3])
{
	if (label == KG_EST_LABEL_NONE)
		memcpy(rgb, flagged_grey, 3);
	else if (label == ap_label_unknown(set))
		memcpy(rgb, unknown_magenta, 3);
	else if (label == ap_label_background(set))
		memcpy(rgb, background_dark, 3);
	else
		ap_class_colour(label - 1, rgb);
}

/* The refusal stage (kg_classify_options), applied to every block after the label
 * kernel, whichever implementation produced it: per pixel, in double. */
typedef struct refusal {
	const kg_est_kernel *k;
	const kg_est_classifier *cls;
	double inv_frames, noise_rel2, noise_floor2, resid2;
	double g[KG_EST_MAX_K * 3]; /* A_w P: K x 3 */
	double threshold;           /* +Inf: no unknown test */
	float background_level;     /* 0: no low-signal test */
	uint8_t unknown, background;
} refusal;

/* Pixel i of a block whose input planes are pl (raw: the image's values, before pre;
 * kin: what the kernel saw; var and mask when given). */
static void refuse_pixel(const refusal *r, const planes *pl, size_t i, uint8_t *label,
                         float *conf)
{
	const float *px = pl->raw + 3 * i;
	if (pl->mask && pl->mask[i] == 0.0f) {
		*label = r->background;
		*conf = NAN;
		return;
	}
	if (*label == KG_EST_LABEL_NONE)
		return;
	if (fmaxf(px[0], fmaxf(px[1], px[2])) < r->background_level) {
		*label = r->background;
		*conf = NAN;
		return;
	}
	if (isinf(r->threshold))
		return;
	const int k = r->cls->k;
	float w[KG_EST_MAX_K];
	kg_est_kernel_eval(r->k, pl->kin + 3 * i, INFINITY, 1, w);
	double var[3];
	for (int c = 0; c < 3; c++) {
		double rho = px[c] > 0.0f ? px[c] : 0.0;
		double noise = pl->var ? pl->var[3 * i + c] * r->inv_frames
		                      : r->noise_floor2 + r->noise_rel2 * rho * rho;
		var[c] = noise + r->resid2 * rho * rho;
	}
	double sigma[KG_EST_MAX_K * KG_EST_MAX_K];
	for (int a = 0; a < k; a++)
		for (int b = 0; b < k; b++)
			sigma[a * k + b] = r->g[a * 3] * r->g[b * 3] * var[0] +
			                   r->g[a * 3 + 1] * r->g[b * 3 + 1] * var[1] +
			                   r->g[a * 3 + 2] * r->g[b * 3 + 2] * var[2];
	if (kg_est_classifier_chi2(r->cls, *label - 1, w, sigma) > r->threshold) {
		*label = r->unknown;
		*conf = NAN;
	}
}

/* Exact order statistics of each class's margins in bounded memory. Margins map to
 * 32-bit keys that sort as the floats do; the sink counts each class's keys by their
 * high 16 bits (pass 1); the ranks wanted then lie in known buckets, whose low 16
 * bits a second pass over the written confidence file counts. */
uint32_t ap_order_key(float v)
{
	uint32_t u;
	memcpy(&u, &v, 4);
	return u & 0x80000000u ? ~u : u | 0x80000000u;
}

float ap_key_value(uint32_t k)
{
	uint32_t u = k & 0x80000000u ? k & 0x7fffffffu : ~k;
	float v;
	memcpy(&v, &u, 4);
	return v;
}

typedef struct cls_sink {
	kg_envi_writer *labels, *conf, *mask;
	staging stage;
	progress prog;
	const feed *in;
	const refusal *refuse;
	int nmaterials;
	uint64_t count[KG_EST_MAX_MATERIALS + 3]; /* per label */
	class_stats *cs;   /* per material, index label - 1 */
	uint8_t *preview;  /* pw x ph labels, nearest sample */
	int pw, ph, next_py;
	int height;
} cls_sink;

static int cls_sink_fn(void *user, const kg_est_block *b, kg_err *err)
{
	cls_sink *s = user;
	size_t n = (size_t)b->rows * b->width;
	uint8_t *lab = (uint8_t *)b->data;
	float *conf = (float *)b->confidence;
	planes pl = ap_feed_planes(s->in, b->input, n);
	for (size_t i = 0; i < n; i++) {
		refuse_pixel(s->refuse, &pl, i, &lab[i], &conf[i]);
		s->count[lab[i]]++;
		if (lab[i] == KG_EST_LABEL_NONE || lab[i] > s->nmaterials)
			continue;
		class_stats *c = &s->cs[lab[i] - 1];
		if (!c->hi && !(c->hi = calloc(HIST_BINS, sizeof(uint32_t))))
			return kg_fail(err, KG_ENOMEM, "classify: out of memory for the margins");
		c->hi[ap_order_key(conf[i]) >> 16]++;
		c->count++;
		c->margin_sum += conf[i];
		for (int ch = 0; ch < 3; ch++)
			c->rgb_sum[ch] += pl.kin[3 * i + ch];
	}
	for (; s->next_py < s->ph; s->next_py++) {
		int sy = (int)((long)s->next_py * s->height / s->ph);
		if (sy >= b->y0 + b->rows)
			break;
		const uint8_t *row = lab + (size_t)(sy - b->y0) * b->width;
		for (int x = 0; x < s->pw; x++)
			s->preview[(size_t)s->next_py * s->pw + x] = row[(long)x * b->width / s->pw];
	}
	int rc = ap_put_bytes(s->labels, &s->stage, b, lab, err);
	if (!rc)
		rc = kg_envi_writer_put(s->conf, b->y0, b->y0 + b->rows, KG_LAYOUT_BIP, conf, err);
	if (!rc)
		rc = ap_put_bytes(s->mask, &s->stage, b, b->mask, err);
	ap_progress_rows(&s->prog, b->y0 + b->rows);
	return rc;
}

/* The ranks wanted of each class, and the buckets of pass 1 they fall in. */
void ap_stats_targets(class_stats *c)
{
	uint64_t m = c->count;
	c->ntargets = 0;
	if (m % 2)
		c->rank[c->ntargets++] = m / 2;
	else {
		c->rank[c->ntargets++] = m / 2 - 1;
		c->rank[c->ntargets++] = m / 2;
	}
	uint64_t p5 = (uint64_t)ceil(0.05 * (double)m);
	c->rank[c->ntargets++] = p5 ? p5 - 1 : 0;
	for (int t = 0; t < c->ntargets; t++) {
		uint64_t below = 0;
		uint32_t bin = 0;
		while (below + c->hi[bin] <= c->rank[t])
			below += c->hi[bin++];
		c->bucket[t] = bin;
		c->below[t] = below;
	}
}

/* Pass 2: the low halves of the keys in the wanted buckets, from the files just
 * written (labels after the refusals, margins), read back in bands of rows. */
int ap_margin_pass(class_stats *cs, int nclasses, const char *labels_hdr, const char *conf_hdr,
                   int bands, int width, int height, kg_err *err)
{
	for (int j = 0; j < nclasses; j++) {
		class_stats *c = &cs[j];
		if (!c->count)
			continue;
		ap_stats_targets(c);
		for (int t = 0; t < c->ntargets; t++)
			if (!(c->lo[t] = calloc(HIST_BINS, sizeof(uint32_t))))
				return kg_fail(err, KG_ENOMEM, "classify: out of memory for the margins");
	}
	kg_envi *el = NULL, *ec = NULL;
	int band = (int)(((size_t)1 << 20) / (size_t)width);
	band = band < 1 ? 1 : band > height ? height : band;
	float *lab = malloc(sizeof(float) * (size_t)band * width);
	float *conf = malloc(sizeof(float) * (size_t)band * width * (size_t)bands);
	int rc = lab && conf ? 0 : kg_fail(err, KG_ENOMEM, "classify: out of memory");
	if (!rc)
		rc = kg_envi_open(labels_hdr, &el, err);
	if (!rc)
		rc = kg_envi_open(conf_hdr, &ec, err);
	for (int y = 0; y < height && !rc; y += band) {
		int rows = height - y < band ? height - y : band;
		rc = kg_envi_read(el, 0, y, width, rows, KG_LAYOUT_BIP, lab, err);
		if (!rc)
			rc = kg_envi_read(ec, 0, y, width, rows, KG_LAYOUT_BIP, conf, err);
		size_t n = (size_t)rows * width;
		for (size_t i = 0; i < n && !rc; i++) {
			int l = (int)lab[i];
			if (l < 1 || l > nclasses)
				continue;
			class_stats *c = &cs[l - 1];
			uint32_t key = ap_order_key(conf[i * (size_t)bands]);
			for (int t = 0; t < c->ntargets; t++)
				if (key >> 16 == c->bucket[t])
					c->lo[t][key & 0xffffu]++;
		}
	}
	kg_envi_close(&el);
	kg_envi_close(&ec);
	free(lab);
	free(conf);
	for (int j = 0; j < nclasses && !rc; j++) {
		class_stats *c = &cs[j];
		for (int t = 0; t < c->ntargets && c->count; t++) {
			uint64_t below = c->below[t];
			uint32_t bin = 0;
			while (bin < HIST_BINS - 1 && below + c->lo[t][bin] <= c->rank[t])
				below += c->lo[t][bin++];
			c->value[t] = ap_key_value(c->bucket[t] << 16 | bin);
		}
	}
	return rc;
}

void ap_class_stats_free(class_stats *cs, int n)
{
	for (int j = 0; cs && j < n; j++) {
		free(cs[j].hi);
		for (int t = 0; t < MAX_TARGETS; t++)
			free(cs[j].lo[t]);
	}
	free(cs);
}

static void cls_sink_free(cls_sink *s)
{
	ap_class_stats_free(s->cs, s->nmaterials);
	free(s->preview);
	free(s->stage.v);
}

/* Counts, mean spectra and margin statistics per class (after ap_margin_pass). */
int ap_summarise(const kg_est_kernel *k, const kg_est_material_set *set, const uint64_t *count,
                 const class_stats *cstats, size_t npix, kg_classify_result *res, kg_err *err)
{
	int n = set->n;
	res->nclasses = n;
	res->classes = calloc((size_t)n, sizeof(*res->classes));
	if (!res->classes)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	res->unclassified = count[0];
	res->unknown = count[ap_label_unknown(set)];
	res->background = count[ap_label_background(set)];
	for (int j = 0; j < n; j++) {
		kg_class_summary *c = &res->classes[j];
		const class_stats *cs = &cstats[j];
		snprintf(c->name, sizeof(c->name), "%s", set->names[j]);
		c->pixels = cs->count;
		c->fraction = npix ? (double)c->pixels / (double)npix : 0.0;
		if (!c->pixels) {
			for (int l = 0; l < KG_NBANDS; l++)
				c->mean_spectrum[l] = NAN;
			c->margin_mean = c->margin_median = c->margin_p5 = NAN;
			continue;
		}
		float mean_rgb[3], spec[KG_NBANDS];
		for (int ch = 0; ch < 3; ch++)
			mean_rgb[ch] = (float)(cs->rgb_sum[ch] / (double)c->pixels);
		if (k)
			kg_est_kernel_eval(k, mean_rgb, INFINITY, 0, spec);
		for (int l = 0; l < KG_NBANDS; l++)
			c->mean_spectrum[l] = k ? spec[l] : NAN;
		c->margin_mean = cs->margin_sum / (double)c->pixels;
		c->margin_median = cs->ntargets == 3 ? 0.5 * ((double)cs->value[0] + cs->value[1])
		                                     : cs->value[0];
		c->margin_p5 = cs->value[cs->ntargets - 1];
	}
	return 0;
}

/* A number, or null where JSON has none (NaN, +-Inf). */
json_t *ap_json_num(double v)
{
	return isfinite(v) ? json_real(v) : json_null();
}

static const char *distance_name(kg_est_distance d)
{
	return d == KG_EST_DIST_SCALE_FREE ? "scale-free" : "plain";
}

/* How unknown and background were decided, for LABELS.json. */
static json_t *refusal_json(const kg_classify_options *copt, const kg_classify_info *info,
                            const kg_classify_result *res)
{
	json_t *r = json_object();
	json_t *bg = json_object();
	json_object_set_new(bg, "level", copt->background_level > 0
	                                     ? json_real(copt->background_level)
	                                     : json_null());
	json_object_set_new(bg, "signal",
	                    json_string("largest channel of the image, 0..1 full scale"));
	json_object_set_new(bg, "mask", copt->mask ? json_string(info && info->mask ? info->mask
	                                                                            : "given")
	                                           : json_null());
	json_object_set_new(r, "background", bg);
	json_t *u = json_object();
	int on = isfinite(res->unknown_threshold);
	json_object_set_new(u, "enabled", json_boolean(on));
	json_object_set_new(u, "statistic",
	                    json_string("chi2 = r^T (sigma_w + (o_j / K) I)^-1 r of the best "
	                                "material j: r its residual in the K weights, o_j the "
	                                "distance's part outside the basis, sigma_w the noise "
	                                "and calibration error propagated through the weight "
	                                "matrix"));
	json_object_set_new(u, "threshold", ap_json_num(res->unknown_threshold));
	json_object_set_new(u, "dof", json_integer(res->dof));
	json_object_set_new(u, "probability",
	                    on && copt->unknown_threshold == 0 ? json_real(0.999) : json_null());
	json_object_set_new(u, "residual_relative", json_real(copt->residual_relative));
	if (copt->variance) {
		json_object_set_new(u, "noise", json_string("variance image"));
		json_object_set_new(u, "variance", json_string(info && info->variance ? info->variance
		                                                                      : "given"));
		json_object_set_new(u, "frames", json_integer(copt->frames));
	} else {
		json_object_set_new(u, "noise", json_string("model"));
		json_object_set_new(u, "noise_relative", json_real(copt->noise_relative));
		json_object_set_new(u, "noise_floor", json_real(copt->noise_floor));
		json_object_set_new(u, "note",
		                    json_string("no variance image: assumed per channel sigma^2 = "
		                                "noise_floor^2 + (noise_relative rho)^2"));
	}
	json_object_set_new(r, "unknown", u);
	return r;
}

json_t *ap_refusal_class(const kg_est_material_set *set, int label, uint64_t pixels,
                             uint64_t total)
{
	unsigned char col[3];
	ap_label_colour(set, label, col);
	json_t *o = json_object();
	json_object_set_new(o, "label", json_integer(label));
	json_object_set_new(o, "name", json_string(ap_label_name(set, label)));
	json_object_set_new(o, "pixels", json_integer((json_int_t)pixels));
	json_object_set_new(o, "fraction", json_real(total ? (double)pixels / (double)total : 0.0));
	json_object_set_new(o, "colour", json_pack("[iii]", col[0], col[1], col[2]));
	json_object_set_new(o, "mean_spectrum", json_null());
	json_object_set_new(o, "confidence", json_null());
	return o;
}

static int write_json(const char *path, const kg_est_material_set *set,
                      const kg_classify_options *copt, const kg_row_source *img,
                      const kg_apply_options *opt, const kg_classify_info *info,
                      const char *const files[4], const kg_classify_result *res, kg_err *err)
{
	json_t *root = json_object();
	json_t *classes = json_array();
	json_t *wl = json_array();
	if (!root || !classes || !wl) {
		json_decref(root);
		json_decref(classes);
		json_decref(wl);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	json_object_set_new(root, "format", json_string("kogei-labels/1"));
	const char *keys[4] = {"image", "calib", "materials", "method"};
	const char *vals[4] = {info ? info->image : NULL, info ? info->calib : NULL,
	                       info ? info->materials : NULL, info ? info->method : NULL};
	for (int i = 0; i < 4; i++)
		json_object_set_new(root, keys[i], vals[i] ? json_string(vals[i]) : json_null());
	json_object_set_new(root, "distance", json_string(distance_name(copt->distance)));
	json_object_set_new(root, "angle_deg", json_real(set->angle_deg));
	json_object_set_new(root, "clip_level", ap_json_num(opt->clip_level));
	{ /* per channel: the clip level, or the saturation found from the data below it */
		json_t *cl = json_array();
		for (int c = 0; c < 3; c++)
			json_array_append_new(cl, ap_json_num(opt->clip_rgb[c] > 0 &&
			                                      opt->clip_rgb[c] < opt->clip_level
			                                          ? opt->clip_rgb[c] : opt->clip_level));
		json_object_set_new(root, "clip_levels", cl);
	}
	json_object_set_new(root, "width", json_integer(img->width));
	json_object_set_new(root, "height", json_integer(img->height));
	json_object_set_new(root, "pixels", json_integer((json_int_t)res->stats.pixels));
	json_t *fl = json_object();
	json_object_set_new(fl, "unclassified", json_integer((json_int_t)res->unclassified));
	json_object_set_new(fl, "nonfinite", json_integer((json_int_t)res->stats.nonfinite));
	json_object_set_new(fl, "clipped", json_integer((json_int_t)res->stats.clipped));
	json_object_set_new(root, "flagged", fl);
	json_object_set_new(root, "refusal", refusal_json(copt, info, res));
	json_t *fs = json_object();
	const char *fkeys[4] = {"labels", "confidence", "mask", "preview"};
	for (int i = 0; i < 4; i++)
		json_object_set_new(fs, fkeys[i], json_string(files[i]));
	json_object_set_new(root, "files", fs);
	json_object_set_new(root, "confidence",
	                    json_string("margin: distance to the runner-up minus distance to the "
	                                "chosen material (squared reflectance over 61 bands); "
	                                "none for unknown and background"));
	for (int l = 0; l < KG_NBANDS; l++)
		json_array_append_new(wl, json_real(kg_band_nm(l)));
	json_object_set_new(root, "wavelength_nm", wl);
	json_t *c0 = json_object();
	json_object_set_new(c0, "label", json_integer(0));
	json_object_set_new(c0, "name", json_string("unclassified"));
	json_object_set_new(c0, "pixels", json_integer((json_int_t)res->unclassified));
	json_object_set_new(c0, "fraction",
	                    json_real(res->stats.pixels
	                                  ? (double)res->unclassified / (double)res->stats.pixels
	                                  : 0.0));
	json_array_append_new(classes, c0);
	for (int j = 0; j < res->nclasses; j++) {
		const kg_class_summary *c = &res->classes[j];
		json_t *o = json_object();
		unsigned char col[3];
		ap_label_colour(set, j + 1, col);
		json_object_set_new(o, "label", json_integer(j + 1));
		json_object_set_new(o, "name", json_string(c->name));
		json_object_set_new(o, "pixels", json_integer((json_int_t)c->pixels));
		json_object_set_new(o, "fraction", json_real(c->fraction));
		json_object_set_new(o, "colour", json_pack("[iii]", col[0], col[1], col[2]));
		json_t *ms = json_null();
		if (c->pixels) {
			ms = json_array();
			for (int l = 0; l < KG_NBANDS; l++)
				json_array_append_new(ms, ap_json_num(c->mean_spectrum[l]));
		}
		json_object_set_new(o, "mean_spectrum", ms);
		json_t *conf = json_object();
		json_object_set_new(conf, "mean", ap_json_num(c->margin_mean));
		json_object_set_new(conf, "median", ap_json_num(c->margin_median));
		json_object_set_new(conf, "p5", ap_json_num(c->margin_p5));
		json_object_set_new(o, "confidence", conf);
		json_array_append_new(classes, o);
	}
	json_array_append_new(classes, ap_refusal_class(set, ap_label_unknown(set), res->unknown,
	                                             res->stats.pixels));
	json_array_append_new(classes, ap_refusal_class(set, ap_label_background(set), res->background,
	                                             res->stats.pixels));
	json_object_set_new(root, "classes", classes);
	int rc = kg_json_write(root, path, err);
	json_decref(root);
	if (rc)
		kg_err_prefix(err, "%s: ", path);
	return rc;
}

/* The label map with class colours (flagged pixels grey, unknown magenta, background
 * near-black), at most 720 pixels on its longer side (nearest sample), and a legend
 * with each class's share. */
void ap_preview_size(int width, int height, int *pw, int *ph)
{
	double scale = 720.0 / (width > height ? width : height);
	*pw = (int)lround(width * scale);
	*ph = (int)lround(height * scale);
	*pw = *pw < 1 ? 1 : *pw;
	*ph = *ph < 1 ? 1 : *ph;
}

/* labels: the pw x ph nearest samples the sink kept (ap_preview_size). */
int ap_write_preview(const char *path, const kg_est_material_set *set,
                         const uint8_t *labels, int pw, int ph,
                         const kg_classify_result *res, int legend, kg_err *err)
{
	/* The legend in full: a compound class's members one per line (no name is cut
	 * off), 14 px text, the legend as wide as its longest line (about 0.62 em a
	 * character for the sans-serif face) */
	const int margin = 10, line_h = 19, gap = 6, font = 14;
	const int nlabels = set->n + 3;
	int lines = 0;
	size_t longest = 0;
	for (int j = 0; j < nlabels; j++) {
		const char *name = j ? ap_label_name(set, j) : "flagged (unclassified)";
		for (const char *q = name; q;) {
			const char *bar = strchr(q, '|');
			/* " |  100.0 %" on the first line, an indent and " |" on the others */
			size_t len = (bar ? (size_t)(bar - q) : strlen(q)) + (q == name ? 12 : 4);
			longest = len > longest ? len : longest;
			lines++;
			q = bar ? bar + 1 : NULL;
		}
	}
	int legend_w = 30 + (int)ceil(0.62 * font * (double)longest) + margin;
	legend_w = !legend ? 0 : legend_w < 260 ? 260 : legend_w;
	int legend_h = legend ? line_h * lines + gap * nlabels + 2 * margin : 0;
	int fig_h = (ph + 2 * margin > legend_h ? ph + 2 * margin : legend_h);
	kg_plot *p = NULL;
	int rc = kg_plot_new(pw + legend_w + 2 * margin, fig_h, &p, err);
	if (rc)
		return rc;
	unsigned char (*pal)[3] = malloc(sizeof(*pal) * 256);
	if (!pal) {
		kg_plot_free(&p);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	for (int l = 0; l < 256; l++)
		ap_label_colour(set, l < nlabels ? l : 0, pal[l]);
	for (int y = 0; y < ph; y++) {
		const uint8_t *row = labels + (size_t)y * pw;
		for (int x0 = 0; x0 < pw;) {
			uint8_t l = row[x0];
			int x1 = x0 + 1;
			while (x1 < pw && row[x1] == l)
				x1++;
			double c[3] = {pal[l][0] / 255.0, pal[l][1] / 255.0, pal[l][2] / 255.0};
			kg_plot_fill_rect(p, margin + x0, margin + y, x1 - x0, 1, c);
			x0 = x1;
		}
	}
	const double black[3] = {0, 0, 0}, edge[3] = {0.5, 0.5, 0.5};
	double lx = pw + 2 * margin, y = margin;
	for (int j = 0; legend && j < nlabels; j++) {
		double c[3] = {pal[j][0] / 255.0, pal[j][1] / 255.0, pal[j][2] / 255.0};
		kg_plot_fill_rect(p, lx, y + 2, 16, 16, c);
		kg_plot_stroke_rect(p, lx, y + 2, 16, 16, edge, 1);
		uint64_t count = j == 0                        ? res->unclassified
		                 : j == ap_label_unknown(set)     ? res->unknown
		                 : j == ap_label_background(set)  ? res->background
		                                               : res->classes[j - 1].pixels;
		double frac =
			res->stats.pixels ? 100.0 * (double)count / (double)res->stats.pixels : 0.0;
		const char *name = j ? ap_label_name(set, j) : "flagged (unclassified)";
		for (const char *q = name; q;) {
			const char *bar = strchr(q, '|');
			if (q == name && !bar)
				kg_plot_text(p, lx + 24, y + 15, font, KG_ALIGN_LEFT, black, "%s  %.1f %%", q,
				             frac);
			else if (q == name)
				kg_plot_text(p, lx + 24, y + 15, font, KG_ALIGN_LEFT, black, "%.*s |  %.1f %%",
				             (int)(bar - q), q, frac);
			else if (bar)
				kg_plot_text(p, lx + 36, y + 15, font, KG_ALIGN_LEFT, black, "%.*s |",
				             (int)(bar - q), q);
			else
				kg_plot_text(p, lx + 36, y + 15, font, KG_ALIGN_LEFT, black, "%s", q);
			y += line_h;
			q = bar ? bar + 1 : NULL;
		}
		y += gap;
	}
	free(pal);
	rc = kg_plot_save_png(p, path, err);
	kg_plot_free(&p);
	if (rc)
		kg_err_prefix(err, "%s: ", path);
	return rc;
}

void kg_classify_options_init(kg_classify_options *o)
{
	memset(o, 0, sizeof(*o));
	o->distance = KG_EST_DIST_PLAIN;
	o->frames = 1;
	o->noise_relative = 0.01;
	o->noise_floor = 0.002;
	o->residual_relative = 0.0;
	o->unknown_threshold = 0.0;
	o->background_level = 0.01;
}

static const char *side_name_variance(const kg_classify_info *info)
{
	return info && info->variance ? info->variance : "the variance image";
}

static const char *side_name_mask(const kg_classify_info *info)
{
	return info && info->mask ? info->mask : "the mask";
}

int ap_check_options(const kg_classify_options *o, const kg_row_source *img,
                         const kg_classify_info *info, const char *what, kg_err *err)
{
	if (o->frames < 1)
		return kg_fail(err, KG_EINVAL, "%s: frames %d: expected 1 or more", what, o->frames);
	const double nonneg[3] = {o->noise_relative, o->noise_floor, o->residual_relative};
	const char *names[3] = {"noise_relative", "noise_floor", "residual_relative"};
	for (int i = 0; i < 3; i++)
		if (!(nonneg[i] >= 0 && isfinite(nonneg[i])))
			return kg_fail(err, KG_EINVAL, "%s: %s %g: expected a finite value >= 0", what,
			               names[i], nonneg[i]);
	if (!(o->unknown_threshold >= 0))
		return kg_fail(err, KG_EINVAL,
		               "%s: unknown threshold %g: expected a value > 0, 0 for the 99.9 %% "
		               "point or infinity for no unknown test",
		               what, o->unknown_threshold);
	if (!(o->background_level >= 0 && o->background_level <= 1))
		return kg_fail(err, KG_EINVAL,
		               "%s: background level %g: expected 0 to 1 of full scale (0: none)", what,
		               o->background_level);
	if (o->distance != KG_EST_DIST_PLAIN && o->distance != KG_EST_DIST_SCALE_FREE)
		return kg_fail(err, KG_EINVAL, "%s: distance %d: expected plain or scale-free", what,
		               (int)o->distance);
	const kg_row_source *side[2] = {o->variance, o->mask};
	const int side_channels[2] = {3, 1};
	for (int s = 0; s < 2; s++) {
		const kg_row_source *v = side[s];
		if (!v)
			continue;
		const char *name = s ? side_name_mask(info) : side_name_variance(info);
		if (!v->read || v->width != img->width || v->height != img->height)
			return kg_fail(err, KG_EINVAL,
			               "%s: %s is %d x %d pixels: expected the image's size, %d x %d",
			               what, name, v->width, v->height, img->width, img->height);
		if (v->channels != side_channels[s])
			return kg_fail(err, KG_EINVAL, "%s: %s has %d channel%s: expected %d (%s)", what,
			               name, v->channels, v->channels == 1 ? "" : "s", side_channels[s],
			               s ? "grey: 0 = background, non-zero = object"
			                 : "one variance per channel of the image");
	}
	return 0;
}

/* The refusal stage's constants; dof and threshold also go to the result. */
static int refusal_init(refusal *r, const kg_est_kernel *k, const kg_est_classifier *cls,
                        const kg_est_material_set *set, const kg_apply_options *opt,
                        const kg_classify_options *o, kg_classify_result *res, kg_err *err)
{
	memset(r, 0, sizeof(*r));
	r->k = k;
	r->cls = cls;
	r->inv_frames = 1.0 / o->frames;
	r->noise_rel2 = o->noise_relative * o->noise_relative;
	r->noise_floor2 = o->noise_floor * o->noise_floor;
	r->resid2 = o->residual_relative * o->residual_relative;
	r->background_level = (float)o->background_level;
	r->unknown = (uint8_t)ap_label_unknown(set);
	r->background = (uint8_t)ap_label_background(set);
	res->dof = kg_est_classifier_dof(cls);
	r->threshold = o->unknown_threshold > 0 ? o->unknown_threshold
	                                        : kg_chi2_quantile(0.999, res->dof);
	res->unknown_threshold = r->threshold;
	if (isinf(r->threshold))
		return 0;
	if (k->method != KG_EST_LINEAR)
		return kg_fail(err, KG_EINVAL,
		               "classify: the unknown test propagates the noise through the kernel's "
		               "weight matrix: expected the linear pca kernel, not a %s one (or no "
		               "unknown test)",
		               k->method == KG_EST_LUT ? "lookup-table" : "root-polynomial");
	const double ident[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
	const double *P = opt->pre ? opt->pre : ident;
	for (int a = 0; a < k->k; a++)
		for (int c = 0; c < 3; c++) {
			double g = 0;
			for (int t = 0; t < 3; t++)
				g += (double)k->wts.a[a * 3 + t] * P[3 * t + c];
			r->g[a * 3 + c] = g;
		}
	return 0;
}

int kg_classify_image(const kg_est_kernel *k, const kg_est_material_set *set,
                      kg_est_distance distance, const kg_image *img,
                      const kg_apply_options *opt, const kg_classify_info *info,
                      const char *out_hdr, kg_classify_result *res, kg_err *err)
{
	kg_classify_options o;
	kg_classify_options_init(&o);
	o.distance = distance;
	o.unknown_threshold = INFINITY;
	o.background_level = 0;
	return kg_classify_image_opts(k, set, img, opt, &o, info, out_hdr, res, err);
}

int kg_classify_image_opts(const kg_est_kernel *k, const kg_est_material_set *set,
                           const kg_image *img, const kg_apply_options *opt,
                           const kg_classify_options *copt, const kg_classify_info *info,
                           const char *out_hdr, kg_classify_result *res, kg_err *err)
{
	kg_check_arg(k && set && img && out_hdr, err);
	if (res)
		memset(res, 0, sizeof(*res));
	int rc = check_image(img, "classify", err);
	if (rc)
		return rc;
	kg_row_source src;
	kg_row_source_of_image(img, &src);
	return kg_classify_rows(k, set, &src, opt, copt, info, out_hdr, res, err);
}

int kg_classify_rows(const kg_est_kernel *k, const kg_est_material_set *set,
                     const kg_row_source *src, const kg_apply_options *opt,
                     const kg_classify_options *copt, const kg_classify_info *info,
                     const char *out_hdr, kg_classify_result *res, kg_err *err)
{
	kg_check_arg(k && set && src && out_hdr, err);
	kg_apply_options dflt;
	if (!opt) {
		kg_apply_options_init(&dflt);
		opt = &dflt;
	}
	kg_classify_options cdflt;
	if (!copt) {
		kg_classify_options_init(&cdflt);
		copt = &cdflt;
	}
	const kg_est_distance distance = copt->distance;
	kg_classify_result local = {0};
	if (res)
		memset(res, 0, sizeof(*res));
	if (kg_est_kernel_k(k) == 0)
		return kg_fail(err, KG_EINVAL,
		               "%s: classification works in the K-dimensional subspace of a basis "
		               "(the paper's eq. 11): it needs a method with one (pca)",
		               out_hdr);
	if (set->n < 1 || set->n > KG_EST_MAX_MATERIALS)
		return kg_fail(err, KG_EINVAL, "%s: %d materials: expected 1 to %d", out_hdr, set->n,
		               KG_EST_MAX_MATERIALS);

	feed in;
	int rc = ap_feed_init(&in, src, opt, "classify", err);
	if (!rc)
		rc = ap_check_options(copt, src, info, "classify", err);
	if (rc)
		return rc;
	in.var = copt->variance;
	in.var_name = side_name_variance(info);
	in.mask = copt->mask;
	refusal refuse;
	kg_est_classifier *cls = NULL;
	kg_envi_writer *ws[3] = {NULL, NULL, NULL};
	char *conf_path = NULL, *mask_path = NULL, *json_path = NULL, *png_path = NULL;
	const char *paths[3] = {out_hdr, NULL, NULL};
	cls_sink sink = {0};
	written done = {0};
	const int W = src->width, H = src->height;
	size_t npix = (size_t)W * (size_t)H;

	if ((rc = kg_est_classifier_new(k, set->materials, set->n, distance, &cls, err)) ||
	    (rc = refusal_init(&refuse, k, cls, set, opt, copt, &local, err)))
		goto out;
	if ((rc = kg_apply_side_path(out_hdr, "_confidence.hdr", &conf_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, ".json", &json_path, err)) ||
	    (rc = kg_apply_side_path(out_hdr, ".png", &png_path, err)) ||
	    (rc = kg_inputs_check_output(json_path, err)) ||
	    (rc = kg_inputs_check_output(png_path, err)))
		goto out;
	ap_preview_size(W, H, &sink.pw, &sink.ph);
	sink.preview = malloc((size_t)sink.pw * sink.ph);
	sink.cs = calloc((size_t)set->n, sizeof(*sink.cs));
	if (!sink.preview || !sink.cs) {
		rc = kg_fail(err, KG_ENOMEM, "classify: out of memory");
		goto out;
	}
	char desc[160];
	snprintf(desc, sizeof(desc), "kogei classify: %d materials, %s distance, %g degrees",
	         set->n, distance_name(distance), set->angle_deg);
	if ((rc = ap_open_label_map(out_hdr, W, H, set,
	                            opt->description ? opt->description : desc, &ws[0], err)))
		goto out;
	const char *band[1] = {"margin"};
	if ((rc = ap_open_floats(conf_path, W, H, 1,
	                         "kogei classify confidence: distance to the runner-up minus "
	                         "distance to the chosen material; NaN for flagged, unknown and "
	                         "background pixels, Inf with one material",
	                         band, &ws[1], err)))
		goto out;
	paths[1] = conf_path;
	if ((rc = ap_open_mask(out_hdr, W, H, &mask_path, &ws[2], err)))
		goto out;
	paths[2] = mask_path;

	kg_est_job job;
	kg_est_job_init(&job, k, KG_EST_LABELS);
	ap_feed_job(&in, &job);
	job.classifier = cls;
	job.threads = opt->threads;
	job.block_rows = opt->block_rows;
	job.isa = opt->isa;
	sink.labels = ws[0];
	sink.conf = ws[1];
	sink.mask = ws[2];
	sink.in = &in;
	sink.refuse = &refuse;
	sink.nmaterials = set->n;
	sink.height = H;
	ap_progress_init(&sink.prog, opt, "classify", W, H);
	rc = kg_est_run_stream(&job, NULL, W, H, cls_sink_fn, &sink, &local.stats, err);
	if (rc) {
		kg_err_prefix(err, "%s: ", out_hdr);
		goto out;
	}
	if ((rc = ap_check_estimable(&local.stats, &in, "classify", err)))
		goto out;
	if ((rc = ap_finish_all(ws, paths, 3, &done, err)))
		goto out;
	if ((rc = ap_margin_pass(sink.cs, sink.nmaterials, out_hdr, conf_path, 1, W, H, err)) ||
	    (rc = ap_summarise(k, set, sink.count, sink.cs, npix, &local, err)))
		goto out;
	const char *files[4] = {out_hdr, conf_path, mask_path, png_path};
	if ((rc = write_json(json_path, set, copt, src, opt, info, files, &local, err)))
		goto out;
	ap_written_add(&done, json_path);
	if ((rc = ap_write_preview(png_path, set, sink.preview, sink.pw, sink.ph, &local,
	                           !copt->preview_no_legend, err)))
		goto out;
	ap_written_add(&done, png_path);

out:
	for (int i = 0; i < 3; i++)
		if (ws[i])
			kg_envi_writer_abort(&ws[i]);
	ap_written_clear(&done, rc != 0);
	if (rc == 0 && res)
		*res = local;
	else
		kg_classify_result_free(&local);
	kg_est_classifier_free(&cls);
	cls_sink_free(&sink);
	free(conf_path);
	free(mask_path);
	free(json_path);
	free(png_path);
	return rc;
}
