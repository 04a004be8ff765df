/* Site calibration: M2 = rho0 pinv(rho_r), the 3 x 3 map from a site camera's RGB
 * into the reference camera's, and the per-pixel maps that fold it in. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib_private.h"

#define NB KG_NBANDS

void kg_camera_options_default(kg_camera_options *o)
{
	memset(o, 0, sizeof(*o));
	o->max_cond = KG_CALIB_MAX_COND;
	o->clip_level = KG_CALIB_CLIP_LEVEL;
	o->black_level = KG_CALIB_BLACK_LEVEL;
	o->pinv_rtol = KG_CALIB_PINV_RTOL;
	o->max_residual = KG_CALIB_MAX_RESIDUAL;
}

void kg_camera_calib_free(kg_camera_calib **pcam)
{
	if (!pcam || !*pcam)
		return;
	kg_camera_calib *cam = *pcam;
	calib_strv_free(cam->ids, cam->k);
	free(cam->rho_r);
	free(cam->rho0);
	free(cam->residual);
	calib_strv_free(cam->flagged_ids, cam->nflagged);
	free(cam->flagged_flags);
	calib_sources_free(&cam->sources, &cam->nsources);
	kg_pairing_record_free(&cam->pairing);
	free(cam);
	*pcam = NULL;
}

static int find_id(char *const *ids, int n, const char *id)
{
	for (int i = 0; i < n; i++)
		if (strcmp(ids[i], id) == 0)
			return i;
	return -1;
}

static int is_excluded(const kg_camera_options *opt, const char *id)
{
	for (int i = 0; i < opt->nexclude; i++)
		if (strcmp(opt->exclude[i], id) == 0)
			return 1;
	return 0;
}

/* The index in ref->flagged_ids of a patch the reference left out because chart
 * detection flagged it on the reference's chart, else -1. */
static int ref_flagged(const kg_reference *ref, const char *id)
{
	for (int i = 0; i < ref->nflagged; i++)
		if (strcmp(ref->flagged_ids[i], id) == 0)
			return i;
	return -1;
}

/* Fold M2 into a reference map: linear methods get A M2, root-polynomial ones keep
 * A and apply M2 first. */
static void site_map_from(const kg_spectral_map *ref, const double M2[9], kg_site_map *out)
{
	memset(out, 0, sizeof(*out));
	out->method = ref->method;
	out->available = ref->available;
	out->nterms = ref->nterms;
	out->lambda = ref->lambda;
	out->loo_rmse = ref->loo_rmse;
	memcpy(out->offset, ref->offset, sizeof(out->offset));
	if (ref->nterms == 3) {
		for (int l = 0; l < NB; l++)
			for (int c = 0; c < 3; c++)
				out->A[l * 3 + c] = ref->A[l * 3 + 0] * M2[0 * 3 + c] +
				                    ref->A[l * 3 + 1] * M2[1 * 3 + c] +
				                    ref->A[l * 3 + 2] * M2[2 * 3 + c];
		out->pre[0] = out->pre[4] = out->pre[8] = 1;
	} else {
		memcpy(out->A, ref->A, (size_t)NB * ref->nterms * sizeof(double));
		memcpy(out->pre, M2, sizeof(out->pre));
	}
}

static int check_options(const kg_camera_options *opt, kg_err *err)
{
	if (!(opt->max_cond >= 1))
		return kg_fail(err, KG_EINVAL, "condition-number limit %g: expected >= 1",
		               opt->max_cond);
	if (!(opt->clip_level > 0) || !isfinite(opt->clip_level))
		return kg_fail(err, KG_EINVAL, "clip level %g: expected a finite value > 0",
		               opt->clip_level);
	if (!(opt->black_level >= 0) || !(opt->black_level < opt->clip_level))
		return kg_fail(err, KG_EINVAL, "black level %g: expected 0 <= level < clip level",
		               opt->black_level);
	if (!(opt->pinv_rtol >= 0 && opt->pinv_rtol < 1))
		return kg_fail(err, KG_EINVAL, "pinv tolerance %g: expected 0 <= rtol < 1",
		               opt->pinv_rtol);
	if (!(opt->max_residual > 0) || !isfinite(opt->max_residual))
		return kg_fail(err, KG_EINVAL, "residual limit %g: expected a finite number > 0",
		               opt->max_residual);
	return 0;
}

/* The reference's field chart (rho0) and the site file as the two sides of a pairing,
 * without the excluded patches and the site's flagged and clipped ones. */
