/* Every refusal of the site calibration (and the matching ones of the reference
 * calibration) produces its intended message, naming the cause and the patches:
 *  - fewer than 3 patches in common: how many, and which ids are missing;
 *  - only neutral patches: nearly collinear, condition number, "neutral";
 *  - rank deficient (two colours only);
 *  - clipped patches (a channel >= 0.98), unless the clipped-fraction column says
 *    they are not; a clipped fraction > 0 refuses even below 0.98;
 *  - near-black patches (brightest channel < 0.01);
 *  - site ids the reference does not know;
 *  - NaN values, duplicate ids, an --exclude id that exists nowhere;
 *  - exactly 3 patches (residual 0 by construction) unless forced;
 *  - patches read in the wrong order (relative residual above max_residual);
 *  - too few patches left after those detection flagged (which are left out and
 *    listed, also through kogei-camera/1);
 * and --exclude turns a refused chart into an accepted one. The camera identity
 * comparison and its JSON round trip are checked at the end. */
#include <stdlib.h>
#include <unistd.h>

#include "calib_fixture.h"
#include "kg_test.h"

static kg_reference *reference(const kg_patchset *chart)
{
	kg_reference_options opt;
	kg_reference_options_default(&opt);
	kg_reference *ref = NULL;
	kg_err err = {{0}};
	if (kg_reference_fit(chart, chart, &opt, &ref, &err)) {
		fprintf(stderr, "reference: %s\n", err.msg);
		kg_test_failures++;
	}
	return ref;
}

/* A site patch set: n patches with the given ids and RGB. */
static kg_patchset *site_set(int n, const char *const *ids, const double (*rgb)[3])
{
	kg_patchset *ps = NULL;
	kg_err err = {{0}};
	if (kg_patchset_new(n, KG_PATCH_RGB, &ps, &err))
		return NULL;
	for (int i = 0; i < n; i++) {
		memcpy(ps->rgb[i], rgb[i], sizeof(ps->rgb[i]));
		kg_patchset_set_id(ps, i, ids[i], &err);
	}
	ps->source = strdup("site.cgats");
	return ps;
}

/* Fit and expect a refusal whose message holds every one of the fragments. */
static void expect_refusal(const char *what, const kg_reference *ref, const kg_patchset *site,
                           const kg_camera_options *opt, const char *const *fragments)
{
	kg_camera_calib *cam = NULL;
	kg_err err = {{0}};
	int ret = kg_camera_fit(ref, site, opt, &cam, &err);
	printf("%s: %s\n", what, ret ? err.msg : "(accepted)");
	CHECK(ret == KG_EINVAL, "%s: expected a refusal, got %d", what, ret);
	CHECK(cam == NULL, "%s: a camera was returned", what);
	for (int i = 0; fragments[i]; i++)
		CHECK(strstr(err.msg, fragments[i]) != NULL, "%s: message lacks \"%s\": %s", what,
		      fragments[i], err.msg);
	kg_camera_calib_free(&cam);
}

static void expect_accepted(const char *what, const kg_reference *ref, const kg_patchset *site,
                            const kg_camera_options *opt, int k)
{
	kg_camera_calib *cam = NULL;
	kg_err err = {{0}};
	int ret = kg_camera_fit(ref, site, opt, &cam, &err);
	CHECK(ret == 0, "%s: refused: %s", what, err.msg);
	if (cam)
		CHECK(cam->k == k, "%s: %d patches used, expected %d", what, cam->k, k);
	kg_camera_calib_free(&cam);
}

/* Patches flagged by detection (a FLAGS column) are left out and listed; too few
 * left refuses. Patches in the wrong order leave a residual above the limit. */
