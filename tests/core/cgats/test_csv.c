/* The CSV readers on the reference data in ../shared/reference, plus malformed input. */
#include <string.h>
#include <unistd.h>

#include "kg_core.h"
#include "kg_test.h"

static char *ref_path(const char *rel)
{
	return kg_path_join(kg_test_reference_dir(), rel);
}

static void test_camera(void)
{
	char *path = ref_path("cameras/Nikon_D5100.csv");
	kg_err err = { { 0 } };
	kg_csv *t = NULL;
	CHECK(kg_csv_read(path, &t, &err) == 0, "%s", err.msg);
	if (t) {
		CHECK(t->ncols == 4 && t->nrows == 81, "81 rows of 4 columns");
		CHECK(kg_csv_column(t, "g") == 2 && kg_csv_column(t, "x") == -1, "columns");
		CHECK(t->row_lines[0] == 2, "first data row is line 2");
	}
	kg_csv_free(&t);

	/* File lines: "400,0,0,0.001532461" and "550,0.041188738,0.889102316,0.065253131" */
	const char *rgb[] = { "r", "g", "b" };
	double *wl = NULL, *v = NULL;
	int n = 0;
	CHECK(kg_csv_read_columns(path, rgb, 3, &wl, &v, &n, &err) == 0, "%s", err.msg);
	if (n == 81) {
		CHECK(wl[4] == 400 && v[4 * 3 + 2] == 0.001532461, "400 nm row");
		CHECK(wl[34] == 550 && v[34 * 3 + 1] == 0.889102316, "550 nm row");
	}
	free(wl);
	free(v);

	kg_spectrum css[3];
	CHECK(kg_csv_read_column_spectra(path, rgb, 3, 0, css, &err) == 0, "%s", err.msg);
	CHECK_NEAR(css[1].v[30], 0.889102316, 1e-12, "green at 550 nm on the grid");
	CHECK_NEAR(css[2].v[0], 0.001532461, 1e-12, "blue at 400 nm on the grid");

	const char *bad[] = { "r", "nir" };
	CHECK(kg_csv_read_columns(path, bad, 2, &wl, &v, &n, &err) == KG_EINVAL &&
	          strstr(err.msg, "nir") && strstr(err.msg, "Nikon_D5100.csv"),
	      "absent column named: %s", err.msg);
	free(path);

	/* Jiang et al. 400-720 / 10 nm */
	path = ref_path("cameras/jiang2013_camspec_CC-BY-NC-SA/Canon_20D.csv");
	if (kg_test_file_exists(path))
		CHECK(kg_csv_read_column_spectra(path, rgb, 3, 0, css, &err) == 0, "%s", err.msg);
	free(path);

	path = ref_path("nk/Au_JohnsonChristy1972.csv");
	const char *nk[] = { "n", "k" };
	kg_spectrum au[2];
	CHECK(kg_csv_read_column_spectra(path, nk, 2, 0, au, &err) == 0, "%s", err.msg);
	CHECK(au[1].v[0] > 1.0 && au[1].v[60] > 3.0, "gold k rises to the red");
	free(path);
}

static void test_spectra_rows(void)
{
	static const struct {
		const char *file;
		int n;
		const char *first_id;
	} files[] = {
		{ "charts/colorchecker24_ohta1997.csv", 24, "1" },
		{ "charts/colorchecker24_babelcolor_avg.csv", 24, "1" },
		{ "charts/pmc30_luo2024_10nm.csv", 30, NULL },
		{ "reflectance/cie1995_tcs14_5nm.csv", 14, NULL },
		{ "reflectance/cie2017_cfi_ces99_5nm.csv", 99, NULL },
		{ "reflectance/uef_natural219_koivisto_5nm.csv", 219, NULL },
		{ "reflectance/vrhel1994_170_2nm.csv", 170, "1" },
		{ "reflectance/rawtoaces_training190.csv", 190, "patch1" },
		{ "reflectance/munsell_matt_uef1269_5nm.csv", 1269, NULL },
	};
	for (size_t k = 0; k < sizeof(files) / sizeof(files[0]); k++) {
		char *path = ref_path(files[k].file);
		kg_err err = { { 0 } };
		kg_patchset *ps = NULL;
		CHECK(kg_csv_read_spectra_rows(path, 0, &ps, &err) == 0, "%s", err.msg);
		if (ps) {
			CHECK(ps->n == files[k].n, "%s: %d rows, expected %d", files[k].file, ps->n,
			      files[k].n);
			CHECK(!files[k].first_id || !strcmp(ps->ids[0], files[k].first_id),
			      "%s: first id %s", files[k].file, ps->ids[0]);
			for (int i = 0; i < ps->n; i++)
				CHECK(kg_spectrum_isfinite(&ps->spectra[i]), "finite");
		}
		kg_patchset_free(&ps);
		free(path);
	}

	/* Ohta dark skin: 0.065 at 400 nm, 0.282 at 700 nm (5 nm data, kept exactly). */
	char *path = ref_path("charts/colorchecker24_ohta1997.csv");
	kg_patchset *ps = NULL;
	kg_err err = { { 0 } };
	CHECK(kg_csv_read_spectra_rows(path, 0, &ps, &err) == 0, "%s", err.msg);
	if (ps) {
		CHECK_NEAR(ps->spectra[0].v[0], 0.065, 1e-15, "dark skin 400 nm");
		CHECK_NEAR(ps->spectra[0].v[60], 0.282, 1e-15, "dark skin 700 nm");
	}
	kg_patchset_free(&ps);
	free(path);

	/* Vrhel rock #2: 2 nm data averaged per band; the text column `natural` skipped. */
	path = ref_path("reflectance/vrhel1994_170_2nm.csv");
	CHECK(kg_csv_read_spectra_rows(path, 0, &ps, &err) == 0, "%s", err.msg);
	if (ps)
		CHECK(ps->spectra[1].v[0] > 0.06 && ps->spectra[1].v[0] < 0.08, "Vrhel 2 at 400");
	kg_patchset_free(&ps);
	free(path);
}

