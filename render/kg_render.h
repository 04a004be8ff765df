/* The public header of the offline renderer (render/): a scene (the handoff format,
 * docs/render.md) rendered spectrally with Embree 3 into CIE 1931 XYZ (or any three
 * spectral weightings, e.g. a camera's sensitivities), then written as an sRGB PNG
 * and a linear float TIFF, with optional truth maps of the primary hits.
 *
 * Scene files are JSON, "format": "kogei-scene/1": a mesh (PLY or a built-in
 * generator), its materials (one library material, per-face or per-vertex ids, or a
 * label map projected from a camera), a directional light and/or an environment, a
 * camera and the sampling. Rendering needs Embree (HAVE_EMBREE); without it
 * kg_render_available() is 0 and kg_render refuses with KG_ENOTSUP.
 *
 * Image scale: XYZ relative to the scene's white (the illuminant of the directional
 * light, else of the environment), Y = 1 for a perfect white diffuser lit by a light
 * of intensity 1. */
#ifndef KG_RENDER_H
#define KG_RENDER_H

#include <stdint.h>

#include "kg_core.h"
#include "kg_mesh.h"
#include "kg_optics.h"

typedef struct kg_scene kg_scene;

/* Read and check a scene file, its mesh, material library, label map, environment
 * image and illuminants. Errors name the scene file and the field (key path), or the
 * file the field refers to, and what was expected. */
int kg_scene_load(const char *path, kg_scene **out, kg_err *err);
void kg_scene_free(kg_scene **s);

/* Assign one library material to the whole mesh (replacing the scene's assignment);
 * the name must be in the scene's library. */
int kg_scene_set_material(kg_scene *s, const char *name, kg_err *err);
/* The mesh being rendered (owned by the scene). */
const kg_mesh *kg_scene_mesh(const kg_scene *s);
/* The white the image is relative to (Y = 1), and the name of its illuminant. */
kg_xyz kg_scene_white(const kg_scene *s);
const char *kg_scene_white_name(const kg_scene *s);
/* The spectrum of the scene's light (the directional light's illuminant, else the
 * environment's) at intensity 1 on the image scale, per band of the 61-band grid:
 * the spectral radiance of a perfect white diffuser it lights. Camera weights are
 * scaled against it (kg_render_options.observer). */
void kg_scene_light_spectrum(const kg_scene *s, kg_spectrum *out);
/* The renderer's CIE 1931 weights: XYZ = sum over the bands of out[c] L, Y = 1 for the
 * scene's white at Y = 1 (what observer = NULL uses). */
void kg_scene_xyz_observer(const kg_scene *s, kg_spectrum out[3]);

/* Every hero wavelength path carries `wavelengths` bands (1..61); this many is all. */
#define KG_RENDER_ALL_BANDS 61
/* Surface interactions per path: 1 to this many. */
#define KG_RENDER_MAX_BOUNCES 64

/* A material every scene knows besides its library's (a library entry of the same name
 * wins): a neutral grey Lambertian diffuser of reflectance KG_SCENE_NEUTRAL_GREY_LEVEL
 * at every wavelength, with no surface reflection. It is no library material: kogei
 * process renders its unknown and background pixels with it. */
#define KG_SCENE_NEUTRAL_GREY "neutral-grey"
#define KG_SCENE_NEUTRAL_GREY_LEVEL 0.18

typedef enum kg_render_mode {
	KG_RENDER_FULL,    /* spectral path tracing (the default) */
	KG_RENDER_PREVIEW, /* primary rays only, grey N.V shading: a quick look at camera
	                      and mesh, and the primary-ray rate in bench/ */
} kg_render_mode;

/* Progress: tiles done of total; called from worker threads, one call at a time. */
typedef void (*kg_render_progress_fn)(void *user, int done, int total);

