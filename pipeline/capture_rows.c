/* A capture's image as the job reads it, a band of rows at a time: the recorded mean
 * (or acquire's own RGB), the session's dark subtracted and its flat divided where
 * acquire did not, demosaiced where it is a mosaic, normalised to the chart's exposure;
 * its variance alongside. Nothing is held whole, so memory does not grow with the
 * image (proc_capture_image reads every row into memory for the chart, which needs the
 * whole frame).
 *
 * A plane (the image, or its variance) is planned once: its files, the flat's colour
 * means (two passes over the flat) and, for a mosaic, the corrected mosaic's range
 * (one pass), which the demosaicing scales over as it would over the whole mosaic.
 * Each read of it is a pass: files opened at the top, read to the bottom once. The
 * demosaicing works on bands of the corrected mosaic cut DEMOSAIC_MARGIN rows inside,
 * which give the same values as the whole mosaic (kg_demosaic_range). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline_private.h"

#define DEMOSAIC_MARGIN 4 /* rows, even: beyond the bilinear 3 x 3 window */

typedef struct plane {
	char *path;                 /* the mean, acquire's RGB, or the variance */
	char *dark;                 /* subtracted from it, or NULL */
	char *flat, *flat_dark;     /* the flat and the flat's dark, or NULL */
	int width, height, channels; /* of the file */
	char cfa[17];
	int cfa_rows, cfa_cols;
	double norm[4], cut[4];     /* the flat's colour means and validity cuts */
	kg_flat_smooth *sm;         /* the flat low-passed (plan_flat), divided by */
	int sm_owned;               /* 1: sm is this plane's (the variance borrows it) */
	int variance;               /* the flat divides by its square */
	int demosaic;               /* a mosaic made RGB */
	double lo, hi;              /* the corrected mosaic's range */
	double scale, frames;       /* exposure normalisation; the variance's frames */
	double flare[3];            /* subtracted from the RGB after scaling: the site
	                             * chart's flare, for objects (0: none) */
	long invalid;               /* samples where the flat is not valid */
} plane;

struct proc_source {
	proc *p;
	const proc_capture *c;
	plane img, var;
	int has_var;
};

/* One top-to-bottom read of a plane. */
typedef struct pass {
	const plane *pl;
	kg_image_rows *main, *dark, *flat, *flat_dark;
	float *side;   /* a band of the dark, flat or flat's dark */
	size_t side_cap;
	int next;      /* the next file row */
	float *win;    /* the corrected mosaic's rows [wy0, wy1) */
	int wy0, wy1, wcap;
	int raw;       /* corrections only: no demosaicing, no scaling */
	long invalid;  /* samples where the flat is not valid, so far */
} pass;

struct proc_pass {
	pass ps;
};

static void plane_clear(plane *pl)
{
	free(pl->path);
	free(pl->dark);
	free(pl->flat);
	free(pl->flat_dark);
	if (pl->sm_owned && pl->sm) {
		kg_flat_smooth_free(pl->sm);
		free(pl->sm);
	}
	memset(pl, 0, sizeof(*pl));
}

/* The colour class of sample i of a band starting at row y0 (kg_colour_class). */
static int colour_class(const plane *pl, int y0, size_t i)
{
	size_t C = (size_t)pl->channels, p = i / C;
	return kg_colour_class(pl->channels, pl->cfa[0] ? pl->cfa : NULL, pl->cfa_rows,
	                       pl->cfa_cols, (int)(i % C), p % (size_t)pl->width,
	                       (size_t)y0 + p / (size_t)pl->width);
}

static int open_rows(const char *path, const plane *like, const char *what,
                     kg_image_rows **out, kg_err *err)
{
	int ret = kg_image_rows_open(path, out, err);
	if (ret || !like)
		return ret;
	const kg_image *h = kg_image_rows_header(*out);
	if (h->width != like->width || h->height != like->height || h->channels != like->channels)
		ret = kg_fail(err, KG_EINVAL,
		              "%s is %dx%d with %d channel(s); the image is %dx%d with %d: expected "
		              "the same size",
		              what, h->width, h->height, h->channels, like->width, like->height,
		              like->channels);
	else if (h->cfa && like->cfa[0] && strcmp(h->cfa, like->cfa))
		ret = kg_fail(err, KG_EINVAL, "%s has the CFA pattern %s; the image has %s", what,
		              h->cfa, like->cfa);
	if (ret)
		kg_image_rows_free(out);
	return ret;
}

