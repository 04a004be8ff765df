/* Private to acquire/: OpenCV's demosaicing behind a C interface (demosaic_cv.cpp),
 * built only with OpenCV and a C++ compiler (KG_HAVE_DEMOSAIC). */
#ifndef KG_DEMOSAIC_CV_H
#define KG_DEMOSAIC_CV_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* core's error convention; its header has no C++ linkage block of its own */
#include "error.h"

/* Bilinear demosaicing (cv::demosaicing, COLOR_Bayer<cfa>2RGB) of a 16-bit mosaic
 * (width x height, row-major) whose top-left 2x2 repeat is cfa ("RGGB", "GRBG",
 * "GBRG", "BGGR") into interleaved 16-bit RGB (width x height x 3). */
int kg_cv_demosaic_u16(const uint16_t *mosaic, int width, int height, const char *cfa,
                       uint16_t *rgb, kg_err *err);
/* "OpenCV <version> cv::demosaicing bilinear (COLOR_Bayer*2RGB)". */
const char *kg_cv_demosaic_name(void);

#ifdef __cplusplus
}
#endif

#endif
