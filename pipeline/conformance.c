/* Imaging-quality analysis of the chart capture against ISO 19264-1 and FADGI 2023:
 * the records of OUTDIR/conformance.json (kg_pipeline.h, docs/report.md). Built from
 * the per-patch values of process.json's calibration.patches and the flat's
 * illuminance non-uniformity; no image is read here. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kg_pipeline.h"
#include "sfr.h"

/* One characteristic's limits: ISO 19264-1 levels A, B, C (inclusive: <=, or >= when
 * higher is better) and FADGI stars 4, 3, 2, 1 (strict: <, or >); NaN where no
 * published value was found (that side is not graded), INFINITY (or -INFINITY when
 * higher is better) where the lowest star has no limit. iso_src and fadgi_src cite the
 * document and table each limit comes from; they are written beside the tolerances.
 *
 * The values were checked against a published side-by-side table of ISO 19264-1:2021
 * levels A-C and FADGI 2023 (Bound General Collections) stars 4-1 (skandalski.pl,
 * "Tabela porownawcza FADGI/ISO/Metamorfoze"), rows "Tone response dL* (OECF)",
 * "White balance dE(a*b*)", "Color accuracy mean / max / 90th percentile", "Noise
 * upper limit (RMS)", "Sampling efficiency MTF10". Illuminance non-uniformity and
 * colour channel misregistration are in the tables of FADGI's August 2010 Technical
 * Guidelines ("Lightness non-uniformity", "Color channel misregistration", option A:
 * any single feature); their 2023 values and ISO 19264-1's were not found, so ISO
 * grades neither. */
typedef struct limits {
	double iso[3];
	double fadgi[4];
	int higher; /* higher values are better (sampling efficiency) */
	const char *iso_src, *fadgi_src;
} limits;

#define NOT_FOUND "not graded: no published limit found"
#define ISO_TABLE "ISO 19264-1:2021, limits of levels A, B, C: "
#define FADGI_TABLE "FADGI Technical Guidelines 2023, Bound General Collections, stars 4-1: "
#define FADGI_2010 "FADGI Technical Guidelines, August 2010 (2023 value not found), stars 4-1: "

static const limits oecf_lim = {{2, 3, 4}, {1.5, 3, 4.5, 6}, 0,
                                ISO_TABLE "tone response, |dL*| <= 2, 3, 4",
                                FADGI_TABLE "tone response (OECF), |dL*| < 1.5, 3, 4.5, 6"};
static const limits wb_lim = {{3, 4, 5}, {2, 4, 6, 8}, 0,
                              ISO_TABLE "white balance, dE(a*b*) <= 3, 4, 5",
                              FADGI_TABLE "white balance error, dE(a*b*) < 2, 4, 6, 8"};
static const limits noise_lim = {{1.6, 2, 2.2}, {1, 2, 3, 4}, 0,
                                 ISO_TABLE "noise upper limit (RMS L*) <= 1.6, 2, 2.2",
                                 FADGI_TABLE "noise (RMS L*) < 1, 2, 3, 4"};
static const limits nu_lim = {{NAN, NAN, NAN}, {1, 3, 5, INFINITY}, 0, NOT_FOUND,
                              FADGI_2010 "lightness non-uniformity < 1, 3, 5 %, 1 star "
                                         "above 5 %"};
/* colour accuracy: mean (ISO, FADGI), maximum (ISO), 90th percentile (FADGI) */
static const limits de_mean_lim = {{4, 5, 5}, {2, 3.5, 5, 6.5}, 0,
                                   ISO_TABLE "colour accuracy, mean dE <= 4, 5, 5",
                                   FADGI_TABLE "colour accuracy, mean dE2000 < 2, 3.5, 5, 6.5"};
static const limits de_max_lim = {{10, 15, 15}, {NAN, NAN, NAN, NAN}, 0,
                                  ISO_TABLE "colour accuracy, maximum dE <= 10, 15, 15",
                                  "FADGI 2023 grades the 90th percentile, not the maximum"};
