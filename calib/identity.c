/* The site camera's identity: read from a patch file's keywords, described, and
 * compared with an image's (kg_calib.h). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib_private.h"

static const char *keyword(char *const *names, char *const *values, int n, const char *name)
{
	for (int i = 0; i < n; i++)
		if (strcmp(names[i], name) == 0)
			return values[i];
	return NULL;
}

int kg_camera_identity_from_keywords(const char *what, char *const *names,
                                     char *const *values, int n, kg_camera_identity *out,
                                     kg_err *err)
{
	kg_check_arg(out && (n == 0 || (names && values)), err);
	memset(out, 0, sizeof(*out));
	const char *backend = keyword(names, values, n, "CAMERA_BACKEND");
	const char *model = keyword(names, values, n, "CAMERA_MODEL");
	const char *serial = keyword(names, values, n, "CAMERA_SERIAL");
	const char *pixfmt = keyword(names, values, n, "CAMERA_PIXFMT");
	const char *white = keyword(names, values, n, "CAMERA_WHITE_LEVEL");
	const char *demosaic = keyword(names, values, n, "CAMERA_DEMOSAIC");
	const char *capture = keyword(names, values, n, "CAPTURE");
	if (white) {
		char *end;
		long v = strtol(white, &end, 10);
		if (end == white || *end || v < 1)
			return kg_fail(err, KG_EINVAL, "%s: CAMERA_WHITE_LEVEL \"%s\": expected a whole "
			               "number >= 1 (the full scale in DN)", what ? what : "patch file",
			               white);
		out->white_level = v;
	}
	if (!backend || !model || !serial)
		return 0;
	out->known = 1;
	snprintf(out->backend, sizeof(out->backend), "%s", backend);
	snprintf(out->model, sizeof(out->model), "%s", model);
	snprintf(out->serial, sizeof(out->serial), "%s", serial);
	snprintf(out->pixfmt, sizeof(out->pixfmt), "%s", pixfmt ? pixfmt : "");
	snprintf(out->demosaic, sizeof(out->demosaic), "%s", demosaic ? demosaic : "");
	snprintf(out->capture, sizeof(out->capture), "%s", capture ? capture : "");
	return 0;
}

void kg_camera_identity_describe(const kg_camera_identity *id, char *buf, size_t size)
{
	if (!id->known) {
		snprintf(buf, size, "an unknown camera");
		return;
	}
	snprintf(buf, size, "%s camera \"%s\" serial %s (%s, white level %ld, demosaic %s%s%s)",
	         id->backend, id->model, id->serial, id->pixfmt[0] ? id->pixfmt : "format unknown",
	         id->white_level, id->demosaic[0] ? id->demosaic : "unknown",
	         id->capture[0] ? ", capture " : "", id->capture);
}

int kg_camera_identity_check(const kg_camera_identity *calib, const char *calib_what,
                             const kg_camera_identity *image, const char *image_what,
                             char *note, size_t note_size, kg_err *err)
{
	kg_check_arg(calib && image && calib_what && image_what, err);
	if (note && note_size)
		note[0] = 0;
	if (!calib->known)
		return kg_fail(err, KG_ENOENT, "%s records no camera identity (its chart was not "
		               "photographed in a kogei session, or the file is older): the camera "
		               "of %s was not checked", calib_what, image_what);
	if (!image->known)
		return kg_fail(err, KG_ENOENT, "%s is not a capture of a kogei session: its camera "
		               "is unknown and was not checked against %s's", image_what, calib_what);
	char a[512], b[512];
	kg_camera_identity_describe(calib, a, sizeof(a));
	kg_camera_identity_describe(image, b, sizeof(b));
	if (strcmp(calib->backend, image->backend) || strcmp(calib->model, image->model) ||
	    strcmp(calib->serial, image->serial))
		return kg_fail(err, KG_EINVAL, "%s was taken by %s, but %s calibrates %s: another "
		               "camera's calibration gives wrong spectra; calibrate this camera "
		               "(photograph the chart with it) or pass --force", image_what, b,
		               calib_what, a);
	if (note && note_size) {
		size_t at = 0;
		if (strcmp(calib->pixfmt, image->pixfmt))
			at += (size_t)snprintf(note + at, note_size - at, "pixel format %s, calibrated "
			                       "in %s", image->pixfmt, calib->pixfmt);
		if (at < note_size && calib->white_level != image->white_level)
			at += (size_t)snprintf(note + at, note_size - at, "%swhite level %ld, calibrated "
			                       "at %ld", at ? "; " : "", image->white_level,
			                       calib->white_level);
		if (at < note_size && strcmp(calib->demosaic, image->demosaic))
			snprintf(note + at, note_size - at, "%sdemosaic %s, calibrated with %s",
			         at ? "; " : "", image->demosaic, calib->demosaic);
	}
	return 0;
}
