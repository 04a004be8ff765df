/* The pure parts of the gphoto2 backend (of libgphoto2 only its result codes; unit-tested in
 * tests/gphoto2): the camera's choice strings of its radio/menu settings read as numbers,
 * the exact choice for a value (or the nearest ones in the error), raw image formats and
 * file names, exposure programs, and the raw image to a 16-bit Bayer frame. */
#ifndef KG_GP_CHOICES_H
#define KG_GP_CHOICES_H

#include <stddef.h>
#include <stdint.h>

#include "kg_camera.h"

/* A choice string of the setting behind feature f as a number in the feature's unit:
 *   KG_FEAT_EXPOSURE_US  "1/125", "1/1.6", "0.3", "2", "30", "2s", "30\"", "1/250s" -> us
 *   KG_FEAT_ISO          "100", "ISO 400", "6400"                          -> ISO
 *   KG_FEAT_APERTURE     "f/5.6", "F5.6", "5.6"                            -> f-number
 *   KG_FEAT_FOCAL_LENGTH "50", "50mm", "50 mm", "24.5"                     -> mm
 * 1 with *value set when the text is such a number, 0 for anything else ("Auto",
 * "Bulb", "Time", "x 250", "implicit auto", ""), which no number can select. */
int kg_gp_choice_value(kg_feature f, const char *text, double *value);
/* The unit kogei gives a feature: "us", "ISO", "f", "mm"; "bool" for the others. */
const char *kg_gp_unit(kg_feature f);

/* Numeric choices among n: how many, and their smallest and largest value (0 and 0
 * when none). */
int kg_gp_choice_range(kg_feature f, const char *const *choices, int n, double *min,
                       double *max);

/* The index of the one choice equal to value (relative 1e-6; exposure also within
 * 0.5 us, so whole microseconds select 1/3 s), the first when several are. Otherwise
 * KG_ERANGE: "<config> has no choice for <value> <unit>; nearest: A (a unit) and B (b
 * unit)" (the nearest below and above, or the only one on one side); KG_ENOTSUP when no
 * choice is a number. */
int kg_gp_choice_pick(kg_feature f, const char *config, const char *const *choices, int n,
                      double value, int *index, kg_err *err);

/* 1 when an image format / quality choice delivers a raw file kogei can decode
 * ("RAW", "RAW + Large Fine JPEG", "NEF (Raw)", "NEF+Basic", "cRAW", "ARW", "DNG"),
 * 0 for JPEG/HEIF/TIFF only and for Canon's reduced sRAW/mRAW (demosaiced: not CFA). */
int kg_gp_is_raw_choice(const char *text);
/* 1 when a file name has a camera raw extension (.dng .cr2 .cr3 .nef .arw ...). */
int kg_gp_is_raw_name(const char *name);
/* 1 when an exposure program choice is manual ("M", "Manual", "Bulb"), where the
 * camera does not choose the exposure itself. */
int kg_gp_program_is_manual(const char *text);

/* The error of a camera that could not be opened (gp_camera_init failed with gpret,
 * gp_text its name, detail libgphoto2's own message or NULL): permission denied on the
 * USB device node (denied: node exists and cannot be opened read-write for want of
 * permission) -> install libgphoto2's udev rules; the interface claimed by another
 * program -> close it (gvfs, `gio mount -s gphoto2`); device gone -> KG_ENODEV;
 * anything else KG_EIO. Each message names the camera and its port. */
int kg_gp_open_error(const char *model, const char *port, const char *node, int denied,
                     int gpret, const char *gp_text, const char *detail, kg_err *err);

/* A decoded raw (1 channel, values (raw-black)/(white-black)) to BAYER16 samples:
 * round(clamp(v, 0, 1) * 65535) as little-endian 16-bit words, n samples (2n bytes);
 * NaN becomes 0. */
void kg_gp_to_bayer16(const float *in, size_t n, uint8_t *out);

#endif
