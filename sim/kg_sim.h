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
 * the incidence angle as the reflectance. Values are linear on a 0..1 scale (1 = full
 * scale), as every camera value in kogei.
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
/* kg_sim_noise_apply on every sample of an image in place (e.g. a rendered camera
 * image), row by row, each row drawing from its own kg_rng seeded from (seed, row),
 * samples in order: the same seed gives the same bytes. Nothing changes when the
 * noise is "none". */
void kg_sim_noise_image(const kg_sim_noise *n, kg_image *img, uint64_t seed);

/* ---- inputs -------------------------------------------------------------------- */

/* Reflectance spectra from CGATS (SPEC_<nm> fields) or from a CSV laid out as
 * `patch,name,<nm>,<nm>,...` (the reference charts; chosen by the .csv suffix),
 * resampled to the grid (flags: KG_RESAMPLE_*), each value a reflectance
 * (KG_PATCH_REFLECTANCE). A file without spectra is refused. */
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
	double flare; /* veiling glare: a fraction of each channel's reading of the perfect
	               * diffuser added to every reading before the noise (0: none) */
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
	int width, height;                /* the image, the grid centred in it; 0: the
	                                   * grid's own size */
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

/* ==== Chart scenes (chart_scene.c) ================================================ */

/* A photograph of printed chart cards: each card is a flat rectangle of paper in
 * millimetres (x right, y down, origin at its top-left corner) carrying black-and-
 * white tag bit grids, colour patches and, optionally, occluders and specular glare,
 * seen through a pinhole camera at a pose. The renderer is plain geometry: it knows
 * nothing of chart layout files (calib/ turns those into this description).
 *
 * Pixel coordinates are continuous: pixel (x, y) covers [x, x+1) x [y, y+1), so its
 * centre is (x + 0.5, y + 0.5); the principal point is the image centre
 * (width/2, height/2). The camera looks along +z with image x right and y down.
 *
 * Rendering, in order: (1) each output pixel is inverse-mapped through the card
 * homographies; a pixel whose four corners fall in the same uniform region (the
 * same patch, tag cell, occluder, paper or background) takes that region's colour,
 * any other pixel is the mean of supersample x supersample samples (anti-aliased
 * edges); (2) glare is added (smooth, evaluated at the pixel centre); (3) the
 * pixel is multiplied by the vignetting v(r) = (1 + a (r / r_corner)^2)^-2, the cos^4
 * law of a lens whose corners lose the fraction `vignetting` of the light
 * (a = (1 - vignetting)^-1/2 - 1); (4) a Gaussian lens blur of blur_sigma pixels
 * (separable, edges clamped); (5) optionally a Bayer mosaic (one sample per pixel);
 * (6) sensor noise through the capture's noise model (kg_sim_noise_apply), every
 * image row drawing from its own kg_rng seeded from (seed, row), so the image is
 * the same bit for bit for a seed whatever the number of threads.
 *
 * Truth. The value a perfect sampler of a patch's inner region finds in the noise-
 * free image: the patch colour (capture response to its reflectance, or its given
 * RGB) times the vignetting at the image position of the patch centre. Blur does
 * not reach an inner region away from the edges; vignetting varies across a patch
 * only to second order about its centre: the mean over a square of half-side h
 * (in units of the centre-to-corner distance) differs from the centre value by at
 * most about 8 a h^2 / 6 relative, 6e-4 for h = 0.034 (a 24-patch chart filling a
 * frame, half of each side sampled) at vignetting 0.5. Glare and occluders are not
 * in the truth: the patches they touch are flagged instead. */

/* A tag's bit grid printed on a card. */
typedef struct kg_sim_chart_tag {
	/* Card positions (mm) of the grid's outer corners: grid (0,0), (cells,0),
	 * (cells,cells), (0,cells), i.e. top-left, top-right, bottom-right, bottom-left
	 * of the bit array as stored. */
	double corner_mm[4][2];
	int cells;                 /* cells per side */
	const unsigned char *bits; /* cells * cells, row-major: 1 white (paper), 0 black */
} kg_sim_chart_tag;

/* A colour patch: an axis-aligned rectangle on the card. */
typedef struct kg_sim_chart_patch {
	const char *id;                 /* SAMPLE_ID (may be NULL) */
	double centre_mm[2], size_mm[2];
	const kg_spectrum *reflectance; /* seen through the capture; NULL: rgb */
	double rgb[3];                  /* camera values (0..1) when reflectance is NULL */
} kg_sim_chart_patch;

/* A dark (or any colour) rectangle in front of the card, in card mm: a hand, a
 * clip, a cable. */
typedef struct kg_sim_chart_occluder {
	double x0_mm, y0_mm, x1_mm, y1_mm;
	double reflectance; /* flat */
} kg_sim_chart_occluder;

/* Specular glare: light added over an ellipse on the card,
 * amplitude * exp(-((u/ru)^2 + (v/rv)^2) / 2) within 3 radii, (u, v) the card
 * position relative to the centre, rotated by angle_deg. */
