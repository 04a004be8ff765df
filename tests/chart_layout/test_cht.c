/* The ArgyllCMS .cht reader: every template under /usr/share/color/argyll/ref
 * (skipped without argyll-ref), the geometry of three known ones, scaling to a
 * physical width, and malformed templates refused with a message naming the line. */
#include <dirent.h>
#include <ctype.h>

#include "chart_test.h"

#define ARGYLL_REF "/usr/share/color/argyll/ref"

/* Every id listed under EXPECTED is a patch of the layout (ids as the template
 * writes them). Returns the number of ids checked. */
static int check_expected_ids(const char *path, const kg_chart_layout *l)
{
	char *buf = NULL;
	size_t len;
	kg_err err = {{0}};
	if (kg_read_file(path, &buf, &len, &err) != 0)
		return 0;
	int checked = 0;
	char *save = NULL;
	int in_expected = 0;
	for (char *line = strtok_r(buf, "\r\n", &save); line; line = strtok_r(NULL, "\r\n", &save)) {
		char first[64] = "";
		if (sscanf(line, "%63s", first) != 1)
			continue;
		if (strcmp(first, "EXPECTED") == 0) {
			in_expected = 1;
			continue;
		}
		if (!in_expected)
			continue;
		int found = 0;
		for (int i = 0; i < l->npatches; i++)
			if (strcmp(l->patches[i].id, first) == 0)
				found = 1;
		CHECK(found, "%s: EXPECTED id %s is not a box of the template", path, first);
		checked++;
	}
	free(buf);
	return checked;
}

static void test_all_templates(void)
{
	DIR *d = opendir(ARGYLL_REF);
	if (!d)
		kg_test_skip(ARGYLL_REF " is absent (package argyll-ref)");
	int n = 0;
	struct dirent *e;
	while ((e = readdir(d))) {
		size_t len = strlen(e->d_name);
		if (len < 5 || strcmp(e->d_name + len - 4, ".cht") != 0)
			continue;
		char path[4200];
		snprintf(path, sizeof(path), "%s/%s", ARGYLL_REF, e->d_name);
		kg_chart_layout *l = NULL;
		kg_err err = {{0}};
		int ret = kg_chart_layout_load(path, &l, &err);
		CHECK(ret == 0, "%s: %s", path, err.msg);
		if (ret)
			continue;
		CHECK(l->template_units == 1, "%s: template units", path);
		CHECK(l->npatches > 0 && l->ntags == 0, "%s: %d patches, %d tags", path, l->npatches,
		      l->ntags);
		int checked = check_expected_ids(path, l);
		CHECK(checked > 0, "%s: no EXPECTED ids", path);
		printf("%-32s %4d boxes, %4d expected ids, area %.1f x %.1f, sample %.3f\n",
		       e->d_name, l->npatches, checked, l->chart_area_mm[2], l->chart_area_mm[3],
		       l->sample_fraction);
		/* printing a template needs a physical scale */
		CHECK(kg_chart_print(l, "/nonexistent/x.svg", 150, &err) == KG_EINVAL &&
		      strstr(err.msg, "template units"), "%s: print refused: %s", path, err.msg);
		kg_chart_layout_free(&l);
		n++;
	}
	closedir(d);
	if (n == 0)
		kg_test_skip("no .cht templates in " ARGYLL_REF);
	CHECK(n >= 20, "only %d templates read", n);
}

static const kg_chart_patch *patch(const kg_chart_layout *l, const char *id)
{
	int i = kg_chart_layout_find_patch(l, id);
	CHECK(i >= 0, "%s: no patch %s", l->name, id);
	return i >= 0 ? &l->patches[i] : &l->patches[0];
}

