/* A measurement session: references, samples as reflectance and the output file,
 * shared by `kogei measure` (operator-guided) and unattended runs (`kogei demo`). */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "kg_devices.h"

static void warn(const kg_measure_session *m, const char *fmt, ...) KG_PRINTF(2, 3);
static void warn(const kg_measure_session *m, const char *fmt, ...)
{
	if (!m->warn)
		return;
	char msg[256];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(msg, sizeof(msg), fmt, ap);
	va_end(ap);
	m->warn(m->warn_user, msg);
}

void kg_measure_session_clear(kg_measure_session *m)
{
	if (!m)
		return;
	kg_spectro_reading_clear(&m->dark);
	kg_spectro_reading_clear(&m->white);
}

int kg_measure_reading(kg_measure_session *m, const char *target, const char *what,
                       kg_spectro_reading *out, kg_err *err)
{
	kg_check_arg(m && m->spectro && target && out, err);
	int r = kg_spectro_set_target(m->spectro, target, err);
	if (!r)
		r = kg_spectro_acquire(m->spectro, &m->acq, out, err);
	if (!r && out->saturated) {
		const kg_spectro_info *info = kg_spectro_get_info(m->spectro);
		r = kg_fail(err, KG_ERANGE,
		            "%s: %d pixels saturated at %.1f-%.1f nm (peak %.0f of %.0f counts): the "
		            "reading is refused, its counts there are wrong; shorten the integration "
		            "time (--integration, now %g ms) or reduce the light",
		            what ? what : target, out->saturated, out->saturated_nm[0],
		            out->saturated_nm[1], out->peak, info->saturation,
		            info->integration_us / 1000.0);
		kg_spectro_reading_clear(out);
	}
	return r;
}

int kg_measure_sample(kg_measure_session *m, const char *id, kg_spectrum *out, kg_err *err)
{
	kg_check_arg(m && id && out, err);
	kg_spectro_reading s = {0};
	int dropped = 0, r = kg_measure_reading(m, id, id, &s, err);
	if (!r)
		r = kg_reflectance(&m->dark, &m->white, &m->white_refl, &s, out, &dropped, err);
	if (!r && dropped)
		warn(m, "%s: %d pixels within 400-700 nm had no white signal and were "
		        "interpolated across", id, dropped);
	kg_spectro_reading_clear(&s);
	return r;
}

int kg_measure_write(const kg_measure_session *m, const char *path, const kg_patchset *ps,
                     const char *originator, const char *const *extra, kg_err *err)
{
	kg_check_arg(m && m->spectro && path && ps, err);
	const kg_spectro_info *info = kg_spectro_get_info(m->spectro);
	char integ[32], scans[16], boxcar[16], created[32];
	snprintf(integ, sizeof(integ), "%u", info->integration_us);
	snprintf(scans, sizeof(scans), "%d", m->acq.scans);
	snprintf(boxcar, sizeof(boxcar), "%d", m->acq.boxcar);
	time_t now = time(NULL);
	struct tm tm;
	strftime(created, sizeof(created), "%Y-%m-%dT%H:%M:%S", localtime_r(&now, &tm));
	const char *base[] = {"ORIGINATOR", originator ? originator : "kogei",
	                      "INSTRUMENT", info->model,
	                      "SERIAL_NUMBER", info->serial,
	                      "SPECTROMETER", m->uri ? m->uri : info->backend,
	                      "INTEGRATION_TIME_US", integ,
	                      "SCANS_AVERAGED", scans,
	                      "BOXCAR_HALF_WIDTH", boxcar,
	                      "WHITE_REFERENCE", m->white_ref_path ? m->white_ref_path
	                                                           : "flat 0.99",
	                      "MEASUREMENT_MODE", "reflectance",
	                      "CREATED", created};
	size_t nbase = sizeof(base) / sizeof(base[0]), nextra = 0;
	while (extra && extra[nextra] && extra[nextra + 1])
		nextra += 2;
	const char **kw = malloc(sizeof(char *) * (nbase + nextra + 1));
	if (!kw)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	memcpy(kw, base, sizeof(base));
	for (size_t i = 0; i < nextra; i++)
		kw[nbase + i] = extra[i];
	kw[nbase + nextra] = NULL;
	int r = kg_patchset_write(path, ps, KG_PATCH_SPECTRA, kw, err);
	free(kw);
	return r;
}

int kg_spectro_measure_patches(kg_measure_session *m, int n, const char *const *ids,
                               kg_measure_progress_fn progress, void *user,
                               kg_patchset **out, kg_err *err)
{
	kg_check_arg(m && m->spectro && n > 0 && ids && out, err);
	*out = NULL;
	kg_patchset *ps = NULL;
	kg_spectro_reading_clear(&m->dark);
	kg_spectro_reading_clear(&m->white);
	int r = kg_measure_reading(m, "dark", "dark reference", &m->dark, err);
	if (!r)
		r = kg_measure_reading(m, "white", "white reference", &m->white, err);
	if (!r)
		r = kg_patchset_new(n, KG_PATCH_SPECTRA, &ps, err);
	for (int i = 0; !r && i < n; i++) {
		if (!ids[i])
			r = kg_fail(err, KG_EINVAL, "patch %d has no id", i + 1);
		if (!r)
			r = kg_patchset_set_id(ps, i, ids[i], err);
		if (!r)
			r = kg_measure_sample(m, ids[i], &ps->spectra[i], err);
		if (!r && progress)
			progress(user, i, n, ids[i], &ps->spectra[i]);
	}
	if (r)
		kg_patchset_free(&ps);
	*out = ps;
	return r;
}
