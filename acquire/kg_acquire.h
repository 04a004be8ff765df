/* acquire/: capture sessions on top of devices/ cameras (docs/acquire.md).
 *
 * A session is a directory (docs/formats.md, "Capture sessions"):
 *   session.json              the manifest ("kogei-session/1"): station, devices, and one
 *                             entry per completed capture (settings read back, times,
 *                             frames and outputs with their sha256, statistics, the
 *                             dark/flat and demosaicing used)
 *   frames/                   raw frames as the camera delivered them (devices/ recorder,
 *                             kg_camera_record_*), so replay:SESSION serves them again
 *   captures/<name>/          mean.tif and variance.tif (float32), rgb.tif (float32,
 *                             demosaiced, Bayer only)
 * The manifest is rewritten to a temporary name and renamed only after a capture's
 * outputs are in place, so a session killed at any moment holds every completed capture;
 * files of an unfinished capture may exist but are not referenced.
 *
 * A capture: kg_camera_manual, format/ROI, gain, exposure (a number, or the exposure
 * helper), N frames averaged in double precision (Welford) with per-pixel variance,
 * dark subtraction and flat-field correction, clipping and under-exposure statistics,
 * Bayer demosaicing (OpenCV, when built with it). A frame flagged incomplete or
 * corrupt, more dropped frames than allowed, or a timeout ends the capture with an
 * error giving the stream counts; nothing of it enters the manifest. */
#ifndef KG_ACQUIRE_H
#define KG_ACQUIRE_H

#include <stdint.h>

#include "kg_camera.h"
#include "kg_core.h"

#define KG_SESSION_FORMAT "kogei-session/1"
#define KG_SESSION_MANIFEST "session.json"
#define KG_CAPTURE_NAME_MAX 64

/* A sample whose mean is below this fraction of full scale counts as under-exposed. */
#define KG_UNDEREXPOSED_LEVEL 0.02

/* ==== Frame averaging =============================================================== */

/* Accumulates frames of one format: per sample (pixel and channel) the running mean and
 * sum of squared deviations in double precision (Welford's update), and whether any
 * frame reached full scale. Integer formats are accumulated as sensor values (DN) and
 * scaled to 0..1 by 2^bits - 1 at the end; YUYV and MJPEG (only when allow_nonlinear)
 * decoded through kg_frame_to_image. */
typedef struct kg_frame_accum kg_frame_accum;

int kg_frame_accum_new(const kg_frame_format *fmt, int allow_nonlinear, kg_frame_accum **out,
                       kg_err *err);
/* Add one frame; its format must equal the accumulator's (KG_EINVAL otherwise). */
int kg_frame_accum_add(kg_frame_accum *a, const kg_frame *f, kg_err *err);
long kg_frame_accum_count(const kg_frame_accum *a);
/* Mean and per-sample variance of the frames (unbiased, n - 1; 0 for one frame), both
 * on the 0..1 scale (variance in its square), as new float images; Bayer formats keep
 * their CFA pattern attached. Either output may be NULL. */
int kg_frame_accum_result(const kg_frame_accum *a, kg_image **mean, kg_image **variance,
                          kg_err *err);
/* Fraction of samples that reached the saturation level in at least one frame: the
 * level found from the data per channel (CFA position) where the samples pile up below
 * full scale (kg_frame_accum_saturation), else full scale. */
double kg_frame_accum_clipped_fraction(const kg_frame_accum *a);
/* The saturation found in the frames added so far (integer formats; -1 for YUYV/MJPEG
 * or before a frame): per channel, or per CFA position of a Bayer format ("RGGB" order
 * of the format's cfa), the pile-up level and the fraction of samples at it. */
int kg_frame_accum_saturation(const kg_frame_accum *a, kg_saturation *out);
void kg_frame_accum_free(kg_frame_accum **a);

/* ==== Corrections and statistics ===================================================== */

