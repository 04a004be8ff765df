/* The interface a spectrometer driver implements (private to devices/). A driver is
 * one table of entry points; spectro.c keeps the registry of drivers by URI scheme
 * and calls the entry points in order at open: open, identify, wavelength
 * calibration, dark pixels, nonlinearity. Every entry point returns 0 or a negative
 * KG_E* code with a message naming the device and what was expected. */
#ifndef KG_SPECTRO_DRIVER_H
#define KG_SPECTRO_DRIVER_H

#include "kg_config.h"
#include "kg_devices.h"

typedef struct kg_spectro_driver {
	const char *scheme;      /* URI scheme */
	const char *description; /* one line for `kogei devices` */
	/* Find and open the device named by the part of the URI after "scheme:". */
	int (*open)(const char *target, void **state, kg_err *err);
	/* Fill backend-independent identity: model, serial, npixels, saturation,
	 * integration range, high_speed. */
	int (*identify)(void *state, kg_spectro_info *info, kg_err *err);
	/* The wavelength polynomial c0..c3. */
	int (*wavelength_calibration)(void *state, double coeffs[4], kg_err *err);
	/* Electrical-dark pixel range (inclusive), -1 -1 when none. */
	void (*dark_pixels)(void *state, int *first, int *last);
	/* Nonlinearity coefficients and order (-1 when none). */
	int (*nonlinearity)(void *state, double coeffs[KG_SPECTRO_MAX_NL], int *order,
	                    kg_err *err);
	int (*set_integration)(void *state, uint32_t us, kg_err *err);
	/* npixels raw counts. */
	int (*read_raw)(void *state, double *counts, kg_err *err);
	/* Optional (NULL): what is under the probe, for simulated instruments. */
	int (*set_target)(void *state, const char *what, kg_err *err);
	void (*close)(void *state);
} kg_spectro_driver;

extern const kg_spectro_driver kg_spectro_sim_driver;
extern const kg_spectro_driver kg_spectro_replay_driver;

/* The recorder behind kg_spectro_record_start (spectro_replay.c, which owns the format
 * replay: reads): open writes the identity to a temporary file, target notes what
 * kg_spectro_set_target named, read appends one raw spectrum, close writes the end
 * line and renames the file into place (*nreads: the reads recorded). */
typedef struct kg_spectro_recorder kg_spectro_recorder;
int kg_recorder_open(const char *path, const kg_spectro_info *info, kg_spectro_recorder **out,
                     kg_err *err);
void kg_recorder_target(kg_spectro_recorder *r, const char *what);
void kg_recorder_read(kg_spectro_recorder *r, uint32_t us, const double *counts);
int kg_recorder_close(kg_spectro_recorder **r, int *nreads, kg_err *err);
#if HAVE_LIBUSB
extern const kg_spectro_driver kg_spectro_ocean_fpga_driver;
#endif

#endif
