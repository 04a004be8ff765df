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

/* Append a formatted progress line through cfg->progress. */
void bench_progress(const kg_bench_config *cfg, const char *fmt, ...) KG_PRINTF(2, 3);

#endif
