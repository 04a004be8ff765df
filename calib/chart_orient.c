/* The ColorChecker 24's published colours and the 3 x 3 matrix that maps expected
 * colours onto sampled ones (any camera, white balance and light level): which way up
 * a ColorChecker 24 found without tags lies (its four turns against the chart's
 * colours), and the check of every chart's patches against its layout's colours
 * (chart_colours.c). */
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"

/* The patches of a ColorChecker 24 layout by chart position, row-major from A01
 * (dark skin) to D06 (black 2): 1 when the layout has exactly these 24 ids. */
int chart_colorchecker24_patches(const kg_chart_layout *l, int idx[24])
{
	if (l->npatches != 24)
		return 0;
	for (int i = 0; i < 24; i++) {
		char id[8];
		snprintf(id, sizeof(id), "%c%02d", 'A' + i / 6, i % 6 + 1);
		if ((idx[i] = kg_chart_layout_find_patch(l, id)) < 0)
			return 0;
	}
	return 1;
}

#if KG_HAVE_MCC
/* mcc's box in layout mm (tl, tr, br, bl as the chart is read, A01 top left): the
 * centres of A01, A06 and D01 give one pitch along a row and down a column, and the
 * box lies KG_MCC24_BOX_MARGIN_PITCH pitches beyond the outer patch centres. */
void chart_mcc24_box_mm(const layout_view *L, const int idx[24], double box[4][2])
{
	const double *a1 = L->patch_center[idx[0]], *a6 = L->patch_center[idx[5]],
	             *d1 = L->patch_center[idx[18]];
	double m = KG_MCC24_BOX_MARGIN_PITCH;
	double uv[4][2] = {{-m, -m}, {5 + m, -m}, {5 + m, 3 + m}, {-m, 3 + m}};
	for (int k = 0; k < 4; k++)
		for (int c = 0; c < 2; c++)
			box[k][c] = a1[c] + uv[k][0] * (a6[c] - a1[c]) / 5 + uv[k][1] * (d1[c] - a1[c]) / 3;
}

double chart_quad_signed_area(const double q[4][2])
{
	double a = 0;
	for (int k = 0; k < 4; k++)
		a += q[k][0] * q[(k + 1) % 4][1] - q[(k + 1) % 4][0] * q[k][1];
	return a / 2;
}

void chart_samples_free(kg_chart_sample *p, int n)
{
	for (int i = 0; p && i < n; i++)
		free(p[i].id);
	free(p);
}

#endif

/* The ColorChecker 24's colours as X-Rite publishes them in sRGB (8 bit, D65),
 * row-major from A01 (dark skin) to D06 (black 2). Only their directions in RGB
 * matter to the orientation: the camera's own primaries, white balance and exposure
 * are fitted. */
static const unsigned char cc24_srgb8[24][3] = {
	{115, 82, 68},   {194, 150, 130}, {98, 122, 157},  {87, 108, 67},   {133, 128, 177},
	{103, 189, 170}, {214, 126, 44},  {80, 91, 166},   {193, 90, 99},   {94, 60, 108},
	{157, 188, 64},  {224, 163, 46},  {56, 61, 150},   {70, 148, 73},   {175, 54, 60},
	{231, 199, 31},  {187, 86, 149},  {8, 133, 161},   {243, 243, 242}, {200, 200, 200},
	{160, 160, 160}, {122, 122, 121}, {85, 85, 85},    {52, 52, 52},
};

void chart_cc24_linear(int k, double lin[3])
{
	for (int c = 0; c < 3; c++) {
		double v = cc24_srgb8[k][c] / 255.0;
		lin[c] = v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);
	}
}

void chart_unit3(const double v[3], double u[3])
{
	double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
	for (int c = 0; c < 3; c++)
		u[c] = n > 0 ? v[c] / n : 0;
}

double chart_colour_sin2(const double M[9], const double e[3], const double u[3])
{
	double p[3], pp = 0, up = 0;
	for (int r = 0; r < 3; r++) {
		p[r] = M[3 * r] * e[0] + M[3 * r + 1] * e[1] + M[3 * r + 2] * e[2];
		pp += p[r] * p[r];
		up += u[r] * p[r];
	}
	return up > 0 && pp > 0 ? fmax(0, 1 - up * up / pp) : 1;
}