static const limits de_p90_lim = {{NAN, NAN, NAN}, {4, 7, 10, 13}, 0,
                                  "ISO 19264-1 grades the maximum, not the 90th percentile",
                                  FADGI_TABLE "colour accuracy, 90th percentile dE2000 < 4, "
                                              "7, 10, 13"};
/* sampling efficiency (MTF10 frequency / Nyquist, %) */
static const limits sfr_lim = {{85, 80, 70}, {90, 80, 70, 60}, 1,
                               ISO_TABLE "sampling efficiency (MTF10) >= 85, 80, 70 %",
                               FADGI_TABLE "sampling efficiency (MTF10) > 90, 80, 70, 60 %"};
static const limits misreg_lim = {{NAN, NAN, NAN}, {0.33, 0.5, 0.8, INFINITY}, 0, NOT_FOUND,
                                  FADGI_2010 "colour channel misregistration, any single "
                                             "feature, < 0.33, 0.50, 0.80 pixel, 1 star "
                                             "above 0.80"};

static int iso_level(const limits *l, double v) /* 0 A, 1 B, 2 C, 3 none, -1 unknown */
{
	if (isnan(l->iso[0]))
		return -1;
	for (int k = 0; k < 3; k++)
		if (l->higher ? v >= l->iso[k] : v <= l->iso[k])
			return k;
	return 3;
}

static int fadgi_stars(const limits *l, double v) /* 4..1, 0 none, -1 unknown */
{
	if (isnan(l->fadgi[0]))
		return -1;
	for (int k = 0; k < 4; k++)
		if (l->higher ? v > l->fadgi[k] : v < l->fadgi[k])
			return 4 - k;
	return 0;
}

static const limits *limits_of(const char *id)
{
	static const struct {
		const char *id;
		const limits *l;
	} t[] = {{"oecf", &oecf_lim},
	         {"white_balance", &wb_lim},
	         {"illuminance_non_uniformity", &nu_lim},
	         {"noise", &noise_lim},
	         {"sfr", &sfr_lim},
	         {"colour_misregistration", &misreg_lim}};
	for (size_t i = 0; id && i < sizeof(t) / sizeof(t[0]); i++)
		if (!strcmp(t[i].id, id))
			return t[i].l;
	return NULL;
}

