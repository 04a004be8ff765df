/* Placeholder until the libcamera backend lands: registered so the build and the registry
 * are complete, refuses to open. */
#include "camera_driver.h"

static int ph_open(const char *target, void **state, kg_camera_info *info, kg_err *err)
{
	return kg_fail(err, KG_ENOTSUP, "the libcamera backend is not implemented yet");
}

const kg_camera_driver kg_camera_libcamera_driver = {
	.scheme = "libcamera",
	.description = "libcamera (not implemented yet)",
	.open = ph_open,
};