static void test_known_templates(void)
{
	kg_chart_layout *l = NULL;
	kg_err err = {{0}};
	/* ColorChecker: "Y 1 6 A D 46 46 12 11.5 52.5 52.5", BOX_SHRINK 6 */
	CHECK(kg_chart_layout_load_cht(ARGYLL_REF "/ColorChecker.cht", 0, &l, &err) == 0, "%s",
	      err.msg);
	if (l) {
		CHECK(l->npatches == 24, "24 boxes (%d)", l->npatches);
		CHECK(strcmp(l->name, "ColorChecker") == 0, "name %s", l->name);
		CHECK(strcmp(l->patches[0].id, "A1") == 0 && strcmp(l->patches[5].id, "A6") == 0 &&
		      strcmp(l->patches[23].id, "D6") == 0, "Y boxes: y label first, rows of x");
		CHECK_NEAR(patch(l, "A1")->center_mm[0], 12 + 23, 1e-9, "A1 x");
		CHECK_NEAR(patch(l, "A1")->center_mm[1], 11.5 + 23, 1e-9, "A1 y");
		CHECK_NEAR(patch(l, "A2")->center_mm[0], 12 + 52.5 + 23, 1e-9, "A2 steps in x");
		CHECK_NEAR(patch(l, "D6")->center_mm[1], 11.5 + 3 * 52.5 + 23, 1e-9, "D6 y");
		CHECK_NEAR(patch(l, "B3")->size_mm[0], 46, 1e-12, "box size");
		CHECK_NEAR(l->sample_fraction, 1 - 12.0 / 46.0, 1e-12, "BOX_SHRINK 6 of 46");
		/* area: F (10, 9.75)-(321.26, 217) and the boxes (to 320.5, 215) */
		CHECK_NEAR(l->chart_area_mm[0], 10, 1e-9, "area x");
		CHECK_NEAR(l->chart_area_mm[1], 9.75, 1e-9, "area y");
		CHECK_NEAR(l->chart_area_mm[2], 311.26, 1e-9, "area w");
		CHECK_NEAR(l->chart_area_mm[3], 207.25, 1e-9, "area h");
		kg_chart_layout_free(&l);
	}
	/* scaled: the chart area becomes 279.4 mm wide, everything with it */
	CHECK(kg_chart_layout_load_cht(ARGYLL_REF "/ColorChecker.cht", 279.4, &l, &err) == 0,
	      "%s", err.msg);
	if (l) {
		double s = 279.4 / 311.26;
		CHECK(l->template_units == 0, "scaled layout is in mm");
		CHECK_NEAR(l->chart_area_mm[2], 279.4, 1e-9, "scaled width");
		CHECK_NEAR(patch(l, "A1")->size_mm[0], 46 * s, 1e-9, "scaled box");
		CHECK_NEAR(patch(l, "D6")->center_mm[0], (12 + 5 * 52.5 + 23) * s, 1e-9, "scaled x");
		CHECK_NEAR(l->sample_fraction, 1 - 12.0 / 46.0, 1e-12, "fraction is scale-free");
		kg_chart_layout_free(&l);
	}
	/* SG: "X A N 1 10": x label first, columns A..N, rows 1..10 */
	CHECK(kg_chart_layout_load(ARGYLL_REF "/ColorCheckerSG.cht", &l, &err) == 0, "%s",
	      err.msg);
	if (l) {
		CHECK(l->npatches == 140, "140 boxes (%d)", l->npatches);
		CHECK_NEAR(patch(l, "A10")->center_mm[0], 27.5 + 12.675 / 2, 1e-9, "A10 x");
		CHECK_NEAR(patch(l, "A10")->center_mm[1], 20 + 9 * 15.25 + 12.75 / 2, 1e-9, "A10 y");
		CHECK_NEAR(patch(l, "N1")->center_mm[0], 27.5 + 13 * 15.175 + 12.675 / 2, 1e-9,
		           "N1 x");
		CHECK(kg_chart_layout_find_patch(l, "N11") < 0 && kg_chart_layout_find_patch(l, "O1") < 0,
		      "nothing beyond N10");
		kg_chart_layout_free(&l);
	}
	/* Passport: five box lines, negative y steps, multi-letter labels */
	CHECK(kg_chart_layout_load(ARGYLL_REF "/ColorCheckerPassport.cht", &l, &err) == 0, "%s",
	      err.msg);
	if (l) {
		CHECK(l->npatches == 50, "50 boxes (%d)", l->npatches);
		CHECK_NEAR(patch(l, "SAT8")->center_mm[1], 102.1 - 7 * 12.9 + 5, 1e-9, "SAT8 y");
		CHECK(patch(l, "A6")->center_mm[1] < patch(l, "A1")->center_mm[1], "A6 above A1");
		CHECK(patch(l, "D1")->center_mm[0] > patch(l, "A1")->center_mm[0], "D1 right of A1");
		kg_chart_layout_free(&l);
	}
	/* it8: "X GS00 GS23 _ _": digits carry inside a label, "_" is no label */
	CHECK(kg_chart_layout_load(ARGYLL_REF "/it8.cht", &l, &err) == 0, "%s", err.msg);
	if (l) {
		CHECK(kg_chart_layout_find_patch(l, "GS09") >= 0 &&
		      kg_chart_layout_find_patch(l, "GS10") >= 0 &&
		      kg_chart_layout_find_patch(l, "GS23") >= 0 &&
		      kg_chart_layout_find_patch(l, "GS24") < 0, "GS00..GS23");
		CHECK(kg_chart_layout_find_patch(l, "L22") >= 0 && kg_chart_layout_find_patch(l, "A01")
		      >= 0, "Y 01 22 A L keeps the zero");
		kg_chart_layout_free(&l);
	}
}

