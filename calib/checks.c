/* Checks a chart must pass before it is fitted, with messages that name the
 * patches: values, clipping, near-black patches, collinearity. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "calib_private.h"

void calib_strv_free(char **v, int n)
{
	if (!v)
		return;
	for (int i = 0; i < n; i++)
		free(v[i]);
	free(v);
}

char **calib_strv_dup(char *const *v, int n)
{
	char **out = calloc(n > 0 ? (size_t)n : 1, sizeof(char *));
	if (!out)
		return NULL;
	for (int i = 0; i < n; i++) {
		out[i] = strdup(v[i]);
		if (!out[i]) {
			calib_strv_free(out, i);
			return NULL;
		}
	}
	return out;
}

double calib_median(double *v, int n)
{
	for (int i = 1; i < n; i++) /* insertion sort: a few dozen values */
		for (int j = i; j > 0 && v[j - 1] > v[j]; j--) {
			double t = v[j];
			v[j] = v[j - 1];
			v[j - 1] = t;
		}
	return n <= 0 ? NAN : n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void calib_list_ids(char *buf, size_t len, char *const *ids, const int *which, int n,
                    int max)
{
	size_t used = strlen(buf);
	for (int i = 0; i < n && used + 1 < len; i++) {
		if (i == max) {
			snprintf(buf + used, len - used, " and %d more", n - max);
			return;
		}
		snprintf(buf + used, len - used, "%s%s", i ? ", " : "", ids[which ? which[i] : i]);
		used = strlen(buf);
	}
}

int calib_rgb_conditioning(const double (*rgb)[3], int n, double *cond,
                           double *cond_equilibrated, double sv[3], double sv_eq[3],
                           kg_err *err)
{
	kg_mat *a = NULL, *s = NULL;
	int ret = kg_mat_new(3, n, &a, err);
	if (ret)
		return ret;
	for (int pass = 0; pass < 2 && ret == 0; pass++) {
		for (int c = 0; c < 3; c++) {
			double rms = 0;
			for (int i = 0; i < n; i++)
				rms += rgb[i][c] * rgb[i][c];
			rms = sqrt(rms / n);
			/* Pass 1 scales each channel to unit RMS; a dead channel stays 0. */
			double scale = pass == 0 ? 1.0 : (rms > 0 ? 1.0 / rms : 0.0);
			for (int i = 0; i < n; i++)
				a->a[c * n + i] = rgb[i][c] * scale;
		}
		ret = kg_svd(a, NULL, &s, NULL, err);
		if (ret)
			break;
		/* Singular values at the rounding level of the largest count as zero. */
		int rows = s->rows;
		double smin = rows < 3 ? 0.0 : s->a[2];
		double tol = (n > 3 ? n : 3) * DBL_EPSILON * s->a[0];
		double c = smin > tol ? s->a[0] / smin : INFINITY;
		double *out = pass == 0 ? sv : sv_eq;
		for (int i = 0; i < 3; i++)
			out[i] = i < rows ? s->a[i] : 0.0;
		if (pass == 0)
			*cond = c;
		else
			*cond_equilibrated = c;
		kg_mat_free(&s);
	}
	kg_mat_free(&a);
	return ret;
}

/* Append the first 8 of the patches which[0..n) to msg: "A01 (0.123 0.456 0.789), ..."
 * with digits decimals, or "A01 (fraction 0.5)" from fraction when given; " and N
 * more" after 8. */
static void list_patches(char *msg, size_t len, const int *which, int n, char *const *ids,
                         const double (*rgb)[3], const double *fraction, int digits)
{
	for (int j = 0; j < n && j < 8; j++) {
		int i = which[j];
		size_t u = strlen(msg);
		if (fraction)
			snprintf(msg + u, len - u, "%s%s (fraction %.3g)", j ? ", " : "", ids[i],
			         fraction[i]);
		else
			snprintf(msg + u, len - u, "%s%s (%.*f %.*f %.*f)", j ? ", " : "", ids[i], digits,
			         rgb[i][0], digits, rgb[i][1], digits, rgb[i][2]);
	}
	size_t u = strlen(msg);
	if (n > 8)
		snprintf(msg + u, len - u, " and %d more", n - 8);
}

