/* AprilTag fiducials (libapriltag): the tags found, the one chart's tags chosen by a
 * consensus over pairs of tags against outliers and other charts, and the homography
 * fitted to their corners. */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

#if HAVE_APRILTAG
#include <apriltag/apriltag.h>
#include <apriltag/tag16h5.h>
#include <apriltag/tag25h9.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagCircle21h7.h>
#include <apriltag/tagStandard41h12.h>
#endif

#if HAVE_APRILTAG

/* Append "a, b, c" (ints) to buf. */
static void list_ints(char *buf, size_t len, const int *v, int n)
{
	size_t at = strlen(buf);
	for (int i = 0; i < n && at < len; i++)
		at += (size_t)snprintf(buf + at, len - at, "%s%d", i ? ", " : "", v[i]);
}

static int layout_tag_index(const layout_view *L, int id)
{
	for (int i = 0; i < L->ntags; i++)
		if (L->tag_ids[i] == id)
			return i;
	return -1;
}

static apriltag_family_t *family_create(const char *name)
{
	if (!strcmp(name, "tag36h11"))
		return tag36h11_create();
	if (!strcmp(name, "tagStandard41h12"))
		return tagStandard41h12_create();
	if (!strcmp(name, "tag25h9"))
		return tag25h9_create();
	if (!strcmp(name, "tag16h5"))
		return tag16h5_create();
	if (!strcmp(name, "tagCircle21h7"))
		return tagCircle21h7_create();
	return NULL;
}

static void family_destroy(apriltag_family_t *f)
{
	const char *name = f->name;
	if (!strcmp(name, "tag36h11"))
		tag36h11_destroy(f);
	else if (!strcmp(name, "tagStandard41h12"))
		tagStandard41h12_destroy(f);
	else if (!strcmp(name, "tag25h9"))
		tag25h9_destroy(f);
	else if (!strcmp(name, "tag16h5"))
		tag16h5_destroy(f);
	else
		tagCircle21h7_destroy(f);
}

/* Tags on grey (width x height), each of its pixels `zoom` image pixels a side. */
static int run_apriltag(const unsigned char *grey, int width, int height, int zoom,
                        const char *family, int decimate, int threads, kg_chart_result *r,
                        kg_err *err)
{
	apriltag_family_t *tf = family_create(family);
	if (!tf)
		return kg_fail(err, KG_EINVAL,
		               "tag family '%s': expected tag36h11, tagStandard41h12, tag25h9, "
		               "tag16h5 or tagCircle21h7", family);
	apriltag_detector_t *td = apriltag_detector_create();
	if (!td) {
		family_destroy(tf);
		return kg_fail(err, KG_ENOMEM, "apriltag: out of memory");
	}
	apriltag_detector_add_family_bits(td, tf, 1);
	td->quad_decimate = (float)decimate;
	td->quad_sigma = 0;
	/* libapriltag's workers before 3.4.3 can run a task from a freed array when they
	 * start late (see meson.build): there it runs on the calling thread alone, which
	 * cost 0.4 ms at decimate 4 on 12 Mpix and 38-46 % more tag time at decimate 1-2
	 * (docs/chart-detect.md). */
	td->nthreads = KG_APRILTAG_THREADS_OK ? threads : 1;
	td->refine_edges = 1;
	/* A tile whose darkest and brightest pixels differ by less than this is left
	 * unsegmented. libapriltag's default, 5 codes, lets the sensor noise of a dark
	 * background (the grey picture is sRGB-encoded, which lifts the shadows) make
	 * thousands of specks to cluster and fit: 58 ms of a 12 Mpix chart check on black
	 * paper, 18 ms at 10. A printed tag's black and white lie 40 or more codes apart
	 * even at 2 % exposure or with 0.6 grey ink (the grey is scaled to the image's
	 * white): its corners and the patch values are the same (docs/chart-detect.md). */
	td->qtp.min_white_black_diff = 10;
	td->decode_sharpening = 0.25;
	image_u8_t im = {.width = width, .height = height, .stride = width,
	                 .buf = (uint8_t *)grey};
	zarray_t *dets = apriltag_detector_detect(td, &im);
	int ret = 0;
	int n = dets ? zarray_size(dets) : 0;
	if (n > 0) {
		r->tags = calloc((size_t)n, sizeof(*r->tags));
		if (!r->tags)
			ret = kg_fail(err, KG_ENOMEM, "apriltag: out of memory");
	}
	for (int i = 0; i < n && !ret; i++) {
		apriltag_detection_t *d;
		zarray_get(dets, i, &d);
		kg_chart_tag_found *t = &r->tags[r->ntags++];
		t->id = d->id;
		t->hamming = d->hamming;
		t->margin = d->decision_margin;
		for (int k = 0; k < 4; k++) {
			t->corners[k][0] = (d->p[k][0] + 0.5) * zoom;
			t->corners[k][1] = (d->p[k][1] + 0.5) * zoom;
		}
	}
	if (dets)
		apriltag_detections_destroy(dets);
	apriltag_detector_destroy(td);
	family_destroy(tf);
	return ret;
}