/* mean -= dark (same size and channels). */
int kg_correct_dark(kg_image *mean, const kg_image *dark, kg_err *err);
/* Flat-field: flat is an already dark-subtracted flat capture of the same size. It is
 * low-passed first (kg_flat_smooth: the board's texture and the flat's own noise are
 * not the light's). Each colour (channel for RGB, CFA colour for a Bayer mosaic, the
 * one channel for mono) is normalised to its mean over the valid flat samples (finite
 * and above 5 % of that mean), and mean /= normalised smoothed flat, variance /= its
 * square (variance may be NULL). Samples where the smoothed flat is not valid become
 * NaN; *invalid (may be NULL) counts them. */
int kg_correct_flat(kg_image *mean, kg_image *variance, const kg_image *flat, long *invalid,
                    kg_err *err);
/* A flat sample below this fraction of its colour's mean is not usable (dust, a dead
 * pixel, the edge of the illumination). */
#define KG_FLAT_VALID_FRACTION 0.05

/* The flat low-passed: per colour class (kg_colour_class), the mean of its valid
 * samples (finite, above 0) over blocks of block x block pixels, block =
 * max(KG_FLAT_BLOCK_MIN, the image's short side / KG_FLAT_BLOCK_DIVISOR, rounded; a
 * multiple of a mosaic's CFA tile),
 * read between block centres bilinearly (linearly extrapolated from the two outermost
 * centres in the border half-blocks, so a fall-off towards the edge is followed). A
 * box filter of that size and a linear interpolation: it keeps the light's slow
 * variation (lamp fall-off, vignetting) and removes what varies within a few pixels
 * (the board's texture, dust on it, the flat's noise). Built row by row
 * (kg_flat_smooth_add, rows in order), so a flat need not be held whole. */
#define KG_FLAT_BLOCK_DIVISOR 32
#define KG_FLAT_BLOCK_MIN 4
typedef struct kg_flat_smooth {
	int width, height, channels, block, gw, gh;
	char cfa[17];
	int cfa_rows, cfa_cols;
	double *sum[4];  /* gw x gh per colour class; after kg_flat_smooth_finish, means
	                  * (NaN where a block has no valid sample) */
	long *count[4];
	double lo[4], hi[4]; /* the smallest and largest block mean per class (NaN: none) */
	double ox[4], oy[4]; /* a mosaic colour's mean place in its CFA tile, from the
	                      * tile's centre: its block means sit there, not at the centres */
	int finished;
} kg_flat_smooth;
int kg_flat_smooth_init(kg_flat_smooth *s, int width, int height, int channels,
                        const char *cfa, int cfa_rows, int cfa_cols, kg_err *err);
/* nrows rows from row y0 (width x channels samples each). */
void kg_flat_smooth_add(kg_flat_smooth *s, const float *rows, int y0, int nrows);
void kg_flat_smooth_finish(kg_flat_smooth *s);
/* The smoothed flat at sample `channel` of pixel (x, y) (NaN where no block near it
 * has a valid sample). */
double kg_flat_smooth_at(const kg_flat_smooth *s, int channel, int x, int y);
void kg_flat_smooth_free(kg_flat_smooth *s);
/* A flat is refused when more than this share of its samples reached the sensor's
 * saturation when it was taken (its statistics.clipped_fraction: judged on the codes,
 * the level found from the data): where it clipped, it does not measure the light. */
#define KG_FLAT_MAX_CLIPPED 0.001
/* ... and when the smoothed flat's smallest block mean is below this fraction of its
 * largest, in any colour: the dimmest part of the frame gets less than 40 % of the
 * brightest part's light (its noise is raised 2.5 x by the division, and light that
 * uneven is rarely smooth; light the object evenly, centre the lamp, stop down). */
#define KG_FLAT_MIN_RATIO 0.4
/* Refuse a flat (name: the capture's, for the message) that is clipped or too uneven,
 * naming which and by how much; clipped_fraction NaN when not recorded. *ratio (may be
 * NULL) gets the smallest min/max ratio of its colours. */
int kg_flat_check(const kg_flat_smooth *s, double clipped_fraction, const char *name,
                  double *ratio, kg_err *err);
/* The same for a flat in memory. */
int kg_flat_check_image(const kg_image *flat, double clipped_fraction, const char *name,
                        double *ratio, kg_err *err);