static float *side_band(pass *ps, size_t n, kg_err *err)
{
	if (n > ps->side_cap) {
		float *v = realloc(ps->side, n * sizeof(float));
		if (!v) {
			kg_fail(err, KG_ENOMEM, "out of memory for a band of %zu samples", n);
			return NULL;
		}
		ps->side = v;
		ps->side_cap = n;
	}
	return ps->side;
}

/* The next rows of file into x (n samples), the same rows of dark (when not NULL)
 * subtracted; dark's band is read into the side buffer's first n samples. */
static int rows_minus_dark(pass *ps, kg_image_rows *file, kg_image_rows *dark, int rows,
                           size_t n, float *x, kg_err *err)
{
	int ret = kg_image_rows_read(file, rows, x, err);
	if (!ret && dark) {
		float *d = side_band(ps, n, err);
		ret = d ? kg_image_rows_read(dark, rows, d, err) : KG_ENOMEM;
		for (size_t i = 0; !ret && i < n; i++)
			x[i] -= d[i];
	}
	return ret;
}

/* The next rows of the plane's file with the dark and the flat applied, into out. */
static int corrected_rows(pass *ps, int rows, float *out, kg_err *err)
{
	const plane *pl = ps->pl;
	size_t n = (size_t)rows * pl->width * pl->channels;
	int y0 = ps->next;
	int ret = rows_minus_dark(ps, ps->main, ps->dark, rows, n, out, err);
	if (!ret && pl->flat && pl->sm) {
		/* the smoothed flat (kg_flat_smooth), from plan_flat */
		size_t C = (size_t)pl->channels, W = (size_t)pl->width;
		for (size_t i = 0; i < n; i++) {
			size_t px = i / C;
			int c = colour_class(pl, y0, i);
			double v = kg_flat_smooth_at(pl->sm, (int)(i % C), (int)(px % W),
			                             y0 + (int)(px / W));
			if (!(isfinite(v) && v > pl->cut[c])) {
				out[i] = NAN;
				ps->invalid++;
				continue;
			}
			double g = v / pl->norm[c];
			out[i] = (float)(pl->variance ? out[i] / (g * g) : out[i] / g);
		}
	}
	ps->next += rows;
	return ret;
}

static void pass_close(pass *ps)
{
	kg_image_rows_free(&ps->main);
	kg_image_rows_free(&ps->dark);
	kg_image_rows_free(&ps->flat);
	kg_image_rows_free(&ps->flat_dark);
	free(ps->side);
	free(ps->win);
	memset(ps, 0, sizeof(*ps));
}

static int pass_open(const plane *pl, int raw, int with_main, pass *ps, kg_err *err)
{
	memset(ps, 0, sizeof(*ps));
	ps->pl = pl;
	ps->raw = raw;
	int ret = 0;
	if (with_main)
		ret = open_rows(pl->path, pl, pl->path, &ps->main, err);
	if (!ret && pl->dark && with_main)
		ret = open_rows(pl->dark, pl, "the dark", &ps->dark, err);
	if (!ret && pl->flat && !pl->sm)
		ret = open_rows(pl->flat, pl, "the flat", &ps->flat, err);
	if (!ret && pl->flat_dark && !pl->sm)
		ret = open_rows(pl->flat_dark, pl, "the flat's dark", &ps->flat_dark, err);
	if (ret)
		pass_close(ps);
	return ret;
}

/* The flat's colour means over its positive samples, then over the valid ones (above
 * KG_FLAT_VALID_FRACTION of the first): two passes, summed in file order as
 * kg_correct_flat sums them; the first also low-passes it (kg_flat_smooth), and the
 * corrections divide by that. */
