/* The estimation methods: names, regression terms and the evaluation of a map. */
#include <math.h>
#include <string.h>

#include "calib_private.h"

static const char *const method_names[KG_METHOD_COUNT] = {
	"pca", "linear", "wiener", "rootpoly2", "rootpoly3",
};

static const char *const term_names[KG_CALIB_MAX_TERMS] = {
	"r", "g", "b", "sqrt(rg)", "sqrt(gb)", "sqrt(rb)", "cbrt(rgg)", "cbrt(gbb)",
	"cbrt(rbb)", "cbrt(grr)", "cbrt(bgg)", "cbrt(brr)", "cbrt(rgb)",
};

const char *kg_method_name(kg_method m)
{
	if (m == KG_METHOD_AUTO)
		return "auto";
	if (m < 0 || m >= KG_METHOD_COUNT)
		return "unknown";
	return method_names[m];
}

int kg_method_parse(const char *name, kg_method *out, kg_err *err)
{
	if (name && strcmp(name, "auto") == 0) {
		*out = KG_METHOD_AUTO;
		return 0;
	}
	for (int i = 0; name && i < KG_METHOD_COUNT; i++) {
		if (strcmp(name, method_names[i]) == 0) {
			*out = (kg_method)i;
			return 0;
		}
	}
	return kg_fail(err, KG_EINVAL,
	               "method '%s': expected pca, linear, wiener, rootpoly2, rootpoly3 or auto",
	               name ? name : "");
}

int kg_method_nterms(kg_method m)
{
	return kg_est_method_terms(kg_method_est(m));
}

const char *kg_method_term_name(kg_method m, int i)
{
	if (i < 0 || i >= kg_method_nterms(m))
		return "";
	return term_names[i];
}

kg_est_method kg_method_est(kg_method m)
{
	switch (m) {
	case KG_METHOD_ROOTPOLY2:
		return KG_EST_ROOTPOLY2;
	case KG_METHOD_ROOTPOLY3:
		return KG_EST_ROOTPOLY3;
	default:
		return KG_EST_LINEAR;
	}
}

void kg_method_terms(kg_method m, const double rgb[3], double *x)
{
	kg_est_terms(kg_method_est(m), rgb, x);
}

/* s = offset + A x, A 61 x T. */
static void apply_terms(const double *A, const double *offset, int T, const double *x,
                        kg_spectrum *out)
{
	for (int l = 0; l < KG_NBANDS; l++) {
		double v = offset[l];
		for (int t = 0; t < T; t++)
			v += A[l * T + t] * x[t];
		out->v[l] = v;
	}
}

void kg_spectral_map_apply(const kg_spectral_map *map, const double rgb[3],
                           kg_spectrum *out)
{
	double x[KG_CALIB_MAX_TERMS];
	kg_method_terms(map->method, rgb, x);
	apply_terms(map->A, map->offset, map->nterms, x, out);
}

void kg_site_map_apply(const kg_site_map *map, const double rgb[3], kg_spectrum *out)
{
	double p[3], x[KG_CALIB_MAX_TERMS];
	for (int i = 0; i < 3; i++)
		p[i] = map->pre[3 * i] * rgb[0] + map->pre[3 * i + 1] * rgb[1] +
		       map->pre[3 * i + 2] * rgb[2];
	kg_method_terms(map->method, p, x);
	apply_terms(map->A, map->offset, map->nterms, x, out);
}