/* Largest corner distance of tag t under H (mm -> px), in pixels. */
static double tag_error(const double H[9], const kg_chart_tag_found *t, const double (*mm)[2])
{
	double e = 0;
	for (int k = 0; k < 4; k++) {
		double q[2];
		kg_homography_map(H, mm[k][0], mm[k][1], q);
		e = fmax(e, hypot(q[0] - t->corners[k][0], q[1] - t->corners[k][1]));
	}
	return e;
}

static double tag_side_px(const kg_chart_tag_found *t)
{
	double s = 0;
	for (int k = 0; k < 4; k++)
		s += hypot(t->corners[k][0] - t->corners[(k + 1) % 4][0],
		           t->corners[k][1] - t->corners[(k + 1) % 4][1]);
	return s / 4;
}

/* Fit H to the corners of the tags marked used. */
static int fit_used(const layout_view *L, const kg_chart_result *r, int refine, double H[9],
                    double *rms, kg_err *err)
{
	int n = 0;
	for (int i = 0; i < r->ntags; i++)
		n += r->tags[i].used ? 4 : 0;
	double (*src)[2] = malloc((size_t)(n ? n : 1) * sizeof(*src));
	double (*dst)[2] = malloc((size_t)(n ? n : 1) * sizeof(*dst));
	if (!src || !dst) {
		free(src);
		free(dst);
		return kg_fail(err, KG_ENOMEM, "homography: out of memory");
	}
	int at = 0;
	for (int i = 0; i < r->ntags; i++) {
		if (!r->tags[i].used)
			continue;
		int li = layout_tag_index(L, r->tags[i].id);
		for (int k = 0; k < 4; k++, at++) {
			src[at][0] = L->tag_corners[li][k][0];
			src[at][1] = L->tag_corners[li][k][1];
			dst[at][0] = r->tags[i].corners[k][0];
			dst[at][1] = r->tags[i].corners[k][1];
		}
	}
	int ret = kg_homography_fit((const double (*)[2])src, (const double (*)[2])dst, n, refine,
	                            H, rms, err);
	free(src);
	free(dst);
	return ret;
}

/* Mark the tags consistent with H (the closest of duplicates of an id) as used;
 * returns their number and the sum of their errors. */
static int classify_tags(const layout_view *L, kg_chart_result *r, const double H[9],
                         double tol_px, double tol_rel, double *sum_err)
{
	int count = 0;
	double sum = 0;
	for (int i = 0; i < r->ntags; i++)
		r->tags[i].used = 0;
	for (int i = 0; i < r->ntags; i++) {
		kg_chart_tag_found *t = &r->tags[i];
		int li = layout_tag_index(L, t->id);
		if (li < 0)
			continue;
		double e = tag_error(H, t, L->tag_corners[li]);
		t->error = e;
		if (!(e <= fmax(tol_px, tol_rel * tag_side_px(t))))
			continue;
		int dup = -1;
		for (int j = 0; j < i; j++)
			if (r->tags[j].used && r->tags[j].id == t->id)
				dup = j;
		if (dup >= 0) {
			if (r->tags[dup].error <= e)
				continue;
			r->tags[dup].used = 0;
			sum -= r->tags[dup].error;
			count--;
		}
		t->used = 1;
		sum += e;
		count++;
	}
	*sum_err = sum;
	return count;
}

/* Choose the tags of one chart: every pair of tags with layout ids proposes a
 * homography; the one most tags agree with wins (ties: the smaller error). Then the
 * fit over all agreeing tags is refined and the agreement re-checked. */
