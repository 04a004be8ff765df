/* Chart layouts as chart scenes: the glue between calib/'s kg_chart_layout and
 * sim/'s kg_sim_chart_card (see chart_scene_glue.h), for `kogei sim chart`. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_scene_glue.h"

/* Built-in test colours: hues on a golden-angle wheel at varied lightness and
 * saturation, and every sixth patch a neutral, as camera values. */
static void test_colour(int i, double white, double rgb[3])
{
	double level = 0.06 + 0.8 * fmod(0.37 + 0.618033988749895 * i * 0.5, 1.0);
	if (i % 6 == 5) {
		rgb[0] = rgb[1] = rgb[2] = white * level;
		return;
	}
	double hue = fmod(0.618033988749895 * i, 1.0) * 6.0, sat = 0.35 + 0.5 * ((i * 7) % 5) / 4.0;
	double f = hue - floor(hue), v = white * level;
	double p = v * (1 - sat), q = v * (1 - sat * f), t = v * (1 - sat * (1 - f));
	double tab[6][3] = {{v, t, p}, {q, v, p}, {p, v, t}, {p, q, v}, {t, p, v}, {v, p, q}};
	memcpy(rgb, tab[(int)hue % 6], sizeof(double) * 3);
}

void kg_cli_card_parts_free(kg_cli_card_parts *p)
{
	for (int i = 0; i < p->ntags; i++)
		free(p->bits[i]);
	free(p->bits);
	free(p->tags);
	free(p->patches);
	memset(p, 0, sizeof(*p));
}

/* A tag id of the family that the layout does not use, for the decoy frame. */
static int decoy_id(const kg_chart_layout *l, int id, int *taken, int ntaken)
{
	for (int cand = id + 100;; cand++) {
		int used = kg_chart_layout_find_tag(l, cand) >= 0;
		for (int k = 0; k < ntaken && !used; k++)
			used = taken[k] == cand;
		if (!used)
			return cand;
	}
}

/* The decoy has other tag ids and the colours in reverse order. */
int kg_cli_chart_card(const kg_chart_layout *l, const kg_patchset *spectra,
                      const kg_cli_card_options *o, kg_sim_chart_card *card,
                      kg_cli_card_parts *parts, kg_err *err)
{
	int decoy = o->decoy;
	memset(card, 0, sizeof(*card));
	memset(parts, 0, sizeof(*parts));
	card->size_mm[0] = l->width_mm;
	card->size_mm[1] = l->height_mm;
	card->paper = o->paper;
	card->ink = o->ink;
	parts->tags = calloc((size_t)l->ntags + 1, sizeof(*parts->tags));
	parts->bits = calloc((size_t)l->ntags + 1, sizeof(*parts->bits));
	parts->patches = calloc((size_t)l->npatches + 1, sizeof(*parts->patches));
	int *ids = calloc((size_t)l->ntags + 1, sizeof(int));
	if (!parts->tags || !parts->bits || !parts->patches || !ids) {
		free(ids);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	int ret = 0;
	for (int i = 0; i < l->ntags && !ret; i++) {
		int id = l->tags[i].id, total, border;
		if (decoy)
			id = decoy_id(l, id, ids, i);
		ids[i] = id;
		ret = kg_chart_tag_cells(l->family, id, &parts->bits[i], &total, &border, err);
		if (ret)
			break;
		parts->ntags = i + 1;
		double r[4];
		kg_chart_tag_footprint(l, i, r);
		kg_sim_chart_tag *t = &parts->tags[i];
		double c[4][2] = {{r[0], r[1]}, {r[0] + r[2], r[1]}, {r[0] + r[2], r[1] + r[3]},
		                  {r[0], r[1] + r[3]}};
		memcpy(t->corner_mm, c, sizeof(c));
		t->cells = total;
		t->bits = parts->bits[i];
	}
	free(ids);
	if (ret)
		return ret;
	int missing = 0;
	char missing_ids[256] = "";
	for (int i = 0; i < l->npatches; i++) {
		const kg_chart_patch *lp = &l->patches[i];
		kg_sim_chart_patch *p = &parts->patches[i];
		p->id = lp->id;
		memcpy(p->centre_mm, lp->center_mm, sizeof(p->centre_mm));
		memcpy(p->size_mm, lp->size_mm, sizeof(p->size_mm));
		int src = decoy ? l->npatches - 1 - i : i;
		if (spectra) {
			int k = kg_patchset_find(spectra, l->patches[src].id);
			if (k < 0 && l->patches[src].alias[0])
				k = kg_patchset_find(spectra, l->patches[src].alias);
			if (k < 0) {
				if (missing++ < 8)
					snprintf(missing_ids + strlen(missing_ids),
					         sizeof(missing_ids) - strlen(missing_ids), "%s%s",
					         missing > 1 ? ", " : "", l->patches[src].id);
				continue;
			}
			p->reflectance = &spectra->spectra[k];
		} else {
			test_colour(src, o->white_level, p->rgb);
		}
	}
	if (missing)
		return kg_fail(err, KG_EINVAL,
		               "%s: %d patch(es) of layout %s have no spectrum (matched by "
		               "SAMPLE_ID to the layout's ids or aliases): %s%s",
		               o->spectra_name ? o->spectra_name : "spectra", missing, l->name,
		               missing_ids, missing > 8 ? ", ..." : "");
	card->tags = parts->tags;
	card->ntags = parts->ntags;
	card->patches = parts->patches;
	card->npatches = l->npatches;
	if (decoy)
		return 0;
	if (o->occlude && !strcmp(o->occlude, "tags")) {
		if (l->ntags < 2)
			return kg_fail(err, KG_EINVAL, "--occlude tags: layout %s has %d tag(s)", l->name,
			               l->ntags);
		for (int k = 0; k < 2; k++) {
			double r[4];
			kg_chart_tag_footprint(l, k, r);
			double m = 0.05 * r[2];
			parts->occ[k] = (kg_sim_chart_occluder){r[0] - m, r[1] - m, r[0] + r[2] + m,
			                                        r[1] + r[3] + m, 0.04};
		}
		card->occluders = parts->occ;
		card->noccluders = 2;
	} else if (o->occlude && !strcmp(o->occlude, "patches")) {
		int n = l->npatches < 2 ? l->npatches : 2;
		double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY;
		for (int i = 0; i < n; i++) {
			const kg_chart_patch *p = &l->patches[i];
			x0 = fmin(x0, p->center_mm[0] - 0.5 * p->size_mm[0]);
			x1 = fmax(x1, p->center_mm[0] + 0.5 * p->size_mm[0]);
			y0 = fmin(y0, p->center_mm[1] - 0.5 * p->size_mm[1]);
			y1 = fmax(y1, p->center_mm[1] + 0.5 * p->size_mm[1]);
		}
		if (n) {
			parts->occ[0] = (kg_sim_chart_occluder){x0, y0, x1, y1, 0.04};
			card->occluders = parts->occ;
			card->noccluders = 1;
		}
	}
	if (o->glare && l->npatches) {
		/* An elongated highlight on the upper left part of a middle patch. */
		const kg_chart_patch *p = &l->patches[l->npatches / 2];
		parts->glare = (kg_sim_chart_glare){
		    {p->center_mm[0] - 0.2 * p->size_mm[0], p->center_mm[1] - 0.2 * p->size_mm[1]},
		    {0.15 * p->size_mm[0], 0.08 * p->size_mm[1]},
		    30.0,
		    0.6};
		card->glare = &parts->glare;
		card->nglare = 1;
	}
	return 0;
}
