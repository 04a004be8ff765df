/* CGATS written by kogei reads back equal: a hand-built table (keywords, quoted text,
 * several tables) and a patch set with spectra, RGB and extra columns. */
#include <string.h>
#include <unistd.h>

#include "kg_core.h"
#include "kg_test.h"

static char tmpdir[] = "/tmp/kg-cgats-rt-XXXXXX";

static void test_table_roundtrip(void)
{
	kg_err err = { { 0 } };
	kg_cgats *cg = NULL, *back = NULL;
	kg_cgats_table *t, *t2;
	CHECK(kg_cgats_new(NULL, &cg, &err) == 0, "%s", err.msg);
	t = cg->tables[0];
	CHECK(kg_cgats_set_keyword(t, "DESCRIPTOR", "round trip # not a comment", &err) == 0,
	      "%s", err.msg);
	CHECK(kg_cgats_set_keyword(t, "LIGHT", "D50", &err) == 0, "%s", err.msg);
	CHECK(kg_cgats_set_keyword_number(t, "EXPOSURE_S", 0.125, &err) == 0, "%s", err.msg);
	CHECK(kg_cgats_set_keyword(t, "LIGHT", "D65", &err) == 0, "replace: %s", err.msg);
	CHECK(kg_cgats_set_keyword(t, "BAD", "say \"hi\"", &err) == KG_EINVAL,
	      "quote in a keyword value refused");
	const char *fields[] = { "SAMPLE_ID", "SAMPLE_NAME", "RGB_R", "RGB_G", "RGB_B",
		                     "SPREAD" };
	CHECK(kg_cgats_set_fields(t, fields, 6, &err) == 0, "%s", err.msg);
	const char *row1[] = { "A1", "dark skin", "0.1", "0.2", "0.3", "0.01" };
	CHECK(kg_cgats_add_row(t, row1, &err) == 0, "%s", err.msg);
	const char *row0[] = { "END_DATA", "#1", "0.1", "0.2", "0.3", "0" };
	CHECK(kg_cgats_add_row(t, row0, &err) == 0, "%s", err.msg);
	int set;
	CHECK(kg_cgats_append_set(t, &set, &err) == 0 && set == 2, "%s", err.msg);
	CHECK(kg_cgats_set_cell(t, set, 0, "A2", &err) == 0, "%s", err.msg);
	CHECK(kg_cgats_set_cell(t, set, 1, "", &err) == 0, "%s", err.msg);
	double third = 1.0 / 3.0;
	for (int f = 2; f < 6; f++)
		CHECK(kg_cgats_set_cell_number(t, set, f, third * f, &err) == 0, "%s", err.msg);
	CHECK(kg_cgats_set_cell_number(t, set, 2, NAN, &err) == KG_EINVAL, "NaN refused");

	CHECK(kg_cgats_add_table(cg, "CTI1", &t2, &err) == 0, "%s", err.msg);
	const char *f2[] = { "INDEX", "XYZ_X", "XYZ_Y", "XYZ_Z" };
	CHECK(kg_cgats_set_fields(t2, f2, 4, &err) == 0, "%s", err.msg);
	double v[3] = { 95.047, 100, 108.883 };
	CHECK(kg_cgats_add_row_numbers(t2, "0", v, 3, &err) == 0, "%s", err.msg);
	CHECK(kg_cgats_add_row_numbers(t2, "1", v, 2, &err) == KG_EINVAL, "short row refused");

	CHECK(kg_cgats_write(cg, "/nonexistent/dir/t.cgats", &err) == KG_EIO &&
	          strstr(err.msg, "/nonexistent/dir/t.cgats"), "unwritable path: %s", err.msg);
	char *path = kg_path_join(tmpdir, "table.cgats");
	CHECK(kg_cgats_write(cg, path, &err) == 0, "%s", err.msg);
	CHECK(kg_cgats_read(path, &back, &err) == 0, "%s", err.msg);
	if (back) {
		CHECK(back->ntables == 2, "2 tables, got %d", back->ntables);
		for (int k = 0; k < back->ntables && k < 2; k++) {
			const kg_cgats_table *a = cg->tables[k], *b = back->tables[k];
			CHECK(strcmp(a->type, b->type) == 0, "type %s vs %s", a->type, b->type);
			CHECK(a->nkeywords == b->nkeywords, "keywords %d vs %d", a->nkeywords,
			      b->nkeywords);
			for (int i = 0; i < a->nkeywords && i < b->nkeywords; i++)
				CHECK(!strcmp(a->keywords[i].name, b->keywords[i].name) &&
				          !strcmp(a->keywords[i].value, b->keywords[i].value),
				      "keyword %s", a->keywords[i].name);
			CHECK(a->nfields == b->nfields && a->nsets == b->nsets, "shape");
			for (int i = 0; i < a->nfields && a->nfields == b->nfields; i++)
				CHECK(!strcmp(a->fields[i], b->fields[i]), "field %s", a->fields[i]);
			for (int s = 0; s < a->nsets && a->nsets == b->nsets; s++)
				for (int i = 0; i < a->nfields && a->nfields == b->nfields; i++)
					CHECK(!strcmp(kg_cgats_cell(a, s, i), kg_cgats_cell(b, s, i)),
					      "cell %d,%d: '%s' vs '%s'", s, i, kg_cgats_cell(a, s, i),
					      kg_cgats_cell(b, s, i));
			CHECK(b->set_lines[0] > 0, "source lines recorded");
		}
		double x;
		CHECK(kg_cgats_number(back->tables[0], 2, 3, &x, &err) == 0 && x == third * 3,
		      "numbers read back exactly: %.17g", x);
		CHECK(kg_cgats_keyword_number(back->tables[0], "EXPOSURE_S", &x, &err) == 0 &&
		          x == 0.125, "keyword number");
		CHECK(!strcmp(kg_cgats_keyword(back->tables[0], "LIGHT"), "D65"), "replaced keyword");
		CHECK(kg_cgats_number(back->tables[0], 0, 1, &x, &err) == KG_EINVAL &&
		          strstr(err.msg, "SAMPLE_NAME") && strstr(err.msg, "line"),
		      "text cell as number: %s", err.msg);
	}
	unlink(path);
	free(path);
	kg_cgats_free(&back);
	kg_cgats_free(&cg);
	CHECK(cg == NULL, "free nulls the pointer");
}

