/* The renderer's materials: the paper's eq. 2 (gloss + mirror lobes with per-band
 * Fresnel) and eq. 5 (a diffuse body under a dielectric surface) as optics/ defines
 * them in kg_material_eval, with the Fresnel reflectance tabulated once per material
 * against cos(theta), and importance sampling of each lobe. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "render_private.h"

static double dot3(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* An orthonormal basis t, b around the unit vector n (T. Duff et al., "Building an
 * orthonormal basis, revisited", JCGT 6(1), 2017). */
static void basis_of(const double n[3], double t[3], double b[3])
{
	double sign = copysign(1.0, n[2]);
	double a = -1.0 / (sign + n[2]);
	double c = n[0] * n[1] * a;
	t[0] = 1.0 + sign * n[0] * n[0] * a;
	t[1] = sign * c;
	t[2] = -sign * n[0];
	b[0] = c;
	b[1] = sign + n[1] * n[1] * a;
	b[2] = -n[1];
}

/* x t + y b + z n */
static void from_basis(const double n[3], double x, double y, double z, double out[3])
{
	double t[3], b[3];
	basis_of(n, t, b);
	for (int i = 0; i < 3; i++)
		out[i] = x * t[i] + y * b[i] + z * n[i];
}

int rd_material_init(rd_material *m, const kg_material *src, kg_err *err)
{
	memset(m, 0, sizeof(*m));
	int ret = kg_material_validate(src, err);
	if (ret)
		return ret;
	m->src = src;
	m->gloss = src->gloss;
	m->mirror = src->mirror;
	m->roughness = src->roughness;
	m->mirror_width = src->mirror_width;
	m->has_body = src->kind == KG_MATERIAL_DIELECTRIC;
	m->fresnel = malloc(sizeof(float) * (RD_NCOS + 1) * KG_NBANDS);
	if (!m->fresnel)
		return kg_fail(err, KG_ENOMEM, "material '%s': out of memory", src->name);
	for (int row = 0; row <= RD_NCOS; row++) {
		double c = (double)row / RD_NCOS;
		float *f = m->fresnel + (size_t)row * KG_NBANDS;
		if (m->has_body) {
			for (int i = 0; i < KG_NBANDS; i++)
				f[i] = (float)kg_fresnel_dielectric(src->nk.n.v[i], 1.0, c);
		} else {
			kg_spectrum r;
			if ((ret = kg_material_reflectance(src, acos(c), &r, err))) {
				rd_material_clear(m);
				return ret;
			}
			for (int i = 0; i < KG_NBANDS; i++)
				f[i] = (float)r.v[i];
		}
	}
	double f0 = 0.0, body = 0.0;
	for (int i = 0; i < KG_NBANDS; i++) {
		f0 += m->fresnel[(size_t)RD_NCOS * KG_NBANDS + i] / KG_NBANDS;
		if (m->has_body) {
			m->body[i] = (float)src->body.v[i];
			body += src->body.v[i] / KG_NBANDS;
		}
	}
	/* Lobes are picked in proportion to their normal-incidence albedo; a lobe that
	 * carries weight keeps a small chance so that no contribution is unreachable. */
	double a[3] = {m->gloss * f0, m->mirror * f0, m->has_body ? (1.0 - f0) * body : 0.0};
	double w[3] = {m->gloss, m->mirror, m->has_body ? body : 0.0};
	double total = 0.0;
	for (int i = 0; i < 3; i++) {
		if (w[i] > 0.0 && a[i] < 1e-3 * w[i])
			a[i] = 1e-3 * w[i];
		total += a[i];
	}
	for (int i = 0; i < 3; i++)
		m->p_lobe[i] = total > 0.0 ? a[i] / total : 0.0;
	return 0;
}

void rd_material_clear(rd_material *m)
{
	free(m->fresnel);
	m->fresnel = NULL;
}

void rd_fresnel(const rd_material *m, double c, const int *band, int n, float *out)
{
	double x = (c > 0.0 ? (c < 1.0 ? c : 1.0) : 0.0) * RD_NCOS;
	int row = (int)x;
	if (row >= RD_NCOS)
		row = RD_NCOS - 1;
	float t = (float)(x - row);
	const float *a = m->fresnel + (size_t)row * KG_NBANDS, *b = a + KG_NBANDS;
	for (int j = 0; j < n; j++)
		out[j] = a[band[j]] + t * (b[band[j]] - a[band[j]]);
}

int rd_eval(const rd_material *m, const double N[3], const double V[3],
            const double L[3], const int *band, int n, float *out)
{
	double nl = fmin(1.0, dot3(N, L)), nv = dot3(N, V);
	double cos_vh = 1.0;
	double gloss = kg_lobe_gloss(N, V, L, m->roughness, &cos_vh);
	double mirror = kg_lobe_mirror(N, V, L, m->mirror_width, NULL);
	if (!(nl > 0.0) || !(nv > 0.0) || isnan(gloss) || isnan(mirror)) {
		memset(out, 0, sizeof(float) * (size_t)n);
		return 0;
	}
	float s = (float)((m->gloss * gloss + m->mirror * mirror) * nl);
	rd_fresnel(m, cos_vh, band, n, out);
	for (int j = 0; j < n; j++)
		out[j] *= s;
	if (m->has_body) {
		float fi[KG_NBANDS], k = (float)(nl / M_PI);
		rd_fresnel(m, nl, band, n, fi);
		for (int j = 0; j < n; j++)
			out[j] += (1.0f - fi[j]) * m->body[band[j]] * k;
	}
	return 1;
}

