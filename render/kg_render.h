/* The public header of the offline renderer (render/): a scene (the handoff format,
 * docs/render.md) rendered spectrally with Embree 3 into CIE 1931 XYZ, then written
 * as an sRGB PNG and a linear float TIFF.
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

/* Every hero wavelength path carries `wavelengths` bands (1..61); this many is all. */
#define KG_RENDER_ALL_BANDS 61

typedef enum kg_render_mode {
	KG_RENDER_FULL,    /* spectral path tracing (the default) */
	KG_RENDER_PREVIEW, /* primary rays only, grey N.V shading: a quick look at camera
	                      and mesh, and the primary-ray rate in bench/ */
} kg_render_mode;

/* Progress: tiles done of total; called from worker threads, one call at a time. */
typedef void (*kg_render_progress_fn)(void *user, int done, int total);

/* Overrides of the scene's settings; zero (or negative seed_set = 0) keeps the
 * scene's. A zero-initialised struct renders the scene as written. */
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
} kg_render_options;

typedef struct kg_render_stats {
	int width, height, spp, wavelengths, bounces, threads;
	double build_s;          /* Embree scene and BVH build */
	double render_s;         /* tracing and shading, all tiles */
	uint64_t primary_rays;   /* camera rays (traced as 16-ray packets) */
	uint64_t rays;           /* every closest-hit ray, primary included */
	uint64_t shadow_rays;    /* occlusion rays towards the directional light */
	uint64_t label_rays;     /* occlusion rays projecting a label map */
} kg_render_stats;

/* 1 when the renderer was built (Embree found). */
int kg_render_available(void);

/* Render into a new 3-channel float image of CIE XYZ (Y = 1 = the scene's white);
 * the same seed and settings give the same bytes whatever the thread count. stats
 * may be NULL. */
int kg_render(const kg_scene *s, const kg_render_options *opt, kg_image **xyz,
              kg_render_stats *stats, kg_err *err);

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
/* Linear 32-bit float TIFF holding the XYZ samples as they are (Y = 1 = white). */
int kg_render_write_xyz_tiff(const kg_image *xyz, const char *path, kg_err *err);

#endif
