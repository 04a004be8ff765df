/* Camera spectral sensitivities from CSV `wavelength_nm,r,g,b`. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fsutil.h"
#include "kg_sim.h"

/* The simulated cameras of the demo, by name, so that a session can be simulated from
 * any folder without knowing where kogei's data lives. */
static const kg_data_name bundled_cameras[] = {
	{"demo-site", "demo/site_camera.csv"},
	{"demo-reference", "demo/reference_camera.csv"},
};

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
	char *file = NULL;
	int ret = kg_data_resolve(path, "camera sensitivities", bundled_cameras,
	                          (int)(sizeof(bundled_cameras) / sizeof(bundled_cameras[0])),
	                          &file, err);
	if (ret)
		return ret;
	ret = kg_csv_read_column_spectra(file, channels, 3, flags, cam->sens, err);
	if (ret)
		kg_err_prefix(err, "camera sensitivities");
	for (int ch = 0; ch < 3 && !ret; ch++)
		for (int i = 0; i < KG_NBANDS && !ret; i++) {
			double v = cam->sens[ch].v[i];
			if (!isfinite(v) || v < 0.0)
				ret = kg_fail(err, KG_EINVAL,
				              "%s: column %s at %g nm: %g: expected a sensitivity >= 0",
				              file, channels[ch], kg_band_nm(i), v);
		}
	if (!ret)
		camera_name(file, cam->name, sizeof(cam->name));
	free(file);
	return ret;
}