static int site_sides(const kg_reference *ref, const kg_patchset *site,
                      const kg_camera_options *opt, const char *what, calib_pair_side *a,
                      calib_pair_side *b, kg_err *err)
{
	int ret = calib_pair_side_new("the reference", "reference",
	                              "the reference camera's values of the field chart (rho0)",
	                              ref->field_ids, ref->k, (const double(*)[3])ref->rho0, a,
	                              err);
	if (ret == 0)
		ret = calib_pair_side_new(what, "rgb", "", site->ids, site->n,
		                          (const double(*)[3])site->rgb, b, err);
	if (ret == 0) {
		calib_pair_side_skip(a, opt->exclude, opt->nexclude, NULL, 0);
		calib_pair_side_skip(b, opt->exclude, opt->nexclude, site, opt->clip_level);
	}
	return ret;
}

/* Pair the site file's patches with the reference's field chart, refusing ids that
 * another pairing explains (calib_pair_check; the whole chart is judged by the
 * relative residual, single patches by check_site_patches): alias[i] is the reference
 * patch of site patch i, or -1. */
static int pair_site(const kg_reference *ref, const kg_patchset *site,
                     const kg_camera_options *opt, const char *what, int *alias,
                     const char **id_rule, kg_pairing_record *rec, kg_err *err)
{
	calib_pair_side a = {0}, b = {0};
	calib_pair_result r = {0};
	int ret = site_sides(ref, site, opt, what, &a, &b, err);
	if (ret == 0)
		ret = calib_pair_check(&a, &b, opt->id_pairing, 0, opt->id_pairing_option, &r, err);
	if (ret == 0)
		ret = calib_pair_record(&a, &b, &r, opt->id_pairing, rec, err);
	for (int i = 0; ret == 0 && i < site->n; i++)
		alias[i] = -1;
	for (int j = 0; ret == 0 && j < ref->k; j++)
		if (r.match[j] >= 0)
			alias[r.match[j]] = j;
	if (ret == 0)
		*id_rule = r.alias;
	calib_pair_result_free(&r);
	calib_pair_side_free(&a);
	calib_pair_side_free(&b);
	return ret;
}

/* Single patches that fit other patches' colours. On a chart that reads as the
 * reference's (relative residual within the default limit) they are refused; when
 * the residual was refused (`refused`), they are named after its message, since two
 * swapped patches raise the residual too; a chart accepted only by a raised
 * --max-residual gives no fit to judge them by. */
static int check_site_patches(const kg_reference *ref, const kg_patchset *site,
                              const kg_camera_options *opt, const char *what,
                              const kg_camera_calib *cam, int refused, kg_err *err)
{
	if (!refused && cam->residual_relative > KG_CALIB_MAX_RESIDUAL)
		return 0;
	calib_pair_side a = {0}, b = {0};
	calib_pair_result r = {0};
	kg_err own = {{0}};
	int ret = site_sides(ref, site, opt, what, &a, &b, &own);
	if (ret == 0)
		ret = calib_pair_check(&a, &b, opt->id_pairing, 0, opt->id_pairing_option, &r, &own);
	if (ret == 0 && !refused) {
		ret = calib_pair_check_patches(&a, &b, &r, opt->id_pairing_option, err);
	} else if (ret == 0) {
		char moved[800];
		size_t at = strlen(err->msg);
		if (calib_pair_moved(&a, &b, &r, opt->id_pairing_option, moved, sizeof(moved)) > 0 &&
		    at < sizeof(err->msg))
			snprintf(err->msg + at, sizeof(err->msg) - at, ". Also, %s", moved);
	}
	calib_pair_result_free(&r);
	calib_pair_side_free(&a);
	calib_pair_side_free(&b);
	return ret;
}

/* Which site patches take part: every non-excluded site id must be on the
 * reference's field chart, and at least 3 must be in common. idx_ref/idx_site
 * receive the pairs in the reference's order. */