/* Overrides of the scene's settings; zero (or negative seed_set = 0) keeps the
 * scene's. A zero-initialised struct renders the scene as written.
 *
 * The observer. Each path's spectral radiance L (on the scene's scale: emitters
 * normalised as in docs/render.md) becomes the image's three channels in one place,
 *     out_c = exposure * sum over the 61 bands of observer[c](lambda) L(lambda)
 * (estimated from the path's hero bands). observer = NULL takes the CIE 1931 weights
 * of kg_scene_xyz_observer, i.e. XYZ with Y = 1 for the white. For a camera, pass
 * its sensitivities times a scale k: with k = W / max_c sum S_c(lambda) E(lambda),
 * E = kg_scene_light_spectrum, a perfect white diffuser lit by the light at
 * intensity 1 reads W in its brightest channel. That is sim/'s exposure:
 * kg_sim_capture_init(&cap, &camera, &E, W, ...) gives these weights in
 * cap.signal_weight (kogei render --camera does exactly that). The preview mode
 * shades the white's reading (observer applied to the white at Y = 1) by N.V. */
typedef struct kg_render_options {
	int width, height;  /* image size (the field of view stays vertical) */
	int spp;            /* samples per pixel */
	int wavelengths;    /* bands per path, 1..61 */
	int bounces;        /* surface interactions per path, >= 1 */
	int threads;        /* render and BVH build threads; 0 = every core */
	int seed_set;       /* use seed instead of the scene's */
	uint64_t seed;
	kg_render_mode mode;
	kg_render_progress_fn progress;
	void *progress_user;
	const kg_spectrum *observer; /* [3] weights of the output channels, or NULL: XYZ */
	int want_xyz;       /* with an observer: also CIE XYZ of the same paths
	                       (kg_render_result.xyz), e.g. for the sRGB preview */
	int want_truth;     /* record the truth of the primary hits (kg_render_truth) */
} kg_render_options;

typedef struct kg_render_stats {
	int width, height, spp, wavelengths, bounces, threads;
	uint64_t seed;           /* the seed used (the option's, else the scene's) */
	double build_s;          /* Embree scene and BVH build */
	double render_s;         /* tracing and shading, all tiles */
	uint64_t primary_rays;   /* camera rays (traced as 16-ray packets) */
	uint64_t rays;           /* every closest-hit ray, primary included */
	uint64_t shadow_rays;    /* occlusion rays towards the directional light */
	uint64_t label_rays;     /* occlusion rays projecting a label map */
	/* The same rays by depth (summed over the worker threads): depth_rays[0] are the
	 * camera rays, depth_rays[d] the rays leaving the d-th surface interaction (up to
	 * [bounces]); depth_shadow_rays[d] the shadow rays from the hits of the rays of
	 * depth d (up to [bounces - 1]). The preview traces depth 0 only. depth_s[d]:
	 * the worker threads' time (summed over them) spent tracing the rays of depth d
	 * and shading their hits, shadow rays and the choice of the next direction
	 * included (depth 0: making the camera rays too); full mode only (0 in the
	 * preview). The paths of a packet advance together, so it is read from the clock
	 * three times per depth per 16 paths. */
	uint64_t depth_rays[KG_RENDER_MAX_BOUNCES + 1];
	uint64_t depth_shadow_rays[KG_RENDER_MAX_BOUNCES];
	double depth_s[KG_RENDER_MAX_BOUNCES + 1];
} kg_render_stats;

/* 1 when the renderer was built (Embree found). */
int kg_render_available(void);

/* Render into a new 3-channel float image of CIE XYZ (Y = 1 = the scene's white), or
 * of opt->observer's channels; the same seed and settings give the same bytes
 * whatever the thread count. want_xyz and want_truth are ignored here
 * (kg_render_full). stats may be NULL. */
int kg_render(const kg_scene *s, const kg_render_options *opt, kg_image **xyz,
              kg_render_stats *stats, kg_err *err);

