/* The 61-band grid (400-700 nm, 5 nm) and the spectrum value type. */
#ifndef KG_SPECTRUM_H
#define KG_SPECTRUM_H

#include "error.h"

#define KG_NBANDS 61
#define KG_LAMBDA_MIN 400.0
#define KG_LAMBDA_MAX 700.0
#define KG_LAMBDA_STEP 5.0

static inline double kg_band_nm(int i) { return KG_LAMBDA_MIN + KG_LAMBDA_STEP * i; }

/* A spectrum on the grid: reflectance, radiance or any per-band quantity. A plain
 * value: copy it by assignment. */
typedef struct kg_spectrum {
	double v[KG_NBANDS];
} kg_spectrum;

/* Flags for resampling. */
enum {
	KG_RESAMPLE_EXTRAPOLATE = 1 << 0, /* hold the end values beyond the data's range */
};

/* Resample samples (wl[i] nm, strictly increasing, val[i]) onto the grid. Data
 * sampled more finely than 5 nm are averaged over each band (triangular weights);
 * coarser data are interpolated linearly. Data that do not cover 400-700 nm are
 * refused (KG_ERANGE, message names the range found) unless
 * KG_RESAMPLE_EXTRAPOLATE is given. `what` names the data in messages. */
int kg_spectrum_resample(const double *wl, const double *val, int n, unsigned flags,
                         const char *what, kg_spectrum *out, kg_err *err);

/* Linear interpolation of samples at one wavelength (holds end values outside). */
double kg_samples_interp(const double *wl, const double *val, int n, double at);

kg_spectrum kg_spectrum_const(double c);
kg_spectrum kg_spectrum_add(const kg_spectrum *a, const kg_spectrum *b);
kg_spectrum kg_spectrum_sub(const kg_spectrum *a, const kg_spectrum *b);
kg_spectrum kg_spectrum_mul(const kg_spectrum *a, const kg_spectrum *b);
kg_spectrum kg_spectrum_scale(const kg_spectrum *a, double s);
/* a + s*b */
kg_spectrum kg_spectrum_axpy(const kg_spectrum *a, double s, const kg_spectrum *b);
double kg_spectrum_dot(const kg_spectrum *a, const kg_spectrum *b);
double kg_spectrum_max(const kg_spectrum *a);
/* Root-mean-square difference over the bands. */
double kg_spectrum_rmse(const kg_spectrum *a, const kg_spectrum *b);
/* Goodness-of-fit coefficient |a.b| / (|a| |b|) (1 = same shape). */
double kg_spectrum_gfc(const kg_spectrum *a, const kg_spectrum *b);
/* 1 if every band is finite. */
int kg_spectrum_isfinite(const kg_spectrum *a);

#endif
