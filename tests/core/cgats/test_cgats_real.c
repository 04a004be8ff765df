/* Every CGATS file shipped by colord-data and argyll-ref parses, every table yields a
 * patch set (except the three argyll-ref illuminants whose spectral keywords disagree
 * with their fields, which spec2cie refuses too), and known values come out as the
 * files state them. */
#include <dirent.h>
#include <string.h>

#include "kg_core.h"
#include "kg_test.h"

#define COLORD "/usr/share/colord"
#define ARGYLL "/usr/share/color/argyll/ref"

static int parsed_files, parsed_tables;

static int has_ext(const char *name, const char *const *exts)
{
	const char *dot = strrchr(name, '.');
	if (!dot)
		return 0;
	for (int i = 0; exts[i]; i++)
		if (strcmp(dot + 1, exts[i]) == 0)
			return 1;
	return 0;
}

/* argyll-ref illuminants whose SPECTRAL_START_NM or SPECTRAL_BANDS disagree with
 * their SPEC_<nm> fields: spec2cie stops on them ("doesn't contain field SPEC_389"),
 * and so does the reader. */
static int disagreeing_keywords(const char *name)
{
	static const char *const files[] = { "GTIPlus.sp", "Office.sp", "Trulux.sp" };
	for (size_t i = 0; i < sizeof(files) / sizeof(files[0]); i++)
		if (strcmp(name, files[i]) == 0)
			return 1;
	return 0;
}

static void parse_dir(const char *dir, const char *const *exts)
{
	DIR *d = opendir(dir);
	if (!d)
		return;
	struct dirent *e;
	while ((e = readdir(d))) {
		if (!has_ext(e->d_name, exts))
			continue;
		char *path = kg_path_join(dir, e->d_name);
		kg_err err = { { 0 } };
		kg_cgats *cg = NULL;
		int r = kg_cgats_read(path, &cg, &err);
		CHECK(r == 0, "%s does not parse: %s", path, err.msg);
		if (r == 0) {
			parsed_files++;
			for (int k = 0; k < cg->ntables; k++) {
				kg_patchset *ps = NULL;
				r = kg_patchset_from_table(cg->tables[k], 0, &ps, &err);
				if (disagreeing_keywords(e->d_name)) {
					CHECK(r == KG_EINVAL && strstr(err.msg, e->d_name) &&
					          strstr(err.msg, "SPECTRAL_") && strstr(err.msg, "SPEC_"),
					      "%s: expected a refusal naming the keyword and the field, got "
					      "%d: %s", path, r, err.msg);
					continue;
				}
				CHECK(r == 0, "%s table %d: no patch set: %s", path, k + 1, err.msg);
				CHECK(!ps || ps->n == cg->tables[k]->nsets, "one patch per set");
				CHECK(!ps || !ps->spectra || kg_spectrum_isfinite(&ps->spectra[0]),
				      "finite spectra");
				parsed_tables += r == 0;
				kg_patchset_free(&ps);
			}
		}
		kg_cgats_free(&cg);
		free(path);
	}
	closedir(d);
}

static kg_patchset *read_ps(const char *path, unsigned flags)
{
	kg_err err = { { 0 } };
	kg_patchset *ps = NULL;
	CHECK(kg_patchset_read(path, flags, &ps, &err) == 0, "%s: %s", path, err.msg);
	return ps;
}

