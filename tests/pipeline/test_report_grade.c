/* The colour accuracy aggregates and grades of the report (kg_pipeline.h) on small
 * hand-checked vectors, boundaries included. */
#include <math.h>
#include <string.h>

#include "kg_pipeline.h"
#include "kg_test.h"

static kg_de_summary summarise(const double *v, int n)
{
	kg_de_summary s = {0};
	kg_err err;
	int ret = kg_de_summarise(v, n, &s, &err);
	CHECK(ret == 0, "kg_de_summarise: %s", err.msg);
	return s;
}

static void test_aggregates(void)
{
	/* 1..10 shuffled: mean 5.5, nearest rank ceil(0.9 * 10) = 9 -> 9, max 10. */
	const double ten[10] = {7, 3, 10, 1, 9, 2, 8, 5, 4, 6};
	kg_de_summary s = summarise(ten, 10);
	CHECK(s.n == 10, "n %d", s.n);
	CHECK_NEAR(s.mean, 5.5, 0, "mean of 1..10");
	CHECK_NEAR(s.p90, 9, 0, "p90 of 1..10 (rank 9)");
	CHECK_NEAR(s.max, 10, 0, "max of 1..10");

	/* 24 patches 0.5, 0.6, ..., 2.8: rank ceil(21.6) = 22 -> 0.5 + 2.1 = 2.6. */
	double chart[24];
	for (int i = 0; i < 24; i++)
		chart[i] = 0.5 + 0.1 * i;
	s = summarise(chart, 24);
	CHECK_NEAR(s.p90, 0.5 + 0.1 * 21, 1e-15, "p90 of 24 patches (rank 22)");
	CHECK_NEAR(s.mean, 1.65, 1e-12, "mean of 24 patches");
	CHECK_NEAR(s.max, 2.8, 1e-15, "max of 24 patches");

	/* One value: every statistic is that value. Eleven: rank ceil(9.9) = 10. */
	const double one[1] = {3.25};
	s = summarise(one, 1);
	CHECK(s.mean == 3.25 && s.p90 == 3.25 && s.max == 3.25, "one value: %g %g %g", s.mean,
	      s.p90, s.max);
	const double eleven[11] = {11, 10, 9, 8, 7, 6, 5, 4, 3, 2, 1};
	s = summarise(eleven, 11);
	CHECK_NEAR(s.p90, 10, 0, "p90 of 1..11 (rank 10)");

	/* NaN marks a patch without a value: skipped, not counted. */
	const double gaps[4] = {1, NAN, 3, NAN};
	s = summarise(gaps, 4);
	CHECK(s.n == 2, "n with gaps %d", s.n);
	CHECK_NEAR(s.mean, 2, 0, "mean with gaps");
	CHECK_NEAR(s.p90, 3, 0, "p90 with gaps (rank 2 of 2)");

	/* Refusals: nothing to summarise, negative, infinite. */
	kg_err err;
	kg_de_summary t;
	const double none[2] = {NAN, NAN}, negative[2] = {1, -0.5}, inf[2] = {1, INFINITY};
	CHECK(kg_de_summarise(none, 2, &t, &err) == KG_EINVAL, "all NaN accepted");
	CHECK(kg_de_summarise(none, 0, &t, &err) == KG_EINVAL, "empty accepted");
	CHECK(kg_de_summarise(negative, 2, &t, &err) == KG_EINVAL, "negative accepted");
	CHECK(kg_de_summarise(inf, 2, &t, &err) == KG_EINVAL, "infinity accepted");
}

static void test_fadgi(void)
{
	/* mean < 2 and p90 < 4, both strict. */
	const double pass[4] = {1, 1.5, 2, 3.9};      /* mean 2.1: fails on the mean */
	kg_de_summary s = summarise(pass, 4);
	CHECK(!kg_grade_fadgi4(&s), "mean 2.1 passed FADGI");
	const double exact[2] = {1, 3};               /* mean exactly 2.0 */
	s = summarise(exact, 2);
	CHECK(s.mean == 2.0, "mean %g", s.mean);
	CHECK(!kg_grade_fadgi4(&s), "mean exactly 2 passed FADGI's < 2");
	const double below[2] = {1, 2.998};           /* mean 1.999, p90 2.998 */
	s = summarise(below, 2);
	CHECK(kg_grade_fadgi4(&s), "mean 1.999, p90 2.998 failed FADGI");
	/* Ten values, mean 1.2, p90 (rank 9) exactly 4: fails on the percentile. */
	const double p90_four[10] = {0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 4, 4};
	s = summarise(p90_four, 10);
	CHECK(s.p90 == 4 && s.mean < 2, "p90 %g mean %g", s.p90, s.mean);
	CHECK(!kg_grade_fadgi4(&s), "p90 exactly 4 passed FADGI's < 4");
	/* The same with the top value alone large: p90 is rank 9, 0.5, below the 9.5. */
	const double one_outlier[10] = {0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 0.5, 9.5};
	s = summarise(one_outlier, 10);
	CHECK(s.p90 == 0.5 && s.mean == 1.4, "p90 %g mean %g", s.p90, s.mean);
	CHECK(kg_grade_fadgi4(&s), "one outlier beyond the 90th percentile failed FADGI");
	kg_de_summary empty = {0};
	CHECK(!kg_grade_fadgi4(&empty), "no values passed FADGI");
}

