/* Numbers against independent computations:
 *  - linear and root-polynomial kernels against a dense double-precision product
 *    (terms from kg_est_terms), to 1e-6 of the size of the sum (float arithmetic
 *    with up to 13 terms stays well inside that: about 2.5e-7 measured);
 *  - root-polynomial terms of a known rgb against values computed outside the project
 *    (Python's math module), and the kernel's cube root to within 2 ulp;
 *  - a LUT reproduces its source exactly at the nodes, within 1e-5 between nodes for
 *    a linear source (trilinear interpolation of a linear map is exact up to
 *    rounding), within a stated error for a root-polynomial source;
 *  - classification distances against the dense 61-band computation of eq. 11 (and
 *    its scale-free variant) in double, to 1e-6 relative; labels and margins of whole
 *    images, both implementations, against the same. Ties are real in the
 *    scale-free case (every material with c_j.v <= 0 has a = 0 and distance ||s||^2):
 *    there the label must be one of the tied materials and the margin 0. */
#include "est_fixture.h"
#include "kg_test.h"

static void check_linear_dense(void)
{
	fx_rng r = {21};
	double a[KG_NBANDS * 3], off[KG_NBANDS], basis[KG_NBANDS * 3], m[9], b2[KG_NBANDS * 3];
	fx_matrix(&r, KG_NBANDS, 3, 1.0, a);
	fx_matrix(&r, KG_NBANDS, 1, 0.1, off);
	fx_basis(3, basis);
	fx_matrix(&r, 3, 3, 2.0, m);
	/* the paper's A = B (M M2) as one 61x3 product, for the dense side */
	for (int o = 0; o < KG_NBANDS; o++)
		for (int t = 0; t < 3; t++) {
			b2[o * 3 + t] = 0;
			for (int i = 0; i < 3; i++)
				b2[o * 3 + t] += basis[o * 3 + i] * m[i * 3 + t];
		}
	kg_est_kernel *direct = NULL, *pca = NULL;
	CHECK(kg_est_kernel_new(&(kg_est_desc){KG_EST_LINEAR, 0, a, off, NULL, NULL}, &direct, NULL) ==
	          0,
	      "kernel");
	CHECK(kg_est_kernel_new(&(kg_est_desc){KG_EST_LINEAR, 3, m, NULL, basis, NULL}, &pca, NULL) == 0,
	      "kernel");
	enum { N = 4000 };
	float *rgb = fx_image(&r, N, -0.02, 0.99, 0);
	for (int isa = KG_EST_ISA_AUTO; isa <= KG_EST_ISA_C; isa++)
		for (int which = 0; which < 2; which++) {
			const double *A = which ? b2 : a, *O = which ? NULL : off;
			kg_est_job job;
			kg_est_job_init(&job, which ? pca : direct, KG_EST_F32_BIP);
			job.isa = (kg_est_isa)isa;
			float *out = malloc(sizeof(float) * N * KG_NBANDS);
			CHECK(kg_est_run(&job, rgb, N, 1, &(kg_est_dest){out, NULL, NULL}, NULL, NULL) == 0,
			      "run");
			double worst = 0;
			for (int i = 0; i < N; i++)
				for (int o = 0; o < KG_NBANDS; o++) {
					double s = O ? O[o] : 0, size = O ? fabs(O[o]) : 0;
					for (int t = 0; t < 3; t++) {
						s += A[o * 3 + t] * rgb[3 * i + t];
						size += fabs(A[o * 3 + t] * rgb[3 * i + t]);
					}
					double expect = s < 0 ? 0 : s, err = fabs(out[i * KG_NBANDS + o] - expect);
					if (err / fmax(size, 1e-30) > worst)
						worst = err / fmax(size, 1e-30);
					CHECK(err <= 1e-6 * size, "%s pixel %d band %d: %.9g vs %.9g",
					      which ? "pca" : "direct", i, o, (double)out[i * KG_NBANDS + o], expect);
				}
			printf("linear %s (isa %d): worst error %.3g of the sum's size\n", which ? "B M M2" : "61x3",
			       isa, worst);
			free(out);
		}
	free(rgb);
	kg_est_kernel_free(&direct);
	kg_est_kernel_free(&pca);
}

/* Root-polynomial kernels against A x(rgb) in double, x from kg_est_terms, over
 * inputs beyond [0, 1] on both sides (a site map's pre-transform makes them), both
 * implementations, to 1e-6 of the size of the sum. */