static int match_patches(const kg_reference *ref, const kg_patchset *site,
                         const kg_camera_options *opt, const char *what, int *idx_ref,
                         int *idx_site, int *k, const char **id_rule,
                         kg_pairing_record *rec, kg_err *err)
{
	int n = site->n, nunknown = 0, nmissing = 0;
	int *unknown = malloc((n > 0 ? (size_t)n : 1) * sizeof(int));
	int *missing = malloc((ref->k > 0 ? (size_t)ref->k : 1) * sizeof(int));
	int ret = 0;
	if (!unknown || !missing) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto done;
	}
	for (int i = 0; i < n; i++)
		for (int j = 0; j < i; j++)
			if (strcmp(site->ids[i], site->ids[j]) == 0) {
				ret = kg_fail(err, KG_EINVAL, "%s: SAMPLE_ID %s appears twice", what,
				              site->ids[i]);
				goto done;
			}
	for (int e = 0; e < opt->nexclude; e++)
		if (find_id(site->ids, n, opt->exclude[e]) < 0 &&
		    find_id(ref->field_ids, ref->k, opt->exclude[e]) < 0) {
			ret = kg_fail(err, KG_EINVAL,
			              "--exclude %s: no patch of that SAMPLE_ID in %s or in the reference",
			              opt->exclude[e], what);
			goto done;
		}
	/* the site file's patches as the reference's (kg_patch_ids_match: A1 = A01 = 1, or
	 * as opt->id_pairing says), checked by colour */
	int *alias = malloc((n > 0 ? (size_t)n : 1) * sizeof(int));
	if (!alias) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto done;
	}
	if ((ret = pair_site(ref, site, opt, what, alias, id_rule, rec, err))) {
		free(alias);
		goto done;
	}
	for (int i = 0; i < n; i++)
		if (!is_excluded(opt, site->ids[i]) && ref_flagged(ref, site->ids[i]) < 0 &&
		    alias[i] < 0)
			unknown[nunknown++] = i;
	if (nunknown) {
		free(alias);
		char a[400] = "", b[300] = "";
		calib_list_ids(a, sizeof(a), site->ids, unknown, nunknown, 12);
		calib_list_ids(b, sizeof(b), ref->field_ids, NULL, ref->k, 12);
		ret = kg_fail(err, KG_EINVAL,
		              "%s: patch ids do not match the reference: %d of its %d SAMPLE_IDs are "
		              "not on the reference's field chart (%s); the reference's ids are %s. "
		              "Was the site chart detected with the same layout?",
		              what, nunknown, n, a, b);
		goto done;
	}
	*k = 0;
	for (int j = 0; j < ref->k; j++) {
		if (is_excluded(opt, ref->field_ids[j]))
			continue;
		int i = -1;
		for (int t = 0; t < n && i < 0; t++)
			if (alias[t] == j)
				i = t;
		if (i >= 0 && is_excluded(opt, site->ids[i]))
			continue;
		if (i < 0) {
			missing[nmissing++] = j;
			continue;
		}
		idx_ref[*k] = j;
		idx_site[*k] = i;
		(*k)++;
	}
	free(alias);
	if (*k < 3) {
		char a[300] = "", b[400] = "";
		int *common = malloc(((size_t)*k + 1) * sizeof(int));
		if (!common) {
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
			goto done;
		}
		for (int i = 0; i < *k; i++)
			common[i] = idx_ref[i];
		calib_list_ids(a, sizeof(a), ref->field_ids, common, *k, 12);
		calib_list_ids(b, sizeof(b), ref->field_ids, missing, nmissing, 24);
		free(common);
		ret = kg_fail(err, KG_EINVAL,
		              "%s: only %d patch%s in common with the reference's field chart (%s); "
		              "M2 needs at least 3. Missing from %s: %s",
		              what, *k, *k == 1 ? "" : "es", *k ? a : "none", what,
		              nmissing ? b : "none (the rest were excluded)");
	}
done:
	free(unknown);
	free(missing);
	return ret;
}

/* The residuals rho0 - M2 rho_r of the k patches, their RMS and relative size. */
static void m2_residuals(kg_camera_calib *cam)
{
	double res2 = 0, ref2 = 0;
	for (int i = 0; i < cam->k; i++)
		for (int r = 0; r < 3; r++) {
			double p = cam->M2[r * 3 + 0] * cam->rho_r[i][0] +
			           cam->M2[r * 3 + 1] * cam->rho_r[i][1] +
			           cam->M2[r * 3 + 2] * cam->rho_r[i][2];
			cam->residual[i][r] = cam->rho0[i][r] - p;
			res2 += cam->residual[i][r] * cam->residual[i][r];
			ref2 += cam->rho0[i][r] * cam->rho0[i][r];
		}
	cam->residual_rms = sqrt(res2 / (3.0 * cam->k));
	cam->residual_relative = ref2 > 0 ? sqrt(res2 / ref2) : 0;
}

/* M2 = R0 pinv(R) with R, R0 the 3 x k site and reference values. */
static int solve_m2(kg_camera_calib *cam, double rtol, kg_err *err)
{
	int k = cam->k;
	kg_mat *R = NULL, *P = NULL;
	int ret = kg_mat_new(3, k, &R, err);
	if (ret)
		return ret;
	for (int c = 0; c < 3; c++)
		for (int i = 0; i < k; i++)
			R->a[c * k + i] = cam->rho_r[i][c];
	ret = kg_pinv(R, rtol, &P, &cam->rank, NULL, err);
	if (ret == 0 && cam->rank < 3)
		ret = kg_fail(err, KG_EINVAL, "site chart: RGB has rank %d; expected 3", cam->rank);
	if (ret == 0) {
		for (int r = 0; r < 3; r++)
			for (int c = 0; c < 3; c++) {
				double v = 0;
				for (int i = 0; i < k; i++)
					v += cam->rho0[i][r] * P->a[i * 3 + c];
				cam->M2[r * 3 + c] = v;
			}
		/* rho_r has rank 3, but rho0 (the reference's readings) may not: the same
		 * refusal as a loaded calibration's */
		ret = kg_mat3_check_invertible(cam->M2, NULL, "M2", err);
	}
	if (ret == 0)
		m2_residuals(cam);
	kg_mat_free(&R);
	kg_mat_free(&P);
	return ret;
}

