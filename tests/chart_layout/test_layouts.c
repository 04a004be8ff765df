/* The bundled chart layouts load, their geometry is sane, their ids match the
 * measurement files they go with; malformed layouts are refused with a message that
 * names the problem. */
#include "chart_test.h"

static void rect_of_patch(const kg_chart_patch *p, double r[4])
{
	r[0] = p->center_mm[0] - 0.5 * p->size_mm[0];
	r[1] = p->center_mm[1] - 0.5 * p->size_mm[1];
	r[2] = p->size_mm[0];
	r[3] = p->size_mm[1];
}

static int overlap(const double a[4], const double b[4])
{
	return a[0] < b[0] + b[2] && b[0] < a[0] + a[2] && a[1] < b[1] + b[3] &&
	       b[1] < a[1] + a[3];
}

static int inside(const double in[4], const double out[4])
{
	return in[0] >= out[0] && in[1] >= out[1] && in[0] + in[2] <= out[0] + out[2] &&
	       in[1] + in[3] <= out[1] + out[3];
}

/* Independent of kg_chart_layout_check: recomputed here from the raw numbers. */
static void check_geometry(const kg_chart_layout *l)
{
	double frame[4] = {0, 0, l->width_mm, l->height_mm};
	CHECK(inside(l->chart_area_mm, frame), "%s: chart area inside the frame", l->name);
	for (int i = 0; i < l->npatches; i++) {
		double r[4];
		rect_of_patch(&l->patches[i], r);
		CHECK(inside(r, l->chart_area_mm), "%s: patch %s inside the chart area", l->name,
		      l->patches[i].id);
		for (int j = 0; j < i; j++) {
			double s[4];
			rect_of_patch(&l->patches[j], s);
			CHECK(!overlap(r, s), "%s: patches %s and %s overlap", l->name,
			      l->patches[i].id, l->patches[j].id);
		}
	}
	CHECK(l->ntags == 4, "%s: %d tags", l->name, l->ntags);
	CHECK(strcmp(l->family, "tag36h11") == 0, "%s: family %s", l->name, l->family);
	for (int i = 0; i < l->ntags; i++) {
		const kg_chart_tag *t = &l->tags[i];
		CHECK(kg_chart_layout_find_tag(l, i) >= 0, "%s: tag id %d present", l->name, i);
		double fp[4];
		kg_chart_tag_footprint(l, i, fp);
		CHECK_NEAR(fp[2], t->size_mm * 10.0 / 8.0, 1e-9, "tag36h11 footprint = 10/8 size");
		CHECK(inside(fp, frame), "%s: tag %d inside the frame", l->name, t->id);
		CHECK(!overlap(fp, l->chart_area_mm), "%s: tag %d outside the chart area", l->name,
		      t->id);
		/* apriltag order: bottom-left, bottom-right, top-right, top-left (y down) */
		double h = 0.5 * t->size_mm, cx = t->center_mm[0], cy = t->center_mm[1];
		CHECK_NEAR(t->corners_mm[0][0], cx - h, 1e-9, "p0 x (left)");
		CHECK_NEAR(t->corners_mm[0][1], cy + h, 1e-9, "p0 y (bottom)");
		CHECK_NEAR(t->corners_mm[1][0], cx + h, 1e-9, "p1 x (right)");
		CHECK_NEAR(t->corners_mm[1][1], cy + h, 1e-9, "p1 y (bottom)");
		CHECK_NEAR(t->corners_mm[2][0], cx + h, 1e-9, "p2 x (right)");
		CHECK_NEAR(t->corners_mm[2][1], cy - h, 1e-9, "p2 y (top)");
		CHECK_NEAR(t->corners_mm[3][0], cx - h, 1e-9, "p3 x (left)");
		CHECK_NEAR(t->corners_mm[3][1], cy - h, 1e-9, "p3 y (top)");
	}
	/* tags in the corners: 0 top-left, 1 top-right, 2 bottom-right, 3 bottom-left */
	const kg_chart_tag *t0 = &l->tags[kg_chart_layout_find_tag(l, 0)];
	const kg_chart_tag *t2 = &l->tags[kg_chart_layout_find_tag(l, 2)];
	CHECK(t0->center_mm[0] < l->chart_area_mm[0] && t0->center_mm[1] < 0.5 * l->height_mm,
	      "%s: tag 0 at the top left", l->name);
	CHECK(t2->center_mm[0] > l->chart_area_mm[0] + l->chart_area_mm[2] &&
	      t2->center_mm[1] > 0.5 * l->height_mm, "%s: tag 2 at the bottom right", l->name);
	CHECK(l->sample_fraction > 0 && l->sample_fraction <= 1, "%s: sample fraction %g",
	      l->name, l->sample_fraction);
	kg_err err = {{0}};
	CHECK(kg_chart_layout_check(l, &err) == 0, "%s: check: %s", l->name, err.msg);
}