/* A small valid template with one substitution. */
static const char base_cht[] =
	"\n"
	"BOXES 5\n"
	"  F _ _ 1 1  41 1  41 31  1 31\n"
	"  D ALL ALL _ _ 42 32 0 0 0 0\n"
	"  Y 1 2 A B  8 8  10 10  12 12\n"
	"\n"
	"BOX_SHRINK 1.0\n"
	"\n"
	"REF_ROTATION 0.0\n"
	"\n"
	"XLIST 2\n"
	"  10 1.0 1.0\n"
	"  18 1.0 1.0\n"
	"\n"
	"YLIST 1\n"
	"  10 1.0 1.0\n"
	"\n"
	"EXPECTED XYZ 4\n"
	"  A1 10 10 10\n"
	"  A2 20 20 20\n"
	"  B1 30 30 30\n"
	"  B2 40 40 40\n";

static void expect_cht(const char *dir, const char *from, const char *to, int ok,
                       const char *message_part)
{
	char text[4096], path[4200];
	const char *at = strstr(base_cht, from);
	if (!at) {
		CHECK(0, "test bug: '%s' not in the base template", from);
		return;
	}
	snprintf(text, sizeof(text), "%.*s%s%s", (int)(at - base_cht), base_cht, to,
	         at + strlen(from));
	snprintf(path, sizeof(path), "%s/t.cht", dir);
	write_text(path, text);
	kg_chart_layout *l = NULL;
	kg_err err = {{0}};
	int ret = kg_chart_layout_load(path, &l, &err);
	if (ok) {
		CHECK(ret == 0, "'%s' -> '%s': %s", from, to, err.msg);
	} else {
		CHECK(ret == KG_EINVAL && l == NULL, "'%s' -> '%s': ret %d", from, to, ret);
		CHECK(strstr(err.msg, message_part) != NULL,
		      "'%s' -> '%s': message \"%s\" lacks \"%s\"", from, to, err.msg, message_part);
		CHECK(strstr(err.msg, "t.cht") != NULL, "message names the file: %s", err.msg);
	}
	kg_chart_layout_free(&l);
}