static void check_rootpoly_dense(void)
{
	fx_rng r = {23};
	const kg_est_method methods[2] = {KG_EST_ROOTPOLY2, KG_EST_ROOTPOLY3};
	enum { N = 20000 };
	float *rgb = fx_image(&r, N, -0.3, 1.5, 0);
	float *out = malloc(sizeof(float) * N * KG_NBANDS);
	for (int mi = 0; mi < 2; mi++) {
		int nt = kg_est_method_terms(methods[mi]);
		double a[KG_NBANDS * 13], off[KG_NBANDS];
		fx_matrix(&r, KG_NBANDS, nt, 1.0, a);
		fx_matrix(&r, KG_NBANDS, 1, 0.1, off);
		kg_est_kernel *k = NULL;
		CHECK(kg_est_kernel_new(&(kg_est_desc){methods[mi], 0, a, off, NULL, NULL}, &k, NULL) == 0,
		      "kernel");
		for (int isa = KG_EST_ISA_AUTO; isa <= KG_EST_ISA_C; isa++) {
			kg_est_job job;
			kg_est_job_init(&job, k, KG_EST_F32_BSQ);
			job.isa = (kg_est_isa)isa;
			job.clip_level = INFINITY;
			CHECK(kg_est_run(&job, rgb, N, 1, &(kg_est_dest){out, NULL, NULL}, NULL, NULL) == 0,
			      "run");
			double worst = 0;
			for (int i = 0; i < N; i++) {
				double px[3] = {rgb[3 * i], rgb[3 * i + 1], rgb[3 * i + 2]}, t[13];
				kg_est_terms(methods[mi], px, t);
				for (int o = 0; o < KG_NBANDS; o++) {
					double s = off[o], size = fabs(off[o]);
					for (int j = 0; j < nt; j++) {
						s += a[o * nt + j] * t[j];
						size += fabs(a[o * nt + j] * t[j]);
					}
					double err = fabs(out[(size_t)o * N + i] - (s < 0 ? 0 : s));
					worst = fmax(worst, err / fmax(size, 1e-30));
					CHECK(err <= 1e-6 * size, "root-poly %d pixel %d band %d: %.9g vs %.9g", nt, i, o,
					      (double)out[(size_t)o * N + i], s);
				}
			}
			printf("root-polynomial %d terms (isa %d), inputs in [-0.3, 1.5]: worst error %.3g of "
			       "the sum's size\n",
			       nt, isa, worst);
		}
		kg_est_kernel_free(&k);
	}
	free(out);
	free(rgb);
}

/* A root-polynomial kernel whose band o is term o % 13. */
static kg_est_kernel *term_selector(void)
{
	double a[KG_NBANDS * 13] = {0};
	for (int o = 0; o < KG_NBANDS; o++)
		a[o * 13 + o % 13] = 1.0;
	kg_est_kernel *k = NULL;
	CHECK(kg_est_kernel_new(&(kg_est_desc){KG_EST_ROOTPOLY3, 0, a, NULL, NULL, NULL}, &k, NULL) == 0,
	      "selector");
	return k;
}

