/* Colorimetry formulas against published values: CIEDE2000 (Sharma et al.), the D65
 * white point, CIELAB and sRGB identities, illuminant construction and errors. */
#include <math.h>
#include <string.h>

#include "colorimetry.h"
#include "kg_test.h"

/* Sharma, G., Wu, W., Dalal, E. N. (2005), "The CIEDE2000 color-difference formula:
 * implementation notes, supplementary test data, and mathematical observations",
 * Color Res. Appl. 30(1):21-30, Table 1: L1 a1 b1, L2 a2 b2, Delta E00. */
static const double sharma_pairs[34][7] = {
	{50.0000, 2.6772, -79.7751, 50.0000, 0.0000, -82.7485, 2.0425},
	{50.0000, 3.1571, -77.2803, 50.0000, 0.0000, -82.7485, 2.8615},
	{50.0000, 2.8361, -74.0200, 50.0000, 0.0000, -82.7485, 3.4412},
	{50.0000, -1.3802, -84.2814, 50.0000, 0.0000, -82.7485, 1.0000},
	{50.0000, -1.1848, -84.8006, 50.0000, 0.0000, -82.7485, 1.0000},
	{50.0000, -0.9009, -85.5211, 50.0000, 0.0000, -82.7485, 1.0000},
	{50.0000, 0.0000, 0.0000, 50.0000, -1.0000, 2.0000, 2.3669},
	{50.0000, -1.0000, 2.0000, 50.0000, 0.0000, 0.0000, 2.3669},
	{50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0009, 7.1792},
	{50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0010, 7.1792},
	{50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0011, 7.2195},
	{50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0012, 7.2195},
	{50.0000, -0.0010, 2.4900, 50.0000, 0.0009, -2.4900, 4.8045},
	{50.0000, -0.0010, 2.4900, 50.0000, 0.0010, -2.4900, 4.8045},
	{50.0000, -0.0010, 2.4900, 50.0000, 0.0011, -2.4900, 4.7461},
	{50.0000, 2.5000, 0.0000, 50.0000, 0.0000, -2.5000, 4.3065},
	{50.0000, 2.5000, 0.0000, 73.0000, 25.0000, -18.0000, 27.1492},
	{50.0000, 2.5000, 0.0000, 61.0000, -5.0000, 29.0000, 22.8977},
	{50.0000, 2.5000, 0.0000, 56.0000, -27.0000, -3.0000, 31.9030},
	{50.0000, 2.5000, 0.0000, 58.0000, 24.0000, 15.0000, 19.4535},
	{50.0000, 2.5000, 0.0000, 50.0000, 3.1736, 0.5854, 1.0000},
	{50.0000, 2.5000, 0.0000, 50.0000, 3.2972, 0.0000, 1.0000},
	{50.0000, 2.5000, 0.0000, 50.0000, 1.8634, 0.5757, 1.0000},
	{50.0000, 2.5000, 0.0000, 50.0000, 3.2592, 0.3350, 1.0000},
	{60.2574, -34.0099, 36.2677, 60.4626, -34.1751, 39.4387, 1.2644},
	{63.0109, -31.0961, -5.8663, 62.8187, -29.7946, -4.0864, 1.2630},
	{61.2901, 3.7196, -5.3901, 61.4292, 2.2480, -4.9620, 1.8731},
	{35.0831, -44.1164, 3.7933, 35.0232, -40.0716, 1.5901, 1.8645},
	{22.7233, 20.0904, -46.6940, 23.0331, 14.9730, -42.5619, 2.0373},
	{36.4612, 47.8580, 18.3852, 36.2715, 50.5065, 21.2231, 1.4146},
	{90.8027, -2.0831, 1.4410, 91.1528, -1.6435, 0.0447, 1.4441},
	{90.9257, -0.5406, -0.9208, 88.6381, -0.8985, -0.7239, 1.5381},
	{6.7747, -0.2908, -2.4247, 5.8714, -0.0985, -2.2286, 0.6377},
	{2.0776, 0.0795, -1.1350, 0.9033, -0.0636, -0.5514, 0.9082},
};