static void test_patchset_roundtrip(void)
{
	kg_err err = { { 0 } };
	kg_patchset *ps = NULL, *back = NULL;
	CHECK(kg_patchset_new(3, KG_PATCH_SPECTRA | KG_PATCH_RGB, &ps, &err) == 0, "%s",
	      err.msg);
	if (!ps)
		return;
	CHECK(kg_patchset_add_extra(ps, "CLIPPED", &err) == 0, "%s", err.msg);
	CHECK(kg_patchset_add_extra(ps, "SPREAD", &err) == 0, "%s", err.msg);
	for (int i = 0; i < 3; i++) {
		char id[16];
		snprintf(id, sizeof(id), "P%d", i + 1);
		CHECK(kg_patchset_set_id(ps, i, id, &err) == 0, "%s", err.msg);
		for (int b = 0; b < KG_NBANDS; b++)
			ps->spectra[i].v[b] = 0.05 + 0.9 * b / 60.0 * (i + 1) / 3.0 + 1e-7 * b;
		for (int k = 0; k < 3; k++)
			ps->rgb[i][k] = 0.1 * (i + 1) + 0.01 * k + 1.0 / 7.0;
		ps->extra[i * 2 + 0] = i * 0.001;
		ps->extra[i * 2 + 1] = 1.0 / (i + 3);
	}
	char *path = kg_path_join(tmpdir, "patches.cgats");
	const char *kw[] = { "DESCRIPTOR", "test patches", "LIGHT", "D50", NULL };
	CHECK(kg_patchset_write(path, ps, KG_PATCH_SPECTRA | KG_PATCH_RGB | KG_PATCH_EXTRA, kw,
	                        &err) == 0, "%s", err.msg);
	CHECK(kg_patchset_write(path, ps, KG_PATCH_XYZ, NULL, &err) == KG_EINVAL,
	      "asking for absent XYZ refused");
	CHECK(kg_patchset_read(path, 0, &back, &err) == 0, "%s", err.msg);
	if (back) {
		CHECK(back->n == 3 && back->spectra && back->rgb && !back->xyz && !back->lab,
		      "columns present");
		CHECK(back->spectral_scale == 0.01, "written in percent, SPECTRAL_NORM 100");
		CHECK(back->nextra == 2 && kg_patchset_extra_index(back, "SPREAD") == 1, "extras");
		for (int i = 0; i < 3 && back->n == 3; i++) {
			CHECK(!strcmp(ps->ids[i], back->ids[i]), "id %s", back->ids[i]);
			for (int b = 0; b < KG_NBANDS; b++)
				CHECK(ps->spectra[i].v[b] == back->spectra[i].v[b], "band %d exact", b);
			for (int k = 0; k < 3; k++)
				CHECK(ps->rgb[i][k] == back->rgb[i][k], "rgb exact");
			for (int k = 0; k < 2 && back->nextra == 2; k++)
				CHECK(ps->extra[i * 2 + k] == back->extra[i * 2 + k], "extra exact");
		}
		CHECK(kg_patchset_find(back, "P2") == 1, "find P2");
		CHECK(kg_patchset_find(back, "P9") == -1, "find absent");
	}
	kg_cgats *cg = NULL;
	CHECK(kg_cgats_read(path, &cg, &err) == 0, "%s", err.msg);
	if (cg) {
		const kg_cgats_table *t = cg->tables[0];
		CHECK(!strcmp(kg_cgats_keyword(t, "LIGHT"), "D50"), "user keyword kept");
		CHECK(!strcmp(kg_cgats_keyword(t, "SPECTRAL_BANDS"), "61"), "SPECTRAL_BANDS");
		CHECK(kg_cgats_field(t, "SPEC_400") == 1 && kg_cgats_field(t, "SPEC_700") == 61,
		      "SAMPLE_ID then SPEC_400..SPEC_700");
	}
	kg_cgats_free(&cg);
	unlink(path);
	free(path);
	kg_patchset_free(&back);
	kg_patchset_free(&ps);
	CHECK(ps == NULL, "free nulls the pointer");
}