static int plan_flat(plane *pl, kg_err *err)
{
	double sum[4] = {0};
	long count[4] = {0};
	size_t row = (size_t)pl->width * pl->channels;
	int band = (int)((1u << 20) / row) + 1;
	float *f = malloc(sizeof(float) * row * (size_t)band);
	kg_flat_smooth *sm = calloc(1, sizeof(*sm));
	int ret = f && sm ? 0 : kg_fail(err, KG_ENOMEM, "out of memory");
	int sm_ready = 0;
	if (!ret)
		ret = kg_flat_smooth_init(sm, pl->width, pl->height, pl->channels,
		                          pl->cfa[0] ? pl->cfa : NULL, pl->cfa_rows, pl->cfa_cols, err);
	sm_ready = !ret;
	for (int round = 0; round < 2 && !ret; round++) {
		pass ps;
		if ((ret = pass_open(pl, 1, 0, &ps, err)))
			break;
		for (int y = 0; y < pl->height && !ret; y += band) {
			int rows = pl->height - y < band ? pl->height - y : band;
			if ((ret = rows_minus_dark(&ps, ps.flat, ps.flat_dark, rows, (size_t)rows * row, f,
			                           err)))
				break;
			if (round == 0)
				kg_flat_smooth_add(sm, f, y, rows);
			for (size_t i = 0; i < (size_t)rows * row; i++) {
				float v = f[i];
				int c = colour_class(pl, y, i);
				if (round == 0 ? isfinite(v) && v > 0 : isfinite(v) && v > pl->cut[c]) {
					sum[c] += v;
					count[c]++;
				}
			}
		}
		pass_close(&ps);
		for (int c = 0; c < 4 && !ret; c++) {
			if (round == 0)
				pl->cut[c] = count[c] ? KG_FLAT_VALID_FRACTION * sum[c] / (double)count[c]
				                      : INFINITY;
			else
				pl->norm[c] = sum[c] / (double)count[c];
			sum[c] = 0;
			count[c] = 0;
		}
	}
	free(f);
	if (!ret) {
		kg_flat_smooth_finish(sm);
		pl->sm = sm;
		pl->sm_owned = 1;
	} else if (sm) {
		if (sm_ready)
			kg_flat_smooth_free(sm);
		free(sm);
	}
	return ret;
}

/* The corrected plane's range (for the demosaicing) and its invalid flat samples. */
static int plan_range(plane *pl, kg_err *err)
{
	pass ps;
	int ret = pass_open(pl, 1, 1, &ps, err);
	if (ret)
		return ret;
	size_t row = (size_t)pl->width * pl->channels;
	int band = (int)((1u << 20) / row) + 1;
	float *v = malloc(sizeof(float) * row * (size_t)band);
	double lo = INFINITY, hi = -INFINITY;
	ret = v ? 0 : kg_fail(err, KG_ENOMEM, "out of memory");
	for (int y = 0; y < pl->height && !ret; y += band) {
		int rows = pl->height - y < band ? pl->height - y : band;
		if ((ret = corrected_rows(&ps, rows, v, err)))
			break;
		for (size_t i = 0; i < (size_t)rows * row; i++)
			if (isfinite(v[i])) {
				lo = fmin(lo, v[i]);
				hi = fmax(hi, v[i]);
			}
	}
	free(v);
	pl->invalid = ps.invalid;
	pass_close(&ps);
	if (!(lo <= hi))
		lo = hi = 0;
	pl->lo = lo;
	pl->hi = hi;
	return ret;
}

