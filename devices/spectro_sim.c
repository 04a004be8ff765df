/* sim: a simulated spectrometer measuring known spectra.
 *
 * URI sim:<spectra.cgats>. The instrument has the USB2000+ geometry (2048 pixels,
 * electrical-dark pixels 6-21, 16-bit counts) and a fixed wavelength calibration
 * covering 339-1054 nm. A pixel's count is physical:
 *   offset + dark current x t + lamp(lambda) x R(lambda) x t + noise,
 * clipped to 0..65535, where t is the integration time, R the reflectance of what
 * is under the probe (kg_spectro_set_target: "dark" = covered, "white" = the
 * sample named WHITE in the file or else a flat 0.99 standard, any other name a
 * SAMPLE_ID of the file or a 1-based row number; anything else is an error) and the noise is shot noise plus
 * read noise from a fixed seed, so runs repeat exactly. */
#include <ctype.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "spectro_driver.h"

enum { SIM_PIXELS = 2048, SIM_DARK_FIRST = 6, SIM_DARK_LAST = 21 };
static const double sim_wl[4] = {339.0, 0.38, -1.5e-5, 0.0};
#define SIM_OFFSET 1000.0        /* electrical offset, counts */
#define SIM_DARK_PER_MS 0.5      /* thermal dark counts per ms (fixed pattern +-20 %) */
#define SIM_WHITE_PEAK 400000.0  /* counts per second at the lamp's peak for R = 1 */
#define SIM_READ_NOISE 3.0       /* counts rms */
#define SIM_GAIN 20.0            /* counts per noise-equivalent electron group */

typedef struct sim_state {
	kg_patchset *spectra;
	char *path;
	uint32_t integration_us;
	kg_spectrum target; /* reflectance under the probe */
	int covered;        /* probe covered: no light */
	uint64_t rng;
	double pattern[SIM_PIXELS]; /* dark-current fixed pattern */
} sim_state;

