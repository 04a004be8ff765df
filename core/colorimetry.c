#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#include "cgats.h"
#include "colorimetry.h"

/* Row of the 1 nm CMF table at the grid's band i. */
#define GRID_CMF_ROW(i) ((int)(KG_LAMBDA_MIN - KG_CMF_FIRST_NM) + 5 * (i))

/* Samples at most this far apart (nm, on average) are interpolated linearly, coarser
 * ones by a cubic: "5 nm or finer", with slack for rounded wavelengths (ArgyllCMS
 * uses the same threshold). */
#define LINEAR_MAX_SPACING 5.01

/* --- sampled data --- */

/* Index i with wl[i] <= at < wl[i+1], limited to 0..n-2. */
static int interval(const double *wl, int n, double at)
{
	int lo = 0, hi = n - 1;
	while (hi - lo > 1) {
		int mid = (lo + hi) / 2;
		if (wl[mid] <= at)
			lo = mid;
		else
			hi = mid;
	}
	return lo;
}

/* The value of samples at `at`: end values held outside their range, linear inside
 * for data 5 nm apart or finer, four-point Lagrange for coarser data (the interval's
 * neighbours on both sides, shifted inwards at the ends). */
static double sample_at(const double *wl, const double *v, int n, double at)
{
	if (at <= wl[0])
		return v[0];
	if (at >= wl[n - 1])
		return v[n - 1];
	int i = interval(wl, n, at);
	double spacing = (wl[n - 1] - wl[0]) / (n - 1);
	if (spacing < LINEAR_MAX_SPACING || n < 4) {
		double t = (at - wl[i]) / (wl[i + 1] - wl[i]);
		return (1.0 - t) * v[i] + t * v[i + 1];
	}
	if (i < 1)
		i = 1;
	else if (i > n - 3)
		i = n - 3;
	double sum = 0.0;
	for (int j = i - 1; j <= i + 2; j++) {
		double w = 1.0;
		for (int k = i - 1; k <= i + 2; k++)
			if (k != j)
				w *= (at - wl[k]) / (wl[j] - wl[k]);
		sum += w * v[j];
	}
	return sum;
}

static int check_samples(const double *wl, const double *v, int n, const char *what,
                         kg_err *err)
{
	if (!wl || !v || n < 2)
		return kg_fail(err, KG_EINVAL, "%s: expected at least 2 samples, got %d", what,
		               n);
	for (int i = 0; i < n; i++) {
		if (!isfinite(wl[i]) || !isfinite(v[i]))
			return kg_fail(err, KG_EINVAL,
			               "%s: sample %d (%g nm): expected finite numbers", what, i,
			               wl[i]);
		if (i > 0 && !(wl[i] > wl[i - 1]))
			return kg_fail(err, KG_EINVAL,
			               "%s: wavelengths must increase strictly (%g nm after %g nm)",
			               what, wl[i], wl[i - 1]);
	}
	return 0;
}

/* --- illuminants --- */

static int illuminant_alloc(const char *name, int n, kg_illuminant **out, kg_err *err)
{
	kg_illuminant *ill = calloc(1, sizeof(*ill));
	if (!ill)
		goto error;
	snprintf(ill->name, sizeof(ill->name), "%s", name ? name : "");
	ill->nsamples = n;
	ill->wl = malloc(sizeof(double) * (size_t)n);
	ill->v = malloc(sizeof(double) * (size_t)n);
	if (!ill->wl || !ill->v)
		goto error;
	*out = ill;
	return 0;
error:
	kg_illuminant_free(&ill);
	return kg_fail(err, KG_ENOMEM, "illuminant %s: out of memory", name ? name : "");
}

/* Grid spectrum of a built-in illuminant whose samples include every band centre. */
static void grid_from_samples(kg_illuminant *ill)
{
	for (int i = 0; i < KG_NBANDS; i++)
		ill->spd.v[i] = sample_at(ill->wl, ill->v, ill->nsamples, kg_band_nm(i));
}

void kg_illuminant_free(kg_illuminant **ill)
{
	if (!ill || !*ill)
		return;
	free((*ill)->wl);
	free((*ill)->v);
	free(*ill);
	*ill = NULL;
}

