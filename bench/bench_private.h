/* Inside bench/: the speed loop the whole benchmark calls. Not included from outside. */
#ifndef KG_BENCH_PRIVATE_H
#define KG_BENCH_PRIVATE_H

#include "kg_bench.h"

/* Time every kernel in k (NULL entries skipped) over the image rgb (width x height)
 * for each format it supports and each thread count of cfg, appending speed rows
 * and the matching non-temporal write limits to r. out: one buffer large enough for
 * the largest output (61 float bands), conf: width x height floats. */
int bench_speed_all(const kg_bench_config *cfg, kg_est_kernel *const *k,
                    const kg_est_classifier *cls, const float *rgb, int width, int height,
                    void *out, float *conf, kg_bench_results *r, kg_err *err);

/* The camera-space rows (r->camspace) on cfg->camspace_mpix Mpix; the material
 * library is cfg->materials (none: skipped, no rows), the sensor noise r->noise. */
int bench_camspace(const kg_bench_config *cfg, kg_bench_results *r, kg_err *err);

/* The camera-space rows' models: the library `materials` under the synthetic camera
 * and D65, angles 0-70 degrees every `step` (m) and every degree (fine, the pixels'
 * truth), intensity 0.3-1.0. */
int bench_cs_models(const char *materials, double step, kg_cs_model **m, kg_cs_model **fine,
                    kg_err *err);
/* n noisy readings x (3 each) with their covariances cov (6 each: c00 c01 c02 c11 c12
 * c22) of random materials of `fine` at random angles and intensities, through the
 * sensor `noise`; truth[i] the material of reading i. */
void bench_cs_pixels(const kg_cs_model *fine, const kg_sim_noise *noise, uint64_t seed, size_t n,
                     float *x, float *cov, uint8_t *truth);

/* Append a formatted progress line through cfg->progress. */
void bench_progress(const kg_bench_config *cfg, const char *fmt, ...) KG_PRINTF(2, 3);

#endif
