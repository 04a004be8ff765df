/* The interface a camera driver implements (private to devices/). camera.c keeps the
 * registry of drivers by URI scheme, the stream bookkeeping (dropped-frame counting
 * from sequence gaps, timeouts) and the recorder; a driver only talks to its device.
 * Every entry point returns 0 or a negative KG_E* code with a message naming the
 * device and what was expected. Optional entry points may be NULL. */
#ifndef KG_CAMERA_DRIVER_H
#define KG_CAMERA_DRIVER_H

#include "kg_camera.h"
#include "kg_config.h"

typedef struct kg_camera_driver {
	const char *scheme;      /* URI scheme */
	const char *description; /* one line for `kogei devices` */
	/* Optional: report every camera this backend sees (found) or why it cannot look
	 * (return an error). */
	int (*enumerate)(kg_camera_found_fn found, void *user, kg_err *err);
	/* Open the camera named by the part of the URI after "scheme:"; fill info
	 * (backend and uri are filled by camera.c). */
	int (*open)(const char *target, void **state, kg_camera_info *info, kg_err *err);
	void (*close)(void *state);
	int (*feature_info)(void *state, kg_feature f, kg_feature_info *out, kg_err *err);
	int (*get)(void *state, kg_feature f, double *value, kg_err *err);
	int (*set)(void *state, kg_feature f, double value, kg_err *err);
	int (*set_format)(void *state, const kg_frame_format *want, kg_frame_format *got,
	                  kg_err *err);
	int (*get_format)(void *state, kg_frame_format *out, kg_err *err);
	int (*start)(void *state, int nbuffers, kg_err *err);
	int (*stop)(void *state, kg_err *err);
	/* Fill frame (data, size, fmt, sequence, timestamp, status, slot; exposure_us and
	 * gain if the driver knows them per frame, else camera.c fills the last values
	 * read back). KG_ETIMEDOUT when nothing arrived in time. */
	int (*pop)(void *state, int timeout_ms, kg_frame *frame, kg_err *err);
	int (*push)(void *state, kg_frame *frame, kg_err *err);
	/* Optional: driver-level counters (failed, incomplete, resent, missing_packets);
	 * camera.c adds completed, dropped and timeouts. */
	void (*stats)(void *state, kg_stream_stats *out);
	/* Optional: frames left to deliver (a finite source such as files:), else -1. */
	long (*frames_available)(void *state);
	/* Optional: the camera's own live-view image for a focus aid (gphoto2: the
	 * viewfinder, never a full exposure; sim: a quick synthesis), with or without the
	 * stream started. The data stays the driver's until its next preview or close (no
	 * push). Without it kg_camera_preview starts the stream and pops a frame. */
	int (*preview)(void *state, int timeout_ms, kg_frame *frame, kg_err *err);
} kg_camera_driver;

/* One line of a recording's index (camera_recording.c reads them; replay serves them). */
typedef struct kg_rec_frame {
	char *file;  /* relative to the session folder: frames/<capture>/<n>.raw */
	char *capture;
	char sha256[65];
	kg_frame_format fmt;
	size_t bytes;
	uint64_t sequence;
	double timestamp, exposure_us, gain; /* NAN when recorded as null */
	int status;
	int line; /* in index.jsonl */
} kg_rec_frame;
/* Parse and check line lineno of index_path (types, ranges, a safe capture name, a file
 * frames/<capture>/<name> that cannot leave that folder). */
int kg_rec_parse_line(const char *index_path, const char *text, int lineno, kg_rec_frame *fr,
                      kg_err *err);
void kg_rec_frame_clear(kg_rec_frame *fr);
/* The next line of an index read into buf (len bytes), from *pos on, that is complete
 * and not blank: NUL-terminated in place, its number in *lineno (start both at 0);
 * NULL at the end. A last line without its newline is a write that was cut off: not
 * part of the recording. */