/* Demosaiced rows [y0, y0 + rows) from the window of corrected mosaic rows. */
static int demosaic_rows(pass *ps, int y0, int rows, float *out, kg_err *err)
{
	const plane *pl = ps->pl;
	int W = pl->width;
	int a = y0 - DEMOSAIC_MARGIN < 0 ? 0 : y0 - DEMOSAIC_MARGIN;
	a -= a % pl->cfa_rows; /* the band keeps the mosaic's CFA phase */
	int b = y0 + rows + DEMOSAIC_MARGIN > pl->height ? pl->height : y0 + rows + DEMOSAIC_MARGIN;
	if (a > ps->wy0) { /* drop rows no longer needed */
		int keep = ps->wy1 > a ? ps->wy1 - a : 0;
		if (keep)
			memmove(ps->win, ps->win + (size_t)(a - ps->wy0) * W, sizeof(float) * keep * W);
		ps->wy0 = a;
		ps->wy1 = a + keep;
	}
	if (b - ps->wy0 > ps->wcap) {
		float *w = realloc(ps->win, sizeof(float) * (size_t)W * (b - ps->wy0));
		if (!w)
			return kg_fail(err, KG_ENOMEM, "out of memory for %d rows", b - ps->wy0);
		ps->win = w;
		ps->wcap = b - ps->wy0;
	}
	if (ps->wy1 != ps->next) /* bands come in order, so the window ends at the file's row */
		return kg_fail(err, KG_EINVAL, "%s: rows read out of order", pl->path);
	if (b > ps->wy1) {
		int ret = corrected_rows(ps, b - ps->wy1, ps->win + (size_t)(ps->wy1 - ps->wy0) * W, err);
		if (ret)
			return ret;
		ps->wy1 = b;
	}
	kg_image band = {0};
	band.width = W;
	band.height = b - a;
	band.channels = 1;
	band.data = ps->win + (size_t)(a - ps->wy0) * W;
	band.cfa = (char *)pl->cfa;
	band.cfa_rows = pl->cfa_rows;
	band.cfa_cols = pl->cfa_cols;
	kg_image *rgb = NULL;
	int ret = kg_demosaic_range(&band, pl->lo, pl->hi, &rgb, NULL, err);
	if (!ret)
		memcpy(out, rgb->data + (size_t)(y0 - a) * W * 3, sizeof(float) * 3 * W * rows);
	kg_image_free(&rgb);
	return ret;
}

static int pass_read(void *user, int y0, int rows, float *out, kg_err *err)
{
	pass *ps = user;
	const plane *pl = ps->pl;
	int ret;
	if (pl->demosaic && !ps->raw) {
		ret = demosaic_rows(ps, y0, rows, out, err);
	} else {
		if (y0 != ps->next)
			return kg_fail(err, KG_EINVAL, "%s: row %d asked, the next is %d", pl->path, y0,
			               ps->next);
		ret = corrected_rows(ps, rows, out, err);
	}
	if (ret || ps->raw)
		return ret;
	size_t n = (size_t)rows * pl->width * (pl->demosaic ? 3 : pl->channels);
	if (pl->variance)
		for (size_t i = 0; i < n; i++)
			out[i] = (float)(out[i] * pl->scale * pl->scale / pl->frames);
	else if (pl->scale != 1.0)
		for (size_t i = 0; i < n; i++)
			out[i] = (float)(out[i] * pl->scale);
	if (!pl->variance && (pl->demosaic || pl->channels == 3) &&
	    (pl->flare[0] != 0 || pl->flare[1] != 0 || pl->flare[2] != 0))
		for (size_t i = 0; i < n; i++)
			out[i] = (float)(out[i] - pl->flare[i % 3]);
	return 0;
}

/* ---- planning -------------------------------------------------------------------- */

/* The path of a capture's output (mean, variance, rgb), its sha256 checked and
 * recorded; KG_ENOENT (no message) when the capture has none. */
static int output_path(proc *p, const proc_capture *c, const char *key, char **path)
{
	char where[96];
	snprintf(where, sizeof(where), "outputs.%s.file", key);
	const char *rel = json_string_value(kg_json_find(c->j, where));
	snprintf(where, sizeof(where), "outputs.%s.sha256", key);
	const char *sha = json_string_value(kg_json_find(c->j, where));
	*path = NULL;
	if (!rel)
		return KG_ENOENT;
	*path = kg_path_join(p->o->session, rel);
	char role[128];
	snprintf(role, sizeof(role), "capture %s %s", c->name, key);
	int ret = *path ? proc_input(p, role, *path, sha) : kg_fail(p->err, KG_ENOMEM, "out of memory");
	if (ret) {
		kg_err_prefix(p->err, "capture %s: ", c->name);
		free(*path);
		*path = NULL;
	}
	return ret;
}

/* A capture's mean and the dark to subtract from it where acquire did not and the
 * session holds a matching one (*dark_name: its name, "" when none). */
