/* Cameras behind one driver table (public part of devices/; drivers implement
 * devices/camera_driver.h).
 *
 * A camera is opened by URI:
 *   v4l2:/dev/videoN                 V4L2 capture device, mmap streaming
 *   aravis:<id or address>           GigE Vision / USB3 Vision through Aravis
 *                                    (an IP address is opened without discovery)
 *   libcamera:<id>                   libcamera (C++ shim)
 *   gphoto2:<model or port>[?delete=1&save=DIR]
 *                                    tethered DSLR / mirrorless camera through
 *                                    libgphoto2: one raw capture per frame
 *   replay:<session dir>             the raw frames recorded in a session, served back
 *   sim:[<image.tif>][?k=v&...]      a simulated sensor looking at a linear image
 *
 * Use: kg_camera_open -> set features and format -> kg_camera_start -> kg_camera_pop /
 * kg_camera_push per frame -> kg_camera_stop -> kg_camera_free. Every call returns 0 or
 * a negative KG_E* code with a message naming the camera (its URI), the feature and
 * what was expected; device failures are KG_EIO / KG_ETIMEDOUT / KG_ENODEV. */
#ifndef KG_CAMERA_H
#define KG_CAMERA_H

#include <stddef.h>
#include <stdint.h>

#include "kg_core.h"

/* Pixel formats as delivered by a camera. Samples wider than 8 bits are 16-bit
 * little-endian words holding `bits` significant bits in the low bits (V4L2 Y10/Y12,
 * Bayer 10/12 unpacked, GenICam Mono12/16). */
typedef enum kg_pixfmt {
	KG_PIX_NONE = 0,
	KG_PIX_MONO8,
	KG_PIX_MONO16,  /* bits 10, 12, 14 or 16 */
	KG_PIX_BAYER8,  /* cfa names the 2x2 pattern */
	KG_PIX_BAYER16, /* bits 10, 12, 14 or 16; cfa names the pattern */
	KG_PIX_RGB8,    /* interleaved R G B */
	KG_PIX_RGB16,   /* interleaved R G B, 16-bit words */
	KG_PIX_YUYV,    /* 4:2:2 Y Cb Y Cr, 8 bit (not linear: refused for measurement
	                   unless forced) */
	KG_PIX_MJPEG,   /* compressed, lossy: refused for measurement unless forced */
} kg_pixfmt;

/* "mono8", "mono16", "bayer8", "bayer16", "rgb8", "rgb16", "yuyv", "mjpeg". */
const char *kg_pixfmt_name(kg_pixfmt f);
/* Parse the names above, plus "mono10/12/14", "bayer10/12/14" (setting *bits) and
 * "bayer_rggb8"-style names (setting cfa, 5 bytes). */
int kg_pixfmt_parse(const char *text, kg_pixfmt *f, int *bits, char cfa[5], kg_err *err);

typedef struct kg_frame_format {
	kg_pixfmt pixfmt;
	int width, height;  /* pixels */
	int offset_x, offset_y; /* ROI origin on the sensor (0 when the camera has no ROI) */
	int bits;           /* significant bits per sample (8 for 8-bit formats) */
	char cfa[5];        /* Bayer: "RGGB", "GRBG", "GBRG" or "BGGR"; "" otherwise */
	size_t stride;      /* bytes per row (>= width * bytes per pixel) */
	size_t size;        /* bytes per frame (stride * height, or the JPEG's size bound) */
} kg_frame_format;

/* Bytes per pixel of an uncompressed format (0 for MJPEG). */
int kg_pixfmt_bytes_per_pixel(kg_pixfmt f);
/* Channels after conversion to float: 1 for mono and raw Bayer, 3 for RGB/YUYV. */
int kg_pixfmt_channels(kg_pixfmt f);
/* 1 for formats whose samples are linear sensor values (mono, Bayer, RGB from a
 * machine-vision camera), 0 for YUYV and MJPEG. */