static void test_flagged_and_residual(const kg_reference *ref, int n, const char *const *ids,
                                      const double (*rgb)[3])
{
	kg_camera_options opt;
	kg_camera_options_default(&opt);
	kg_err err = {{0}};
	kg_patchset *site = site_set(n, ids, rgb);
	CHECK(kg_patchset_add_extra(site, "FLAGS", &err) == 0, "%s", err.msg);
	int col = kg_patchset_extra_index(site, "FLAGS");
	site->extra[1 * site->nextra + col] = KG_CHART_FLAG_NONUNIFORM;
	site->extra[4 * site->nextra + col] = KG_CHART_FLAG_GLARE | KG_CHART_FLAG_CLIPPED;
	kg_camera_calib *cam = NULL;
	int ret = kg_camera_fit(ref, site, &opt, &cam, &err);
	CHECK(ret == 0 && cam && cam->k == n - 2 && cam->nflagged == 2, "two flagged: %d %s", ret,
	      err.msg);
	if (cam && cam->nflagged == 2) {
		CHECK(!strcmp(cam->flagged_ids[0], ids[1]) && !strcmp(cam->flagged_ids[1], ids[4]) &&
		          cam->flagged_flags[0] == KG_CHART_FLAG_NONUNIFORM &&
		          cam->flagged_flags[1] == (KG_CHART_FLAG_GLARE | KG_CHART_FLAG_CLIPPED),
		      "flagged: %s %u, %s %u", cam->flagged_ids[0], cam->flagged_flags[0],
		      cam->flagged_ids[1], cam->flagged_flags[1]);
		for (int i = 0; i < cam->k; i++)
			CHECK(strcmp(cam->ids[i], ids[1]) && strcmp(cam->ids[i], ids[4]),
			      "flagged patch %s used", cam->ids[i]);
		/* Through the file and back. */
		memcpy(cam->identity.backend, "sim", 4);
		cam->identity.known = 1;
		snprintf(cam->identity.model, sizeof(cam->identity.model), "simulated sensor");
		snprintf(cam->identity.serial, sizeof(cam->identity.serial), "A");
		snprintf(cam->identity.pixfmt, sizeof(cam->identity.pixfmt), "bayer16");
		cam->identity.white_level = 4095;
		snprintf(cam->identity.demosaic, sizeof(cam->identity.demosaic), "bilinear");
		snprintf(cam->identity.capture, sizeof(cam->identity.capture), "chart");
		char path[] = "/tmp/kg-calib-refusals-XXXXXX";
		int fd = mkstemp(path);
		if (fd >= 0)
			close(fd);
		kg_camera_calib *back = NULL;
		CHECK(fd >= 0 && kg_camera_save(cam, path, &err) == 0 &&
		          kg_camera_load(path, &back, &err) == 0,
		      "round trip: %s", err.msg);
		if (back) {
			CHECK(back->nflagged == 2 && !strcmp(back->flagged_ids[1], ids[4]) &&
			          back->flagged_flags[1] == cam->flagged_flags[1],
			      "flagged after the round trip");
			CHECK(!memcmp(&back->identity, &cam->identity, sizeof(cam->identity)),
			      "identity after the round trip: %s %s", back->identity.model,
			      back->identity.serial);
		}
		kg_camera_calib_free(&back);
		unlink(path);
	}
	kg_camera_calib_free(&cam);
	/* All but 2 flagged: refused, naming them and why. */
	for (int i = 0; i < n - 2; i++)
		site->extra[i * site->nextra + col] = KG_CHART_FLAG_NONUNIFORM;
	expect_refusal("all but 2 flagged", ref, site, &opt,
	               (const char *const[]){"flagged by chart detection and left out",
	                                     "(non-uniform)", "2 usable patches left", NULL});
	kg_patchset_free(&site);

	/* The chart read turned around: ids kept, values reversed. */
	double turned[64][3];
	for (int i = 0; i < n; i++)
		memcpy(turned[i], rgb[n - 1 - i], sizeof(turned[i]));
	kg_patchset *rev = site_set(n, ids, (const double (*)[3])turned);
	expect_refusal("turned chart", ref, rev, &opt,
	               (const char *const[]){"site.cgats: relative residual",
	                                     "above the limit of 10.0 %", "Worst patches: P", NULL});
	opt.max_residual = 10;
	expect_accepted("turned chart, limit 1000 %", ref, rev, &opt, n);
	opt.max_residual = 0;
	expect_refusal("limit 0", ref, rev, &opt, (const char *const[]){"residual limit 0", NULL});
	kg_patchset_free(&rev);
}