static void test_ciede2000(void)
{
	double max_err = 0.0;
	for (int i = 0; i < 34; i++) {
		const double *p = sharma_pairs[i];
		kg_lab a = {p[0], p[1], p[2]}, b = {p[3], p[4], p[5]};
		double d = kg_ciede2000(a, b), back = kg_ciede2000(b, a);
		char what[64];
		snprintf(what, sizeof(what), "Sharma pair %d", i + 1);
		CHECK_NEAR(d, p[6], 1e-4, what);
		CHECK_NEAR(back, d, 1e-12, "CIEDE2000 symmetry");
		if (fabs(d - p[6]) > max_err)
			max_err = fabs(d - p[6]);
	}
	CHECK(kg_ciede2000((kg_lab){50, 10, -10}, (kg_lab){50, 10, -10}) == 0.0,
	      "identical colours differ");
	printf("CIEDE2000: max |error| over the 34 Sharma pairs = %.3g\n", max_err);
}

static kg_illuminant *named(const char *name)
{
	kg_illuminant *ill = NULL;
	kg_err err = {{0}};
	if (kg_illuminant_by_name(name, &ill, &err) != 0) {
		fprintf(stderr, "%s\n", err.msg);
		exit(1);
	}
	return ill;
}

/* The CIE way for a tabulated illuminant: sums at 5 nm over 360-830 nm. */
static kg_xyz d65_white_5nm(void)
{
	double t[3] = {0, 0, 0};
	for (int nm = KG_CMF_FIRST_NM; nm <= KG_CMF_LAST_NM; nm += 5) {
		double s = kg_cie_d65[(nm - KG_DAYLIGHT_FIRST_NM) / 5];
		for (int c = 0; c < 3; c++)
			t[c] += s * kg_cie1931_cmf[nm - KG_CMF_FIRST_NM][c];
	}
	return (kg_xyz){100.0 * t[0] / t[1], 100.0, 100.0 * t[2] / t[1]};
}

static void test_white_points(void)
{
	kg_xyY w5 = kg_xyz_to_xyY(d65_white_5nm());
	printf("D65 white, 5 nm table 360-830: x %.6f y %.6f\n", w5.x, w5.y);
	CHECK_NEAR(w5.x, 0.31272, 1e-4, "D65 x (5 nm)");
	CHECK_NEAR(w5.y, 0.32903, 1e-4, "D65 y (5 nm)");

	kg_illuminant *d65 = named("D65");
	kg_xyY wf = kg_xyz_to_xyY(kg_illuminant_white_full(d65));
	printf("D65 white, 1 nm integration: x %.6f y %.6f\n", wf.x, wf.y);
	CHECK_NEAR(wf.x, 0.31272, 1e-4, "D65 x (1 nm)");
	CHECK_NEAR(wf.y, 0.32903, 1e-4, "D65 y (1 nm)");

	/* The grid truncates at 400 and 700 nm: the white moves, but not far. */
	kg_xyz wg = kg_illuminant_white(d65);
	kg_xyY wgy = kg_xyz_to_xyY(wg);
	printf("D65 white, 400-700 nm grid: x %.6f y %.6f (X %.4f Z %.4f)\n", wgy.x, wgy.y,
	       wg.X, wg.Z);
	CHECK_NEAR(wg.Y, 100.0, 1e-10, "grid white Y");
	CHECK_NEAR(wgy.x, 0.31272, 3e-3, "D65 x (grid)");
	CHECK_NEAR(wgy.y, 0.32903, 3e-3, "D65 y (grid)");

	/* The perfect diffuser is the white, whatever the illuminant. */
	kg_spectrum one = kg_spectrum_const(1.0);
	const char *names[] = {"D65", "D50", "A", "E", "D75", "4000K"};
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++) {
		kg_illuminant *ill = named(names[i]);
		kg_xyz w = kg_illuminant_white(ill);
		kg_lab lab = kg_xyz_to_lab(kg_reflectance_to_xyz(&one, ill), w);
		CHECK_NEAR(lab.L, 100.0, 1e-10, names[i]);
		CHECK_NEAR(lab.a, 0.0, 1e-10, names[i]);
		CHECK_NEAR(lab.b, 0.0, 1e-10, names[i]);
		kg_illuminant_free(&ill);
	}
	kg_illuminant_free(&d65);
}

