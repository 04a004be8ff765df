/* Camera-space label maps: regions, connected components of the per-pixel classes
 * found as the rows stream past, or a user's region map, and their decisions. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "labels_cam_private.h"

/* ---- regions ----------------------------------------------------------------------- */

void lc_regions_free(regions *g)
{
	free(g->parent);
	free(g->label);
	free(g->count);
	free(g->d2);
	free(g->f_sum);
	free(g->comp);
	free(g->prev);
	free(g->cur);
	free(g->final);
	free(g->q999);
	free(g->min_px);
	free(g->merged);
	memset(g, 0, sizeof(*g));
}

int lc_regions_grow(regions *g, uint32_t need, kg_err *err)
{
	if (need <= g->cap)
		return 0;
	uint32_t cap = g->cap ? g->cap : 4096;
	while (cap < need)
		cap *= 2;
	uint32_t *p = realloc(g->parent, sizeof(uint32_t) * cap);
	if (p)
		g->parent = p;
	uint8_t *l = realloc(g->label, cap);
	if (l)
		g->label = l;
	uint64_t *c = realloc(g->count, sizeof(uint64_t) * cap);
	if (c)
		g->count = c;
	double *d = realloc(g->d2, sizeof(double) * (size_t)cap * (size_t)g->nm);
	if (d)
		g->d2 = d;
	double *f = realloc(g->f_sum, sizeof(double) * cap);
	if (f)
		g->f_sum = f;
	double *cm = realloc(g->comp, sizeof(double) * 6 * cap);
	if (cm)
		g->comp = cm;
	if (!p || !l || !c || !d || !f || !cm)
		return kg_fail(err, KG_ENOMEM, "classify: out of memory for the regions");
	g->cap = cap;
	return 0;
}

uint32_t lc_find_root(uint32_t *parent, uint32_t a)
{
	while (parent[a] != a) {
		parent[a] = parent[parent[a]];
		a = parent[a];
	}
	return a;
}

static void unite(regions *g, uint32_t a, uint32_t b)
{
	a = lc_find_root(g->parent, a);
	b = lc_find_root(g->parent, b);
	if (a < b)
		g->parent[b] = a;
	else if (b < a)
		g->parent[a] = b;
}

uint32_t lc_new_id(regions *g, uint8_t label)
{
	uint32_t id = g->n++;
	g->parent[id] = id;
	g->label[id] = label;
	g->count[id] = 0;
	g->f_sum[id] = 0;
	memset(g->comp + 6 * (size_t)id, 0, 6 * sizeof(double));
	memset(g->d2 + (size_t)id * g->nm, 0, sizeof(double) * (size_t)g->nm);
	return id;
}

/* The runs of one row of labels (classes 1..nc only), each given a provisional id when
 * assign is set (pass 1) or in the same order again (pass 2). */
int lc_row_runs(const uint8_t *lab, int width, int nc, run_seg *out)
{
	int n = 0;
	for (int x = 0; x < width;) {
		uint8_t l = lab[x];
		int x1 = x;
		while (x1 + 1 < width && lab[x1 + 1] == l)
			x1++;
		if (l >= 1 && l <= nc)
			out[n++] = (run_seg){x, x1, 0, l};
		x = x1 + 1;
	}
	return n;
}

/* Link the current row's runs to the previous row's (ids given in order from *next). */
void lc_link_rows(regions *g, run_seg *cur, int ncur, const run_seg *prev, int nprev,
                      int assign)
{
	int p = 0;
	for (int i = 0; i < ncur; i++) {
		if (assign)
			cur[i].id = lc_new_id(g, cur[i].label);
		else
			cur[i].id = g->n++;
		while (p < nprev && prev[p].x1 < cur[i].x0)
			p++;
		for (int q = p; q < nprev && prev[q].x0 <= cur[i].x1; q++)
			if (prev[q].label == cur[i].label && assign)
				unite(g, cur[i].id, prev[q].id);
	}
}

/* A pixel's composition into a region's sums (inverse-variance weights). */
static void add_comp(double *acc, const float *c)
{
	for (int q = 0; q < 3; q++) {
		double sd = c[3 + q];
		if (!isfinite(c[q]) || !isfinite(sd))
			continue;
		double w = 1.0 / (sd > 1e-6 ? sd * sd : 1e-12);
		acc[q] += w * c[q];
		acc[3 + q] += w;
	}
}

/* Pass 1, one row: its runs, their unions, and each pixel's distances added to its
 * run's sums. */