/* Same camera, another camera, unknown. */
static void test_identity(void)
{
	kg_camera_identity a = {.known = 1, .white_level = 4095}, b, u = {0};
	snprintf(a.backend, sizeof(a.backend), "sim");
	snprintf(a.model, sizeof(a.model), "simulated sensor");
	snprintf(a.serial, sizeof(a.serial), "A");
	snprintf(a.pixfmt, sizeof(a.pixfmt), "bayer16");
	snprintf(a.demosaic, sizeof(a.demosaic), "bilinear");
	b = a;
	char note[256];
	kg_err err = {{0}};
	CHECK(kg_camera_identity_check(&a, "cam.json", &b, "img.tif", note, sizeof(note), &err) ==
	              0 && note[0] == 0,
	      "same camera: %s / %s", err.msg, note);
	snprintf(b.pixfmt, sizeof(b.pixfmt), "rgb16");
	CHECK(kg_camera_identity_check(&a, "cam.json", &b, "img.tif", note, sizeof(note), &err) ==
	              0 && strstr(note, "pixel format rgb16, calibrated in bayer16"),
	      "same camera, another format: %s", note);
	snprintf(b.serial, sizeof(b.serial), "B");
	int ret = kg_camera_identity_check(&a, "cam.json", &b, "img.tif", note, sizeof(note), &err);
	CHECK(ret == KG_EINVAL && strstr(err.msg, "img.tif was taken by sim camera") &&
	          strstr(err.msg, "serial B") && strstr(err.msg, "cam.json calibrates") &&
	          strstr(err.msg, "serial A") && strstr(err.msg, "--force"),
	      "another camera: %d %s", ret, err.msg);
	ret = kg_camera_identity_check(&u, "cam.json", &b, "img.tif", note, sizeof(note), &err);
	CHECK(ret == KG_ENOENT && strstr(err.msg, "cam.json records no camera identity"),
	      "calibration unknown: %s", err.msg);
	ret = kg_camera_identity_check(&a, "cam.json", &u, "img.tif", note, sizeof(note), &err);
	CHECK(ret == KG_ENOENT && strstr(err.msg, "img.tif is not a capture of a kogei session"),
	      "image unknown: %s", err.msg);
	/* From keywords: known only with backend, model and serial. */
	char *names[] = {"CAMERA_BACKEND", "CAMERA_MODEL", "CAMERA_SERIAL", "CAMERA_WHITE_LEVEL"};
	char *values[] = {"sim", "simulated sensor", "A", "4095"};
	kg_camera_identity k;
	CHECK(kg_camera_identity_from_keywords("p.cgats", names, values, 4, &k, &err) == 0 &&
	          k.known && k.white_level == 4095 && !strcmp(k.serial, "A"),
	      "from keywords: %s", err.msg);
	CHECK(kg_camera_identity_from_keywords("p.cgats", names, values, 2, &k, &err) == 0 &&
	          !k.known,
	      "without a serial: unknown");
	values[3] = "4095.5";
	CHECK(kg_camera_identity_from_keywords("p.cgats", names, values, 4, &k, &err) ==
	              KG_EINVAL && strstr(err.msg, "p.cgats: CAMERA_WHITE_LEVEL"),
	      "bad white level: %s", err.msg);
}