static int select_tags(const layout_view *L, kg_chart_result *r, const kg_chart_detect_options *opt,
                       kg_err *err)
{
	int *cand = malloc((size_t)(r->ntags ? r->ntags : 1) * sizeof(int));
	if (!cand)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	int nc = 0;
	for (int i = 0; i < r->ntags; i++)
		if (layout_tag_index(L, r->tags[i].id) >= 0)
			cand[nc++] = i;
	int ret = 0;
	int best = -1;
	double best_err = INFINITY, bestH[9];
	kg_err tmp;
	if (nc == 1) {
		r->tags[cand[0]].used = 1;
		if ((ret = fit_used(L, r, 0, bestH, NULL, err)))
			goto done;
		best = 1;
	}
	for (int a = 0; a < nc; a++) {
		for (int b = a + 1; b < nc; b++) {
			kg_chart_tag_found *ta = &r->tags[cand[a]], *tb = &r->tags[cand[b]];
			if (ta->id == tb->id)
				continue;
			for (int i = 0; i < r->ntags; i++)
				r->tags[i].used = i == cand[a] || i == cand[b];
			double H[9], s;
			if (fit_used(L, r, 0, H, NULL, &tmp))
				continue;
			int count = classify_tags(L, r, H, 3.0, 0.1, &s);
			if (count > best || (count == best && s < best_err)) {
				best = count;
				best_err = s;
				memcpy(bestH, H, sizeof(bestH));
			}
		}
	}
	if (best < 0) {
		ret = kg_fail(err, KG_ENOENT, "no consistent set of tags");
		goto done;
	}
	double s;
	classify_tags(L, r, bestH, 3.0, 0.1, &s);
	for (int pass = 0; pass < 2; pass++) {
		if ((ret = fit_used(L, r, 1, r->H, &r->rms_px, err)))
			goto done;
		int n_used = 0;
		for (int i = 0; i < r->ntags; i++)
			n_used += r->tags[i].used;
		if (n_used < 2)
			break;
		classify_tags(L, r, r->H, fmax(1.5, 5 * r->rms_px), 0.1, &s);
	}
	ret = fit_used(L, r, 1, r->H, &r->rms_px, err);
	(void)opt;
done:
	free(cand);
	return ret;
}
#endif

