/* Placeholder until the aravis backend lands: registered so the build and the registry
 * are complete, refuses to open. */
#include "camera_driver.h"

static int ph_open(const char *target, void **state, kg_camera_info *info, kg_err *err)
{
	return kg_fail(err, KG_ENOTSUP, "the aravis backend is not implemented yet");
}

const kg_camera_driver kg_camera_aravis_driver = {
	.scheme = "aravis",
	.description = "GigE Vision and USB3 Vision through Aravis (not implemented yet)",
	.open = ph_open,
};
