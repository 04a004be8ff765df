/* What the gphoto2 backend keeps beyond the frame: the camera file behind the last
 * frame, as downloaded, so that a later step can save the original raw. */
#ifndef KG_GPHOTO2_PRIVATE_H
#define KG_GPHOTO2_PRIVATE_H

#include <stddef.h>
#include <stdint.h>

#include "kg_camera.h"
#include "raw.h"

/* The file of the last capture of a gphoto2: camera (the frame last popped, or the
 * capture that learnt the format): its bytes exactly as downloaded, its name on the
 * camera (folder/name) and what its metadata said (meta may be NULL). The pointers
 * stay valid until the next capture or kg_camera_free. KG_EINVAL when c is not a
 * gphoto2 camera, KG_ENOENT before its first capture. */
int kg_gphoto2_last_file(kg_camera *c, const void **data, size_t *size, const char **name,
                         kg_raw_meta *meta, kg_err *err);

/* How many full exposures (gp_camera_capture) and live-view images
 * (gp_camera_capture_preview) the gphoto2: camera c has taken since it was opened;
 * KG_EINVAL when c is not one. */
int kg_gphoto2_counts(kg_camera *c, uint64_t *captures, uint64_t *previews);

#endif