static int mean_and_dark(proc *p, const proc_capture *c, char **mean, char **dark,
                         char *dark_name, int *by_process)
{
	int ret = output_path(p, c, "mean", mean);
	if (ret)
		return ret == KG_ENOENT ? kg_fail(p->err, KG_EINVAL, "%s: capture %s has no "
		                                  "outputs.mean", p->manifest_path, c->name)
		                        : ret;
	dark_name[0] = '\0';
	*by_process = 0;
	*dark = NULL;
	if (c->dark) {
		snprintf(dark_name, KG_CAPTURE_NAME_MAX, "%s", c->dark);
		return 0;
	}
	const proc_capture *d = c->kind == KG_CAPTURE_DARK ? NULL : proc_matching_dark(p, c);
	if (!d)
		return 0;
	if ((ret = output_path(p, d, "mean", dark)))
		return ret == KG_ENOENT ? kg_fail(p->err, KG_EINVAL, "%s: capture %s has no "
		                                  "outputs.mean", p->manifest_path, d->name)
		                        : ret;
	snprintf(dark_name, KG_CAPTURE_NAME_MAX, "%s", d->name);
	*by_process = 1;
	return 0;
}

static int plane_header(plane *pl, kg_err *err)
{
	kg_image_rows *r = NULL;
	int ret = kg_image_rows_open(pl->path, &r, err);
	if (ret)
		return ret;
	const kg_image *h = kg_image_rows_header(r);
	pl->width = h->width;
	pl->height = h->height;
	pl->channels = h->channels;
	if (h->cfa && strlen(h->cfa) < sizeof(pl->cfa)) {
		snprintf(pl->cfa, sizeof(pl->cfa), "%s", h->cfa);
		pl->cfa_rows = h->cfa_rows;
		pl->cfa_cols = h->cfa_cols;
	}
	kg_image_rows_free(&r);
	return 0;
}

