/* Readings (averaged, corrected, smoothed spectra on the device's pixel grid) and
 * reflectance against dark and white references. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "kg_devices.h"

void kg_acquire_options_default(kg_acquire_options *o)
{
	o->scans = 1;
	o->boxcar = 0;
	o->corrections = KG_CORRECT_ELECTRICAL_DARK | KG_CORRECT_NONLINEARITY;
}

void kg_spectro_reading_clear(kg_spectro_reading *r)
{
	if (!r)
		return;
	free(r->wl);
	free(r->counts);
	memset(r, 0, sizeof(*r));
}

void kg_boxcar(const double *in, double *out, int n, int half)
{
	for (int p = 0; p < n; p++) {
		int a = p - half < 0 ? 0 : p - half, b = p + half >= n ? n - 1 : p + half;
		double sum = 0;
		for (int q = a; q <= b; q++)
			sum += in[q];
		out[p] = sum / (b - a + 1);
	}
}

static int in_grid(double wl) { return wl >= KG_LAMBDA_MIN && wl <= KG_LAMBDA_MAX; }

int kg_spectro_acquire(kg_spectro *s, const kg_acquire_options *o, kg_spectro_reading *out,
                       kg_err *err)
{
	kg_check_arg(s && o && out && o->scans >= 1 && o->boxcar >= 0, err);
	const kg_spectro_info *info = kg_spectro_get_info(s);
	int n = info->npixels;
	memset(out, 0, sizeof(*out));
	double *raw = malloc(sizeof(double) * n), *sum = calloc(n, sizeof(double));
	unsigned char *sat = calloc(n, 1);
	out->wl = malloc(sizeof(double) * n);
	out->counts = malloc(sizeof(double) * n);
	int r = 0;
	if (!raw || !sum || !sat || !out->wl || !out->counts)
		r = KG_ENOMEM;
	for (int k = 0; !r && k < o->scans; k++) {
		if ((r = kg_spectro_read_raw(s, raw, err)) != 0)
			break;
		for (int p = 0; p < n; p++) {
			if (in_grid(kg_spectro_wavelength(info, p))) {
				if (raw[p] >= info->saturation)
					sat[p] = 1;
				if (raw[p] > out->peak)
					out->peak = raw[p];
			}
		}
		if ((r = kg_spectro_correct(info, o->corrections, raw, raw, err)) != 0)
			break;
		for (int p = 0; p < n; p++)
			sum[p] += raw[p];
	}
	if (!r) {
		out->n = n;
		out->scans = o->scans;
		out->integration_us = info->integration_us;
		for (int p = 0; p < n; p++) {
			out->wl[p] = kg_spectro_wavelength(info, p);
			sum[p] /= o->scans;
			if (sat[p]) {
				if (!out->saturated++)
					out->saturated_nm[0] = out->saturated_nm[1] = out->wl[p];
				out->saturated_nm[0] = fmin(out->saturated_nm[0], out->wl[p]);
				out->saturated_nm[1] = fmax(out->saturated_nm[1], out->wl[p]);
			}
		}
		if (o->boxcar > 0)
			kg_boxcar(sum, out->counts, n, o->boxcar);
		else
			memcpy(out->counts, sum, sizeof(double) * n);
		struct timespec ts;
		clock_gettime(CLOCK_REALTIME, &ts);
		out->when = ts.tv_sec + ts.tv_nsec * 1e-9;
	} else {
		kg_spectro_reading_clear(out);
	}
	free(raw);
	free(sum);
	free(sat);
	return r;
}

int kg_white_reference_load(const char *path, kg_spectrum *out, kg_err *err)
{
	kg_check_arg(out, err);
	if (!path) {
		*out = kg_spectrum_const(0.99);
		return 0;
	}
	kg_patchset *ps = NULL;
	int r = kg_patchset_read(path, 0, &ps, err);
	if (!r && (!ps->spectra || ps->n < 1))
		r = kg_fail(err, KG_EINVAL,
		            "%s: white reference: expected a spectrum (SPEC_<nm> fields)", path);
	if (!r)
		*out = ps->spectra[0];
	for (int i = 0; !r && i < KG_NBANDS; i++)
		if (!(out->v[i] > 0 && out->v[i] <= 1.5))
			r = kg_fail(err, KG_EINVAL,
			            "%s: white reference at %g nm is %g: expected a reflectance in "
			            "(0, 1.5]", path, kg_band_nm(i), out->v[i]);
	kg_patchset_free(&ps);
	return r;
}

int kg_reflectance(const kg_spectro_reading *dark, const kg_spectro_reading *white,
                   const kg_spectrum *white_reflectance, const kg_spectro_reading *sample,
                   kg_spectrum *out, int *dropped, kg_err *err)
{
	kg_check_arg(dark && white && white_reflectance && sample && out, err);
	int n = sample->n;
	if (dark->n != n || white->n != n || n < 2)
		return kg_fail(err, KG_EINVAL,
		               "reflectance: dark (%d), white (%d) and sample (%d) readings have "
		               "different pixel counts", dark->n, white->n, n);
	if (dark->integration_us != sample->integration_us ||
	    white->integration_us != sample->integration_us)
		return kg_fail(err, KG_EINVAL,
		               "reflectance: integration times differ (dark %u, white %u, sample "
		               "%u us): measure the references again at the sample's setting",
		               dark->integration_us, white->integration_us, sample->integration_us);
	double grid[KG_NBANDS];
	for (int i = 0; i < KG_NBANDS; i++)
		grid[i] = kg_band_nm(i);
	double *wl = malloc(sizeof(double) * n), *val = malloc(sizeof(double) * n);
	if (!wl || !val) {
		free(wl);
		free(val);
		return KG_ENOMEM;
	}
	int m = 0, lost = 0;
	for (int p = 0; p < n; p++) {
		if (p > 0 && !(sample->wl[p] > sample->wl[p - 1])) {
			free(wl);
			free(val);
			return kg_fail(err, KG_EINVAL,
			               "reflectance: wavelength calibration is not increasing at "
			               "pixel %d (%g nm after %g nm)", p, sample->wl[p], sample->wl[p - 1]);
		}
		double w = white->counts[p] - dark->counts[p];
		if (!(w > 1.0)) {
			lost += in_grid(sample->wl[p]);
			continue;
		}
		double rw = kg_samples_interp(grid, white_reflectance->v, KG_NBANDS, sample->wl[p]);
		wl[m] = sample->wl[p];
		val[m] = (sample->counts[p] - dark->counts[p]) / w * rw;
		m++;
	}
	int r = m < 2 ? kg_fail(err, KG_EINVAL,
	                        "reflectance: the white reference has no signal above the dark "
	                        "(is the lamp on and the probe on the white?)")
	              : kg_spectrum_resample(wl, val, m, 0, "measured reflectance", out, err);
	free(wl);
	free(val);
	if (dropped)
		*dropped = lost;
	return r;
}

double kg_white_drift(const kg_spectro_reading *dark, const kg_spectro_reading *earlier,
                      const kg_spectro_reading *later)
{
	double a = 0, b = 0;
	for (int p = 0; p < earlier->n && p < later->n && p < dark->n; p++) {
		if (!in_grid(earlier->wl[p]))
			continue;
		a += earlier->counts[p] - dark->counts[p];
		b += later->counts[p] - dark->counts[p];
	}
	return a > 0 ? (b - a) / a : 0;
}
