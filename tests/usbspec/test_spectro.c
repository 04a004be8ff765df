/* Reflectance math and the sim spectrometer, without USB. */
#include <string.h>

#include "kg_devices.h"
#include "kg_test.h"

static void reading_of(kg_spectro_reading *r, int n, double (*f)(double), double scale)
{
	memset(r, 0, sizeof(*r));
	r->n = n;
	r->wl = malloc(sizeof(double) * n);
	r->counts = malloc(sizeof(double) * n);
	r->integration_us = 1000;
	for (int p = 0; p < n; p++) {
		r->wl[p] = 380 + p * 0.5;
		r->counts[p] = 100 + scale * (f ? f(r->wl[p]) : 0);
	}
}

static double one(double wl) { return 1.0; }
static double ramp(double wl) { return 0.1 + 0.8 * (wl - 380) / 340; }

static void test_math(void)
{
	/* Corrections: electrical dark = mean of the masked pixels, then c / poly(c). */
	kg_spectro_info info = {.npixels = 6, .dark_first = 0, .dark_last = 1, .nl_order = 1,
	                        .nl_coeffs = {1.0, -1e-3}};
	double raw[6] = {10, 12, 111, 211, 311, 11}, out[6];
	kg_spectro_correct(&info, KG_CORRECT_ELECTRICAL_DARK | KG_CORRECT_NONLINEARITY, raw, out, NULL);
	CHECK_NEAR(out[2], 100 / (1 - 0.1), 1e-9, "dark + nonlinearity");
	CHECK_NEAR(out[4], 300 / (1 - 0.3), 1e-9, "dark + nonlinearity");
	kg_spectro_correct(&info, KG_CORRECT_ELECTRICAL_DARK, raw, out, NULL);
	CHECK_NEAR(out[3], 200, 1e-12, "dark only");
	kg_spectro_correct(&info, 0, raw, out, NULL);
	CHECK_NEAR(out[3], 211, 1e-12, "no correction");
	/* A factor that is not positive is an error, not a count left uncorrected. */
	kg_spectro_info bad = {.npixels = 6, .dark_first = 0, .dark_last = 1, .nl_order = 1,
	                       .nl_coeffs = {1.0, -4e-3}, .model = "M", .serial = "S1"};
	kg_err nerr = {{0}};
	CHECK(kg_spectro_correct(&bad, KG_CORRECT_ELECTRICAL_DARK | KG_CORRECT_NONLINEARITY, raw,
	                         out, &nerr) == KG_ERANGE &&
	          strstr(nerr.msg, "nonlinearity correction factor -0.2 at pixel 4"),
	      "nonlinearity factor <= 0: %s", nerr.msg);
	bad.nl_coeffs[0] = 0;
	bad.nl_coeffs[1] = 0;
	CHECK(kg_spectro_correct(&bad, KG_CORRECT_NONLINEARITY, raw, out, &nerr) == KG_ERANGE,
	      "nonlinearity factor 0");
	CHECK(kg_spectro_correct(&bad, KG_CORRECT_ELECTRICAL_DARK, raw, out, &nerr) == 0,
	      "no nonlinearity asked for: %s", nerr.msg);

	double in[5] = {0, 0, 3, 0, 0}, sm[5];
	kg_boxcar(in, sm, 5, 1);
	CHECK_NEAR(sm[1], 1, 1e-12, "boxcar");
	CHECK_NEAR(sm[0], 0, 1e-12, "boxcar end");
	kg_boxcar(in, sm, 5, 0);
	CHECK_NEAR(sm[2], 3, 1e-12, "boxcar 0");

	/* R = (S - D) / (W - D) x R_white. */
	kg_spectro_reading d, w, s;
	int n = 700;
	reading_of(&d, n, NULL, 0);
	reading_of(&w, n, one, 30000);
	reading_of(&s, n, ramp, 30000);
	kg_spectrum white = kg_spectrum_const(0.5), r;
	kg_err err = {{0}};
	int dropped = -1;
	CHECK(kg_reflectance(&d, &w, &white, &s, &r, &dropped, &err) == 0, "%s", err.msg);
	for (int i = 0; i < KG_NBANDS; i++)
		CHECK_NEAR(r.v[i], 0.5 * ramp(kg_band_nm(i)), 1e-9, "reflectance");
	CHECK(dropped == 0, "dropped %d", dropped);
	/* No white signal at some pixels: dropped and interpolated across. */
	for (int p = 300; p < 310; p++)
		w.counts[p] = d.counts[p];
	CHECK(kg_reflectance(&d, &w, &white, &s, &r, &dropped, &err) == 0, "%s", err.msg);
	CHECK(dropped == 10, "dropped %d", dropped);
	CHECK_NEAR(r.v[(530 - 400) / 5], 0.5 * ramp(530), 1e-3, "across the gap");
	/* Different integration times are refused. */
	s.integration_us = 2000;
	CHECK(kg_reflectance(&d, &w, &white, &s, &r, NULL, &err) == KG_EINVAL, "integration");
	/* Drift: a white 3 % brighter. */
	kg_spectro_reading w2;
	kg_spectro_reading_clear(&w);
	reading_of(&w, n, one, 30000);
	reading_of(&w2, n, one, 30900);
	s.integration_us = 1000;
	CHECK_NEAR(kg_white_drift(&d, &w, &w2), 0.03, 2e-3, "drift");
	kg_spectro_reading_clear(&d);
	kg_spectro_reading_clear(&w);
	kg_spectro_reading_clear(&w2);
	kg_spectro_reading_clear(&s);

	CHECK(kg_white_reference_load(NULL, &white, &err) == 0, "flat white");
	CHECK_NEAR(white.v[30], 0.99, 1e-12, "flat white");
}

