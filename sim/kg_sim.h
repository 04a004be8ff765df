/* sim/: physically simulated camera readings and scenes for tests, benchmarks and
 * the demo.
 *
 * Camera model. A camera with spectral sensitivities S_c (c = r, g, b) looking at a
 * surface of reflectance R under an illuminant E responds
 *
 *     rho_c = k * sum_lambda E(lambda) R(lambda) S_c(lambda) dlambda
 *
 * over the 61-band grid (dlambda = 5 nm). The exposure k is set so the perfect
 * diffuser (R = 1) gives `white_level` in its brightest channel:
 * k = white_level / max_c sum E S_c dlambda. For a metal the camera sees the
 * specular colour signal E(lambda) R_material(lambda, theta); pass R_material at
 * the incidence angle as the reflectance. Values are on the 0..1 scale of DESIGN.md
 * §4 (1 = full scale).
 *
 * Noise model (kg_sim_noise). The noise-free value v is turned into v * full_well
 * expected photo-electrons; the count is drawn from a Poisson distribution (exact:
 * inversion below a mean of 10, Hormann's PTRS above), Gaussian read noise is added,
 * the result is clipped to [0, full_well] and quantised to 2^bits - 1 levels, so
 *     E[v'] ~ v,  Var[v'] ~ (v * full_well + read^2) / full_well^2 + q^2 / 12,
 *     q = 1 / (2^bits - 1)
 * away from 0 and 1. With noise "none" the value is returned exactly (neither
 * clipped nor quantised). Every draw comes from a kg_rng seeded by the caller:
 * the same seed gives the same output, bit for bit. */
#ifndef KG_SIM_H
#define KG_SIM_H

#include <stddef.h>
#include <stdint.h>

#include "kg_optics.h"

/* ---- random numbers ------------------------------------------------------------ */

/* xoshiro256** seeded through splitmix64. Plain value; no global state. */
typedef struct kg_rng {
	uint64_t s[4];
	double spare; /* second normal deviate of the polar method */
	int has_spare;
} kg_rng;

void kg_rng_seed(kg_rng *r, uint64_t seed);
uint64_t kg_rng_next(kg_rng *r);
/* Uniform on [0, 1), 53 random bits. */
double kg_rng_uniform(kg_rng *r);
/* Standard normal deviate. */
double kg_rng_normal(kg_rng *r);
/* Poisson deviate (a whole number, returned as double); 0 for mean <= 0 or NaN. */
double kg_rng_poisson(kg_rng *r, double mean);

/* ---- sensor noise -------------------------------------------------------------- */

typedef struct kg_sim_noise {
	double full_well;  /* electrons at full scale; 0 = no noise */
	double read_noise; /* electrons rms */
	int bits;          /* 8, 10, 12, 14 or 16 (kg_sim_noise_parse); 0: not quantised */
} kg_sim_noise;

/* Parse "none" or "FULLWELL:READ:BITS", e.g. "20000:5:12". */
int kg_sim_noise_parse(const char *text, kg_sim_noise *out, kg_err *err);
/* The inverse of kg_sim_noise_parse (round-trips exactly). */
void kg_sim_noise_format(const kg_sim_noise *n, char *buf, size_t len);
int kg_sim_noise_enabled(const kg_sim_noise *n);
/* One noisy reading of the noise-free value v (see the model above). */
double kg_sim_noise_apply(const kg_sim_noise *n, double v, kg_rng *rng);

/* ---- inputs -------------------------------------------------------------------- */

/* Reflectance spectra from CGATS (SPEC_<nm> fields) or from a CSV laid out as
 * `patch,name,<nm>,<nm>,...` (the reference charts; chosen by the .csv suffix),
 * resampled to the grid (flags: KG_RESAMPLE_*). A file without spectra is refused. */
int kg_sim_read_spectra(const char *path, unsigned flags, kg_patchset **out, kg_err *err);
/* An illuminant by name (D65, D50, A, E, Dnn, <T>K), from a CGATS file, or from a
 * CSV `wavelength_nm,<relative power>` (by the .csv suffix). */