/* The truth of a render: what each pixel's camera rays hit first. Classes: 0
 * "background" (the ray hits nothing, or a mesh part marked "background": true, e.g.
 * a ground plane), then one per material of the scene's library in library order,
 * named as there (class 1 + i = library entry i), whether the scene uses it or not.
 * A pixel takes the class most of its samples' primary rays hit (a tie: the lower
 * class). angle_deg: the incidence angle at the primary hit, between the shading
 * normal (the one the material is evaluated with) and the direction to the camera,
 * in degrees (0..90), the mean over the pixel's samples of its class; NaN for
 * background pixels. The jittered sample positions are the image's. */
typedef struct kg_render_truth {
	int width, height;
	int nclasses;      /* 1 + the library's materials, at most 256 */
	char **class_names; /* [nclasses] */
	uint8_t *label;    /* [width * height], row by row */
	float *angle_deg;  /* [width * height] */
} kg_render_truth;

void kg_render_truth_free(kg_render_truth **t);

typedef struct kg_render_result {
	kg_image *image;        /* 3 channels: opt->observer's, or CIE XYZ */
	kg_image *xyz;          /* CIE XYZ of the same samples when opt->observer and
	                           opt->want_xyz, else NULL */
	kg_render_truth *truth; /* when opt->want_truth, else NULL */
} kg_render_result;

/* kg_render with every output; *out is zeroed first and left zeroed on failure. The
 * image does not depend on want_xyz or want_truth. */
int kg_render_full(const kg_scene *s, const kg_render_options *opt, kg_render_result *out,
                   kg_render_stats *stats, kg_err *err);
void kg_render_result_clear(kg_render_result *r);

/* The renderer's own materials, for checking them against optics/: the Fresnel
 * reflectance tabulated per band against cos(theta) (1024 steps, linear
 * interpolation), and the importance sampling of the lobes. */
typedef struct kg_render_material kg_render_material;

int kg_render_material_new(const kg_material *mat, kg_render_material **out, kg_err *err);
void kg_render_material_free(kg_render_material **m);
/* What kg_material_eval gives for the same unit vectors (f_r (N.L), all bands). */
void kg_render_material_eval(const kg_render_material *m, const double N[3],
                             const double V[3], const double L[3], kg_spectrum *out);
/* The directional albedo int f_r (N.L) dL for viewer direction V, estimated with the
 * renderer's importance sampling from n samples (seeded): converges to the integral of
 * kg_material_eval over the hemisphere when the sampling densities are right. */
void kg_render_material_albedo(const kg_render_material *m, const double N[3],
                               const double V[3], int n, uint64_t seed, kg_spectrum *out);

/* 8-bit sRGB PNG: XYZ relative to white, adapted to D65 (Bradford) so white is
 * (255, 255, 255), encoded with the sRGB curve and clipped. Atomic. */
int kg_render_write_png(const kg_image *xyz, kg_xyz white, const char *path, kg_err *err);
/* Linear 32-bit float TIFF holding the XYZ samples as they are (Y = 1 = white); the
 * same for any 3-channel image (camera RGB). */
int kg_render_write_xyz_tiff(const kg_image *xyz, const char *path, kg_err *err);
/* The truth labels as an ENVI classification map (uint8, class names, lookup colours:
 * background black, the materials in the plots' series colours), and the incidence
 * angles as an ENVI float32 cube of one band (NaN for background). Atomic. */
int kg_render_truth_write_labels(const kg_render_truth *t, const char *hdr_path,
                                 kg_err *err);
int kg_render_truth_write_angle(const kg_render_truth *t, const char *hdr_path,
                                kg_err *err);

/* The scene as a Mitsuba 3 scene (docs/render.md): xml_path (written atomically, last)
 * and, in the folder of the same name without ".xml", one binary PLY per material
 * (<material>.ply, the triangles that material covers; a label map projected as
 * kg_render projects it, which needs Embree: KG_ENOTSUP without it). Spectral
 * conductors with the library's n, k, alloys as blends of their metals, dielectrics
 * as rough plastic with their index, the scene's camera, light and sampling. threads
 * as kg_render_options.threads. */
int kg_scene_write_mitsuba(const kg_scene *s, const char *xml_path, int threads,
                           kg_err *err);

#endif
