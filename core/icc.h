/* Colour-managed outputs (LittleCMS): the RGB working spaces of an archival master
 * and the 16-bit TIFF master itself, rendered from a reflectance cube.
 *
 * The spaces, as their specifications define them:
 *   eciRGB v2    D50 white, the CIE L* tone curve, primaries (0.67, 0.33),
 *                (0.21, 0.71), (0.14, 0.08) (ECI, eciRGB v2, 2007; ISO 22028-4:2012);
 *   Adobe RGB    D65 white, gamma 563/256, primaries (0.64, 0.33), (0.21, 0.71),
 *                (0.15, 0.06) (Adobe RGB (1998) Color Image Encoding, 2005);
 *   ProPhoto RGB D50 white, gamma 1.8, primaries (0.7347, 0.2653), (0.1596, 0.8404),
 *                (0.0366, 0.0001) (ROMM RGB, ISO 22028-2:2013). */
#ifndef KG_ICC_H
#define KG_ICC_H

#include <stddef.h>

#include "colorimetry.h"
#include "error.h"

typedef enum kg_icc_space {
	KG_ICC_NONE = 0,
	KG_ICC_ECIRGB_V2,
	KG_ICC_ADOBE_RGB,
	KG_ICC_PROPHOTO,
} kg_icc_space;

/* 1 when kogei was built with LittleCMS (the master and camera.icc need it). */
int kg_icc_available(void);
/* "ecirgb-v2", "adobe-rgb", "prophoto", "none" (case-insensitive) -> *out; else
 * KG_EINVAL naming the value and what was expected. */
int kg_icc_space_parse(const char *name, kg_icc_space *out, kg_err *err);
/* The canonical name (as parsed) and the profile's description. */
const char *kg_icc_space_name(kg_icc_space s);
const char *kg_icc_space_description(kg_icc_space s);

/* The ICC version a profile is written in: v2 (2.4, the default: ArgyllCMS 2.3's
 * iccdump and profcheck, older viewers and the archives' own tools read it) or v4
 * (4.3, on request). In v2 a parametric curve (eciRGB v2's L* curve) is written as a
 * sampled curve. */
typedef enum { KG_ICC_V2 = 2, KG_ICC_V4 = 4 } kg_icc_version;
/* "2" or "4" (also "v2", "v4") -> *out; else KG_EINVAL naming the value. */
int kg_icc_version_parse(const char *name, kg_icc_version *out, kg_err *err);

/* The ICC profile (matrix/shaper, version v) of a space, serialised: *buf (caller
 * frees). */
int kg_icc_profile_bytes(kg_icc_space s, kg_icc_version v, unsigned char **buf, size_t *len,
                         kg_err *err);

/* OUTDIR/<object>/master.tif: the reflectance cube `cube` (an ENVI cube on the 61-band
 * grid, 400-700 nm at 5 nm) rendered to XYZ under `ill` (CIE 1931 2 degree), adapted
 * to D50 with Bradford when ill's white is not D50 (the ICC connection space) and
 * converted, relative colorimetric, into `space`: 16-bit RGB, the profile embedded
 * (TIFFTAG_ICCPROFILE). Non-finite estimates are written as black; colours outside
 * the space are clipped. Written to a temporary file and renamed. */
typedef struct kg_tiff_identity {
	/* ASCII tags (UTF-8 text without control characters), each written when not NULL:
	 * ImageDescription (270), Artist (315), Copyright (33432); DateTime (306) as TIFF
	 * writes it, "YYYY:MM:DD HH:MM:SS" (checked). */
	const char *description, *artist, *copyright, *datetime;
	/* The XMP packet (TIFF tag 700, XMLPacket, BYTE), xmp_len bytes, or NULL. */
	const char *xmp;
	size_t xmp_len;
	/* > 0: XResolution = YResolution = pixels_per_mm x 25.4, ResolutionUnit inch (2);
	 * else 1 and 1 with ResolutionUnit none (1): square pixels of no stated size. */
	double pixels_per_mm;
} kg_tiff_identity;

