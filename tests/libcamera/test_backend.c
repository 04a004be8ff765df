/* The libcamera backend as applications see it, on whatever cameras libcamera lists
 * here (none on a machine without them): the backend is registered; kogei's
 * enumeration (kg_camera_enumerate and `kogei devices`) lists exactly the cameras
 * libcamera's CameraManager lists; opening an id or index that is not there gives
 * KG_ENODEV naming it and the number of cameras libcamera sees; no manager is left
 * running afterwards. argv[1]: the kogei executable. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_camera.h"
#include "kg_test.h"

#if HAVE_LIBCAMERA
#include "lc_shim.h"

typedef struct seen {
	int libcamera;     /* cameras kg_camera_enumerate reported for libcamera: */
	int notes;         /* notes from the libcamera backend (failures) */
	char note[1024];
} seen;

static void found(void *user, const char *uri, const char *model, const char *serial,
                  const char *transport)
{
	seen *s = user;
	if (!strncmp(uri, "libcamera:", 10)) {
		s->libcamera++;
		CHECK(model && *model, "camera %s has no model", uri);
		CHECK(transport && !strcmp(transport, "libcamera"), "camera %s transport %s", uri,
		      transport ? transport : "(null)");
	}
}

static void noted(void *user, const char *scheme, const char *message)
{
	seen *s = user;
	if (!strcmp(scheme, "libcamera")) {
		s->notes++;
		snprintf(s->note, sizeof(s->note), "%s", message);
	}
}

static void collect_id(void *user, int index, const char *id, const char *model)
{
	if (index == 0)
		snprintf(user, 256, "%s", id);
}

/* Open uri, expect KG_ENODEV with a message naming `names` and libcamera's count. */
static void expect_missing(const char *uri, const char *names, int count)
{
	kg_camera *c = (kg_camera *)1;
	kg_err e = {{0}};
	int ret = kg_camera_open(uri, &c, &e);
	CHECK(ret == KG_ENODEV, "open %s: %d (%s), expected KG_ENODEV", uri, ret, e.msg);
	CHECK(c == NULL, "open %s failed but left a camera", uri);
	CHECK(strstr(e.msg, names) != NULL, "message does not name '%s': %s", names, e.msg);
	char sees[64];
	snprintf(sees, sizeof(sees), "sees %d camera", count);
	CHECK(strstr(e.msg, sees) != NULL, "message does not say '%s': %s", sees, e.msg);
	CHECK(kg_lc_manager_refs() == 0, "open %s left %d manager references", uri,
	      kg_lc_manager_refs());
}

/* `kogei devices`: the libcamera backend is listed, and its cameras are libcamera's. */
static void check_cli(const char *kogei, int count)
{
	char cmd[4096];
	snprintf(cmd, sizeof(cmd), "KOGEI_CAMERA_DISCOVERY=none '%s' devices 2>&1", kogei);
	FILE *p = popen(cmd, "r");
	CHECK(p != NULL, "cannot run %s", cmd);
	if (!p)
		return;
	char line[2048];
	int backend = 0, listed = 0;
	while (fgets(line, sizeof(line), p)) {
		if (!strncmp(line, "  libcamera ", 12))
			backend = !strstr(line, "not built");
		if (!strncmp(line, "  libcamera:", 12) && strstr(line, "libcamera)"))
			listed++;
		CHECK(strncmp(line, "  libcamera: ", 13), "kogei devices notes a libcamera failure: %s",
		      line);
	}
	int status = pclose(p);
	CHECK(status == 0, "kogei devices exited with status %d", status);
	CHECK(backend, "kogei devices does not list the libcamera backend as built");
	CHECK(listed == count, "kogei devices lists %d libcamera cameras, libcamera %d", listed,
	      count);
}
#endif

int main(int argc, char **argv)
{
#if !HAVE_LIBCAMERA
	(void)argc;
	(void)argv;
	kg_test_skip("the libcamera backend is not built (pkg-config libcamera and a C++ "
	             "compiler are needed)");
	return 77;
#else
	setenv("KOGEI_CAMERA_DISCOVERY", "none", 1); /* never broadcast (aravis) */

	int registered = -1;
	for (int i = 0; i < kg_camera_backend_count(); i++)
		if (!strcmp(kg_camera_backend_scheme(i), "libcamera"))
			registered = i;
	CHECK(registered >= 0, "no libcamera backend among %d", kg_camera_backend_count());
	if (registered >= 0) {
		const char *d = kg_camera_backend_description(registered);
		CHECK(d && *d && !strstr(d, "not implemented"), "description '%s'", d ? d : "(null)");
	}

	/* libcamera's own count, straight from CameraManager::cameras() */
	kg_err e = {{0}};
	char first_id[256] = "";
	int count = kg_lc_list(collect_id, first_id, &e);
	CHECK(count >= 0, "listing libcamera cameras: %s", e.msg);
	CHECK(kg_lc_manager_refs() == 0, "kg_lc_list left %d manager references",
	      kg_lc_manager_refs());
	printf("libcamera %s lists %d camera(s)\n", kg_lc_version(), count);

	seen s = {0, 0, ""};
	kg_camera_enumerate(found, noted, &s);
	CHECK(s.notes == 0, "the libcamera backend failed to enumerate: %s", s.note);
	CHECK(s.libcamera == count, "kg_camera_enumerate reports %d libcamera cameras, libcamera %d",
	      s.libcamera, count);
	CHECK(kg_lc_manager_refs() == 0, "enumeration left %d manager references",
	      kg_lc_manager_refs());

	/* ids and indexes that are not there */
	expect_missing("libcamera:no-such-camera-7f3a", "no-such-camera-7f3a", count);
	char uri[64];
	snprintf(uri, sizeof(uri), "libcamera:%d", count);
	expect_missing(uri, uri + 10, count);
	if (count > 0) { /* a real id with something appended is still not a camera */
		char longer[300];
		snprintf(longer, sizeof(longer), "libcamera:%s-x", first_id);
		expect_missing(longer, first_id, count);
	}

	/* no id at all is a usage error, not a missing device */
	kg_camera *c = NULL;
	int ret = kg_camera_open("libcamera:", &c, &e);
	CHECK(ret == KG_EINVAL && c == NULL, "open libcamera: gave %d (%s)", ret, e.msg);
	CHECK(strstr(e.msg, "libcamera:<id>") != NULL, "message does not say what is expected: %s",
	      e.msg);

	if (argc > 1)
		check_cli(argv[1], count);
	else
		CHECK(0, "usage: test_libcamera_backend KOGEI");
	return kg_test_done("libcamera-backend");
#endif
}
