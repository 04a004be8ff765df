/* Private to render/: the parsed scene, the renderer's materials (Fresnel tabulated
 * per band against the cosine of incidence) and the spectral helpers. */
#ifndef KG_RENDER_PRIVATE_H
#define KG_RENDER_PRIVATE_H

#include <stdint.h>

#include "kg_optics.h"
#include "kg_render.h"

/* ---- spectral helpers (spectral.c) ---------------------------------------------- */

/* RGB texels upsampled to spectra (the linear-basis method of A. S. Glassner, "How to
 * derive a spectrum from an RGB triplet", IEEE CG&A 9(4), 95-99, 1989): three smooth
 * non-negative basis reflectances that sum to 1 at every band (blue, green, red;
 * smoothstep transitions at 470-510 and 570-610 nm); the coefficients c solve the 3x3
 * system that makes sum_k c_k b_k(lambda) S(lambda) reproduce the texel's XYZ under the
 * CIE 1931 observer exactly, the texel's RGB being linear sRGB whose white (1, 1, 1)
 * is the illuminant S. So white gives c = (1, 1, 1), i.e. S itself. */
typedef struct rd_upsampler {
	float basis[3][KG_NBANDS];
	double rgb_to_c[3][3];
} rd_upsampler;

int rd_upsampler_init(rd_upsampler *u, const kg_illuminant *ill, kg_err *err);
void rd_upsample(const rd_upsampler *u, const float rgb[3], float c[3]);

/* ---- the renderer's materials (bsdf.c) ------------------------------------------ */

/* Fresnel table resolution: cos(theta) from 0 to 1 in RD_NCOS steps. */
#define RD_NCOS 1024

typedef struct rd_material {
	const kg_material *src;
	double gloss, mirror, roughness, mirror_width;
	int has_body;
	float body[KG_NBANDS];
	float *fresnel; /* (RD_NCOS + 1) x KG_NBANDS: F(cos) per band, row per cosine */
	/* Lobe selection probabilities (gloss, mirror, body), from each lobe's share of
	 * the normal-incidence albedo; sum to 1. */
	double p_lobe[3];
} rd_material;

int rd_material_init(rd_material *m, const kg_material *src, kg_err *err);
void rd_material_clear(rd_material *m);

/* F at cosine c for the n bands in band[]. */
void rd_fresnel(const rd_material *m, double c, const int *band, int n, float *out);

/* f_r (N.L) for bands band[0..n-1] (kg_material_eval with tabulated Fresnel); unit
 * vectors in double. Returns 0 when every value is 0 (below the horizon). */
int rd_eval(const rd_material *m, const double N[3], const double V[3],
            const double L[3], const int *band, int n, float *out);

/* Sample an outgoing direction L for viewer direction V by importance (pick a lobe by
 * p_lobe, then Beckmann facets for gloss, the Gaussian cone for mirror, cosine for the
 * body) and give the weight f_i (N.L) / (p_i pdf_i) per band. u are three uniform
 * numbers in [0, 1). Returns 0 when the sample carries nothing. */
int rd_sample(const rd_material *m, const double N[3], const double V[3],
              const double u[3], const int *band, int n, double L[3], float *weight);

/* ---- the scene (scene.c) -------------------------------------------------------- */

typedef struct rd_view {
	double pos[3], look_at[3], up[3];
	double fov_deg; /* vertical */
	int width, height;
} rd_view;

/* The camera's frame: forward, right, up (unit), and tan(fov / 2). */
typedef struct rd_frame {
	double fwd[3], right[3], up[3];
	double tan_half;
} rd_frame;

void rd_view_frame(const rd_view *v, rd_frame *f);

/* How the mesh gets its materials. */
typedef enum rd_assign {
	RD_ASSIGN_ONE,       /* material 0 everywhere */
	RD_ASSIGN_FACE,      /* tri_mat from the mesh's per-face ids */
	RD_ASSIGN_VERTEX,    /* tri_mat from the mesh's per-vertex ids */
	RD_ASSIGN_LABEL_MAP, /* resolved at render time by projecting the label map */
} rd_assign;

typedef struct rd_label_map {
	char *path;
	int width, height;
	uint8_t *labels;  /* width x height, 0 = unclassified */
	int nclasses;
	int *class_mat;   /* nclasses entries: material index, -1 = use the fallback */
	char **class_names; /* nclasses entries, as in the map's header */
	rd_view view;     /* the pose it was seen from (width, height = the map's) */
	int fallback;     /* material index for unlabelled or unseen triangles */
} rd_label_map;

struct kg_scene {
	char *path;
	kg_mesh *mesh;
	char *library_path;
	kg_material_library *lib;

	int nmat;
	const kg_material **mat; /* library entries, in the order first used */
	kg_material neutral;     /* KG_SCENE_NEUTRAL_GREY, when the scene names it */
	rd_assign assign;
	uint16_t *tri_mat;       /* ntris entries (FACE, VERTEX), else NULL */
	rd_label_map label;      /* LABEL_MAP */
	uint8_t *tri_background; /* ntris: 1 on triangles of parts marked "background"
	                            (class 0 of the truth), or NULL when none is */

	/* Emitters: spectra normalised so that each has luminance Y = 1 on the image
	 * scale, times their intensity. */
	int has_sun;
	double sun_dir[3];               /* unit, towards the light */
	double sun_intensity;
	float sun_irradiance[KG_NBANDS]; /* pi * intensity * normalised spectrum */

	int has_env;
	double env_intensity;
	double env_rotation_deg;
	float env_radiance[KG_NBANDS];   /* uniform: intensity * normalised spectrum */
	int env_width, env_height;       /* image: texel coefficients (rd_upsample) */
	float *env_coef;                 /* env_width x env_height x 3, or NULL */
	rd_upsampler env_up;
	char env_illuminant[64];

	rd_view view;
	double exposure;
	int spp, wavelengths, bounces;
	uint64_t seed;

	char white_name[64];
	kg_xyz white;                   /* Y = 1 */
	float xyz_w[3][KG_NBANDS];       /* signal -> XYZ on the image scale */
	float white_spd[KG_NBANDS];      /* the white's spectrum at Y = 1 */
	float light_spd[KG_NBANDS];      /* the light's (else the environment's) spectrum
	                                    at intensity 1: a white diffuser's radiance */
};

/* Index of a library material in s->mat, adding it when new. */
int rd_scene_material_index(kg_scene *s, const char *name, const char *field,
                            kg_err *err);

/* The material of each triangle (an index into s->mat), the label map projected as
 * the renderer projects it (this needs Embree: without it a label-map scene fails with
 * KG_ENOTSUP). *out: ntris entries, newly allocated (NULL for an empty mesh). */
int rd_scene_triangle_materials(const kg_scene *s, int threads, uint16_t **out, kg_err *err);
/* The mean radiance of the scene's image environment over the sphere (texels weighted
 * by their solid angle), per band (KG_NBANDS): what a uniform stand-in emits (the
 * Mitsuba scene's constant emitter, the glTF backdrop). */
void rd_env_mean(const kg_scene *s, float *out);
/* The same without a label map (render.c's and render_none.c's common part). */
int rd_scene_triangle_materials_plain(const kg_scene *s, uint16_t **out, kg_err *err);

#endif