/* Every SAMPLE_ID (or, with loc_field, that field) of an ArgyllCMS file is a patch. */
static void check_ids_against(const kg_chart_layout *l, const char *path,
                              const char *field, int expected)
{
	if (!kg_test_file_exists(path)) {
		printf("note: %s absent (argyll-ref), ids not cross-checked\n", path);
		return;
	}
	kg_cgats *cg = NULL;
	kg_err err = {{0}};
	int ret = kg_cgats_read(path, &cg, &err);
	CHECK(ret == 0, "%s: %s", path, err.msg);
	if (ret)
		return;
	const kg_cgats_table *t = cg->tables[0];
	int f = kg_cgats_field(t, field);
	CHECK(f >= 0, "%s: no field %s", path, field);
	CHECK(t->nsets == expected, "%s: %d sets, expected %d", path, t->nsets, expected);
	for (int s = 0; f >= 0 && s < t->nsets; s++) {
		const char *id = t->cells[s * t->nfields + f];
		int i = kg_chart_layout_find_patch(l, id);
		CHECK(i >= 0 && strcmp(l->patches[i].id, id) == 0, "%s: %s %s is not a patch id of %s",
		      path, field, id, l->name);
	}
	kg_cgats_free(&cg);
}

/* The ColorChecker aliases are the 1..24 of ../shared/reference/charts, with the
 * same names. */
static void check_reference_numbering(const kg_chart_layout *l)
{
	const char *env = getenv("KOGEI_REFERENCE");
	char path[4096];
	snprintf(path, sizeof(path), "%s/charts/colorchecker24_ohta1997.csv",
	         env && *env ? env : KG_SOURCE_ROOT "/../shared/reference");
	if (!kg_test_file_exists(path)) {
		printf("note: %s absent, numbering not cross-checked\n", path);
		return;
	}
	kg_csv *csv = NULL;
	kg_err err = {{0}};
	int ret = kg_csv_read(path, &csv, &err);
	CHECK(ret == 0, "%s", err.msg);
	if (ret)
		return;
	int cp = kg_csv_column(csv, "patch"), cn = kg_csv_column(csv, "name");
	CHECK(csv->nrows == 24 && cp >= 0 && cn >= 0, "%s: 24 rows with patch, name", path);
	for (int r = 0; r < csv->nrows && cp >= 0 && cn >= 0; r++) {
		const char *num = kg_csv_cell(csv, r, cp), *name = kg_csv_cell(csv, r, cn);
		int i = kg_chart_layout_find_patch(l, num);
		CHECK(i >= 0, "%s: patch %s not found by alias", l->name, num);
		if (i >= 0)
			CHECK(strcasecmp(l->patches[i].name, name) == 0, "%s: patch %s (%s) is \"%s\" in "
			      "%s", l->name, num, l->patches[i].name, name, path);
	}
	kg_csv_free(&csv);
}

