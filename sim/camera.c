/* Camera spectral sensitivities from CSV `wavelength_nm,r,g,b`. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "kg_sim.h"

static void camera_name(const char *path, char *buf, size_t len)
{
	const char *base = strrchr(path, '/');
	base = base ? base + 1 : path;
	snprintf(buf, len, "%s", base);
	char *dot = strrchr(buf, '.');
	if (dot && dot != buf)
		*dot = '\0';
}

int kg_sim_camera_load(const char *path, unsigned flags, kg_sim_camera *cam, kg_err *err)
{
	kg_check_arg(path && cam, err);
	static const char *const channels[3] = {"r", "g", "b"};
	memset(cam, 0, sizeof(*cam));
	int ret = kg_csv_read_column_spectra(path, channels, 3, flags, cam->sens, err);
	if (ret) {
		kg_err_prefix(err, "camera sensitivities");
		return ret;
	}
	for (int ch = 0; ch < 3; ch++)
		for (int i = 0; i < KG_NBANDS; i++) {
			double v = cam->sens[ch].v[i];
			if (!isfinite(v) || v < 0.0)
				return kg_fail(err, KG_EINVAL,
				               "%s: column %s at %g nm: %g: expected a sensitivity >= 0",
				               path, channels[ch], kg_band_nm(i), v);
		}
	camera_name(path, cam->name, sizeof(cam->name));
	return 0;
}