int kg_sim_illuminant(const char *spec, kg_illuminant **out, kg_err *err);

/* Material samples for a scene: each material's reflectance at one incidence angle
 * (metals and alloys through the library's Fresnel model; dielectrics from their
 * reflectance). */
typedef struct kg_sim_material_set {
	int n;
	char **names;             /* [n] library names */
	kg_spectrum *reflectance; /* [n] at angle_deg */
	double angle_deg;
} kg_sim_material_set;

/* Load a material library and take every material, or only those named in `only`
 * (comma-separated, in that order; an unknown name is refused with the list of
 * known ones). */
int kg_sim_material_set_load(const char *library_path, const char *only, double angle_deg,
                             kg_sim_material_set **out, kg_err *err);
void kg_sim_material_set_free(kg_sim_material_set **s);

/* ---- camera and exposure ------------------------------------------------------- */

typedef struct kg_sim_camera {
	char name[128];         /* file name without folder and extension */
	kg_spectrum sens[3];    /* r, g, b sensitivities on the grid */
} kg_sim_camera;

/* Read CSV `wavelength_nm,r,g,b` (any increasing wavelengths) and resample onto the
 * grid. Data not covering 400-700 nm are refused unless flags holds
 * KG_RESAMPLE_EXTRAPOLATE. Negative or non-finite sensitivities are refused. */
int kg_sim_camera_load(const char *path, unsigned flags, kg_sim_camera *cam, kg_err *err);

/* A camera, an illuminant and an exposure: everything needed to turn a reflectance
 * into a reading. Plain value. */
typedef struct kg_sim_capture {
	kg_spectrum weight[3]; /* k E(lambda) S_c(lambda) dlambda: rho_c = sum weight_c R */
	kg_spectrum signal_weight[3]; /* k S_c(lambda) dlambda: rho_c = sum signal_weight_c C
	                               * for a colour signal C in the illuminant's units */
	double exposure;       /* k */
	double white_level;
	kg_sim_noise noise;
} kg_sim_capture;

/* white_level in (0, 1] is usual; larger values are allowed and clip under noise.
 * noise may be NULL (noise-free). Fails if the camera sees nothing of the
 * illuminant (all responses to the perfect diffuser are 0). */
int kg_sim_capture_init(kg_sim_capture *c, const kg_sim_camera *cam,
                        const kg_spectrum *illuminant, double white_level,
                        const kg_sim_noise *noise, kg_err *err);
/* Noise-free response to a reflectance (or to a specular reflectance R(lambda,
 * theta), giving the camera's view of the colour signal E R). */
void kg_sim_capture_mean(const kg_sim_capture *c, const kg_spectrum *reflectance,
                         double rgb[3]);
/* Noise-free response to a colour signal C(lambda) = E(lambda) R(lambda, geometry)
 * on the illuminant's scale (e.g. from a renderer): the same exposure, so C = E
 * reads the white level. */
void kg_sim_capture_signal_mean(const kg_sim_capture *c, const kg_spectrum *signal,
                                double rgb[3]);
/* One noisy reading (r, g and b drawn in that order from rng). */
void kg_sim_capture_sample(const kg_sim_capture *c, const kg_spectrum *reflectance,
                           kg_rng *rng, double rgb[3]);

/* One reading per spectrum into rgb[3 * i + c], all draws from one kg_rng seeded
 * with seed, patches in order. */
void kg_sim_patches(const kg_sim_capture *c, const kg_spectrum *spectra, int n,
                    uint64_t seed, double *rgb);

/* kg_sim_camera_load + kg_sim_illuminant + kg_sim_capture_init (flags apply to the
 * camera file). */
int kg_sim_capture_load(kg_sim_capture *c, const char *camera_path,
                        const char *illuminant_spec, double white_level,
                        const kg_sim_noise *noise, unsigned flags, kg_err *err);
/* kg_sim_patches over a patch set's spectra, written atomically as CGATS with
 * SAMPLE_ID (the patch set's ids) and RGB_R RGB_G RGB_B. keywords: NULL or a
 * NULL-terminated list of name, value pairs (camera, illuminant, noise, seed...). */