static void test_lab_round_trip(void)
{
	kg_xyz white = {95.047, 100.0, 108.883};
	const kg_xyz samples[] = {
		{41.24, 21.26, 1.93}, {20.0, 30.0, 40.0}, {0.1, 0.2, 0.05},
		{0.5, 0.8856, 1.0},   {0.0, 0.0, 0.0},    {150.0, 120.0, 90.0},
	};
	for (size_t i = 0; i < sizeof(samples) / sizeof(samples[0]); i++) {
		kg_xyz c = samples[i];
		kg_xyz back = kg_lab_to_xyz(kg_xyz_to_lab(c, white), white);
		CHECK_NEAR(back.X, c.X, 1e-10 * (1 + c.X), "Lab round trip X");
		CHECK_NEAR(back.Y, c.Y, 1e-10 * (1 + c.Y), "Lab round trip Y");
		CHECK_NEAR(back.Z, c.Z, 1e-10 * (1 + c.Z), "Lab round trip Z");
		kg_xyY xyy = kg_xyz_to_xyY(c);
		kg_xyz back2 = kg_xyY_to_xyz(xyy);
		CHECK_NEAR(back2.X, c.X, 1e-10 * (1 + c.X), "xyY round trip X");
		CHECK_NEAR(back2.Z, c.Z, 1e-10 * (1 + c.Z), "xyY round trip Z");
	}
	/* Continuity at the break point of the cube root (CIE 15:2004 eq. 8.5). */
	double t = 216.0 / 24389.0;
	kg_lab below = kg_xyz_to_lab((kg_xyz){0, 100.0 * t * (1 - 1e-12), 0}, white);
	kg_lab above = kg_xyz_to_lab((kg_xyz){0, 100.0 * t * (1 + 1e-12), 0}, white);
	CHECK_NEAR(below.L, 8.0, 1e-8, "L* at the break point");
	CHECK_NEAR(above.L, 8.0, 1e-8, "L* at the break point");
	kg_lab l = kg_xyz_to_lab((kg_xyz){0, 100.0 * pow(66.0 / 116.0, 3.0), 0}, white);
	CHECK_NEAR(l.L, 50.0, 1e-9, "L* of Y = 18.42");
}

