/* The models of the usbspec driver (ocean_models.h). Facts: the Ocean Optics / Ocean
 * Insight FPGA spectrometers as the public SeaBreeze sources describe them (vendor and
 * product ids, pixel counts, endpoints, integration limits); docs/measure.md. */
#include "ocean_models.h"

const ocean_model kg_ocean_models[] = {
	{0x2457, 0x101E, "USB2000+/Flame-S", 2048, 6, 21, 1000, 655350000, 65535, 0},
	{0x2457, 0x1022, "USB4000", 3840, 5, 16, 10, 65535000, 65535, 1},
	/* Not in the measured notes: the HR4000 is taken to share the USB4000's
	 * detector layout and to have a 14-bit converter. Check on hardware. */
	{0x2457, 0x1012, "HR4000", 3840, 5, 16, 10, 655350000, 16383, 0},
};
const int kg_ocean_nmodels = (int)(sizeof(kg_ocean_models) / sizeof(kg_ocean_models[0]));