int kg_sim_write_patches(const char *path, const kg_patchset *spectra,
                         const kg_sim_capture *c, uint64_t seed,
                         const char *const *keywords, kg_err *err);

/* ---- scenes -------------------------------------------------------------------- */

/* What goes into a scene: chart patches (one class, "chart") and material samples
 * (one class each, named after the material), laid out row by row on a grid of
 * square tiles separated by background. The chart comes first; the materials start
 * on a new row. */
typedef struct kg_sim_scene_desc {
	const kg_spectrum *patches;       /* reflectance of each chart patch */
	const char *const *patch_names;   /* SAMPLE_IDs */
	int npatches;
	const kg_spectrum *materials;     /* reflectance of each material (at the angle) */
	const char *const *material_names;
	int nmaterials;
	int tile;                         /* tile side in pixels (>= 1) */
	int gap;                          /* background between and around tiles (>= 0) */
	int columns;                      /* tiles per row (>= 1) */
	double background;                /* flat reflectance of the background */
} kg_sim_scene_desc;

/* Class 0 of every scene; background pixels carry it. */
#define KG_SIM_UNCLASSIFIED "unclassified"
/* The one class of all chart patches. */
#define KG_SIM_CHART_CLASS "chart"

typedef struct kg_sim_scene {
	int width, height;
	int nsamples;           /* patches then materials */
	kg_spectrum *truth;     /* [nsamples] true reflectance of each sample */
	char **sample_names;    /* [nsamples] */
	int *sample_class;      /* [nsamples] class of each sample */
	int nclasses;           /* 1 (unclassified) + materials (+ 1 chart if any patches) */
	char **class_names;     /* [nclasses]: unclassified, materials..., chart */
	kg_spectrum background; /* reflectance of background pixels */
	int32_t *sample;        /* [width*height] sample index of each pixel, -1 background */
	uint16_t *label;        /* [width*height] class of each pixel, 0 background */
	float *rgb;             /* [width*height*3] interleaved camera values, 0..1 scale */
} kg_sim_scene;

/* Lay out and render a scene: every pixel is drawn independently through the
 * capture's noise, in raster order, from one kg_rng seeded with seed. */
int kg_sim_scene_new(const kg_sim_scene_desc *d, const kg_sim_capture *c, uint64_t seed,
                     kg_sim_scene **out, kg_err *err);
void kg_sim_scene_free(kg_sim_scene **s);

/* Image depths for kg_sim_scene_write_image. */
enum kg_sim_depth { KG_SIM_DEPTH_U8 = 8, KG_SIM_DEPTH_U16 = 16, KG_SIM_DEPTH_F32 = 32 };
/* "8", "16" or "float". */
int kg_sim_depth_parse(const char *text, enum kg_sim_depth *out, kg_err *err);

/* Write the camera image (3 samples, linear) atomically as TIFF (or PNG for 8 and
 * 16 bits, by the extension): integers are the values times full scale (255 or
 * 65535), rounded and clipped; float as is. */
int kg_sim_scene_write_image(const kg_sim_scene *s, const char *path,
                             enum kg_sim_depth depth, kg_err *err);
/* Write the true reflectance as an ENVI cube (float32, 61 bands, BSQ, wavelengths
 * in nm); background pixels hold the background reflectance. */
int kg_sim_scene_write_truth_cube(const kg_sim_scene *s, const char *hdr_path,
                                  kg_err *err);
/* Write the label map as an ENVI classification file (class names = scene classes,
 * 0 = unclassified). */
int kg_sim_scene_write_labels(const kg_sim_scene *s, const char *hdr_path, kg_err *err);
/* The image and, when their paths are not NULL, the truth cube and the label map.
 * Each file is written atomically; if a later one fails, the ones already written
 * are removed, so a failed call leaves no partial set behind. */
int kg_sim_scene_write(const kg_sim_scene *s, const char *image_path,
                       enum kg_sim_depth depth, const char *truth_cube_path,
                       const char *labels_path, kg_err *err);

#endif
