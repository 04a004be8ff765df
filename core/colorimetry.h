/* CIE colorimetry: the CIE 1931 2 degree observer, standard illuminants, spectrum to
 * XYZ on the 61-band grid and on arbitrary samples, CIELAB, CIEDE2000 and sRGB.
 *
 * Scale: tristimulus values are relative with Y = 100 for the white (the perfect
 * diffuser under the illuminant), except the absolute colour-signal conversion, which
 * gives cd/m^2 for radiance in W sr^-1 m^-2 nm^-1. CIELAB, sRGB and the Bradford
 * adaptation take XYZ on that Y = 100 scale together with the white it refers to. */
#ifndef KG_COLORIMETRY_H
#define KG_COLORIMETRY_H

#include "error.h"
#include "spectrum.h"

/* --- standard tables (cie_tables.c, each with its citation) --- */

/* CIE 1931 2 degree colour-matching functions xbar, ybar, zbar, 360-830 nm at 1 nm.
 * The 5 nm table of CIE 15 is every fifth row (kg_cie1931_cmf[5 * i]). */
#define KG_CMF_FIRST_NM 360
#define KG_CMF_LAST_NM 830
#define KG_CMF_COUNT (KG_CMF_LAST_NM - KG_CMF_FIRST_NM + 1)
extern const double kg_cie1931_cmf[KG_CMF_COUNT][3];

/* CIE D65 (100 at 560 nm) and the daylight components S0, S1, S2: 300-830 nm, 5 nm. */
#define KG_DAYLIGHT_FIRST_NM 300
#define KG_DAYLIGHT_LAST_NM 830
#define KG_DAYLIGHT_COUNT 107
extern const double kg_cie_d65[KG_DAYLIGHT_COUNT];
extern const double kg_cie_daylight_s[KG_DAYLIGHT_COUNT][3];

/* Maximum luminous efficacy for photopic vision, lm/W (CIE 15:2018, 683.002 lm/W; the
 * SI defines 683 lm/W at 540 THz). */
#define KG_KM 683.002

/* --- colour value types --- */

typedef struct kg_xyz {
	double X, Y, Z;
} kg_xyz;

typedef struct kg_xyY {
	double x, y, Y;
} kg_xyY;

typedef struct kg_lab {
	double L, a, b;
} kg_lab;

/* Red, green, blue: linear or encoded sRGB, nominally 0..1. */
typedef struct kg_rgb {
	double r, g, b;
} kg_rgb;

/* --- illuminants --- */

/* A relative spectral power distribution on the grid, plus (when known) its samples
 * over their full range, which the full-range integration (kg_samples_to_xyz) uses.
 * Create with one of the constructors below; free with kg_illuminant_free(). */
typedef struct kg_illuminant {
	char name[64];
	kg_spectrum spd; /* on the grid (400-700 nm, 5 nm) */
	int nsamples;    /* full-range samples; 0 when only the grid is known */
	double *wl;      /* nm, strictly increasing */
	double *v;       /* same relative scale as spd */
} kg_illuminant;

/* A standard illuminant by name (case-insensitive):
 *   "D65"    the tabulated CIE D65 (kg_cie_d65);
 *   "A"      CIE A from Planck's law as CIE 15:2004 defines it (c2 = 1.435e-2 m K,
 *            T = 2848 K, i.e. 2856 K on the present temperature scale), 300-830 nm
 *            at 1 nm, 100 at 560 nm;
 *   "E"      equal energy, 100 everywhere;
 *   "D<nn>"  CIE daylight of nominal temperature nn x 100 K (D50, D55, D75, ...;
 *            40 <= nn <= 250), computed at nn x 100 x 1.4388/1.4380 K as the CIE does
 *            for its tables, so "D50" reproduces the CIE D50 table;
 *   "<T>K"   daylight at exactly T kelvin, e.g. "5500K" (4000 <= T <= 25000).
 * An unknown name is KG_EINVAL, a temperature outside the daylight range KG_ERANGE. */
