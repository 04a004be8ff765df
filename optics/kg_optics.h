/* The public header of optics/: Fresnel reflectance of conductors and dielectrics,
 * the Torrance-Sparrow gloss lobe and a narrow mirror lobe, complex refractive
 * indices (the Lorentz-Drude model of Rakic et al. 1998 and user n,k tables), and
 * the material library (metals, alloys, lacquer) built on them.
 *
 * The reflection models follow Matsuda, Tanaka et al., "CG reproduction of a craft
 * object based on a light reflection model": a metal reflects by the Fresnel
 * equations of its complex index through a gloss lobe plus a mirror lobe (eq. 2); an
 * alloy's reflectance is the composition-weighted sum of its metals' (eq. 3/4); a
 * lacquer adds a diffuse body reflection under a dielectric surface (eq. 5). */
#ifndef KG_OPTICS_H
#define KG_OPTICS_H

#include "kg_core.h"

/* ---- Fresnel reflectance (fresnel.c) ------------------------------------------ */

/* Power reflectances of the plane interface between an ambient medium of real index
 * n0 (1 for air) and a medium of complex index n + ik (k >= 0 absorbs), for light
 * arriving at incidence angle theta given as cos_i = cos(theta) in [0, 1] (0 is
 * grazing). rs and rp are the s- and p-polarised reflectances; the unpolarised
 * reflectance is their mean. Exact equations (no approximation), evaluated to within
 * about 1e-15 from normal incidence to grazing, for k up to 50 and more, and at the
 * critical angle (how: fresnel.c); 0 <= R <= 1 holds in floating point, and R = 1
 * at cos_i = 0. Total internal reflection (n0 > n, k = 0) gives 1. An interface
 * between identical media (n = n0, k = 0) reflects nothing, at every angle.
 * Invalid arguments (n < 0, k < 0, n = k = 0, n0 <= 0, cos_i outside [0, 1], NaN)
 * give NaN. */
void kg_fresnel_conductor_sp(double n, double k, double n0, double cos_i, double *rs,
                             double *rp);
double kg_fresnel_conductor(double n, double k, double n0, double cos_i);
/* The same for a real index n (k = 0), including total internal reflection. */
void kg_fresnel_dielectric_sp(double n, double n0, double cos_i, double *rs, double *rp);
double kg_fresnel_dielectric(double n, double n0, double cos_i);

/* ---- Complex refractive index on the grid (nk.c) ------------------------------ */

typedef struct kg_nk {
	kg_spectrum n; /* real part of the index, per band */
	kg_spectrum k; /* extinction coefficient, per band */
} kg_nk;

/* Unpolarised reflectance per band from air (n0 = 1) at cos_i = cos(theta). */
void kg_nk_reflectance(const kg_nk *nk, double cos_i, kg_spectrum *out);

/* The Lorentz-Drude model of A. D. Rakic, A. B. Djurisic, J. M. Elazar and
 * M. L. Majewski, "Optical properties of metallic films for vertical-cavity
 * optoelectronic devices", Applied Optics 37(22), 5271-5283 (1998) (its table of LD
 * parameters), for element "Ag", "Au" or "Cu" (any case): n + ik at one wavelength,
 * or sampled at the band centres. Unknown elements are refused (KG_ENOTSUP).
 * In the visible the model departs from Johnson & Christy's (1972) measurements:
 * normal-incidence reflectance 0.02-0.06 low for Ag and 0.04-0.06 low for Au
 * (450-700 nm), up to 0.16 high for Cu at 520-590 nm (tests/optics/test_nk.c). */
int kg_nk_rakic1998_ld_at(const char *element, double lambda_nm, double *n, double *k,
                          kg_err *err);
int kg_nk_rakic1998_ld(const char *element, kg_nk *out, kg_err *err);

