/* Malformed CGATS is refused with a message naming the file, the line, the field and
 * what was expected; nothing crashes or leaks. */
#include <string.h>

#include "kg_core.h"
#include "kg_test.h"

#define HEAD "CGATS.17\nORIGINATOR \"test\"\nNUMBER_OF_FIELDS 3\nBEGIN_DATA_FORMAT\n" \
             "SAMPLE_ID RGB_R RGB_G\nEND_DATA_FORMAT\n"
/* Line numbers: 1 CGATS.17, 2 ORIGINATOR, 3 NUMBER_OF_FIELDS, 4 BEGIN_DATA_FORMAT,
 * 5 fields, 6 END_DATA_FORMAT, 7 NUMBER_OF_SETS, 8 BEGIN_DATA, 9 first set. */

/* Parse text expecting failure `code` and a message containing every string given. */
static void expect_parse_error(const char *what, const char *text, size_t len, int code,
                               const char *const *needles)
{
	kg_err err = { { 0 } };
	kg_cgats *cg = NULL;
	int r = kg_cgats_parse(text, len, "bad.cgats", &cg, &err);
	CHECK(r == code, "%s: expected code %d, got %d (%s)", what, code, r, err.msg);
	CHECK(cg == NULL, "%s: no result on failure", what);
	CHECK(strncmp(err.msg, "bad.cgats", 9) == 0, "%s: message names the file: %s", what,
	      err.msg);
	for (int i = 0; needles[i]; i++)
		CHECK(strstr(err.msg, needles[i]), "%s: message lacks '%s': %s", what, needles[i],
		      err.msg);
	kg_cgats_free(&cg);
}

#define PARSE_FAILS(what, text, code, ...)                                              \
	expect_parse_error(what, text, strlen(text), code, (const char *const[]){ __VA_ARGS__, \
	                                                                          NULL })

/* Parse text that is valid, then expect the patch set (or a number) to fail. */
static void expect_patchset_error(const char *what, const char *text, unsigned flags,
                                  int code, const char *const *needles)
{
	kg_err err = { { 0 } };
	kg_cgats *cg = NULL;
	kg_patchset *ps = NULL;
	int r = kg_cgats_parse(text, strlen(text), "bad.cgats", &cg, &err);
	CHECK(r == 0, "%s: parses: %s", what, err.msg);
	if (r != 0)
		return;
	r = kg_patchset_from_cgats(cg, flags, &ps, &err);
	CHECK(r == code, "%s: expected code %d, got %d (%s)", what, code, r, err.msg);
	CHECK(ps == NULL, "%s: no patch set on failure", what);
	for (int i = 0; needles[i]; i++)
		CHECK(strstr(err.msg, needles[i]), "%s: message lacks '%s': %s", what, needles[i],
		      err.msg);
	kg_patchset_free(&ps);
	kg_cgats_free(&cg);
}

#define PATCHSET_FAILS(what, text, flags, code, ...)                                     \
	expect_patchset_error(what, text, flags, code, (const char *const[]){ __VA_ARGS__, NULL })