int calib_check_patch_values(const char *what, char *const *ids, const double (*rgb)[3],
                             const double *clipped_fraction, int n, double clip_level,
                             double black_level, kg_err *err)
{
	for (int i = 0; i < n; i++)
		for (int c = 0; c < 3; c++)
			if (!isfinite(rgb[i][c]))
				return kg_fail(err, KG_EINVAL, "%s: patch %s: RGB_%c is %g; expected a finite value",
				               what, ids[i], "RGB"[c], rgb[i][c]);
	int *clipped = malloc((n > 0 ? (size_t)n : 1) * sizeof(int));
	int *black = malloc((n > 0 ? (size_t)n : 1) * sizeof(int));
	int nclip = 0, nblack = 0;
	if (!clipped || !black) {
		free(clipped);
		free(black);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	for (int i = 0; i < n; i++) {
		double hi = fmax(rgb[i][0], fmax(rgb[i][1], rgb[i][2]));
		int is_clipped = clipped_fraction ? clipped_fraction[i] > 0 : hi >= clip_level;
		if (is_clipped)
			clipped[nclip++] = i;
		else if (black_level > 0 && hi < black_level)
			black[nblack++] = i;
	}
	int ret = 0;
	if (nclip || nblack) {
		char msg[sizeof(err->msg)];
		snprintf(msg, sizeof(msg), "%s: ", what);
		if (nclip) {
			size_t u = strlen(msg);
			if (clipped_fraction)
				snprintf(msg + u, sizeof(msg) - u,
				         "%d clipped patch%s (pixels at the sensor's saturation: "
				         "clipped-fraction column above 0): ",
				         nclip, nclip == 1 ? "" : "es");
			else
				snprintf(msg + u, sizeof(msg) - u,
				         "%d clipped patch%s (a channel at or above %.2f of full scale): ",
				         nclip, nclip == 1 ? "" : "es", clip_level);
			list_patches(msg, sizeof(msg), clipped, nclip, ids, rgb, clipped_fraction, 3);
			u = strlen(msg);
			snprintf(msg + u, sizeof(msg) - u,
			         "; photograph with less exposure or leave them out (--exclude)");
		}
		if (nblack) {
			size_t u = strlen(msg);
			snprintf(msg + u, sizeof(msg) - u,
			         "%s%d near-black patch%s (brightest channel below %.2f of full scale): ",
			         nclip ? "; and " : "", nblack, nblack == 1 ? "" : "es", black_level);
			list_patches(msg, sizeof(msg), black, nblack, ids, rgb, NULL, 4);
			u = strlen(msg);
			snprintf(msg + u, sizeof(msg) - u,
			         "; photograph with more light or exposure or leave them out (--exclude)");
		}
		ret = kg_fail(err, KG_EINVAL, "%s", msg);
	}
	free(clipped);
	free(black);
	return ret;
}

int calib_check_collinear(const char *what, char *const *ids, const double (*rgb)[3],
                          int n, double max_cond, double *cond, double *cond_eq,
                          double sv[3], kg_err *err)
{
	double sv_eq[3];
	int ret = calib_rgb_conditioning(rgb, n, cond, cond_eq, sv, sv_eq, err);
	if (ret)
		return ret;
	if (*cond_eq <= max_cond)
		return 0;
	/* How many colour directions the patches do fix (equilibrated singular values
	 * within max_cond of the largest), and how alike their colours are: the largest
	 * distance of a chromaticity (r, g) / (r + g + b) from their mean (grey patches
	 * of one camera give almost 0). */
	int directions = 1 + (sv_eq[1] * max_cond > sv_eq[0]);
	double mr = 0, mg = 0, spread = 0;
	int nc = 0;
	for (int i = 0; i < n; i++) {
		double t = rgb[i][0] + rgb[i][1] + rgb[i][2];
		if (t > 0) {
			mr += rgb[i][0] / t;
			mg += rgb[i][1] / t;
			nc++;
		}
	}
	if (nc) {
		mr /= nc;
		mg /= nc;
	}
	for (int i = 0; i < n; i++) {
		double t = rgb[i][0] + rgb[i][1] + rgb[i][2];
		if (t > 0)
			spread = fmax(spread, hypot(rgb[i][0] / t - mr, rgb[i][1] / t - mg));
	}
	char list[512] = "", why[256];
	calib_list_ids(list, sizeof(list), ids, NULL, n, 24);
	if (directions == 1)
		snprintf(why, sizeof(why),
		         "they differ in level, not in colour: their chromaticities r/(r+g+b), "
		         "g/(r+g+b) all lie within %.2g of (%.3f, %.3f), as neutral (grey) patches "
		         "do",
		         spread, mr, mg);
	else
		snprintf(why, sizeof(why), "they vary in only two colour directions");
	return kg_fail(err, KG_EINVAL,
	               "%s: the chart is %s: condition number %.3g of its RGB with each channel "
	               "scaled to unit RMS (limit %g; singular values %.3g %.3g %.3g); its %d "
	               "patches (%s) do not span three independent colours: %s; use a chart with "
	               "clearly red, green and blue patches",
	               what, isfinite(*cond_eq) ? "nearly collinear" : "rank deficient", *cond_eq,
	               max_cond, sv_eq[0], sv_eq[1], sv_eq[2], n, list, why);
}

const double *calib_clipped_column(const kg_patchset *ps, int *stride)
{
	for (int j = 0; j < ps->nextra; j++)
		if (strcasestr(ps->extra_names[j], "CLIP")) {
			*stride = ps->nextra;
			return ps->extra + j;
		}
	return NULL;
}

int calib_d65_init(calib_d65 *d, kg_err *err)
{
	kg_illuminant *ill = NULL;
	int ret = kg_illuminant_by_name("D65", &ill, err);
	if (ret)
		return ret;
	kg_xyz_weights_reflectance(ill, &d->w);
	d->white = kg_illuminant_white(ill);
	kg_illuminant_free(&ill);
	return 0;
}

double calib_de00(const calib_d65 *d, const kg_spectrum *a, const kg_spectrum *b)
{
	kg_lab la = kg_xyz_to_lab(kg_xyz_from_weights(&d->w, a), d->white);
	kg_lab lb = kg_xyz_to_lab(kg_xyz_from_weights(&d->w, b), d->white);
	return kg_ciede2000(la, lb);
}
