/* Flare (veiling glare): light scattered in the lens and camera adds a near-constant
 * offset to every pixel of a frame, so a chart's neutral patches, plotted against their
 * measured luminance factor, meet zero above the origin. The offset per channel is the
 * intercept of the straight line through the neutrals (camera value against Y under
 * D65 of their spectra); as a fraction of white it is intercept / slope (the value the
 * line gives the perfect diffuser). kg_reference_fit removes it when that validates
 * better (leave-one-out) and refuses a frame whose flare is too large to trust. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "calib_private.h"

/* A neutral: chroma C*ab under D65 below this (the ColorChecker's neutral row reads
 * 0.3-2.5 from its published spectra; its least chromatic colour patch, 14 or more). */
#define NEUTRAL_MAX_CHROMA 5.0

/* Left out: listed, or flagged by chart detection in either set. */
static int left_out(const kg_patchset *ps, int i, const char *const *exclude, int nexclude)
{
	for (int e = 0; e < nexclude; e++)
		if (!strcmp(exclude[e], ps->ids[i]))
			return 1;
	int col = kg_patchset_extra_index(ps, "FLAGS");
	double f = col >= 0 ? ps->extra[(size_t)i * ps->nextra + col] : 0;
	return f != 0;
}

int kg_flare_estimate(const kg_patchset *train, const kg_patchset *field,
                      const char *const *exclude, int nexclude, kg_flare *out, kg_err *err)
{
	memset(out, 0, sizeof(*out));
	if (!train || !train->spectra || !train->rgb)
		return 0;
	const kg_patchset *cam = field ? field : train;
	if (!cam->rgb)
		return 0;
	calib_d65 d65;
	int ret = calib_d65_init(&d65, err);
	if (ret)
		return ret;
	double Y[KG_FLARE_MAX_NEUTRALS], v[KG_FLARE_MAX_NEUTRALS][3];
	int n = 0;
	for (int i = 0; i < train->n && n < KG_FLARE_MAX_NEUTRALS; i++) {
		kg_xyz c = kg_xyz_from_weights(&d65.w, &train->spectra[i]);
		kg_lab l = kg_xyz_to_lab(c, d65.white);
		if (!(hypot(l.a, l.b) < NEUTRAL_MAX_CHROMA) || !(c.Y > 0))
			continue;
		int j = cam == train ? i : kg_patchset_find(cam, train->ids[i]);
		if (j < 0 || !isfinite(cam->rgb[j][0] + cam->rgb[j][1] + cam->rgb[j][2]) ||
		    left_out(train, i, exclude, nexclude) || left_out(cam, j, exclude, nexclude))
			continue;
		Y[n] = c.Y / 100;
		memcpy(v[n], cam->rgb[j], sizeof(v[n]));
		snprintf(out->ids[n], sizeof(out->ids[n]), "%s", train->ids[i]);
		n++;
	}
	out->n = n;
	double lo = INFINITY, hi = 0;
	for (int i = 0; i < n; i++) {
		lo = fmin(lo, Y[i]);
		hi = fmax(hi, Y[i]);
	}
	/* a line needs at least three neutrals from dark to light (the ColorChecker's
	 * black reads Y 0.03, its white 0.9) */
	if (n < 3 || !(hi > 4 * lo) || !(hi > 0.3))
		return 0;
	double my = 0;
	for (int i = 0; i < n; i++)
		my += Y[i];
	my /= n;
	double sxx = 0;
	for (int i = 0; i < n; i++)
		sxx += (Y[i] - my) * (Y[i] - my);
	out->found = 1;
	for (int ch = 0; ch < 3; ch++) {
		double mv = 0, sxy = 0, rss = 0;
		for (int i = 0; i < n; i++)
			mv += v[i][ch];
		mv /= n;
		for (int i = 0; i < n; i++)
			sxy += (Y[i] - my) * (v[i][ch] - mv);
		double slope = sxy / sxx, icpt = mv - slope * my;
		for (int i = 0; i < n; i++) {
			double r = v[i][ch] - (icpt + slope * Y[i]);
			rss += r * r;
		}
		out->slope[ch] = slope;
		out->offset[ch] = icpt;
		out->white_fraction[ch] = slope > 0 ? icpt / slope : NAN;
		/* the line's own scatter, as a fraction of white: how well a straight line
		 * through the origin shifted by the offset describes the neutrals */
		out->residual[ch] = slope > 0 && n > 2 ? sqrt(rss / (n - 2)) / slope : NAN;
		if (!(slope > 0))
			out->found = 0;
	}
	return 0;
}

double kg_flare_max_fraction(const kg_flare *f)
{
	double m = 0;
	for (int ch = 0; f->found && ch < 3; ch++)
		if (f->white_fraction[ch] > m)
			m = f->white_fraction[ch];
	return m;
}

int kg_flare_remove(const kg_patchset *ps, const kg_flare *f, kg_patchset **out, kg_err *err)
{
	int ret = calib_patchset_without(ps, NULL, 0, out, err);
	for (int i = 0; !ret && ps->rgb && i < ps->n; i++)
		for (int ch = 0; ch < 3; ch++) {
			double x = ps->rgb[i][ch] - f->offset[ch];
			(*out)->rgb[i][ch] = x > 0 ? x : 0;
		}
	return ret;
}