static void test_structure(void)
{
	PARSE_FAILS("empty", "", KG_EINVAL, "empty");
	PARSE_FAILS("only comments", "# nothing here\n\n   \n", KG_EINVAL, "empty");
	PARSE_FAILS("no identifier", "NUMBER_OF_FIELDS 2\n", KG_EINVAL, "line 1",
	            "file-type identifier");
	PARSE_FAILS("truncated in the data",
	            HEAD "NUMBER_OF_SETS 2\nBEGIN_DATA\nA1 0.1 0.2\n", KG_EINVAL, "line 9",
	            "END_DATA", "truncated");
	PARSE_FAILS("truncated mid-set", HEAD "BEGIN_DATA\nA1 0.1 0.2\nA2 0.", KG_EINVAL,
	            "line 9", "set 2 has 2 values, expected 3");
	PARSE_FAILS("truncated in the header", "CGATS.17\nORIGINATOR \"x\"\n", KG_EINVAL,
	            "line 2", "BEGIN_DATA_FORMAT");
	PARSE_FAILS("truncated in the field list",
	            "CGATS.17\nBEGIN_DATA_FORMAT\nSAMPLE_ID RGB_R\n", KG_EINVAL, "line 3",
	            "END_DATA_FORMAT");
	PARSE_FAILS("wrong field count", HEAD "BEGIN_DATA\nA1 0.1 0.2\nA2 0.1 0.2 0.3\nEND_DATA\n",
	            KG_EINVAL, "line 9", "set 2 has 4 values, expected 3", "SAMPLE_ID");
	PARSE_FAILS("missing BEGIN_DATA", HEAD "NUMBER_OF_SETS 1\n", KG_EINVAL, "line 7",
	            "expected BEGIN_DATA");
	PARSE_FAILS("data without BEGIN_DATA", HEAD "A1 0.1 0.2\nEND_DATA\n", KG_EINVAL,
	            "line 8", "END_DATA without its BEGIN");
	PARSE_FAILS("missing BEGIN_DATA_FORMAT",
	            "CGATS.17\nNUMBER_OF_FIELDS 2\nBEGIN_DATA\n1 2\nEND_DATA\n", KG_EINVAL,
	            "line 3", "BEGIN_DATA_FORMAT");
	PARSE_FAILS("empty field list",
	            "CGATS.17\nBEGIN_DATA_FORMAT END_DATA_FORMAT\nBEGIN_DATA\nEND_DATA\n",
	            KG_EINVAL, "line 2", "no fields");
	/* NUMBER_OF_FIELDS disagreeing with the field list is tolerated (real Argyll files
	 * do it) as long as the sets match the list; when they do not, it is mentioned. */
	PARSE_FAILS("NUMBER_OF_FIELDS and sets disagree with the field list",
	            "CGATS.17\nNUMBER_OF_FIELDS 3\nBEGIN_DATA_FORMAT\nSAMPLE_ID RGB_R\n"
	            "END_DATA_FORMAT\nBEGIN_DATA\nA 1 2\nEND_DATA\n",
	            KG_EINVAL, "line 7", "set 1 has 3 values, expected 2",
	            "NUMBER_OF_FIELDS (line 2) says 3");
	PARSE_FAILS("NUMBER_OF_SETS mismatch",
	            HEAD "NUMBER_OF_SETS 3\nBEGIN_DATA\nA1 0.1 0.2\nA2 0.1 0.2\nEND_DATA\n",
	            KG_EINVAL, "line 11", "NUMBER_OF_SETS is 3", "2 sets");
	PARSE_FAILS("NUMBER_OF_SETS not a number", HEAD "NUMBER_OF_SETS many\n", KG_EINVAL,
	            "line 7", "NUMBER_OF_SETS", "integer", "many");
	PARSE_FAILS("unterminated quote", HEAD "BEGIN_DATA\n\"A1 0.1 0.2\nEND_DATA\n", KG_EINVAL,
	            "line 8", "unterminated");
	static const char nul[] = "CGATS.17\nORIG\0INATOR \"x\"\n";
	expect_parse_error("NUL byte", nul, sizeof(nul) - 1, KG_EINVAL,
	                   (const char *const[]){ "line 2", "NUL", NULL });

	/* A line over the 1 MiB cap: refused by number, not read into memory twice. */
	size_t big = (size_t)KG_CGATS_MAX_LINE + 100;
	char *text = malloc(big + 64);
	if (text) {
		size_t n = (size_t)sprintf(text, "CGATS.17\nDESCRIPTOR \"");
		memset(text + n, 'x', big);
		n += big;
		n += (size_t)sprintf(text + n, "\"\n");
		expect_parse_error("long line", text, n, KG_EINVAL,
		                   (const char *const[]){ "line 2", "longer than", NULL });
		free(text);
	}

	kg_err err = { { 0 } };
	kg_cgats *cg = NULL;
	CHECK(kg_cgats_read("/nonexistent/x.cgats", &cg, &err) == KG_ENOENT &&
	          strstr(err.msg, "/nonexistent/x.cgats"), "missing file: %s", err.msg);
}

