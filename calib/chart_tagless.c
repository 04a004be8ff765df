/* ColorChecker 24 without tags: OpenCV mcc (chart_mcc.cpp) gives boxes around the
 * patches; each box is placed as the layout, refined (chart_refine.c), its four turns
 * sampled and the orientation chosen from the patches' colours (chart_orient.c). */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

#if KG_HAVE_MCC
#include "chart_mcc.h"
#endif

#if KG_HAVE_MCC

static int tagless_box(const kg_chart_layout *l, const layout_view *L, work_image *wi,
                       const kg_chart_detect_options *opt, const int idx[24],
                       const double box_in[4][2], double cost, int grid_patches, int f,
                       const char *copy, double white, int turns_too,
                       kg_chart_result *r, kg_err *err);

/* The reduction of the copy the tagless detector looks at first: about 1000 px on the
 * longer side (opt->tagless_decimate when set), 1 when the image is too small. */
static int tagless_reduction(int width, int height, const kg_chart_detect_options *opt)
{
	int big = width > height ? width : height;
	int f = opt->tagless_decimate > 0 ? opt->tagless_decimate : big / 1000;
	while (f > 1 && (width / f < MCC_MIN_SIDE || height / f < MCC_MIN_SIDE))
		f--;
	return f;
}

/* The patch-grid finder's boxes (chart_grid.c; px of the full image, found on the
 * copy described), each tried as mcc's would be: 0 with the chart in r when one reads
 * as the layout; KG_ENOENT, with r as it was, when none does (mcc looks next); another
 * code on failure. */
static int tagless_grid(const kg_chart_layout *l, const layout_view *L, work_image *wi,
                        const kg_chart_detect_options *opt, const int idx[24],
                        double (*boxes)[4][2], const double *costs, const int *counts, int n,
                        int f, const char *copy, double white, kg_chart_result *r,
                        kg_err *err)
{
	int ncand = r->ncandidates, ret;
	if (n && (ret = chart_image_levels(wi, err)))
		return ret;
	double box_mm[4][2];
	chart_mcc24_box_mm(L, idx, box_mm);
	int winding = chart_quad_signed_area(box_mm) > 0;
	for (int b = 0; b < n; b++) {
		/* The grid's lattice may come out mirrored: the box is given the layout's
		 * winding here by reversing it along its first side (which stays the row of 6
		 * patches), not by tagless_box's swap of corners 1 and 3, which would put the
		 * row of 6 on the box's short side. */
		if ((chart_quad_signed_area((const double (*)[2])boxes[b]) > 0) != winding) {
			double t[4][2];
			memcpy(t, boxes[b], sizeof(t));
			static const int rev[4] = {1, 0, 3, 2};
			for (int k = 0; k < 4; k++)
				memcpy(boxes[b][k], t[rev[k]], sizeof(t[k]));
		}
		kg_err box_err = {{0}};
		ret = tagless_box(l, L, wi, opt, idx, boxes[b], costs[b], counts[b], f, copy, white,
		                  0, r, &box_err);
		if (ret == 0) {
			r->tagless_grid = 1;
			return 0;
		}
		/* not this one: r as before it, for the next box or mcc */
		chart_samples_free(r->patches, L->npatches);
		r->patches = NULL;
		r->npatches = 0;
		r->ncandidates = ncand;
		if (ret != KG_ENOENT)
			return kg_fail(err, ret, "%s", box_err.msg);
	}
	return KG_ENOENT;
}

/* Find a ColorChecker 24 without tags: mcc gives the box around its patches; the
 * homography from the box in layout mm to the box in the image places the patches,
 * which chart_sample_all measures as on the tag path. Of the four ways the box's corners
 * can meet the chart's, the one whose patches look most like a ColorChecker read
 * the right way up (chart_orientation_score) wins: mcc's own choice is not trusted. */
