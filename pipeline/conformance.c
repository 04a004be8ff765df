/* Imaging-quality analysis of the chart capture against ISO 19264-1 and FADGI 2023:
 * the records of OUTDIR/conformance.json (kg_pipeline.h, docs/report.md). Built from
 * the per-patch values of process.json's calibration.patches and the flat's
 * illuminance non-uniformity; no image is read here. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kg_pipeline.h"
#include "sfr.h"

/* One characteristic's limits: ISO 19264-1 levels A, B, C (inclusive, <=) and FADGI
 * 2023 stars 4, 3, 2, 1 (strict, <); NaN where no value was found. */
typedef struct limits {
	double iso[3];
	double fadgi[4];
} limits;

static const limits oecf_lim = {{2, 3, 4}, {1.5, 3, 4.5, 6}};
static const limits wb_lim = {{3, 4, 5}, {2, 4, 6, 8}};
static const limits noise_lim = {{1.6, 2, 2.2}, {1, 2, 3, 4}};
/* FADGI's percentages as published in its 2010 guidelines; ISO 19264-1's not found. */
static const limits nu_lim = {{NAN, NAN, NAN}, {1, 3, 5, INFINITY}};
/* colour accuracy: mean (ISO, FADGI), maximum (ISO), 90th percentile (FADGI) */
static const limits de_mean_lim = {{4, 5, 5}, {2, 3.5, 5, 6.5}};
static const limits de_max_lim = {{10, 15, 15}, {NAN, NAN, NAN, NAN}};
static const limits de_p90_lim = {{NAN, NAN, NAN}, {4, 7, 10, 13}};

static int iso_level(const limits *l, double v) /* 0 A, 1 B, 2 C, 3 none, -1 unknown */
{
	if (isnan(l->iso[0]))
		return -1;
	for (int k = 0; k < 3; k++)
		if (v <= l->iso[k])
			return k;
	return 3;
}

static int fadgi_stars(const limits *l, double v) /* 4..1, 0 none, -1 unknown */
{
	if (isnan(l->fadgi[0]))
		return -1;
	for (int k = 0; k < 4; k++)
		if (v < l->fadgi[k])
			return 4 - k;
	return 0;
}

static json_t *tolerance_json(const limits *l)
{
	json_t *iso = json_object(), *fadgi = json_object();
	static const char *const lv[] = {"A", "B", "C"};
	static const char *const st[] = {"4", "3", "2", "1"};
	for (int k = 0; k < 3; k++)
		json_object_set_new(iso, lv[k], isnan(l->iso[k]) ? json_null() : json_real(l->iso[k]));
	for (int k = 0; k < 4; k++)
		json_object_set_new(fadgi, st[k], isfinite(l->fadgi[k]) ? json_real(l->fadgi[k])
		                                                      : json_null());
	return json_pack("{s:o, s:o}", "iso19264_1", iso, "fadgi_2023", fadgi);
}

static json_t *level_json(int k)
{
	static const char *const lv[] = {"A", "B", "C"};
	return k >= 0 && k < 3 ? json_string(lv[k]) : json_null();
}

static json_t *record(const char *id, const char *unit, double value, double aim,
                      json_t *tolerance, json_t *level, int stars, json_t *used, int measured,
                      const char *note)
{
	return json_pack("{s:s, s:o, s:s, s:o, s:o, s:o, s:i, s:o, s:b, s:s}", "id", id, "value",
	                 measured && isfinite(value) ? json_real(value) : json_null(), "unit",
	                 unit, "aim", isfinite(aim) ? json_real(aim) : json_null(), "tolerance",
	                 tolerance ? tolerance : json_null(), "level", level ? level : json_null(),
	                 "stars", stars > 0 ? stars : 0, "used", used ? used : json_array(),
	                 "measured", measured, "note", note);
}

