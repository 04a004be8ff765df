/* Private to calib/: OpenCV's mcc ColorChecker detector (opencv_contrib) behind a C
 * interface, for chart_detect.c's tagless mode. Built only with OpenCV and a C++
 * compiler (KG_HAVE_MCC). */
#ifndef KG_CHART_MCC_H
#define KG_CHART_MCC_H

#ifdef __cplusplus
extern "C" {
#endif

/* core's error convention; its header has no C++ linkage block of its own */
#include "error.h"

/* The corners of mcc's ColorChecker 24 model (MCC24) around its patch centres, in
 * patch pitches beyond the centres of the corner patches: mcc's model draws 2.5-unit
 * cells on a 2.75-unit pitch inside a box 0.25 units beyond the outer cells, so its
 * box edge is 1.5 / 2.75 = 6/11 of a pitch beyond the outer patch centres. */
#define KG_MCC24_BOX_MARGIN_PITCH (6.0 / 11.0)

/* Find the best ColorChecker 24 in an image with cv::mcc::CCheckerDetector.
 * data: interleaved linear floats, width x height x channels (1 or 3, RGB);
 * white: the value shown as white in the 8-bit gamma-encoded (sRGB curve) BGR copy
 * mcc works on; threads: OpenCV worker threads for the call (the previous setting is
 * restored; <= 0 leaves it). box: the four corners of mcc's chart box in pixels,
 * kogei's convention (pixel centres at +0.5), in mcc's order (its first corner is the
 * one it places at the dark-skin patch). cost: mcc's fit cost (may be NULL).
 * 0; KG_ENOENT when mcc finds no chart; KG_ENOMEM or KG_EIO when OpenCV fails. */
int kg_mcc_find_colorchecker(const float *data, int width, int height, int channels,
                             double white, int threads, double box[4][2], double *cost,
                             kg_err *err);

/* The same, up to max charts (mcc's candidates, in its order: the best first): their
 * boxes and costs (costs may be NULL), *found of them. */
int kg_mcc_find_colorcheckers(const float *data, int width, int height, int channels,
                              double white, int threads, int max, double (*boxes)[4][2],
                              double *costs, int *found, kg_err *err);

/* OpenCV's colour conversion tables (mcc converts to Lab; OpenCV builds its tables in
 * software floating point on the first conversion of a process, about a third of the
 * instructions of a whole `kogei chart detect` of 12 Mpix) built on a detached thread
 * of their own, once a process; kg_mcc_find_colorcheckers waits for them if they are
 * still being built. */
void kg_mcc_warm_up(void);
/* Joins the warm-up thread, if one runs: before the caller may exit. */
void kg_mcc_warm_wait(void);

#ifdef __cplusplus
}
#endif

#endif
