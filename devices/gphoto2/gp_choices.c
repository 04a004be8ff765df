/* Choice strings of gphoto2 settings as numbers, and other pure parts of the gphoto2
 * backend (gp_choices.h). */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include <gphoto2/gphoto2-port-result.h>
#include <gphoto2/gphoto2-result.h>

#include "gp_choices.h"

static const char *skip_space(const char *p)
{
	while (*p == ' ' || *p == '\t')
		p++;
	return p;
}

/* A positive decimal number at p (no sign, no exponent, no hex); *end after it. */
static int number(const char *p, double *v, const char **end)
{
	const char *q = p;
	int digits = 0;
	while (isdigit((unsigned char)*q)) {
		q++;
		digits++;
	}
	if (*q == '.') {
		q++;
		while (isdigit((unsigned char)*q)) {
			q++;
			digits++;
		}
	}
	if (!digits)
		return 0;
	char buf[64];
	size_t len = (size_t)(q - p);
	if (len >= sizeof(buf))
		return 0;
	memcpy(buf, p, len);
	buf[len] = 0;
	*v = strtod(buf, NULL);
	*end = q;
	return isfinite(*v);
}

/* The rest of a choice after its number: only the unit suffixes given may follow. */
static int rest_is(const char *p, const char *const *suffixes)
{
	p = skip_space(p);
	if (!*p)
		return 1;
	for (int i = 0; suffixes[i]; i++)
		if (!strcasecmp(p, suffixes[i]))
			return 1;
	return 0;
}

int kg_gp_choice_value(kg_feature f, const char *text, double *value)
{
	if (!text)
		return 0;
	const char *p = skip_space(text), *end;
	double v, d;
	switch (f) {
	case KG_FEAT_EXPOSURE_US:
		if (!number(p, &v, &end))
			return 0;
		p = skip_space(end);
		if (*p == '/') {
			if (!number(skip_space(p + 1), &d, &end) || d <= 0)
				return 0;
			v /= d;
			p = end;
		}
		if (!rest_is(p, (const char *const[]){"s", "sec", "\"", NULL}) || v <= 0)
			return 0;
		*value = v * 1e6;
		return 1;
	case KG_FEAT_ISO:
		if (!strncasecmp(p, "ISO", 3))
			p = skip_space(p + 3);
		if (!number(p, &v, &end) || !rest_is(end, (const char *const[]){NULL}) || v <= 0)
			return 0;
		*value = v;
		return 1;
	case KG_FEAT_APERTURE:
		if (!strncasecmp(p, "f/", 2))
			p += 2;
		else if (*p == 'f' || *p == 'F')
			p++;
		if (!number(skip_space(p), &v, &end) || !rest_is(end, (const char *const[]){NULL}) ||
		    v <= 0)
			return 0;
		*value = v;
		return 1;
	case KG_FEAT_FOCAL_LENGTH:
		if (!number(p, &v, &end) || !rest_is(end, (const char *const[]){"mm", NULL}) ||
		    v <= 0)
			return 0;
		*value = v;
		return 1;
	default:
		return 0;
	}
}

int kg_gp_choice_range(kg_feature f, const char *const *choices, int n, double *min,
                       double *max)
{
	int count = 0;
	*min = *max = 0;
	for (int i = 0; i < n; i++) {
		double v;
		if (!kg_gp_choice_value(f, choices[i], &v))
			continue;
		if (!count || v < *min)
			*min = v;
		if (!count || v > *max)
			*max = v;
		count++;
	}
	return count;
}

const char *kg_gp_unit(kg_feature f)
{
	switch (f) {
	case KG_FEAT_EXPOSURE_US:
		return "us";
	case KG_FEAT_ISO:
		return "ISO";
	case KG_FEAT_APERTURE:
		return "f";
	case KG_FEAT_FOCAL_LENGTH:
		return "mm";
	default:
		return "bool";
	}
}

int kg_gp_choice_pick(kg_feature f, const char *config, const char *const *choices, int n,
                      double value, int *index, kg_err *err)
{
	int below = -1, above = -1;
	double vb = 0, va = 0;
	for (int i = 0; i < n; i++) {
		double v;
		if (!kg_gp_choice_value(f, choices[i], &v))
			continue;
		double tol = 1e-6 * fabs(value);
		if (f == KG_FEAT_EXPOSURE_US && tol < 0.5)
			tol = 0.5;
		if (fabs(v - value) <= tol) {
			*index = i;
			return 0;
		}
		if (v < value && (below < 0 || v > vb)) {
			below = i;
			vb = v;
		}
		if (v > value && (above < 0 || v < va)) {
			above = i;
			va = v;
		}
	}
	const char *unit = kg_gp_unit(f);
	if (below < 0 && above < 0)
		return kg_fail(err, KG_ENOTSUP, "%s offers no numeric choice for %s", config,
		               kg_feature_name(f));
	char near[256];
	if (below >= 0 && above >= 0)
		snprintf(near, sizeof(near), "%s (%g %s) and %s (%g %s)", choices[below], vb, unit,
		         choices[above], va, unit);
	else if (below >= 0)
		snprintf(near, sizeof(near), "%s (%g %s), the largest", choices[below], vb, unit);
	else
		snprintf(near, sizeof(near), "%s (%g %s), the smallest", choices[above], va, unit);
	return kg_fail(err, KG_ERANGE,
	               "%s has no choice for %s %g %s; the camera offers only its own steps, "
	               "nearest: %s",
	               config, kg_feature_name(f), value, unit, near);
}