static void test_numbers(void)
{
	const char *text = HEAD "NUMBER_OF_SETS 5\nBEGIN_DATA\nA1 0.1 0.2\nA2 abc 0.2\n"
	                        "A3 nan 0.1\nA4 0.1 inf\nA5 1e999 0\nEND_DATA\n";
	kg_err err = { { 0 } };
	kg_cgats *cg = NULL;
	CHECK(kg_cgats_parse(text, strlen(text), "bad.cgats", &cg, &err) == 0, "%s", err.msg);
	if (!cg)
		return;
	const kg_cgats_table *t = cg->tables[0];
	double v = -1;
	CHECK(kg_cgats_number(t, 0, 1, &v, &err) == 0 && v == 0.1, "good number");
	CHECK(kg_cgats_number(t, 1, 1, &v, &err) == KG_EINVAL && strstr(err.msg, "bad.cgats") &&
	          strstr(err.msg, "line 10") && strstr(err.msg, "field RGB_R") &&
	          strstr(err.msg, "expected a number") && strstr(err.msg, "'abc'"),
	      "non-numeric: %s", err.msg);
	CHECK(kg_cgats_number(t, 2, 1, &v, &err) == KG_EINVAL && strstr(err.msg, "line 11") &&
	          strstr(err.msg, "NaN"), "NaN: %s", err.msg);
	CHECK(kg_cgats_number(t, 3, 2, &v, &err) == KG_EINVAL && strstr(err.msg, "line 12") &&
	          strstr(err.msg, "field RGB_G"), "inf: %s", err.msg);
	CHECK(kg_cgats_number(t, 4, 1, &v, &err) == KG_EINVAL && strstr(err.msg, "line 13") &&
	          strstr(err.msg, "beyond the largest number a double holds"),
	      "overflow to infinity: %s", err.msg);
	CHECK(kg_cgats_parse_number("0x1p3", &v) == KG_EINVAL, "hex floats refused");
	CHECK(kg_cgats_parse_number("-1.5e-3", &v) == 0 && v == -1.5e-3, "exponent");
	kg_cgats_free(&cg);

	PATCHSET_FAILS("RGB not a number",
	               "CGATS.17\nBEGIN_DATA_FORMAT\nSAMPLE_ID RGB_R RGB_G RGB_B\n"
	               "END_DATA_FORMAT\nBEGIN_DATA\nA1 0.1 0.2 0.3\nA2 abc 0.2 0.3\nEND_DATA\n",
	               0, KG_EINVAL, "line 7", "field RGB_R", "'abc'");
}

static void test_patchsets(void)
{
	PATCHSET_FAILS("partial RGB", HEAD "BEGIN_DATA\nA1 0.1 0.2\nEND_DATA\n", 0, KG_EINVAL,
	               "RGB_B missing");
	PATCHSET_FAILS("no sets", HEAD "BEGIN_DATA\nEND_DATA\n", 0, KG_EINVAL, "no data sets");

	const char *narrow = "CGATS.17\nBEGIN_DATA_FORMAT\nSAMPLE_ID SPEC_420 SPEC_560 SPEC_700\n"
	                     "END_DATA_FORMAT\nBEGIN_DATA\nP1 0.1 0.2 0.3\nP2 0.1 0.2 0.4\n"
	                     "END_DATA\n";
	PATCHSET_FAILS("spectrum not covering 400-700", narrow, 0, KG_ERANGE, "line 6", "P1",
	               "420-700");
	const char *with_nan = "CGATS.17\nBEGIN_DATA_FORMAT\nSAMPLE_ID SPEC_400 SPEC_700\n"
	                       "END_DATA_FORMAT\nBEGIN_DATA\nP1 0.1 0.3\nP2 0.1 NaN\n"
	                       "END_DATA\n";
	PATCHSET_FAILS("NaN in a spectrum", with_nan, 0, KG_EINVAL, "line 7", "field SPEC_700",
	               "NaN");

	const char *spec_order = "CGATS.17\nBEGIN_DATA_FORMAT\nSPEC_500 SPEC_400\n"
	                         "END_DATA_FORMAT\nBEGIN_DATA\n0.1 0.2\nEND_DATA\n";
	PATCHSET_FAILS("spectral fields out of order", spec_order, 0, KG_EINVAL, "SPEC_400",
	               "increase");

	/* Argyll .ti3 style: no SPECTRAL_NORM, percent values -> fractions. */
	const char *ti3 = "CTI3\nBEGIN_DATA_FORMAT\nSAMPLE_ID SPEC_400 SPEC_550 SPEC_700\n"
	                  "END_DATA_FORMAT\nBEGIN_DATA\n1 10 50 91.5\n2 1 2 3\nEND_DATA\n";
	kg_err err = { { 0 } };
	kg_cgats *cg = NULL;
	kg_patchset *ps = NULL;
	CHECK(kg_cgats_parse(ti3, strlen(ti3), "pct.ti3", &cg, &err) == 0, "%s", err.msg);
	CHECK(cg && kg_patchset_from_cgats(cg, 0, &ps, &err) == 0, "%s", err.msg);
	if (ps) {
		CHECK(ps->spectral_scale == 0.01, "percent detected");
		CHECK_NEAR(ps->spectra[0].v[60], 0.915, 1e-12, "700 nm as a fraction");
		CHECK_NEAR(ps->spectra[0].v[2], 0.1 + 0.4 * 10 / 150.0, 1e-12, "410 nm interpolated");
	}
	kg_patchset_free(&ps);
	CHECK(cg && kg_patchset_from_cgats(cg, KG_PATCH_KEEP_SCALE, &ps, &err) == 0, "%s",
	      err.msg);
	if (ps)
		CHECK(ps->spectral_scale == 1.0 && ps->spectra[0].v[60] == 91.5, "scale kept");
	kg_patchset_free(&ps);
	kg_cgats_free(&cg);
}