int main(void)
{
	kg_patchset *chart = fx_chart(24, 0.0, 7);
	kg_reference *ref = chart ? reference(chart) : NULL;
	if (!ref)
		return kg_test_done("calib-refusals");
	kg_patchset *good = fx_site(chart);
	double rgb[24][3];
	const char *ids[24];
	for (int i = 0; i < 24; i++) {
		memcpy(rgb[i], good->rgb[i], sizeof(rgb[i]));
		ids[i] = good->ids[i];
	}
	kg_camera_options opt;
	kg_camera_options_default(&opt);

	/* The intact chart is accepted. */
	good->source = strdup("site.cgats");
	expect_accepted("intact chart", ref, good, &opt, 24);

	/* Fewer than 3 patches in common. */
	kg_patchset *two = site_set(2, ids, (const double (*)[3])rgb);
	expect_refusal("two patches", ref, two, &opt,
	               (const char *const[]){"only 2 patches in common", "at least 3",
	                                     "Missing from site.cgats: P3, P4", NULL});
	kg_patchset_free(&two);

	/* Exactly 3 patches suffice (k = 3 is a hard case the design names): the best
	 * conditioned triple of the chart gives M2 = T^-1 exactly. */
	int best[3] = {0, 1, 2};
	double best_cond = INFINITY;
	for (int a = 0; a < 24; a++)
		for (int b = a + 1; b < 24; b++)
			for (int c = b + 1; c < 24; c++) {
				double m[9], det;
				for (int r = 0; r < 3; r++) {
					m[r] = rgb[a][r];
					m[3 + r] = rgb[b][r];
					m[6 + r] = rgb[c][r];
				}
				det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6]) +
				      m[2] * (m[3] * m[7] - m[4] * m[6]);
				/* Largest |det| of unit-normalised rows: the least collinear triple. */
				double na = hypot(hypot(m[0], m[1]), m[2]), nb = hypot(hypot(m[3], m[4]), m[5]);
				double nc = hypot(hypot(m[6], m[7]), m[8]);
				double q = -fabs(det) / (na * nb * nc);
				if (q < best_cond) {
					best_cond = q;
					best[0] = a;
					best[1] = b;
					best[2] = c;
				}
			}
	const char *three_ids[3] = {ids[best[0]], ids[best[1]], ids[best[2]]};
	double three_rgb[3][3];
	for (int i = 0; i < 3; i++)
		memcpy(three_rgb[i], rgb[best[i]], sizeof(three_rgb[i]));
	kg_patchset *three = site_set(3, three_ids, (const double (*)[3])three_rgb);
	kg_camera_calib *cam3 = NULL;
	kg_err err3 = {{0}};
	/* Their residual is 0 whatever they are: refused as unchecked, unless forced. */
	int ret3 = kg_camera_fit(ref, three, &opt, &cam3, &err3);
	CHECK(ret3 == KG_EINVAL && !cam3 && strstr(err3.msg, "only 3 usable patches") &&
	          strstr(err3.msg, "cannot be checked") && strstr(err3.msg, "--force"),
	      "three patches unforced: %d %s", ret3, err3.msg);
	kg_camera_options forced = opt;
	forced.force = 1;
	ret3 = kg_camera_fit(ref, three, &forced, &cam3, &err3);
	CHECK(ret3 == 0, "three patches %s %s %s: %s", three_ids[0], three_ids[1], three_ids[2],
	      err3.msg);
	if (cam3) {
		printf("three patches %s %s %s: accepted, condition number %.4g\n", three_ids[0],
		       three_ids[1], three_ids[2], cam3->cond_equilibrated);
		double check[3];
		for (int i = 0; i < 3; i++) {
			/* M2 rho_r = rho0 exactly for each of the three. */
			for (int r = 0; r < 3; r++)
				check[r] = cam3->M2[3 * r] * three_rgb[i][0] +
				           cam3->M2[3 * r + 1] * three_rgb[i][1] +
				           cam3->M2[3 * r + 2] * three_rgb[i][2];
			for (int r = 0; r < 3; r++)
				CHECK_NEAR(check[r], chart->rgb[best[i]][r], 1e-12, "M2 rho_r = rho0");
		}
	}
	kg_camera_calib_free(&cam3);
	kg_patchset_free(&three);

	/* Only neutral patches: all proportional to one grey, with a tiny tint. */
	double grey[6][3];
	const char *grey_ids[6] = {"P1", "P2", "P3", "P4", "P5", "P6"};
	for (int i = 0; i < 6; i++) {
		double level = 0.05 + 0.15 * i;
		grey[i][0] = level * 0.42 * (1 + 1e-3 * (i % 2));
		grey[i][1] = level * 0.50;
		grey[i][2] = level * 0.31 * (1 - 1e-3 * (i % 3));
	}
	kg_patchset *neutral = site_set(6, grey_ids, (const double (*)[3])grey);
	expect_refusal("neutral patches", ref, neutral, &opt,
	               (const char *const[]){"nearly collinear", "condition number", "limit 100",
	                                     "P1, P2, P3, P4, P5, P6", "neutral (grey) patches",
	                                     "differ in level, not in colour", NULL});
	kg_patchset_free(&neutral);

	/* Rank deficient: two colours, repeated at several levels. */
	double two_col[6][3];
	for (int i = 0; i < 6; i++)
		for (int c = 0; c < 3; c++)
			two_col[i][c] = (0.2 + 0.1 * i) * rgb[i % 2][c];
	kg_patchset *flat = site_set(6, grey_ids, (const double (*)[3])two_col);
	expect_refusal("two colours", ref, flat, &opt,
	               (const char *const[]){"rank deficient", "three independent colours",
	                                     "only two colour directions", NULL});
	kg_patchset_free(&flat);

	/* Clipped: P5 saturates in green. */
	double clipped[24][3];
	memcpy(clipped, rgb, sizeof(clipped));
	clipped[4][1] = 0.985;
	kg_patchset *clip = site_set(24, ids, (const double (*)[3])clipped);
	expect_refusal("clipped patch", ref, clip, &opt,
	               (const char *const[]){"1 clipped patch", "0.98 of full scale", "P5",
	                                     "--exclude", NULL});
	/* ... accepted when left out. */
	const char *excl[1] = {"P5"};
	kg_camera_options ex = opt;
	ex.exclude = excl;
	ex.nexclude = 1;
	expect_accepted("clipped patch excluded", ref, clip, &ex, 23);
	/* ... and when the file's clipped-fraction column says no pixel clipped. */
	kg_err err = {{0}};
	CHECK(kg_patchset_add_extra(clip, "CLIPPED_FRACTION", &err) == 0, "%s", err.msg);
	/* (P5, its green raised to 0.985, no longer fits the other patches through M2:
	 * the fit leaves it out as a misfit, flag 64, rather than refusing it as clipped) */
	expect_accepted("clipped-fraction 0", ref, clip, &opt, 23);
	/* A clipped fraction above 0 refuses a patch below 0.98. */
	clip->extra[(size_t)10 * clip->nextra + clip->nextra - 1] = 0.25;
	expect_refusal("clipped fraction", ref, clip, &opt,
	               (const char *const[]){"clipped-fraction column", "P11 (fraction 0.25)",
	                                     NULL});
	kg_patchset_free(&clip);

	/* Near-black: P8 and P12 far under exposed. */
	double dark[24][3];
	memcpy(dark, rgb, sizeof(dark));
	for (int c = 0; c < 3; c++) {
		dark[7][c] = 0.004 + 0.001 * c;
		dark[11][c] = 0.002;
	}
	kg_patchset *black = site_set(24, ids, (const double (*)[3])dark);
	expect_refusal("near-black patches", ref, black, &opt,
	               (const char *const[]){"2 near-black patches", "below 0.01", "P8", "P12",
	                                     NULL});
	kg_patchset_free(&black);

	/* Ids that do not match: another layout's names. */
	const char *other[24];
	char names[24][8];
	for (int i = 0; i < 24; i++) {
		snprintf(names[i], sizeof(names[i]), "%c%d", 'A' + i / 6, i % 6 + 1);
		other[i] = names[i];
	}
	kg_patchset *wrong = site_set(24, other, (const double (*)[3])rgb);
	expect_refusal("foreign ids", ref, wrong, &opt,
	               (const char *const[]){"patch ids do not match", "24 of its 24", "A1, A2",
	                                     "P1, P2", NULL});
	kg_patchset_free(&wrong);
	/* One stray id among the right ones. */
	other[0] = "P1";
	for (int i = 1; i < 24; i++)
		other[i] = ids[i];
	other[23] = "X99";
	kg_patchset *stray = site_set(24, other, (const double (*)[3])rgb);
	expect_refusal("stray id", ref, stray, &opt,
	               (const char *const[]){"patch ids do not match", "1 of its 24", "X99", NULL});
	kg_patchset_free(&stray);

	/* Duplicate ids, NaN, unknown --exclude. */
	other[23] = "P1";
	kg_patchset *dup = site_set(24, other, (const double (*)[3])rgb);
	expect_refusal("duplicate id", ref, dup, &opt,
	               (const char *const[]){"SAMPLE_ID P1 appears twice", NULL});
	kg_patchset_free(&dup);
	double bad[24][3];
	memcpy(bad, rgb, sizeof(bad));
	bad[2][2] = NAN;
	kg_patchset *nan = site_set(24, ids, (const double (*)[3])bad);
	expect_refusal("NaN", ref, nan, &opt, (const char *const[]){"patch P3", "RGB_B", NULL});
	kg_patchset_free(&nan);
	const char *nowhere[1] = {"Q7"};
	ex.exclude = nowhere;
	expect_refusal("unknown --exclude", ref, good, &ex,
	               (const char *const[]){"--exclude Q7", NULL});

	/* The reference calibration refuses the same kinds of chart. */
	kg_reference_options ropt;
	kg_reference_options_default(&ropt);
	kg_reference *r2 = NULL;
	chart->rgb[3][0] = 0.99;
	int ret = kg_reference_fit(chart, chart, &ropt, &r2, &err);
	printf("reference with a clipped patch: %s\n", err.msg);
	CHECK(ret == KG_EINVAL && strstr(err.msg, "clipped") && strstr(err.msg, "P4"), "%s",
	      err.msg);
	const char *p4[1] = {"P4"};
	ropt.exclude = p4;
	ropt.nexclude = 1;
	ret = kg_reference_fit(chart, chart, &ropt, &r2, &err);
	CHECK(ret == 0 && r2 && r2->m == 23 && r2->k == 23, "reference with P4 excluded: %s",
	      err.msg);
	kg_reference_free(&r2);

	test_flagged_and_residual(ref, 24, ids, (const double (*)[3])rgb);
	test_identity();

	kg_patchset_free(&good);
	kg_reference_free(&ref);
	kg_patchset_free(&chart);
	return kg_test_done("calib-refusals");
}