static void test_malformed(void)
{
	kg_err err = { { 0 } };
	kg_csv *t = NULL;
	const char *text = "wavelength_nm,r,g\n400,0.1,0.2\n# comment\n410,0.1\n";
	CHECK(kg_csv_parse(text, strlen(text), "cam.csv", &t, &err) == KG_EINVAL &&
	          strstr(err.msg, "cam.csv: line 4") && strstr(err.msg, "2 values, expected 3"),
	      "short row: %s", err.msg);
	CHECK(t == NULL, "no table on failure");
	CHECK(kg_csv_parse("", 0, "empty.csv", &t, &err) == KG_EINVAL &&
	          strstr(err.msg, "empty.csv") && strstr(err.msg, "header"), "empty: %s", err.msg);

	text = "wavelength_nm,r\n400,0.1\n410,x1\n420,nan\n";
	CHECK(kg_csv_parse(text, strlen(text), "cam.csv", &t, &err) == 0, "%s", err.msg);
	double v;
	CHECK(t && kg_csv_number(t, 1, 1, &v, &err) == KG_EINVAL && strstr(err.msg, "line 3") &&
	          strstr(err.msg, "column r") && strstr(err.msg, "'x1'"),
	      "non-numeric: %s", err.msg);
	CHECK(t && kg_csv_number(t, 2, 1, &v, &err) == KG_EINVAL && strstr(err.msg, "line 4"),
	      "NaN: %s", err.msg);
	kg_csv_free(&t);

	/* A chart covering only 420-680 nm needs extrapolation. */
	char dir[] = "/tmp/kg-csv-XXXXXX";
	if (!mkdtemp(dir))
		return;
	char *path = kg_path_join(dir, "narrow.csv");
	FILE *fp = fopen(path, "w");
	if (fp) {
		fprintf(fp, "patch,name,420,550,680\nA,red,0.1,0.2,0.6\n");
		fclose(fp);
		kg_patchset *ps = NULL;
		CHECK(kg_csv_read_spectra_rows(path, 0, &ps, &err) == KG_ERANGE &&
		          strstr(err.msg, "line 2") && strstr(err.msg, "patch A") &&
		          strstr(err.msg, "420-680"), "narrow range refused: %s", err.msg);
		CHECK(kg_csv_read_spectra_rows(path, KG_RESAMPLE_EXTRAPOLATE, &ps, &err) == 0,
		      "%s", err.msg);
		if (ps)
			CHECK(ps->spectra[0].v[0] == 0.1 && ps->spectra[0].v[60] == 0.6, "held ends");
		kg_patchset_free(&ps);
		unlink(path);
	}
	free(path);
	rmdir(dir);
}

/* Quoted values (RFC 4180, as kg_csv_put writes them): commas, blanks and "" inside;
 * an unclosed quote or text after the closing one refused naming line and column. */
static void test_quoted(void)
{
	kg_err err = { { 0 } };
	kg_csv *t = NULL;
	const char *ok = "a, \"b,c\" ,d\r\n\"x \"\"y\"\"\",2, \" 3 \"\n\"\",,\"\"\"\"\n";
	CHECK(kg_csv_parse(ok, strlen(ok), "q.csv", &t, &err) == 0, "%s", err.msg);
	if (t) {
		CHECK(t->ncols == 3 && t->nrows == 2 && t->header_line == 1, "shape %d x %d", t->nrows,
		      t->ncols);
		CHECK(!strcmp(t->names[1], "b,c") && !strcmp(t->names[2], "d"), "header '%s' '%s'",
		      t->names[1], t->names[2]);
		CHECK(!strcmp(kg_csv_cell(t, 0, 0), "x \"y\"") && !strcmp(kg_csv_cell(t, 0, 2), " 3 "),
		      "row 1: '%s' '%s'", kg_csv_cell(t, 0, 0), kg_csv_cell(t, 0, 2));
		CHECK(!*kg_csv_cell(t, 1, 0) && !*kg_csv_cell(t, 1, 1) &&
		      !strcmp(kg_csv_cell(t, 1, 2), "\""), "row 2");
	}
	kg_csv_free(&t);
	static const char *const bad[] = {"a,b\n1,\"2\n", "a,b\n1,\"2\"x\n", "\"a,b\n"};
	static const char *const where[] = {"line 2, column 2", "line 2, column 2",
	                                    "line 1, column 1"};
	for (int i = 0; i < 3; i++) {
		CHECK(kg_csv_parse(bad[i], strlen(bad[i]), "q.csv", &t, &err) == KG_EINVAL && !t &&
		      strstr(err.msg, where[i]) && strstr(err.msg, "quoted"), "bad %d: %s", i, err.msg);
		kg_csv_free(&t);
	}
}

int main(void)
{
	kg_test_reference_dir();
	test_malformed();
	test_quoted();
	test_camera();
	test_spectra_rows();
	return kg_test_done("csv");
}
