/* Placeholder until the v4l2 backend lands: registered so the build and the registry
 * are complete, refuses to open. */
#include "camera_driver.h"

static int ph_open(const char *target, void **state, kg_camera_info *info, kg_err *err)
{
	return kg_fail(err, KG_ENOTSUP, "the v4l2 backend is not implemented yet");
}

const kg_camera_driver kg_camera_v4l2_driver = {
	.scheme = "v4l2",
	.description = "V4L2 capture devices (not implemented yet)",
	.open = ph_open,
};