/* What the master shows of the counted pixels: those set in lit (a bitmap, pixel
 * i = y * width + x at bit i % 8 of byte i / 8; NULL: every pixel) that have a finite
 * estimate. Y is relative to the perfect diffuser under the illuminant (1 = the
 * diffuse white); a surface that reflects more than it toward the camera (a specular
 * highlight on polished metal) or that is lit more than the chart was is above it. */
typedef struct kg_master_stats {
	long counted;
	long clipped;        /* a channel outside 0..1 in the 16-bit master, either end */
	long clipped_top;    /* a channel above 1 (above the space's white): written as 65535 */
	long clipped_low;    /* clipped, but no channel above 1: one below 0, a chromaticity
	                      * outside the space's primaries */
	long above_white;    /* Y > 1: brighter than the diffuse white */
	long above_clipped;  /* of those, clipped at the top in the 16-bit master (all of
	                      * them but for rounding: the white is 1, 1, 1, so Y > 1 puts a
	                      * channel above 1) */
	long band_above_one; /* a band's reflectance estimate above 1 */
	double max_y;           /* the largest Y (0 when none counted) */
	double max_reflectance; /* the largest band value */
} kg_master_stats;

/* The highlight map's pixel colours (display sRGB, 0..255), worst first; the master's
 * Y in grey elsewhere. */
#define KG_MASTER_MAP_ABOVE 0xe0, 0x10, 0x10  /* above white (at full scale in master.tif) */
#define KG_MASTER_MAP_TOP 0xff, 0xb0, 0x00    /* a channel at full scale, Y <= 1 */
#define KG_MASTER_MAP_LOW 0x20, 0x90, 0xff    /* clipped below 0 only: outside the primaries */

typedef struct kg_master_extra {
	/* in: not NULL: also the linear float master there (32-bit IEEE float RGB, LZW with
	 * the floating-point predictor): the same colours in the space's primaries and
	 * white, linear, scene-referred with the diffuse white at 1.0, unclipped (above 1
	 * and below 0 kept), with a linear-curve ICC profile of those primaries embedded
	 * (kg_icc_linear_profile_bytes), the same identity tags */
	const char *linear_path;
	/* in: > 0: *map gets the highlight map, at most this many pixels a side (each map
	 * pixel a block of the image: its colour the block's worst case, above white and
	 * clipped first, its grey the block's mean Y) */
	int map_max_side;
	unsigned char *map; /* out: map_w x map_h 8-bit RGB (caller frees), or NULL */
	int map_w, map_h;
	/* out: the smallest box of the map holding every counted pixel (the object):
	 * x0 <= x < x1, y0 <= y < y1; all 0 when none was counted */
	int box[4];
	kg_master_stats stats; /* out */
} kg_master_extra;

/* id (may be NULL: no identity, resolution unit none) gives the tags that tie the
 * master to its object; x (may be NULL) the linear master, the map and the counts. */
int kg_master_write(const char *cube, const kg_illuminant *ill, kg_icc_space space,
                    kg_icc_version v, const char *path, const unsigned char *lit,
                    const kg_tiff_identity *id, kg_master_extra *x, kg_err *err);

/* The linear profile of a space: its white and primaries with linear curves (gamma 1),
 * described "<space's description> linear (scene-referred, diffuse white 1.0)". */
int kg_icc_linear_profile_bytes(kg_icc_space s, kg_icc_version v, unsigned char **buf,
                                size_t *len, kg_err *err);

/* A camera input profile (ICC version v, class input, matrix/shaper with linear curves) from
 * n >= 3 chart patches: rgb their camera values (linear, 0..1) and xyz their XYZ
 * under D50 (Y = 1 for the perfect diffuser). The matrix is the least-squares fit
 * xyz = M rgb; M (row-major 3 x 3) is returned in m when not NULL. *buf: the profile
 * (caller frees). */
int kg_icc_camera_profile(const double (*rgb)[3], const double (*xyz)[3], int n,
                          const char *description, kg_icc_version v, double m[9],
                          unsigned char **buf, size_t *len, kg_err *err);
/* The profile's matrix alone (no LittleCMS needed): the least-squares xyz = M rgb over
 * the n patches but patch skip (-1: none), for the profile and its leave-one-out. */
int kg_icc_camera_matrix(const double (*rgb)[3], const double (*xyz)[3], int n, int skip,
                         double M[9], kg_err *err);

#endif