int proc_source_open(proc *p, const proc_capture *c, double scale, int keep_mosaic,
                     proc_source **out, proc_image_info *info)
{
	*out = NULL;
	memset(info, 0, sizeof(*info));
	proc_source *s = calloc(1, sizeof(*s));
	if (!s)
		return kg_fail(p->err, KG_ENOMEM, "out of memory");
	s->p = p;
	s->c = c;
	plane *im = &s->img, *va = &s->var;
	const proc_capture *fc = c->flat ? NULL : proc_matching_flat(p, c);
	int needs_dark = !c->dark && proc_matching_dark(p, c);
	int rgb_ok = json_object_get(json_object_get(c->j, "outputs"), "rgb") && !needs_dark && !fc;
	int ret;
	if (rgb_ok) {
		ret = output_path(p, c, "rgb", &im->path);
		if (c->dark)
			snprintf(info->dark, sizeof(info->dark), "%s", c->dark);
	} else {
		ret = mean_and_dark(p, c, &im->path, &im->dark, info->dark, &info->dark_by_process);
	}
	if (c->flat)
		snprintf(info->flat, sizeof(info->flat), "%s", c->flat);
	if (!ret) {
		int r2 = output_path(p, c, "variance", &va->path);
		s->has_var = r2 == 0;
		if (r2 && r2 != KG_ENOENT)
			ret = r2;
	}
	if (!ret)
		ret = plane_header(im, p->err);
	if (!ret && im->dark) {
		kg_image_rows *r = NULL;
		ret = open_rows(im->dark, im, "the dark", &r, p->err);
		kg_image_rows_free(&r);
		if (ret)
			kg_err_prefix(p->err, "capture %s, dark %s: ", c->name, info->dark);
	}
	if (!ret && fc && !rgb_ok) {
		char fdark[KG_CAPTURE_NAME_MAX];
		int fby;
		ret = mean_and_dark(p, fc, &im->flat, &im->flat_dark, fdark, &fby);
		if (!ret) {
			kg_image_rows *r = NULL;
			ret = open_rows(im->flat, im, "the flat", &r, p->err);
			kg_image_rows_free(&r);
		}
		if (!ret) {
			proc_progress(p, "%s: the flat %s's colour means (two passes)", c->name, fc->name);
			ret = plan_flat(im, p->err);
		}
		if (!ret) { /* a clipped or too uneven flat is refused, naming which */
			const json_t *cf = kg_json_find(fc->j, "statistics.clipped_fraction");
			ret = kg_flat_check(im->sm, json_is_number(cf) ? json_number_value(cf) : NAN,
			                    fc->name, NULL, p->err);
		}
		if (ret) {
			kg_err_prefix(p->err, "capture %s, flat %s: ", c->name, fc->name);
		} else {
			snprintf(info->flat, sizeof(info->flat), "%s", fc->name);
			info->flat_by_process = 1;
			if (!fdark[0])
				proc_warn(p, NULL, "flat %s has no dark subtracted (no matching dark in the "
				          "session)", fc->name);
		}
	}
	if (!ret) {
		im->scale = scale;
		/* the flare measured on the site chart (and removed from it for M2) is taken
		 * out of an object's values too: the same lens and light (docs/process.md) */
		if (c->kind == KG_CAPTURE_OBJECT && p->cam && p->cam->flare_removed)
			for (int ch = 0; ch < 3; ch++)
				im->flare[ch] = p->cam->flare.offset[ch];
		if (im->channels == 1 && im->cfa[0]) {
			im->demosaic = kg_demosaic_algorithm() != NULL;
			if (!im->demosaic && !keep_mosaic)
				ret = kg_fail(p->err, KG_ENOTSUP, "capture %s: demosaic: kogei was built "
				              "without OpenCV; the raw mosaic is kept", c->name);
		} else if (im->channels != 3) {
			ret = kg_fail(p->err, KG_EINVAL, "capture %s: a grey (1-channel) image without a "
			              "CFA pattern cannot give colour: expected RGB or raw Bayer", c->name);
		}
	}
	if (!ret && (im->demosaic || im->flat)) {
		proc_progress(p, "%s: a first pass over the corrected image (%s%s)", c->name,
		              im->flat ? "invalid flat samples" : "",
		              im->demosaic ? (im->flat ? ", the mosaic's range" : "the mosaic's range") : "");
		ret = plan_range(im, p->err);
	}
	if (!ret && im->invalid)
		proc_warn(p, NULL, "capture %s: %ld samples where the flat %s is not valid are left "
		          "out (NaN)", c->name, im->invalid, fc ? fc->name : "");
	/* The variance follows the image into RGB: a mosaic's by the same demosaicing; one
	 * that cannot is left out, and the noise model takes its place. */
	if (!ret && s->has_var) {
		kg_err quiet = {{0}};
		int ok = plane_header(va, &quiet) == 0 && va->width == im->width &&
		         va->height == im->height && va->channels == im->channels;
		if (ok && im->flat) {
			va->flat = strdup(im->flat);
			va->flat_dark = im->flat_dark ? strdup(im->flat_dark) : NULL;
			memcpy(va->norm, im->norm, sizeof(va->norm));
			memcpy(va->cut, im->cut, sizeof(va->cut));
			va->sm = im->sm; /* borrowed */
			ok = va->flat && (!im->flat_dark || va->flat_dark);
		}
		va->variance = 1;
		va->scale = scale;
		va->frames = c->frames > 0 ? (double)c->frames : 1.0;
		if (ok && va->channels == 1 && va->cfa[0]) {
			va->demosaic = im->demosaic;
			ok = va->demosaic && plan_range(va, &quiet) == 0;
		} else if (ok) {
			ok = va->channels == 3;
		}
		s->has_var = ok;
	}
	info->width = im->width;
	info->height = im->height;
	info->channels = im->demosaic ? 3 : im->channels;
	info->has_variance = s->has_var;
	if (ret)
		proc_source_free(&s);
	*out = s;
	return ret;
}

void proc_source_free(proc_source **ps)
{
	if (!ps || !*ps)
		return;
	plane_clear(&(*ps)->img);
	plane_clear(&(*ps)->var);
	free(*ps);
	*ps = NULL;
}

int proc_pass_open(proc_source *s, int variance, proc_pass **out, kg_row_source *src)
{
	*out = NULL;
	const plane *pl = variance ? &s->var : &s->img;
	if (variance && !s->has_var)
		return kg_fail(s->p->err, KG_EINVAL, "capture %s: no variance", s->c->name);
	proc_pass *pp = calloc(1, sizeof(*pp));
	if (!pp)
		return kg_fail(s->p->err, KG_ENOMEM, "out of memory");
	int ret = pass_open(pl, 0, 1, &pp->ps, s->p->err);
	if (ret) {
		free(pp);
		kg_err_prefix(s->p->err, "capture %s: ", s->c->name);
		return ret;
	}
	*src = (kg_row_source){pl->width, pl->height, pl->demosaic ? 3 : pl->channels, pass_read,
	                       &pp->ps};
	*out = pp;
	return 0;
}