static void test_iso(void)
{
	/* mean <= 4 and max <= 10, both inclusive. */
	const double max_ten[4] = {1, 1, 1, 10};      /* mean 3.25, max exactly 10 */
	kg_de_summary s = summarise(max_ten, 4);
	CHECK(s.max == 10, "max %g", s.max);
	CHECK(kg_grade_iso19264_a(&s), "max exactly 10 failed ISO's <= 10");
	const double mean_four[2] = {3, 5};           /* mean exactly 4 */
	s = summarise(mean_four, 2);
	CHECK(s.mean == 4, "mean %g", s.mean);
	CHECK(kg_grade_iso19264_a(&s), "mean exactly 4 failed ISO's <= 4");
	const double over_max[3] = {1, 1, 10.01};
	s = summarise(over_max, 3);
	CHECK(!kg_grade_iso19264_a(&s), "max 10.01 passed ISO");
	const double over_mean[2] = {4, 4.02};        /* mean 4.01 */
	s = summarise(over_mean, 2);
	CHECK(!kg_grade_iso19264_a(&s), "mean 4.01 passed ISO");
	/* Passing ISO but not FADGI: mean 3, max 9. */
	const double between[3] = {0, 0, 9};
	s = summarise(between, 3);
	CHECK(kg_grade_iso19264_a(&s) && !kg_grade_fadgi4(&s), "mean 3, max 9: ISO %d FADGI %d",
	      kg_grade_iso19264_a(&s), kg_grade_fadgi4(&s));
	kg_de_summary empty = {0};
	CHECK(!kg_grade_iso19264_a(&empty), "no values passed ISO");
}

static const json_t *record_of(const json_t *list, const char *id)
{
	size_t i;
	const json_t *r;
	json_array_foreach(list, i, r)
		if (!strcmp(json_string_value(json_object_get(r, "id")), id))
			return r;
	return NULL;
}

/* kg_conformance_grade: sampling efficiency graded higher-is-better (ISO >= 85/80/70 %
 * inclusive, FADGI > 90/80/70/60 % strict); misregistration on FADGI's pixels (strict)
 * with no ISO level; an unknown id or a NaN is ungraded. */
static void test_grade_edges(void)
{
	int st = 9, lv = kg_conformance_grade("sfr", 85.0, &st);
	CHECK(lv == 0 && st == 3, "efficiency 85 %%: A (>= 85), 3 stars (> 80, not > 90); "
	      "got %d, %d", lv, st);
	lv = kg_conformance_grade("sfr", 80.0, &st);
	CHECK(lv == 1 && st == 2, "efficiency 80 %%: B (>= 80), 2 stars (not > 80); got %d, %d",
	      lv, st);
	lv = kg_conformance_grade("sfr", 90.0, &st);
	CHECK(lv == 0 && st == 3, "efficiency 90 %%: A, 3 stars (not > 90); got %d, %d", lv, st);
	lv = kg_conformance_grade("sfr", 90.5, &st);
	CHECK(lv == 0 && st == 4, "efficiency 90.5 %%: A, 4 stars; got %d, %d", lv, st);
	lv = kg_conformance_grade("sfr", 79.9, &st);
	CHECK(lv == 2 && st == 2, "efficiency 79.9 %%: C (>= 70), 2 stars (> 70); got %d, %d",
	      lv, st);
	lv = kg_conformance_grade("sfr", 55.0, &st);
	CHECK(lv == 3 && st == 0, "efficiency 55 %%: no level, no star; got %d, %d", lv, st);
	lv = kg_conformance_grade("colour_misregistration", 0.2, &st);
	CHECK(lv == -1 && st == 4, "misregistration 0.2 px: no ISO limit, 4 stars; got %d, %d",
	      lv, st);
	lv = kg_conformance_grade("colour_misregistration", 0.33, &st);
	CHECK(st == 3, "misregistration 0.33 px: 3 stars (not < 0.33); got %d", st);
	lv = kg_conformance_grade("colour_misregistration", 5.0, &st);
	CHECK(st == 1, "misregistration 5 px: 1 star (no limit below 2 stars); got %d", st);
	lv = kg_conformance_grade("noise", 1.6, &st);
	CHECK(lv == 0 && st == 3, "noise 1.6: A (<= 1.6), 3 stars (< 2); got %d, %d", lv, st);
	lv = kg_conformance_grade("noise", 2.0, &st);
	CHECK(lv == 1 && st == 2, "noise 2.0: B (<= 2), 2 stars (not < 2); got %d, %d", lv, st);
	lv = kg_conformance_grade("sharpness", 1.0, &st);
	CHECK(lv == -1 && st == -1, "unknown id graded: %d, %d", lv, st);
	lv = kg_conformance_grade("sfr", NAN, &st);
	CHECK(lv == -1 && st == -1, "NaN graded: %d, %d", lv, st);
}

