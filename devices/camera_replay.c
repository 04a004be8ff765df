/* Placeholder until the replay backend lands: registered so the build and the registry
 * are complete, refuses to open. */
#include "camera_driver.h"

static int ph_open(const char *target, void **state, kg_camera_info *info, kg_err *err)
{
	return kg_fail(err, KG_ENOTSUP, "the replay backend is not implemented yet");
}

const kg_camera_driver kg_camera_replay_driver = {
	.scheme = "replay",
	.description = "frames recorded in a session (not implemented yet)",
	.open = ph_open,
};
