/* The DNG the PTP replay serves as the captured picture (tests/gphoto2): a tiny
 * uncompressed 16-bit CFA DNG written with libtiff, and the values it holds. */
#ifndef KG_TEST_DNG_FIXTURE_H
#define KG_TEST_DNG_FIXTURE_H

#define DNG_W 64
#define DNG_H 48
#define DNG_BLACK 256
#define DNG_WHITE 4095
#define DNG_CFA "RGGB"
#define DNG_EXPOSURE_NUM 1 /* 1/125 s */
#define DNG_EXPOSURE_DEN 125
#define DNG_ISO 800
#define DNG_MAKE "Kogei"
#define DNG_MODEL "PTP Test Camera"

/* The raw value at (x, y): spans 0..4199, so some pixels are below black and some
 * above white (both clipped in the frame). */
static inline unsigned dng_raw(int x, int y) { return (unsigned)(x * 37 + y * 101) % 4200u; }

/* Write the DNG to path; 0 or -1 (message on stderr). */
int dng_fixture_write(const char *path);

#endif