static void test_sim(const char *spectra)
{
	char uri[4200];
	snprintf(uri, sizeof(uri), "sim:%s", spectra);
	kg_spectro *s = NULL;
	kg_err err = {{0}};
	int r = kg_spectro_open(uri, &s, &err);
	CHECK(r == 0, "%s", err.msg);
	if (r)
		return;
	const kg_spectro_info *info = kg_spectro_get_info(s);
	CHECK(info->npixels == 2048 && info->dark_first == 6, "sim geometry");
	double raw[2048];
	CHECK(kg_spectro_read_raw(s, raw, &err) == KG_EINVAL, "read before integration");
	CHECK(kg_spectro_set_integration(s, 10, &err) == KG_EINVAL, "integration range");
	CHECK(kg_spectro_set_integration(s, 100000, &err) == 0, "%s", err.msg);
	kg_acquire_options o;
	kg_acquire_options_default(&o);
	o.scans = 4;
	o.boxcar = 2;
	kg_spectro_reading d = {0}, w = {0}, x = {0};
	kg_patchset *ps = NULL;
	CHECK(kg_patchset_read(spectra, 0, &ps, &err) == 0, "%s", err.msg);
	CHECK(kg_spectro_set_target(s, "dark", &err) == 0 && kg_spectro_acquire(s, &o, &d, &err) == 0,
	      "%s", err.msg);
	CHECK(kg_spectro_set_target(s, "white", &err) == 0 && kg_spectro_acquire(s, &o, &w, &err) == 0,
	      "%s", err.msg);
	CHECK(w.saturated == 0, "white saturated %d", w.saturated);
	kg_spectrum white = kg_spectrum_const(0.99), refl;
	for (int i = 0; ps && i < ps->n; i++) {
		CHECK(kg_spectro_set_target(s, ps->ids[i], &err) == 0, "%s", err.msg);
		CHECK(kg_spectro_acquire(s, &o, &x, &err) == 0, "%s", err.msg);
		CHECK(kg_reflectance(&d, &w, &white, &x, &refl, NULL, &err) == 0, "%s", err.msg);
		CHECK(kg_spectrum_rmse(&refl, &ps->spectra[i]) < 0.01, "%s: rmse %g", ps->ids[i],
		      kg_spectrum_rmse(&refl, &ps->spectra[i]));
		kg_spectro_reading_clear(&x);
	}
	CHECK(kg_spectro_set_target(s, "NOPE", &err) == KG_EINVAL, "unknown sample");
	/* Saturation: a long integration saturates the white. */
	CHECK(kg_spectro_set_integration(s, 2000000, &err) == 0, "%s", err.msg);
	CHECK(kg_spectro_set_target(s, "white", &err) == 0 && kg_spectro_acquire(s, &o, &x, &err) == 0,
	      "%s", err.msg);
	CHECK(x.saturated > 100, "saturated %d", x.saturated);
	kg_spectro_reading_clear(&x);
	/* ... and a measurement refuses it, naming where it saturated. */
	kg_measure_session m = {.spectro = s, .acq = o};
	CHECK(kg_measure_reading(&m, "white", "white reference", &x, &err) == KG_ERANGE &&
	          strstr(err.msg, "white reference: ") && strstr(err.msg, " nm (peak 65535") &&
	          strstr(err.msg, "shorten the integration time"),
	      "saturated white accepted: %s", err.msg);
	CHECK(x.counts == NULL, "a refused reading is cleared");
	kg_spectro_reading_clear(&d);
	kg_spectro_reading_clear(&w);
	kg_patchset_free(&ps);
	kg_spectro_free(&s);
	CHECK(s == NULL, "freed");
	CHECK(kg_spectro_open("bogus", &s, &err) == KG_EINVAL, "bad uri");
	CHECK(kg_spectro_open("replay:/nonexistent/x", &s, &err) == KG_ENOENT && !s,
	      "replay of a missing recording: %s", err.msg);
}

int main(int argc, char **argv)
{
	test_math();
	test_sim(argc > 1 ? argv[1] : KG_SOURCE_ROOT "/fixtures/usbspec/chart_spectra.cgats");
	return kg_test_done("test_spectro");
}
