/* Resampling onto the 61-band grid and the small spectrum arithmetic. */
#include <string.h>

#include "kg_core.h"
#include "kg_test.h"

/* A smooth test function with curvature, so averaging and interpolation differ. */
static double f(double nm)
{
	return 0.5 + 0.3 * sin(nm / 37.0) + 1e-6 * (nm - 550) * (nm - 550);
}

static void test_same_grid(void)
{
	double wl[KG_NBANDS], v[KG_NBANDS];
	for (int i = 0; i < KG_NBANDS; i++) {
		wl[i] = kg_band_nm(i);
		v[i] = f(wl[i]);
	}
	kg_spectrum s;
	kg_err err = { { 0 } };
	CHECK(kg_spectrum_resample(wl, v, KG_NBANDS, 0, "grid", &s, &err) == 0, "%s", err.msg);
	for (int i = 0; i < KG_NBANDS; i++)
		CHECK_NEAR(s.v[i], v[i], 1e-15, "data on the grid are taken as they are");
}

/* 1 nm data: each band is the triangle-weighted mean, which for a linear function is
 * its value at the centre, and for data constant within a band is that constant. */
static void test_finer(void)
{
	double wl[401], v[401];
	for (int i = 0; i < 401; i++) {
		wl[i] = 350 + i;
		v[i] = 0.2 + 0.001 * wl[i];
	}
	kg_spectrum s;
	kg_err err = { { 0 } };
	CHECK(kg_spectrum_resample(wl, v, 401, 0, "linear 1 nm", &s, &err) == 0, "%s", err.msg);
	for (int i = 0; i < KG_NBANDS; i++)
		CHECK_NEAR(s.v[i], 0.2 + 0.001 * kg_band_nm(i), 1e-12, "finer linear data");

	/* A spike of 1 at one sample (553 nm): the bands at 550 and 555 see it through
	 * the triangle with weights (1 - 3/5) and (1 - 2/5), each over 5 nm of area;
	 * interpolating instead would give 0 at both. */
	for (int i = 0; i < 401; i++)
		v[i] = wl[i] == 553 ? 1.0 : 0.0;
	CHECK(kg_spectrum_resample(wl, v, 401, 0, "spike", &s, &err) == 0, "%s", err.msg);
	/* integral of the hat (1 nm wide base each side) times the triangle / 5 */
	CHECK_NEAR(s.v[30], 0.4 / 5.0, 1e-12, "550 nm band sees the 553 nm spike");
	CHECK_NEAR(s.v[31], 0.6 / 5.0, 1e-12, "555 nm band sees the 553 nm spike");
	CHECK_NEAR(s.v[29], 0.0, 1e-15, "545 nm band does not");
	double sum = 0;
	for (int i = 0; i < KG_NBANDS; i++)
		sum += s.v[i] * KG_LAMBDA_STEP;
	CHECK_NEAR(sum, 1.0, 1e-12, "band averaging keeps the area of the data");
}

/* 10 nm data are interpolated linearly: values at the samples kept, midpoints linear. */
static void test_coarser(void)
{
	double wl[41], v[41];
	for (int i = 0; i < 41; i++) {
		wl[i] = 380 + 10 * i;
		v[i] = f(wl[i]);
	}
	kg_spectrum s;
	kg_err err = { { 0 } };
	CHECK(kg_spectrum_resample(wl, v, 41, 0, "10 nm", &s, &err) == 0, "%s", err.msg);
	for (int i = 0; i < KG_NBANDS; i++) {
		double nm = kg_band_nm(i);
		int k = (int)((nm - 380) / 10);
		double want = ((int)nm % 10 == 0) ? f(nm) : 0.5 * (f(wl[k]) + f(wl[k + 1]));
		CHECK_NEAR(s.v[i], want, 1e-12, "coarser data interpolated linearly");
	}
	CHECK_NEAR(kg_samples_interp(wl, v, 41, 100), v[0], 0, "interp holds below");
	CHECK_NEAR(kg_samples_interp(wl, v, 41, 1000), v[40], 0, "interp holds above");
	CHECK_NEAR(kg_samples_interp(wl, v, 41, 385), 0.5 * (v[0] + v[1]), 1e-15, "interp");
}