int chart_detect_tagless(const kg_chart_layout *l, const layout_view *L, work_image *wi,
                          const kg_chart_detect_options *opt, kg_chart_result *r, kg_err *err)
{
	int idx[24];
	if (!chart_colorchecker24_patches(l, idx))
		return kg_fail(err, KG_ENOTSUP, "layout %s is not a ColorChecker 24 (24 patches "
		               "A01..D06): the tagless detector (OpenCV mcc) finds only that chart",
		               l->name);
	/* mcc keeps only contours of at least 100 px (its minContourLengthAllowed), i.e.
	 * patches of 25 px: a ColorChecker 24 of 4 x 6 patches spans 100 px or more. */
	int ret = chart_check_sides(wi->width, wi->height, MCC_MIN_SIDE, INT_MAX,
	                      "the tagless detector (OpenCV mcc)", NULL, err);
	if (ret)
		return ret;
	double t0 = chart_now_seconds(), boxes[MCC_CANDIDATES][4][2], costs[MCC_CANDIDATES];
	double white = chart_white_level(wi);
	int nboxes = 0;
	/* the region searched (all of the image), for the overlay of a refusal */
	r->searched[0][0] = r->searched[3][0] = 0;
	r->searched[1][0] = r->searched[2][0] = wi->width;
	r->searched[0][1] = r->searched[1][1] = 0;
	r->searched[2][1] = r->searched[3][1] = wi->height;
	r->has_searched = 1;
	int small_w = 0, small_h = 0, f = tagless_reduction(wi->width, wi->height, opt);
	r->prepare_seconds += chart_now_seconds() - t0;
	if (f > 1) {
		/* The patch-grid finder first (--tagless-decimate 1 asks for mcc alone): on the
		 * tag search's grey picture reduced to the copy's size when there is one (no
		 * pass over the image), else on the reduced copy mcc would read. */
		double t1 = chart_now_seconds(), gboxes[MCC_CANDIDATES][4][2], gcosts[MCC_CANDIDATES];
		int gcounts[MCC_CANDIDATES], ng = 0, z = wi->grey_zoom;
		char copy[200];
		float *small = NULL;
		if (wi->grey && z >= 1 && f % z == 0) {
			int gw, gh;
			ng = chart_grid_find_grey8(wi->grey, wi->grey_w, wi->grey_h, f / z, MCC_CANDIDATES,
			                           gboxes, gcosts, gcounts, &gw, &gh);
			r->tag_seconds += chart_now_seconds() - t1;
			/* a grey pixel is the image's pixel (z i, z j): a position x on the reduced
			 * grey is f x - z / 2 + 1 / 2 in the image */
			for (int b = 0; b < ng; b++)
				for (int k = 0; k < 4; k++)
					for (int c = 0; c < 2; c++)
						gboxes[b][k][c] = f * gboxes[b][k][c] - 0.5 * z + 0.5;
			if (z > 1)
				snprintf(copy, sizeof(copy), "the tag search's grey picture (every %d%s pixel of "
				         "every %d%s row) reduced to %d x %d", z, z == 2 ? "nd" : "th", z,
				         z == 2 ? "nd" : "th", gw, gh);
			else
				snprintf(copy, sizeof(copy), "the tag search's grey picture reduced to %d x %d",
				         gw, gh);
		} else {
			small = chart_decimate_image(wi, f, &small_w, &small_h);
			if (!small)
				return kg_fail(err, KG_ENOMEM, "out of memory");
			double t2 = chart_now_seconds();
			r->prepare_seconds += t2 - t1;
			ng = chart_grid_find(small, small_w, small_h, wi->channels, white, MCC_CANDIDATES,
			                     gboxes, gcosts, gcounts);
			r->tag_seconds += chart_now_seconds() - t2;
			for (int b = 0; b < ng; b++)
				for (int k = 0; k < 4; k++)
					for (int c = 0; c < 2; c++)
						gboxes[b][k][c] *= f;
			snprintf(copy, sizeof(copy), "a %d x %d copy averaged over %d x %d pixels", small_w,
			         small_h, f, f);
		}
		ret = tagless_grid(l, L, wi, opt, idx, gboxes, gcosts, gcounts, ng, f, copy, white, r,
		                   err);
		if (ret == KG_ENOENT && !small) {
			double t3 = chart_now_seconds();
			small = chart_decimate_image(wi, f, &small_w, &small_h);
			if (!small)
				return kg_fail(err, KG_ENOMEM, "out of memory");
			r->prepare_seconds += chart_now_seconds() - t3;
		}
		if (ret != KG_ENOENT) {
			free(small);
			if (!ret) {
				r->tagless = 1;
				r->tagless_decimate = f;
				r->decimate = 0;
				r->rms_px = 0;
			}
			return ret;
		}
		double t2 = chart_now_seconds();
		kg_err small_err = {{0}};
		ret = kg_mcc_find_colorcheckers(small, small_w, small_h, wi->channels, white,
		                                opt->threads, MCC_CANDIDATES, boxes, costs, &nboxes,
		                                &small_err);
		free(small);
		r->tag_seconds += chart_now_seconds() - t2;
		/* Not found on the reduced copy (a chart too small there): the full image
		 * decides, so nothing the full-resolution detector finds is refused. */
		if (ret == KG_ENOENT)
			f = 1;
		else if (ret)
			return kg_fail(err, ret, "%s", small_err.msg);
		else
			for (int b = 0; b < nboxes; b++)
				for (int k = 0; k < 4; k++)
					for (int c = 0; c < 2; c++)
						boxes[b][k][c] *= f;
	}
	if (f <= 1) {
		double t1 = chart_now_seconds();
		if ((ret = chart_demosaic_all(wi, err)))
			return ret;
		double t2 = chart_now_seconds();
		r->prepare_seconds += t2 - t1;
		ret = kg_mcc_find_colorcheckers(wi->data, wi->width, wi->height, wi->channels, white,
		                                opt->threads, MCC_CANDIDATES, boxes, costs, &nboxes,
		                                err);
		r->tag_seconds += chart_now_seconds() - t2;
		if (ret)
			return ret;
	}
	/* the boxes are sampled: the saturation scan's clip levels are needed now */
	if ((ret = chart_image_levels(wi, err)))
		return ret;
	r->tagless = 1;
	r->tagless_decimate = f > 1 ? f : 1;
	r->decimate = 0;
	r->rms_px = 0;
	/* mcc's boxes, its best first: the first whose patches read as the layout is
	 * taken; a refusal reports the best box's reason, and every box tried stays a
	 * candidate for the overlay */
	kg_chart_sample *first_patches = NULL;
	double first_H[9], first_outline[4][2];
	char first_msg[sizeof(err->msg)] = "";
	char copy[120];
	snprintf(copy, sizeof(copy), "a %d x %d copy averaged over %d x %d pixels", small_w,
	         small_h, f, f);
	for (int b = 0; b < nboxes; b++) {
		kg_err box_err = {{0}};
		ret = tagless_box(l, L, wi, opt, idx, boxes[b], costs[b], 0, f, copy, white, b == 0, r,
		                  &box_err);
		if (ret == 0) {
			chart_samples_free(first_patches, L->npatches);
			if (b > 0 && chart_add_warning(r, "mcc's best box (fit cost %.3g) was refused (%s); "
			                         "its candidate %d of %d (fit cost %.3g) was taken",
			                         costs[0], first_msg, b + 1, nboxes, costs[b]))
				return kg_fail(err, KG_ENOMEM, "out of memory");
			return 0;
		}
		if (ret != KG_ENOENT) {
			chart_samples_free(first_patches, L->npatches);
			return kg_fail(err, ret, "%s", box_err.msg);
		}
		if (b == 0) {
			/* the best box's regions stay in the result, for the overlay */
			snprintf(first_msg, sizeof(first_msg), "%s", box_err.msg);
			first_patches = r->patches;
			memcpy(first_H, r->H, sizeof(first_H));
			memcpy(first_outline, r->outline, sizeof(first_outline));
		} else {
			chart_samples_free(r->patches, L->npatches);
		}
		r->patches = NULL;
		r->npatches = 0;
	}
	r->patches = first_patches;
	r->npatches = first_patches ? L->npatches : 0;
	memcpy(r->H, first_H, sizeof(r->H));
	memcpy(r->outline, first_outline, sizeof(r->outline));
	if (nboxes > 1)
		return kg_fail(err, KG_ENOENT, "%s; mcc's %d other candidate%s refused too",
		               first_msg, nboxes - 1, nboxes > 2 ? "s were" : " was");
	return kg_fail(err, KG_ENOENT, "%s", first_msg);
}