/* The worst of a per-patch key over the neutral patches with a value (absolute). */
static double neutral_max(const json_t *patches, const char *key, json_t *used)
{
	double m = NAN;
	size_t i;
	const json_t *e;
	json_array_foreach(patches, i, e) {
		const json_t *v = json_object_get(e, key);
		if (!json_is_true(json_object_get(e, "neutral")) || !json_is_number(v))
			continue;
		double x = fabs(json_number_value(v));
		if (isnan(m) || x > m)
			m = x;
		if (used)
			json_array_append_new(used, json_copy(json_object_get(e, "id")));
	}
	return m;
}

static json_t *graded(const char *id, const char *unit, const limits *l, double v,
                      json_t *used, const char *note_measured, const char *note_missing)
{
	int measured = isfinite(v);
	int lvl = measured ? iso_level(l, v) : -1, st = measured ? fadgi_stars(l, v) : 0;
	return record(id, unit, v, 0, tolerance_json(l), level_json(lvl), st, used, measured,
	              measured ? note_measured : note_missing);
}

static void summarise_key(const json_t *patches, const char *key, kg_de_summary *s,
                          json_t *used)
{
	size_t n = json_array_size(patches), i;
	double *v = malloc(sizeof(double) * (n ? n : 1));
	const json_t *e;
	memset(s, 0, sizeof(*s));
	if (!v)
		return;
	json_array_foreach(patches, i, e) {
		const json_t *x = json_object_get(e, key);
		v[i] = json_is_number(x) ? json_number_value(x) : NAN;
		if (used && json_is_number(x))
			json_array_append_new(used, json_copy(json_object_get(e, "id")));
	}
	kg_err err;
	if (kg_de_summarise(v, (int)n, s, &err))
		memset(s, 0, sizeof(*s));
	free(v);
}

static json_t *summary_json(const kg_de_summary *s)
{
	if (s->n == 0)
		return json_null();
	return json_pack("{s:i, s:f, s:f, s:f}", "n", s->n, "mean", s->mean, "p90", s->p90, "max",
	                 s->max);
}

static json_t *colour_record(const json_t *patches)
{
	kg_de_summary in, out;
	json_t *used = json_array();
	summarise_key(patches, "de00_d50", &in, NULL);
	kg_de_summary ver;
	json_t *vused = json_array();
	summarise_key(patches, "de00_d50_verify", &ver, vused);
	summarise_key(patches, "de00_d50_heldout", &out, used);
	const kg_de_summary *g = ver.n ? &ver : out.n ? &out : &in;
	const char *basis = ver.n ? "verify" : out.n ? "held-out" : "in-sample";
	if (ver.n) {
		json_decref(used);
		used = vused;
	} else {
		json_decref(vused);
	}
	if (!ver.n && !out.n) {
		json_decref(used);
		used = json_array();
		summarise_key(patches, "de00_d50", &in, used);
	}
	int measured = g->n > 0;
	int lvl = -1, st = 0;
	if (measured) {
		int a = iso_level(&de_mean_lim, g->mean), b = iso_level(&de_max_lim, g->max);
		lvl = a > b ? a : b;
		int c = fadgi_stars(&de_mean_lim, g->mean), d = fadgi_stars(&de_p90_lim, g->p90);
		st = c < d ? c : d;
	}
	json_t *tol = json_pack("{s:o, s:o, s:o}", "mean", tolerance_json(&de_mean_lim), "max",
	                        tolerance_json(&de_max_lim), "p90", tolerance_json(&de_p90_lim));
	json_t *r = record("colour_accuracy", "ΔE00", measured ? g->mean : NAN, 0, tol,
	                   level_json(lvl), st, used, measured,
	                   measured ? "CIEDE2000 of the spectral estimate against the measured "
	                              "spectra; value is the mean; graded on the verification "
	                              "capture's patches (--verify) when given, else held-out "
	                              "(leave-one-out: the calibration refitted without each "
	                              "patch), else in-sample"
	                            : "no measured chart spectra: not measured");
	json_object_set_new(r, "graded_on", json_string(basis));
	json_object_set_new(r, "in_sample", summary_json(&in));
	json_object_set_new(r, "held_out", summary_json(&out));
	json_object_set_new(r, "verify", summary_json(&ver));
	json_object_set_new(r, "cielab",
	                    json_pack("{s:s, s:s, s:s}", "illuminant", "CIE D50", "observer",
	                              "CIE 1931 2°", "white", "the perfect reflecting diffuser "
	                              "under D50 (Xn, Yn, Zn of D50, Yn = 100)"));
	return r;
}