int lc_regions_row(regions *g, const uint8_t *lab, const float *d2, const float *fshare,
                       const float *comp, int nc, kg_err *err)
{
	if (!g->on || g->overflow)
		return 0;
	g->ncur = lc_row_runs(lab, g->width, nc, g->cur);
	if (g->n + (uint32_t)g->ncur > MAX_PROVISIONAL) {
		g->overflow = 1;
		return 0;
	}
	int rc = lc_regions_grow(g, g->n + (uint32_t)g->ncur, err);
	if (rc)
		return rc;
	lc_link_rows(g, g->cur, g->ncur, g->prev, g->nprev, 1);
	for (int i = 0; i < g->ncur; i++) {
		run_seg *s = &g->cur[i];
		double *acc = g->d2 + (size_t)s->id * g->nm;
		for (int x = s->x0; x <= s->x1; x++) {
			const float *d = d2 + (size_t)x * g->nm;
			for (int j = 0; j < g->nm; j++)
				acc[j] += d[j];
			g->f_sum[s->id] += fshare[x];
			add_comp(g->comp + 6 * (size_t)s->id, comp + 6 * (size_t)x);
		}
		g->count[s->id] += (uint64_t)(s->x1 - s->x0 + 1);
	}
	run_seg *t = g->prev;
	g->prev = g->cur;
	g->cur = t;
	g->nprev = g->ncur;
	return 0;
}

/* User regions: ids straight from the map. */
int lc_regions_user_row(regions *g, int y, const float *ids, const uint8_t *lab,
                            const float *d2, const float *fshare, const float *comp, int nc,
                            kg_err *err)
{
	for (int x = 0; x < g->width; x++) {
		double v = ids[x] * g->user_scale, rv = floor(v + 0.5);
		if (!(rv >= 0 && rv < MAX_USER_REGIONS) || fabs(v - rv) > 1e-3)
			return kg_fail(err, KG_EINVAL, "%s: pixel (%d, %d) holds %g: expected a whole "
			               "region number from 0 (none) to %d",
			               g->user_name ? g->user_name : "the region map", x, y, v,
			               MAX_USER_REGIONS - 1);
		uint32_t id = (uint32_t)rv;
		if (!id || lab[x] < 1 || lab[x] > nc)
			continue;
		double *acc = g->d2 + (size_t)id * g->nm;
		const float *d = d2 + (size_t)x * g->nm;
		for (int j = 0; j < g->nm; j++)
			acc[j] += d[j];
		g->f_sum[id] += fshare[x];
		add_comp(g->comp + 6 * (size_t)id, comp + 6 * (size_t)x);
		g->count[id]++;
	}
	return 0;
}

/* Roots' sums, and region numbers in order of first appearance. */
int lc_regions_resolve(regions *g, kg_err *err)
{
	if (!(g->final = calloc(g->n ? g->n : 1, sizeof(uint32_t))))
		return kg_fail(err, KG_ENOMEM, "classify: out of memory for the regions");
	if (!g->user)
		for (uint32_t id = 0; id < g->n; id++) {
			uint32_t r = lc_find_root(g->parent, id);
			if (r == id)
				continue;
			g->count[r] += g->count[id];
			g->f_sum[r] += g->f_sum[id];
			for (int q = 0; q < 6; q++)
				g->comp[6 * (size_t)r + q] += g->comp[6 * (size_t)id + q];
			for (int j = 0; j < g->nm; j++)
				g->d2[(size_t)r * g->nm + j] += g->d2[(size_t)id * g->nm + j];
			g->count[id] = 0;
		}
	for (uint32_t id = 0; id < g->n; id++)
		if (g->count[id] && (g->user || lc_find_root(g->parent, id) == id)) {
			++g->nfinal;
			g->final[id] = g->user ? id : g->nfinal; /* a user map keeps its numbers */
		}
	return 0;
}

region_decision lc_decide(const regions *g, uint32_t id, const int *group, int nc)
{
	const double *D = g->d2 + (size_t)id * g->nm;
	double N = (double)g->count[id], lev = g->f_sum[id] / N;
	/* the comparison between materials: the calibration's error is one error for the
	 * whole region */
	double s = 1.0 / (1.0 + N * lev * g->cal_tr);
	double dmin = INFINITY, pc[KG_EST_MAX_MATERIALS] = {0}, sum = 0, w[KG_EST_MAX_MATERIALS];
	for (int j = 0; j < g->nm; j++)
		dmin = fmin(dmin, D[j]);
	for (int j = 0; j < g->nm; j++) {
		w[j] = exp_or_zero(-0.5 * s * (D[j] - dmin));
		sum += w[j];
		pc[group[j]] += w[j];
	}
	region_decision r = {0, 0, -1, 0, 0};
	for (int c = 1; c < nc; c++)
		if (pc[c] > pc[r.cls])
			r.cls = c;
	int jbest = -1, members = 0;
	for (int j = 0; j < g->nm; j++)
		if (group[j] == r.cls) {
			members++;
			if (jbest < 0 || w[j] > w[jbest])
				jbest = j;
		}
	r.posterior = pc[r.cls] / sum;
	if (members == 1 || w[jbest] / pc[r.cls] >= RESOLVE_POSTERIOR) {
		r.material = jbest;
		r.posterior = w[jbest] / sum;
	}
	r.d2_mean = D[jbest] / N;
	/* the pooled unknown test: the decided member's summed d2 against chi-square with
	 * dof N s degrees of freedom (its 99.9 % point; Wilson-Hilferty above 1000), s
	 * now with the material's own model error beside the calibration's: both are one
	 * error for the whole region. (The model error is left out of the comparison
	 * between materials: the published constants' spread moves the predictions of
	 * every material made of the same metals together.) */
	s = 1.0 / (1.0 + N * lev * (g->cal_tr + (g->model_tr ? g->model_tr[jbest] : 0.0)));
	double dof = ceil(g->dof * N * s), q;
	if (dof <= 1000) {
		/* one bisection per degree of freedom, not per region */
		double *qc = &g->q999[(int)dof];
		if (!(*qc > 0))
			*qc = kg_chi2_quantile(0.999, (int)dof);
		q = *qc;
	}
	else {
		double h = 2.0 / (9.0 * dof), z = 3.090232306167813;
		q = dof * pow(1.0 - h + z * sqrt(h), 3.0);
	}
	r.unknown = s * D[jbest] > q;
	return r;
}

