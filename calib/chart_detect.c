/* Chart detection: AprilTag fiducials (libapriltag) give points whose positions on the
 * chart are known; a homography mm -> px fitted to all of them (chart_homography.c)
 * places every patch; each patch is sampled over an inner region with robust
 * statistics (chart_sample.c). Tagless ColorCheckers go through the patch-grid finder
 * and OpenCV's mcc detector (chart_tagless.c) when mcc is available. This file holds
 * the options, the results and kg_chart_detect, which runs the stages:
 *   chart_image.c      the image as the stages see it (raw frames demosaiced on demand), threads
 *   chart_grey.c       the white level and the 8-bit grey picture of the tag detector
 *   chart_tags.c       AprilTags: detection, choice of one chart's tags, the homography
 *   chart_tagless.c    ColorChecker 24 without tags: a box, its four turns
 *   chart_grid.c       the patch-grid finder's box (on the reduced copy, tried first)
 *   chart_mcc.cpp      OpenCV mcc's box
 *   chart_orient.c     which turn: the patches' colours against the ColorChecker's
 *   chart_refine.c     a tagless box from a reduced copy refined on the patch edges
 *   chart_colours.c    every patch against the layout's colour: covered patches, steps in light
 *   chart_sample.c     each patch's pixels; chart_select.c and chart_count.c their statistics
 *   chart_overlay.c    the overlay PNG
 *
 * Pixel coordinates: (0, 0) is the top-left corner of the top-left pixel, so pixel
 * (i, j) has its centre at (i + 0.5, j + 0.5). libapriltag reports corners with
 * pixel centres at integers; they are shifted by half a pixel on the way in. */
#include <stdarg.h>
#include <time.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

/* ---- options, results -------------------------------------------------------- */

void kg_chart_detect_options_default(kg_chart_detect_options *o)
{
	memset(o, 0, sizeof(*o));
	o->decimate = 0;
	o->threads = 2;
	o->sample_fraction = 0.6;
	o->statistic = KG_CHART_MEDIAN;
	o->trim = 0.1;
	o->family = NULL;
	o->tagless = 0;
	o->min_tags = 0;
	o->min_pixels = 30;
	o->clip_level = 0;
	o->nonuniformity_limit = 0.05;
	o->glare_fraction = 0.01;
	o->light_field = 1;
	o->max_light_variation = 0;
}

const char *kg_chart_statistic_name(kg_chart_statistic s)
{
	return s == KG_CHART_TRIMMED_MEAN ? "trimmed-mean" : "median";
}

int kg_chart_statistic_parse(const char *name, kg_chart_statistic *out, kg_err *err)
{
	if (strcmp(name, "median") == 0)
		*out = KG_CHART_MEDIAN;
	else if (strcmp(name, "trimmed-mean") == 0)
		*out = KG_CHART_TRIMMED_MEAN;
	else
		return kg_fail(err, KG_EINVAL, "statistic '%s': expected median or trimmed-mean",
		               name);
	return 0;
}

void kg_chart_result_free(kg_chart_result **pr)
{
	kg_chart_result *r = *pr;
	if (!r)
		return;
	free(r->tags);
	for (int i = 0; i < r->npatches; i++)
		free(r->patches[i].id);
	free(r->patches);
	for (int i = 0; i < r->nwarnings; i++)
		free(r->warnings[i]);
	free(r->warnings);
	free(r->candidates);
	free(r);
	*pr = NULL;
}

int chart_add_warning(kg_chart_result *r, const char *fmt, ...)
{
	char buf[1024];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(buf, sizeof(buf), fmt, ap);
	va_end(ap);
	char **w = realloc(r->warnings, (size_t)(r->nwarnings + 1) * sizeof(*w));
	if (!w)
		return KG_ENOMEM;
	r->warnings = w;
	if (!(w[r->nwarnings] = strdup(buf)))
		return KG_ENOMEM;
	r->nwarnings++;
	return 0;
}