static void test_srgb(void)
{
	kg_illuminant *d65 = named("D65"), *d50 = named("D50");
	kg_xyz w65 = kg_illuminant_white(d65), w50 = kg_illuminant_white(d50);
	kg_rgb r = kg_xyz_to_linear_srgb(w65, w65);
	CHECK_NEAR(r.r, 1.0, 1e-12, "sRGB of the D65 white, R");
	CHECK_NEAR(r.g, 1.0, 1e-12, "sRGB of the D65 white, G");
	CHECK_NEAR(r.b, 1.0, 1e-12, "sRGB of the D65 white, B");
	kg_rgb e = kg_srgb_encode(r);
	unsigned char u8[3];
	kg_rgb_to_u8(e, u8);
	CHECK(u8[0] == 255 && u8[1] == 255 && u8[2] == 255, "white is %d %d %d", u8[0], u8[1],
	      u8[2]);
	r = kg_xyz_to_linear_srgb(w50, w50);
	CHECK_NEAR(r.r, 1.0, 1e-12, "sRGB of the D50 white under D50, R");
	CHECK_NEAR(r.g, 1.0, 1e-12, "sRGB of the D50 white under D50, G");
	CHECK_NEAR(r.b, 1.0, 1e-12, "sRGB of the D50 white under D50, B");
	/* Mid grey stays grey. */
	r = kg_xyz_to_linear_srgb((kg_xyz){0.2 * w50.X, 0.2 * w50.Y, 0.2 * w50.Z}, w50);
	CHECK_NEAR(r.r, 0.2, 1e-12, "grey R");
	CHECK_NEAR(r.b, 0.2, 1e-12, "grey B");
	/* The sRGB primaries (IEC 61966-2-1, rounded): red is (1, 0, 0). */
	kg_xyz std_white = {95.05, 100.0, 108.90};
	r = kg_xyz_to_linear_srgb((kg_xyz){41.24, 21.26, 1.93}, std_white);
	CHECK_NEAR(r.r, 1.0, 2e-3, "red primary R");
	CHECK_NEAR(r.g, 0.0, 2e-3, "red primary G");
	CHECK_NEAR(r.b, 0.0, 2e-3, "red primary B");
	/* Inverse for the same white. */
	kg_xyz c = {30.0, 25.0, 10.0};
	kg_xyz back = kg_linear_srgb_to_xyz(kg_xyz_to_linear_srgb(c, w50), w50);
	CHECK_NEAR(back.X, c.X, 1e-10, "sRGB round trip X");
	CHECK_NEAR(back.Y, c.Y, 1e-10, "sRGB round trip Y");
	CHECK_NEAR(back.Z, c.Z, 1e-10, "sRGB round trip Z");

	/* Transfer function: published break points and a mid value. */
	kg_rgb enc = kg_srgb_encode((kg_rgb){0.0031308, 0.5, -0.25});
	CHECK_NEAR(enc.r, 0.0404500, 1e-6, "encode at the break");
	CHECK_NEAR(enc.g, 0.7353569831, 1e-9, "encode 0.5");
	CHECK(enc.b < 0.0, "negative values are mirrored");
	kg_rgb dec = kg_srgb_decode(enc);
	CHECK_NEAR(dec.g, 0.5, 1e-12, "decode(encode(0.5))");
	CHECK_NEAR(dec.b, -0.25, 1e-12, "decode(encode(-0.25))");
	CHECK_NEAR(kg_srgb_decode((kg_rgb){0.5, 0, 0}).r, 0.2140411405, 1e-9, "decode 0.5");

	kg_rgb_to_u8((kg_rgb){-0.1, 1.2, 0.5}, u8);
	CHECK(u8[0] == 0 && u8[1] == 255 && u8[2] == 128, "clamp gives %d %d %d", u8[0],
	      u8[1], u8[2]);
	kg_rgb_to_u8((kg_rgb){NAN, 1.0 / 255.0, 0.998}, u8);
	CHECK(u8[0] == 0 && u8[1] == 1 && u8[2] == 254, "clamp gives %d %d %d", u8[0], u8[1],
	      u8[2]);

	kg_xyz a = kg_bradford_adapt(w65, w65, w50);
	CHECK_NEAR(a.X, w50.X, 1e-10, "Bradford maps white to white (X)");
	CHECK_NEAR(a.Z, w50.Z, 1e-10, "Bradford maps white to white (Z)");
	kg_illuminant_free(&d65);
	kg_illuminant_free(&d50);
}

