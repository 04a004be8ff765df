/* kogei devices: the backends built into this binary and the spectrometers attached. */
#include <stdio.h>
#include <string.h>

#include "cli.h"
#include "kg_config.h"
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

int kg_cmd_devices(int argc, char **argv)
{
	if (kg_cli_wants_help(argc, argv)) {
		printf("usage: %s\n\n"
		       "List the camera and spectrometer backends built into this kogei, and the\n"
		       "USB spectrometers attached whose ids the drivers know.\n",
		       devices_usage);
		return KG_EXIT_OK;
	}
	if (argc > 1)
		return kg_cli_usage_error(devices_usage, "unexpected argument '%s'", argv[1]);

	static const struct {
		const char *name;
		int built;
	} cameras[] = {
		{"v4l2", HAVE_V4L2},
		{"aravis", HAVE_ARAVIS},
		{"libcamera", HAVE_LIBCAMERA},
	};
	printf("camera backends:\n");
	for (size_t i = 0; i < sizeof(cameras) / sizeof(cameras[0]); i++)
		printf("  %-10s %s\n", cameras[i].name,
		       cameras[i].built ? "dependency found, camera support not implemented yet"
		                        : "not built");

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