int kg_illuminant_by_name(const char *name, kg_illuminant **out, kg_err *err);
/* CIE daylight at the correlated colour temperature cct (4000-25000 K; KG_ERANGE
 * outside) from S0, S1, S2 with the CIE 15:2004 formulas for x_D, y_D, M1 and M2;
 * M1 and M2 are rounded to three decimals as CIE 15:2004 prescribes, which
 * reproduces the published D tables. 300-830 nm at 5 nm, 100 at 560 nm. */
int kg_illuminant_daylight(double cct, kg_illuminant **out, kg_err *err);
/* An illuminant from samples (wl strictly increasing, values finite; a measured
 * spectrum may dip slightly below zero, but its luminance on the grid must be
 * positive). They are kept as the full-range samples and resampled to the grid
 * (kg_spectrum_resample), which they must cover (400-700 nm). `name` may be NULL. */
int kg_illuminant_from_samples(const char *name, const double *wl, const double *v,
                               int n, kg_illuminant **out, kg_err *err);
/* An illuminant from a CGATS file (ArgyllCMS or colord .sp) holding one spectrum in
 * SPEC_<nm> fields, values as stored. Only the first table is read; it must hold
 * exactly one data set. */
int kg_illuminant_from_file(const char *path, kg_illuminant **out, kg_err *err);
/* The `--illuminant NAME|FILE` argument: a name kg_illuminant_by_name knows, else an
 * existing file read by kg_illuminant_from_file. */
int kg_illuminant_lookup(const char *spec, kg_illuminant **out, kg_err *err);
void kg_illuminant_free(kg_illuminant **ill);

/* --- spectrum to XYZ on the grid (the pipeline) --- */

/* Weights w such that X = sum_i w[0][i] s[i] (likewise Y, Z): the CMF at the band
 * centres times the illuminant (if any) times the normalising constant k. Computing
 * them once lets per-pixel code do three dot products. */
typedef struct kg_xyz_weights {
	double w[3][KG_NBANDS];
} kg_xyz_weights;

/* Reflectance (or transmittance) factors under `ill`:
 * X = k sum R S xbar dl with k = 100 / sum S ybar dl, so the perfect diffuser has
 * Y = 100. */
void kg_xyz_weights_reflectance(const kg_illuminant *ill, kg_xyz_weights *w);
/* Colour signals C (eq. 12 of the paper): X = k sum C xbar dl. With a reference
 * illuminant, k = 100 / sum S_ref ybar dl (relative: C = S_ref gives Y = 100, so a
 * signal computed as S_ref times a reflectance matches kg_reflectance_to_xyz). With
 * ref == NULL, k = KG_KM (absolute: C in W sr^-1 m^-2 nm^-1 gives cd/m^2). */
void kg_xyz_weights_signal(const kg_illuminant *ref, kg_xyz_weights *w);
kg_xyz kg_xyz_from_weights(const kg_xyz_weights *w, const kg_spectrum *s);

/* One-off conversions (kg_xyz_weights_* + kg_xyz_from_weights). */
kg_xyz kg_reflectance_to_xyz(const kg_spectrum *r, const kg_illuminant *ill);
kg_xyz kg_signal_to_xyz(const kg_spectrum *c, const kg_illuminant *ref);
/* White point of an illuminant on the grid (Y = 100): what the perfect diffuser gives
 * in kg_reflectance_to_xyz. */
kg_xyz kg_illuminant_white(const kg_illuminant *ill);

/* --- spectrum to XYZ over the full CMF range (comparison with other tools) --- */

/* XYZ of arbitrary samples (wl strictly increasing, n >= 2, finite), integrated at
 * 1 nm over 360-830 nm against the 1 nm CMF table, as ArgyllCMS spec2cie and CIE 15
 * do: data sampled every 5 nm or finer are interpolated linearly, coarser data by
 * four-point Lagrange (cubic) interpolation (CIE 15:2004 section 7.2.2.1), and
 * values beyond the data's range are held at the end values. The same applies to the
 * illuminant's full-range samples (its grid spectrum when it has none).
 * ill != NULL: reflectance factors, XYZ = 100 sum v S xbar / sum S ybar.
 * ill == NULL: emission, XYZ = KG_KM sum v xbar dl (v in W sr^-1 m^-2 nm^-1 gives
 * cd/m^2; divide by Y / 100 for a Y = 100 white point). */