static void test_illuminants(void)
{
	/* Daylight from S0, S1, S2 against the tabulated D65: at 6504 K (the rounded
	 * temperature) the shape is close; at 6500 x 1.4388/1.4380 K, the temperature the
	 * CIE uses, the rounded M1, M2 reproduce the table. */
	kg_err err = {{0}};
	kg_illuminant *d65 = named("D65");
	const double ccts[2] = {6504.0, 6500.0 * 1.4388 / 1.4380}, tols[2] = {0.1, 2e-3};
	for (int k = 0; k < 2; k++) {
		kg_illuminant *day = NULL;
		CHECK(kg_illuminant_daylight(ccts[k], &day, &err) == 0, "%s", err.msg);
		if (!day)
			continue;
		double max_diff = 0.0;
		for (int i = 0; i < KG_DAYLIGHT_COUNT; i++)
			if (fabs(day->v[i] - kg_cie_d65[i]) > max_diff)
				max_diff = fabs(day->v[i] - kg_cie_d65[i]);
		printf("daylight %.2f K vs tabulated D65: max |diff| %.4g (100 at 560 nm), "
		       "GFC %.8f\n",
		       ccts[k], max_diff, kg_spectrum_gfc(&day->spd, &d65->spd));
		CHECK(max_diff < tols[k], "daylight %g K differs from D65 by %g", ccts[k],
		      max_diff);
		kg_xyY a = kg_xyz_to_xyY(kg_illuminant_white_full(day));
		kg_xyY b = kg_xyz_to_xyY(kg_illuminant_white_full(d65));
		CHECK_NEAR(a.x, b.x, 1e-4, "daylight x");
		CHECK_NEAR(a.y, b.y, 1e-4, "daylight y");
		kg_illuminant_free(&day);
	}
	kg_illuminant_free(&d65);

	/* The CIE daylight locus: x_D of D50 and D75 (CIE 15:2004 Table T.3). */
	const struct {
		const char *name;
		double x, y;
	} locus[] = {{"D50", 0.34567, 0.35851}, {"D55", 0.33243, 0.34744},
	             {"D75", 0.29903, 0.31488}};
	for (size_t i = 0; i < sizeof(locus) / sizeof(locus[0]); i++) {
		kg_illuminant *ill = named(locus[i].name);
		kg_xyY w = kg_xyz_to_xyY(kg_illuminant_white_full(ill));
		printf("%s white (1 nm integration): x %.5f y %.5f\n", ill->name, w.x, w.y);
		CHECK_NEAR(w.x, locus[i].x, 1e-4, locus[i].name);
		CHECK_NEAR(w.y, locus[i].y, 1e-4, locus[i].name);
		CHECK(strcmp(ill->name, locus[i].name) == 0, "name %s", ill->name);
		kg_illuminant_free(&ill);
	}

	/* Illuminant A: 100 at 560 nm and the published end values (CIE 15:2004 T.1). */
	kg_illuminant *ia = named("a");
	CHECK(ia->nsamples == 531, "A has %d samples", ia->nsamples);
	CHECK_NEAR(ia->v[560 - 300], 100.0, 1e-12, "A at 560 nm");
	CHECK_NEAR(ia->spd.v[32], 100.0, 1e-12, "A on the grid at 560 nm");
	CHECK_NEAR(ia->v[0], 0.930483, 1e-5, "A at 300 nm");
	CHECK_NEAR(ia->v[780 - 300], 241.675, 1e-3, "A at 780 nm");
	CHECK_NEAR(ia->v[830 - 300], 261.602, 1e-3, "A at 830 nm");
	kg_xyY wa = kg_xyz_to_xyY(kg_illuminant_white_full(ia));
	printf("A white (1 nm): x %.5f y %.5f\n", wa.x, wa.y);
	CHECK_NEAR(wa.x, 0.44757, 1e-4, "A x");
	CHECK_NEAR(wa.y, 0.40745, 1e-4, "A y");
	kg_illuminant_free(&ia);

	/* Names and their errors. */
	kg_illuminant *ill = NULL;
	CHECK(kg_illuminant_by_name("5500K", &ill, &err) == 0 && ill, "%s", err.msg);
	kg_illuminant_free(&ill);
	CHECK(kg_illuminant_by_name("d065", &ill, &err) == 0 && ill &&
	          ill->spd.v[0] == kg_cie_d65[20],
	      "d065 is the tabulated D65");
	kg_illuminant_free(&ill);
	CHECK(kg_illuminant_by_name("D39", &ill, &err) == KG_ERANGE && !ill, "D39");
	CHECK(strstr(err.msg, "D39") != NULL, "message names the input: %s", err.msg);
	CHECK(kg_illuminant_by_name("D251", &ill, &err) == KG_ERANGE, "D251");
	CHECK(kg_illuminant_by_name("3000K", &ill, &err) == KG_ERANGE, "3000K");
	CHECK(strstr(err.msg, "4000-25000") != NULL, "message says the range: %s", err.msg);
	CHECK(kg_illuminant_by_name("F2", &ill, &err) == KG_EINVAL, "F2");
	CHECK(kg_illuminant_by_name("", &ill, &err) == KG_EINVAL, "empty name");
	CHECK(kg_illuminant_by_name("DK", &ill, &err) == KG_EINVAL, "DK");
	CHECK(kg_illuminant_daylight(3999.0, &ill, &err) == KG_ERANGE, "3999 K");
	CHECK(kg_illuminant_daylight(25001.0, &ill, &err) == KG_ERANGE, "25001 K");
	CHECK(kg_illuminant_daylight(NAN, &ill, &err) == KG_ERANGE, "NaN K");
	CHECK(kg_illuminant_daylight(25000.0, &ill, &err) == 0, "25000 K: %s", err.msg);
	kg_illuminant_free(&ill);
	CHECK(kg_illuminant_lookup("no-such-illuminant", &ill, &err) == KG_EINVAL,
	      "lookup of an unknown name");
	CHECK(strstr(err.msg, "nor a file") && strstr(err.msg, "D<nn>"), "message: %s",
	      err.msg);
	CHECK(kg_illuminant_lookup("d50", &ill, &err) == 0 && ill && strcmp(ill->name, "D50") == 0,
	      "lookup of a name: %s", err.msg);
	kg_illuminant_free(&ill);

	/* From samples: must cover the grid and have some light. */
	double wl[] = {380, 500, 780}, v[] = {1, 2, 1}, zero[] = {0, 0, 0};
	CHECK(kg_illuminant_from_samples("test", wl, v, 3, &ill, &err) == 0, "%s", err.msg);
	CHECK(ill && ill->nsamples == 3 && fabs(ill->spd.v[20] - 2.0) < 1e-12,
	      "samples kept and resampled");
	kg_illuminant_free(&ill);
	CHECK(kg_illuminant_from_samples("dark", wl, zero, 3, &ill, &err) == KG_EINVAL,
	      "all-zero illuminant");
	double short_wl[] = {450, 500, 780};
	CHECK(kg_illuminant_from_samples("short", short_wl, v, 3, &ill, &err) != 0 && !ill,
	      "illuminant not covering 400 nm");
	double bad_wl[] = {380, 380, 780};
	CHECK(kg_illuminant_from_samples("bad", bad_wl, v, 3, &ill, &err) == KG_EINVAL,
	      "repeated wavelength");
}