static int illuminant_5nm_table(const char *name, const double *table,
                                kg_illuminant **out, kg_err *err)
{
	int ret = illuminant_alloc(name, KG_DAYLIGHT_COUNT, out, err);
	if (ret)
		return ret;
	for (int i = 0; i < KG_DAYLIGHT_COUNT; i++) {
		(*out)->wl[i] = KG_DAYLIGHT_FIRST_NM + 5.0 * i;
		(*out)->v[i] = table[i];
	}
	grid_from_samples(*out);
	return 0;
}

/* CIE 15:2004 section 3.1: chromaticity of daylight (eq. 3.2, 3.3) and the factors of
 * S1 and S2 (eq. 3.4), rounded to three decimals. */
static void daylight_factors(double cct, double *m1, double *m2)
{
	double t = cct, t2 = t * t, t3 = t2 * t, xd;
	if (t <= 7000.0)
		xd = -4.6070e9 / t3 + 2.9678e6 / t2 + 0.09911e3 / t + 0.244063;
	else
		xd = -2.0064e9 / t3 + 1.9018e6 / t2 + 0.24748e3 / t + 0.237040;
	double yd = -3.000 * xd * xd + 2.870 * xd - 0.275;
	double m = 0.0241 + 0.2562 * xd - 0.7341 * yd;
	*m1 = round(1000.0 * (-1.3515 - 1.7703 * xd + 5.9114 * yd) / m) / 1000.0;
	*m2 = round(1000.0 * (0.0300 - 31.4424 * xd + 30.0717 * yd) / m) / 1000.0;
}

static int daylight_named(double cct, const char *name, kg_illuminant **out,
                          kg_err *err)
{
	if (!(cct >= 4000.0 && cct <= 25000.0))
		return kg_fail(err, KG_ERANGE,
		               "daylight illuminant %s: correlated colour temperature %g K is "
		               "outside the CIE daylight range 4000-25000 K",
		               name, cct);
	double m1, m2;
	daylight_factors(cct, &m1, &m2);
	double spd[KG_DAYLIGHT_COUNT];
	for (int i = 0; i < KG_DAYLIGHT_COUNT; i++) {
		const double *s = kg_cie_daylight_s[i];
		spd[i] = s[0] + m1 * s[1] + m2 * s[2];
	}
	return illuminant_5nm_table(name, spd, out, err);
}

int kg_illuminant_daylight(double cct, kg_illuminant **out, kg_err *err)
{
	kg_check_arg(out, err);
	*out = NULL;
	char name[64];
	snprintf(name, sizeof(name), "daylight %g K", cct);
	return daylight_named(cct, name, out, err);
}

/* CIE illuminant A: Planck's law with the constants of CIE 15:2004 eq. 3.1. */
static int illuminant_a(kg_illuminant **out, kg_err *err)
{
	const double c2 = 1.435e-2, t = 2848.0; /* m K, K */
	const int first = 300, last = 830;
	int ret = illuminant_alloc("A", last - first + 1, out, err);
	if (ret)
		return ret;
	double at560 = expm1(c2 / (t * 560e-9));
	for (int i = 0; i <= last - first; i++) {
		double nm = first + i;
		(*out)->wl[i] = nm;
		(*out)->v[i] = 100.0 * pow(560.0 / nm, 5.0) * at560 / expm1(c2 / (t * nm * 1e-9));
	}
	grid_from_samples(*out);
	return 0;
}

static int illuminant_e(kg_illuminant **out, kg_err *err)
{
	int ret = illuminant_alloc("E", 2, out, err);
	if (ret)
		return ret;
	(*out)->wl[0] = KG_CMF_FIRST_NM;
	(*out)->wl[1] = KG_CMF_LAST_NM;
	(*out)->v[0] = (*out)->v[1] = 100.0;
	grid_from_samples(*out);
	return 0;
}

/* A whole decimal number (digits only), or -1. */
static long parse_digits(const char *s, size_t len)
{
	if (len == 0 || len > 6)
		return -1;
	long v = 0;
	for (size_t i = 0; i < len; i++) {
		if (!isdigit((unsigned char)s[i]))
			return -1;
		v = 10 * v + (s[i] - '0');
	}
	return v;
}