int kg_samples_to_xyz(const double *wl, const double *v, int n, const kg_illuminant *ill,
                      kg_xyz *out, kg_err *err);
/* White point (Y = 100) of an illuminant from its full-range samples by the
 * integration of kg_samples_to_xyz (the grid spectrum when it has none). */
kg_xyz kg_illuminant_white_full(const kg_illuminant *ill);
/* kg_samples_to_xyz over lo_nm..hi_nm only: the 1 nm rows of the CMF table within
 * both those limits and 360-830 nm, the normalisation (sum S ybar) over the same rows.
 * This is CIE 15 practice for data that cover less than the observer: integrate over
 * the wavelengths the data give, the illuminant interpolated to them, rather than
 * extend the data. KG_ERANGE when fewer than 2 nm remain. kg_samples_to_xyz is the
 * range 360-830. */
int kg_samples_to_xyz_range(const double *wl, const double *v, int n,
                            const kg_illuminant *ill, double lo_nm, double hi_nm,
                            kg_xyz *out, kg_err *err);
/* The perfect diffuser's XYZ (Y = 100) under `ill` over lo_nm..hi_nm, by
 * kg_samples_to_xyz_range: the white that CIELAB of those XYZ refers to. NaN when the
 * range is empty. */
kg_xyz kg_illuminant_white_range(const kg_illuminant *ill, double lo_nm, double hi_nm);

/* --- colour spaces --- */

/* Chromaticity and luminance. Black (X + Y + Z = 0) gives x = y = 0. */
kg_xyY kg_xyz_to_xyY(kg_xyz c);
/* y = 0 gives black. */
kg_xyz kg_xyY_to_xyz(kg_xyY c);

/* CIELAB (CIE 15:2004, section 8.2.1) relative to `white` (same scale as c). */
kg_lab kg_xyz_to_lab(kg_xyz c, kg_xyz white);
kg_xyz kg_lab_to_xyz(kg_lab c, kg_xyz white);
/* CIEDE2000 colour difference (kL = kC = kH = 1), in the formulation of Sharma, Wu and
 * Dalal, Color Res. Appl. 30(1):21-30 (2005). Symmetric in its arguments. */
double kg_ciede2000(kg_lab a, kg_lab b);

/* Chromatic adaptation of c from src_white to dst_white with the Bradford matrix
 * (von Kries scaling in the Bradford cone space; Lam 1985, as in ICC.1 Annex E). */
kg_xyz kg_bradford_adapt(kg_xyz c, kg_xyz src_white, kg_xyz dst_white);
/* Linear sRGB (IEC 61966-2-1:1999, D65). c is relative to `white` (Y = 100 scale);
 * when that white is not the sRGB white it is first adapted with Bradford, so `white`
 * itself maps to (1, 1, 1). Not clamped: out-of-gamut colours give values outside
 * 0..1. */
kg_rgb kg_xyz_to_linear_srgb(kg_xyz c, kg_xyz white);
/* The inverse of kg_xyz_to_linear_srgb for the same white. */
kg_xyz kg_linear_srgb_to_xyz(kg_rgb c, kg_xyz white);
/* The sRGB transfer function (piecewise: 12.92 x below 0.0031308, else
 * 1.055 x^(1/2.4) - 0.055), applied to each channel; negative values are mirrored. */
kg_rgb kg_srgb_encode(kg_rgb linear);
kg_rgb kg_srgb_decode(kg_rgb encoded);
/* Encoded 0..1 values to 8 bits: clamped to 0..1, scaled by 255 and rounded; NaN
 * gives 0. */
void kg_rgb_to_u8(kg_rgb encoded, unsigned char out[3]);

#endif
