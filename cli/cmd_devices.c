/* kogei devices: the camera and spectrometer backends built into this binary, the
 * cameras they can enumerate, and the spectrometers attached. */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "kg_config.h"
#include "kg_camera.h"
#include "kg_devices.h"

#if HAVE_LIBUSB
#include <libusb.h>
#endif

static const char devices_usage[] = "kogei devices";

/* Attached USB devices whose ids are in the drivers' table. */
static void list_attached(void)
{
	printf("\nattached spectrometers:\n");
#if HAVE_LIBUSB
	int nids;
	const kg_spectro_usb_id *ids = kg_spectro_usb_ids(&nids);
	libusb_context *ctx = NULL;
	int rc = libusb_init(&ctx);
	if (rc) {
		printf("  cannot scan USB: libusb_init failed: %s\n", libusb_error_name(rc));
		return;
	}
	libusb_device **list = NULL;
	ssize_t n = libusb_get_device_list(ctx, &list);
	int found = 0;
	for (ssize_t i = 0; i < n; i++) {
		struct libusb_device_descriptor d;
		if (libusb_get_device_descriptor(list[i], &d))
			continue;
		for (int k = 0; k < nids; k++) {
			if (ids[k].vid != d.idVendor || ids[k].pid != d.idProduct)
				continue;
			printf("  %s:%04x:%04x  %s  (bus %u, address %u)\n", ids[k].scheme,
			       d.idVendor, d.idProduct, ids[k].model,
			       (unsigned)libusb_get_bus_number(list[i]),
			       (unsigned)libusb_get_device_address(list[i]));
			found++;
		}
	}
	if (n < 0)
		printf("  cannot scan USB: %s\n", libusb_error_name((int)n));
	else if (!found)
		printf("  none found\n");
	if (n >= 0)
		libusb_free_device_list(list, 1);
	libusb_exit(ctx);
#else
	printf("  not scanned: built without libusb\n");
#endif
}

static void camera_found(void *user, const char *uri, const char *model, const char *serial,
                         const char *transport)
{
	(*(int *)user)++;
	printf("  %-28s %s%s%s (%s)\n", uri, model, serial && *serial ? "  serial " : "",
	       serial ? serial : "", transport);
}

static void camera_note(void *user, const char *scheme, const char *message)
{
	(void)user;
	printf("  %s: %s\n", scheme, message);
}

/* Cameras the backends that can enumerate see (sim and replay are opened by URI). */
static void list_cameras(void)
{
	printf("\ncameras:\n");
	int found = 0;
	kg_camera_enumerate(camera_found, camera_note, &found);
	if (!found)
		printf("  none found\n");
}

int kg_cmd_devices(int argc, char **argv)
{
	if (kg_cli_wants_help(argc, argv)) {
		printf("usage: %s\n\n"
		       "List the camera and spectrometer backends built into this kogei, the\n"
		       "cameras each camera backend can enumerate, and the USB spectrometers\n"
		       "attached whose ids the drivers know. sim: and replay: cameras are not\n"
		       "listed: they are opened by URI (docs/cameras.md).\n\n"
		       "Environment: KOGEI_CAMERA_DISCOVERY=none skips backends that discover\n"
		       "cameras by broadcasting on the network (aravis: GigE Vision; gphoto2 only\n"
		       "when its libgphoto2 would browse mDNS for PTP/IP cameras).\n",
		       devices_usage);
		return KG_EXIT_OK;
	}
	if (argc > 1)
		return kg_cli_usage_error(devices_usage, "unexpected argument '%s'", argv[1]);

	printf("camera backends:\n");
	int nc = kg_camera_backend_count();
	for (int i = 0; i < nc; i++)
		printf("  %-10s %s\n", kg_camera_backend_scheme(i), kg_camera_backend_description(i));
	static const struct {
		const char *scheme, *needs;
	} optional[] = {
		{"v4l2", "linux/videodev2.h"},
		{"aravis", "aravis-0.8"},
		{"libcamera", "libcamera"},
		{"gphoto2", "libgphoto2"},
	};
	for (size_t k = 0; k < sizeof(optional) / sizeof(optional[0]); k++) {
		int built = 0;
		for (int i = 0; i < nc; i++)
			built |= !strcmp(kg_camera_backend_scheme(i), optional[k].scheme);
		if (!built)
			printf("  %-10s not built (needs %s)\n", optional[k].scheme, optional[k].needs);
	}
	list_cameras();

	printf("\nspectrometer backends:\n");
	int n = kg_spectro_backend_count();
	for (int i = 0; i < n; i++)
		printf("  %-10s %s\n", kg_spectro_backend_scheme(i),
		       kg_spectro_backend_description(i));
	int has_usbspec = 0;
	for (int i = 0; i < n; i++)
		has_usbspec |= !strcmp(kg_spectro_backend_scheme(i), "usbspec");
	if (!has_usbspec)
		printf("  %-10s not built (needs libusb-1.0)\n", "usbspec");

	list_attached();
	return KG_EXIT_OK;
}