/* Published analytic dispersion models by name (parameters and full citations in
 * nk.c), for an element (any case): n + ik at one wavelength, or sampled at the band
 * centres. The material library's {"model": ..., "element": ...} takes the same names.
 *   "rakic1998-ld"          Ag, Au, Cu  Lorentz-Drude, Rakic et al., Appl. Opt. 37,
 *                                       5271 (1998) (= kg_nk_rakic1998_ld)
 *   "vial-laroche2008-dcp"  Ag, Au      Drude + 2 critical points fitted to Johnson &
 *                                       Christy, A. Vial and T. Laroche, Appl. Phys. B
 *                                       93, 139 (2008)
 *   "vial2008ch-dcp"        Ag, Au, Cu  Drude + 2 critical points fitted over
 *                                       400-1000 nm (Au to Johnson & Christy, Ag and Cu
 *                                       to Palik), A. Vial, book chapter, Transworld
 *                                       Research Network (2008), pp. 23-46
 *   "leru-etchegoin2009"    Au          Drude + 2 critical points in wavelength form,
 *                                       E. C. Le Ru and P. G. Etchegoin, Principles of
 *                                       SERS, Elsevier (2009), eq. (E.1)
 * Largest normal-incidence |R - R(Johnson & Christy 1972)| over 450-700 nm, measured
 * by tests/optics/test_nk.c: Au 0.016 (vial-laroche2008-dcp), 0.028 (vial2008ch-dcp),
 * 0.044 (leru-etchegoin2009), 0.067 (rakic1998-ld); Ag 0.014 (vial-laroche2008-dcp;
 * 0.034 at 400-405 nm), 0.060 (vial2008ch-dcp), 0.061 (rakic1998-ld); Cu 0.030
 * (vial2008ch-dcp), 0.158 (rakic1998-ld). n + ik = sqrt(eps) with n, k >= 0; where a
 * fit's Im eps < 0 (vial-laroche2008-dcp Ag, 410-595 nm, down to -0.12: not physical,
 * a property of the published fit) k is |Im sqrt(eps)|, which leaves the reflectance at
 * every angle unchanged (the Fresnel amplitudes are conjugated). Unknown models or
 * elements are refused (KG_ENOTSUP), the message naming what is available;
 * wavelengths must be > 0. */
int kg_nk_model_at(const char *model, const char *element, double lambda_nm, double *n,
                   double *k, kg_err *err);
int kg_nk_model(const char *model, const char *element, kg_nk *out, kg_err *err);

/* Tables of n and k, resampled to the grid by interpolating n and k separately
 * (kg_spectrum_resample). Data that do not cover 400-700 nm are refused (KG_ERANGE)
 * unless flags holds KG_RESAMPLE_EXTRAPOLATE. n must be >= 0 and k >= 0.
 *
 * CSV: header `wavelength_nm,n,k` (further columns ignored), one row per wavelength
 * in nm, as tables exported from refractiveindex.info are. Blank lines and lines starting with '#' are
 * skipped.
 *
 * refractiveindex.info YAML, the subset its database uses for measured data: a
 * top-level `DATA:` list whose items are `- type: tabulated nk` with a `data: |` block
 * of "wavelength[um] n k" lines, or a `tabulated n` item together with an optional
 * `tabulated k` item (two columns each; k = 0 when absent). Other keys (REFERENCES,
 * COMMENTS, SPECS, ...) are skipped; other data types (formulas) are refused.
 *
 * `name` names the data in messages (NULL: "<memory>"); text must be NUL-terminated. */
int kg_nk_parse_csv(const char *text, const char *name, unsigned flags, kg_nk *out,
                    kg_err *err);
int kg_nk_parse_yaml(const char *text, const char *name, unsigned flags, kg_nk *out,
                     kg_err *err);
/* Read a file: `.csv` as CSV, `.yml`/`.yaml` as refractiveindex.info YAML. */
int kg_nk_load(const char *path, unsigned flags, kg_nk *out, kg_err *err);

/* ---- Reflection lobes (lobes.c) ----------------------------------------------- */

/* Geometry: N is the surface normal, V the direction towards the viewer, L towards
 * the light; all unit vectors (|v|^2 within 1e-6 of 1, else the result is NaN).
 * H = (V + L) / |V + L|. Dot products of unit vectors are limited to [-1, 1] to absorb
 * rounding; nothing else is clamped. */

/* Beckmann distribution of facet normals at angle alpha from N (cos_alpha = N.H),
 * RMS slope m > 0: D = exp(-tan^2(alpha) / m^2) / (pi m^2 cos^4(alpha)), normalised
 * so that the projected facet area integrates to one, int D (N.H) dw = 1. */
double kg_beckmann(double cos_alpha, double m);

/* Torrance-Sparrow geometric attenuation (V-groove shadowing and masking):
 * G = min(1, 2 (N.H)(N.V)/(V.H), 2 (N.H)(N.L)/(V.H)); 0 when V or L is below the
 * surface. */
double kg_ts_geometry(const double N[3], const double V[3], const double L[3]);