/* kg_conformance: ISO levels inclusive, FADGI stars strict, on the limits; what has
 * no neutral patch or no flat is not measured and not passed. */
static void test_conformance(void)
{
	json_t *patches = json_pack(
		"[{s:s, s:b, s:f, s:f, s:f, s:f, s:f}, {s:s, s:b, s:f, s:f, s:f, s:f, s:f}]",
		"id", "D01", "neutral", 1, "dL", -2.0, "dab", 4.0, "noise_L", 1.0, "de00_d50", 1.0,
		"de00_d50_heldout", 2.0,
		"id", "A01", "neutral", 0, "dL", 9.0, "dab", 9.0, "noise_L", 9.0, "de00_d50", 3.0,
		"de00_d50_heldout", 10.0);
	json_t *c = kg_conformance(patches, 0.03);
	CHECK(json_array_size(c) == 7, "%zu records", json_array_size(c));
	const json_t *r = record_of(c, "oecf");
	CHECK(r && json_real_value(json_object_get(r, "value")) == 2.0, "oecf: |dL| of the neutral");
	CHECK(r && !strcmp(json_string_value(json_object_get(r, "level")), "A") &&
	      json_integer_value(json_object_get(r, "stars")) == 3, "oecf 2.0: A (<= 2), 3 stars (< 3)");
	r = record_of(c, "white_balance");
	CHECK(r && !strcmp(json_string_value(json_object_get(r, "level")), "B") &&
	      json_integer_value(json_object_get(r, "stars")) == 2, "white balance 4.0: B, 2 stars");
	r = record_of(c, "noise");
	CHECK(r && !strcmp(json_string_value(json_object_get(r, "level")), "A") &&
	      json_integer_value(json_object_get(r, "stars")) == 3, "noise 1.0: A, 3 stars");
	r = record_of(c, "illuminance_non_uniformity");
	CHECK(r && json_is_null(json_object_get(r, "level")) &&
	      json_integer_value(json_object_get(r, "stars")) == 2, "3 %%: no ISO level, 2 stars");
	r = record_of(c, "colour_accuracy"); /* held out: mean 6, max 10, p90 10 */
	CHECK(r && !strcmp(json_string_value(json_object_get(r, "graded_on")), "held-out") &&
	      json_real_value(json_object_get(r, "value")) == 6.0, "colour graded held-out");
	CHECK(r && json_is_null(json_object_get(r, "level")) &&
	      json_integer_value(json_object_get(r, "stars")) == 1,
	      "colour: mean 6 above ISO C's 5 (no level); mean 6 < 6.5 and p90 10 not below "
	      "2 stars' 10: 1 star, got %d", (int)json_integer_value(json_object_get(r, "stars")));
	r = record_of(c, "sfr");
	CHECK(r && json_is_false(json_object_get(r, "measured")) &&
	      json_is_null(json_object_get(r, "value")), "sfr not measured");
	/* every record carries its limits' sources; a side without a published limit
	 * says so */
	for (size_t i = 0; i < 5; i++) {
		const json_t *tol = json_object_get(json_array_get(c, i), "tolerance");
		if (i == 4) /* colour accuracy: per statistic */
			tol = json_object_get(tol, "mean");
		const json_t *src = json_object_get(tol, "source");
		CHECK(json_is_string(json_object_get(src, "iso19264_1")) &&
		      json_is_string(json_object_get(src, "fadgi_2023")), "record %zu: no source", i);
	}
	r = record_of(c, "illuminance_non_uniformity");
	CHECK(r && strstr(json_string_value(json_object_get(json_object_get(json_object_get(
	                  r, "tolerance"), "source"), "iso19264_1")), "no published limit found"),
	      "illuminance non-uniformity: ISO side not said to be unsourced");
	json_decref(c);
	json_decref(patches);
	patches = json_pack("[{s:s, s:b, s:n, s:n, s:n, s:n, s:n}]", "id", "A01", "neutral", 0,
	                    "dL", "dab", "noise_L", "de00_d50", "de00_d50_heldout");
	c = kg_conformance(patches, NAN);
	for (size_t i = 0; i < 7; i++) {
		r = json_array_get(c, i);
		CHECK(json_is_false(json_object_get(r, "measured")) &&
		      json_is_null(json_object_get(r, "level")) &&
		      json_integer_value(json_object_get(r, "stars")) == 0, "%s passed unmeasured",
		      json_string_value(json_object_get(r, "id")));
	}
	json_decref(c);
	json_decref(patches);
}

int main(void)
{
	test_aggregates();
	test_fadgi();
	test_iso();
	test_conformance();
	test_grade_edges();
	return kg_test_done("report-grade");
}
