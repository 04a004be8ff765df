/* The camera-space rows: kg_cs_match_block_method over a synthetic image, each method
 * (exact, quadratic) in each implementation the CPU has (C, AVX2, AVX-512) on each
 * thread count; whether each writes its method's C reference's bytes, and how often the
 * quadratic method's labels and outputs are the exact reference's.
 *
 * Model: the library's materials under the synthetic camera (Gaussian sensitivities,
 * kg_bench_synthetic_camera) and CIE D65, white at KG_BENCH_WHITE_LEVEL, angles 0 to 70
 * degrees every 5 (15; kogei bench --camspace-step), intensity 0.3 to 1.0. Pixels: a random material at a random
 * angle in [0, 70] (every degree, so mostly between the model's angles) and a random
 * intensity in [0.3, 1.0], with the noise of the bench's sensor (full well, read
 * noise) on the camera's channels mapped through a colour matrix with cross terms,
 * so every pixel has its own full 3 x 3 covariance; the reading is drawn from it. */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "bench_private.h"

#define CS_ANGLE_TO 70.0
#define CS_ANGLE_STEP 5.0
#define CS_LO 0.3
#define CS_HI 1.0
#define CS_MAX_THREADS 64

/* The site-to-reference matrix the noise goes through (rows sum to 1). */
static const double cs_m2[9] = {
	1.25, -0.18, -0.07,
	-0.12, 1.20, -0.08,
	0.02, -0.25, 1.23,
};

typedef struct cs_share {
	const kg_cs_model *m;
	const float *x, *cov;
	size_t n;
	kg_cs_block out;
	kg_cs_method method;
	kg_est_isa isa;
	int ret;
	pthread_t thread;
} cs_share;

static void *cs_share_main(void *arg)
{
	cs_share *s = arg;
	s->ret = kg_cs_match_block_method(s->m, s->x, s->cov, s->n, &s->out, s->method, s->isa);
	return NULL;
}

static float *offset(float *p, size_t i, size_t per)
{
	return p ? p + i * per : NULL;
}

/* One run over n pixels on `threads` threads (created for the run, as kg_est_run
 * does), each a contiguous share of whole vectors (32 pixels: two of AVX-512). */
static int cs_run(const kg_cs_model *m, const float *x, const float *cov, size_t n,
                  const kg_cs_block *out, kg_cs_method method, kg_est_isa isa, int threads)
{
	cs_share sh[CS_MAX_THREADS];
	int created[CS_MAX_THREADS] = {0};
	threads = threads < 1 ? 1 : threads > CS_MAX_THREADS ? CS_MAX_THREADS : threads;
	size_t per = ((n + (size_t)threads - 1) / (size_t)threads + 31) & ~(size_t)31;
	for (int t = 0; t < threads; t++) {
		size_t at = per * (size_t)t < n ? per * (size_t)t : n;
		size_t len = n - at < per ? n - at : per;
		sh[t] = (cs_share){m, x + 3 * at, cov + 6 * at, len,
		                   {out->best + at, offset(out->d2best, at, 1),
		                    offset(out->d2second, at, 1), offset(out->angle_deg, at, 1),
		                    offset(out->scale, at, 1), offset(out->d2, at, (size_t)m->n)},
		                   method, isa, 0, 0};
	}
	for (int t = 1; t < threads; t++) {
		created[t] = pthread_create(&sh[t].thread, NULL, cs_share_main, &sh[t]) == 0;
		if (!created[t])
			cs_share_main(&sh[t]);
	}
	cs_share_main(&sh[0]);
	int ret = 0;
	for (int t = 0; t < threads; t++) {
		if (t && created[t])
			pthread_join(sh[t].thread, NULL);
		ret = ret ? ret : sh[t].ret;
	}
	return ret;
}