static void test_malformed(void)
{
	char *dir = make_scratch();
	expect_cht(dir, "BOXES 5", "BOXES 5", 1, "");
	expect_cht(dir, "BOXES 5", "BOXES 6", 0, "declares 6 boxes");
	expect_cht(dir, "BOXES 5", "BOXES five", 0, "count \"five\"");
	expect_cht(dir, "BOXES 5", "BOXEN 5", 0, "\"BOXEN\": expected BOXES");
	expect_cht(dir, "Y 1 2 A B", "Y 1 2 B A", 0, "never reaches A");
	expect_cht(dir, "Y 1 2 A B", "Y 1 2 A _", 0, "\"_\" must be used for both");
	expect_cht(dir, "Y 1 2 A B", "Y 1 2 A- B-", 0, "cannot be stepped");
	expect_cht(dir, "8 8  10 10", "8 x  10 10", 0, "height: \"x\" is not a number");
	expect_cht(dir, "8 8  10 10", "8 0  10 10", 0, "expected positive sizes");
	expect_cht(dir, "8 8  10 10  12 12", "8 8  10 10  12", 0, "expected 4 labels and 6 numbers");
	expect_cht(dir, "12 12\n", "6 6\n", 0, "overlap");
	expect_cht(dir, "10 10  12 12", "-5 10  12 12", 0, "negative coordinates");
	expect_cht(dir, "  F _ _ 1 1  41 1", "  F _ _ 1 1  41", 0, "F line");
	expect_cht(dir, "  Y 1 2", "  Q 1 2", 0, "expected F, D, X or Y");
	expect_cht(dir, "BOX_SHRINK 1.0", "BOX_SHRINK 4.0", 0, "leaves nothing");
	expect_cht(dir, "BOX_SHRINK 1.0", "BOX_SHRINK -1", 0, "expected >= 0");
	expect_cht(dir, "XLIST 2", "XLIST 3", 0, "XLIST line 3 of 3");
	expect_cht(dir, "EXPECTED XYZ 4", "EXPECTED XYZ 5", 0, "EXPECTED declares 5 lines");
	expect_cht(dir, "EXPECTED XYZ 4", "EXPECTED 4", 0, "colour space and a count");
	expect_cht(dir, "\nBOXES 5\n", "\nBOXES 5\nBOXES 5\n", 0, "a second BOXES");
	expect_cht(dir, "  Y 1 2 A B  8 8  10 10  12 12\n", "", 0, "no X or Y sample boxes");
	/* an unlabelled "_ _" x range, a lower-case label range, CRLF line ends */
	expect_cht(dir, "Y 1 2 A B  8 8  10 10  12 12", "X a b _ _  8 8  10 10  12 12\n"
	           "  X _ _ 1 2  8 8  10 30  0 12", 1, "");
	char path[4200];
	kg_chart_layout *l = NULL;
	kg_err err = {{0}};
	/* CRLF */
	char crlf[4096];
	size_t k = 0;
	for (const char *s = base_cht; *s && k < sizeof(crlf) - 2; s++) {
		if (*s == '\n')
			crlf[k++] = '\r';
		crlf[k++] = *s;
	}
	crlf[k] = '\0';
	snprintf(path, sizeof(path), "%s/crlf.cht", dir);
	write_text(path, crlf);
	CHECK(kg_chart_layout_load(path, &l, &err) == 0 && l->npatches == 4, "CRLF: %s", err.msg);
	kg_chart_layout_free(&l);
	/* empty file, NUL bytes, no BOXES */
	snprintf(path, sizeof(path), "%s/empty.cht", dir);
	write_text(path, "");
	CHECK(kg_chart_layout_load(path, &l, &err) == KG_EINVAL && strstr(err.msg, "no BOXES"),
	      "empty: %s", err.msg);
	snprintf(path, sizeof(path), "%s/nul.cht", dir);
	FILE *fp = fopen(path, "wb");
	fwrite("BOXES 1\0\n", 1, 9, fp);
	fclose(fp);
	CHECK(kg_chart_layout_load(path, &l, &err) == KG_EINVAL && strstr(err.msg, "NUL"),
	      "NUL: %s", err.msg);
	snprintf(path, sizeof(path), "%s/missing.cht", dir);
	CHECK(kg_chart_layout_load(path, &l, &err) != 0 && l == NULL, "missing file refused");
	CHECK(kg_chart_layout_load_cht(path, -1, &l, &err) == KG_EINVAL, "negative width");
	rm_scratch(dir);
}

int main(void)
{
	test_malformed();
	test_known_templates();
	test_all_templates();
	return kg_test_done("chart-cht");
}