static void test_bundled(void)
{
	static const int npatches[NBUNDLED] = {24, 24, 140};
	for (int k = 0; k < NBUNDLED; k++) {
		kg_chart_layout *l = NULL;
		kg_err err = {{0}};
		int ret = kg_chart_layout_load(bundled_path(bundled_layouts[k]), &l, &err);
		CHECK(ret == 0, "%s: %s", bundled_layouts[k], err.msg);
		if (ret)
			continue;
		CHECK(strcmp(l->name, bundled_layouts[k]) == 0, "name %s", l->name);
		CHECK(l->npatches == npatches[k], "%s: %d patches", l->name, l->npatches);
		CHECK(!l->template_units, "%s: in mm", l->name);
		check_geometry(l);
		/* ids and aliases */
		int a01 = kg_chart_layout_find_patch(l, "A01");
		CHECK(a01 == 0, "%s: A01 first (%d)", l->name, a01);
		CHECK(kg_chart_layout_find_patch(l, "1") == a01, "%s: alias 1 is A01", l->name);
		CHECK(kg_chart_layout_find_patch(l, "no such patch") == -1, "unknown id");
		if (l->npatches == 24) {
			CHECK(kg_chart_layout_find_patch(l, "24") ==
			      kg_chart_layout_find_patch(l, "D06"), "%s: alias 24 is D06", l->name);
			CHECK(strcmp(l->patches[kg_chart_layout_find_patch(l, "D01")].name, "white 9.5 (.05 D)")
			      == 0, "%s: D01 is white", l->name);
			check_reference_numbering(l);
		} else {
			/* SG: column-major numbering, A01..A10 = 1..10, B01 = 11, N10 = 140 */
			CHECK(kg_chart_layout_find_patch(l, "11") == kg_chart_layout_find_patch(l, "B01"),
			      "SG alias 11 is B01");
			CHECK(kg_chart_layout_find_patch(l, "140") ==
			      kg_chart_layout_find_patch(l, "N10"), "SG alias 140 is N10");
		}
		/* sample corners: centred, sample_fraction of the patch */
		double c[4][2];
		kg_chart_patch_sample_corners(l, 0, c);
		const kg_chart_patch *p = &l->patches[0];
		CHECK_NEAR(c[2][0] - c[0][0], p->size_mm[0] * l->sample_fraction, 1e-9, "sample w");
		CHECK_NEAR(c[2][1] - c[0][1], p->size_mm[1] * l->sample_fraction, 1e-9, "sample h");
		CHECK_NEAR(0.5 * (c[0][0] + c[2][0]), p->center_mm[0], 1e-9, "sample centre x");
		CHECK_NEAR(c[1][1], c[0][1], 1e-12, "top edge");
		CHECK_NEAR(c[3][0], c[0][0], 1e-12, "left edge");
		kg_chart_layout_free(&l);
		CHECK(l == NULL, "free nulls the pointer");
	}

	/* ColorChecker ids are those of ColorChecker.cie; ColorCheckerPassport.cie names
	 * the same patches "A1".."D6", which find_patch maps onto "A01".."D06". */
	kg_chart_layout *cc = NULL, *sg = NULL, *pp = NULL;
	kg_err err = {{0}};
	if (kg_chart_layout_load(bundled_path("colorchecker-passport-frame"), &pp, &err) == 0) {
		CHECK(kg_chart_layout_find_patch(pp, "A1") == kg_chart_layout_find_patch(pp, "A01"),
		      "A1 finds A01");
		CHECK(kg_chart_layout_find_patch(pp, "D6") == kg_chart_layout_find_patch(pp, "D06"),
		      "D6 finds D06");
		CHECK(kg_chart_layout_find_patch(pp, "A001") == 0, "A001 finds A01");
		CHECK(kg_chart_layout_find_patch(pp, "A1x") == -1, "A1x finds nothing");
		CHECK(kg_chart_layout_find_patch(pp, "SAT1") == -1, "SAT1 is not on the page");
		kg_chart_layout_free(&pp);
	}
	if (kg_chart_layout_load(bundled_path("colorchecker24-frame"), &cc, &err) == 0) {
		check_ids_against(cc, "/usr/share/color/argyll/ref/ColorChecker.cie", "SAMPLE_ID", 24);
		/* row-major: A01..A06 the first row, left to right */
		const kg_chart_patch *a1 = &cc->patches[kg_chart_layout_find_patch(cc, "A01")];
		const kg_chart_patch *a2 = &cc->patches[kg_chart_layout_find_patch(cc, "A02")];
		const kg_chart_patch *b1 = &cc->patches[kg_chart_layout_find_patch(cc, "B01")];
		CHECK(a2->center_mm[0] > a1->center_mm[0] && fabs(a2->center_mm[1] -
		      a1->center_mm[1]) < 1e-9, "A02 right of A01");
		CHECK(b1->center_mm[1] > a1->center_mm[1], "B01 below A01");
		CHECK_NEAR(a1->size_mm[0], 40.0, 1e-9, "ColorChecker patch 40 mm");
		kg_chart_layout_free(&cc);
	}
	if (kg_chart_layout_load(bundled_path("colorchecker-sg-frame"), &sg, &err) == 0) {
		check_ids_against(sg, "/usr/share/color/argyll/ref/ColorCheckerSG.ti2", "SAMPLE_LOC",
		                  140);
		kg_chart_layout_free(&sg);
	}
}