static double sim_uniform(sim_state *s)
{
	/* splitmix64 */
	uint64_t z = (s->rng += 0x9E3779B97F4A7C15ull);
	z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
	z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
	z ^= z >> 31;
	return ((z >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

static double sim_gauss(sim_state *s)
{
	double u = sim_uniform(s), v = sim_uniform(s);
	return sqrt(-2 * log(u)) * cos(2 * M_PI * v);
}

/* Lamp (tungsten-like) times detector response, relative, peak 1 near 600 nm. */
static double sim_lamp(double wl)
{
	double x = (wl - 600.0) / 180.0;
	return exp(-x * x);
}

static int sim_open(const char *target, void **state, kg_err *err)
{
	if (!*target)
		return kg_fail(err, KG_EINVAL, "sim: expected sim:<spectra file>");
	sim_state *s = calloc(1, sizeof(*s));
	if (!s)
		return KG_ENOMEM;
	int r = kg_patchset_read(target, 0, &s->spectra, err);
	if (!r && !s->spectra->spectra)
		r = kg_fail(err, KG_EINVAL, "%s: sim spectrometer: expected SPEC_<nm> fields",
		            target);
	if (!r && !(s->path = strdup(target)))
		r = KG_ENOMEM;
	if (r) {
		kg_patchset_free(&s->spectra);
		free(s);
		return r;
	}
	s->rng = 1;
	for (int p = 0; p < SIM_PIXELS; p++)
		s->pattern[p] = 1.0 + 0.2 * (2 * sim_uniform(s) - 1);
	s->covered = 1;
	*state = s;
	return 0;
}

static int sim_identify(void *state, kg_spectro_info *info, kg_err *err)
{
	sim_state *s = state;
	snprintf(info->model, sizeof(info->model), "simulated USB2000+");
	/* A serial that names the spectra it measures, as a real serial names the unit. */
	const char *base = strrchr(s->path, '/');
	snprintf(info->serial, sizeof(info->serial), "SIM-%.27s", base ? base + 1 : s->path);
	info->npixels = SIM_PIXELS;
	info->saturation = 65535;
	info->min_integration_us = 1000;
	info->max_integration_us = 655350000;
	info->high_speed = 1;
	return 0;
}

static int sim_wavelengths(void *state, double coeffs[4], kg_err *err)
{
	memcpy(coeffs, sim_wl, sizeof(sim_wl));
	return 0;
}

static void sim_dark_pixels(void *state, int *first, int *last)
{
	*first = SIM_DARK_FIRST;
	*last = SIM_DARK_LAST;
}

static int sim_nonlinearity(void *state, double coeffs[KG_SPECTRO_MAX_NL], int *order,
                            kg_err *err)
{
	*order = -1; /* the simulated detector is linear */
	return 0;
}

static int sim_set_integration(void *state, uint32_t us, kg_err *err)
{
	((sim_state *)state)->integration_us = us;
	return 0;
}

static int sim_set_target(void *state, const char *what, kg_err *err)
{
	sim_state *s = state;
	s->covered = !what || !strcasecmp(what, "dark");
	if (s->covered)
		return 0;
	kg_patchset *ps = s->spectra;
	int i = -1;
	if (!strcasecmp(what, "white")) {
		for (int k = 0; k < ps->n && i < 0; k++)
			if (!strcasecmp(ps->ids[k], "white"))
				i = k;
		s->target = i >= 0 ? ps->spectra[i] : kg_spectrum_const(0.99);
		return 0;
	}
	i = kg_patchset_find(ps, what);
	if (i < 0) {
		char *end;
		long row = strtol(what, &end, 10);
		if (*what && !*end && row >= 1 && row <= ps->n)
			i = (int)row - 1;
	}
	if (i < 0)
		return kg_fail(err, KG_EINVAL,
		               "%s: sim spectrometer: no sample '%s' (expected a SAMPLE_ID of the "
		               "file or a row number 1-%d)", s->path, what, ps->n);
	s->target = ps->spectra[i];
	return 0;
}

static int sim_read_raw(void *state, double *counts, kg_err *err)
{
	sim_state *s = state;
	double t = s->integration_us * 1e-6;
	double grid[KG_NBANDS];
	for (int i = 0; i < KG_NBANDS; i++)
		grid[i] = kg_band_nm(i);
	for (int p = 0; p < SIM_PIXELS; p++) {
		double signal = 0;
		if (p > SIM_DARK_LAST) {
			signal = SIM_DARK_PER_MS * s->pattern[p] * t * 1e3;
			if (!s->covered) {
				double wl = kg_spectro_wavelength(&(kg_spectro_info){
				                .wl_coeffs = {sim_wl[0], sim_wl[1], sim_wl[2], sim_wl[3]}},
				            p);
				double refl = kg_samples_interp(grid, s->target.v, KG_NBANDS, wl);
				signal += SIM_WHITE_PEAK * sim_lamp(wl) * refl * t;
			}
		}
		double c = SIM_OFFSET + signal +
		           sqrt(signal / SIM_GAIN + SIM_READ_NOISE * SIM_READ_NOISE) * sim_gauss(s);
		c = floor(c + 0.5);
		counts[p] = c < 0 ? 0 : c > 65535 ? 65535 : c;
	}
	return 0;
}

static void sim_close(void *state)
{
	sim_state *s = state;
	kg_patchset_free(&s->spectra);
	free(s->path);
	free(s);
}

const kg_spectro_driver kg_spectro_sim_driver = {
	.scheme = "sim",
	.description = "simulated spectrometer measuring the spectra of a CGATS file",
	.open = sim_open,
	.identify = sim_identify,
	.wavelength_calibration = sim_wavelengths,
	.dark_pixels = sim_dark_pixels,
	.nonlinearity = sim_nonlinearity,
	.set_integration = sim_set_integration,
	.read_raw = sim_read_raw,
	.set_target = sim_set_target,
	.close = sim_close,
};