/* The detector's reasons for flags, as kogei chart detect's FLAGS column codes them. */
static void describe_flags(unsigned f, char *buf, size_t n)
{
	static const struct {
		unsigned bit;
		const char *why;
	} names[] = {{KG_CHART_FLAG_CLIPPED, "clipped"},
	             {KG_CHART_FLAG_GLARE, "glare"},
	             {KG_CHART_FLAG_FEW_PIXELS, "too few pixels"},
	             {KG_CHART_FLAG_OUT_OF_FRAME, "out of frame"},
	             {KG_CHART_FLAG_NONUNIFORM, "non-uniform"},
	             {KG_CHART_FLAG_REJECTED, "rejected"},
	             {KG_CHART_FLAG_MISFIT, "colour not the layout's"}};
	size_t at = 0;
	buf[0] = 0;
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]) && at < n; i++)
		if (f & names[i].bit)
			at += (size_t)snprintf(buf + at, n - at, "%s%s", at ? ", " : "", names[i].why);
	if (!at)
		snprintf(buf, n, "flags %u", f);
}

/* Leave out the pairs whose site patch the detector flagged (FLAGS column != 0),
 * recording them in cam with the site patches the reference left out because they
 * were flagged on its chart; fewer than 3 left is refused naming them. */
static int drop_flagged(const kg_patchset *site, const char *what, int *idx_ref,
                        int *idx_site, int *k, const kg_reference *ref, kg_camera_calib *cam,
                        kg_err *err)
{
	int col = kg_patchset_extra_index(site, "FLAGS");
	int kept = 0, n = *k;
	size_t cap = (size_t)n + (size_t)ref->nflagged + 1;
	cam->flagged_ids = calloc(cap, sizeof(char *));
	cam->flagged_flags = calloc(cap, sizeof(unsigned));
	if (!cam->flagged_ids || !cam->flagged_flags)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	/* the site's patches the reference left out, flagged on its chart */
	for (int i = 0; i < site->n; i++) {
		int r = ref_flagged(ref, site->ids[i]);
		if (r < 0)
			continue;
		if (!(cam->flagged_ids[cam->nflagged] = strdup(site->ids[i])))
			return kg_fail(err, KG_ENOMEM, "out of memory");
		cam->flagged_flags[cam->nflagged++] = ref->flagged_flags[r];
	}
	if (col < 0)
		return 0;
	for (int i = 0; i < n; i++) {
		double f = site->extra[(size_t)idx_site[i] * site->nextra + col];
		if (f == 0 || !isfinite(f) || f < 0) {
			idx_ref[kept] = idx_ref[i];
			idx_site[kept++] = idx_site[i];
			continue;
		}
		if (!(cam->flagged_ids[cam->nflagged] = strdup(ref->field_ids[idx_ref[i]])))
			return kg_fail(err, KG_ENOMEM, "out of memory");
		/* Detection writes small whole numbers; anything else still counts as flagged. */
		cam->flagged_flags[cam->nflagged++] = f < 65536 ? (unsigned)f : 0xffffu;
	}
	*k = kept;
	if (kept >= 3)
		return 0;
	char list[600] = "";
	size_t at = 0;
	for (int i = 0; i < cam->nflagged && at < sizeof(list) - 1; i++) {
		char why[96];
		describe_flags(cam->flagged_flags[i], why, sizeof(why));
		if (i == 12) {
			snprintf(list + at, sizeof(list) - at, " and %d more", cam->nflagged - 12);
			break;
		}
		at += (size_t)snprintf(list + at, sizeof(list) - at, "%s%s (%s)", i ? ", " : "",
		                       cam->flagged_ids[i], why);
	}
	return kg_fail(err, KG_EINVAL,
	               "%s: %d of its %d patches in common with the reference were flagged by "
	               "chart detection and left out: %s; %d usable patch%s left, M2 needs at "
	               "least 3. Was the chart detected with its own layout, evenly lit and in "
	               "full view?",
	               what, cam->nflagged, n, list, kept, kept == 1 ? "" : "es");
}