/* A 400-700 nm table every 100 nm with the given field names, keywords and values. */
#define SPEC4(keywords, names, row)                                                     \
	"CGATS.17\n" keywords "BEGIN_DATA_FORMAT\nSAMPLE_ID " names "\nEND_DATA_FORMAT\n"      \
	"BEGIN_DATA\nP1 " row "\nEND_DATA\n"

/* Spectral fields are never passed over or reordered: a band dropped or misplaced
 * would be interpolated across and change XYZ without a word. */
static void test_spectral_fields(void)
{
	PATCHSET_FAILS("SPEC_ without a number",
	               SPEC4("", "SPEC_400 SPEC_500 SPEC_abc SPEC_700", "0.1 0.2 0.3 0.4"), 0,
	               KG_EINVAL, "bad.cgats", "field SPEC_abc", "SPEC_<nm>",
	               "finite wavelength in nm");
	PATCHSET_FAILS("SPEC_Inf", SPEC4("", "SPEC_400 SPEC_500 SPEC_Inf SPEC_700", "0.1 0.2 0.3 0.4"),
	               0, KG_EINVAL, "field SPEC_Inf", "finite wavelength");
	PATCHSET_FAILS("SPEC_ alone", SPEC4("", "SPEC_400 SPEC_ SPEC_600 SPEC_700", "0.1 0.2 0.3 0.4"),
	               0, KG_EINVAL, "field SPEC_:", "finite wavelength");
	PATCHSET_FAILS("SPEC_0", SPEC4("", "SPEC_0 SPEC_400 SPEC_600 SPEC_700", "0.1 0.2 0.3 0.4"),
	               0, KG_EINVAL, "field SPEC_0:", "0 nm: expected a wavelength between 100 "
	               "and 5000 nm");
	PATCHSET_FAILS("duplicate wavelength",
	               SPEC4("", "SPEC_400 SPEC_500 SPEC_500.0 SPEC_700", "0.1 0.2 0.3 0.4"), 0,
	               KG_EINVAL, "SPEC_500 and SPEC_500.0", "500 nm", "each wavelength once");
	PATCHSET_FAILS("duplicate in picometres",
	               SPEC4("", "SPEC_400 SPEC_500 SPEC_500000 SPEC_700", "0.1 0.2 0.3 0.4"), 0,
	               KG_EINVAL, "SPEC_500 and SPEC_500000", "each wavelength once");
	PATCHSET_FAILS("fields out of step with the keywords",
	               SPEC4("SPECTRAL_START_NM 400\nSPECTRAL_END_NM 700\nSPECTRAL_BANDS 4\n",
	                     "SPEC_400 SPEC_450 SPEC_600 SPEC_700", "0.1 0.2 0.3 0.4"),
	               0, KG_EINVAL, "field SPEC_450", "500 nm", "keywords' order and spacing");
	PATCHSET_FAILS("SPECTRAL_BANDS disagrees",
	               SPEC4("SPECTRAL_BANDS 5\n", "SPEC_400 SPEC_500 SPEC_600 SPEC_700",
	                     "0.1 0.2 0.3 0.4"),
	               0, KG_EINVAL, "SPECTRAL_BANDS is 5", "4 SPEC_<nm> fields");
	PATCHSET_FAILS("SPECTRAL_START_NM disagrees",
	               SPEC4("SPECTRAL_START_NM 380\n", "SPEC_400 SPEC_500 SPEC_600 SPEC_700",
	                     "0.1 0.2 0.3 0.4"),
	               0, KG_EINVAL, "SPECTRAL_START_NM is 380", "SPEC_400");
	PATCHSET_FAILS("SPECTRAL_END_NM disagrees",
	               SPEC4("SPECTRAL_END_NM 730\n", "SPEC_400 SPEC_500 SPEC_600 SPEC_700",
	                     "0.1 0.2 0.3 0.4"),
	               0, KG_EINVAL, "SPECTRAL_END_NM is 730", "SPEC_700");
	PATCHSET_FAILS("SPECTRAL_BANDS not a number",
	               SPEC4("SPECTRAL_BANDS \"many\"\n", "SPEC_400 SPEC_500 SPEC_600 SPEC_700",
	                     "0.1 0.2 0.3 0.4"),
	               0, KG_EINVAL, "SPECTRAL_BANDS", "expected a number");
	/* Agreeing keywords, rounded names (within 1 nm): accepted, the keyword grid used. */
	kg_err err = { { 0 } };
	kg_cgats *cg = NULL;
	const char *ok = SPEC4("SPECTRAL_START_NM 400\nSPECTRAL_END_NM 700\nSPECTRAL_BANDS 4\n",
	                       "SPEC_400 SPEC_500 SPEC_600 SPEC_700", "0.1 0.2 0.3 0.4");
	CHECK(kg_cgats_parse(ok, strlen(ok), "ok.cgats", &cg, &err) == 0, "%s", err.msg);
	kg_patchset *ps = NULL;
	CHECK(cg && kg_patchset_from_cgats(cg, 0, &ps, &err) == 0, "agreeing keywords: %s",
	      err.msg);
	kg_patchset_free(&ps);
	kg_cgats_free(&cg);
}

