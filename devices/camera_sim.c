/* Placeholder until the sim backend lands: registered so the build and the registry
 * are complete, refuses to open. */
#include "camera_driver.h"

static int ph_open(const char *target, void **state, kg_camera_info *info, kg_err *err)
{
	return kg_fail(err, KG_ENOTSUP, "the sim backend is not implemented yet");
}

const kg_camera_driver kg_camera_sim_driver = {
	.scheme = "sim",
	.description = "simulated sensor (not implemented yet)",
	.open = ph_open,
};