/* A patch that does not fit the others through M2 (a card over it on the site chart,
 * a patch painted over): its residual relative to its reference value (floored at
 * M2_MISFIT_FLOOR of the brightest, so dark patches' noise does not count) above
 * M2_MISFIT_SPREAD times the patches' robust spread (1.4826 x their median), and
 * above M2_MISFIT_MIN, the residuals from M2 fitted three times on the three quarters
 * of the patches that fit best (so the patch does not bend the fit it is judged by).
 * Left out worst first, at most a quarter of the patches, and 6 stay; M2 is fitted
 * again on the rest (docs/calib-camera.md). */
#define M2_MISFIT_FLOOR 0.05
#define M2_MISFIT_SPREAD 6.0
#define M2_MISFIT_MIN 0.25

/* The patches' relative residuals in e. */
static void misfits(const kg_camera_calib *cam, double *e)
{
	double bright = 0;
	for (int i = 0; i < cam->k; i++)
		bright = fmax(bright, sqrt(cam->rho0[i][0] * cam->rho0[i][0] +
		                           cam->rho0[i][1] * cam->rho0[i][1] +
		                           cam->rho0[i][2] * cam->rho0[i][2]));
	for (int i = 0; i < cam->k; i++) {
		const double *r = cam->residual[i], *v = cam->rho0[i];
		double nv = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
		e[i] = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]) /
		       fmax(nv, M2_MISFIT_FLOOR * bright);
	}
}

static void swap_patches(kg_camera_calib *cam, int i, int j)
{
	double a[3];
	char *id = cam->ids[i];
	cam->ids[i] = cam->ids[j];
	cam->ids[j] = id;
	memcpy(a, cam->rho_r[i], sizeof(a));
	memcpy(cam->rho_r[i], cam->rho_r[j], sizeof(a));
	memcpy(cam->rho_r[j], a, sizeof(a));
	memcpy(a, cam->rho0[i], sizeof(a));
	memcpy(cam->rho0[i], cam->rho0[j], sizeof(a));
	memcpy(cam->rho0[j], a, sizeof(a));
}

/* The k patches sorted by key (ascending), their arrays and `other` alongside. */
static void sort_patches(kg_camera_calib *cam, int k, double *key, double *other)
{
	for (int i = 1; i < k; i++) /* insertion sort: a few dozen patches */
		for (int j = i; j > 0 && key[j - 1] > key[j]; j--) {
			double t = key[j];
			key[j] = key[j - 1];
			key[j - 1] = t;
			t = other[j];
			other[j] = other[j - 1];
			other[j - 1] = t;
			swap_patches(cam, j, j - 1);
		}
}

/* e[i]: patch i's misfit to M2 fitted to the other patches; 0 when one of those fits
 * fails (too few colours without it). */
static int deleted_misfits(kg_camera_calib *cam, const kg_camera_options *opt, double *e)
{
	int k = cam->k, ok = 1;
	double *all = malloc((size_t)k * sizeof(*all));
	if (!all)
		return 0;
	for (int i = 0; i < k && ok; i++) {
		swap_patches(cam, i, k - 1);
		kg_err ignored;
		cam->k = k - 1;
		ok = solve_m2(cam, opt->pinv_rtol, &ignored) == 0;
		cam->k = k;
		m2_residuals(cam);
		misfits(cam, all);
		e[i] = all[k - 1];
		swap_patches(cam, i, k - 1);
	}
	free(all);
	return ok;
}