/* Spectra are written in percent for ArgyllCMS (SPECT, MEAS_TYPE REFLECTIVE,
 * SPECTRAL_NORM 100, a decimal point in every value) and still read back bit for bit:
 * awkward doubles, values whose x100 or /100 in binary would round, tiny, negative,
 * huge (up to the largest the reader takes, KG_SPECTRAL_MAX_ABS) and zero. */
static void test_percent_exact(void)
{
	enum { N = 40 };
	kg_err err = { { 0 } };
	kg_patchset *ps = NULL, *back = NULL;
	CHECK(kg_patchset_new(N, KG_PATCH_SPECTRA, &ps, &err) == 0, "%s", err.msg);
	if (!ps)
		return;
	const double special[] = { 0.0, -0.0, 1.0, 0.1, 0.07, 0.57, 1.0 / 3.0, 2.0 / 3.0,
		                       0.123456789012345678, 1e-300, 5e-324, -1e-12, -0.015,
		                       9.87654321e29, 123456.789, 0.9274505, 1.15, 0.29, 0.58, 0.285 };
	const int nspecial = sizeof(special) / sizeof(special[0]);
	unsigned long long x = 88172645463325252ull;
	for (int i = 0; i < N; i++)
		for (int b = 0; b < KG_NBANDS; b++) {
			int k = i * KG_NBANDS + b;
			x ^= x << 13;
			x ^= x >> 7;
			x ^= x << 17;
			ps->spectra[i].v[b] = k < nspecial ? special[k] : (double)(x >> 11) / 0x1p53 * 1.2;
		}
	char *path = kg_path_join(tmpdir, "percent.sp");
	CHECK(kg_patchset_write(path, ps, KG_PATCH_SPECTRA, NULL, &err) == 0, "%s", err.msg);
	kg_cgats *cg = NULL;
	CHECK(kg_cgats_read(path, &cg, &err) == 0, "%s", err.msg);
	if (cg) {
		const kg_cgats_table *t = cg->tables[0];
		const char *meas = kg_cgats_keyword(t, "MEAS_TYPE");
		const char *norm = kg_cgats_keyword(t, "SPECTRAL_NORM");
		CHECK(!strcmp(t->type, "SPECT"), "type %s, expected SPECT", t->type);
		CHECK(meas && !strcmp(meas, "REFLECTIVE"), "MEAS_TYPE REFLECTIVE");
		CHECK(norm && !strcmp(norm, "100"), "SPECTRAL_NORM 100");
		int f = kg_cgats_field(t, "SPEC_700");
		const char *c = kg_cgats_cell(t, 0, kg_cgats_field(t, "SPEC_400"));
		CHECK(c && !strcmp(c, "0.0"), "0 written as 0.0, found %s", c ? c : "(none)");
		c = kg_cgats_cell(t, 0, kg_cgats_field(t, "SPEC_420"));
		CHECK(c && !strcmp(c, "7.0"), "0.07 written as 7.0, found %s", c ? c : "(none)");
		for (int s = 0; s < t->nsets && f >= 0; s++)
			for (int k = 1; k < t->nfields; k++) {
				c = kg_cgats_cell(t, s, k);
				CHECK(strpbrk(c, ".e"), "set %d field %s: '%s' has no decimal point", s + 1,
				      t->fields[k], c);
			}
	}
	kg_cgats_free(&cg);
	CHECK(kg_patchset_read(path, 0, &back, &err) == 0, "%s", err.msg);
	int exact = 0;
	for (int i = 0; back && i < N; i++)
		for (int b = 0; b < KG_NBANDS; b++) {
			double a = ps->spectra[i].v[b], r = back->spectra[i].v[b];
			int same = a == r; /* -0 comes back as 0 from the grid interpolation */
			exact += same;
			CHECK(same, "patch %d band %d: wrote %.17g, read %.17g", i + 1, b, a, r);
		}
	printf("percent round trip: %d of %d values exact\n", exact, N * KG_NBANDS);
	unlink(path);
	free(path);
	kg_patchset_free(&ps);
	kg_patchset_free(&back);
}

int main(void)
{
	if (!mkdtemp(tmpdir)) {
		perror("mkdtemp");
		return 1;
	}
	test_table_roundtrip();
	test_patchset_roundtrip();
	test_percent_exact();
	rmdir(tmpdir);
	return kg_test_done("cgats-roundtrip");
}