int kg_illuminant_by_name(const char *name, kg_illuminant **out, kg_err *err)
{
	kg_check_arg(name && out, err);
	*out = NULL;
	size_t len = strlen(name);
	if (strcasecmp(name, "D65") == 0)
		return illuminant_5nm_table("D65", kg_cie_d65, out, err);
	if (strcasecmp(name, "A") == 0)
		return illuminant_a(out, err);
	if (strcasecmp(name, "E") == 0)
		return illuminant_e(out, err);
	if (len >= 2 && (name[0] == 'D' || name[0] == 'd')) {
		long nn = parse_digits(name + 1, len - 1);
		if (nn == 65)
			return illuminant_5nm_table("D65", kg_cie_d65, out, err);
		if (nn >= 40 && nn <= 250) {
			char canon[16];
			snprintf(canon, sizeof(canon), "D%ld", nn);
			return daylight_named(100.0 * nn * 1.4388 / 1.4380, canon, out, err);
		}
		if (nn >= 0)
			return kg_fail(err, KG_ERANGE,
			               "illuminant '%s': D<nn> needs 40 <= nn <= 250 (the CIE "
			               "daylight range 4000-25000 K)",
			               name);
	}
	if (len >= 2 && (name[len - 1] == 'K' || name[len - 1] == 'k')) {
		long t = parse_digits(name, len - 1);
		if (t >= 0) {
			char canon[24];
			snprintf(canon, sizeof(canon), "%ldK", t);
			return daylight_named((double)t, canon, out, err);
		}
	}
	return kg_fail(err, KG_EINVAL,
	               "illuminant '%s': expected D65, A, E, D<nn> (daylight of nn x 100 K, "
	               "e.g. D50) or <T>K (daylight at T kelvin, e.g. 5500K)",
	               name);
}

int kg_illuminant_from_samples(const char *name, const double *wl, const double *v,
                               int n, kg_illuminant **out, kg_err *err)
{
	kg_check_arg(out, err);
	*out = NULL;
	const char *what = name && *name ? name : "illuminant";
	int ret = check_samples(wl, v, n, what, err);
	if (ret)
		return ret;
	kg_illuminant *ill;
	ret = illuminant_alloc(name, n, &ill, err);
	if (ret)
		return ret;
	memcpy(ill->wl, wl, sizeof(double) * (size_t)n);
	memcpy(ill->v, v, sizeof(double) * (size_t)n);
	ret = kg_spectrum_resample(wl, v, n, 0, what, &ill->spd, err);
	if (ret)
		goto error;
	double lum = 0.0;
	for (int i = 0; i < KG_NBANDS; i++)
		lum += ill->spd.v[i] * kg_cie1931_cmf[GRID_CMF_ROW(i)][1];
	if (!(lum > 0.0)) {
		ret = kg_fail(err, KG_EINVAL,
		              "%s: expected a spectral power distribution with positive "
		              "luminance over 400-700 nm",
		              what);
		goto error;
	}
	*out = ill;
	return 0;
error:
	kg_illuminant_free(&ill);
	return ret;
}

int kg_illuminant_from_file(const char *path, kg_illuminant **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	kg_cgats *cg = NULL;
	double *wl = NULL, *v = NULL;
	int n = 0;
	int ret = kg_cgats_read(path, &cg, err);
	if (ret)
		return ret;
	if (cg->ntables < 1) {
		ret = kg_fail(err, KG_EINVAL, "%s: expected a CGATS table with one spectrum",
		              path);
		goto done;
	}
	const kg_cgats_table *t = cg->tables[0];
	ret = kg_cgats_spectra(t, KG_PATCH_KEEP_SCALE, &wl, &v, &n, NULL, err);
	if (ret)
		goto done;
	if (n < 2) {
		ret = kg_fail(err, KG_EINVAL,
		              "%s: expected spectral fields SPEC_<nm> holding an illuminant, "
		              "found %d",
		              path, n);
		goto done;
	}
	if (t->nsets != 1) {
		ret = kg_fail(err, KG_EINVAL,
		              "%s: expected one spectrum (one data set), found %d", path,
		              t->nsets);
		goto done;
	}
	/* The path names the data in messages; the illuminant is named by the file. */
	ret = kg_illuminant_from_samples(path, wl, v, n, out, err);
	if (ret == 0) {
		const char *base = strrchr(path, '/');
		snprintf((*out)->name, sizeof((*out)->name), "%s", base ? base + 1 : path);
	}
done:
	free(wl);
	free(v);
	kg_cgats_free(&cg);
	return ret;
}

