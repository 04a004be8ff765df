/* Inputs of the simulator named on the command line: spectra files (CGATS or the
 * reference CSV layout), illuminants (name, CGATS or CSV) and material samples. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#include "kg_sim.h"

static int has_suffix(const char *s, const char *suffix)
{
	size_t n = strlen(s), m = strlen(suffix);
	return n >= m && strcasecmp(s + n - m, suffix) == 0;
}

int kg_sim_read_spectra(const char *path, unsigned flags, kg_patchset **out, kg_err *err)
{
	kg_check_arg(path && out, err);
	*out = NULL;
	kg_patchset *ps = NULL;
	flags |= KG_PATCH_REFLECTANCE;
	int ret = has_suffix(path, ".csv") ? kg_csv_read_spectra_rows(path, flags, &ps, err)
	                                   : kg_patchset_read(path, flags, &ps, err);
	if (ret) {
		kg_err_prefix(err, "spectra");
		return ret;
	}
	if (!ps->spectra || ps->n < 1) {
		kg_patchset_free(&ps);
		return kg_fail(err, KG_EINVAL,
		               "%s: no spectra: expected SPEC_<nm> fields (CGATS) or wavelength "
		               "columns (CSV patch,name,<nm>...)",
		               path);
	}
	for (int i = 0; i < ps->n; i++)
		if (!kg_spectrum_isfinite(&ps->spectra[i])) {
			kg_fail(err, KG_EINVAL, "%s: sample %s: spectrum is not finite", path,
			        ps->ids[i]);
			kg_patchset_free(&ps);
			return KG_EINVAL;
		}
	*out = ps;
	return 0;
}

/* CSV `wavelength_nm,<power>`: the first column after the wavelengths. */
static int illuminant_from_csv(const char *path, kg_illuminant **out, kg_err *err)
{
	kg_csv *t = NULL;
	int ret = kg_csv_read(path, &t, err);
	if (ret)
		return ret;
	int wcol = kg_csv_column(t, "wavelength_nm");
	if (wcol < 0)
		wcol = 0;
	int pcol = wcol == 0 ? 1 : 0;
	double *wl = malloc((size_t)(t->nrows > 0 ? t->nrows : 1) * sizeof(*wl));
	double *v = malloc((size_t)(t->nrows > 0 ? t->nrows : 1) * sizeof(*v));
	if (!wl || !v) {
		ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
		goto done;
	}
	if (t->ncols < 2 || t->nrows < 2) {
		ret = kg_fail(err, KG_EINVAL,
		              "%s: expected columns wavelength_nm and a relative power, and at "
		              "least 2 rows",
		              path);
		goto done;
	}
	for (int i = 0; i < t->nrows && !ret; i++) {
		ret = kg_csv_number(t, i, wcol, &wl[i], err);
		if (!ret)
			ret = kg_csv_number(t, i, pcol, &v[i], err);
	}
	if (!ret) {
		const char *base = strrchr(path, '/');
		ret = kg_illuminant_from_samples(base ? base + 1 : path, wl, v, t->nrows, out, err);
		if (ret && err && !strstr(err->msg, path))
			kg_err_prefix(err, "%s", path);
	}
done:
	free(wl);
	free(v);
	kg_csv_free(&t);
	return ret;
}

int kg_sim_illuminant(const char *spec, kg_illuminant **out, kg_err *err)
{
	kg_check_arg(spec && out, err);
	*out = NULL;
	struct stat st;
	if (stat(spec, &st) != 0) {
		int ret = kg_illuminant_by_name(spec, out, err);
		if (ret == KG_EINVAL && err) {
			size_t n = strlen(err->msg);
			snprintf(err->msg + n, sizeof(err->msg) - n,
			         ", or an illuminant file (CGATS, or CSV wavelength_nm,power): "
			         "no file of that name");
		}
		return ret;
	}
	int ret = has_suffix(spec, ".csv") ? illuminant_from_csv(spec, out, err)
	                                   : kg_illuminant_from_file(spec, out, err);
	if (ret)
		kg_err_prefix(err, "illuminant");
	return ret;
}

int kg_sim_capture_load(kg_sim_capture *c, const char *camera_path,
                        const char *illuminant_spec, double white_level,
                        const kg_sim_noise *noise, unsigned flags, kg_err *err)
{
	kg_check_arg(c && camera_path && illuminant_spec, err);
	kg_sim_camera cam;
	int ret = kg_sim_camera_load(camera_path, flags, &cam, err);
	if (ret)
		return ret;
	kg_illuminant *ill = NULL;
	ret = kg_sim_illuminant(illuminant_spec, &ill, err);
	if (ret)
		return ret;
	ret = kg_sim_capture_init(c, &cam, &ill->spd, white_level, noise, err);
	kg_illuminant_free(&ill);
	return ret;
}