static void known_values(void)
{
	/* ColorChecker.cie: "A01 37.99 13.56 14.06", "D01 96.54 -0.43 1.19" */
	kg_patchset *ps = read_ps(ARGYLL "/ColorChecker.cie", 0);
	if (ps) {
		CHECK(ps->n == 24 && ps->lab && !ps->spectra && !ps->rgb, "24 L*a*b* patches");
		int a01 = kg_patchset_find(ps, "A01"), d01 = kg_patchset_find(ps, "D01");
		CHECK(a01 == 0 && d01 == 18, "ids A01 at 0, D01 at 18: %d %d", a01, d01);
		if (a01 == 0 && d01 == 18) {
			CHECK_NEAR(ps->lab[a01][0], 37.99, 1e-12, "A01 L*");
			CHECK_NEAR(ps->lab[a01][2], 14.06, 1e-12, "A01 b*");
			CHECK_NEAR(ps->lab[d01][1], -0.43, 1e-12, "D01 a*");
		}
	}
	kg_patchset_free(&ps);

	/* ColorCheckerPassport.cie names patches by SAMPLE_LOC: "SAT1 31.444334 ..." */
	ps = read_ps(ARGYLL "/ColorCheckerPassport.cie", 0);
	if (ps) {
		CHECK(ps->n == 50 && !strcmp(ps->ids[0], "SAT1"), "SAMPLE_LOC ids");
		CHECK(ps->xyz && ps->lab, "XYZ and L*a*b*");
		if (ps->xyz)
			CHECK_NEAR(ps->xyz[0][0], 31.444334, 1e-12, "SAT1 XYZ_X");
	}
	kg_patchset_free(&ps);

	/* ColorCheckerDC.ti2: SAMPLE_ID 1.., quoted SAMPLE_LOC "A01", RGB 95.27 94.34 100 */
	ps = read_ps(ARGYLL "/ColorCheckerDC.ti2", 0);
	if (ps) {
		CHECK(ps->n == 240 && !strcmp(ps->ids[0], "1") && ps->rgb, "DC ids and RGB");
		if (ps->rgb)
			CHECK(ps->rgb[0][0] == 95.27 && ps->rgb[0][2] == 100, "DC patch 1 RGB");
		CHECK(kg_patchset_extra_index(ps, "SAMPLE_LOC") < 0, "text column not an extra");
	}
	kg_patchset_free(&ps);

	/* CIE-TCS.sp: TCS09 is 0.052 at 400 nm and 0.828 at 700 nm, 360-830 nm every 5 nm */
	ps = read_ps(COLORD "/ref/CIE-TCS.sp", 0);
	if (ps && ps->spectra) {
		int i = kg_patchset_find(ps, "TCS09");
		CHECK(i == 8 && ps->spectral_scale == 1.0, "TCS09 found, no rescaling");
		if (i == 8) {
			CHECK_NEAR(ps->spectra[i].v[0], 0.052, 1e-15, "TCS09 400 nm");
			CHECK_NEAR(ps->spectra[i].v[60], 0.828, 1e-15, "TCS09 700 nm");
		}
	}
	kg_patchset_free(&ps);

	/* Reflectance and transmittance files keep the reflectance range. */
	ps = read_ps(COLORD "/ref/CIE-TCS.sp", KG_PATCH_REFLECTANCE);
	kg_patchset_free(&ps);
	ps = read_ps(ARGYLL "/SOtele.sp", KG_PATCH_REFLECTANCE);
	kg_patchset_free(&ps);

	/* colord CIE-A.sp: fields in picometres (SPEC_300000), 1 nm, 1.0 at 560 nm. No
	 * SPECTRAL_NORM nor MEAS_TYPE and values up to 2.4: the percent rule applies; as
	 * stored with KG_PATCH_KEEP_SCALE (kg_illuminant_from_file reads it so). */
	ps = read_ps(COLORD "/illuminant/CIE-A.sp", KG_PATCH_KEEP_SCALE);
	if (ps && ps->spectra) {
		CHECK(ps->spectral_scale == 1.0, "SPD taken as it is");
		CHECK_NEAR(ps->spectra[0].v[32], 1.0, 1e-4, "CIE A at 560 nm (band average)");
	}
	kg_patchset_free(&ps);
	ps = read_ps(COLORD "/illuminant/CIE-A.sp", 0);
	CHECK(!ps || ps->spectral_scale == 0.01, "CIE-A.sp without KEEP_SCALE: percent");
	kg_patchset_free(&ps);

	/* SOtele.sp: MEAS_TYPE TRANSMISSIVE, SPECTRAL_NORM 100, 92.74505 at 700 nm. */
	ps = read_ps(ARGYLL "/SOtele.sp", 0);
	if (ps && ps->spectra)
		CHECK(ps->spectral_scale == 0.01 && ps->spectra[0].v[60] == 0.9274505,
		      "SOtele 700 nm as the fraction 0.9274505 exactly: %.17g",
		      ps->spectra[0].v[60]);
	kg_patchset_free(&ps);

	/* Argyll example121.sp: 121 bands 350-750 with rounded names (SPEC_353); the
	 * keyword grid is used. SPECTRAL_NORM 100. */
	kg_cgats *cg = NULL;
	kg_err err = { { 0 } };
	if (kg_cgats_read(ARGYLL "/example121.sp", &cg, &err) == 0) {
		int *f, n;
		double *wl;
		CHECK(kg_cgats_spectral_fields(cg->tables[0], &f, &wl, &n, &err) == 0 && n == 121,
		      "121 spectral fields: %s", err.msg);
		if (n == 121)
			CHECK_NEAR(wl[1], 350 + 400.0 / 120, 1e-9, "exact 3.33 nm grid");
		free(f);
		free(wl);
	} else
		CHECK(0, "%s", err.msg);
	kg_cgats_free(&cg);
	ps = read_ps(ARGYLL "/example121.sp", 0);
	CHECK(!ps || ps->spectral_scale == 0.01, "SPECTRAL_NORM 100 gives scale 0.01");
	kg_patchset_free(&ps);

	/* GTIPlus.sp: keywords say 80 bands to 750 nm, the fields are 40 to 730 nm:
	 * refused, naming the file, the keyword and the fields. */
	if (kg_cgats_read(ARGYLL "/GTIPlus.sp", &cg, &err) == 0) {
		int *f = NULL, n = -1;
		double *wl = NULL;
		CHECK(kg_cgats_spectral_fields(cg->tables[0], &f, &wl, &n, &err) == KG_EINVAL &&
		          n == 0 && !f && !wl,
		      "GTIPlus.sp refused");
		CHECK(strstr(err.msg, "GTIPlus.sp") && strstr(err.msg, "SPECTRAL_BANDS is 80") &&
		          strstr(err.msg, "40 SPEC_<nm> fields"),
		      "message: %s", err.msg);
		free(f);
		free(wl);
	} else
		CHECK(0, "%s", err.msg);
	kg_cgats_free(&cg);

	/* Multiple tables per file (Argyll .ti1). */
	if (kg_cgats_read(ARGYLL "/FograStrip2.ti1", &cg, &err) == 0) {
		CHECK(cg->ntables == 3, "3 tables, got %d", cg->ntables);
		CHECK(!strcmp(cg->tables[1]->type, "CTI1") && cg->tables[1]->nsets == 8,
		      "second table");
		CHECK(!strcmp(kg_cgats_keyword(cg->tables[0], "COLOR_REP"), "CMYK"), "keyword");
	} else
		CHECK(0, "%s", err.msg);
	kg_cgats_free(&cg);
}

int main(void)
{
	if (!kg_test_file_exists(COLORD "/cmf"))
		kg_test_skip(COLORD " is absent (package colord-data)");
	const char *const colord_exts[] = { "sp", "cmf", "ti1", "ti2", "ti3", "cie", NULL };
	parse_dir(COLORD "/cmf", colord_exts);
	parse_dir(COLORD "/illuminant", colord_exts);
	parse_dir(COLORD "/ref", colord_exts);
	parse_dir(COLORD "/ti1", colord_exts);
	int colord = parsed_files;
	if (kg_test_file_exists(ARGYLL)) {
		const char *const argyll_exts[] = { "cie", "ti2", "sp", "ti1", "ti3", NULL };
		parse_dir(ARGYLL, argyll_exts);
		known_values();
	} else
		printf("note: %s is absent (package argyll-ref); only colord files checked\n",
		       ARGYLL);
	printf("parsed %d real CGATS files (%d colord, %d argyll), %d tables\n", parsed_files,
	       colord, parsed_files - colord, parsed_tables);
	CHECK(colord >= 20, "expected the colord illuminants at least, parsed %d", colord);
	return kg_test_done("cgats-real");
}