int kg_illuminant_lookup(const char *spec, kg_illuminant **out, kg_err *err)
{
	kg_check_arg(spec && out, err);
	if (kg_illuminant_by_name(spec, out, NULL) == 0)
		return 0;
	struct stat st;
	if (stat(spec, &st) == 0 && S_ISREG(st.st_mode))
		return kg_illuminant_from_file(spec, out, err);
	int ret = kg_illuminant_by_name(spec, out, err);
	if (ret == KG_EINVAL && err)
		kg_err_prefix(err, "'%s' is neither a known illuminant nor a file", spec);
	return ret;
}

/* --- spectrum to XYZ on the grid --- */

static void weights_scaled(const kg_spectrum *s, double k, kg_xyz_weights *w)
{
	for (int i = 0; i < KG_NBANDS; i++) {
		const double *cmf = kg_cie1931_cmf[GRID_CMF_ROW(i)];
		double f = k * (s ? s->v[i] : 1.0);
		for (int c = 0; c < 3; c++)
			w->w[c][i] = f * cmf[c];
	}
}

static double grid_luminance_sum(const kg_spectrum *s)
{
	double sum = 0.0;
	for (int i = 0; i < KG_NBANDS; i++)
		sum += s->v[i] * kg_cie1931_cmf[GRID_CMF_ROW(i)][1];
	return sum;
}

void kg_xyz_weights_reflectance(const kg_illuminant *ill, kg_xyz_weights *w)
{
	weights_scaled(&ill->spd, 100.0 / grid_luminance_sum(&ill->spd), w);
}

void kg_xyz_weights_signal(const kg_illuminant *ref, kg_xyz_weights *w)
{
	if (ref)
		weights_scaled(NULL, 100.0 / grid_luminance_sum(&ref->spd), w);
	else
		weights_scaled(NULL, KG_KM * KG_LAMBDA_STEP, w);
}

kg_xyz kg_xyz_from_weights(const kg_xyz_weights *w, const kg_spectrum *s)
{
	double t[3] = {0.0, 0.0, 0.0};
	for (int i = 0; i < KG_NBANDS; i++)
		for (int c = 0; c < 3; c++)
			t[c] += w->w[c][i] * s->v[i];
	return (kg_xyz){t[0], t[1], t[2]};
}

kg_xyz kg_reflectance_to_xyz(const kg_spectrum *r, const kg_illuminant *ill)
{
	kg_xyz_weights w;
	kg_xyz_weights_reflectance(ill, &w);
	return kg_xyz_from_weights(&w, r);
}

kg_xyz kg_signal_to_xyz(const kg_spectrum *c, const kg_illuminant *ref)
{
	kg_xyz_weights w;
	kg_xyz_weights_signal(ref, &w);
	return kg_xyz_from_weights(&w, c);
}

kg_xyz kg_illuminant_white(const kg_illuminant *ill)
{
	kg_spectrum one = kg_spectrum_const(1.0);
	return kg_reflectance_to_xyz(&one, ill);
}

/* --- full-range integration --- */

/* The illuminant's samples, or its grid spectrum when it has none. */
static void illuminant_samples(const kg_illuminant *ill, double *grid_wl,
                               const double **wl, const double **v, int *n)
{
	if (ill->nsamples >= 2) {
		*wl = ill->wl;
		*v = ill->v;
		*n = ill->nsamples;
		return;
	}
	for (int i = 0; i < KG_NBANDS; i++)
		grid_wl[i] = kg_band_nm(i);
	*wl = grid_wl;
	*v = ill->spd.v;
	*n = KG_NBANDS;
}

