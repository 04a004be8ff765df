/* Camera-space label maps: the sink of the run's blocks, and the region map and table
 * written after it (pass 2). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "labels_cam_private.h"

/* ---- the sink -------------------------------------------------------------------- */

int lc_cam_sink_fn(void *user, const kg_est_block *b, kg_err *err)
{
	cam_sink *s = user;
	const cam_run *r = s->run;
	size_t n = (size_t)b->rows * b->width;
	uint8_t *lab = (uint8_t *)b->data;
	const float *margin = b->confidence;
	planes pl = ap_feed_planes(&r->in, b->input, n);
	cam_planes cp = lc_cam_planes_of(r, (void *)b->input, n);
	if (n > s->conf4_cap) {
		float *c = realloc(s->conf4, sizeof(float) * 4 * n);
		if (!c)
			return kg_fail(err, KG_ENOMEM, "classify: out of memory");
		s->conf4 = c;
		s->conf4_cap = n;
	}
	for (size_t i = 0; i < n; i++) {
		s->count[lab[i]]++;
		float *c4 = s->conf4 + 4 * i;
		c4[0] = margin[i];
		c4[1] = cp.post[i];
		c4[2] = cp.angle[i];
		c4[3] = cp.scale[i];
		if (lab[i] == KG_EST_LABEL_NONE || lab[i] > s->nclasses)
			continue;
		int bad = ap_class_stats_add(&s->cs[lab[i] - 1], margin[i], pl.raw + 3 * i, err);
		if (bad)
			return bad;
	}
	int rc = 0;
	if (s->reg.on)
		for (int y = 0; y < b->rows && !rc; y++) {
			size_t o = (size_t)y * b->width;
			const float *fshare = cp.fshare + o;
			const float *d2 = cp.d2 + o * (size_t)r->nm;
			if (s->reg.user) {
				rc = s->region_map->read(s->region_map->user, b->y0 + y, 1, s->region_row, err);
				if (!rc)
					rc = lc_regions_user_row(&s->reg, b->y0 + y, s->region_row, lab + o, d2,
					                      fshare, cp.comp + 6 * o, s->nclasses, err);
			} else {
				rc = lc_regions_row(&s->reg, lab + o, d2, fshare, cp.comp + 6 * o, s->nclasses,
				                 err);
			}
		}
	if (rc)
		return rc;
	ap_preview_rows(s->preview, s->pw, s->ph, &s->next_py, s->height, b, lab);
	if (s->comp) {
		/* gold only where its sd is below the declared range */
		for (size_t i = 0; i < n; i++)
			if (!(cp.comp[6 * i + 5] < r->gold_range))
				cp.comp[6 * i + 2] = NAN;
		rc = kg_envi_writer_put(s->comp, b->y0, b->y0 + b->rows, KG_LAYOUT_BIP, cp.comp, err);
		if (rc)
			return rc;
	}
	rc = ap_put_bytes(s->labels, &s->stage, b, lab, err);
	if (!rc)
		rc = kg_envi_writer_put(s->conf, b->y0, b->y0 + b->rows, KG_LAYOUT_BIP, s->conf4, err);
	if (!rc)
		rc = ap_put_bytes(s->mask, &s->stage, b, b->mask, err);
	ap_progress_rows(&s->prog, b->y0 + b->rows);
	return rc;
}

/* ---- region map and table (pass 2) ------------------------------------------------- */

/* The material map's classes: the label map's (0 unclassified, the classes, unknown,
 * background), then the materials regions resolved to that are no class of their own
 * (a member of a compound class). of[f]: region f's label in that list; mat[l]: the
 * material of an added label. */
typedef struct mat_classes {
	int n;
	const char *names[256];
	unsigned char lookup[3 * 256];
	int mat[256];
	uint16_t *of; /* [nfinal + 1] */
} mat_classes;