/* One of mcc's boxes (px, full resolution; found on a copy reduced f x f when f > 1)
 * placed as layout l: its winding fixed, refined on the patch edges (f > 1), each of
 * its 4 turns sampled and the orientation chosen from the patches' colours. 0 with
 * the patches in r; KG_ENOENT when its patches do not read as the layout (the reason
 * in err; the best turn's patches in r and the box, with A01 of each turn when
 * turns_too, added to r's candidates). */
static int tagless_box(const kg_chart_layout *l, const layout_view *L, work_image *wi,
                       const kg_chart_detect_options *opt, const int idx[24],
                       const double box_in[4][2], double cost, int grid_patches, int f,
                       const char *copy, double white, int turns_too,
                       kg_chart_result *r, kg_err *err)
{
	double box_px[4][2], box_mm[4][2], edge_rms = 0;
	int ret = 0, refined = 0;
	memcpy(box_px, box_in, sizeof(box_px));
	chart_mcc24_box_mm(L, idx, box_mm);
	/* A photograph does not mirror the chart: give mcc's corners the layout's winding. */
	if ((chart_quad_signed_area(box_mm) > 0) != (chart_quad_signed_area((const double (*)[2])box_px) > 0)) {
		double t[2] = {box_px[1][0], box_px[1][1]};
		memcpy(box_px[1], box_px[3], sizeof(t));
		memcpy(box_px[3], t, sizeof(t));
	}
	if (f > 1) {
		/* mcc's box, f times coarser than the image's pixels, refined on the patch
		 * edges in the full image; the four turns below use the refined box. */
		double t1 = chart_now_seconds(), H0[9];
		if ((ret = kg_homography_fit((const double (*)[2])box_mm, (const double (*)[2])box_px,
		                             4, 0, H0, NULL, err)))
			return ret;
		refined = chart_refine_on_edges(wi, L, idx, white, H0, &edge_rms);
		if (refined)
			for (int k = 0; k < 4; k++)
				kg_homography_map(H0, box_mm[k][0], box_mm[k][1], box_px[k]);
		r->tag_seconds += chart_now_seconds() - t1;
	}
	double ts = chart_now_seconds();
	double score[4], H[4][9], angle[4];
	kg_chart_sample *sampled[4] = {NULL, NULL, NULL, NULL}; /* each turn's patches */
	int best = 0, upright = 0, full[4] = {0, 0, 0, 0}, used[4] = {0, 0, 0, 0};
	/* Each turn scored first on a sparse sample of its patches, every stride-th row
	 * and column (about a thousand pixels a patch): the wrong turns read as far from a
	 * ColorChecker on that as on all pixels. The best, and every turn within 1.5 times
	 * its score (all four when even the best does not read as a ColorChecker), are
	 * then sampled whole and scored again: those scores decide. */
	double patch_px = fabs(chart_quad_signed_area((const double (*)[2])box_px)) / 24 *
	                  opt->sample_fraction * opt->sample_fraction;
	int stride = (int)sqrt(fmax(patch_px, 1) / 1024);
	stride = stride < 1 ? 1 : stride > 8 ? 8 : stride;
	for (int turn = 0; turn < 4 && !ret; turn++) {
		double dst[4][2];
		for (int k = 0; k < 4; k++)
			memcpy(dst[k], box_px[(k + turn) % 4], sizeof(dst[k]));
		ret = kg_homography_fit((const double (*)[2])box_mm, (const double (*)[2])dst, 4, 0,
		                        H[turn], NULL, err);
	}
	for (int pass = stride > 1 ? 0 : 1; pass < 2 && !ret; pass++) {
		double cheapest = INFINITY;
		for (int turn = 0; pass == 1 && stride > 1 && turn < 4; turn++)
			cheapest = fmin(cheapest, score[turn]);
		for (int turn = 0; turn < 4 && !ret; turn++) {
			if (pass == 1 && stride > 1 &&
			    !(score[turn] <= KG_ORIENT_MARGIN * cheapest + 0.01 ||
			      !(cheapest <= KG_ORIENT_SCORE_MAX)))
				continue;
			memcpy(r->H, H[turn], sizeof(r->H));
			ret = chart_sample_all_with(L, wi, opt, 1, pass == 0 ? stride : 1, r, err);
			chart_samples_free(sampled[turn], L->npatches);
			sampled[turn] = r->patches;
			r->patches = NULL;
			r->npatches = 0;
			if (!ret) {
				score[turn] = chart_orientation_score(sampled[turn], idx, &used[turn]);
				full[turn] = pass == 1;
			}
		}
	}
	for (int turn = 0; turn < 4 && !ret; turn++) {
		/* a turn never sampled whole is never the best */
		if (full[turn] && (!full[best] || score[turn] < score[best]))
			best = turn;
		double a1[2], a6[2];
		kg_homography_map(H[turn], L->patch_center[idx[0]][0], L->patch_center[idx[0]][1], a1);
		kg_homography_map(H[turn], L->patch_center[idx[5]][0], L->patch_center[idx[5]][1], a6);
		angle[turn] = atan2(a6[1] - a1[1], a6[0] - a1[0]) * 180 / M_PI;
		if (fabs(angle[turn]) < fabs(angle[upright]))
			upright = turn;
	}
	/* The best turn must read as a ColorChecker (its colours fit the layout's through
	 * one 3 x 3 matrix), have colour at all (a grey picture fits every turn), and read
	 * clearly better than the next best turn; otherwise neither the patches nor mcc,
	 * whose choice rests on the same colours, can say which patch is which. */
	r->sample_seconds += chart_now_seconds() - ts;
	double next = INFINITY;
	int next_turn = -1;
	for (int turn = 0; turn < 4 && !ret; turn++)
		if (turn != best && score[turn] < next) {
			next = score[turn];
			next_turn = turn;
		}
	double spread = ret ? 0 : chart_colour_spread(sampled[best], idx);
	char why[400] = "";
	if (ret)
		;
	else if (used[best] < 12)
		snprintf(why, sizeof(why), "only %d of its 24 patches can be read (the others are "
		         "clipped, rejected or out of the image; 12 are needed)", used[best]);
	else if (spread < KG_ORIENT_SPREAD_MIN)
		snprintf(why, sizeof(why), "they have next to no colour (spread %.3f, a "
		         "ColorChecker has more than %.2f)", spread, KG_ORIENT_SPREAD_MIN);
	else if (!(score[best] <= KG_ORIENT_SCORE_MAX))
		snprintf(why, sizeof(why), "their colours match the layout's in none of its 4 turns "
		         "(best colour misfit %.3f, a ColorChecker fits below %.2f)", score[best],
		         KG_ORIENT_SCORE_MAX);
	else if (!(next >= KG_ORIENT_MARGIN * score[best]))
		snprintf(why, sizeof(why), "two of its turns match the layout's colours about as "
		         "well (colour misfit %.3f and %.3f, the best must be %.1f times better)",
		         score[best], next, KG_ORIENT_MARGIN);
	int uncertain = !ret && why[0];
	if (uncertain) {
		/* what was tried, for the overlay: mcc's box, A01's corner of each turn */
		int add = turns_too ? 5 : 1;
		kg_chart_candidate *c = realloc(r->candidates,
		                                (size_t)(r->ncandidates + add) * sizeof(*c));
		if (c) {
			r->candidates = c;
			c += r->ncandidates;
			r->ncandidates += add;
			memset(c, 0, (size_t)add * sizeof(*c));
			memcpy(c[0].quad, box_px, sizeof(c[0].quad));
			snprintf(c[0].why, sizeof(c[0].why), "mcc's box (fit cost %.3g): its patches do "
			         "not read as the layout: %s", cost, why);
			for (int turn = 0; turn < 4 && turns_too; turn++) {
				kg_chart_sample *a = &sampled[turn][idx[0]];
				memcpy(c[1 + turn].quad, a->quad, sizeof(c[1 + turn].quad));
				snprintf(c[1 + turn].why, sizeof(c[1 + turn].why), "A01 if turn %d: misfit "
				         "%.3f%s", turn, score[turn], full[turn] ? "" : " (sparse)");
			}
		}
	}
	for (int turn = 0; turn < 4; turn++)
		if (ret || turn != best)
			chart_samples_free(sampled[turn], L->npatches);
	if (ret)
		return ret;
	if (uncertain) {
		/* the best turn's regions stay in the result, for the overlay */
		r->patches = sampled[best];
		r->npatches = L->npatches;
		memcpy(r->H, H[best], sizeof(r->H));
		for (int k = 0; k < 4; k++)
			kg_homography_map(r->H, L->outline[k][0], L->outline[k][1], r->outline[k]);
		return kg_fail(err, KG_ENOENT,
		               "the tagless detector (OpenCV mcc, fit cost %.3g) found a box, but "
		               "its patches do not read as layout %s: %s. No ColorChecker in view "
		               "(other colours on its geometry), or light too coloured, clipped or "
		               "processed to tell; row A01-A06 would run at %.0f degrees from the "
		               "image's x axis", cost, l->name, why, angle[upright]);
	}
	r->patches = sampled[best];
	r->npatches = L->npatches;
	memcpy(r->H, H[best], sizeof(r->H));
	for (int k = 0; k < 4; k++)
		kg_homography_map(r->H, L->outline[k][0], L->outline[k][1], r->outline[k]);
	int next_sparse = next_turn >= 0 && !full[next_turn];
	char sparse[80] = "";
	if (next_sparse)
		snprintf(sparse, sizeof(sparse), " (on every %d%s row and column)", stride,
		         stride == 2 ? "nd" : stride == 3 ? "rd" : "th");
	char how[300] = "";
	if (f > 1 && refined)
		snprintf(how, sizeof(how), " on %s, refined on %d points of the patch edges at full "
		         "resolution (RMS %.2f px)", copy, refined, edge_rms);
	else if (f > 1)
		snprintf(how, sizeof(how), " on %s (too few patch edges to refine it at full "
		         "resolution)", copy);
	char source[160], own[40] = "";
	if (grid_patches > 0)
		snprintf(source, sizeof(source), "its patch-grid finder: %d of the 24 patches found "
		         "as uniform regions on a 6 x 4 grid, RMS %.2g of a pitch off it",
		         grid_patches, cost);
	else
		snprintf(source, sizeof(source), "OpenCV mcc, fit cost %.3g", cost);
	if (grid_patches <= 0)
		snprintf(own, sizeof(own), ", %s mcc's own", best == 0 ? "agreeing with" : "overruling");
	ret = chart_add_warning(r, "chart placed by the tagless detector (%s) from the 4 corners "
	                  "of its box%s, not by tags; orientation chosen from the patches' "
	                  "colours (%d patches fitted to the layout's through one 3 x 3 matrix, "
	                  "light level free): colour misfit %.3f, next best of the 4 turns "
	                  "%.3f%s%s; row A01-A06 runs at %.0f degrees clockwise from the image's "
	                  "x axis", source, how, used[best], score[best], next, sparse, own,
	                  angle[best]);
	return ret ? kg_fail(err, ret, "out of memory") : 0;
}
#else
int chart_detect_tagless(const kg_chart_layout *l, const layout_view *L, work_image *wi,
                          const kg_chart_detect_options *opt, kg_chart_result *r, kg_err *err)
{
	(void)L;
	(void)wi;
	(void)opt;
	(void)r;
	if (l->ntags == 0)
		return kg_fail(err, KG_ENOTSUP, "layout %s has no tags: it can only be found by the "
		               "tagless detector (OpenCV mcc), not available in this build", l->name);
	return kg_fail(err, KG_ENOTSUP, "tagless detection (OpenCV mcc) is not available in "
	               "this build");
}
#endif