double lc_small_min_pixels(const regions *g, const int *group, int c, int host)
{
	double d = INFINITY;
	for (int i = 0; i < g->nm; i++) {
		if (group[i] != c)
			continue;
		if ((host == -1 || host == -2) && g->flat_sep)
			d = fmin(d, g->flat_sep[i]);
		for (int j = 0; j < g->nm && g->sep; j++) {
			int alt = host == -2 || (host >= 0 && group[j] == host) || host == -3 - j;
			if (group[j] != c && alt)
				d = fmin(d, g->sep[(size_t)i * g->nm + j]);
		}
	}
	return kg_cs_pixels_for(d); /* 0 for +Inf: no alternative */
}

/* A region's composition: inverse-variance means of its pixels' fractions, their sds
 * widened by sqrt(1 + N f) (the calibration's error does not average out). out: 3
 * fractions, 3 sds, NaN without data; gold NaN where its sd is not below gold_range. */
void lc_region_composition(const regions *g, uint32_t id, double gold_range, double out[6])
{
	const double *a = g->comp + 6 * (size_t)id;
	double N = (double)g->count[id], f = g->f_sum[id] / N * g->cal_tr;
	for (int q = 0; q < 3; q++) {
		out[q] = a[3 + q] > 0 ? a[q] / a[3 + q] : NAN;
		out[3 + q] = a[3 + q] > 0 ? sqrt((1.0 + N * f) / a[3 + q]) : NAN;
	}
	if (!(out[5] < gold_range))
		out[2] = NAN;
}

const char *lc_region_label(const region_decision *d, const kg_est_material_set *set,
                                const kg_est_material_set *classes)
{
	return d->unknown ? "unknown" : d->material >= 0 ? set->names[d->material]
	                                                 : classes->names[d->cls];
}

/* A connected region's pixels' class beside its decision, and why they differ:
 * "pixel_class", "differs", "why" (null when they agree). The label map shows the
 * pixels' classes; the decision is the table's. */
void lc_region_why(json_t *row, const regions *g, uint32_t id, const region_decision *d,
                   const char *label, double merged_min, const kg_est_material_set *classes)
{
	if (g->user || g->label[id] == 0 || g->label[id] > classes->n)
		return;
	const char *px = classes->names[g->label[id] - 1];
	int differs = strcmp(px, label) != 0;
	char why[320];
	if (!differs)
		why[0] = 0;
	else if (merged_min > 0 && !strcmp(label, "unknown"))
		snprintf(why, sizeof(why), "too small for the noise: %llu pixels, fewer than the "
		         "%.0f a pooled decision for %s needs against its nearest alternative "
		         "(1 %% error), amid nothing decided: unknown",
		         (unsigned long long)g->count[id], merged_min, px);
	else if (merged_min > 0)
		snprintf(why, sizeof(why), "too small for the noise: %llu pixels, fewer than the "
		         "%.0f a pooled decision between %s and %s needs (1 %% error), so it takes "
		         "%s from its surroundings", (unsigned long long)g->count[id], merged_min,
		         px, label, label);
	else if (d->unknown)
		snprintf(why, sizeof(why), "refused as unknown on the pooled test: its pixels' mean "
		         "d2 against the nearest material is %.2f (%d expected), a misfit that, "
		         "pooled over %llu pixels, exceeds the bound; each pixel alone reads %s",
		         d->d2_mean, g->dof, (unsigned long long)g->count[id], px);
	else if (kg_class_holds(px, label))
		snprintf(why, sizeof(why), "resolved: the pooled pixels single out %s within the "
		         "merged class %s (its share of the class's posterior >= %.2f)", label, px,
		         RESOLVE_POSTERIOR);
	else
		snprintf(why, sizeof(why), "the pooled likelihood of its pixels prefers %s to %s, "
		         "which each pixel alone reads", label, px);
	json_object_set_new(row, "pixel_class", json_string(px));
	json_object_set_new(row, "differs", json_boolean(differs));
	json_object_set_new(row, "why", differs ? json_string(why) : json_null());
}