/* The pixels: readings and covariances, and the material each was drawn from. */
void bench_cs_pixels(const kg_cs_model *fine, const kg_sim_noise *noise, uint64_t seed,
                      size_t n, float *x, float *cov, uint8_t *truth)
{
	kg_rng rng;
	kg_rng_seed(&rng, seed);
	const double fw = noise->full_well, rn = noise->read_noise;
	for (size_t i = 0; i < n; i++) {
		int j = (int)(kg_rng_next(&rng) % (uint64_t)fine->n);
		int k = (int)(kg_rng_next(&rng) % (uint64_t)fine->nangles);
		double a = CS_LO + (CS_HI - CS_LO) * kg_rng_uniform(&rng);
		const double *mu = fine->mu + 3 * ((size_t)j * fine->nangles + k);
		/* the camera channel's variance at its level (photons and read noise, in
		 * units of full scale), through the matrix */
		double var[3], C[9];
		for (int c = 0; c < 3; c++)
			var[c] = (fmax(a * mu[c], 0) * fw + rn * rn) / (fw * fw);
		for (int p = 0; p < 3; p++)
			for (int q = 0; q < 3; q++) {
				double s = 0;
				for (int c = 0; c < 3; c++)
					s += cs_m2[p * 3 + c] * var[c] * cs_m2[q * 3 + c];
				C[p * 3 + q] = s;
			}
		double l0 = sqrt(C[0]), l3 = C[3] / l0, l6 = C[6] / l0;
		double l4 = sqrt(C[4] - l3 * l3), l7 = (C[7] - l6 * l3) / l4;
		double l8 = sqrt(C[8] - l6 * l6 - l7 * l7);
		double z0 = kg_rng_normal(&rng), z1 = kg_rng_normal(&rng), z2 = kg_rng_normal(&rng);
		x[3 * i + 0] = (float)(a * mu[0] + l0 * z0);
		x[3 * i + 1] = (float)(a * mu[1] + l3 * z0 + l4 * z1);
		x[3 * i + 2] = (float)(a * mu[2] + l6 * z0 + l7 * z1 + l8 * z2);
		static const int tri[6] = {0, 1, 2, 4, 5, 8};
		for (int q = 0; q < 6; q++)
			cov[6 * i + q] = (float)C[tri[q]];
		truth[i] = (uint8_t)j;
	}
}

typedef struct cs_out {
	uint8_t *best;
	float *d2best, *d2second, *angle, *scale, *d2;
} cs_out;

static int cs_out_alloc(cs_out *o, size_t n, int nm, int with_d2)
{
	o->best = malloc(n);
	o->d2best = malloc(sizeof(float) * n);
	o->d2second = malloc(sizeof(float) * n);
	o->angle = malloc(sizeof(float) * n);
	o->scale = malloc(sizeof(float) * n);
	o->d2 = with_d2 ? malloc(sizeof(float) * n * (size_t)nm) : NULL;
	if (!o->best || !o->d2best || !o->d2second || !o->angle || !o->scale ||
	    (with_d2 && !o->d2))
		return -1;
	/* fault the pages in: that cost belongs to no kernel */
	memset(o->best, 0, n);
	memset(o->d2best, 0, sizeof(float) * n);
	memset(o->d2second, 0, sizeof(float) * n);
	memset(o->angle, 0, sizeof(float) * n);
	memset(o->scale, 0, sizeof(float) * n);
	if (o->d2)
		memset(o->d2, 0, sizeof(float) * n * (size_t)nm);
	return 0;
}

static void cs_out_free(cs_out *o)
{
	free(o->best);
	free(o->d2best);
	free(o->d2second);
	free(o->angle);
	free(o->scale);
	free(o->d2);
	memset(o, 0, sizeof(*o));
}

static kg_cs_block cs_block(const cs_out *o)
{
	return (kg_cs_block){o->best, o->d2best, o->d2second, o->angle, o->scale, o->d2};
}

static int cs_same(const cs_out *a, const cs_out *b, size_t n, int nm)
{
	return !memcmp(a->best, b->best, n) && !memcmp(a->d2best, b->d2best, 4 * n) &&
	       !memcmp(a->d2second, b->d2second, 4 * n) && !memcmp(a->angle, b->angle, 4 * n) &&
	       !memcmp(a->scale, b->scale, 4 * n) &&
	       (!a->d2 || !memcmp(a->d2, b->d2, 4 * n * (size_t)nm));
}

/* Pixel i's every output in a and b: the same bytes. */
static int cs_same_pixel(const cs_out *a, const cs_out *b, size_t i, int nm)
{
	return a->best[i] == b->best[i] && !memcmp(a->d2best + i, b->d2best + i, 4) &&
	       !memcmp(a->d2second + i, b->d2second + i, 4) &&
	       !memcmp(a->angle + i, b->angle + i, 4) && !memcmp(a->scale + i, b->scale + i, 4) &&
	       !memcmp(a->d2 + i * (size_t)nm, b->d2 + i * (size_t)nm, 4 * (size_t)nm);
}