#define SCALED(type, keywords, row)                                                     \
	type "\n" keywords "BEGIN_DATA_FORMAT\nSAMPLE_ID SPEC_400 SPEC_500 SPEC_600 SPEC_700\n" \
	"END_DATA_FORMAT\nBEGIN_DATA\nP1 " row "\nEND_DATA\n"

/* Every prefix the reader takes as spectral (SPEC_, SPECTRAL_NM, SPECTRAL_NM_, nm, in
 * any case) reads the same bands, and is refused, never passed over, when what follows
 * is not a plausible wavelength. */
static void test_field_forms(void)
{
	static const char *const forms[] = { "nm", "NM", "Nm", "SPECTRAL_NM", "spectral_nm_",
		                                 "spec_" };
	for (size_t i = 0; i < sizeof(forms) / sizeof(forms[0]); i++) {
		char names[128], text[512];
		snprintf(names, sizeof(names), "%s400 %s500 %s600 %s700", forms[i], forms[i],
		         forms[i], forms[i]);
		snprintf(text, sizeof(text), SPEC4("", "%s", "0.1 0.2 0.3 0.4"), names);
		kg_err err = { { 0 } };
		kg_cgats *cg = NULL;
		kg_patchset *ps = NULL;
		CHECK(kg_cgats_parse(text, strlen(text), "f.cgats", &cg, &err) == 0 &&
		          kg_patchset_from_cgats(cg, 0, &ps, &err) == 0 && ps->spectra,
		      "%s<nm>: %s", forms[i], err.msg);
		if (ps && ps->spectra) {
			CHECK(ps->spectra[0].v[0] == 0.1 && ps->spectra[0].v[60] == 0.4,
			      "%s<nm>: 400 and 700 nm read", forms[i]);
			CHECK_NEAR(ps->spectra[0].v[30], 0.25, 1e-12, "550 nm between the bands");
		}
		kg_patchset_free(&ps);
		kg_cgats_free(&cg);
	}
	static const struct {
		const char *in_file, *name;
	} unreadable[] = {
		{ "nmInf", "nmInf" }, { "nmnan", "nmnan" }, { "NMinf", "NMinf" }, { "nm-x", "nm-x" },
		{ "nm400x", "nm400x" }, { "nm+", "nm+" }, { "\"nm 400\"", "nm 400" }, { "nm", "nm" },
		{ "spec_Inf", "spec_Inf" }, { "SPECTRAL_NM_abc", "SPECTRAL_NM_abc" },
		{ "SPECTRAL_NM", "SPECTRAL_NM" }, { "nm0x1p9", "nm0x1p9" },
	};
	for (size_t i = 0; i < sizeof(unreadable) / sizeof(unreadable[0]); i++) {
		char names[128], text[512], field[64];
		snprintf(names, sizeof(names), "nm400 nm500 %s nm700", unreadable[i].in_file);
		snprintf(text, sizeof(text), SPEC4("", "%s", "0.1 0.2 0.3 0.4"), names);
		snprintf(field, sizeof(field), "field %s:", unreadable[i].name);
		PATCHSET_FAILS(unreadable[i].name, text, 0, KG_EINVAL, "bad.cgats", field,
		               "with a finite wavelength in nm as a plain number");
	}
	static const char *const implausible[] = { "nm-5", "nm0", "nm50", "SPEC_99.9",
		                                       "SPEC_5001", "nm9999", "SPEC_50000" };
	for (size_t i = 0; i < sizeof(implausible) / sizeof(implausible[0]); i++) {
		char names[128], text[512], field[64];
		snprintf(names, sizeof(names), "%s SPEC_400 SPEC_500 SPEC_700", implausible[i]);
		snprintf(text, sizeof(text), SPEC4("", "%s", "0.1 0.2 0.3 0.4"), names);
		snprintf(field, sizeof(field), "field %s:", implausible[i]);
		PATCHSET_FAILS(implausible[i], text, 0, KG_EINVAL, field,
		               "expected a wavelength between 100 and 5000 nm");
	}
	PATCHSET_FAILS("picometres named", SPEC4("", "SPEC_50000 SPEC_400 SPEC_500 SPEC_700",
	                                          "0.1 0.2 0.3 0.4"),
	               0, KG_EINVAL, "50 nm (a number from 10000 up is read as picometres)");
	PATCHSET_FAILS("one wavelength in two forms",
	               SPEC4("", "nm400 nm500 SPEC_500 nm700", "0.1 0.2 0.3 0.4"), 0, KG_EINVAL,
	               "nm500 and SPEC_500 both hold 500 nm", "each wavelength once");
	PATCHSET_FAILS("one wavelength in nm and picometres",
	               SPEC4("", "nm400 SPECTRAL_NM_500 SPEC_500000 nm700", "0.1 0.2 0.3 0.4"), 0,
	               KG_EINVAL, "SPECTRAL_NM_500 and SPEC_500000 both hold 500 nm");
}

