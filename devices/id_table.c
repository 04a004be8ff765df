/* The USB id table of every spectrometer driver, built whether or not the driver
 * itself is (libusb): the udev rules (devices/gen_udev_rules.c, udev/70-kogei.rules)
 * and `kogei devices` come from it. Keep in step with each driver's own table
 * (usbspec: ocean_models[] in usbspec/ocean_fpga.c); tests/udev/test_id_table.c
 * checks, when libusb is built, that the driver accepts every id listed here. */
#include <stddef.h>

#include "kg_devices.h"

static const kg_spectro_usb_id usb_ids[] = {
	{"usbspec", 0x2457, 0x101E, "Ocean Optics USB2000+/Flame-S"},
	{"usbspec", 0x2457, 0x1022, "Ocean Optics USB4000"},
	{"usbspec", 0x2457, 0x1012, "Ocean Optics HR4000"},
};

const kg_spectro_usb_id *kg_spectro_usb_ids(int *n)
{
	if (n)
		*n = (int)(sizeof(usb_ids) / sizeof(usb_ids[0]));
	return usb_ids;
}