/* The illuminance non-uniformity of a flat capture (FADGI's "illuminance
 * non-uniformity", docs/acquire.md): each colour normalised to its mean over the
 * valid samples, the frame cut into KG_FLAT_BLOCKS x KG_FLAT_BLOCKS blocks, and the
 * largest deviation of a block mean from the mean of the blocks, relative to it
 * (0.03: 3 %). NaN when no block has a valid sample. */
#define KG_FLAT_BLOCKS 8
int kg_flat_nonuniformity(const kg_image *flat, double *out, kg_err *err);
/* The colour class the flat normalises sample `channel` of pixel (x, y) by: the channel
 * of an image of several, the CFA letter of a mosaic (R 0, G 1, B 2, others 3; cfa of
 * rows x cols letters), 0 for mono (cfa NULL). */
int kg_colour_class(int channels, const char *cfa, int cfa_rows, int cfa_cols, int channel,
                    size_t x, size_t y);

typedef struct kg_image_stats {
	double min, max;
	double p01, p50, p99, p999; /* percentiles 1, 50, 99, 99.9 of the finite samples */
	double underexposed_fraction; /* of samples below KG_UNDEREXPOSED_LEVEL */
	long nonfinite;               /* NaN or Inf samples (left out of the above) */
} kg_image_stats;

int kg_image_stats_compute(const kg_image *img, kg_image_stats *out, kg_err *err);

/* The robust bright level of an image (the exposure helper's measure without a chart
 * detector): each sample is replaced by the mean of the (2 radius + 1)^2 samples of the
 * same colour around it (same channel; same CFA site for a mosaic), and the given
 * percentile (0..100) of those is returned. */
int kg_bright_level(const kg_image *img, int radius, double percentile, double *level,
                    kg_err *err);
#define KG_BRIGHT_RADIUS 2
#define KG_BRIGHT_PERCENTILE 99.5

/* Demosaicing of a float Bayer mosaic (1 channel with a 2x2 CFA) into RGB with OpenCV
 * (bilinear, cv::demosaicing on a 16-bit copy scaled to the mosaic's range; the step of
 * that scaling goes to *step). KG_ENOTSUP when kogei was built without OpenCV.
 * kg_demosaic_algorithm() names the method, or NULL without OpenCV. */
int kg_demosaic(const kg_image *mosaic, kg_image **rgb, double *step, kg_err *err);
/* The same with the 16-bit scaling over [lo, hi] given: a band of rows of a larger
 * mosaic, scaled over the whole mosaic's range and cut at least 2 rows inside the band,
 * demosaics exactly as the whole would (bilinear: each output reads a 3 x 3 window). */
int kg_demosaic_range(const kg_image *mosaic, double lo, double hi, kg_image **rgb,
                      double *step, kg_err *err);
const char *kg_demosaic_algorithm(void);

/* ==== Sessions ======================================================================= */

typedef struct kg_session kg_session;

/* Validate a session's manifest root, read from file (DIR/session.json), and the
 * session around it: the format; devices.cameras entries (strings, sizes, unique ids);
 * every capture's name (1 to KG_CAPTURE_NAME_MAX - 1 of [A-Za-z0-9._-], not starting
 * with '.', unique), kind, camera id, times, settings (exposure_us > 0 or null, gain a
 * number or null, frames >= 1, format: a known pixfmt, bits 1..32, width and height
 * >= 1, offsets >= 0), its frames (frames/<name>/...), exposure-helper steps and
 * outputs (captures/<name>/..., a "mean" among them) as {file, sha256} entries whose
 * file is a relative path that cannot leave the session and names a regular file in
 * it; corrections.dark / .flat null or an earlier capture of that kind; then the
 * recording (kg_camera_recording_validate). KG_EINVAL naming file, the key and what
 * was expected. Every reader of a session calls it: kg_session_open,
 * kg_session_image_identify, replay: (the recording part), kogei process. */