static int material_classes(regions *g, const kg_est_material_set *set,
                            const kg_est_material_set *classes, const int *group,
                            const char *mat_hdr, mat_classes *mc, kg_err *err)
{
	const int nlab = classes->n + 3;
	mc->n = nlab;
	for (int l = 0; l < nlab; l++) {
		mc->names[l] = ap_label_name(classes, l);
		ap_label_colour(classes, l, mc->lookup + 3 * l);
		mc->mat[l] = -1;
	}
	if (!(mc->of = calloc((size_t)g->nfinal + 1, sizeof(uint16_t))))
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (uint32_t id = 0; id < g->n; id++) {
		uint32_t f = g->final[id];
		if (!f)
			continue;
		region_decision d = lc_decide(g, id, group, classes->n);
		const char *name = lc_region_label(&d, set, classes);
		int l = -1;
		for (int k = 0; k < mc->n && l < 0; k++)
			if (!strcmp(mc->names[k], name))
				l = k;
		if (l < 0) {
			if (mc->n >= 256)
				return kg_fail(err, KG_EINVAL, "%s: the regions resolve to more materials "
				               "than a label map holds (256 classes)", mat_hdr);
			l = mc->n++;
			mc->names[l] = name;
			mc->mat[l] = d.material;
			ap_class_colour(d.material >= 0 ? d.material : l, mc->lookup + 3 * l);
		}
		mc->of[f] = (uint16_t)l;
	}
	return 0;
}

/* The written labels again, row by row, each pixel with its region's number: pass 1's
 * runs found again in the same order, so each gets its provisional id and its root's
 * number. g->n counts the ids anew while it is open. */
typedef struct id_rows {
	regions *g;
	kg_envi *el;
	int W, H, y, na, nc;
	uint32_t saved_n;
	float *lab;
	run_seg *a, *b;
} id_rows;

static void id_rows_close(id_rows *r)
{
	if (r->g)
		r->g->n = r->saved_n;
	kg_envi_close(&r->el);
	free(r->lab);
	free(r->a);
	free(r->b);
	memset(r, 0, sizeof(*r));
}

