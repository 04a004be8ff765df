/* Spectrometer registry and the application API over the driver table. */
#include <stdlib.h>
#include <string.h>

#include "kg_config.h"
#include "device_uri.h"
#include "spectro_driver.h"

/* Drivers built into this binary, by URI scheme. */
static const kg_spectro_driver *const drivers[] = {
#if HAVE_LIBUSB
	&kg_spectro_ocean_fpga_driver,
#endif
	&kg_spectro_sim_driver,
	&kg_spectro_replay_driver,
};
#define NDRIVERS ((int)(sizeof(drivers) / sizeof(drivers[0])))

/* Schemes the design names whose backend may be missing from this build. */
static const char *const known_schemes[] = {"usbspec", "sim", "replay", NULL};

struct kg_spectro {
	const kg_spectro_driver *drv;
	void *state;
	kg_spectro_info info;
	kg_spectro_recorder *rec; /* kg_spectro_record_start, NULL when not recording */
};

int kg_spectro_backend_count(void) { return NDRIVERS; }
const char *kg_spectro_backend_scheme(int i)
{
	return i >= 0 && i < NDRIVERS ? drivers[i]->scheme : NULL;
}
const char *kg_spectro_backend_description(int i)
{
	return i >= 0 && i < NDRIVERS ? drivers[i]->description : NULL;
}

int kg_spectro_open(const char *uri, kg_spectro **out, kg_err *err)
{
	kg_check_arg(uri && out, err);
	*out = NULL;
	const char *colon = strchr(uri, ':');
	if (!colon || colon == uri)
		return kg_fail(err, KG_EINVAL,
		               "spectrometer '%s': expected a URI usbspec:<vid>:<pid>[:<serial>], "
		               "sim:<spectra file> or replay:<recording>", uri);
	size_t slen = (size_t)(colon - uri);
	const kg_spectro_driver *drv = NULL;
	for (int i = 0; i < NDRIVERS; i++)
		if (kg_uri_scheme_is(uri, slen, drivers[i]->scheme))
			drv = drivers[i];
	if (!drv)
		return kg_uri_scheme_unknown("spectrometer", uri, slen, known_schemes,
		                             "expected usbspec, sim or replay", err);
	kg_spectro *s = calloc(1, sizeof(*s));
	if (!s)
		return KG_ENOMEM;
	s->drv = drv;
	snprintf(s->info.backend, sizeof(s->info.backend), "%s", drv->scheme);
	s->info.dark_first = s->info.dark_last = -1;
	s->info.nl_order = -1;
	int r = drv->open(colon + 1, &s->state, err);
	if (r) {
		free(s);
		return r;
	}
	if (!(r = drv->identify(s->state, &s->info, err)) &&
	    !(r = drv->wavelength_calibration(s->state, s->info.wl_coeffs, err))) {
		drv->dark_pixels(s->state, &s->info.dark_first, &s->info.dark_last);
		r = drv->nonlinearity(s->state, s->info.nl_coeffs, &s->info.nl_order, err);
	}
	if (!r && (s->info.npixels < 2 || s->info.dark_last >= s->info.npixels))
		r = kg_fail(err, KG_EIO, "%s: driver reported %d pixels, dark pixels %d-%d",
		            uri, s->info.npixels, s->info.dark_first, s->info.dark_last);
	if (r) {
		kg_spectro_free(&s);
		return r;
	}
	*out = s;
	return 0;
}

void kg_spectro_free(kg_spectro **s)
{
	if (!s || !*s)
		return;
	kg_recorder_close(&(*s)->rec, NULL, NULL);
	if ((*s)->state)
		(*s)->drv->close((*s)->state);
	free(*s);
	*s = NULL;
}

const kg_spectro_info *kg_spectro_get_info(const kg_spectro *s) { return &s->info; }

int kg_spectro_set_integration(kg_spectro *s, uint32_t us, kg_err *err)
{
	kg_check_arg(s, err);
	if (us < s->info.min_integration_us || us > s->info.max_integration_us)
		return kg_fail(err, KG_EINVAL,
		               "%s %s: integration time %u us: expected %u to %u us", s->info.model,
		               s->info.serial, us, s->info.min_integration_us,
		               s->info.max_integration_us);
	int r = s->drv->set_integration(s->state, us, err);
	if (!r)
		s->info.integration_us = us;
	return r;
}

int kg_spectro_read_raw(kg_spectro *s, double *counts, kg_err *err)
{
	kg_check_arg(s && counts, err);
	if (!s->info.integration_us)
		return kg_fail(err, KG_EINVAL, "%s %s: set the integration time before reading",
		               s->info.model, s->info.serial);
	int r = s->drv->read_raw(s->state, counts, err);
	if (!r && s->rec)
		kg_recorder_read(s->rec, s->info.integration_us, counts);
	return r;
}

int kg_spectro_set_target(kg_spectro *s, const char *what, kg_err *err)
{
	kg_check_arg(s && what, err);
	int r = s->drv->set_target ? s->drv->set_target(s->state, what, err) : 0;
	if (!r && s->rec)
		kg_recorder_target(s->rec, what);
	return r;
}

int kg_spectro_record_start(kg_spectro *s, const char *path, kg_err *err)
{
	kg_check_arg(s && path && !s->rec, err);
	return kg_recorder_open(path, &s->info, &s->rec, err);
}

int kg_spectro_record_finish(kg_spectro *s, int *nreads, kg_err *err)
{
	kg_check_arg(s, err);
	return kg_recorder_close(&s->rec, nreads, err);
}

double kg_spectro_wavelength(const kg_spectro_info *info, int pixel)
{
	const double *c = info->wl_coeffs;
	double p = pixel;
	return c[0] + p * (c[1] + p * (c[2] + p * c[3]));
}

int kg_spectro_correct(const kg_spectro_info *info, unsigned flags, const double *raw,
                       double *out, kg_err *err)
{
	int n = info->npixels;
	double dark = 0;
	if ((flags & KG_CORRECT_ELECTRICAL_DARK) && info->dark_first >= 0 &&
	    info->dark_last >= info->dark_first) {
		for (int p = info->dark_first; p <= info->dark_last; p++)
			dark += raw[p];
		dark /= info->dark_last - info->dark_first + 1;
	}
	int nl = (flags & KG_CORRECT_NONLINEARITY) ? info->nl_order : -1;
	for (int p = 0; p < n; p++) {
		double c = raw[p] - dark;
		if (nl >= 0) {
			double f = info->nl_coeffs[nl]; /* Horner on k0..kn */
			for (int k = nl - 1; k >= 0; k--)
				f = f * c + info->nl_coeffs[k];
			if (!(f > 0))
				return kg_fail(err, KG_ERANGE,
				               "%s %s: nonlinearity correction factor %g at pixel %d (%.1f nm, "
				               "%.0f counts above the dark): expected > 0; the device's "
				               "nonlinearity coefficients do not cover this count (check its "
				               "calibration, or measure with --no-nonlinearity)",
				               info->model, info->serial, f, p, kg_spectro_wavelength(info, p),
				               c);
			c /= f;
		}
		out[p] = c;
	}
	return 0;
}
