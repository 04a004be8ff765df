/* Images to files: the per-class statistics of a classification (counts, mean spectra,
 * exact margin order statistics in bounded memory). */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "apply_private.h"

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

/* Pass 1: one pixel of a class, its margin and the RGB the kernel saw. */
int ap_class_stats_add(class_stats *c, float margin, const float *rgb, kg_err *err)
{
	if (!c->hi && !(c->hi = calloc(HIST_BINS, sizeof(uint32_t))))
		return kg_fail(err, KG_ENOMEM, "classify: out of memory for the margins");
	c->hi[ap_order_key(margin) >> 16]++;
	c->count++;
	c->margin_sum += margin;
	for (int ch = 0; ch < 3; ch++)
		c->rgb_sum[ch] += rgb[ch];
	return 0;
}