double chart_now_seconds(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* ---- input images ------------------------------------------------------------ */

/* Every stage states the image sides it supports, and an image outside them is refused
 * before the stage runs: a corrupted width or height field in a TIFF or PNG must end
 * in a message, not in a crash or an assertion inside a library. */
int chart_check_sides(int width, int height, long min_side, long max_side, const char *stage,
                       const char *hint, kg_err *err)
{
	if (width >= min_side && height >= min_side && width <= max_side && height <= max_side)
		return 0;
	if (max_side >= INT_MAX)
		return kg_fail(err, KG_EINVAL, "image %d x %d px: %s needs at least %ld px per side%s",
		               width, height, stage, min_side, hint ? hint : "");
	return kg_fail(err, KG_EINVAL, "image %d x %d px: %s needs %ld to %ld px per side%s",
	               width, height, stage, min_side, max_side, hint ? hint : "");
}

/* ---- the detector ------------------------------------------------------------ */

static int patch_summary_warnings(kg_chart_result *r)
{
	int nflag = 0, nrej = 0;
	for (int i = 0; i < r->npatches; i++) {
		nflag += r->patches[i].flags != 0;
		nrej += (r->patches[i].flags & KG_CHART_FLAG_REJECTED) != 0;
	}
	if (!nflag)
		return 0;
	char buf[900] = "";
	size_t at = 0;
	for (int i = 0; i < r->npatches && at < sizeof(buf) - 1; i++)
		if (r->patches[i].flags)
			at += (size_t)snprintf(buf + at, sizeof(buf) - at, "%s%s: %s", at ? "; " : "",
			                       r->patches[i].id, r->patches[i].warning);
	return chart_add_warning(r, "%d patch%s flagged%s: %s", nflag, nflag == 1 ? "" : "es",
	                   nrej ? " (rejected ones are left out of the patch file)" : "", buf);
}


/* The layout as flat arrays. */
typedef struct layout_arrays {
	int *tag_ids;
	double (*tag_corners)[4][2];
	char **patch_ids;
	double (*patch_center)[2];
	double (*patch_size)[2];
} layout_arrays;

static void layout_arrays_free(layout_arrays *a)
{
	free(a->tag_ids);
	free(a->tag_corners);
	free(a->patch_ids);
	free(a->patch_center);
	free(a->patch_size);
}

static int make_view(const kg_chart_layout *l, layout_view *v, layout_arrays *a, kg_err *err)
{
	memset(v, 0, sizeof(*v));
	memset(a, 0, sizeof(*a));
	size_t nt = l->ntags > 0 ? (size_t)l->ntags : 1, np = l->npatches > 0 ? (size_t)l->npatches : 1;
	a->tag_ids = malloc(nt * sizeof(*a->tag_ids));
	a->tag_corners = malloc(nt * sizeof(*a->tag_corners));
	a->patch_ids = malloc(np * sizeof(*a->patch_ids));
	a->patch_center = malloc(np * sizeof(*a->patch_center));
	a->patch_size = malloc(np * sizeof(*a->patch_size));
	if (!a->tag_ids || !a->tag_corners || !a->patch_ids || !a->patch_center || !a->patch_size) {
		layout_arrays_free(a);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	for (int i = 0; i < l->ntags; i++) {
		a->tag_ids[i] = l->tags[i].id;
		memcpy(a->tag_corners[i], l->tags[i].corners_mm, sizeof(a->tag_corners[i]));
	}
	for (int i = 0; i < l->npatches; i++) {
		a->patch_ids[i] = (char *)l->patches[i].id;
		memcpy(a->patch_center[i], l->patches[i].center_mm, sizeof(a->patch_center[i]));
		memcpy(a->patch_size[i], l->patches[i].size_mm, sizeof(a->patch_size[i]));
	}
	v->name = l->name;
	v->family = l->family[0] ? l->family : NULL;
	v->ntags = l->ntags;
	v->tag_ids = a->tag_ids;
	v->tag_corners = (const double (*)[4][2])a->tag_corners;
	v->npatches = l->npatches;
	v->patch_ids = a->patch_ids;
	v->patch_center = (const double (*)[2])a->patch_center;
	v->patch_size = (const double (*)[2])a->patch_size;
	const double *ca = l->chart_area_mm;
	double o[4][2] = {{ca[0], ca[1]}, {ca[0] + ca[2], ca[1]}, {ca[0] + ca[2], ca[1] + ca[3]},
	                  {ca[0], ca[1] + ca[3]}};
	memcpy(v->outline, o, sizeof(o));
	return 0;
}

/* Saturation found below full scale (chart_image_levels) as the result's first
 * warning: the scan runs beside the detectors, but its note leads. */
static int saturation_warning(kg_chart_result *r, const work_image *wi, kg_err *err)
{
	if (!wi->sat_note[0])
		return 0;
	if (chart_add_warning(r, "saturation found from the data below full scale: %s; samples "
	                         "there count as clipped", wi->sat_note))
		return kg_fail(err, KG_ENOMEM, "out of memory");
	char *w = r->warnings[r->nwarnings - 1];
	memmove(r->warnings + 1, r->warnings, (size_t)(r->nwarnings - 1) * sizeof(*r->warnings));
	r->warnings[0] = w;
	return 0;
}

/* A refusal: each tag seen becomes a candidate with why it did not place the chart
 * (added after the tagless detector's, if any). Out of memory: left as it is. */
static void refused_tags(const layout_view *L, const kg_chart_detect_options *opt,
                         kg_chart_result *r)
{
	if (r->ntags <= 0)
		return;
	kg_chart_candidate *c = realloc(r->candidates,
	                                (size_t)(r->ncandidates + r->ntags) * sizeof(*c));
	if (!c)
		return;
	r->candidates = c;
	for (int i = 0; i < r->ntags; i++) {
		const kg_chart_tag_found *t = &r->tags[i];
		kg_chart_candidate *k = &c[r->ncandidates++];
		memset(k, 0, sizeof(*k));
		memcpy(k->quad, t->corners, sizeof(k->quad));
		const char *family = opt->family ? opt->family : L->family;
		int of_layout = 0;
		for (int j = 0; j < L->ntags; j++)
			of_layout |= L->tag_ids[j] == t->id;
		if (!of_layout)
			snprintf(k->why, sizeof(k->why), "tag %d (%s): not one of layout %s's tags",
			         t->id, family, L->name);
		else if (t->used)
			snprintf(k->why, sizeof(k->why), "tag %d: of the layout, used, but the chart "
			         "needs %d", t->id, opt->min_tags);
		else if (isfinite(t->error) && t->error > 0)
			snprintf(k->why, sizeof(k->why), "tag %d: of the layout, %.1f px off the chart "
			         "the other tags place", t->id, t->error);
		else
			snprintf(k->why, sizeof(k->why), "tag %d: of the layout, too few with it to "
			         "place the chart (%d needed)", t->id, opt->min_tags);
	}
}

int kg_chart_detect(const kg_chart_layout *l, const kg_image *img,
                    const kg_chart_detect_options *options, kg_chart_result **out,
                    kg_err *err)
{
	/* a mapped 16-bit image (kg_image_map) is read through its codes */
	kg_check_arg(l && img && (img->data || (img->u16 && !img->cfa)) && out, err);
	*out = NULL;
	double t0 = chart_now_seconds();
	kg_chart_detect_options opt;
	if (options)
		opt = *options;
	else
		kg_chart_detect_options_default(&opt);
	if (!(opt.sample_fraction > 0))
		opt.sample_fraction = l->sample_fraction > 0 ? l->sample_fraction : 0.6;
	if (opt.sample_fraction > 1 || opt.trim < 0 || opt.trim >= 0.5 || opt.decimate < 0 ||
	    opt.min_tags < 0)
		return kg_fail(err, KG_EINVAL, "chart detection: sample fraction %g (expected "
		               "0..1), trim %g (0..0.5), decimate %d (>= 0) or min tags %d (>= 0) "
		               "out of range", opt.sample_fraction, opt.trim, opt.decimate,
		               opt.min_tags);
	const kg_chart_detect_options asked = opt; /* before the defaults below fill it in */
	/* min_tags 0: the default of 2 tags, with the ColorChecker fallback. */
	int fallback = opt.min_tags == 0;
	if (fallback)
		opt.min_tags = 2;
	if (l->npatches < 1)
		return kg_fail(err, KG_EINVAL, "layout %s has no patches", l->name);
	/* the sampler's pixel indexing, for images that did not come from core's readers */
	int ret = chart_check_sides(img->width, img->height, 1, INT_MAX, "chart detection",
	                      NULL, err);
	if (ret)
		return ret;
	layout_view L;
	layout_arrays arrays;
	ret = make_view(l, &L, &arrays, err);
	if (ret)
		return ret;
	work_image wi;
	kg_chart_result *r = calloc(1, sizeof(*r));
	if (!r) {
		layout_arrays_free(&arrays);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	snprintf(r->layout, sizeof(r->layout), "%s", l->name);
	/* OpenCV's colour tables, which mcc builds on its first call in a process, built on
	 * another thread while the image is prepared and the tags looked for (joined at
	 * the end, on every path from here), when mcc is what the tagless detector would
	 * try first */
	chart_tagless_warm_up(l, &asked, img->width, img->height);
	double tp = chart_now_seconds();
	ret = chart_prepare_image(img, &opt, &wi, err);
	r->prepare_seconds = chart_now_seconds() - tp;
	if (ret)
		goto fail;
	int tagless = opt.tagless || l->ntags == 0;
	if (!tagless) {
		kg_err tag_err = {{0}};
		ret = chart_detect_with_tags(&L, &wi, &opt, r, &tag_err);
		if (ret && fallback && chart_tagless_fallback(l, r, ret)) {
			kg_err mcc_err = {{0}};
			ret = chart_detect_tagless(l, &L, &wi, &opt, r, &mcc_err);
			if (ret)
				kg_fail(err, ret, "%s; %s", tag_err.msg, mcc_err.msg);
			else if (chart_add_warning(r, "%s: fell back to the tagless detector", tag_err.msg))
				ret = kg_fail(err, KG_ENOMEM, "out of memory");
		} else if (ret) {
			kg_fail(err, ret, "%s", tag_err.msg);
		} else {
			double ts = chart_now_seconds();
			ret = chart_image_levels(&wi, err);
			if (!ret)
				ret = chart_sample_all(&L, &wi, &opt, r, err);
			r->sample_seconds = chart_now_seconds() - ts;
		}
		if (ret)
			goto fail;
	} else if ((ret = chart_detect_tagless(l, &L, &wi, &opt, r, err))) {
		goto fail;
	}
	if ((ret = chart_image_levels(&wi, err)) || (ret = saturation_warning(r, &wi, err)))
		goto fail;
	memcpy(r->clip, wi.clip_ch, sizeof(r->clip));
	if (opt.light_field && (ret = calib_light_field_apply(r, &opt, err)))
		goto fail;
	if ((ret = chart_check_colours(l, r, err)))
		goto fail;
	if ((ret = patch_summary_warnings(r))) {
		ret = kg_fail(err, ret, "out of memory");
		goto fail;
	}
	kg_chart_warm_wait(); /* no thread may be left inside OpenCV when detection returns */
	r->total_seconds = chart_now_seconds() - t0;
	chart_image_free(&wi);
	layout_arrays_free(&arrays);
	*out = r;
	return 0;
fail:
	kg_chart_warm_wait();
	if (ret == KG_ENOENT && opt.keep_refused) {
		kg_err sat_err = {{0}};
		if (!chart_image_levels(&wi, &sat_err))
			saturation_warning(r, &wi, &sat_err);
	}
	chart_image_free(&wi);
	if (ret == KG_ENOENT && opt.keep_refused)
		refused_tags(&L, &opt, r);
	layout_arrays_free(&arrays);
	if (ret == KG_ENOENT && opt.keep_refused) {
		/* what was searched and seen stays, for the overlay */
		r->refused = 1;
		snprintf(r->refusal, sizeof(r->refusal), "%s", err ? err->msg : "chart not found");
		if (!r->has_searched) {
			r->searched[0][0] = r->searched[3][0] = 0;
			r->searched[1][0] = r->searched[2][0] = img->width;
			r->searched[0][1] = r->searched[1][1] = 0;
			r->searched[2][1] = r->searched[3][1] = img->height;
			r->has_searched = 1;
		}
		r->total_seconds = chart_now_seconds() - t0;
		*out = r;
		return ret;
	}
	kg_chart_result_free(&r);
	return ret;
}

int calib_chart_sample(const kg_chart_layout *l, const kg_image *img, const double H[9],
                       const kg_chart_detect_options *options, int reference,
                       kg_chart_result **out, kg_err *err)
{
	kg_check_arg(l && img && img->data && H && options && out, err);
	*out = NULL;
	kg_chart_detect_options opt = *options;
	if (!(opt.sample_fraction > 0))
		opt.sample_fraction = l->sample_fraction > 0 ? l->sample_fraction : 0.6;
	layout_view L;
	layout_arrays arrays;
	int ret = make_view(l, &L, &arrays, err);
	if (ret)
		return ret;
	work_image wi;
	kg_chart_result *r = calloc(1, sizeof(*r));
	if (!r)
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	if (!ret)
		ret = chart_prepare_image(img, &opt, &wi, err);
	if (!ret) {
		snprintf(r->layout, sizeof(r->layout), "%s", l->name);
		memcpy(r->H, H, sizeof(r->H));
		ret = chart_image_levels(&wi, err);
		if (!ret)
			memcpy(r->clip, wi.clip_ch, sizeof(r->clip));
		if (!ret)
			ret = chart_sample_all_with(&L, &wi, &opt, !reference, 1, r, err);
		chart_image_free(&wi);
	}
	layout_arrays_free(&arrays);
	if (ret)
		kg_chart_result_free(&r);
	*out = r;
	return ret;
}

int kg_chart_result_patchset(const kg_chart_result *r, kg_patchset **out, kg_err *err)
{
	kg_check_arg(r && out, err);
	static const char *const extra[] = {"RGB_R_SD", "RGB_G_SD", "RGB_B_SD", "CLIPPED_FRACTION",
	                                    "NONUNIFORMITY", "PIXELS", "FLAGS"};
	int n = 0;
	for (int i = 0; i < r->npatches; i++)
		n += !(r->patches[i].flags & KG_CHART_FLAG_REJECTED);
	if (n == 0)
		return kg_fail(err, KG_ENOENT, "chart %s: no patch could be sampled", r->layout);
	kg_patchset *ps = NULL;
	int ret = kg_patchset_new(n, KG_PATCH_RGB, &ps, err);
	for (int k = 0; k < 7 && !ret; k++)
		ret = kg_patchset_add_extra(ps, extra[k], err);
	int j = 0;
	for (int i = 0; i < r->npatches && !ret; i++) {
		const kg_chart_sample *p = &r->patches[i];
		if (p->flags & KG_CHART_FLAG_REJECTED)
			continue;
		if ((ret = kg_patchset_set_id(ps, j, p->id, err)))
			break;
		double *e = ps->extra + (size_t)j * ps->nextra;
		for (int c = 0; c < 3; c++) {
			ps->rgb[j][c] = p->rgb[c];
			e[c] = p->sd[c];
		}
		e[3] = p->clipped_fraction;
		e[4] = p->nonuniformity;
		e[5] = (double)p->pixels;
		e[6] = p->flags;
		j++;
	}
	if (ret) {
		kg_patchset_free(&ps);
		return ret;
	}
	*out = ps;
	return 0;
}