/* The gloss lobe: the Torrance-Sparrow BRDF without its Fresnel factor,
 * D(N.H; m) G / (4 (N.L)(N.V)), in 1/sr. Multiply by F(lambda) at the facet angle
 * *cos_vh = V.H (may be NULL). Times (N.L) it is the paper's D G F / cos(theta_r)
 * term; the 1/4 comes with D normalised as above. Its directional albedo,
 * int f (N.V) dw_V over the viewing hemisphere, is at most 1 for every L and m (the
 * V-groove term G never exceeds a masking function that conserves projected area;
 * checked numerically in tests/optics/test_lobes.c), so F times the lobe never
 * reflects more than F. 0 below the horizon (*cos_vh = 1 there). */
double kg_lobe_gloss(const double N[3], const double V[3], const double L[3], double m,
                     double *cos_vh);

/* The mirror lobe: a narrow cone of angular width w (radians, > 0) around the mirror
 * direction of L, exp(-(delta/w)^2) / (pi w^2 (N.V)), delta being the angle between V
 * and the mirror direction; in 1/sr, multiply by F at *cos_vh = V.H. It tends to the
 * BRDF of a perfect mirror as w -> 0, and its directional albedo is at most 1
 * (the Gaussian's integral over the sphere is below pi w^2). */
double kg_lobe_mirror(const double N[3], const double V[3], const double L[3], double w,
                      double *cos_vh);

/* ---- Materials (materials.c) -------------------------------------------------- */

typedef enum kg_material_kind {
	KG_MATERIAL_METAL,      /* Fresnel reflectance of its own n, k */
	KG_MATERIAL_ALLOY,      /* composition-weighted sum of its metals' reflectances */
	KG_MATERIAL_DIELECTRIC, /* body reflectance under a dielectric surface (lacquer) */
} kg_material_kind;

#define KG_MATERIAL_NAME_MAX 64
#define KG_ALLOY_MAX_COMPONENTS 8

typedef struct kg_alloy_component {
	char name[KG_MATERIAL_NAME_MAX]; /* the metal's name in its library */
	double fraction;                 /* mixing weight; the weights sum to 1 */
	kg_nk nk;                        /* the metal's optical constants */
} kg_alloy_component;

/* An empirical template: a material's reading learned from photographs of a reference
 * coupon at the station (kogei materials learn), in the reference camera's space at
 * the chart's exposure, per incidence angle of the views. Matching prefers it to the
 * reading predicted from the published n, k. */
#define KG_TEMPLATE_MAX_VIEWS 8
typedef struct kg_material_template {
	int n;                                  /* views; 0: no template */
	double angle_deg[KG_TEMPLATE_MAX_VIEWS]; /* increasing */
	double mean[KG_TEMPLATE_MAX_VIEWS][3];
	double cov[KG_TEMPLATE_MAX_VIEWS][9];    /* of the coupon's pixels */
	long pixels[KG_TEMPLATE_MAX_VIEWS];
	char reference[65]; /* sha256 of the reference calibration it was learned through,
	                       or "" when unknown */
} kg_material_template;

/* A plain value (copy by assignment). Fields not used by a kind are zero. */
typedef struct kg_material {
	char name[KG_MATERIAL_NAME_MAX];
	kg_material_kind kind;
	kg_nk nk;        /* metal: optical constants; dielectric: n (k = 0) */
	int ncomponents; /* alloy */
	kg_alloy_component component[KG_ALLOY_MAX_COMPONENTS];
	kg_spectrum body; /* dielectric: diffuse body reflectance, in [0, 1] */
	/* Surface: gloss lobe RMS slope (> 0), mirror lobe width (rad, > 0), and the
	 * weights of the two lobes (>= 0, gloss + mirror <= 1). */
	double roughness;
	double mirror_width;
	double gloss;
	double mirror;
	kg_material_template tmpl; /* optional, any kind ("template" in the library file) */
	/* The prediction's own relative sd per camera channel (r, g, b): the spread of the
	 * published optical constants, the alloy mixing rule ("model_rsd"); for a coupon
	 * template, its pixels' relative scatter. 0: none known. */
	double model_rsd[3];
} kg_material;

/* Check a material: finite n >= 0 and k >= 0, alloy fractions in [0, 1] summing to 1
 * within 1e-6, body reflectance in [0, 1], surface parameters as above. Messages
 * name the material and the field. */
int kg_material_validate(const kg_material *mat, kg_err *err);

/* Reflectance spectrum at incidence theta (radians, 0 = normal, up to pi/2) from
 * air, each band in [0, 1]:
 *   metal:      F(theta), the unpolarised Fresnel reflectance of n + ik;
 *   alloy:      sum_i c_i F_i(theta) (the paper's eq. 3/4, fractions c_i; divided
 *               by sum_i c_i, which validation keeps within 1e-6 of 1);
 *   dielectric: F(theta) + (1 - F(theta)) body, the surface reflection plus the part
 *               of the transmitted light the body returns (internal reflections at
 *               the surface on the way out are neglected).
 * The lobe weights do not enter: this is the reflectance at incidence, integrated
 * over the outgoing directions. */
