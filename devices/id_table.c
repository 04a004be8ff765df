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