/* The model's F: the synthetic camera's weights under D65. */
static int cs_response(double F[3 * KG_NBANDS], kg_err *err)
{
	kg_sim_camera cam;
	kg_bench_synthetic_camera(&cam);
	kg_illuminant *d65 = NULL;
	int ret = kg_illuminant_by_name("D65", &d65, err);
	kg_sim_capture cap;
	if (!ret)
		ret = kg_sim_capture_init(&cap, &cam, &d65->spd, KG_BENCH_WHITE_LEVEL, NULL, err);
	kg_illuminant_free(&d65);
	for (int c = 0; !ret && c < 3; c++)
		memcpy(F + c * KG_NBANDS, cap.weight[c].v, sizeof(cap.weight[c].v));
	return ret;
}

int bench_cs_models(const char *materials, double step, kg_cs_model **m, kg_cs_model **fine,
                    kg_err *err)
{
	kg_material_library *lib = NULL;
	const kg_material *mats[KG_EST_MAX_MATERIALS];
	double F[3 * KG_NBANDS];
	*m = *fine = NULL;
	int ret = kg_material_library_load(materials, &lib, err);
	if (!ret)
		ret = cs_response(F, err);
	if (ret)
		goto done;
	int n = kg_material_library_count(lib);
	if (n > KG_EST_MAX_MATERIALS)
		n = KG_EST_MAX_MATERIALS;
	for (int j = 0; j < n; j++)
		mats[j] = kg_material_library_get(lib, j);
	ret = kg_cs_model_new(F, mats, n, 0, CS_ANGLE_TO, step, CS_LO, CS_HI, m, err);
	if (!ret)
		ret = kg_cs_model_new(F, mats, n, 0, CS_ANGLE_TO, 1.0, CS_LO, CS_HI, fine, err);
	if (ret)
		kg_cs_model_free(m);
done:
	kg_material_library_free(&lib);
	return ret;
}