static int id_rows_open(id_rows *r, regions *g, int nc, const char *labels_hdr, kg_err *err)
{
	memset(r, 0, sizeof(*r));
	int rc = kg_envi_open(labels_hdr, &r->el, err);
	if (rc)
		return rc;
	r->W = g->width;
	r->H = r->el->meta.lines;
	r->nc = nc;
	r->lab = malloc(sizeof(float) * (size_t)r->W);
	r->a = malloc(sizeof(run_seg) * ((size_t)r->W + 1));
	r->b = malloc(sizeof(run_seg) * ((size_t)r->W + 1));
	if (!r->lab || !r->a || !r->b) {
		id_rows_close(r);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	r->g = g;
	r->saved_n = g->n;
	g->n = 0;
	return 0;
}

/* The next row: its labels and each pixel's region number (0: none). */
static int id_rows_next(id_rows *r, uint8_t *lab8, uint32_t *ids, kg_err *err)
{
	int rc = kg_envi_read(r->el, 0, r->y++, r->W, 1, KG_LAYOUT_BIP, r->lab, err);
	if (rc)
		return rc;
	for (int x = 0; x < r->W; x++) {
		lab8[x] = (uint8_t)r->lab[x];
		ids[x] = 0;
	}
	int nb = lc_row_runs(lab8, r->W, r->nc, r->b);
	lc_link_rows(r->g, r->b, nb, r->a, r->na, 0);
	for (int i = 0; i < nb; i++) {
		uint32_t f = r->g->final[lc_find_root(r->g->parent, r->b[i].id)];
		for (int x = r->b[i].x0; x <= r->b[i].x1; x++)
			ids[x] = f;
	}
	run_seg *t = r->a;
	r->a = r->b;
	r->b = t;
	r->na = nb;
	return 0;
}

/* Regions too small for the noise. A region of class c is decided on its pooled
 * distances; against an alternative at separability d its decision errs 1 % of the
 * time or less only from kg_cs_pixels_for(d) = (2 z_99 / d)^2 pixels on (the pooled
 * difference grows as N d^2, its standard deviation as 2 d sqrt(N)). A region smaller
 * than that against the nearest of every alternative (another class, the
 * neutral-diffuse background) is a candidate; its surroundings are the label most of
 * its border holds (its 4-neighbours outside it: the material map's label of a region
 * that is no candidate, or a pixel's own unknown or background; unclassified pixels
 * and other candidates do not count). Smaller than what it needs against that label,
 * it takes the label (the material map's pixels); with no such border, or amid unknown
 * pixels, it is unknown. Counts per candidate: the first SMALL_SLOTS labels its border
 * meets. */
#define SMALL_SLOTS 8

static void small_tally(uint16_t *key, uint32_t *cnt, uint16_t l)
{
	for (int s = 0; s < SMALL_SLOTS; s++) {
		if (cnt[s] && key[s] != l)
			continue;
		key[s] = l;
		cnt[s]++;
		return;
	}
}

static int small_regions(regions *g, const int *group, int nc, const char *labels_hdr,
                         mat_classes *mc, kg_err *err)
{
	const uint32_t nf = g->nfinal;
	const int W = g->width;
	small_stats *st = &g->small;
	memset(st, 0, sizeof(*st));
	uint64_t *npx = calloc((size_t)nf + 1, sizeof(uint64_t));
	uint8_t *cls = calloc((size_t)nf + 1, 1);
	uint32_t *cand = calloc((size_t)nf + 1, sizeof(uint32_t));
	g->min_px = calloc((size_t)nf + 1, sizeof(double));
	g->merged = calloc((size_t)nf + 1, sizeof(*g->merged));
	uint8_t *lab = malloc(3 * (size_t)W);
	uint32_t *ids = malloc(3 * sizeof(uint32_t) * (size_t)W);
	uint16_t *key = NULL;
	uint32_t *cnt = NULL;
	int rc = 0;
	if (!npx || !cls || !cand || !g->min_px || !g->merged || !lab || !ids)
		rc = kg_fail(err, KG_ENOMEM, "out of memory for the regions");
	for (uint32_t id = 0; id < g->n && !rc; id++)
		if (g->final[id]) {
			npx[g->final[id]] = g->count[id];
			cls[g->final[id]] = (uint8_t)(g->label[id] - 1);
		}
	uint32_t ncand = 0;
	for (uint32_t f = 1; f <= nf && !rc; f++) {
		g->min_px[f] = lc_small_min_pixels(g, group, cls[f], -2);
		if ((double)npx[f] < g->min_px[f])
			cand[f] = ++ncand;
		st->one_pixel += npx[f] == 1;
	}
	if (!rc && ncand) {
		key = calloc((size_t)ncand * SMALL_SLOTS, sizeof(uint16_t));
		cnt = calloc((size_t)ncand * SMALL_SLOTS, sizeof(uint32_t));
		if (!key || !cnt)
			rc = kg_fail(err, KG_ENOMEM, "out of memory for the regions");
	}
	/* the border tally: row y - 1 (cur) once row y (next) is read */
	id_rows rr = {0};
	if (!rc && ncand)
		rc = id_rows_open(&rr, g, nc, labels_hdr, err);
	const int H = rr.H;
	for (int y = 0; !rc && ncand && y <= H; y++) {
		/* row y into slot y % 3: cur is row y - 1, prev row y - 2 */
		size_t on = (size_t)(y % 3) * W, oc = (size_t)((y + 2) % 3) * W,
		       op = (size_t)((y + 1) % 3) * W;
		uint8_t *nextl = lab + on, *curl = lab + oc, *prevl = lab + op;
		uint32_t *nexti = ids + on, *curi = ids + oc, *previ = ids + op;
		if (y < H && (rc = id_rows_next(&rr, nextl, nexti, err)))
			break;
		if (y == 0)
			continue;
		for (int x = 0; x < W; x++) {
			uint32_t f = curi[x];
			if (!f || !cand[f])
				continue;
			int nx[4] = {x - 1, x + 1, x, x};
			const uint8_t *nl[4] = {curl, curl, y >= 2 ? prevl : NULL,
			                        y < H ? nextl : NULL};
			const uint32_t *ni[4] = {curi, curi, previ, nexti};
			for (int q = 0; q < 4; q++) {
				if (nx[q] < 0 || nx[q] >= W || !nl[q])
					continue;
				uint32_t h = ni[q][nx[q]];
				uint8_t l = nl[q][nx[q]];
				if (h == f || (h && cand[h]) || (!h && (l == 0 || l > nc + 2)))
					continue;
				size_t o = (size_t)(cand[f] - 1) * SMALL_SLOTS;
				small_tally(key + o, cnt + o, h ? mc->of[h] : l);
			}
		}
	}
	id_rows_close(&rr);
	/* the decisions */
	for (uint32_t f = 1; f <= nf && !rc; f++) {
		if (!cand[f]) {
			st->one_pixel_kept += npx[f] == 1;
			continue;
		}
		size_t o = (size_t)(cand[f] - 1) * SMALL_SLOTS;
		int best = -1;
		for (int s = 0; s < SMALL_SLOTS; s++)
			if (cnt[o + s] && (best < 0 || cnt[o + s] > cnt[o + best]))
				best = s;
		int l = best < 0 ? nc + 1 : key[o + best];
		int host = l >= 1 && l <= nc ? l - 1
		           : l == nc + 2     ? -1
		           : l == nc + 1     ? -2
		                             : -3 - mc->mat[l];
		g->min_px[f] = lc_small_min_pixels(g, group, cls[f], host);
		if (!((double)npx[f] < g->min_px[f])) {
			st->one_pixel_kept += npx[f] == 1;
			continue;
		}
		mc->of[f] = (uint16_t)l;
		g->merged[f] = mc->names[l];
		st->regions++;
		st->pixels += npx[f];
		if (l == nc + 1) {
			st->unknown_regions++;
			st->unknown_pixels += npx[f];
		}
	}
	st->done = !rc;
	free(npx);
	free(cls);
	free(cand);
	free(lab);
	free(ids);
	free(key);
	free(cnt);
	return rc;
}

/* The region map of connected components (lc_write_region_map): each pixel its
 * region's number; beside it the material map, each region's pixels its label. */
int lc_write_region_map(regions *g, const kg_est_material_set *set,
                        const kg_est_material_set *classes, const int *group,
                        const char *labels_hdr, const char *reg_hdr, const char *mat_hdr,
                        written *done, kg_err *err)
{
	const int W = g->width;
	mat_classes mc = {0};
	kg_envi_writer *w = NULL, *mw = NULL;
	id_rows rr = {0};
	float *out = malloc(sizeof(float) * W), *mout = malloc(sizeof(float) * W);
	uint8_t *lab8 = malloc((size_t)W);
	uint32_t *ids = malloc(sizeof(uint32_t) * (size_t)W);
	int rc = 0;
	if (!out || !mout || !lab8 || !ids)
		rc = kg_fail(err, KG_ENOMEM, "out of memory");
	if (!rc)
		rc = material_classes(g, set, classes, group, mat_hdr, &mc, err);
	if (!rc)
		rc = small_regions(g, group, classes->n, labels_hdr, &mc, err);
	if (!rc)
		rc = id_rows_open(&rr, g, classes->n, labels_hdr, err);
	const int H = rr.H;
	if (!rc) {
		kg_envi_meta m = ap_envi_meta(W, H, 1, KG_ENVI_U32, KG_ENVI_BSQ,
		                              "kogei classify regions: region number per pixel (0: "
		                              "none), as in the regions table");
		rc = kg_envi_writer_open(reg_hdr, &m, &w, err);
	}
	if (!rc) {
		kg_envi_meta mm = ap_envi_meta(W, H, 1, KG_ENVI_U8, KG_ENVI_BSQ,
		                               "kogei classify materials: per pixel the material its "
		                               "region was decided (the regions table's label; a "
		                               "region too small for the noise its surroundings'); "
		                               "pixels in no region keep their class");
		mm.classes = mc.n;
		mm.class_names = mc.names;
		mm.class_lookup = mc.lookup;
		rc = kg_envi_writer_open(mat_hdr, &mm, &mw, err);
	}
	for (int y = 0; y < H && !rc; y++) {
		if ((rc = id_rows_next(&rr, lab8, ids, err)))
			break;
		for (int x = 0; x < W; x++) {
			out[x] = (float)ids[x];
			mout[x] = ids[x] ? (float)mc.of[ids[x]] : (float)lab8[x];
		}
		rc = kg_envi_writer_put(w, y, y + 1, KG_LAYOUT_BIP, out, err);
		if (!rc)
			rc = kg_envi_writer_put(mw, y, y + 1, KG_LAYOUT_BIP, mout, err);
	}
	id_rows_close(&rr);
	free(out);
	free(mout);
	free(lab8);
	free(ids);
	free(mc.of);
	if (!rc) {
		rc = kg_envi_writer_finish(&w, err);
		if (!rc)
			ap_written_add_envi(done, reg_hdr);
	}
	if (!rc) {
		rc = kg_envi_writer_finish(&mw, err);
		if (!rc)
			ap_written_add_envi(done, mat_hdr);
	}
	if (w)
		kg_envi_writer_abort(&w);
	if (mw)
		kg_envi_writer_abort(&mw);
	return rc;
}

/* The table of every region (CSV). */
int lc_write_region_table(const regions *g, const kg_est_material_set *set,
                              const kg_est_material_set *classes, const int *group,
                              double gold_range, const char *csv_path, written *done,
                              kg_err *err)
{
	kg_outfile of;
	int rc = kg_outfile_open(&of, csv_path, 0, err);
	if (rc)
		return rc;
	fprintf(of.fp, "region,pixels,class,label,posterior,mean_d2,ag,cu,au,sd_ag,sd_cu,sd_au,"
	        "min_pixels,merged\n");
	for (uint32_t id = 0; id < g->n; id++) {
		uint32_t f = g->final[id];
		if (!f)
			continue;
		region_decision d = lc_decide(g, id, group, classes->n);
		const char *merged = g->merged ? g->merged[f] : NULL;
		double c[6];
		lc_region_composition(g, id, gold_range, c);
		fprintf(of.fp, "%u,%llu,", f, (unsigned long long)g->count[id]);
		kg_csv_put(of.fp, classes->names[d.cls]);
		fputc(',', of.fp);
		kg_csv_put(of.fp, merged ? merged : lc_region_label(&d, set, classes));
		if (merged) /* too small to be decided: no pooled decision, no composition */
			fprintf(of.fp, ",,,,,,,,");
		else {
			fprintf(of.fp, ",%.6g,%.6g", d.posterior, d.d2_mean);
			for (int q = 0; q < 6; q++)
				if (isfinite(c[q]))
					fprintf(of.fp, ",%.4f", c[q]);
				else
					fprintf(of.fp, ",");
		}
		if (g->min_px && isfinite(g->min_px[f]))
			fprintf(of.fp, ",%.0f", g->min_px[f]);
		else
			fprintf(of.fp, ",");
		fprintf(of.fp, ",%d\n", merged != NULL);
	}
	rc = kg_outfile_commit(&of, err);
	if (!rc)
		ap_written_add(done, csv_path);
	return rc;
}