/* A table of one reflectance spectrum (SPECTRAL_NORM 1: taken as written) with one
 * value replaced, the rest 0.5. */
#define ONE_VALUE(v) SCALED("CGATS.17", "SPECTRAL_NORM 1\n", "0.5 " v " 0.5 0.5")
#define RGB_ROW(row)                                                                   \
	"CGATS.17\nBEGIN_DATA_FORMAT\nSAMPLE_ID RGB_R RGB_G RGB_B XYZ_X XYZ_Y XYZ_Z\n"       \
	"END_DATA_FORMAT\nBEGIN_DATA\nA1 0.1 0.2 0.3 1 2 3\nA2 " row "\nEND_DATA\n"

/* Parses and gives a patch set with these flags (the value is in range). */
static void expect_taken(const char *what, const char *text, unsigned flags)
{
	kg_err err = { { 0 } };
	kg_cgats *cg = NULL;
	kg_patchset *ps = NULL;
	CHECK(kg_cgats_parse(text, strlen(text), what, &cg, &err) == 0 &&
	          kg_patchset_from_cgats(cg, flags, &ps, &err) == 0,
	      "%s: expected it taken: %s", what, err.msg);
	kg_patchset_free(&ps);
	kg_cgats_free(&cg);
}

/* Values that would overflow later (an eigen-decomposition, XYZ) or are no
 * reflectance are refused where they are read, naming the line and the field. */