int kg_pixfmt_is_linear(kg_pixfmt f);
/* Fill stride (tight) and size from pixfmt, width, height. */
void kg_frame_format_fill(kg_frame_format *f);

/* Frame status as the driver saw it. */
enum {
	KG_FRAME_OK = 0,
	KG_FRAME_INCOMPLETE = 1, /* packets missing or buffer underrun: do not measure */
	KG_FRAME_CORRUPT = 2,    /* the driver flagged an error on this buffer */
};

/* One frame. `data` points into the driver's buffer until kg_camera_push gives it back. */
typedef struct kg_frame {
	kg_frame_format fmt;
	const void *data;
	size_t size;         /* bytes used (MJPEG: the compressed size) */
	uint64_t sequence;   /* the driver's frame counter; gaps mean dropped frames */
	double timestamp;    /* seconds (device clock when it has one, else CLOCK_MONOTONIC) */
	int status;          /* KG_FRAME_* */
	double exposure_us;  /* settings in force when the frame was taken, as read back */
	double gain;
	const char *source;  /* the file the frame was read from (files:, gphoto2:), else NULL */
	const char *source_note; /* how it was decoded ("DNG 1.4.0.0, LibRaw 0.20.2, ..."),
	                            or NULL */
	int slot;            /* driver's buffer index (private) */
} kg_frame;

/* Features every backend maps onto its own controls. */
typedef enum kg_feature {
	KG_FEAT_EXPOSURE_US = 0,   /* exposure time, microseconds */
	KG_FEAT_GAIN,              /* the camera's own gain unit (see kg_feature_info.unit) */
	KG_FEAT_FRAME_RATE,        /* frames per second */
	KG_FEAT_AUTO_EXPOSURE,     /* 1 on, 0 off */
	KG_FEAT_AUTO_WHITE_BALANCE, /* 1 on, 0 off */
	KG_FEAT_WB_RED,            /* white-balance (colour) gain of red, 1 = none */
	KG_FEAT_WB_BLUE,           /* white-balance (colour) gain of blue, 1 = none */
	/* Photographic cameras (gphoto2:, and raw files through files:): */
	KG_FEAT_ISO,               /* ISO speed (unit "ISO"); the sensor gain of a DSLR */
	KG_FEAT_APERTURE,          /* f-number (unit "f") */
	KG_FEAT_FOCAL_LENGTH,      /* millimetres (unit "mm"), usually read-only */
	KG_FEAT_COUNT
} kg_feature;

/* "exposure_us", "gain", "frame_rate", "auto_exposure", "auto_white_balance",
 * "wb_red", "wb_blue", "iso", "aperture", "focal_length_mm". */
const char *kg_feature_name(kg_feature f);
int kg_feature_parse(const char *text, kg_feature *f, kg_err *err);

typedef struct kg_feature_info {
	int available;       /* the camera has it */
	int writable;
	double min, max, step; /* step 0: continuous */
	char unit[16];       /* "us", "dB", "raw", "fps", "bool", "x" */
	char native[48];     /* the camera's own name: "ExposureTimeAbs", "V4L2_CID_..." */
} kg_feature_info;

/* Stream counters since kg_camera_start. */
typedef struct kg_stream_stats {
	uint64_t completed;   /* frames delivered complete */
	uint64_t failed;      /* frames the driver flagged as failed / corrupt */
	uint64_t incomplete;  /* frames with missing data (underrun, missing packets) */
	uint64_t dropped;     /* gaps in the frame sequence */
	uint64_t resent;      /* packets resent (GigE Vision) */
	uint64_t missing_packets; /* packets never received (GigE Vision) */
	uint64_t timeouts;    /* pops that timed out */
} kg_stream_stats;