static void check_rootpoly(void)
{
	/* python3: r,g,b = .25,.5,.8; [r,g,b, sqrt(rg), sqrt(gb), sqrt(rb), (r g^2)^(1/3),
	 * (g b^2)^(1/3), (r b^2)^(1/3), (g r^2)^(1/3), (b g^2)^(1/3), (b r^2)^(1/3), (rgb)^(1/3)] */
	const double expect[13] = {0.25,
	                           0.5,
	                           0.80000000000000004,
	                           0.35355339059327379,
	                           0.63245553203367588,
	                           0.44721359549995793,
	                           0.3968502629920499,
	                           0.6839903786706788,
	                           0.54288352331898138,
	                           0.3149802624737183,
	                           0.58480354764257325,
	                           0.36840314986403871,
	                           0.46415888336127792};
	double rgb[3] = {0.25, 0.5, 0.8}, t[13];
	CHECK(kg_est_terms(KG_EST_ROOTPOLY3, rgb, t) == 13, "13 terms");
	for (int i = 0; i < 13; i++)
		CHECK_NEAR(t[i], expect[i], 1e-15, "double term");
	CHECK(kg_est_terms(KG_EST_ROOTPOLY2, rgb, t) == 6 && kg_est_terms(KG_EST_LINEAR, rgb, t) == 3,
	      "term counts");
	CHECK(kg_est_terms(KG_EST_LUT, rgb, t) == KG_EINVAL, "no terms for a LUT");

	kg_est_kernel *k = term_selector();
	float rgbf[3] = {0.25f, 0.5f, 0.8f}, out[KG_NBANDS];
	CHECK(kg_est_kernel_eval(k, rgbf, INFINITY, 0, out) == 0, "eval");
	for (int i = 0; i < 13; i++)
		CHECK(fabs(out[i] - expect[i]) <= 2.5e-7 * expect[i], "float term %d: %.9g vs %.9g", i,
		      (double)out[i], expect[i]);
	/* a negative channel counts as 0 inside the roots, and keeps its sign outside */
	float neg[3] = {-0.1f, 0.5f, 0.8f};
	kg_est_kernel_eval(k, neg, INFINITY, 0, out);
	CHECK(out[0] == 0.0f /* clamped reflectance: the term itself is -0.1 */ && out[3] == 0.0f &&
	          out[5] == 0.0f && out[6] == 0.0f && out[12] == 0.0f,
	      "negative red: %g %g %g", (double)out[3], (double)out[5], (double)out[12]);
	CHECK(fabs(out[4] - sqrt(0.4)) < 1e-7, "sqrt(gb) unaffected");
	double negd[3] = {-0.1, 0.5, 0.8};
	kg_est_terms(KG_EST_ROOTPOLY3, negd, t);
	CHECK(t[0] == -0.1 && t[3] == 0 && t[5] == 0 && t[12] == 0, "double: negative red");

	/* the cube root: term 6 is cbrt(r g^2) = cbrt(r) when g = b = 1 */
	double worst = 0;
	fx_rng r = {4};
	for (int i = 0; i < 200000; i++) {
		float x = i < 100000 ? (float)exp2(-119.0 + 130.0 * i / 100000.0)
		                     : (float)fx_uniform(&r, 0, 1.5);
		float px[3] = {x, 1.0f, 1.0f};
		kg_est_kernel_eval(k, px, INFINITY, 0, out);
		double e = fabs(out[6] - cbrt((double)x)) / cbrt((double)x);
		if (e > worst)
			worst = e;
	}
	printf("cube root: worst relative error %.3g (float ulp 1.19e-7)\n", worst);
	CHECK(worst <= 2.4e-7, "cube root within 2 ulp: %.3g", worst);
	float tiny[3] = {1e-37f, 1.0f, 1.0f};
	kg_est_kernel_eval(k, tiny, INFINITY, 0, out);
	CHECK(out[6] == 0.0f, "cube root below 2^-120 is 0");
	kg_est_kernel_free(&k);
}