int kg_samples_to_xyz_range(const double *wl, const double *v, int n,
                            const kg_illuminant *ill, double lo_nm, double hi_nm,
                            kg_xyz *out, kg_err *err)
{
	kg_check_arg(out, err);
	int ret = check_samples(wl, v, n, "spectrum", err);
	if (ret)
		return ret;
	/* The 1 nm rows of the CMF table inside lo..hi (a hair of slack for limits such
	 * as 380.0000001 that stand for a whole nanometre). */
	const double slack = 1e-6;
	int first = (int)ceil(lo_nm - slack) - KG_CMF_FIRST_NM;
	int last = (int)floor(hi_nm + slack) - KG_CMF_FIRST_NM;
	if (first < 0)
		first = 0;
	if (last > KG_CMF_COUNT - 1)
		last = KG_CMF_COUNT - 1;
	if (!(isfinite(lo_nm) && isfinite(hi_nm)) || last <= first)
		return kg_fail(err, KG_ERANGE,
		               "integration range %g-%g nm: expected at least 2 nm inside the "
		               "observer's %d-%d nm",
		               lo_nm, hi_nm, KG_CMF_FIRST_NM, KG_CMF_LAST_NM);
	double grid_wl[KG_NBANDS];
	const double *iwl = NULL, *iv = NULL;
	int in = 0;
	if (ill)
		illuminant_samples(ill, grid_wl, &iwl, &iv, &in);
	double t[3] = {0.0, 0.0, 0.0}, lum = 0.0;
	for (int j = first; j <= last; j++) {
		double nm = KG_CMF_FIRST_NM + j;
		double s = ill ? sample_at(iwl, iv, in, nm) : 1.0;
		double sv = s * sample_at(wl, v, n, nm);
		for (int c = 0; c < 3; c++)
			t[c] += sv * kg_cie1931_cmf[j][c];
		lum += s * kg_cie1931_cmf[j][1];
	}
	double k;
	if (ill) {
		if (!(lum > 0.0))
			return kg_fail(err, KG_EINVAL,
			               "illuminant %s: expected positive luminance over %d-%d nm",
			               ill->name, KG_CMF_FIRST_NM + first, KG_CMF_FIRST_NM + last);
		k = 100.0 / lum;
	} else {
		k = KG_KM * 1.0; /* 1 nm steps */
	}
	*out = (kg_xyz){k * t[0], k * t[1], k * t[2]};
	return 0;
}

int kg_samples_to_xyz(const double *wl, const double *v, int n, const kg_illuminant *ill,
                      kg_xyz *out, kg_err *err)
{
	return kg_samples_to_xyz_range(wl, v, n, ill, KG_CMF_FIRST_NM, KG_CMF_LAST_NM, out,
	                               err);
}

kg_xyz kg_illuminant_white_range(const kg_illuminant *ill, double lo_nm, double hi_nm)
{
	const double wl[2] = {KG_CMF_FIRST_NM, KG_CMF_LAST_NM}, one[2] = {1.0, 1.0};
	kg_xyz w;
	if (!ill || kg_samples_to_xyz_range(wl, one, 2, ill, lo_nm, hi_nm, &w, NULL) != 0)
		return (kg_xyz){NAN, NAN, NAN};
	return w;
}

kg_xyz kg_illuminant_white_full(const kg_illuminant *ill)
{
	double grid_wl[KG_NBANDS];
	const double *wl, *v;
	int n;
	illuminant_samples(ill, grid_wl, &wl, &v, &n);
	kg_xyz w = {0.0, 0.0, 0.0};
	if (kg_samples_to_xyz(wl, v, n, NULL, &w, NULL) != 0 || !(w.Y > 0.0))
		return (kg_xyz){NAN, NAN, NAN};
	double k = 100.0 / w.Y;
	return (kg_xyz){k * w.X, 100.0, k * w.Z};
}

/* --- colour spaces --- */

kg_xyY kg_xyz_to_xyY(kg_xyz c)
{
	double sum = c.X + c.Y + c.Z;
	if (sum == 0.0)
		return (kg_xyY){0.0, 0.0, c.Y};
	return (kg_xyY){c.X / sum, c.Y / sum, c.Y};
}

kg_xyz kg_xyY_to_xyz(kg_xyY c)
{
	if (c.y == 0.0)
		return (kg_xyz){0.0, 0.0, 0.0};
	return (kg_xyz){c.x * c.Y / c.y, c.Y, (1.0 - c.x - c.y) * c.Y / c.y};
}

/* CIE 15:2004 eq. 8.3-8.8, with the break points written exactly: (6/29)^3 is the
 * 0.008856 of the standard and (29/6)^2 / 3 = 841/108 the 7.787. */
static double lab_f(double t)
{
	const double d = 6.0 / 29.0;
	return t > d * d * d ? cbrt(t) : t / (3.0 * d * d) + 4.0 / 29.0;
}

static double lab_finv(double f)
{
	const double d = 6.0 / 29.0;
	return f > d ? f * f * f : 3.0 * d * d * (f - 4.0 / 29.0);
}