/* What a camera says about itself at open. */
typedef struct kg_camera_info {
	char backend[16];    /* URI scheme */
	char uri[512];       /* as opened */
	char vendor[64], model[64], serial[64];
	char transport[32];  /* "GigE Vision", "USB3 Vision", "UVC", "V4L2", "sim", ... */
	char lens[64];       /* the lens, where the camera or file names it; "" otherwise */
	int sensor_width, sensor_height;
} kg_camera_info;

typedef struct kg_camera kg_camera;

/* Open by URI. KG_EINVAL for a malformed URI or unknown scheme, KG_ENOTSUP when the
 * backend is not built in, KG_ENODEV when no such camera is attached. */
int kg_camera_open(const char *uri, kg_camera **out, kg_err *err);
/* Stop the stream if running, close and free; *c becomes NULL. Safe on NULL. */
void kg_camera_free(kg_camera **c);
const kg_camera_info *kg_camera_get_info(const kg_camera *c);

int kg_camera_feature_info(kg_camera *c, kg_feature f, kg_feature_info *out, kg_err *err);
int kg_camera_get(kg_camera *c, kg_feature f, double *value, kg_err *err);
/* Set, then read back; *got (may be NULL) is the value read back. A camera that
 * cannot hold the value within its step gives KG_ERANGE naming the feature and the
 * value it settled at. */
int kg_camera_set(kg_camera *c, kg_feature f, double value, double *got, kg_err *err);
/* Manual, measurement-safe state: auto exposure off, auto white balance off, white
 * balance gains 1 where the camera has them; each is read back and verified. A
 * setting the camera has no control for is skipped; one it refuses is an error. */
int kg_camera_manual(kg_camera *c, kg_err *err);

/* Pixel format and ROI. want->pixfmt/bits/cfa/width/height/offset are requests
 * (0 / KG_PIX_NONE keeps the current value); *got is what the camera settled on. */
int kg_camera_set_format(kg_camera *c, const kg_frame_format *want, kg_frame_format *got,
                         kg_err *err);
int kg_camera_get_format(kg_camera *c, kg_frame_format *out, kg_err *err);

/* Start streaming with nbuffers driver buffers (0: the backend's default). */
int kg_camera_start(kg_camera *c, int nbuffers, kg_err *err);
int kg_camera_stop(kg_camera *c, kg_err *err);
/* Next frame, waiting up to timeout_ms. KG_ETIMEDOUT when none came (counted in
 * stats.timeouts). A frame must be given back with kg_camera_push before the driver
 * can reuse its buffer. */
int kg_camera_pop(kg_camera *c, int timeout_ms, kg_frame *frame, kg_err *err);
int kg_camera_push(kg_camera *c, kg_frame *frame, kg_err *err);
/* A live-view frame (the console's live view, a focus aid): the camera's own preview
 * where its driver has one (gphoto2: libgphoto2's capture preview, the viewfinder
 * image, never a full exposure; sim: the scene with Gaussian noise, paced at the frame
 * rate), else the next frame of the stream, started if it was not (give it back with
 * kg_camera_push as usual). *own is set to 1 for a driver's preview: its data stays
 * the camera's until the next kg_camera_preview, kg_camera_stop or kg_camera_free and
 * is not pushed back. A preview is never recorded and not counted in the stats. */
int kg_camera_preview(kg_camera *c, int timeout_ms, kg_frame *frame, int *own, kg_err *err);
/* 1 when the camera's driver has its own preview (kg_camera_preview does not stream). */
int kg_camera_has_preview(const kg_camera *c);
/* How many frames the camera can still deliver: the files left (files:), or -1 for a
 * camera that delivers as long as it streams. */
long kg_camera_frames_available(kg_camera *c);
/* Counters since start (dropped is derived from sequence gaps by camera.c). */
void kg_camera_stats(kg_camera *c, kg_stream_stats *out);

/* Record every frame popped from now on, with the settings in force, into
 * session_dir/frames/ (format below); replay:<session_dir> serves them back
 * bit-identically. `capture` names the group the next frames belong to
 * ("chart-0001"); kg_camera_record_capture changes it. */