void proc_pass_free(proc_pass **pp)
{
	if (!pp || !*pp)
		return;
	pass_close(&(*pp)->ps);
	free(*pp);
	*pp = NULL;
}

/* Rows [y0, y0 + bin) of an RGB source binned bin x bin into one output row of
 * ceil(width / bin) pixels: the mean of each block, except that a channel clipped
 * (>= clip) anywhere in the block keeps the block's largest value, so the binned pixel
 * is still seen as clipped, and a NaN anywhere makes it NaN. */
static void bin_row(const float *rows, int width, int nrows, int bin, float clip, float *out)
{
	int ow = (width + bin - 1) / bin;
	for (int X = 0; X < ow; X++)
		for (int c = 0; c < 3; c++) {
			double sum = 0;
			float top = -INFINITY;
			int n = 0, nan = 0;
			for (int r = 0; r < nrows; r++)
				for (int x = X * bin; x < (X + 1) * bin && x < width; x++) {
					float v = rows[((size_t)r * width + x) * 3 + c];
					nan |= isnan(v);
					sum += v;
					top = fmaxf(top, v);
					n++;
				}
			out[(size_t)X * 3 + c] = nan ? NAN : top >= clip ? top : (float)(sum / n);
		}
}

/* The whole capture in memory; bin > 1 bins an RGB image (bin_row). */
static int read_capture(proc *p, const proc_capture *c, double scale, int bin, float clip,
                        proc_image *out)
{
	memset(out, 0, sizeof(*out));
	proc_source *s = NULL;
	proc_image_info info;
	int ret = proc_source_open(p, c, scale, c->kind == KG_CAPTURE_CHART, &s, &info);
	if (!ret && info.channels != 3)
		bin = 1;
	for (int v = 0; v < 1 + (bin == 1 && info.has_variance) && !ret; v++) {
		proc_pass *pp = NULL;
		kg_row_source src;
		kg_image **dst = v ? &out->variance : &out->rgb;
		float *rows = NULL;
		ret = proc_pass_open(s, v, &pp, &src);
		int ow = (src.width + bin - 1) / bin, oh = (src.height + bin - 1) / bin;
		if (!ret)
			ret = kg_image_new(ow, oh, src.channels, dst, p->err);
		if (!ret && src.channels == 1 && s->img.cfa[0])
			ret = kg_image_set_cfa(*dst, s->img.cfa, s->img.cfa_rows, s->img.cfa_cols, p->err);
		if (!ret && bin == 1)
			ret = src.read(src.user, 0, src.height, (*dst)->data, p->err);
		if (!ret && bin > 1 && !(rows = malloc(sizeof(float) * 3 * (size_t)src.width * bin)))
			ret = kg_fail(p->err, KG_ENOMEM, "out of memory");
		for (int Y = 0; !ret && bin > 1 && Y < oh; Y++) {
			int n = src.height - Y * bin < bin ? src.height - Y * bin : bin;
			if (!(ret = src.read(src.user, Y * bin, n, rows, p->err)))
				bin_row(rows, src.width, n, bin, clip, (*dst)->data + (size_t)Y * ow * 3);
		}
		free(rows);
		if (ret)
			kg_err_prefix(p->err, "capture %s: ", c->name);
		proc_pass_free(&pp);
	}
	memcpy(out->dark, info.dark, sizeof(out->dark));
	memcpy(out->flat, info.flat, sizeof(out->flat));
	out->dark_by_process = info.dark_by_process;
	out->flat_by_process = info.flat_by_process;
	proc_source_free(&s);
	if (ret)
		proc_image_clear(out);
	return ret;
}

int proc_capture_image(proc *p, const proc_capture *c, double scale, proc_image *out)
{
	return read_capture(p, c, scale, 1, INFINITY, out);
}

int proc_chart_image(proc *p, const proc_capture *c, long max_pixels, float clip,
                     proc_image *out, int *bin)
{
	long px = c->width * c->height;
	*bin = 1;
	while (px > 0 && (px + (long)*bin * *bin - 1) / ((long)*bin * *bin) > max_pixels)
		(*bin)++;
	int ret = read_capture(p, c, 1.0, *bin, clip, out);
	if (!ret && out->rgb->channels != 3)
		*bin = 1; /* a mosaic kept whole (no demosaicing in this build) */
	return ret;
}