int rd_sample(const rd_material *m, const double N[3], const double V[3],
              const double u[3], const int *band, int n, double L[3], float *weight)
{
	double nv = dot3(N, V);
	if (!(nv > 0.0))
		return 0;
	int lobe = u[0] < m->p_lobe[0] ? 0 : u[0] < m->p_lobe[0] + m->p_lobe[1] ? 1 : 2;
	double p = m->p_lobe[lobe];
	if (!(p > 0.0))
		return 0;
	double phi = 2.0 * M_PI * u[2];
	double cos_vh = 1.0, scale;
	if (lobe == 0) {
		/* Beckmann facet normals: tan^2(alpha) = -m^2 ln(1 - u), density D (N.H)
		 * over facet directions, D (N.H) / (4 V.H) over L. */
		double r = m->roughness;
		double tan2 = -r * r * log1p(-u[1]);
		double ca = 1.0 / sqrt(1.0 + tan2), sa = sqrt(fmax(0.0, 1.0 - ca * ca));
		double H[3];
		from_basis(N, sa * cos(phi), sa * sin(phi), ca, H);
		double vh = dot3(V, H);
		if (!(vh > 0.0))
			return 0;
		for (int i = 0; i < 3; i++)
			L[i] = 2.0 * vh * H[i] - V[i];
		double pdf = kg_beckmann(ca, r) * ca / (4.0 * vh);
		double f = kg_lobe_gloss(N, V, L, r, &cos_vh);
		if (!(pdf > 0.0) || !isfinite(pdf) || !(f > 0.0))
			return 0;
		scale = m->gloss * f * fmin(1.0, dot3(N, L)) / (p * pdf);
	} else if (lobe == 1) {
		/* The Gaussian cone around the mirror direction of V: delta = w sqrt(-ln(1-u)),
		 * density delta exp(-(delta/w)^2) / (pi w^2 sin(delta)) over L. */
		double w = m->mirror_width;
		double delta = w * sqrt(-log1p(-u[1]));
		if (!(delta < M_PI))
			return 0;
		double R[3];
		for (int i = 0; i < 3; i++)
			R[i] = 2.0 * nv * N[i] - V[i];
		double sd = sin(delta);
		from_basis(R, sd * cos(phi), sd * sin(phi), cos(delta), L);
		double ratio = delta > 1e-8 ? delta / sd : 1.0;
		double pdf = ratio * exp(-(delta / w) * (delta / w)) / (M_PI * w * w);
		double f = kg_lobe_mirror(N, V, L, w, &cos_vh);
		if (!(pdf > 0.0) || !(f > 0.0))
			return 0;
		scale = m->mirror * f * fmin(1.0, dot3(N, L)) / (p * pdf);
	} else {
		/* cosine-weighted: density (N.L) / pi */
		double r = sqrt(u[1]);
		from_basis(N, r * cos(phi), r * sin(phi), sqrt(fmax(0.0, 1.0 - u[1])), L);
		double nl = dot3(N, L);
		if (!(nl > 0.0))
			return 0;
		float fi[KG_NBANDS];
		rd_fresnel(m, fmin(1.0, nl), band, n, fi);
		float k = (float)(1.0 / p);
		int any = 0;
		for (int j = 0; j < n; j++) {
			weight[j] = (1.0f - fi[j]) * m->body[band[j]] * k;
			any |= weight[j] > 0.0f;
		}
		return any;
	}
	if (!(scale > 0.0) || !isfinite(scale))
		return 0;
	rd_fresnel(m, cos_vh, band, n, weight);
	for (int j = 0; j < n; j++)
		weight[j] *= (float)scale;
	return 1;
}

/* ---- public checks ------------------------------------------------------------ */

static const int all_bands[KG_NBANDS] = {
	0,  1,  2,  3,  4,  5,  6,  7,  8,  9,  10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20,
	21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32, 33, 34, 35, 36, 37, 38, 39, 40, 41,
	42, 43, 44, 45, 46, 47, 48, 49, 50, 51, 52, 53, 54, 55, 56, 57, 58, 59, 60,
};

struct kg_render_material {
	rd_material m;
};

int kg_render_material_new(const kg_material *mat, kg_render_material **out, kg_err *err)
{
	kg_check_arg(mat && out, err);
	*out = calloc(1, sizeof(**out));
	if (!*out)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	int ret = rd_material_init(&(*out)->m, mat, err);
	if (ret)
		kg_render_material_free(out);
	return ret;
}

void kg_render_material_free(kg_render_material **m)
{
	if (!m || !*m)
		return;
	rd_material_clear(&(*m)->m);
	free(*m);
	*m = NULL;
}

void kg_render_material_eval(const kg_render_material *m, const double N[3],
                             const double V[3], const double L[3], kg_spectrum *out)
{
	float v[KG_NBANDS];
	rd_eval(&m->m, N, V, L, all_bands, KG_NBANDS, v);
	for (int i = 0; i < KG_NBANDS; i++)
		out->v[i] = v[i];
}

void kg_render_material_albedo(const kg_render_material *m, const double N[3],
                               const double V[3], int n, uint64_t seed, kg_spectrum *out)
{
	kg_rng rng;
	kg_rng_seed(&rng, seed);
	double sum[KG_NBANDS] = {0};
	for (int s = 0; s < n; s++) {
		double u[3] = {kg_rng_uniform(&rng), kg_rng_uniform(&rng), kg_rng_uniform(&rng)};
		double L[3];
		float w[KG_NBANDS];
		if (rd_sample(&m->m, N, V, u, all_bands, KG_NBANDS, L, w))
			for (int i = 0; i < KG_NBANDS; i++)
				sum[i] += w[i];
	}
	for (int i = 0; i < KG_NBANDS; i++)
		out->v[i] = n > 0 ? sum[i] / n : 0.0;
}