static int drop_misfits(kg_camera_calib *cam, const kg_camera_options *opt, kg_err *err)
{
	int k = cam->k, most = k / 4;
	if (most < 1 || k - most < 6)
		return 0;
	/* e: misfits; pos: each patch's place in the reference's order, restored at the end */
	double *e = malloc((size_t)k * sizeof(*e)), *pos = malloc((size_t)k * sizeof(*pos));
	if (!e || !pos) {
		free(e);
		free(pos);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	for (int i = 0; i < k; i++)
		pos[i] = i;
	/* the first ranking by each patch's misfit to M2 fitted without it, so a patch
	 * far from the others (a white card among dark colours) cannot fit itself */
	int fitted = deleted_misfits(cam, opt, e);
	for (int round = 0; fitted && round < 3; round++) {
		if (round)
			misfits(cam, e);
		sort_patches(cam, k, e, pos);
		cam->k = k - most; /* the best three quarters */
		kg_err ignored;
		fitted = solve_m2(cam, opt->pinv_rtol, &ignored) == 0;
		cam->k = k;
		m2_residuals(cam);
	}
	if (fitted) {
		misfits(cam, e);
		sort_patches(cam, k, e, pos);
		double t = fmax(M2_MISFIT_MIN, M2_MISFIT_SPREAD * 1.4826 * calib_median(e, k));
		/* listed with the flagged patches (their arrays hold room for every pair) */
		while (cam->k > k - most && e[cam->k - 1] > t) {
			cam->k--;
			cam->flagged_ids[cam->nflagged] = cam->ids[cam->k];
			cam->flagged_flags[cam->nflagged++] = KG_CHART_FLAG_MISFIT;
			cam->ids[cam->k] = NULL;
		}
	}
	sort_patches(cam, cam->k, pos, e); /* back in the reference's order */
	free(e);
	free(pos);
	/* M2 of the patches kept (all of them when none was left out) */
	return solve_m2(cam, opt->pinv_rtol, err);
}

/* A fit whose residual cannot be checked (k = 3) or is too large is refused. */
static int check_residual(const kg_camera_calib *cam, const kg_camera_options *opt,
                          const char *what, kg_err *err)
{
	if (cam->k == 3 && !opt->force)
		return kg_fail(err, KG_EINVAL,
		               "%s: only 3 usable patches (%s, %s, %s): M2 has 9 numbers for 9 "
		               "values, so its residual is 0 whatever was photographed and the fit "
		               "cannot be checked; photograph more patches, or pass --force to "
		               "accept it unchecked",
		               what, cam->ids[0], cam->ids[1], cam->ids[2]);
	if (cam->k == 3 || !(cam->residual_relative > opt->max_residual))
		return 0;
	/* The worst patches by their residual relative to their reference value. */
	int order[5] = {-1, -1, -1, -1, -1};
	double rel[5] = {0};
	int nworst = cam->k < 5 ? cam->k : 5;
	for (int i = 0; i < cam->k; i++) {
		const double *r = cam->residual[i], *v = cam->rho0[i];
		double e = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
		double nv = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
		double x = nv > 0 ? e / nv : e;
		for (int j = 0; j < nworst; j++)
			if (order[j] < 0 || x > rel[j]) {
				memmove(order + j + 1, order + j, (size_t)(nworst - 1 - j) * sizeof(int));
				memmove(rel + j + 1, rel + j, (size_t)(nworst - 1 - j) * sizeof(double));
				order[j] = i;
				rel[j] = x;
				break;
			}
	}
	char list[400] = "";
	size_t at = 0;
	for (int j = 0; j < nworst && at < sizeof(list) - 1; j++)
		at += (size_t)snprintf(list + at, sizeof(list) - at, "%s%s %.0f %%", j ? ", " : "",
		                       cam->ids[order[j]], 100 * rel[j]);
	return kg_fail(err, KG_EINVAL,
	               "%s: relative residual ||rho0 - M2 rho_r|| / ||rho0|| = %.1f %% over %d "
	               "patches, above the limit of %.1f %%: the patches do not read as the "
	               "reference's chart (wrong layout or orientation, no chart in view, or "
	               "uneven light). Worst patches: %s. --max-residual raises the limit",
	               what, 100 * cam->residual_relative, cam->k, 100 * opt->max_residual, list);
}

/* The site chart's flare against the reference's flare-free rho0 (kg_camera_calib.flare),
 * over the reference's neutral patches; subtracted from rho_r when found. Refused above
 * the limit, naming the values. */
static int site_flare(const kg_reference *ref, kg_camera_calib *cam,
                      const kg_camera_options *opt, const char *what, kg_err *err)
{
	kg_flare *f = &cam->flare;
	memset(f, 0, sizeof(*f));
	if (!ref->flare_removed)
		return 0;
	int idx[KG_FLARE_MAX_NEUTRALS];
	for (int n = 0; n < ref->field_flare.n; n++) {
		int i = find_id(cam->ids, cam->k, ref->field_flare.ids[n]);
		if (i >= 0 && f->n < KG_FLARE_MAX_NEUTRALS) {
			idx[f->n] = i;
			snprintf(f->ids[f->n++], sizeof(f->ids[0]), "%s", cam->ids[i]);
		}
	}
	if (f->n < 3)
		return 0;
	f->found = 1;
	for (int ch = 0; ch < 3; ch++) {
		double mx = 0, my = 0, sxx = 0, sxy = 0, rss = 0;
		for (int n = 0; n < f->n; n++) {
			mx += cam->rho0[idx[n]][ch];
			my += cam->rho_r[idx[n]][ch];
		}
		mx /= f->n;
		my /= f->n;
		for (int n = 0; n < f->n; n++) {
			double dx = cam->rho0[idx[n]][ch] - mx;
			sxx += dx * dx;
			sxy += dx * (cam->rho_r[idx[n]][ch] - my);
		}
		double a = sxx > 0 ? sxy / sxx : NAN, b = my - a * mx;
		for (int n = 0; n < f->n; n++) {
			double r = cam->rho_r[idx[n]][ch] - (b + a * cam->rho0[idx[n]][ch]);
			rss += r * r;
		}
		f->offset[ch] = b;
		f->slope[ch] = a * ref->field_flare.slope[ch];
		f->white_fraction[ch] = f->slope[ch] > 0 ? b / f->slope[ch] : NAN;
		f->residual[ch] = f->slope[ch] > 0 && f->n > 2 ? sqrt(rss / (f->n - 2)) / f->slope[ch]
		                                               : NAN;
		if (!(f->slope[ch] > 0))
			f->found = 0;
	}
	if (!f->found)
		return 0;
	double limit = opt->max_flare > 0 ? opt->max_flare : KG_CALIB_MAX_FLARE;
	if (kg_flare_max_fraction(f) > limit)
		return kg_fail(err, KG_EINVAL,
		               "%s: flare: the chart's %d neutral patches (%s .. %s) meet zero at "
		               "%.1f %% (R), %.1f %% (G), %.1f %% (B) of white, above the %.1f %% a "
		               "calibration can trust (light scattered in the lens: shade the lens "
		               "and the chart from the light source and the sky)",
		               what, f->n, f->ids[0], f->ids[f->n - 1], 100 * f->white_fraction[0],
		               100 * f->white_fraction[1], 100 * f->white_fraction[2], 100 * limit);
	for (int i = 0; i < cam->k; i++)
		for (int ch = 0; ch < 3; ch++)
			cam->rho_r[i][ch] = fmax(cam->rho_r[i][ch] - f->offset[ch], 0);
	cam->flare_removed = 1;
	return 0;
}

int kg_camera_fit(const kg_reference *ref, const kg_patchset *site,
                  const kg_camera_options *opt, kg_camera_calib **out, kg_err *err)
{
	kg_check_arg(ref && site && out, err);
	*out = NULL;
	kg_camera_options defaults;
	if (!opt) {
		kg_camera_options_default(&defaults);
		opt = &defaults;
	}
	const char *what = site->source ? site->source : "site chart";
	int ret = check_options(opt, err);
	if (ret)
		return ret;
	if (!site->rgb)
		return kg_fail(err, KG_EINVAL, "%s: expected fields RGB_R RGB_G RGB_B", what);

	int *idx_ref = malloc((ref->k > 0 ? (size_t)ref->k : 1) * sizeof(int));
	int *idx_site = malloc((ref->k > 0 ? (size_t)ref->k : 1) * sizeof(int));
	double *clipped = NULL;
	kg_camera_calib *cam = calloc(1, sizeof(*cam));
	int k = 0;
	if (!idx_ref || !idx_site || !cam) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto error;
	}
	const char *id_rule = NULL;
	ret = match_patches(ref, site, opt, what, idx_ref, idx_site, &k, &id_rule, &cam->pairing,
	                    err);
	if (!ret && id_rule)
		snprintf(cam->id_rule, sizeof(cam->id_rule), "%s", id_rule);
	if (!ret)
		ret = drop_flagged(site, what, idx_ref, idx_site, &k, ref, cam, err);
	if (ret)
		goto error;

	cam->k = k;
	cam->ids = calloc((size_t)k, sizeof(char *));
	cam->rho_r = malloc((size_t)k * sizeof(*cam->rho_r));
	cam->rho0 = malloc((size_t)k * sizeof(*cam->rho0));
	cam->residual = malloc((size_t)k * sizeof(*cam->residual));
	if (!cam->ids || !cam->rho_r || !cam->rho0 || !cam->residual) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto error;
	}
	int stride = 0;
	const double *clip = calib_clipped_column(site, &stride);
	if (clip && !(clipped = malloc((size_t)k * sizeof(double)))) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto error;
	}
	for (int i = 0; i < k; i++) {
		if (!(cam->ids[i] = strdup(ref->field_ids[idx_ref[i]]))) {
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
			goto error;
		}
		memcpy(cam->rho_r[i], site->rgb[idx_site[i]], sizeof(cam->rho_r[i]));
		memcpy(cam->rho0[i], ref->rho0[idx_ref[i]], sizeof(cam->rho0[i]));
		if (clipped)
			clipped[i] = clip[(size_t)idx_site[i] * stride];
	}
	ret = calib_check_patch_values(what, cam->ids, (const double (*)[3])cam->rho_r, clipped,
	                               k, opt->clip_level, opt->black_level, err);
	if (!ret)
		ret = site_flare(ref, cam, opt, what, err);
	if (ret)
		goto error;
	ret = calib_check_collinear(what, cam->ids, (const double (*)[3])cam->rho_r, k,
	                            opt->max_cond, &cam->cond, &cam->cond_equilibrated,
	                            cam->singular_values, err);
	if (ret)
		goto error;
	ret = solve_m2(cam, opt->pinv_rtol, err);
	if (!ret)
		ret = drop_misfits(cam, opt, err);
	if (!ret)
		ret = check_residual(cam, opt, what, err);
	if (!ret || ret == KG_EINVAL) {
		int refused = ret;
		ret = check_site_patches(ref, site, opt, what, cam, refused != 0, err);
		ret = refused ? refused : ret;
	}
	if (ret)
		goto error;

	cam->K = ref->K;
	cam->centred = ref->centred;
	memcpy(cam->B, ref->B, sizeof(cam->B));
	memcpy(cam->mean, ref->mean, sizeof(cam->mean));
	memcpy(cam->M, ref->M, sizeof(cam->M));
	memcpy(cam->rgb_mean, ref->rgb_mean, sizeof(cam->rgb_mean));
	cam->method = ref->method;
	cam->response = ref->response;
	for (int j = 0; j < KG_METHOD_COUNT; j++)
		site_map_from(&ref->maps[j], cam->M2, &cam->maps[j]);
	calib_camera_derive(cam);
	free(idx_ref);
	free(idx_site);
	free(clipped);
	*out = cam;
	return 0;