kg_lab kg_xyz_to_lab(kg_xyz c, kg_xyz white)
{
	double fx = lab_f(c.X / white.X), fy = lab_f(c.Y / white.Y),
	       fz = lab_f(c.Z / white.Z);
	return (kg_lab){116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}

kg_xyz kg_lab_to_xyz(kg_lab c, kg_xyz white)
{
	double fy = (c.L + 16.0) / 116.0;
	double fx = fy + c.a / 500.0, fz = fy - c.b / 200.0;
	return (kg_xyz){white.X * lab_finv(fx), white.Y * lab_finv(fy),
	                white.Z * lab_finv(fz)};
}

static double to_deg(double radians) { return radians * (180.0 / M_PI); }
static double to_rad(double degrees) { return degrees * (M_PI / 180.0); }

/* Hue angle in degrees, 0..360; 0 for a neutral (Sharma et al., eq. 4). */
static double hue_deg(double b, double a)
{
	if (a == 0.0 && b == 0.0)
		return 0.0;
	double h = to_deg(atan2(b, a));
	return h < 0.0 ? h + 360.0 : h;
}

double kg_ciede2000(kg_lab p, kg_lab q)
{
	const double pow25_7 = 6103515625.0; /* 25^7 */
	double c1 = hypot(p.a, p.b), c2 = hypot(q.a, q.b);
	double cbar = 0.5 * (c1 + c2), cbar7 = pow(cbar, 7.0);
	double g = 0.5 * (1.0 - sqrt(cbar7 / (cbar7 + pow25_7)));
	double a1 = (1.0 + g) * p.a, a2 = (1.0 + g) * q.a;
	double cp1 = hypot(a1, p.b), cp2 = hypot(a2, q.b);
	double h1 = hue_deg(p.b, a1), h2 = hue_deg(q.b, a2);

	double dl = q.L - p.L, dc = cp2 - cp1, dh = 0.0;
	double cprod = cp1 * cp2;
	if (cprod != 0.0) {
		dh = h2 - h1;
		if (dh > 180.0)
			dh -= 360.0;
		else if (dh < -180.0)
			dh += 360.0;
	}
	double dbigh = 2.0 * sqrt(cprod) * sin(to_rad(0.5 * dh));

	double lbar = 0.5 * (p.L + q.L), cpbar = 0.5 * (cp1 + cp2), hbar = h1 + h2;
	if (cprod != 0.0) {
		if (fabs(h1 - h2) <= 180.0)
			hbar = 0.5 * (h1 + h2);
		else if (h1 + h2 < 360.0)
			hbar = 0.5 * (h1 + h2 + 360.0);
		else
			hbar = 0.5 * (h1 + h2 - 360.0);
	}
	double t = 1.0 - 0.17 * cos(to_rad(hbar - 30.0)) + 0.24 * cos(to_rad(2.0 * hbar)) +
	           0.32 * cos(to_rad(3.0 * hbar + 6.0)) - 0.20 * cos(to_rad(4.0 * hbar - 63.0));
	double dtheta = 30.0 * exp(-pow((hbar - 275.0) / 25.0, 2.0));
	double cpbar7 = pow(cpbar, 7.0);
	double rc = 2.0 * sqrt(cpbar7 / (cpbar7 + pow25_7));
	double l50 = (lbar - 50.0) * (lbar - 50.0);
	double sl = 1.0 + 0.015 * l50 / sqrt(20.0 + l50);
	double sc = 1.0 + 0.045 * cpbar;
	double sh = 1.0 + 0.015 * cpbar * t;
	double rt = -sin(to_rad(2.0 * dtheta)) * rc;
	double tl = dl / sl, tc = dc / sc, th = dbigh / sh;
	return sqrt(tl * tl + tc * tc + th * th + rt * tc * th);
}

/* --- adaptation and sRGB --- */

typedef double mat3[3][3];

static kg_xyz mat3_apply(const mat3 m, kg_xyz c)
{
	return (kg_xyz){m[0][0] * c.X + m[0][1] * c.Y + m[0][2] * c.Z,
	                m[1][0] * c.X + m[1][1] * c.Y + m[1][2] * c.Z,
	                m[2][0] * c.X + m[2][1] * c.Y + m[2][2] * c.Z};
}

static void mat3_inverse(const mat3 m, mat3 inv)
{
	double c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
	double c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
	double c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
	double det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
	inv[0][0] = c00 / det;
	inv[1][0] = c01 / det;
	inv[2][0] = c02 / det;
	inv[0][1] = (m[0][2] * m[2][1] - m[0][1] * m[2][2]) / det;
	inv[1][1] = (m[0][0] * m[2][2] - m[0][2] * m[2][0]) / det;
	inv[2][1] = (m[0][1] * m[2][0] - m[0][0] * m[2][1]) / det;
	inv[0][2] = (m[0][1] * m[1][2] - m[0][2] * m[1][1]) / det;
	inv[1][2] = (m[0][2] * m[1][0] - m[0][0] * m[1][2]) / det;
	inv[2][2] = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) / det;
}