static void test_value_ranges(void)
{
	const unsigned refl = KG_PATCH_REFLECTANCE;
	static const char *const far[] = { "1e308", "-1e308", "10.001", "-1.001", "1e30" };
	for (size_t i = 0; i < sizeof(far) / sizeof(far[0]); i++) {
		char text[512], cell[64];
		snprintf(text, sizeof(text), ONE_VALUE("%s"), far[i]);
		snprintf(cell, sizeof(cell), "line 7: field SPEC_500: '%s'", far[i]);
		PATCHSET_FAILS(far[i], text, refl, KG_ERANGE, "bad.cgats", cell,
		               "expected a reflectance between -1 and 10 (-100 % and 1000 %)");
	}
	expect_taken("10 as a reflectance", ONE_VALUE("10"), refl);
	expect_taken("-1 as a reflectance", ONE_VALUE("-1"), refl);
	expect_taken("1.07 as a reflectance", ONE_VALUE("1.07"), refl);
	expect_taken("-0.02 as a reflectance", ONE_VALUE("-0.02"), refl);
	/* Without KG_PATCH_REFLECTANCE (an illuminant, a basis): any unit, up to 1e30. */
	expect_taken("1e30 as a spectral value", ONE_VALUE("1e30"), 0);
	expect_taken("-1e30 as stored", ONE_VALUE("-1e30"), KG_PATCH_KEEP_SCALE);
	PATCHSET_FAILS("1.000001e30", ONE_VALUE("1.000001e30"), 0, KG_ERANGE,
	               "line 7: field SPEC_500: '1.000001e30'", "magnitude at most 1e30");
	PATCHSET_FAILS("1e308 as stored", ONE_VALUE("1e308"), KG_PATCH_KEEP_SCALE, KG_ERANGE,
	               "field SPEC_500: '1e308'", "magnitude at most 1e30");
	/* Finite in the file, beyond a double once scaled. */
	PATCHSET_FAILS("overflow once scaled",
	               SCALED("CGATS.17", "SPECTRAL_NORM 0.001\n", "0.5 1e306 0.5 0.5"), 0,
	               KG_ERANGE, "line 7: field SPEC_500: '1e306' (inf once scaled by 1000)");
	/* Percent read as a fraction: the value as written and as scaled. */
	PATCHSET_FAILS("percent", SCALED("SPECT", "", "50 2000 50 50"), refl, KG_ERANGE,
	               "'2000' (20 once scaled by 0.01): expected a reflectance");

	expect_taken("RGB and XYZ at their limits", RGB_ROW("1e6 -1e6 65535 1e30 -1e30 0"), 0);
	PATCHSET_FAILS("RGB 1e308", RGB_ROW("0.1 1e308 0.3 1 2 3"), 0, KG_ERANGE, "bad.cgats",
	               "line 7: field RGB_G: '1e308'", "magnitude at most 1e+06");
	PATCHSET_FAILS("RGB -2e6", RGB_ROW("-2e6 0.2 0.3 1 2 3"), 0, KG_ERANGE, "field RGB_R");
	PATCHSET_FAILS("XYZ 1e31", RGB_ROW("0.1 0.2 0.3 1 1e31 3"), 0, KG_ERANGE,
	               "line 7: field XYZ_Y: '1e31'", "magnitude at most 1e+30");

	/* The chart CSV layout keeps the same range. */
	kg_test_scratch_dir("cgats-malformed");
	const char *csv = kg_test_path("chart.csv");
	FILE *fp = fopen(csv, "w");
	CHECK(fp != NULL, "cannot write %s", csv);
	if (fp) {
		fprintf(fp, "patch,name,400,550,700\nA1,white,0.9,0.9,0.9\nA2,red,0.1,1e308,0.6\n");
		fclose(fp);
		kg_err err = { { 0 } };
		kg_patchset *ps = NULL;
		CHECK(kg_csv_read_spectra_rows(csv, refl, &ps, &err) == KG_ERANGE && !ps &&
		          strstr(err.msg, "chart.csv: line 3: column 550: '1e308'") &&
		          strstr(err.msg, "expected a reflectance between -1 and 10"),
		      "CSV 1e308: %s", err.msg);
		CHECK(kg_csv_read_spectra_rows(csv, 0, &ps, &err) == KG_ERANGE &&
		          strstr(err.msg, "magnitude at most 1e30"), "CSV 1e308 as any spectrum: %s",
		      err.msg);
	}
	kg_test_scratch_remove();
}

