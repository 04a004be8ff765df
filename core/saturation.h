/* Saturation found from the data.
 *
 * A sensor (or its converter) can stop short of the nominal white level: a 12-bit
 * sensor that saturates at 4092 of 4095, a raw file whose white level comes from a
 * camera table rather than the file, an analogue gain that makes the ADC's top
 * unreachable. Such samples are clipped although they sit below full scale, and a
 * test "value >= full scale" misses them.
 *
 * Clipping leaves a mark in every channel's histogram: the samples a brighter scene
 * would have spread above the ceiling pile up in the highest occupied bin(s), while a
 * natural distribution thins out towards its top. kg_saturation_detect looks at the
 * top of one channel's histogram (one bin per quantisation step of the data, or
 * coarser codes spaced evenly in it, such as a 12-bit raw scaled to 16 bits: the
 * "code spacing", the most common gap between occupied bins, scales the windows):
 * the highest occupied codes (a cluster of KG_SAT_CLUSTER_BINS, for a ceiling that
 * jitters by a count or two) must hold
 *   - at least KG_SAT_MIN_COUNT samples and KG_SAT_MIN_FRACTION of the channel's, and
 *   - more than KG_SAT_RATIO times the mean count of the occupied bins in the window
 *     of KG_SAT_WINDOW_FRACTION of full scale just below the cluster,
 * and that window (at least 8 codes) must be occupied in at least KG_SAT_MIN_OCCUPANCY
 * of the codes it can hold (the
 * distribution runs into the ceiling: a noise-free synthetic patch that happens to be
 * the brightest thing in an image is a spike with an empty window under it, not a
 * clipped one). The level is the lowest bin of the cluster that is itself a pile-up;
 * samples at or above it, less half a quantisation step, are clipped.
 *
 * Two guards against flat synthetic objects (noise-free renders, where a patch is one
 * value in every channel): a ceiling below KG_SAT_MIN_LEVEL of full scale is not taken
 * for saturation, and in an RGB image a channel's pile-up whose pixels are flat (within
 * half a step) in another channel that is not clipped there is an object, not a
 * ceiling: a real sensor's unclipped channel always carries noise. A noise-free image
 * whose brightest object is flat in all channels above KG_SAT_MIN_LEVEL still reads as
 * saturated there; a clip level given by the user (--clip-level) replaces the search. */
#ifndef KG_SATURATION_H
#define KG_SATURATION_H

#include <stddef.h>
#include <stdint.h>

#include "image.h"

#define KG_SAT_CLUSTER_BINS 3
#define KG_SAT_MIN_COUNT 16
#define KG_SAT_MIN_FRACTION 1e-4
#define KG_SAT_RATIO 8.0
#define KG_SAT_WINDOW_FRACTION 0.01
#define KG_SAT_MIN_OCCUPANCY 0.1
#define KG_SAT_MIN_LEVEL 0.75

/* The most channels a saturation search reports (4 CFA positions, or 3 colours). */
#define KG_SAT_MAX_CHANNELS 4

/* One channel's histogram, bins 0..nbins-1 (bin nbins-1 is the nominal white, samples
 * above it counted there). Returns the bin where samples pile up, or -1 when there is
 * no pile-up. */
int kg_saturation_detect(const uint64_t *hist, int nbins);

/* What the data say about each channel of an image. */
typedef struct kg_saturation {
	int channels;                        /* channels (or CFA positions) searched */
	int found[KG_SAT_MAX_CHANNELS];      /* 1: a pile-up below or at the nominal white */
	double level[KG_SAT_MAX_CHANNELS];   /* where samples pile up, on the 0..1 scale */
	double clip[KG_SAT_MAX_CHANNELS];    /* samples >= this are clipped (the level less
	                                      * half a step; the nominal clip when not found) */
	double fraction[KG_SAT_MAX_CHANNELS];/* of the channel's samples >= clip */
	double fraction_any;                 /* of pixels with any channel >= its clip */
	int steps;                           /* quantisation steps of full scale (bins - 1) */
	double nominal;                      /* the nominal clip level searched below */
} kg_saturation;

/* The flat-object guard over an RGB image's pixels, in bands (see above). */
typedef struct kg_sat_flat {
	kg_saturation sat;
	uint64_t piled[3];
	uint64_t n[3][3];
	double ref[3][3], sum[3][3], sumsq[3][3];
} kg_sat_flat;
void kg_sat_flat_init(kg_sat_flat *f, const kg_saturation *s);
void kg_sat_flat_add(kg_sat_flat *f, const float *px, size_t n);
/* The levels with flat objects' pile-ups dropped; returns 1 when one was dropped. */
int kg_sat_flat_result(const kg_sat_flat *f, kg_saturation *out);

/* The histogram resolution of an image's values: 2^bits - 1 steps for integer
 * sources of 8..16 bits (one bin per count), 65535 for float or unknown depths. */
int kg_saturation_steps(const kg_image *img);

/* An accumulator over values on the 0..1 scale, channel by channel. */
typedef struct kg_sat_hist {
	int channels, steps;
	uint64_t *bins[KG_SAT_MAX_CHANNELS]; /* steps + 1 each, and one more the scan uses
	                                      * for the samples it leaves out */
	uint64_t total[KG_SAT_MAX_CHANNELS];
} kg_sat_hist;

int kg_sat_hist_init(kg_sat_hist *h, int channels, int steps, kg_err *err);
void kg_sat_hist_free(kg_sat_hist *h);
/* n pixels of h->channels interleaved values (non-finite ones skipped). */
void kg_sat_hist_add(kg_sat_hist *h, const float *px, size_t n);
/* One sample of channel c. */
void kg_sat_hist_add1(kg_sat_hist *h, int c, double v);
/* The levels from the histograms; nominal_clip is the clip level where nothing piles
 * up below it (e.g. 1.0, or the user's --clip-level): a pile-up found above it does
 * not raise it. fraction_any stays 0 (it needs the pixels: see kg_saturation_count). */
void kg_sat_hist_result(const kg_sat_hist *h, double nominal_clip, kg_saturation *out);

/* The whole search on an image in memory: per channel of a 3-channel image, per CFA
 * position of a 1-channel image with a 2x2 CFA (per channel otherwise, up to 4), with
 * the clipped fractions counted. */
int kg_saturation_of_image(const kg_image *img, double nominal_clip, kg_saturation *out,
                           kg_err *err);
/* The same for a mapped 16-bit image (kg_image_map), which kg_saturation_of_image
 * hands to it: the same results, counted on the codes. */
int kg_saturation_of_u16(const kg_image *img, double nominal_clip, kg_saturation *out,
                         kg_err *err);
/* The same over a row source (read top to bottom once, in bands). */
int kg_saturation_of_rows(const kg_row_source *src, int steps, double nominal_clip,
                          kg_saturation *out, kg_err *err);

/* "R 0.99927 (1.50 %), G -, B -" style summary of the channels where a pile-up was
 * found, or "" when none. names: one letter per channel ("RGB", "RGGB"). */
void kg_saturation_format(const kg_saturation *s, const char *names, char *buf, size_t n);
/* 1 when a pile-up was found in a channel below nominal_clip. */
int kg_saturation_below(const kg_saturation *s, double nominal_clip);

#endif