void kg_chart_warm_up(const kg_chart_layout *l, const kg_chart_detect_options *opt)
{
#if KG_HAVE_MCC
	int idx[24];
	/* the tagless mode, a layout without tags, or the fallback (min_tags 0) of a
	 * ColorChecker 24 layout: the cases kg_chart_detect warms up for */
	if (l && opt && (opt->tagless || l->ntags == 0 || opt->min_tags == 0) &&
	    chart_colorchecker24_patches(l, idx))
		kg_mcc_warm_up();
#else
	(void)l;
	(void)opt;
#endif
}

void chart_tagless_warm_up(const kg_chart_layout *l, const kg_chart_detect_options *opt,
                           int width, int height)
{
#if KG_HAVE_MCC
	/* an image the patch-grid finder reads first may never need mcc */
	if (opt && tagless_reduction(width, height, opt) <= 1)
		kg_chart_warm_up(l, opt);
#else
	(void)l;
	(void)opt;
	(void)width;
	(void)height;
#endif
}

void kg_chart_warm_wait(void)
{
#if KG_HAVE_MCC
	kg_mcc_warm_wait();
#endif
}

/* No tags seen at all: a ColorChecker may still be in view without its frame. */
int chart_tagless_fallback(const kg_chart_layout *l, const kg_chart_result *r, int ret)
{
#if KG_HAVE_MCC
	int idx[24];
	return (ret == KG_ENOENT || ret == KG_ENOTSUP) && r->ntags == 0 &&
	       chart_colorchecker24_patches(l, idx);
#else
	(void)l;
	(void)r;
	(void)ret;
	return 0;
#endif
}