int kg_session_manifest_validate(const char *file, const json_t *root, kg_err *err);
/* 1 when id is a session id: a UUID in lower-case hexadecimal, 8-4-4-4-12. A session's
 * manifest holds one ("id", made at its creation, or added at the next capture to a
 * session recorded before ids): the session is the same wherever it is moved. */
int kg_session_id_ok(const char *id);

/* Open a session directory, creating it (and a new manifest in memory) when absent;
 * an existing manifest is read, validated (kg_session_manifest_validate) and captures
 * are appended; a recording without a manifest is validated too. A directory without a
 * manifest that holds anything other than a session's files is refused (it is not a
 * session); a session's own folder may hold files kogei did not write (the chart's
 * spectra measured into it, notes), which are kept and listed (kg_session_foreign).
 * The session is locked (flock on DIR/.lock) until kg_session_free: a second writer
 * gets KG_EINVAL naming the lock. */
int kg_session_open(const char *dir, kg_session **out, kg_err *err);
/* The entries of the session's folder that kogei did not write, "a, b and 3 more"
 * ("" when none): not part of the session's record (no sha256 in the manifest). */
const char *kg_session_foreign(const kg_session *s);
void kg_session_free(kg_session **s);
const char *kg_session_dir(const kg_session *s);
/* The manifest (borrowed; valid until the next append or free). */
const json_t *kg_session_manifest(const kg_session *s);
/* The capture entry named name, or NULL. */
const json_t *kg_session_find(const kg_session *s, const char *name);
/* Check every file the manifest references exists and has its recorded sha256.
 * KG_EIO naming the first file that does not. *nfiles (may be NULL): files checked. */
int kg_session_verify(const kg_session *s, long *nfiles, kg_err *err);

/* The capture an image file of a session belongs to and the camera that took it. */
typedef struct kg_session_image {
	char session[4096];             /* the session directory (resolved) */
	char capture[KG_CAPTURE_NAME_MAX];
	char backend[16];               /* devices.cameras entry of the capture */
	char model[64], serial[64];
	char pixfmt[16];                /* settings.format.pixfmt ("bayer16", "rgb16") */
	int bits;                       /* settings.format.bits */
	long white_level;               /* full scale: 2^bits - 1 (4095 for 12 bits) */
	char demosaic[128];             /* demosaic.algorithm, "none" when not demosaiced */
} kg_session_image;

/* Identify an image file inside a session: SESSION/captures/<name>/<file> (mean.tif,
 * rgb.tif, variance.tif), the session being the nearest directory above the file
 * holding a session.json of format kogei-session/1. KG_ENOENT when the file is not
 * in a session's captures/ (an image from elsewhere: its camera is unknown);
 * KG_EINVAL, naming the manifest and the key, when the manifest does not list the
 * capture (an unfinished one) or its camera, or fails kg_session_manifest_validate. */
int kg_session_image_identify(const char *image_path, kg_session_image *out, kg_err *err);

/* sha256 of a file as 64 lower-case hex digits. */
int kg_file_sha256(const char *path, char hex[65], kg_err *err);

/* ==== Captures ======================================================================= */

typedef enum kg_capture_kind {
	KG_CAPTURE_CHART = 0,
	KG_CAPTURE_OBJECT,
	KG_CAPTURE_DARK,
	KG_CAPTURE_FLAT,
	KG_CAPTURE_BACKGROUND, /* the scene without the object: kogei process masks the
	                          objects by their difference from it */
} kg_capture_kind;

/* "chart", "object", "dark", "flat", "background". */
const char *kg_capture_kind_name(kg_capture_kind k);
int kg_capture_kind_parse(const char *text, kg_capture_kind *out, kg_err *err);

/* The exposure helper's measure: the level (0..1 of full scale) of the brightest chart
 * patch in a frame (1 channel, possibly a mosaic with its CFA, or 3). Return KG_ENOENT
 * when no chart is found (the helper then uses kg_bright_level for that frame). */
typedef int (*kg_level_fn)(void *user, const kg_image *frame, double *level, kg_err *err);

/* Progress of the averaging: frame i of n, frames per second so far. */
typedef void (*kg_capture_progress_fn)(void *user, const char *name, int i, int n,
                                       double fps);