error:
	free(idx_ref);
	free(idx_site);
	free(clipped);
	kg_camera_calib_free(&cam);
	return ret;
}

int kg_camera_fit_files(const char *reference_path, const char *site_rgb_path,
                        const kg_camera_options *opt, kg_camera_calib **out, kg_err *err)
{
	kg_check_arg(reference_path && site_rgb_path && out, err);
	*out = NULL;
	kg_reference *ref = NULL;
	kg_patchset *site = NULL;
	kg_camera_calib *cam = NULL;
	int ret = kg_reference_load(reference_path, &ref, err);
	if (ret == 0)
		ret = calib_check_encoding(site_rgb_path, err);
	if (ret == 0)
		ret = kg_patchset_read(site_rgb_path, 0, &site, err);
	if (ret == 0 && !site->source && !(site->source = strdup(site_rgb_path)))
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	if (ret == 0)
		ret = kg_camera_fit(ref, site, opt, &cam, err);
	if (ret == 0)
		ret = calib_source_add(&cam->sources, &cam->nsources, "reference", reference_path,
		                       err);
	if (ret == 0)
		ret = calib_source_add(&cam->sources, &cam->nsources, "site_rgb", site_rgb_path, err);
	if (ret == 0) {
		const kg_calib_source *src = &cam->sources[cam->nsources - 1];
		ret = kg_camera_identity_from_keywords(site_rgb_path, src->keyword_names,
		                                       src->keyword_values, src->nkeywords,
		                                       &cam->identity, err);
	}
	kg_reference_free(&ref);
	kg_patchset_free(&site);
	if (ret) {
		kg_camera_calib_free(&cam);
		return ret;
	}
	*out = cam;
	return 0;
}

