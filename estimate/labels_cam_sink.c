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

/* The region map of connected components: pass 1's runs found again in the written
 * labels, in the same order, so each gets its provisional id and its root's number. */
/* The material map's classes: the label map's (0 unclassified, the classes, unknown,
 * background), then the materials regions resolved to that are no class of their own
 * (a member of a compound class). *mat_of[f]: region f's label in that list. */
typedef struct mat_classes {
	int n;
	const char *names[256];
	unsigned char lookup[3 * 256];
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
			ap_class_colour(d.material >= 0 ? d.material : l, mc->lookup + 3 * l);
		}
		mc->of[f] = (uint16_t)l;
	}
	return 0;
}

int lc_write_region_map(regions *g, const kg_est_material_set *set,
                        const kg_est_material_set *classes, const int *group,
                        const char *labels_hdr, const char *reg_hdr, const char *mat_hdr,
                        written *done, kg_err *err)
{
	const int W = g->width;
	kg_envi *el = NULL;
	kg_envi_writer *w = NULL;
	int rc = kg_envi_open(labels_hdr, &el, err);
	if (rc)
		return rc;
	const int H = el->meta.lines;
	kg_envi_meta m = ap_envi_meta(W, H, 1, KG_ENVI_U32, KG_ENVI_BSQ,
	                              "kogei classify regions: region number per pixel (0: "
	                              "none), as in the regions table");
	float *lab = malloc(sizeof(float) * W), *out = malloc(sizeof(float) * W);
	float *mout = malloc(sizeof(float) * W);
	uint8_t *lab8 = malloc((size_t)W);
	run_seg *a = malloc(sizeof(run_seg) * ((size_t)W + 1));
	run_seg *b = malloc(sizeof(run_seg) * ((size_t)W + 1));
	mat_classes mc = {0};
	kg_envi_writer *mw = NULL;
	if (!lab || !out || !mout || !lab8 || !a || !b)
		rc = kg_fail(err, KG_ENOMEM, "out of memory");
	if (!rc)
		rc = material_classes(g, set, classes, group, mat_hdr, &mc, err);
	if (!rc)
		rc = kg_envi_writer_open(reg_hdr, &m, &w, err);
	if (!rc) {
		kg_envi_meta mm = ap_envi_meta(W, H, 1, KG_ENVI_U8, KG_ENVI_BSQ,
		                               "kogei classify materials: per pixel the material its "
		                               "region was decided (the regions table's label); "
		                               "pixels in no region keep their class");
		mm.classes = mc.n;
		mm.class_names = mc.names;
		mm.class_lookup = mc.lookup;
		rc = kg_envi_writer_open(mat_hdr, &mm, &mw, err);
	}
	uint32_t saved_n = g->n;
	g->n = 0;
	int na = 0;
	for (int y = 0; y < H && !rc; y++) {
		rc = kg_envi_read(el, 0, y, W, 1, KG_LAYOUT_BIP, lab, err);
		if (rc)
			break;
		for (int x = 0; x < W; x++)
			lab8[x] = (uint8_t)lab[x];
		{
			int nb = lc_row_runs(lab8, W, classes->n, b);
			lc_link_rows(g, b, nb, a, na, 0);
			for (int x = 0; x < W; x++) {
				out[x] = 0;
				mout[x] = lab[x];
			}
			for (int i = 0; i < nb; i++) {
				uint32_t f = g->final[lc_find_root(g->parent, b[i].id)];
				for (int x = b[i].x0; x <= b[i].x1; x++) {
					out[x] = (float)f;
					mout[x] = (float)mc.of[f];
				}
			}
			run_seg *t = a;
			a = b;
			b = t;
			na = nb;
		}
		rc = kg_envi_writer_put(w, y, y + 1, KG_LAYOUT_BIP, out, err);
		if (!rc)
			rc = kg_envi_writer_put(mw, y, y + 1, KG_LAYOUT_BIP, mout, err);
	}
	g->n = saved_n;
	kg_envi_close(&el);
	free(lab);
	free(out);
	free(mout);
	free(lab8);
	free(a);
	free(b);
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
	fprintf(of.fp, "region,pixels,class,label,posterior,mean_d2,ag,cu,au,sd_ag,sd_cu,sd_au\n");
	for (uint32_t id = 0; id < g->n; id++) {
		uint32_t f = g->final[id];
		if (!f)
			continue;
		region_decision d = lc_decide(g, id, group, classes->n);
		double c[6];
		lc_region_composition(g, id, gold_range, c);
		fprintf(of.fp, "%u,%llu,", f, (unsigned long long)g->count[id]);
		kg_csv_put(of.fp, classes->names[d.cls]);
		fputc(',', of.fp);
		kg_csv_put(of.fp, lc_region_label(&d, set, classes));
		fprintf(of.fp, ",%.6g,%.6g", d.posterior, d.d2_mean);
		for (int q = 0; q < 6; q++)
			isfinite(c[q]) ? fprintf(of.fp, ",%.4f", c[q]) : fprintf(of.fp, ",");
		fprintf(of.fp, "\n");
	}
	rc = kg_outfile_commit(&of, err);
	if (!rc)
		ap_written_add(done, csv_path);
	return rc;
}