int kg_conformance_grade(const char *id, double v, int *stars)
{
	const limits *l = limits_of(id);
	if (!l || !isfinite(v)) {
		if (stars)
			*stars = -1;
		return -1;
	}
	if (stars)
		*stars = fadgi_stars(l, v);
	return iso_level(l, v);
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
	return json_pack("{s:o, s:o, s:b, s:{s:s, s:s}}", "iso19264_1", iso, "fadgi_2023", fadgi,
	                 "higher_is_better", l->higher,
	                 "source", "iso19264_1", l->iso_src, "fadgi_2023", l->fadgi_src);
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

/* A patch chart detection flagged (clipped, glare, covered, ...: "flags" != 0) or the
 * calibration left out ("used": false) grades nothing: a clipped white would grade the
 * tone and the white balance from what the sensor did not record. */
static int left_out(const json_t *e)
{
	const json_t *f = json_object_get(e, "flags"), *u = json_object_get(e, "used");
	return (json_is_integer(f) && json_integer_value(f) != 0) || json_is_false(u);
}

/* The patches of `which` (the neutrals, or every patch with key) left out, with why. */
static json_t *left_out_list(const json_t *patches, const char *key, int neutral)
{
	json_t *list = json_array();
	size_t i;
	const json_t *e;
	json_array_foreach(patches, i, e) {
		if ((neutral && !json_is_true(json_object_get(e, "neutral"))) ||
		    !json_is_number(json_object_get(e, key)) || !left_out(e))
			continue;
		const json_t *w = json_object_get(e, "warning");
		json_array_append_new(list, json_pack("{s:O, s:s}", "id", json_object_get(e, "id"),
		                                      "why", json_is_string(w) ? json_string_value(w)
		                                                               : "flagged by chart "
		                                                                 "detection"));
	}
	return list;
}

/* The worst of a per-patch key over the neutral patches with a value (absolute), those
 * left out (left_out) excepted. */
static double neutral_max(const json_t *patches, const char *key, json_t *used)
{
	double m = NAN;
	size_t i;
	const json_t *e;
	json_array_foreach(patches, i, e) {
		const json_t *v = json_object_get(e, key);
		if (!json_is_true(json_object_get(e, "neutral")) || !json_is_number(v) || left_out(e))
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
		if (left_out(e))
			x = NULL;
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
	json_object_set_new(r, "left_out", left_out_list(patches, "de00_d50", 0));
	json_object_set_new(r, "cielab",
	                    json_pack("{s:s, s:s, s:s}", "illuminant", "CIE D50", "observer",
	                              "CIE 1931 2°", "white", "the perfect reflecting diffuser "
	                              "under D50 (Xn, Yn, Zn of D50, Yn = 100)"));
	return r;
}

/* 1 when a neutral patch has a value of the verification capture (key_verify). */
static int has_verify(const json_t *patches)
{
	size_t i;
	const json_t *e;
	json_array_foreach(patches, i, e)
		if (json_is_true(json_object_get(e, "neutral")) &&
		    json_is_number(json_object_get(e, "dL_verify")))
			return 1;
	return 0;
}

json_t *kg_conformance(const json_t *patches, double flat_nonuniformity)
{
	json_t *list = json_array();
	json_t *u1 = json_array(), *u2 = json_array(), *u3 = json_array();
	/* tone, white balance and noise on the verification capture when there is one:
	 * the calibration was fitted to the chart capture's response and absorbs much of
	 * its tone error */
	int ver = has_verify(patches);
	double dl = neutral_max(patches, ver ? "dL_verify" : "dL", u1);
	double dab = neutral_max(patches, ver ? "dab_verify" : "dab", u2);
	double noise = neutral_max(patches, ver ? "noise_L_verify" : "noise_L", u3);
	json_t *r0 = graded("oecf", "ΔL*", &oecf_lim, dl, u1,
	                    ver ? "largest |ΔL*| of the estimate against the measured L* (D50) "
	                          "over the neutral patches of the verification capture "
	                          "(--verify)"
	                        : "largest |ΔL*| of the estimate against the measured L* (D50) "
	                          "over the neutral patches of the chart capture",
	                    "no neutral patch with a measured spectrum: not measured");
	json_object_set_new(r0, "graded_on", json_string(ver ? "verify" : "chart capture"));
	json_object_set_new(r0, "left_out", left_out_list(patches, ver ? "dL_verify" : "dL", 1));
	json_array_append_new(list, r0);
	json_t *r1 = graded("white_balance", "ΔE(a*b*)", &wb_lim, dab, u2,
	                    ver ? "largest ΔE(a*b*) over the neutral patches (D50) of the "
	                          "verification capture (--verify)"
	                        : "largest ΔE(a*b*) over the neutral patches (D50) of the chart "
	                          "capture",
	                    "no neutral patch with a measured spectrum: not measured");
	json_object_set_new(r1, "graded_on", json_string(ver ? "verify" : "chart capture"));
	json_object_set_new(r1, "left_out", left_out_list(patches, ver ? "dab_verify" : "dab", 1));
	json_array_append_new(list, r1);
	double nu = 100 * flat_nonuniformity;
	json_t *r = graded("illuminance_non_uniformity", "%", &nu_lim, nu, NULL,
	                   "from the flat: largest deviation of an 8 x 8 block mean from the mean "
	                   "of the blocks; ISO 19264-1: " NOT_FOUND " (no level); FADGI stars on "
	                   "the tolerances of its 2010 guidelines (the 2023 values not found)",
	                   "no flat with a recorded non-uniformity: not measured");
	if (isfinite(nu))
		json_array_append_new(json_object_get(r, "used"), json_string("flat"));
	json_array_append_new(list, r);
	json_t *r3 = graded("noise", "L*", &noise_lim, noise, u3,
	                    "largest standard deviation of L* over the neutral patches, from the "
	                    "patches' pixel spread through the calibration (D50)",
	                    "no neutral patch with a pixel spread: not measured");
	json_object_set_new(r3, "graded_on", json_string(ver ? "verify" : "chart capture"));
	json_object_set_new(r3, "left_out",
	                    left_out_list(patches, ver ? "noise_L_verify" : "noise_L", 1));
	json_array_append_new(list, r3);
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
/* Fewest edges the sfr and colour_misregistration records are graded on: a median of
 * three stands one stray edge. */
#define MIN_SFR_EDGES 3

/* Measure tag side e (sfr.h) in the band kg_sfr_find_edges chose (0.8 of a tag cell
 * either side). An edge too blurred for it (its 10-90 % rise more than the band /
 * KG_SFR_BAND_RISE) is refused, the reason saying what band it needs and the widest
 * the tag's cells allow: one cell to the next printed edge less KG_SFR_NEIGHBOUR_RISE
 * rises for that edge's own spread. That widest band holds KG_SFR_BAND_RISE rises only
 * up to a rise of cell / (KG_SFR_BAND_RISE + KG_SFR_NEIGHBOUR_RISE) = 0.48 cell, where
 * the 0.8-cell band already holds them up to 0.5 cell: widening it would recover no
 * edge, so the band is not widened. */
static int measure_edge(const kg_sfr_edge *e, const kg_image *img, kg_sfr_result *s,
                        kg_err *err)
{
	int rc = kg_sfr_measure(img, &e->roi, s, err);
	if (rc && s->too_blurred) {
		double allowed = e->cell_px - KG_SFR_NEIGHBOUR_RISE * s->rise;
		return kg_fail(err, KG_EINVAL, "too blurred for the tag's cells: the edge's 10-90 "
		               "%% rise of %.2f px needs a band of %.2f px either side (%g rises), "
		               "the band is %.2f px, and the tag's cell of %.2f px allows at most "
		               "%.2f px (the next printed edge is a cell away, %g rise kept clear of "
		               "it)", s->rise, KG_SFR_BAND_RISE * s->rise, KG_SFR_BAND_RISE,
		               s->band, e->cell_px, allowed < 0 ? 0 : allowed,
		               KG_SFR_NEIGHBOUR_RISE);
	}
	return rc;
}

/* Why the edge measured in s is shaped by clipping ("" when not): a channel of its band
 * reaches the image's clip level (clip; 0: not known). */
static void clipped_why(const kg_sfr_result *s, const double clip[3], char *why, size_t n)
{
	static const char *const name[3] = {"R", "G", "B"};
	why[0] = 0;
	for (int c = 0; c < s->channels; c++)
		if (clip[c] > 0 && s->peak[c] >= clip[c]) {
			snprintf(why, n, "clipped: %s%s reaches %.4g in the band around the edge, at or "
			         "above the clip level %.4g (the edge is shaped by the clipping, not by "
			         "the optics)", s->channels == 1 ? "the image" : "channel ",
			         s->channels == 1 ? "" : name[c], s->peak[c], clip[c]);
			return;
		}
}

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
	json_t *used = json_array(), *per = json_array(), *left = json_array();
	double *eff = malloc(sizeof(double) * (size_t)(n ? n : 1));
	double *m50 = malloc(sizeof(double) * (size_t)(n ? n : 1));
	double *m10 = malloc(sizeof(double) * (size_t)(n ? n : 1));
	double misreg = NAN;
	int k = 0, refused = 0, nclipped = 0, nblur = 0, tried = 0;
	for (int i = 0; !why && eff && m50 && m10 && i < n && i < MAX_SFR_EDGES; i++) {
		kg_sfr_result s;
		char name[48], cw[300] = "";
		tried++;
		snprintf(name, sizeof(name), "tag%d.side%d", edges[i].tag_id, edges[i].side);
		int rc = measure_edge(&edges[i], img, &s, &err);
		/* clipping first, whatever else the measurement found (peak is set once the
		 * band's pixels were read) */
		if (s.pixels > 0)
			clipped_why(&s, r->clip, cw, sizeof(cw));
		if (cw[0]) {
			rc = KG_EINVAL;
			snprintf(err.msg, sizeof(err.msg), "%s", cw);
			nclipped++;
		} else if (rc && (s.too_blurred || strstr(err.msg, "too blurred"))) {
			nblur++;
		}
		if (rc) {
			refused++;
			json_array_append_new(per, json_pack("{s:s, s:s, s:f}", "edge", name,
			                                     "refused", err.msg, "cell_px",
			                                     edges[i].cell_px));
			json_array_append_new(left, json_pack("{s:s, s:s}", "id", name, "why",
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
			per, json_pack("{s:s, s:f, s:f, s:f, s:b, s:f, s:f, s:f, s:f, s:f, s:f}", "edge",
			               name, "angle_deg", s.angle_deg, "mtf50", s.mtf50, "mtf10",
			               s.mtf10, "mtf10_reached", s.mtf10_reached, "efficiency",
			               s.efficiency, "misregistration",
			               s.channels == 3 ? s.misregistration : 0.0, "length_px", s.length,
			               "rise_px", s.rise, "band_px", s.band, "cell_px",
			               edges[i].cell_px));
	}
	if (!why && k < MIN_SFR_EDGES) {
		snprintf(msg, sizeof(msg), "not measured: %d of the %d slanted tag sides tried hold "
		         "a usable edge (at least %d are needed); left out: %d clipped, %d too "
		         "blurred for the tag's cells, %d for other reasons (left_out says why)",
		         k, tried, MIN_SFR_EDGES, nclipped, nblur, refused - nclipped - nblur);
		why = msg;
	}
	char out_note[400] = "";
	if (refused)
		snprintf(out_note, sizeof(out_note), "; %d of the %d tag sides left out (%d clipped, "
		         "%d too blurred for the tag's cells, %d for other reasons: left_out says "
		         "why)", refused, tried, nclipped, nblur, refused - nclipped - nblur);
	json_t *sfr, *mis;
	char note[1200];
	if (why) {
		sfr = record("sfr", "%", NAN, NAN, NULL, NULL, 0, NULL, 0, why);
		mis = record("colour_misregistration", "pixels", NAN, NAN, NULL, NULL, 0, NULL, 0, why);
		json_decref(used);
		if (tried) {
			json_object_set_new(sfr, "edges", json_incref(per));
			json_object_set_new(sfr, "refused", json_integer(refused));
		}
	} else {
		double e = 100 * median(eff, k), f50 = median(m50, k), f10 = median(m10, k);
		int st = 0, lv = kg_conformance_grade("sfr", e, &st);
		snprintf(note, sizeof(note), "slanted-edge SFR (ISO 12233) on the chart's tag "
		         "sides; value is the median sampling efficiency (MTF10 / Nyquist, capped "
		         "at 100 %%), graded on ISO 19264-1's and FADGI 2023's sampling-efficiency "
		         "limits; MTF50 and MTF10 recorded beside it%s", out_note);
		sfr = record("sfr", "%", e, 100, tolerance_json(&sfr_lim), level_json(lv), st,
		             json_copy(used), 1, note);
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
			int mst = 0, mlv = kg_conformance_grade("colour_misregistration", misreg, &mst);
			snprintf(note, sizeof(note), "largest difference between the R, G and B edge "
			         "positions over the tag sides measured; FADGI stars on the tolerances "
			         "of its 2010 guidelines (the 2023 values not found); ISO 19264-1: "
			         NOT_FOUND " (no level)%s", out_note);
			mis = record("colour_misregistration", "pixels", misreg, 0,
			             tolerance_json(&misreg_lim), level_json(mlv), mst, used, 1, note);
			json_object_set_new(mis, "binned", json_integer(bin));
		}
	}
	json_decref(per);
	/* the tag sides left out, with why, as the patches' left_out */
	if (sfr)
		json_object_set_new(sfr, "left_out", json_copy(left));
	if (mis)
		json_object_set_new(mis, "left_out", json_copy(left));
	json_decref(left);
	if (sfr)
		replace_record(list, "sfr", sfr);
	if (mis)
		replace_record(list, "colour_misregistration", mis);
	free(eff);
	free(m50);
	free(m10);
	free(edges);
}