int kg_camera_set_method(kg_camera_calib *cam, kg_method m, kg_err *err)
{
	kg_check_arg(cam && m >= 0 && m < KG_METHOD_COUNT, err);
	if (!cam->maps[m].available)
		return kg_fail(err, KG_EINVAL,
		               "method %s was not available on the reference chart", kg_method_name(m));
	cam->method = m;
	return 0;
}

int kg_camera_site_map(const kg_camera_calib *cam, kg_method m, const kg_site_map **out,
                       kg_err *err)
{
	kg_check_arg(cam && out && m >= KG_METHOD_AUTO && m < KG_METHOD_COUNT, err);
	if (m == KG_METHOD_AUTO)
		m = cam->method;
	if (!cam->maps[m].available)
		return kg_fail(err, KG_EINVAL,
		               "method %s was not available on the reference chart", kg_method_name(m));
	*out = &cam->maps[m];
	return 0;
}

void kg_camera_residual_cov(const kg_camera_calib *cam, double R[9])
{
	memset(R, 0, 9 * sizeof(double));
	int used = 0;
	double level = 0;
	for (int i = 0; cam && i < cam->k; i++) {
		const double *r = cam->residual[i], *x = cam->rho0[i];
		double l2 = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) / 3.0;
		if (!(l2 > 0) || !isfinite(r[0] + r[1] + r[2]))
			continue;
		for (int a = 0; a < 3; a++)
			for (int b = 0; b < 3; b++)
				R[3 * a + b] += r[a] * r[b];
		level += l2;
		used++;
	}
	/* relative to the patches' mean square level (as residual_relative is), over the
	 * k - 3 degrees of freedom each channel's row of M2 leaves */
	double scale = used > 3 && level > 0 ? (double)used / ((used - 3) * level) : 0.0;
	for (int e = 0; e < 9; e++)
		R[e] *= scale;
}

const char *kg_camera_reference_sha256(const kg_camera_calib *cam)
{
	for (int i = 0; cam && i < cam->nsources; i++)
		if (cam->sources[i].role && strcmp(cam->sources[i].role, "reference") == 0)
			return cam->sources[i].sha256;
	return "";
}
