/* Camera raw files (DNG, CR2, CR3, NEF, ARW, IIQ, ...) decoded linearly through LibRaw.
 *
 * Only the colour filter array data is read, with nothing that breaks linearity: no
 * white balance, no tone curve, no automatic brightness, no highlight recovery, no
 * demosaicing. Each sample becomes (raw - black) / (white - black) as a float, where
 * black is the file's black level for that CFA colour and position (LibRaw's common
 * black, per-channel black and black pattern; for formats whose black comes from the
 * sensor's masked area, the masked-area black LibRaw measured) and white the white
 * level (per channel where the file gives one). Values below black stay negative, so
 * averages of dark pixels are not biased; values above white are kept (>= 1: clipped).
 * The image has one channel and the CFA pattern attached (kg_image.cfa), the visible
 * area only (masked margins cut off).
 *
 * Refused with the reason (KG_ENOTSUP): files LibRaw decodes only to RGB (sRAW/mRAW,
 * linear or lossy DNG, Foveon), non-Bayer mosaics (Fujifilm X-Trans), lossy raw
 * encodings, and anything when kogei was built without LibRaw. Truncated or damaged
 * files are KG_EINVAL naming the file. */
#ifndef KG_RAW_H
#define KG_RAW_H

#include <stddef.h>

#include "error.h"
#include "image.h"

/* What a raw file says about how it was taken (NAN or "" where it says nothing). */
typedef struct kg_raw_meta {
	char format[32];       /* "DNG", "Canon CR2", ... (LibRaw's decoder, for people) */
	char make[64], model[64], serial[64], lens[64];
	double exposure_s;     /* exposure time, seconds */
	double iso;            /* ISO speed */
	double aperture;       /* f-number */
	double focal_length_mm;
	long long timestamp;   /* seconds since the epoch (camera clock), 0 when unknown */
	char cfa[5];           /* "RGGB", "GRBG", "GBRG" or "BGGR" (the visible area's) */
	double black[4];       /* black level per CFA position (row-major in the 2x2) */
	double white[4];       /* white level per CFA position */
	int raw_bits;          /* bits needed for the white level (12, 14, 16) */
	int width, height;     /* visible area */
} kg_raw_meta;

/* 1 when kogei was built with LibRaw. */
int kg_raw_available(void);
/* LibRaw's version ("0.20.2"), or NULL without LibRaw. */
const char *kg_raw_version(void);

/* 1 when path looks like a camera raw file: a raw extension (.dng .cr2 .cr3 .crw .nef
 * .nrw .arw .srf .sr2 .orf .rw2 .raf .pef .iiq .3fr .fff .erf .kdc .dcr .mos .mef .mrw
 * .srw .x3f .rwl), or a TIFF whose first IFD carries DNGVersion. Reads at most the
 * TIFF header and first IFD. */
int kg_raw_is_raw(const char *path);

/* Decode a raw file (or one in memory; name is used in messages). *out is a new
 * 1-channel float image with its CFA; meta (may be NULL) is filled. */
int kg_raw_read(const char *path, kg_image **out, kg_raw_meta *meta, kg_err *err);
int kg_raw_read_memory(const void *data, size_t size, const char *name, kg_image **out,
                       kg_raw_meta *meta, kg_err *err);
/* Only the metadata, without decoding the pixel data (black, white and raw_bits stay
 * 0: LibRaw knows them after decoding); a file decoding would refuse for its mosaic is
 * refused here too. */
int kg_raw_read_meta(const char *path, kg_raw_meta *meta, kg_err *err);

#endif
