/* The Ocean Optics FPGA-family models the usbspec driver knows (private to devices/).
 * One table, built with or without libusb: the driver (ocean_fpga.c) takes the
 * detector layout from it, and the USB id table (id_table.c) that the udev rules and
 * `kogei devices` come from lists its vid:pid pairs. */
#ifndef KG_OCEAN_MODELS_H
#define KG_OCEAN_MODELS_H

#include <stdint.h>

typedef struct ocean_model {
	uint16_t vid, pid;
	const char *name;
	int npixels;
	int dark_first, dark_last;
	uint32_t min_us, max_us;
	double saturation;
	int split_high_speed; /* first 2048 bytes on 0x86 at high speed */
} ocean_model;

extern const ocean_model kg_ocean_models[];
extern const int kg_ocean_nmodels;

#endif