int bench_camspace(const kg_bench_config *cfg, kg_bench_results *r, kg_err *err)
{
	kg_bench_camspace *cs = &r->camspace;
	kg_cs_model *m = NULL, *fine = NULL;
	float *x = NULL, *cov = NULL;
	uint8_t *truth = NULL;
	cs_out ref = {0}, quad = {0}, vec = {0}, timed = {0};
	int ret;
	if (!cfg->materials) {
		bench_progress(cfg, "[camspace] skipped: no material library");
		return 0;
	}
	double step = cfg->camspace_step > 0 ? cfg->camspace_step : CS_ANGLE_STEP;
	ret = bench_cs_models(cfg->materials, step, &m, &fine, err);
	if (ret)
		goto done;
	size_t npix = (size_t)(cfg->camspace_mpix * 1e6 + 0.5);
	if (npix < 8)
		npix = 8;
	cs->pixels = (long)npix;
	cs->materials = m->n;
	cs->angles = m->nangles;
	cs->angle_to = CS_ANGLE_TO;
	cs->lo = CS_LO;
	cs->hi = CS_HI;
	x = malloc(sizeof(float) * 3 * npix);
	cov = malloc(sizeof(float) * 6 * npix);
	truth = malloc(npix);
	if (!x || !cov || !truth || cs_out_alloc(&ref, npix, m->n, 1) ||
	    cs_out_alloc(&quad, npix, m->n, 1) || cs_out_alloc(&vec, npix, m->n, 1) ||
	    cs_out_alloc(&timed, npix, m->n, 0)) {
		ret = kg_fail(err, KG_ENOMEM, "bench: out of memory for the camera-space rows");
		goto done;
	}
	bench_cs_pixels(fine, &r->noise, r->seed + 7, npix, x, cov, truth);

	/* agreement, every output including each material's distance: each path against
	 * its method's C reference and against the exact one */
	static const struct {
		kg_cs_method method;
		kg_est_isa isa;
		const char *name;
	} paths[KG_BENCH_CS_PATHS] = {
		{KG_CS_EXACT, KG_EST_ISA_C, "exact c"},
		{KG_CS_EXACT, KG_EST_ISA_AVX2, "exact avx2"},
		{KG_CS_EXACT, KG_EST_ISA_AVX512, "exact avx512"},
		{KG_CS_QUADRATIC, KG_EST_ISA_C, "quad c"},
		{KG_CS_QUADRATIC, KG_EST_ISA_AVX2, "quad avx2"},
		{KG_CS_QUADRATIC, KG_EST_ISA_AVX512, "quad avx512"},
	};
	kg_cs_block bref = cs_block(&ref), bquad = cs_block(&quad), bvec = cs_block(&vec);
	ret = cs_run(m, x, cov, npix, &bref, KG_CS_EXACT, KG_EST_ISA_C, 1);
	if (!ret)
		ret = cs_run(m, x, cov, npix, &bquad, KG_CS_QUADRATIC, KG_EST_ISA_C, 1);
	if (ret)
		goto done;
	long right = 0, right_quad = 0, refused = 0;
	for (size_t i = 0; i < npix; i++) {
		right += ref.best[i] == truth[i];
		right_quad += quad.best[i] == truth[i];
		refused += ref.best[i] == KG_CS_NO_MATCH;
	}
	cs->accuracy = (double)right / (double)npix;
	cs->accuracy_quad = (double)right_quad / (double)npix;
	cs->refused = refused;
	bench_progress(cfg, "[camspace] %zu pixels, %d materials x %d angles: labels right %.4f "
	               "(exact), %.4f (quadratic)", npix, m->n, m->nangles, cs->accuracy,
	               cs->accuracy_quad);
	for (int q = 0; q < KG_BENCH_CS_PATHS; q++) {
		kg_bench_camspace_path *pa = &cs->paths[q];
		pa->method = paths[q].method;
		pa->isa = paths[q].isa;
		const cs_out *own = pa->method == KG_CS_EXACT ? &ref : &quad;
		const cs_out *got = own;
		if (pa->isa != KG_EST_ISA_C) {
			if (cs_run(m, x, cov, npix, &bvec, pa->method, pa->isa, 1))
				continue;
			got = &vec;
		}
		pa->supported = 1;
		pa->identical = cs_same(own, got, npix, m->n);
		long labels = 0, all = 0;
		for (size_t i = 0; i < npix; i++) {
			labels += got->best[i] == ref.best[i];
			all += cs_same_pixel(&ref, got, i, m->n);
		}
		pa->labels_agree = (double)labels / (double)npix;
		pa->all_agree = (double)all / (double)npix;
		bench_progress(cfg, "[camspace] %-12s: %s its method's C reference; labels of the "
		               "exact C %.6f, every output %.6f", paths[q].name,
		               pa->identical ? "bit-identical to" : "DIFFERS from", pa->labels_agree,
		               pa->all_agree);
	}

	/* speed: best, both distances, angle and intensity (no per-material distances) */
	int reps = cfg->reps < 1 ? 1 : (cfg->reps > 64 ? 64 : cfg->reps);
	kg_bench_camspace_row *rows =
	    calloc((size_t)(KG_BENCH_CS_PATHS * cfg->nthreads), sizeof(*rows));
	if (!rows) {
		ret = kg_fail(err, KG_ENOMEM, "bench: out of memory");
		goto done;
	}
	cs->rows = rows;
	kg_cs_block bt = cs_block(&timed);
	for (int q = 0; q < KG_BENCH_CS_PATHS && !ret; q++)
		for (int ti = 0; ti < cfg->nthreads && cs->paths[q].supported && !ret; ti++) {
			const kg_cs_method method = paths[q].method;
			const kg_est_isa isa = paths[q].isa;
			int threads = cfg->threads[ti] > CS_MAX_THREADS ? CS_MAX_THREADS : cfg->threads[ti];
			double t[64];
			ret = cs_run(m, x, cov, npix, &bt, method, isa, threads); /* warm-up */
			for (int i = 0; i < reps && !ret; i++) {
				double t0 = kg_bench_now();
				ret = cs_run(m, x, cov, npix, &bt, method, isa, threads);
				t[i] = kg_bench_now() - t0;
			}
			if (ret)
				break;
			kg_bench_camspace_row *row = &cs->rows[cs->nrows++];
			row->path = q;
			row->threads = threads;
			row->seconds = kg_bench_percentile(t, reps, 0.5);
			row->mpix_s = (double)npix / row->seconds * 1e-6;
			bench_progress(cfg, "[camspace] %-12s %d thread%s: %7.2f Mpix/s", paths[q].name,
			               threads, threads == 1 ? " " : "s", row->mpix_s);
		}
done:
	kg_cs_model_free(&m);
	kg_cs_model_free(&fine);
	free(x);
	free(cov);
	free(truth);
	cs_out_free(&ref);
	cs_out_free(&quad);
	cs_out_free(&vec);
	cs_out_free(&timed);
	return ret;
}