typedef struct kg_sim_chart_glare {
	double centre_mm[2], radius_mm[2], angle_deg;
	double amplitude;   /* 0..1 scale */
} kg_sim_chart_glare;

/* Where a card is: rotated by rotate_deg in its plane (about its centre, clockwise
 * in the image), then tilted by tilt_deg about an axis in the card plane at
 * tilt_axis_deg from the image x axis, its centre at (offset_mm[0], offset_mm[1],
 * distance_mm) in camera coordinates. */
typedef struct kg_sim_chart_pose {
	double rotate_deg, tilt_deg, tilt_axis_deg;
	double distance_mm, offset_mm[2];
} kg_sim_chart_pose;

typedef struct kg_sim_chart_card {
	double size_mm[2];
	double paper, ink;   /* flat reflectances of the card and of black tag cells */
	const kg_sim_chart_tag *tags;
	int ntags;
	const kg_sim_chart_patch *patches;
	int npatches;
	const kg_sim_chart_occluder *occluders;
	int noccluders;
	const kg_sim_chart_glare *glare;
	int nglare;
	kg_sim_chart_pose pose;
} kg_sim_chart_card;

typedef struct kg_sim_chart_desc {
	int width, height;
	double focal_px;       /* focal length in pixels (> 0; kg_sim_chart_focal_px) */
	const kg_sim_chart_card *cards; /* drawn in order: later cards cover earlier */
	int ncards;            /* 0 is allowed: an image without a chart */
	double background;     /* flat reflectance outside the cards */
	int supersample;       /* samples per side at edges, 1..16 (4 is usual) */
	double blur_sigma;     /* Gaussian lens blur in pixels, >= 0 */
	double vignetting;     /* light lost at the image corners, 0 <= v < 1 */
	const char *cfa;       /* NULL: RGB image; "RGGB", "BGGR", "GRBG" or "GBRG": a
	                        * one-sample Bayer mosaic carrying that CFA pattern */
	int threads;           /* 0: one per online CPU (at most 64) */
	uint64_t seed;
} kg_sim_chart_desc;

/* The truth about one patch. */
typedef struct kg_sim_chart_truth {
	int card, patch;      /* indices into the description */
	double rgb[3];        /* truth (see above) */
	double flat_rgb[3];   /* the patch colour without vignetting */
	double vignetting;    /* at the centre */
	double centre_px[2];  /* image position of the patch centre */
	int occluded;         /* an occluder overlaps the patch */
	int glare;            /* glare within 3 radii overlaps the patch */
	int visible;          /* the centre is inside the image */
} kg_sim_chart_truth;

typedef struct kg_sim_chart_result {
	kg_image *image;      /* linear, 0..1: 3 samples, or 1 with the CFA attached */
	int ncards;
	double (*homography)[9]; /* per card, card mm -> pixel, row-major, H[8] = 1 */
	int ntruth;
	kg_sim_chart_truth *truth; /* every patch of every card, card by card */
	double seconds;       /* wall time of the rendering */
} kg_sim_chart_result;

/* A focal length in pixels for a horizontal field of view (degrees, 1..170). */
double kg_sim_chart_focal_px(int width, double hfov_deg);
/* The homography (card mm -> pixel) of a card of size_mm at a pose. */
void kg_sim_chart_homography(const kg_sim_chart_pose *pose, const double size_mm[2],
                             double focal_px, int width, int height, double H[9]);
/* Apply a homography to a point. */
void kg_sim_chart_project(const double H[9], const double in[2], double out[2]);
/* Choose pose->distance_mm and offset_mm (keeping its angles) so the projected card
 * fills `fill` (0..1] of the box (x0, y0, x1, y1 in pixels) in its tighter
 * direction, centred in it. Fails when the tilt makes that impossible (the card
 * would reach behind the camera). */
int kg_sim_chart_pose_fit(kg_sim_chart_pose *pose, const double size_mm[2],
                          double focal_px, int width, int height, const double box[4],
                          double fill, kg_err *err);

/* Render a chart scene through a capture (exposure and noise; spectra of the
 * patches, paper, ink, occluders and background are read through it). */
int kg_sim_chart_render(const kg_sim_chart_desc *d, const kg_sim_capture *c,
                        kg_sim_chart_result **out, kg_err *err);
void kg_sim_chart_result_free(kg_sim_chart_result **r);

/* The truth of one card as CGATS (atomically): SAMPLE_ID RGB_R RGB_G RGB_B
 * FLAT_R FLAT_G FLAT_B VIGNETTING PIXEL_X PIXEL_Y OCCLUDED GLARE, keyword HOMOGRAPHY
 * (nine numbers, row-major), then the caller's keywords (NULL or a NULL-terminated
 * list of name, value pairs). Patches without an id are named by their 1-based
 * index. */
int kg_sim_chart_write_truth(const kg_sim_chart_result *r, const kg_sim_chart_desc *d,
                             int card, const char *path, const char *const *keywords,
                             kg_err *err);

/* ==== end of chart_scene.c ======================================================== */

#endif