json_t *kg_conformance(const json_t *patches, double flat_nonuniformity)
{
	json_t *list = json_array();
	json_t *u1 = json_array(), *u2 = json_array(), *u3 = json_array();
	double dl = neutral_max(patches, "dL", u1);
	double dab = neutral_max(patches, "dab", u2);
	double noise = neutral_max(patches, "noise_L", u3);
	json_array_append_new(
		list, graded("oecf", "ΔL*", &oecf_lim, dl, u1,
		             "largest |ΔL*| of the estimate against the measured L* (D50) over the "
		             "neutral patches",
		             "no neutral patch with a measured spectrum: not measured"));
	json_array_append_new(
		list, graded("white_balance", "ΔE(a*b*)", &wb_lim, dab, u2,
		             "largest ΔE(a*b*) over the neutral patches (D50)",
		             "no neutral patch with a measured spectrum: not measured"));
	double nu = 100 * flat_nonuniformity;
	json_t *r = graded("illuminance_non_uniformity", "%", &nu_lim, nu, NULL,
	                   "from the flat: largest deviation of an 8 x 8 block mean from the mean "
	                   "of the blocks; ISO 19264-1 limits not found, no level given; FADGI "
	                   "tolerances of its 2010 guidelines (the 2023 values not found)",
	                   "no flat with a recorded non-uniformity: not measured");
	if (isfinite(nu))
		json_array_append_new(json_object_get(r, "used"), json_string("flat"));
	json_array_append_new(list, r);
	json_array_append_new(
		list, graded("noise", "L*", &noise_lim, noise, u3,
		             "largest standard deviation of L* over the neutral patches, from the "
		             "patches' pixel spread through the calibration (D50)",
		             "no neutral patch with a pixel spread: not measured"));
	json_array_append_new(list, colour_record(patches));
	json_array_append_new(list, record("sfr", "cycles/pixel", NAN, NAN, NULL, NULL, 0, NULL, 0,
	                                   "not measured: the chart capture's edges were not "
	                                   "analysed"));
	json_array_append_new(list, record("colour_misregistration", "pixels", NAN, NAN, NULL, NULL,
	                                   0, NULL, 0, "not measured: the chart capture's "
	                                   "edges were not analysed"));
	return list;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

static double median(double *v, int n)
{
	qsort(v, (size_t)n, sizeof(double), cmp_double);
	return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Replace the record of id in list by rec. */
static void replace_record(json_t *list, const char *id, json_t *rec)
{
	size_t i;
	json_t *e;
	json_array_foreach(list, i, e) {
		const char *x = json_string_value(json_object_get(e, "id"));
		if (x && !strcmp(x, id)) {
			json_array_set_new(list, i, rec);
			return;
		}
	}
	json_array_append_new(list, rec);
}

#define MAX_SFR_EDGES 64

void kg_conformance_edges(json_t *list, const kg_chart_layout *l, const kg_chart_result *r,
                          const kg_image *img, int bin)
{
	kg_err err;
	kg_sfr_edge *edges = NULL;
	int n = 0;
	const char *why = NULL;
	char msg[1200];
	if (!l || !r || !img) {
		why = "not measured: no chart capture";
	} else if (r->tagless) {
		why = "not measured: the chart was found without tags (no tag edge to measure)";
	} else if (kg_sfr_find_edges(l, r, img, 0, &edges, &n, &err)) {
		snprintf(msg, sizeof(msg), "not measured: %s", err.msg);
		why = msg;
	} else if (n == 0) {
		why = "not measured on this target: no tag side is slanted 2 to 10 degrees from the "
		      "image axes (the chart sits square to the sensor) or long enough";
	}
	json_t *used = json_array(), *per = json_array();
	double *eff = malloc(sizeof(double) * (size_t)(n ? n : 1));
	double *m50 = malloc(sizeof(double) * (size_t)(n ? n : 1));
	double *m10 = malloc(sizeof(double) * (size_t)(n ? n : 1));
	double misreg = NAN;
	int k = 0, refused = 0;
	for (int i = 0; !why && eff && m50 && m10 && i < n && i < MAX_SFR_EDGES; i++) {
		kg_sfr_result s;
		char name[48];
		snprintf(name, sizeof(name), "tag%d.side%d", edges[i].tag_id, edges[i].side);
		if (kg_sfr_measure(img, &edges[i].roi, &s, &err)) {
			refused++;
			json_array_append_new(per, json_pack("{s:s, s:s}", "edge", name, "refused",
			                                     err.msg));
			continue;
		}
		eff[k] = s.efficiency;
		m50[k] = s.mtf50;
		m10[k] = s.mtf10;
		k++;
		if (s.channels == 3 && (isnan(misreg) || s.misregistration > misreg))
			misreg = s.misregistration;
		json_array_append_new(used, json_string(name));
		json_array_append_new(
			per, json_pack("{s:s, s:f, s:f, s:f, s:b, s:f, s:f, s:f}", "edge", name,
			               "angle_deg", s.angle_deg, "mtf50", s.mtf50, "mtf10", s.mtf10,
			               "mtf10_reached", s.mtf10_reached, "efficiency", s.efficiency,
			               "misregistration", s.channels == 3 ? s.misregistration : 0.0,
			               "length_px", s.length));
	}
	if (!why && k == 0) {
		snprintf(msg, sizeof(msg), "not measured: none of the %d slanted tag sides holds a "
		         "usable edge", n);
		why = msg;
	}
	json_t *sfr, *mis;
	if (why) {
		sfr = record("sfr", "%", NAN, NAN, NULL, NULL, 0, NULL, 0, why);
		mis = record("colour_misregistration", "pixels", NAN, NAN, NULL, NULL, 0, NULL, 0, why);
		json_decref(used);
	} else {
		double e = 100 * median(eff, k), f50 = median(m50, k), f10 = median(m10, k);
		sfr = record("sfr", "%", e, 100, NULL, NULL, 0, json_copy(used), 1,
		             "slanted-edge SFR (ISO 12233) on the chart's tag sides; value is the "
		             "median sampling efficiency (MTF10 / Nyquist, capped at 100 %); "
		             "ISO 19264-1 and FADGI limits not sourced: recorded, not graded");
		json_object_set_new(sfr, "mtf50", json_real(f50));
		json_object_set_new(sfr, "mtf10", json_real(f10));
		json_object_set_new(sfr, "efficiency", json_real(e / 100));
		json_object_set_new(sfr, "frequency_unit", json_string("cycles/pixel"));
		json_object_set_new(sfr, "edges", json_incref(per));
		json_object_set_new(sfr, "refused", json_integer(refused));
		json_object_set_new(sfr, "binned", json_integer(bin));
		if (isnan(misreg)) {
			mis = record("colour_misregistration", "pixels", NAN, NAN, NULL, NULL, 0, NULL, 0,
			             "not measured: the chart capture has one channel");
			json_decref(used);
		} else {
			mis = record("colour_misregistration", "pixels", misreg, 0, NULL, NULL, 0, used,
			             1, "largest difference between the R, G and B edge positions over "
			                "the tag sides measured; ISO 19264-1 and FADGI limits not "
			                "sourced: recorded, not graded");
			json_object_set_new(mis, "binned", json_integer(bin));
		}
	}
	json_decref(per);
	if (sfr)
		replace_record(list, "sfr", sfr);
	if (mis)
		replace_record(list, "colour_misregistration", mis);
	free(eff);
	free(m50);
	free(m10);
	free(edges);
}
