/* Private to acquire/: the session internals capture.c uses. */
#ifndef KG_ACQUIRE_PRIVATE_H
#define KG_ACQUIRE_PRIVATE_H

#include "kg_acquire.h"

/* Names that stay one path component everywhere: [A-Za-z0-9._-], not starting with a
 * dot, shorter than KG_CAPTURE_NAME_MAX. */
int kg_capture_name_ok(const char *name);

/* The next free "<kind>-NNNN" (not in the manifest, no frames/ or captures/ folder). */
int kg_session_next_name(const kg_session *s, const char *kind, char name[KG_CAPTURE_NAME_MAX],
                         kg_err *err);
/* A name the user chose: refused when the manifest has it or an interrupted capture
 * left files under it. */
int kg_session_check_name(const kg_session *s, const char *name, kg_err *err);

/* DIR/rel (caller frees). */
char *kg_session_path(const kg_session *s, const char *rel);

/* Append a capture entry (stolen) taken with the camera described by info (added to
 * devices.cameras when new; the entry gets its "camera" id): the manifest is written to
 * a temporary name, renamed over session.json and the directory synced. On failure the
 * session is unchanged. */
int kg_session_append(kg_session *s, const kg_camera_info *info, json_t *capture,
                      kg_err *err);

/* The current time, UTC, ISO 8601 with milliseconds ("2025-01-31T12:00:00.123Z"). */
void kg_utc_now(char buf[32]);

/* fsync a directory (after a rename in it). */
int kg_sync_dir(const char *path, kg_err *err);

#endif
