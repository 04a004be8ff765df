/* The gphoto2 backend without a camera:
 *   test_gphoto2 enumerate none   no camera can be attached (run inside an empty
 *                                 umockdev testbed): enumeration reports nothing,
 *                                 neither a camera nor a note
 *   test_gphoto2 enumerate any    whatever is attached: no note, and every camera
 *                                 reported is a well-formed gphoto2: entry
 *   test_gphoto2 open-errors      a model nobody knows, a port with nothing on it and
 *                                 malformed options fail with clear errors */
#include <stdio.h>
#include <string.h>

#include "kg_camera.h"
#include "kg_test.h"


typedef struct seen {
	int cameras, notes, bad;
} seen;

static void found(void *user, const char *uri, const char *model, const char *serial,
                  const char *transport)
{
	seen *s = user;
	if (strncmp(uri, "gphoto2:", 8))
		return;
	s->cameras++;
	printf("  found %s (%s, %s)\n", uri, model, transport);
	if (!model[0] || !strstr(transport, " at ") || !uri[8])
		s->bad++;
	(void)serial;
}

static void note(void *user, const char *scheme, const char *message)
{
	seen *s = user;
	if (!strcmp(scheme, "gphoto2")) {
		s->notes++;
		printf("  note from gphoto2: %s\n", message);
	}
}

static int builtin(void)
{
	for (int i = 0; i < kg_camera_backend_count(); i++)
		if (!strcmp(kg_camera_backend_scheme(i), "gphoto2"))
			return 1;
	return 0;
}

static void enumerate(int expect_none)
{
	printf("enumeration through libgphoto2's autodetection: %s\n",
	       expect_none ? "no camera attached, nothing reported, no note"
	                   : "no note, well-formed entries");
	seen s = {0};
	kg_camera_enumerate(found, note, &s);
	CHECK(s.notes == 0, "gphoto2 enumeration left %d note(s)", s.notes);
	CHECK(s.bad == 0, "%d malformed camera entries", s.bad);
	if (expect_none)
		CHECK(s.cameras == 0, "%d camera(s) reported with none attached", s.cameras);
}

static void open_fails(const char *uri, int code, const char *const *words)
{
	kg_camera *c = NULL;
	kg_err err = {{0}};
	int ret = kg_camera_open(uri, &c, &err);
	printf("  %s -> %d: %s\n", uri, ret, err.msg);
	CHECK(ret == code && !c, "%s: returned %d, expected %d", uri, ret, code);
	for (int i = 0; words[i]; i++)
		CHECK(strstr(err.msg, words[i]) != NULL, "%s: the message does not say '%s'", uri,
		      words[i]);
	kg_camera_free(&c);
}

static void open_errors(void)
{
	printf("a model no one knows: KG_ENODEV naming it and pointing at kogei devices\n");
	open_fails("gphoto2:NoSuchCamera", KG_ENODEV,
	           (const char *const[]){"NoSuchCamera", "kogei devices", NULL});
	printf("a USB port with no camera: KG_ENODEV naming the port\n");
	open_fails("gphoto2:usb:250,127", KG_ENODEV,
	           (const char *const[]){"usb:250,127", NULL});
	printf("malformed targets and options: KG_EINVAL saying what is expected\n");
	open_fails("gphoto2:", KG_EINVAL, (const char *const[]){"gphoto2:<model or port>", NULL});
	open_fails("gphoto2:Any?delete=2", KG_EINVAL,
	           (const char *const[]){"delete=2", "delete=0", NULL});
	open_fails("gphoto2:Any?save=/nonexistent/folder", KG_EINVAL,
	           (const char *const[]){"/nonexistent/folder", "existing folder", NULL});
}

int main(int argc, char **argv)
{
	if (!builtin()) {
		printf("SKIP: the gphoto2 backend is not built in\n");
		return 77;
	}
	if (argc == 3 && !strcmp(argv[1], "enumerate"))
		enumerate(!strcmp(argv[2], "none"));
	else if (argc == 2 && !strcmp(argv[1], "open-errors"))
		open_errors();
	else {
		fprintf(stderr, "usage: test_gphoto2 enumerate none|any | open-errors\n");
		return 2;
	}
	if (kg_test_failures)
		printf("%d check(s) failed\n", kg_test_failures);
	else
		printf("all checks passed\n");
	return kg_test_failures ? 1 : 0;
}
