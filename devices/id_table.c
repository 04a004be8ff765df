/* The USB id table of every spectrometer driver, built whether or not the driver
 * itself is (libusb): the udev rules (devices/gen_udev_rules.c, udev/70-kogei.rules)
 * and `kogei devices` come from it. It is made from each driver's own model table
 * (usbspec: kg_ocean_models, usbspec/ocean_models.c), so the two cannot disagree;
 * tests/udev/test_id_table.c checks, when libusb is built, that the driver opens
 * every id listed here. */
#include <stdio.h>
#include <stddef.h>

#include "kg_devices.h"
#include "usbspec/ocean_models.h"

#define MAX_IDS 32

static kg_spectro_usb_id usb_ids[MAX_IDS];
static char usb_names[MAX_IDS][64];
static int nusb_ids = -1;

const kg_spectro_usb_id *kg_spectro_usb_ids(int *n)
{
	/* Built once, on first use; the tables are constant. */
	if (nusb_ids < 0) {
		int k = 0;
		for (int i = 0; i < kg_ocean_nmodels && k < MAX_IDS; i++, k++) {
			snprintf(usb_names[k], sizeof(usb_names[k]), "Ocean Optics %s",
			         kg_ocean_models[i].name);
			usb_ids[k] = (kg_spectro_usb_id){"usbspec", kg_ocean_models[i].vid,
			                                 kg_ocean_models[i].pid, usb_names[k]};
		}
		nusb_ids = k;
	}
	if (n)
		*n = nusb_ids;
	return usb_ids;
}

/* USB3 Vision: an interface of class 0xEF (miscellaneous), subclass 0x05, protocol 0x00
 * (USB3 Vision 1.0, section 4.2; what Aravis' USB3 Vision backend opens through
 * libusb); ID_USB_INTERFACES comes from udev's usb_id builtin. V4L2: UVC cameras
 * (interface class 0x0E, uvcvideo) and CSI sensors, used through their video4linux
 * nodes. */
static const kg_camera_device_class camera_classes[] = {
	{"aravis", "USB3 Vision cameras (interface class EF/05/00, opened through libusb)",
	 "SUBSYSTEM==\"usb\", ENV{DEVTYPE}==\"usb_device\", ENV{ID_USB_INTERFACES}==\"*:ef0500:*\"",
	 "plugdev"},
	{"v4l2", "V4L2 cameras: UVC (interface class 0E, uvcvideo) and sensor drivers, through "
	         "their video4linux nodes",
	 "SUBSYSTEM==\"video4linux\"", "video"},
};

const kg_camera_device_class *kg_camera_device_classes(int *n)
{
	if (n)
		*n = (int)(sizeof(camera_classes) / sizeof(camera_classes[0]));
	return camera_classes;
}