/* Case-insensitive substring. */
static int has_word(const char *text, const char *word)
{
	size_t n = strlen(word);
	for (const char *p = text; *p; p++)
		if (!strncasecmp(p, word, n))
			return 1;
	return 0;
}

int kg_gp_is_raw_choice(const char *text)
{
	if (!text)
		return 0;
	/* Canon's reduced raws are demosaiced YCbCr inside a CR2/CR3: no CFA to measure. */
	for (const char *p = text; *p; p++) {
		if ((*p == 's' || *p == 'S' || *p == 'm' || *p == 'M') && !strncasecmp(p + 1, "RAW", 3))
			return 0;
	}
	static const char *const raw_words[] = {"RAW", "NEF", "ARW", "DNG", "ORF", "RW2",
	                                        "PEF", "RAF", "SRW", "IIQ", "3FR", "CR2", "CR3"};
	for (size_t i = 0; i < sizeof(raw_words) / sizeof(raw_words[0]); i++)
		if (has_word(text, raw_words[i]))
			return 1;
	return 0;
}

int kg_gp_is_raw_name(const char *name)
{
	static const char *const ext[] = {"dng", "cr2", "cr3", "crw", "nef", "nrw", "arw", "srf",
	                                  "sr2", "orf", "rw2", "raf", "pef", "iiq", "3fr", "fff",
	                                  "erf", "kdc", "dcr", "mos", "mef", "mrw", "srw", "x3f",
	                                  "rwl"};
	const char *dot = name ? strrchr(name, '.') : NULL;
	if (!dot)
		return 0;
	for (size_t i = 0; i < sizeof(ext) / sizeof(ext[0]); i++)
		if (!strcasecmp(dot + 1, ext[i]))
			return 1;
	return 0;
}

int kg_gp_program_is_manual(const char *text)
{
	if (!text)
		return 0;
	const char *p = skip_space(text);
	return !strcasecmp(p, "M") || !strcasecmp(p, "Manual") || !strcasecmp(p, "Bulb") ||
	       !strcasecmp(p, "Manual (M)");
}

int kg_gp_open_error(const char *model, const char *port, const char *node, int denied,
                     int gpret, const char *gp_text, const char *detail, kg_err *err)
{
	char why[640];
	snprintf(why, sizeof(why), "%s%s%s", gp_text ? gp_text : "error", detail ? ": " : "",
	         detail ? detail : "");
	if (denied)
		return kg_fail(err, KG_EIO,
		               "camera %s at %s: no permission to use %s; install libgphoto2's udev "
		               "rules (Debian/Ubuntu package libgphoto2-6, which puts its "
		               "*-libgphoto2*.rules in the udev rules directory), then replug the "
		               "camera",
		               model, port, node);
	switch (gpret) {
	case GP_ERROR_IO_USB_CLAIM:
	case GP_ERROR_IO_LOCK:
	case GP_ERROR_CAMERA_BUSY:
		return kg_fail(err, KG_EIO,
		               "camera %s at %s is held by another program: close it (a desktop file "
		               "manager or gvfs-gphoto2-volume-monitor often holds cameras; `gio "
		               "mount -s gphoto2` releases them) and try again (%s)",
		               model, port, why);
	case GP_ERROR_IO_USB_FIND:
		return kg_fail(err, KG_ENODEV,
		               "camera %s at %s: cannot find or access the USB device; if it is "
		               "attached, install libgphoto2's udev rules (package libgphoto2-6) so "
		               "that you may use it (%s)",
		               model, port, why);
	case GP_ERROR_MODEL_NOT_FOUND:
	case GP_ERROR_IO_INIT:
	case GP_ERROR_IO:
		return kg_fail(err, KG_ENODEV,
		               "camera %s at %s does not answer (unplugged, switched off or asleep?) "
		               "(%s)",
		               model, port, why);
	default:
		return kg_fail(err, KG_EIO, "camera %s at %s: cannot open (%s)", model, port, why);
	}
}

void kg_gp_to_bayer16(const float *in, size_t n, uint8_t *out)
{
	for (size_t i = 0; i < n; i++) {
		float v = in[i];
		if (!(v > 0))
			v = 0; /* negative and NaN */
		if (v > 1)
			v = 1;
		unsigned w = (unsigned)floor((double)v * 65535.0 + 0.5);
		out[2 * i] = (uint8_t)(w & 0xff);
		out[2 * i + 1] = (uint8_t)(w >> 8);
	}
}
