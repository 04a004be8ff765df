#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "raw.h"
#include "cli.h"
#include "kg_acquire.h"
#include "kg_config.h"

int kg_cli_parse_range(const char *text, double **values, int *n, kg_err *err)
{
	double a, b, s;
	char tail;
	if (sscanf(text, "%lf:%lf:%lf%c", &a, &b, &s, &tail) != 3 || !isfinite(a) ||
	    !isfinite(b) || !isfinite(s) || s <= 0 || b < a)
		return kg_fail(err, KG_EINVAL,
		               "range '%s': expected start:stop:step with start <= stop and step > 0",
		               text);
	int count = (int)floor((b - a) / s + 1e-9) + 1;
	if (count > 10000)
		return kg_fail(err, KG_EINVAL, "range '%s': more than 10000 values", text);
	double *v = malloc(sizeof(double) * count);
	if (!v)
		return KG_ENOMEM;
	for (int i = 0; i < count; i++)
		v[i] = a + i * s;
	*values = v;
	*n = count;
	return 0;
}

int kg_cli_required(const char *usage, ...)
{
	va_list ap;
	va_start(ap, usage);
	const char *name;
	int ret = 0;
	while (!ret && (name = va_arg(ap, const char *))) {
		const char *value = va_arg(ap, const char *);
		if (!value)
			ret = kg_cli_usage_error(usage, "%s is required", name);
	}
	va_end(ap);
	return ret;
}

int kg_cli_number(const char *text, double *out)
{
	char *end = NULL;
	double v = strtod(text, &end);
	if (!end || end == text || *end || !isfinite(v))
		return -1;
	*out = v;
	return 0;
}

int kg_cli_int(const char *text, int lo, int hi, int *out)
{
	char *end = NULL;
	errno = 0;
	long v = strtol(text, &end, 10);
	if (!end || end == text || *end || errno || v < lo || v > hi)
		return -1;
	*out = (int)v;
	return 0;
}

int kg_cli_number_option(const char *usage, const char *opt, const char *text, double lo,
                         double hi, double *out)
{
	double v;
	if (kg_cli_number(text, &v) || !(v >= lo && v <= hi))
		return kg_cli_usage_error(usage, "%s '%s': expected a number from %g to %g", opt,
		                          text, lo, hi);
	*out = v;
	return 0;
}

int kg_cli_min_option(const char *usage, const char *opt, const char *text, double lo,
                      int strict, double *out)
{
	double v;
	if (kg_cli_number(text, &v) || (strict ? !(v > lo) : !(v >= lo)))
		return kg_cli_usage_error(usage, "%s %s: expected a number %s %g", opt, text,
		                          strict ? ">" : ">=", lo);
	*out = v;
	return 0;
}

int kg_cli_int_option(const char *usage, const char *opt, const char *text, int lo, int hi,
                      int *out)
{
	if (kg_cli_int(text, lo, hi, out))
		return kg_cli_usage_error(usage, "%s '%s': expected a whole number from %d to %d",
		                          opt, text, lo, hi);
	return 0;
}

int kg_cli_seed_option(const char *usage, const char *text, uint64_t *out)
{
	char *end = NULL;
	errno = 0;
	unsigned long long v = strtoull(text, &end, 10);
	if (!*text || *text == '-' || *text == '+' || *end || errno)
		return kg_cli_usage_error(usage, "--seed '%s': expected a whole number >= 0", text);
	*out = (uint64_t)v;
	return 0;
}

int kg_cli_parse_numbers(const char *text, double *v, int max)
{
	int n = 0;
	const char *p = text;
	for (;;) {
		char *end = NULL;
		double x = strtod(p, &end);
		if (!end || end == p || n == max || !isfinite(x))
			return -1;
		v[n++] = x;
		if (*end == '\0')
			return n;
		if (*end != ':')
			return -1;
		p = end + 1;
	}
}

int kg_cli_split_names(char *text, char **names, int max, int *n)
{
	*n = 0;
	for (char *p = text;;) {
		char *comma = strchr(p, ',');
		if (comma)
			*comma = '\0';
		if (!*p || *n == max)
			return -1;
		names[(*n)++] = p;
		if (!comma)
			return 0;
		p = comma + 1;
	}
}

int kg_cli_read_photograph(const char *path, kg_image **out, kg_err *err)
{
	kg_image *img = NULL;
	int rc = kg_image_read(path, &img, err);
	if (rc || img->channels != 1 || !img->cfa || !kg_raw_is_raw(path)) {
		*out = img;
		return rc;
	}
	rc = kg_demosaic(img, out, NULL, err);
	kg_image_free(&img);
	if (rc)
		kg_err_prefix(err, "%s: demosaicing the raw mosaic", path);
	return rc;
}

int kg_cli_image_identity(const char *image, kg_camera_identity *id, kg_err *err)
{
	memset(id, 0, sizeof(*id));
	kg_session_image si;
	kg_err local = {{0}};
	int ret = kg_session_image_identify(image, &si, &local);
	if (ret == KG_ENOENT && kg_raw_is_raw(image)) {
		/* A camera raw file names its camera: the identity a files: capture of it has
		 * (16-bit frames, the demosaicing chart detect and process use). */
		kg_raw_meta m;
		if (kg_raw_read_meta(image, &m, &local))
			return 0; /* the read itself will say what is wrong */
		id->known = 1;
		snprintf(id->backend, sizeof(id->backend), "files");
		snprintf(id->model, sizeof(id->model), "%s", m.model);
		snprintf(id->serial, sizeof(id->serial), "%s", m.serial);
		snprintf(id->pixfmt, sizeof(id->pixfmt), "bayer16");
		id->white_level = 65535;
		snprintf(id->demosaic, sizeof(id->demosaic), "%s",
		         kg_demosaic_algorithm() ? kg_demosaic_algorithm() : "none");
		return 0;
	}
	if (ret == KG_ENOENT)
		return 0;
	if (ret)
		return kg_fail(err, ret, "%s", local.msg);
	id->known = 1;
	snprintf(id->backend, sizeof(id->backend), "%s", si.backend);
	snprintf(id->model, sizeof(id->model), "%s", si.model);
	snprintf(id->serial, sizeof(id->serial), "%s", si.serial);
	snprintf(id->pixfmt, sizeof(id->pixfmt), "%s", si.pixfmt);
	id->white_level = si.white_level;
	snprintf(id->demosaic, sizeof(id->demosaic), "%s", si.demosaic);
	snprintf(id->capture, sizeof(id->capture), "%s", si.capture);
	return 0;
}

int kg_cli_check_camera(const kg_camera_calib *cam, const char *calib_path,
                        const char *image, int force, kg_err *err)
{
	kg_camera_identity id;
	int ret = kg_cli_image_identity(image, &id, err);
	if (ret)
		return ret;
	char note[512];
	kg_err why = {{0}};
	ret = kg_camera_identity_check(&cam->identity, calib_path, &id, image, note,
	                               sizeof(note), &why);
	if (ret == 0 && note[0])
		fprintf(stderr, "kogei: note: %s: same camera as %s, read differently: %s\n", image,
		        calib_path, note);
	else if (ret == KG_ENOENT)
		fprintf(stderr, "kogei: note: camera identity not checked: %s\n", why.msg);
	else if (ret == KG_EINVAL && force)
		fprintf(stderr, "kogei: warning: --force: %s\n", why.msg);
	else if (ret)
		return kg_fail(err, ret, "%s", why.msg);
	return 0;
}