int kg_material_reflectance(const kg_material *mat, double theta, kg_spectrum *out,
                            kg_err *err);

/* The full model at one geometry (unit vectors as for the lobes): f_r(lambda) (N.L),
 * i.e. the radiance towards V per unit radiance arriving from L (per unit irradiance
 * normal to L), in 1/sr; multiply by the illuminant to get the colour signal:
 *   gloss F(V.H) lobe_gloss (N.L) + mirror F(V.H) lobe_mirror (N.L)
 *   + dielectric only: (1 - F(N.L)) body / pi (N.L),
 * F being the material's Fresnel reflectance (for an alloy the weighted sum, the
 * alloy's own surface parameters shared by its metals). 0 below the horizon. */
int kg_material_eval(const kg_material *mat, const double N[3], const double V[3],
                     const double L[3], kg_spectrum *out, kg_err *err);

/* ---- Material library (materials.c) ------------------------------------------- */

/* A JSON library, "format": "kogei-materials/1", "materials": [ entries ]:
 *   common:     "name" (unique), "kind" ("metal" | "alloy" | "dielectric"),
 *               optional "roughness" (default 0.1), "mirror_width" (0.02),
 *               "gloss" (0.8), "mirror" (0.2), "note", "source";
 *   metal:      "nk": {"model": "rakic1998-ld", "element": "Au"} or "nk": "file"
 *               (.csv or .yml, relative to the JSON file), optional "extrapolate";
 *   alloy:      "components": [{"material": "<metal's name>", "fraction": c}, ...];
 *   dielectric: "n" (number), "body": number or {"wavelength_nm": [...],
 *               "reflectance": [...]} (resampled to the grid).
 * Errors name the file, the entry and the field. */
typedef struct kg_material_library kg_material_library;

/* The file a --materials argument names: an existing file (or any argument with a '/')
 * as it is, else a bundled library by name ("default": fixtures/materials/default.json,
 * installed with kogei). An unknown name fails with KG_ENOENT listing the bundled
 * names. *path is newly allocated. kg_material_library_load calls it, so every command
 * and scene that takes a library takes a name too. */
int kg_material_library_resolve(const char *arg, char **path, kg_err *err);
int kg_material_library_load(const char *path, kg_material_library **out, kg_err *err);
void kg_material_library_free(kg_material_library **lib);
int kg_material_library_count(const kg_material_library *lib);
/* Entry i (0 <= i < count) in file order, NULL otherwise. */
const kg_material *kg_material_library_get(const kg_material_library *lib, int i);
/* The entries' names as "a, b, c" in buf (size bytes, cut short where they do not
 * fit), for messages. */
void kg_material_library_names(const kg_material_library *lib, char *buf, size_t size);
/* The entry with that name, or NULL. */
const kg_material *kg_material_library_find(const kg_material_library *lib,
                                            const char *name);

/* ---- Figures (figures.c) ------------------------------------------------------ */

/* The paper's Fig. 7: reflectance at incidence (kg_material_reflectance) per band and
 * angle; table[band * nangles + j] for angles_deg[j] (degrees, 0..90). */
int kg_model_table(const kg_material *mat, const double *angles_deg, int nangles,
                   double *table, kg_err *err);
/* CSV: header `wavelength_nm,<angle>,...`, one row per band 400..700 ("-" = stdout). */
int kg_model_table_write_csv(const char *path, const double *angles_deg, int nangles,
                             const double *table, kg_err *err);
/* A heat map of the table (wavelength against angle) with a colour bar and, below it,
 * the sRGB colour of the light `ill` reflected at each angle. */
int kg_model_figure(const char *path, const char *title, const double *angles_deg,
                    int nangles, const double *table, const kg_illuminant *ill,
                    kg_err *err);
/* The colour of a reflectance under `ill`, encoded sRGB (white = (1,1,1)). */
kg_rgb kg_reflectance_srgb(const kg_spectrum *r, const kg_illuminant *ill);
/* One swatch per library material at normal incidence under `ill`, with its name,
 * its sRGB colour and its reflectance curve. */
int kg_swatch_sheet(const char *path, const kg_material_library *lib,
                    const kg_illuminant *ill, kg_err *err);

#endif