int kg_camera_record_start(kg_camera *c, const char *session_dir, kg_err *err);
int kg_camera_record_capture(kg_camera *c, const char *capture, kg_err *err);
/* The file and sha256 (hex) of the last frame recorded, for a session manifest. */
int kg_camera_record_last(kg_camera *c, char *file, size_t file_len, char sha256[65]);
/* Make every frame recorded so far durable against power loss (one syncfs); call it
 * before a manifest names the frames. Frames are not fsynced one by one: a process
 * killed mid-recording loses nothing already written, and capture boundaries and
 * kg_camera_record_stop sync too. */
int kg_camera_record_sync(kg_camera *c, kg_err *err);
int kg_camera_record_stop(kg_camera *c, kg_err *err);
/* Take a failed capture back out of a stopped recording: the index lines of `capture`
 * and their frame files under frames/<capture>/ go (the index is rewritten to a
 * temporary name and renamed), so replay never serves frames no manifest lists. A
 * session without a recording is left alone. */
int kg_camera_recording_discard(const char *session_dir, const char *capture, kg_err *err);

/* Check a session's recording before anything uses it: frames/camera.json and every
 * complete line of frames/index.jsonl (types and ranges; capture names of 1 to 63 of
 * [A-Za-z0-9._-], not starting with '.'; each file frames/<capture>/<name>, a regular
 * file inside the session whose size is the line's bytes; the sha256 is checked when
 * replay serves the frame). A session without frames/index.jsonl passes. KG_EINVAL
 * naming the file, the line and the field. replay: runs it at open, and so does every
 * reader of a session (kg_session_open, kg_session_manifest_validate). */
int kg_camera_recording_validate(const char *session_dir, kg_err *err);

/* The recording (devices/camera_record.c owns it):
 *   frames/camera.json            identity (kg_camera_info) and the format at start;
 *                                 written to a temporary name and renamed
 *   frames/<capture>/<n>.raw      frame bytes exactly as the driver delivered them;
 *                                 written to a temporary name and renamed
 *   frames/index.jsonl            one JSON object per line, appended (one write) after
 *                                 the frame file is in place: capture, file (relative
 *                                 to the session), sha256, format, bytes, sequence,
 *                                 timestamp, status, exposure_us, gain
 * (details and an example line: docs/cameras.md; the capture is "capture" until named)
 * A line without its newline (a writer killed mid-line) is ignored on read, so a
 * recording interrupted at any point replays every frame that was completed. */

/* Cameras a backend can see: called once per camera. */
typedef void (*kg_camera_found_fn)(void *user, const char *uri, const char *model,
                                   const char *serial, const char *transport);
/* Enumerate every built-in backend that can enumerate; per-backend failures are
 * reported through note (may be NULL) and do not stop the scan. With the environment
 * variable KOGEI_CAMERA_DISCOVERY=none, backends that discover cameras by broadcasting
 * on the network (aravis: GigE Vision) are not scanned (a note says so); tests set it.
 * Other values, or none, scan everything. */
typedef void (*kg_camera_note_fn)(void *user, const char *scheme, const char *message);
void kg_camera_enumerate(kg_camera_found_fn found, kg_camera_note_fn note, void *user);

/* Backends built into this binary. */
int kg_camera_backend_count(void);
const char *kg_camera_backend_scheme(int i);
const char *kg_camera_backend_description(int i);

/* Convert a frame to float samples on 0..1 (divided by 2^bits - 1; RGB and YUYV to
 * 3 channels, Bayer kept raw with its CFA attached). MJPEG and YUYV are refused
 * unless allow_nonlinear; then they are decoded to display-encoded R'G'B' (MJPEG
 * through libjpeg; a damaged stream is an error). *out is a new image. */
int kg_frame_to_image(const kg_frame *f, int allow_nonlinear, kg_image **out, kg_err *err);

#endif