double chart_colour_fit(int n, const double (*u)[3], const double (*e)[3], const int *use,
                        double *s, double M[9])
{
	for (int i = 0; i < n; i++)
		s[i] = 1;
	for (int iter = 0; iter < 40; iter++) {
		double A[9] = {0}, B[9] = {0}, Binv[9];
		for (int i = 0; i < n; i++) {
			if (!use[i])
				continue;
			for (int r = 0; r < 3; r++)
				for (int c = 0; c < 3; c++) {
					A[3 * r + c] += u[i][r] * s[i] * e[i][c];
					B[3 * r + c] += s[i] * s[i] * e[i][r] * e[i][c];
				}
		}
		if (kg_mat3_inverse(B, Binv))
			return 1;
		double F = 0;
		for (int r = 0; r < 3; r++)
			for (int c = 0; c < 3; c++) {
				M[3 * r + c] = A[3 * r] * Binv[c] + A[3 * r + 1] * Binv[3 + c] +
				               A[3 * r + 2] * Binv[6 + c];
				F += M[3 * r + c] * M[3 * r + c];
			}
		if (!(F > 0) || !isfinite(F))
			return 1;
		for (int k = 0; k < 9; k++)
			M[k] /= sqrt(F);
		for (int i = 0; i < n; i++) {
			if (!use[i])
				continue;
			double p[3], pp = 0, up = 0;
			for (int r = 0; r < 3; r++) {
				p[r] = M[3 * r] * e[i][0] + M[3 * r + 1] * e[i][1] + M[3 * r + 2] * e[i][2];
				pp += p[r] * p[r];
				up += u[i][r] * p[r];
			}
			/* a scale stays positive: a colour pointing away is not explained */
			s[i] = pp > 0 ? fmax(up / pp, 1e-3) : 1e-3;
		}
	}
	double sum = 0;
	int k = 0;
	for (int i = 0; i < n; i++)
		if (use[i]) {
			sum += chart_colour_sin2(M, e[i], u[i]);
			k++;
		}
	return k ? sum / k : 1;
}

double chart_direction_spread(int n, const double (*u)[3], const int *use)
{
	double mean[3] = {0, 0, 0};
	int k = 0;
	for (int i = 0; i < n; i++)
		if (use[i]) {
			for (int c = 0; c < 3; c++)
				mean[c] += u[i][c];
			k++;
		}
	if (!k)
		return 0;
	double m[3], sum = 0;
	chart_unit3(mean, m);
	for (int i = 0; i < n; i++)
		if (use[i]) {
			double d = u[i][0] * m[0] + u[i][1] * m[1] + u[i][2] * m[2];
			sum += fmax(0, 1 - d * d);
		}
	return sqrt(sum / k);
}

#if KG_HAVE_MCC
/* A patch whose value can say which colour it is: sampled, in the frame, fewer than
 * half of its pixels clipped (so the median is not), every channel above zero. */
static int colour_usable(const kg_chart_sample *p)
{
	return !(p->flags & (KG_CHART_FLAG_REJECTED | KG_CHART_FLAG_OUT_OF_FRAME)) &&
	       p->clipped_fraction < 0.5 && p->rgb[0] > 0 && p->rgb[1] > 0 && p->rgb[2] > 0 &&
	       isfinite(p->rgb[0] + p->rgb[1] + p->rgb[2]);
}

/* How far the sampled patches are from a ColorChecker read in this orientation:
 * the RMS sine of the angles between each patch's colour (camera RGB as a
 * direction: free of its level, so of the light's falloff and the exposure) and the
 * layout's colour through the 3 x 3 matrix that fits them best (any camera, any
 * white balance). The 2 worst patches of 14 or more usable ones are left out of the
 * final fit (glare, dirt). 0 is a perfect match; a wrong orientation must map six
 * greys onto six colours and reads far worse. *used: the patches fitted. */
double chart_orientation_score(const kg_chart_sample *p, const int idx[24], int *used)
{
	double u[24][3], e[24][3], M[9], s[24];
	int use[24], n = 0;
	for (int i = 0; i < 24; i++) {
		const kg_chart_sample *q = &p[idx[i]];
		double lin[3];
		chart_cc24_linear(i, lin);
		chart_unit3(lin, e[i]);
		use[i] = colour_usable(q);
		if (use[i])
			chart_unit3(q->rgb, u[i]);
		n += use[i];
	}
	*used = n;
	if (n < 12)
		return 1;
	double ms = chart_colour_fit(24, (const double (*)[3])u, (const double (*)[3])e, use, s, M);
	if (n >= 14) {
		for (int drop = 0; drop < 2; drop++) {
			int worst = -1;
			double w = -1;
			for (int i = 0; i < 24; i++)
				if (use[i] && chart_colour_sin2(M, e[i], u[i]) > w) {
					w = chart_colour_sin2(M, e[i], u[i]);
					worst = i;
				}
			use[worst] = 0;
		}
		ms = chart_colour_fit(24, (const double (*)[3])u, (const double (*)[3])e, use, s, M);
	}
	return sqrt(ms);
}

/* How much colour the sampled patches have: the RMS angle (as a sine) of the usable
 * patches' directions from their mean. A grey picture, or an object of one colour,
 * has next to none, and then fits any orientation. */
double chart_colour_spread(const kg_chart_sample *p, const int idx[24])
{
	double u[24][3];
	int use[24];
	for (int i = 0; i < 24; i++)
		if ((use[i] = colour_usable(&p[idx[i]])))
			chart_unit3(p[idx[i]].rgb, u[i]);
	return chart_direction_spread(24, (const double (*)[3])u, use);
}

#endif