static void check_lut(void)
{
	fx_kernels ks;
	CHECK(fx_kernels_make(&ks, 9) == 0, "kernels");
	kg_est_kernel *lut = NULL;
	CHECK(kg_est_kernel_new_lut(ks.pca, 17, 0.0f, 1.0f, &lut, NULL) == 0, "LUT");
	float a[KG_NBANDS], b[KG_NBANDS];
	int mismatches = 0;
	for (int z = 0; z < 17; z++)
		for (int y = 0; y < 17; y++)
			for (int x = 0; x < 17; x++) {
				float px[3] = {kg_est_lut_node(lut, x), kg_est_lut_node(lut, y),
				               kg_est_lut_node(lut, z)};
				for (int w = 0; w < 2; w++) {
					kg_est_kernel_eval(lut, px, INFINITY, w, a);
					kg_est_kernel_eval(ks.pca, px, INFINITY, w, b);
					for (int o = 0; o < (w ? 3 : KG_NBANDS); o++)
						mismatches += a[o] != b[o];
				}
			}
	CHECK(mismatches == 0, "LUT differs from its source at %d node values", mismatches);

	fx_rng r = {17};
	double worst = 0;
	for (int i = 0; i < 20000; i++) {
		float px[3] = {(float)fx_uniform(&r, 0, 1), (float)fx_uniform(&r, 0, 1),
		               (float)fx_uniform(&r, 0, 1)};
		kg_est_kernel_eval(lut, px, INFINITY, 0, a);
		kg_est_kernel_eval(ks.pca, px, INFINITY, 0, b);
		for (int o = 0; o < KG_NBANDS; o++)
			worst = fmax(worst, fabs(a[o] - b[o]));
	}
	printf("LUT 17 of a linear kernel: worst error between nodes %.3g\n", worst);
	CHECK(worst <= 1e-5, "linear source between nodes: %.3g", worst);

	/* inputs outside the grid read its edge */
	float out_px[3] = {1.5f, 0.3f, -0.2f}, edge_px[3] = {1.0f, 0.3f, 0.0f};
	kg_est_kernel_eval(lut, out_px, INFINITY, 0, a);
	kg_est_kernel_eval(lut, edge_px, INFINITY, 0, b);
	CHECK(memcmp(a, b, sizeof(a)) == 0, "outside the range: the edge value");

	/* root-polynomial source: interpolation error away from the kink at 0 */
	kg_est_kernel *lut33 = NULL;
	CHECK(kg_est_kernel_new_lut(ks.rootpoly3, 33, 0.0f, 1.0f, &lut33, NULL) == 0, "LUT 33");
	double se = 0, scale = 0;
	worst = 0;
	int n = 0;
	for (int i = 0; i < 20000; i++) {
		float px[3] = {(float)fx_uniform(&r, 0.05, 0.95), (float)fx_uniform(&r, 0.05, 0.95),
		               (float)fx_uniform(&r, 0.05, 0.95)};
		kg_est_kernel_eval(lut33, px, INFINITY, 0, a);
		kg_est_kernel_eval(ks.rootpoly3, px, INFINITY, 0, b);
		for (int o = 0; o < KG_NBANDS; o++, n++) {
			worst = fmax(worst, fabs(a[o] - b[o]));
			se += (a[o] - b[o]) * (a[o] - b[o]);
			scale = fmax(scale, fabs(b[o]));
		}
	}
	printf("LUT 33 of root-polynomial 3 on [0.05, 0.95]^3: worst %.3g, rms %.3g (outputs up to "
	       "%.3g)\n",
	       worst, sqrt(se / n), scale);
	/* measured 2.6e-3 of the output range with this seed; the bound leaves room */
	CHECK(worst <= 5e-3 * scale, "root-polynomial between nodes: %.3g", worst);
	kg_est_kernel_free(&lut);
	kg_est_kernel_free(&lut33);
	fx_kernels_free(&ks);
}

/* Eq. 11 the long way: s = mean + B w over 61 bands. */
static double dense_distance(const double *basis, int k, const double *mean, const double *c,
                             const float *w, kg_est_distance dist)
{
	double s[KG_NBANDS], cs = 0, cc = 0;
	for (int o = 0; o < KG_NBANDS; o++) {
		s[o] = mean ? mean[o] : 0;
		for (int i = 0; i < k; i++)
			s[o] += basis[o * k + i] * w[i];
		cs += c[o] * s[o];
		cc += c[o] * c[o];
	}
	double a = 1;
	if (dist == KG_EST_DIST_SCALE_FREE)
		a = cs > 0 ? cs / cc : 0;
	double d = 0;
	for (int o = 0; o < KG_NBANDS; o++)
		d += (a * c[o] - s[o]) * (a * c[o] - s[o]);
	return d;
}