static void test_integration(void)
{
	kg_err err = {{0}};
	kg_illuminant *d65 = named("D65");

	/* Coarse (10 nm) data of a cubic are interpolated exactly by the Lagrange cubic, so
	 * they integrate like the same cubic given every nm. */
	double wl10[48], v10[48], wl1[471], v1[471];
	for (int i = 0; i < 48; i++) {
		double x = (360.0 + 10 * i - 600.0) / 100.0;
		wl10[i] = 360.0 + 10 * i;
		v10[i] = 0.5 + 0.1 * x - 0.05 * x * x + 0.02 * x * x * x;
	}
	for (int i = 0; i < 471; i++) {
		double x = (360.0 + i - 600.0) / 100.0;
		wl1[i] = 360.0 + i;
		v1[i] = 0.5 + 0.1 * x - 0.05 * x * x + 0.02 * x * x * x;
	}
	kg_xyz a, b;
	CHECK(kg_samples_to_xyz(wl10, v10, 48, d65, &a, &err) == 0, "%s", err.msg);
	CHECK(kg_samples_to_xyz(wl1, v1, 471, d65, &b, &err) == 0, "%s", err.msg);
	CHECK_NEAR(a.X, b.X, 1e-9, "cubic 10 nm vs 1 nm, X");
	CHECK_NEAR(a.Y, b.Y, 1e-9, "cubic 10 nm vs 1 nm, Y");
	CHECK_NEAR(a.Z, b.Z, 1e-9, "cubic 10 nm vs 1 nm, Z");

	/* A flat unit reflectance is the white; a flat unit radiance gives KG_KM sum ybar. */
	double flat_wl[] = {300, 900}, flat[] = {1, 1};
	CHECK(kg_samples_to_xyz(flat_wl, flat, 2, d65, &a, &err) == 0, "%s", err.msg);
	kg_xyz w = kg_illuminant_white_full(d65);
	CHECK_NEAR(a.X, w.X, 1e-10, "flat reflectance X");
	CHECK_NEAR(a.Y, 100.0, 1e-10, "flat reflectance Y");
	CHECK(kg_samples_to_xyz(flat_wl, flat, 2, NULL, &a, &err) == 0, "%s", err.msg);
	double sum_y = 0.0;
	for (int i = 0; i < KG_CMF_COUNT; i++)
		sum_y += kg_cie1931_cmf[i][1];
	CHECK_NEAR(a.Y, KG_KM * sum_y, 1e-9, "flat radiance Y");
	printf("sum of ybar at 1 nm: %.6f\n", sum_y);

	/* Colour signal relative to its illuminant equals the reflectance conversion. */
	kg_spectrum r;
	for (int i = 0; i < KG_NBANDS; i++)
		r.v[i] = 0.2 + 0.6 * i / (KG_NBANDS - 1.0);
	kg_spectrum c = kg_spectrum_mul(&r, &d65->spd);
	kg_xyz xr = kg_reflectance_to_xyz(&r, d65), xs = kg_signal_to_xyz(&c, d65);
	CHECK_NEAR(xr.X, xs.X, 1e-10, "signal vs reflectance X");
	CHECK_NEAR(xr.Y, xs.Y, 1e-10, "signal vs reflectance Y");
	CHECK_NEAR(xr.Z, xs.Z, 1e-10, "signal vs reflectance Z");
	kg_spectrum unit = kg_spectrum_const(1.0);
	kg_xyz abs_y = kg_signal_to_xyz(&unit, NULL);
	double grid_sum_y = 0.0;
	for (int i = 0; i < KG_NBANDS; i++)
		grid_sum_y += kg_cie1931_cmf[40 + 5 * i][1];
	CHECK_NEAR(abs_y.Y, KG_KM * 5.0 * grid_sum_y, 1e-9, "absolute signal Y");

	/* Bad input. */
	double dup_wl[] = {400, 400}, nan_v[] = {1, NAN};
	CHECK(kg_samples_to_xyz(dup_wl, flat, 2, d65, &a, &err) == KG_EINVAL, "repeated nm");
	CHECK(kg_samples_to_xyz(flat_wl, nan_v, 2, d65, &a, &err) == KG_EINVAL, "NaN value");
	CHECK(strstr(err.msg, "finite") != NULL, "message: %s", err.msg);
	CHECK(kg_samples_to_xyz(flat_wl, flat, 1, d65, &a, &err) == KG_EINVAL, "one sample");
	kg_illuminant_free(&d65);
}

