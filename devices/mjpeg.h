/* Motion-JPEG decoding for cameras that offer nothing better (UVC webcams). MJPEG is
 * compressed, lossy and display-encoded: kogei refuses it for measurement unless the
 * user forces non-linear data (--force-nonlinear). */
#ifndef KG_MJPEG_H
#define KG_MJPEG_H

#include <stddef.h>
#include <stdint.h>

#include "error.h"

/* 1 when this binary was built with libjpeg. */
int kg_mjpeg_available(void);

/* Decode one JPEG frame of the expected size into rgb (width * height * 3 bytes,
 * R'G'B' rows without padding). Missing Huffman tables (as UVC sends them) use the
 * standard ones. A stream of another size, a truncated or damaged stream (any decoder
 * warning), or a build without libjpeg is an error naming the frame's size. */
int kg_mjpeg_decode(const uint8_t *data, size_t size, int width, int height, uint8_t *rgb,
                    kg_err *err);

#endif