char *kg_rec_next_line(char *buf, size_t len, size_t *pos, int *lineno);
/* frames_dir/camera.json: the identity (into info, may be NULL) and the format at start. */
int kg_rec_read_camera(const char *frames_dir, kg_camera_info *info, kg_frame_format *fmt0,
                       kg_err *err);

/* Split a driver's target NAME[?key=value&key=value...]: NAME into name (size n), then
 * option(user, key, value) for each option in order (value NULL when it has no '=').
 * A missing or too long NAME is KG_EINVAL with "expected <usage>, got '<target>'"; an
 * option's own error stops the scan. */
typedef int (*kg_camera_option_fn)(void *user, const char *key, const char *value,
                                   kg_err *err);
int kg_camera_target_split(const char *target, char *name, size_t n, const char *usage,
                           kg_camera_option_fn option, void *user, kg_err *err);

/* Buffers a driver keeps in memory and hands out (sim, replay): held[i] while the
 * caller has buffer i.
 * kg_buffers_count: how many buffers start asks for (nbuffers, or def for 0), refused
 * (KG_EINVAL) above max.
 * kg_buffers_free_slot: the first of the n buffers not held; -1 with err set when the
 * caller holds them all.
 * kg_buffers_release: 0 and held[slot] cleared when the frame's slot is one of the n
 * handed out (and, with data, the frame's data is data[slot]), else KG_EINVAL ("buffer
 * ... was not handed out"). */
int kg_buffers_count(int nbuffers, int def, int max, int *n, kg_err *err);
int kg_buffers_free_slot(const int *held, int n, kg_err *err);
int kg_buffers_release(int *held, void *const *data, int n, const kg_frame *frame,
                       kg_err *err);

extern const kg_camera_driver kg_camera_sim_driver;
extern const kg_camera_driver kg_camera_replay_driver;
extern const kg_camera_driver kg_camera_files_driver;
#if HAVE_V4L2
extern const kg_camera_driver kg_camera_v4l2_driver;
#endif
#if HAVE_ARAVIS
extern const kg_camera_driver kg_camera_aravis_driver;
#endif
#if HAVE_LIBCAMERA
extern const kg_camera_driver kg_camera_libcamera_driver;
#endif
#if HAVE_GPHOTO2
extern const kg_camera_driver kg_camera_gphoto2_driver;
#endif

/* The driver state of an open camera when drv is its driver, else NULL (for a
 * backend's own accessors, e.g. gphoto2_private.h). */
void *kg_camera_driver_state(kg_camera *c, const kg_camera_driver *drv);

/* The recorder behind kg_camera_record_* (camera_record.c; replay: reads its format). */
typedef struct kg_frame_recorder kg_frame_recorder;
int kg_frame_recorder_open(const char *session_dir, const kg_camera_info *info,
                           const kg_frame_format *fmt, kg_frame_recorder **out, kg_err *err);
int kg_frame_recorder_capture(kg_frame_recorder *r, const char *capture, kg_err *err);
int kg_frame_recorder_write(kg_frame_recorder *r, const kg_frame *f, kg_err *err);
int kg_frame_recorder_sync(kg_frame_recorder *r, kg_err *err);
void kg_frame_recorder_last(const kg_frame_recorder *r, char *file, size_t len,
                            char sha256[65]);
int kg_frame_recorder_close(kg_frame_recorder **r, kg_err *err);
/* Shared by the recorder and replay (camera_record.c): the sha256 of a frame's bytes
 * as 64 lower-case hex digits, and a frame format as the JSON object of the index
 * ({"pixfmt","bits","cfa","width","height","offset_x","offset_y","stride","size"}). */
int kg_frame_sha256(const void *data, size_t size, char hex[65]);
json_t *kg_frame_format_json(const kg_frame_format *f);
int kg_frame_format_from_json(const char *file, const json_t *o, kg_frame_format *f,
                              kg_err *err);

#endif