/* Integration over part of the observer's range: the rows inside the limits, the
 * normalisation over the same rows. */
static void test_integration_range(void)
{
	kg_err err = {{0}};
	kg_illuminant *d65 = named("D65");
	double wl[31], v[31];
	for (int i = 0; i < 31; i++) {
		wl[i] = 400.0 + 10 * i;
		v[i] = 0.05 + 0.9 * i / 30.0;
	}
	kg_xyz full, all, part;
	CHECK(kg_samples_to_xyz(wl, v, 31, d65, &full, &err) == 0, "%s", err.msg);
	CHECK(kg_samples_to_xyz_range(wl, v, 31, d65, 360, 830, &all, &err) == 0, "%s",
	      err.msg);
	CHECK(full.X == all.X && full.Y == all.Y && full.Z == all.Z,
	      "360-830 is kg_samples_to_xyz");
	CHECK(kg_samples_to_xyz_range(wl, v, 31, d65, 400, 700, &part, &err) == 0, "%s",
	      err.msg);
	/* By hand: the same sums over rows 400..700 only. */
	kg_xyz hand = {0, 0, 0};
	double lum = 0.0;
	for (int nm = 400; nm <= 700; nm++) {
		const double *c = kg_cie1931_cmf[nm - KG_CMF_FIRST_NM];
		double s = kg_samples_interp(d65->wl, d65->v, d65->nsamples, nm);
		double r = kg_samples_interp(wl, v, 31, nm);
		hand.X += s * r * c[0];
		hand.Y += s * r * c[1];
		hand.Z += s * r * c[2];
		lum += s * c[1];
	}
	CHECK_NEAR(part.X, 100 * hand.X / lum, 1e-9, "400-700 X by hand");
	CHECK_NEAR(part.Y, 100 * hand.Y / lum, 1e-9, "400-700 Y by hand");
	CHECK_NEAR(part.Z, 100 * hand.Z / lum, 1e-9, "400-700 Z by hand");
	CHECK(fabs(part.X - full.X) > 0.05, "held ends beyond 700 nm change X: %g vs %g",
	      part.X, full.X);
	kg_xyz w = kg_illuminant_white_range(d65, 400, 700);
	CHECK_NEAR(w.Y, 100.0, 1e-12, "white over 400-700 has Y = 100");
	CHECK(kg_samples_to_xyz_range(wl, v, 31, d65, 900, 950, &part, &err) == KG_ERANGE &&
	          strstr(err.msg, "900-950"),
	      "a range outside the observer refused: %s", err.msg);
	CHECK(isnan(kg_illuminant_white_range(d65, 700, 400).Y), "empty range: NaN white");
	kg_illuminant_free(&d65);
}

int main(void)
{
	test_ciede2000();
	test_white_points();
	test_lab_round_trip();
	test_srgb();
	test_illuminants();
	test_integration();
	test_integration_range();
	return kg_test_done("colorimetry_formulas");
}