/* A minimal valid layout with one substitution: `from` replaced by `to`. */
static const char base_layout[] =
	"{\"format\": \"kogei-chart/1\", \"name\": \"t\", \"frame_mm\": [200, 100],\n"
	" \"chart_area_mm\": [50, 10, 100, 80], \"sample_fraction\": 0.5,\n"
	" \"tag_family\": \"tag36h11\",\n"
	" \"tags\": [{\"id\": 0, \"center_mm\": [20, 20], \"size_mm\": 16},\n"
	"          {\"id\": 1, \"center_mm\": [180, 80], \"size_mm\": 16}],\n"
	" \"patches\": [{\"id\": \"A01\", \"center_mm\": [70, 30], \"size_mm\": [20, 20]},\n"
	"             {\"id\": \"A02\", \"alias\": \"2\", \"center_mm\": [100, 30], "
	"\"size_mm\": [20, 20]}]}\n";

static void expect_refusal(const char *dir, const char *from, const char *to,
                           const char *message_part)
{
	char text[4096], path[4200];
	const char *at = strstr(base_layout, from);
	if (!at) {
		CHECK(0, "test bug: '%s' not in the base layout", from);
		return;
	}
	snprintf(text, sizeof(text), "%.*s%s%s", (int)(at - base_layout), base_layout, to,
	         at + strlen(from));
	snprintf(path, sizeof(path), "%s/bad.json", dir);
	write_text(path, text);
	kg_chart_layout *l = NULL;
	kg_err err = {{0}};
	int ret = kg_chart_layout_load(path, &l, &err);
	CHECK(ret == KG_EINVAL, "'%s' -> '%s': ret %d (%s)", from, to, ret, err.msg);
	CHECK(l == NULL, "no layout on failure");
	CHECK(strstr(err.msg, message_part) != NULL, "'%s' -> '%s': message \"%s\" lacks \"%s\"",
	      from, to, err.msg, message_part);
	kg_chart_layout_free(&l);
}

static void test_malformed(void)
{
	char *dir = make_scratch();
	char path[4200];
	snprintf(path, sizeof(path), "%s/ok.json", dir);
	write_text(path, base_layout);
	kg_chart_layout *l = NULL;
	kg_err err = {{0}};
	CHECK(kg_chart_layout_load(path, &l, &err) == 0, "base layout: %s", err.msg);
	kg_chart_layout_free(&l);

	expect_refusal(dir, "kogei-chart/1", "kogei-chart/9", "expected \"kogei-chart/1\"");
	expect_refusal(dir, "\"frame_mm\": [200, 100]", "\"frame_mm\": [200]", "frame_mm");
	expect_refusal(dir, "\"frame_mm\": [200, 100]", "\"frame_mm\": [-200, 100]",
	               "expected positive sizes");
	expect_refusal(dir, "[70, 30]", "[40, 30]", "patch A01");               /* outside area */
	expect_refusal(dir, "[100, 30]", "[80, 30]", "patches A01 and A02 overlap");
	expect_refusal(dir, "\"A02\"", "\"A01\"", "appears twice");
	expect_refusal(dir, "\"tag36h11\"", "\"tag25h9\"", "tag family");
	expect_refusal(dir, "\"id\": 1,", "\"id\": 600,", "tag id 600");
	expect_refusal(dir, "\"id\": 1,", "\"id\": 0,", "tag id 0 appears twice");
	expect_refusal(dir, "[180, 80]", "[150, 80]", "tag 1 overlaps the chart area");
	expect_refusal(dir, "[180, 80]", "[195, 80]", "not inside the");
	expect_refusal(dir, "[180, 80]", "[30, 30]", "tags 0 and 1 overlap");
	expect_refusal(dir, "\"sample_fraction\": 0.5", "\"sample_fraction\": 1.5",
	               "sample_fraction");
	expect_refusal(dir, "\"size_mm\": [20, 20]}]", "\"size_mm\": [20, 0]}]",
	               "positive size");
	expect_refusal(dir, "\"patches\": [", "\"patches\": [], \"x\": [", "non-empty array");
	expect_refusal(dir, "\"format\"", "\"format\": 1, \"f\"", "format");

	/* syntax errors come from the JSON reader, naming the file */
	snprintf(path, sizeof(path), "%s/syntax.json", dir);
	write_text(path, "{\"format\": ");
	CHECK(kg_chart_layout_load(path, &l, &err) != 0 && strstr(err.msg, "syntax.json"),
	      "syntax error names the file: %s", err.msg);
	snprintf(path, sizeof(path), "%s/missing.json", dir);
	CHECK(kg_chart_layout_load(path, &l, &err) != 0, "missing file refused");
	CHECK(kg_chart_layout_load(NULL, &l, &err) == KG_EINVAL, "NULL path refused");
	rm_scratch(dir);
}

int main(void)
{
	test_bundled();
	test_malformed();
	return kg_test_done("chart-layouts");
}