int chart_detect_with_tags(const layout_view *L, work_image *wi,
                            const kg_chart_detect_options *opt, kg_chart_result *r,
                            kg_err *err)
{
#if HAVE_APRILTAG
	double t0 = chart_now_seconds(), scale;
	long npix = (long)wi->width * wi->height;
	int big = wi->width > wi->height ? wi->width : wi->height;
	int decimate = opt->decimate > 0 ? opt->decimate : npix < 4000000 ? 2 : 4;
	while (opt->decimate == 0 && big > APRILTAG_MAX_SIDE * (long)decimate)
		decimate *= 2; /* automatic decimation keeps within libapriltag's coordinates */
	/* Decimated by an even factor d, libapriltag finds its quads on every d-th pixel of
	 * every d-th row, which a half-resolution picture holds as its every (d/2)-th: a
	 * Bayer frame's 2 x 2 blocks (d >= 2), or every 2nd pixel of every 2nd row of
	 * other images (d >= 4, where the edge refinement still has 2 or more pixels per
	 * decimated one): half the rows read, no demosaicing. The edges are refined on
	 * that picture. */
	float bw4[4];
	int blocks = !chart_block_weights(wi, bw4), gw, gh;
	int zoom = decimate % 2 == 0 && (blocks || decimate >= 4) &&
	           wi->width / 2 >= decimate + 1 && wi->height / 2 >= decimate + 1 ? 2 : 1;
	unsigned char *g = zoom == 2 && blocks ? chart_grey8_binned(wi, bw4, &gw, &gh)
	                                       : chart_grey8(wi, zoom, &gw, &gh, &scale);
	if (!g)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	double t1 = chart_now_seconds();
	r->prepare_seconds += t1 - t0;
	const char *family = opt->family ? opt->family : L->family ? L->family : "tag36h11";
	r->decimate = decimate;
	/* libapriltag decimates a side s to 1 + (s - 1) / d pixels; below 3 it reads out of
	 * bounds, and its segmentation keeps doubled coordinates in 16 bits (it asserts a
	 * side < 32768). */
	char stage[96];
	snprintf(stage, sizeof(stage), "the tag detector (libapriltag, decimate %d)", decimate);
	int ret = chart_check_sides(wi->width, wi->height, 2L * decimate + 1,
	                      APRILTAG_MAX_SIDE * (long)decimate, stage,
	                      opt->decimate && big > APRILTAG_MAX_SIDE * (long)decimate
	                          ? "; a larger --decimate takes larger images" : NULL,
	                      err);
	if (!ret)
		ret = run_apriltag(g, gw, gh, zoom, family, decimate / zoom,
		                   opt->threads > 0 ? opt->threads : 1, r, err);
	if (!(zoom == 2 && blocks)) {
		/* every zoom-th pixel: kept for the patch-grid finder, should no tag be found */
		free(wi->grey);
		wi->grey = g;
		wi->grey_w = gw;
		wi->grey_h = gh;
		wi->grey_zoom = zoom;
	} else {
		free(g);
	}
	r->tag_seconds = chart_now_seconds() - t1;
	if (ret)
		return ret;
	int nknown = 0, nforeign = 0, foreign[16];
	for (int i = 0; i < r->ntags; i++) {
		if (layout_tag_index(L, r->tags[i].id) >= 0)
			nknown++;
		else if (nforeign < 16)
			foreign[nforeign++] = r->tags[i].id;
	}
	if (nknown == 0) {
		if (r->ntags > 0) {
			char ids[200] = "";
			list_ints(ids, sizeof(ids), foreign, nforeign);
			return kg_fail(err, KG_ENOENT,
			               "no %s tag of layout %s in the image (found %d other tag%s: %s)",
			               family, L->name, r->ntags, r->ntags == 1 ? "" : "s", ids);
		}
		return kg_fail(err, KG_ENOENT,
		               "no %s tags found in the image: is the chart of layout %s in view, "
		               "lit and in focus?", family, L->name);
	}
	if (nforeign) {
		char ids[200] = "";
		list_ints(ids, sizeof(ids), foreign, nforeign);
		if ((ret = chart_add_warning(r, "ignored %d tag%s not in layout %s: %s", nforeign,
		                       nforeign == 1 ? "" : "s", L->name, ids)))
			return kg_fail(err, ret, "out of memory");
	}
	if ((ret = select_tags(L, r, opt, err)))
		return ret;
	int used = 0, inconsistent = 0, missing = 0;
	int used_ids[64] = {0}, bad_ids[64] = {0}, missing_ids[64] = {0};
	for (int i = 0; i < r->ntags; i++) {
		if (r->tags[i].used && used < 64)
			used_ids[used++] = r->tags[i].id;
		else if (!r->tags[i].used && layout_tag_index(L, r->tags[i].id) >= 0 && inconsistent < 64)
			bad_ids[inconsistent++] = r->tags[i].id;
	}
	for (int j = 0; j < L->ntags; j++) {
		int seen = 0;
		for (int i = 0; i < r->ntags; i++)
			seen |= r->tags[i].used && r->tags[i].id == L->tag_ids[j];
		if (!seen && missing < 64)
			missing_ids[missing++] = L->tag_ids[j];
	}
	r->ntags_used = used;
	if (used < opt->min_tags) {
		char ids[200] = "";
		list_ints(ids, sizeof(ids), used_ids, used);
		return kg_fail(err, KG_ENOENT,
		               "only %d tag%s of layout %s found (%s); at least %d are needed to "
		               "place the patches", used, used == 1 ? "" : "s", L->name, ids,
		               opt->min_tags);
	}
	if (inconsistent) {
		char ids[200] = "";
		list_ints(ids, sizeof(ids), bad_ids, inconsistent);
		ret = chart_add_warning(r, "ignored %d tag%s with ids of the layout that do not fit the "
		                  "chosen chart (another chart in the frame, or misread): %s",
		                  inconsistent, inconsistent == 1 ? "" : "s", ids);
		if (ret)
			return kg_fail(err, ret, "out of memory");
	}
	if (missing) {
		char ids[200] = "", uids[200] = "";
		list_ints(ids, sizeof(ids), missing_ids, missing);
		list_ints(uids, sizeof(uids), used_ids, used);
		if (used <= 3)
			ret = chart_add_warning(r, "homography determined from %d tags' corners (%d points; "
			                  "tags %s); tag%s %s not found (occluded or out of frame): "
			                  "patch positions are less certain far from the tags found",
			                  used, 4 * used, uids, missing == 1 ? "" : "s", ids);
		else
			ret = chart_add_warning(r, "tag%s %s of layout %s not found (occluded or out of frame)",
			                  missing == 1 ? "" : "s", ids, L->name);
		if (ret)
			return kg_fail(err, ret, "out of memory");
	}
	return 0;
#else
	(void)L;
	(void)wi;
	(void)opt;
	(void)r;
	return kg_fail(err, KG_ENOTSUP, "kogei was built without libapriltag: tag detection is "
	               "unavailable");
#endif
}