/* Which scale a table's spectral values are on, whatever its type identifier. */
static void expect_scale(const char *what, const char *text, double scale, double at700)
{
	kg_err err = { { 0 } };
	kg_cgats *cg = NULL;
	kg_patchset *ps = NULL;
	CHECK(kg_cgats_parse(text, strlen(text), what, &cg, &err) == 0, "%s: %s", what, err.msg);
	CHECK(cg && kg_patchset_from_cgats(cg, 0, &ps, &err) == 0, "%s: %s", what, err.msg);
	if (ps) {
		CHECK(ps->spectral_scale == scale, "%s: scale %g, expected %g", what,
		      ps->spectral_scale, scale);
		CHECK(ps->spectra[0].v[60] == at700, "%s: 700 nm %.17g, expected %.17g", what,
		      ps->spectra[0].v[60], at700);
	}
	kg_patchset_free(&ps);
	kg_cgats_free(&cg);
}

static void test_spectral_scale(void)
{
	/* spec2cie's output of a percent file: SPECT, MEAS_TYPE, no SPECTRAL_NORM. */
	expect_scale("argyll SPECT in percent",
	             SCALED("SPECT", "MEAS_TYPE \"REFLECTIVE\"\n", "12.0 35.5 60.25 91.5"), 0.01,
	             0.915);
	expect_scale("SPECT in percent, no MEAS_TYPE",
	             SCALED("SPECT", "", "12.0 35.5 60.25 91.5"), 0.01, 0.915);
	expect_scale("CGATS.17 in percent", SCALED("CGATS.17", "", "12 35.5 60.25 91.5"), 0.01,
	             0.915);
	/* colord CIE-TCS.sp style: SPECT, no SPECTRAL_NORM, fractions. */
	expect_scale("SPECT in fractions", SCALED("SPECT", "", "0.12 0.355 0.6025 0.915"), 1.0,
	             0.915);
	/* SPECTRAL_NORM wins over the values, whatever the type. */
	expect_scale("CGATS.17 with SPECTRAL_NORM 100",
	             SCALED("CGATS.17", "SPECTRAL_NORM \"100\"\n", "0.12 0.355 0.6025 0.915"),
	             0.01, 0.00915);
	expect_scale("CTI3 with SPECTRAL_NORM 50",
	             SCALED("CTI3", "SPECTRAL_NORM \"50\"\n", "6 17.75 30.125 45.75"), 0.02,
	             45.75 / 50);
	expect_scale("SPECT with SPECTRAL_NORM 1",
	             SCALED("SPECT", "SPECTRAL_NORM 1\n", "12 35.5 60.25 91.5"), 1.0, 91.5);
	/* An emission spectrum has no percent convention. */
	expect_scale("emission", SCALED("SPECT", "MEAS_TYPE \"EMISSION\"\n", "12 35.5 60.25 91.5"),
	             1.0, 91.5);
	PATCHSET_FAILS("SPECTRAL_NORM 0", SCALED("SPECT", "SPECTRAL_NORM 0\n", "1 2 3 4"), 0,
	               KG_EINVAL, "SPECTRAL_NORM", "positive");
}

int main(void)
{
	test_structure();
	test_numbers();
	test_patchsets();
	test_spectral_fields();
	test_spectral_scale();
	test_field_forms();
	test_value_ranges();
	return kg_test_done("cgats-malformed");
}