typedef struct kg_capture_options {
	kg_capture_kind kind;
	const char *name;        /* NULL: "<kind>-NNNN", the next free number */
	int frames;              /* averaged, >= 1 (default 10) */
	double exposure_us;      /* > 0 sets it; 0 keeps the camera's (read back) */
	int auto_exposure;       /* 1: the exposure helper (exposure_us is ignored) */
	double target;           /* helper: level of the brightest patch, 0..1 (0.8) */
	int max_iterations;      /* helper: frames measured at most (10) */
	kg_level_fn measure;     /* helper: chart measure, or NULL for kg_bright_level */
	void *measure_user;
	const char *measure_name; /* described in the manifest ("chart cie-tcs-frame") */
	const char *chart_layout; /* the chart's layout (path or name), recorded in the
	                           * manifest as "chart_layout"; NULL: none */
	const json_t *meta;      /* the object record (kg_meta_*), stored as the capture's
	                          * "meta"; NULL or empty: none */
	double gain;             /* NAN keeps the camera's gain */
	kg_frame_format format;  /* pixfmt/bits/cfa/width/height/offset requests (0 keeps) */
	const char *dark;        /* NULL: the latest matching dark of the session (if any);
	                          * "none": no dark; else a capture name */
	const char *flat;        /* NULL or "latest": the session's newest flat of this
	                          * camera, format and size (none when it has none; for a
	                          * chart, object or background capture); "none"; else a
	                          * capture name (a warning note when a newer flat exists) */
	int timeout_ms;          /* per frame; 0: 2000 ms plus twice the exposure */
	long max_dropped;        /* dropped frames tolerated (0) */
	int force_nonlinear;     /* accept YUYV and MJPEG */
	int record;              /* record the raw frames into the session (1) */
	kg_capture_progress_fn progress;
	void *progress_user;
	/* Notes for the operator (dark chosen, clipping, ...), one sentence each. */
	void (*note)(void *user, const char *message);
	void *note_user;
} kg_capture_options;

void kg_capture_options_default(kg_capture_options *o);

/* One iteration of the exposure helper. */
typedef struct kg_exposure_step {
	double exposure_us; /* read back */
	double level;       /* measured, 0..1 */
	int chart;          /* 1: measured on the chart, 0: kg_bright_level */
} kg_exposure_step;
#define KG_EXPOSURE_MAX_STEPS 32

typedef struct kg_capture_result {
	char name[KG_CAPTURE_NAME_MAX];
	kg_image *mean;      /* corrected mean (dark, flat) */
	kg_image *variance;  /* per-sample variance of the frames (flat applied) */
	kg_image *rgb;       /* demosaiced mean (Bayer with OpenCV), else NULL */
	kg_frame_format format; /* as read back */
	double exposure_us, gain;
	kg_stream_stats stream;
	double clipped_fraction; /* samples at the saturation level (found from the data) */
	kg_saturation saturation; /* per channel / CFA position; channels 0 when unknown */
	kg_image_stats stats; /* of the uncorrected mean */
	long flat_invalid;
	double illuminance_nonuniformity; /* a flat capture's (kg_flat_nonuniformity), else NaN */
	char dark[KG_CAPTURE_NAME_MAX], flat[KG_CAPTURE_NAME_MAX]; /* "" when none */
	int nsteps;
	kg_exposure_step steps[KG_EXPOSURE_MAX_STEPS];
	int device_failure;  /* the error came from the camera (stream, timeout, drops) */
} kg_capture_result;

/* Take one capture with an open (not streaming) camera into the session and append it
 * to the manifest. On failure nothing is added to the manifest and no output file is
 * left; res->device_failure says whether the camera failed (exit 3) or the request
 * (exit 1). res is filled on success; free it with kg_capture_result_clear. */
int kg_capture_run(kg_session *s, kg_camera *cam, const kg_capture_options *o,
                   kg_capture_result *res, kg_err *err);
void kg_capture_result_clear(kg_capture_result *r);

#endif
