/* Private to devices/libcamera/ (and its tests): libcamera, a C++ library, behind a
 * plain C interface for the driver (libcamera.c). lc_shim.cpp is the only file that
 * includes libcamera's headers.
 *
 * Every function returns 0 (or a count) or a negative KG_E* code with a message in
 * err naming the libcamera call, the field and what was expected; messages do not
 * repeat the camera's URI (camera.c prefixes it). Requests complete on libcamera's
 * own thread; they are handed to kg_lc_pop through a queue under a mutex and a
 * condition variable, and everything else runs on the caller's thread. */
#ifndef KG_LC_SHIM_H
#define KG_LC_SHIM_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* core's error convention; its header has no C++ linkage block of its own */
#include "error.h"

/* ---- the CameraManager ----------------------------------------------------------
 * libcamera allows one per process: the first reference creates and starts it, the
 * last stops and deletes it. Thread-safe. Unless LIBCAMERA_LOG_LEVELS is set, the
 * shim lowers libcamera's logging to errors (its missing-IPA warning is noise). */
int kg_lc_manager_ref(kg_err *err);
void kg_lc_manager_unref(void);
/* References held (0: no manager exists). */
int kg_lc_manager_refs(void);
/* libcamera's version string ("v0.0.3"). */
const char *kg_lc_version(void);

/* Every camera the manager lists, in its order (index is what libcamera:<index>
 * opens); fn may be NULL. Returns the count or a negative code. Takes and drops a
 * manager reference itself. */
typedef void (*kg_lc_camera_fn)(void *user, int index, const char *id, const char *model);
int kg_lc_list(kg_lc_camera_fn fn, void *user, kg_err *err);

/* libcamera's own name of a pixel format (PixelFormat::toString; "<R16 >"-style for a
 * fourcc this libcamera does not know), and the reverse (PixelFormat::fromString;
 * KG_ENOENT for an unknown name). For tests of lc_formats.c. */
void kg_lc_format_name(uint32_t fourcc, uint64_t modifier, char *buf, size_t len);
int kg_lc_format_parse(const char *name, uint32_t *fourcc, uint64_t *modifier);

/* ---- one camera ------------------------------------------------------------------ */
typedef struct kg_lc_camera kg_lc_camera;

typedef struct kg_lc_identity {
	char id[256];             /* libcamera's id */
	char model[64];           /* properties::Model, or "" */
	int sensor_width, sensor_height; /* properties::PixelArraySize, or 0 */
} kg_lc_identity;

/* Open and acquire the camera whose id is target, or whose index in kg_lc_list is
 * target when target is a decimal number and no id equals it. KG_ENODEV when there
 * is none, naming target and how many cameras libcamera sees. */
int kg_lc_open(const char *target, kg_lc_camera **out, kg_lc_identity *who, kg_err *err);
/* Stop if streaming, release, free; *c becomes NULL. Safe on NULL. */
void kg_lc_close(kg_lc_camera **c);

/* Controls kogei drives, set on every request (and at start) from the values last set. */
typedef enum kg_lc_control {
	KG_LC_AE_ENABLE = 0,      /* bool */
	KG_LC_AWB_ENABLE,         /* bool */
	KG_LC_EXPOSURE_TIME,      /* microseconds */
	KG_LC_ANALOGUE_GAIN,      /* x */
	KG_LC_COLOUR_GAIN_RED,    /* ColourGains[0] */
	KG_LC_COLOUR_GAIN_BLUE,   /* ColourGains[1] */
	KG_LC_FRAME_DURATION,     /* microseconds; FrameDurationLimits {d, d}, read back
	                             as FrameDuration */
	KG_LC_NCONTROLS
} kg_lc_control;

/* libcamera's name of the control ("ExposureTime", "ColourGains[0]"). */
const char *kg_lc_control_name(kg_lc_control k);
/* 1 when the camera has the control, with its range (0..1 for bools; 0, 0 when
 * libcamera gives none); 0 when it has not. */
int kg_lc_control_range(kg_lc_camera *c, kg_lc_control k, double *min, double *max);
/* Remember v for every request queued from now on. */
int kg_lc_control_set(kg_lc_camera *c, kg_lc_control k, double v, kg_err *err);
/* The value read back from the metadata of the newest completed request that carried
 * the current settings; until one has completed, the value last set, else the newest
 * metadata of any request, else libcamera's default. KG_ENOENT when none is known. */
int kg_lc_control_get(kg_lc_camera *c, kg_lc_control k, double *v, kg_err *err);

/* A stream configuration as libcamera settled it. */
typedef struct kg_lc_stream {
	uint32_t fourcc;
	uint64_t modifier;
	int width, height;
	unsigned stride, frame_size, buffer_count;
	int raw;                  /* generated for StreamRole::Raw */
} kg_lc_stream;

/* Generate a one-stream configuration (StreamRole::Raw when raw, else StillCapture,
 * or Viewfinder when the camera has no still role), take the first of fourccs[0..n)
 * the stream lists (the first of them when it lists none), the size (0: the role's
 * default) and validate it; the camera is not touched. *got is what validate() left;
 * note (may be NULL) says what it adjusted, "" when nothing. KG_ENOTSUP when the
 * camera has no such role, KG_EINVAL when validate() finds the request invalid. */
int kg_lc_try(kg_lc_camera *c, int raw, const uint32_t *fourccs, int n, int width,
              int height, kg_lc_stream *got, char *note, size_t note_len, kg_err *err);
/* Configure the camera with the configuration kg_lc_try validated last. */
int kg_lc_configure(kg_lc_camera *c, kg_err *err);
/* The formats a role's stream lists, as libcamera names them ("SBGGR10_CSI2P,
 * SBGGR12"), for messages; "none" when the camera has no such role. */
void kg_lc_offered(kg_lc_camera *c, int raw, char *buf, size_t len);

/* Allocate buffers (nbuffers > 0 asks for that many; 0 keeps libcamera's count), map
 * them, create one request per buffer, start and queue them all. */
int kg_lc_start(kg_lc_camera *c, int nbuffers, kg_err *err);
/* Stop (pending requests are cancelled), drop the queue, unmap and free the buffers:
 * data of buffers not yet pushed back is gone. */
int kg_lc_stop(kg_lc_camera *c, kg_err *err);

/* A completed request's buffer. */
typedef struct kg_lc_buffer {
	int slot;                 /* give back with kg_lc_push */
	const void *data;         /* the first plane, mapped read-only */
	size_t bytesused, length;
	uint64_t sequence;        /* FrameMetadata::sequence */
	uint64_t timestamp_ns;    /* FrameMetadata::timestamp */
	int status;               /* 0 success, 1 FrameError, 2 cancelled */
	double exposure_us, gain; /* from the request's metadata; NAN when absent */
} kg_lc_buffer;

/* The next completed request, waiting up to timeout_ms (< 0: no limit).
 * KG_ETIMEDOUT when none completed; KG_ENODEV when the camera was unplugged. */
int kg_lc_pop(kg_lc_camera *c, int timeout_ms, kg_lc_buffer *out, kg_err *err);
/* Reuse the slot's request (Request::reuse(ReuseBuffers)) with the current controls
 * and queue it. Nothing to do once the stream is stopped. */
int kg_lc_push(kg_lc_camera *c, int slot, kg_err *err);
/* Buffers (requests) of the running stream; 0 when stopped. */
int kg_lc_slots(const kg_lc_camera *c);

#ifdef __cplusplus
}
#endif

#endif
