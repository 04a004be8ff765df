/* glTF 2.0 export of a scene (render/gltf.c): the scene's mesh and its material
 * assignment as a binary glTF (.glb) that Blender, three.js, model-viewer and other
 * glTF 2.0 tools open. The layout of the file is in docs/formats.md, the material
 * mapping in docs/render.md.
 *
 * One PBR metallic-roughness material per material region:
 *   metals and alloys: metallicFactor 1, baseColorFactor the normal-incidence
 *     reflectance (an alloy's the composition-weighted sum of its metals') integrated
 *     under D65 with the CIE 1931 observer into linear sRGB, times the lobes' weight
 *     gloss + mirror;
 *   dielectrics (urushi): metallicFactor 0, baseColorFactor the body reflectance in
 *     linear sRGB, the index through KHR_materials_ior, the lobes' weight through
 *     KHR_materials_specular (specularFactor);
 *   every material: roughnessFactor = sqrt(alpha), alpha the lobe-weighted mean of
 *     the gloss lobe's Beckmann RMS slope and the mirror lobe's equivalent slope
 *     (half its cone width), glTF's GGX alpha being roughness^2;
 *   regions that are no library material ("unknown", "background", unseen or
 *     unclassified, and kogei's neutral-grey): a neutral grey diffuser of reflectance
 *     KG_SCENE_NEUTRAL_GREY_LEVEL with no surface reflection, named after the region.
 * A label map is projected onto the triangles as the renderer does it (each
 * triangle takes the class under its centroid seen from the map's camera, the
 * fallback where it is hidden or out of view), and the triangles are split into one
 * primitive per material. */
#ifndef KG_GLTF_H
#define KG_GLTF_H

#include "kg_optics.h"
#include "kg_render.h"

/* The glTF factors of one library material. */
typedef struct kg_gltf_pbr {
	double base_color[3]; /* linear sRGB, clamped to 0..1 */
	int clipped;          /* 1 when a channel was clamped (out of the sRGB gamut) */
	double metallic;      /* 1 metal or alloy, 0 dielectric */
	double roughness;     /* sqrt(alpha) */
	double alpha;         /* the equivalent GGX/Beckmann slope */
	double ior;           /* dielectric: n at 560 nm; 0 for metals */
	double specular;      /* dielectric: gloss + mirror; 1 for metals */
} kg_gltf_pbr;

int kg_gltf_material_pbr(const kg_material *m, kg_gltf_pbr *out, kg_err *err);

/* The neutral grey's linear reflectance (the "unknown" and "background" materials). */
#define KG_GLTF_NEUTRAL_LEVEL KG_SCENE_NEUTRAL_GREY_LEVEL

typedef struct kg_gltf_options {
	/* A PNG of the object as photographed (sRGB, the label map's framing), or NULL:
	 * embedded as the base colour texture of a second node "photograph", the same
	 * mesh textured by projection from the map's camera, placed beside the object. */
	const char *photo_png;
	/* Free text for asset.extras.kogei.source (e.g. the capture's name), or NULL. */
	const char *source;
	/* asset.extras.kogei.scene names the scene relative to this folder when it lies
	 * below it (kogei process: its staging folder, so the path is the final one), or
	 * NULL: as loaded. */
	const char *record_dir;
} kg_gltf_options;

/* Write the scene as a binary glTF 2.0 file (atomic). opt may be NULL. */
int kg_gltf_write(const kg_scene *s, const kg_gltf_options *opt, const char *path,
                  kg_err *err);
/* The same from a scene file (kg_scene_load, then kg_gltf_write). */
int kg_gltf_write_scene_file(const char *scene_path, const kg_gltf_options *opt,
                             const char *path, kg_err *err);

#endif