/* Bradford cone response matrix (Lam 1985; ICC.1:2010 Annex E). */
static const mat3 bradford = {
	{0.8951, 0.2664, -0.1614},
	{-0.7502, 1.7135, 0.0367},
	{0.0389, -0.0685, 1.0296},
};

/* XYZ (white Y = 1) to linear sRGB, IEC 61966-2-1:1999 eq. 5. */
static const mat3 srgb_from_xyz = {
	{3.2406, -1.5372, -0.4986},
	{-0.9689, 1.8758, 0.0415},
	{0.0557, -0.2040, 1.0570},
};

kg_xyz kg_bradford_adapt(kg_xyz c, kg_xyz src_white, kg_xyz dst_white)
{
	mat3 inv;
	mat3_inverse(bradford, inv);
	kg_xyz cone = mat3_apply(bradford, c);
	kg_xyz s = mat3_apply(bradford, src_white), d = mat3_apply(bradford, dst_white);
	cone = (kg_xyz){cone.X * d.X / s.X, cone.Y * d.Y / s.Y, cone.Z * d.Z / s.Z};
	return mat3_apply(inv, cone);
}

/* The white the sRGB matrix maps to (1, 1, 1), Y = 100: the standard's D65 to the
 * four decimals of its matrix. Using it (not x, y = 0.3127, 0.3290 rounded) keeps the
 * neutral axis exactly neutral. */
static kg_xyz srgb_white(const mat3 xyz_from_srgb)
{
	kg_xyz w = mat3_apply(xyz_from_srgb, (kg_xyz){1.0, 1.0, 1.0});
	return (kg_xyz){100.0 * w.X, 100.0 * w.Y, 100.0 * w.Z};
}

kg_rgb kg_xyz_to_linear_srgb(kg_xyz c, kg_xyz white)
{
	mat3 inv;
	mat3_inverse(srgb_from_xyz, inv);
	kg_xyz a = kg_bradford_adapt(c, white, srgb_white(inv));
	kg_xyz rgb = mat3_apply(srgb_from_xyz, (kg_xyz){a.X / 100.0, a.Y / 100.0, a.Z / 100.0});
	return (kg_rgb){rgb.X, rgb.Y, rgb.Z};
}

kg_xyz kg_linear_srgb_to_xyz(kg_rgb c, kg_xyz white)
{
	mat3 inv;
	mat3_inverse(srgb_from_xyz, inv);
	kg_xyz a = mat3_apply(inv, (kg_xyz){c.r, c.g, c.b});
	a = (kg_xyz){100.0 * a.X, 100.0 * a.Y, 100.0 * a.Z};
	return kg_bradford_adapt(a, srgb_white(inv), white);
}

static double srgb_encode1(double x)
{
	double m = fabs(x);
	double e = m <= 0.0031308 ? 12.92 * m : 1.055 * pow(m, 1.0 / 2.4) - 0.055;
	return copysign(e, x);
}

static double srgb_decode1(double x)
{
	double m = fabs(x);
	double d = m <= 0.04045 ? m / 12.92 : pow((m + 0.055) / 1.055, 2.4);
	return copysign(d, x);
}

kg_rgb kg_srgb_encode(kg_rgb c)
{
	return (kg_rgb){srgb_encode1(c.r), srgb_encode1(c.g), srgb_encode1(c.b)};
}

kg_rgb kg_srgb_decode(kg_rgb c)
{
	return (kg_rgb){srgb_decode1(c.r), srgb_decode1(c.g), srgb_decode1(c.b)};
}

static unsigned char to_u8(double v)
{
	if (!(v > 0.0))
		return 0;
	if (v >= 1.0)
		return 255;
	return (unsigned char)(255.0 * v + 0.5);
}

void kg_rgb_to_u8(kg_rgb c, unsigned char out[3])
{
	out[0] = to_u8(c.r);
	out[1] = to_u8(c.g);
	out[2] = to_u8(c.b);
}