static void test_out_of_range(void)
{
	double wl[31], v[31];
	for (int i = 0; i < 31; i++) {
		wl[i] = 410 + 10 * i; /* 410-710: misses 400-409 */
		v[i] = 0.01 * i;
	}
	kg_spectrum s;
	kg_err err = { { 0 } };
	int r = kg_spectrum_resample(wl, v, 31, 0, "short.cgats: sample 7", &s, &err);
	CHECK(r == KG_ERANGE, "uncovered range refused, got %d", r);
	CHECK(strstr(err.msg, "short.cgats: sample 7") && strstr(err.msg, "410-710"),
	      "message names the data and the range found: %s", err.msg);

	CHECK(kg_spectrum_resample(wl, v, 31, KG_RESAMPLE_EXTRAPOLATE, "x", &s, &err) == 0,
	      "%s", err.msg);
	CHECK_NEAR(s.v[0], v[0], 0, "extrapolation holds the first value");
	CHECK_NEAR(s.v[2], v[0], 0, "410 nm is the first sample");
	CHECK_NEAR(s.v[KG_NBANDS - 1], 0.29, 1e-15, "700 nm interpolated");

	double bad_wl[3] = { 400, 500, 500 }, bad_v[3] = { 0, 1, 2 };
	r = kg_spectrum_resample(bad_wl, bad_v, 3, 0, "dup", &s, &err);
	CHECK(r == KG_EINVAL && strstr(err.msg, "increase"), "repeated wavelength: %s", err.msg);
	double nan_wl[3] = { 400, 550, 700 }, nan_v[3] = { 0, NAN, 2 };
	r = kg_spectrum_resample(nan_wl, nan_v, 3, 0, "nan", &s, &err);
	CHECK(r == KG_EINVAL && strstr(err.msg, "550"), "NaN value refused: %s", err.msg);
}

static void test_arith(void)
{
	kg_spectrum a = kg_spectrum_const(2), b = kg_spectrum_const(3);
	b.v[10] = 5;
	kg_spectrum c = kg_spectrum_add(&a, &b);
	CHECK_NEAR(c.v[10], 7, 0, "add");
	c = kg_spectrum_sub(&a, &b);
	CHECK_NEAR(c.v[0], -1, 0, "sub");
	c = kg_spectrum_mul(&a, &b);
	CHECK_NEAR(c.v[10], 10, 0, "mul");
	c = kg_spectrum_scale(&b, 0.5);
	CHECK_NEAR(c.v[10], 2.5, 0, "scale");
	c = kg_spectrum_axpy(&a, 2, &b);
	CHECK_NEAR(c.v[10], 12, 0, "axpy");
	CHECK_NEAR(kg_spectrum_dot(&a, &b), 2 * (3 * 60 + 5), 1e-12, "dot");
	CHECK_NEAR(kg_spectrum_max(&b), 5, 0, "max");
	CHECK_NEAR(kg_spectrum_rmse(&a, &a), 0, 0, "rmse of equal");
	CHECK_NEAR(kg_spectrum_rmse(&a, &b), sqrt((60 * 1.0 + 9) / 61.0), 1e-12, "rmse");
	kg_spectrum a3 = kg_spectrum_scale(&a, 3);
	CHECK_NEAR(kg_spectrum_gfc(&a, &a3), 1, 1e-15, "gfc of same shape");
	kg_spectrum z = kg_spectrum_const(0);
	CHECK_NEAR(kg_spectrum_gfc(&a, &z), 0, 0, "gfc with zero spectrum");
	CHECK(kg_spectrum_isfinite(&a), "finite");
	a.v[3] = INFINITY;
	CHECK(!kg_spectrum_isfinite(&a), "not finite");
}

int main(void)
{
	test_same_grid();
	test_finer();
	test_coarser();
	test_out_of_range();
	test_arith();
	return kg_test_done("spectrum");
}