static void check_classification(void)
{
	fx_kernels ks;
	CHECK(fx_kernels_make(&ks, 13) == 0, "kernels");
	fx_rng r = {29};
	enum { NM = 16 };
	double spectra[NM * KG_NBANDS];
	fx_materials(&r, NM, spectra);
	/* material 3 lies exactly in the span of the K = 3 basis (and so is found with
	 * distance 0 at its own weights) */
	for (int o = 0; o < KG_NBANDS; o++)
		spectra[3 * KG_NBANDS + o] =
		    0.9 * ks.basis3[o * 3] + 0.1 * ks.basis3[o * 3 + 1] - 0.05 * ks.basis3[o * 3 + 2];
	kg_est_material mats[NM];
	char names[NM][8];
	for (int j = 0; j < NM; j++) {
		snprintf(names[j], sizeof(names[j]), "m%d", j);
		mats[j] = (kg_est_material){names[j], spectra + j * KG_NBANDS};
	}
	const struct {
		kg_est_kernel *k;
		const double *basis, *mean;
		int kk;
	} cases[] = {{ks.pca, ks.basis3, NULL, 3}, {ks.centred, ks.basis4, ks.mean, 4}};
	for (int ci = 0; ci < 2; ci++)
		for (int dist = 0; dist < 2; dist++) {
			kg_est_classifier *c = NULL;
			kg_err err = {{0}};
			CHECK(kg_est_classifier_new(cases[ci].k, mats, NM, (kg_est_distance)dist, &c, &err) == 0,
			      "classifier: %s", err.msg);
			CHECK(kg_est_classifier_count(c) == NM && !strcmp(kg_est_classifier_name(c, 5), "m5"),
			      "names");
			/* distances of random weights */
			double worst = 0;
			for (int i = 0; i < 2000; i++) {
				float w[4];
				for (int l = 0; l < cases[ci].kk; l++)
					w[l] = (float)fx_uniform(&r, -1, 2);
				double d[NM];
				kg_est_classifier_distances(c, w, d);
				for (int j = 0; j < NM; j++) {
					double e = dense_distance(cases[ci].basis, cases[ci].kk, cases[ci].mean,
					                          spectra + j * KG_NBANDS, w, (kg_est_distance)dist);
					worst = fmax(worst, fabs(d[j] - e) / fmax(e, 1e-3));
					CHECK(fabs(d[j] - e) <= 1e-6 * fmax(e, 1e-3), "distance %d: %.12g vs %.12g", j,
					      d[j], e);
				}
			}
			printf("classifier K=%d %s: worst relative distance error %.3g\n", cases[ci].kk,
			       dist ? "scale-free" : "plain", worst);
			if (ci == 0) {
				float w3[3] = {0.9f, 0.1f, -0.05f};
				double d[NM];
				kg_est_classifier_distances(c, w3, d);
				CHECK(fabs(d[3]) < 1e-12, "a material in the span at its own weights: %.3g", d[3]);
			}

			/* whole images through both implementations: labels and margins */
			enum { N = 3000 };
			float *rgb = fx_image(&r, N, 0.0, 0.98, 0);
			for (int isa = KG_EST_ISA_AUTO; isa <= KG_EST_ISA_C; isa++) {
				kg_est_job job;
				kg_est_job_init(&job, cases[ci].k, KG_EST_LABELS);
				job.classifier = c;
				job.isa = (kg_est_isa)isa;
				uint8_t labels[N];
				float conf[N];
				CHECK(kg_est_run(&job, rgb, N, 1, &(kg_est_dest){labels, conf, NULL}, NULL, &err) == 0,
				      "run: %s", err.msg);
				int ties = 0;
				for (int i = 0; i < N; i++) {
					float w[4];
					kg_est_kernel_eval(cases[ci].k, rgb + 3 * i, job.clip_level, 1, w);
					double best = INFINITY, second = INFINITY, e[NM];
					int lab = 0;
					for (int j = 0; j < NM; j++) {
						e[j] = dense_distance(cases[ci].basis, cases[ci].kk, cases[ci].mean,
						                      spectra + j * KG_NBANDS, w, (kg_est_distance)dist);
					}
					for (int j = 0; j < NM; j++) {
						if (e[j] < best) {
							second = best;
							best = e[j];
							lab = j;
						} else if (e[j] < second) {
							second = e[j];
						}
					}
					if (second - best <= 1e-9 * second) {
						ties++;
						CHECK(labels[i] >= 1 && labels[i] <= NM &&
						          e[labels[i] - 1] - best <= 1e-9 * second,
						      "pixel %d: label %d is not among the tied best", i, labels[i]);
					} else {
						CHECK(labels[i] == lab + 1, "pixel %d: label %d, dense %d", i, labels[i],
						      lab + 1);
					}
					CHECK(fabs(conf[i] - (second - best)) <= 1e-6 * second, "pixel %d margin %.9g vs %.9g",
					      i, (double)conf[i], second - best);
				}
				if (isa == KG_EST_ISA_AUTO)
					printf("  %d of %d pixels tied for the best material\n", ties, N);
			}
			free(rgb);
			kg_est_classifier_free(&c);
		}
	fx_kernels_free(&ks);
}

int main(void)
{
	check_linear_dense();
	check_rootpoly_dense();
	check_rootpoly();
	check_lut();
	check_classification();
	return kg_test_done("estimate numerics");
}
