/* The public header of devices/: spectrometers behind one driver table, and the
 * reflectance computed from their readings.
 *
 * A spectrometer is opened by URI:
 *   usbspec:<vid>:<pid>[:<serial>]   Ocean Optics FPGA-family over libusb (hex ids)
 *   sim:<spectra.cgats>              simulated instrument measuring known spectra
 *   replay:<recording>               plays back a recording (kg_spectro_record_start)
 * Applications use this header only; drivers implement devices/spectro_driver.h. */
#ifndef KG_DEVICES_H
#define KG_DEVICES_H

#include <stdint.h>

#include "kg_core.h"

/* Most nonlinearity coefficients a driver may report (order 7). */
#define KG_SPECTRO_MAX_NL 8

/* What an instrument says about itself, filled once at open. */
typedef struct kg_spectro_info {
	char backend[16];  /* URI scheme of the driver: "usbspec", "sim" */
	char model[32];    /* "USB2000+/Flame-S", "USB4000", ... */
	char serial[32];
	int npixels;
	double wl_coeffs[4]; /* wavelength of pixel p (nm): c0 + c1 p + c2 p^2 + c3 p^3 */
	int dark_first, dark_last; /* electrical-dark (masked) pixels, inclusive; -1 if none */
	int nl_order;        /* nonlinearity polynomial order; -1 when the device has none */
	double nl_coeffs[KG_SPECTRO_MAX_NL];
	double saturation;   /* raw count at which the converter saturates */
	uint32_t min_integration_us, max_integration_us;
	uint32_t integration_us; /* current setting, 0 before the first set */
	int high_speed;      /* 1 on a USB 2.0 high-speed link */
} kg_spectro_info;

typedef struct kg_spectro kg_spectro;

/* Open by URI. Errors: KG_EINVAL for a malformed URI or unknown scheme, KG_ENODEV
 * when no such device is attached, KG_ENOTSUP when the backend is not built in,
 * KG_EIO / KG_ETIMEDOUT for a device that does not answer as documented. */
int kg_spectro_open(const char *uri, kg_spectro **out, kg_err *err);
/* Close and free; *s becomes NULL. Safe on NULL. */
void kg_spectro_free(kg_spectro **s);
const kg_spectro_info *kg_spectro_get_info(const kg_spectro *s);
/* Integration time in microseconds, checked against the model's range. */
int kg_spectro_set_integration(kg_spectro *s, uint32_t us, kg_err *err);
/* One spectrum of info->npixels raw counts, as the device sent them. */
int kg_spectro_read_raw(kg_spectro *s, double *counts, kg_err *err);
/* Tell a simulated instrument what the operator was asked to put under the probe
 * ("dark", "white" or a sample id). Real instruments ignore it; the simulated one
 * refuses a sample it does not have. */
int kg_spectro_set_target(kg_spectro *s, const char *what, kg_err *err);

/* Record the instrument's identity and then every raw read (with its integration time
 * and the target last named) to path, a recording that replay:<path> plays back
 * (format: devices/spectro_replay.c, docs/measure.md). Written to a temporary file and
 * renamed into place by kg_spectro_record_finish (*nreads, if not NULL: the reads
 * recorded), or by kg_spectro_free with errors unreported; a failed run keeps what was
 * read so far. */
int kg_spectro_record_start(kg_spectro *s, const char *path, kg_err *err);
int kg_spectro_record_finish(kg_spectro *s, int *nreads, kg_err *err);

/* Wavelength of a pixel from the calibration polynomial. */
double kg_spectro_wavelength(const kg_spectro_info *info, int pixel);

/* Corrections of raw counts (kg_spectro_correct, kg_spectro_acquire). */
enum {
	KG_CORRECT_ELECTRICAL_DARK = 1 << 0, /* subtract the mean of the masked pixels */
	KG_CORRECT_NONLINEARITY = 1 << 1,    /* divide by the device's polynomial in counts */
};
/* out[p] = corrected raw[p]: electrical dark first, then nonlinearity
 * c / (k0 + k1 c + ... + kn c^n) on the dark-subtracted count c. A correction the
 * device cannot give (no dark pixels, order < 0) is skipped. A correction factor
 * k0 + ... + kn c^n that is zero or negative (a count outside the range the
 * coefficients were fitted to, or bad coefficients) is KG_ERANGE naming the pixel,
 * its wavelength, the count and the factor. In-place is allowed. */
int kg_spectro_correct(const kg_spectro_info *info, unsigned flags, const double *raw,
                       double *out, kg_err *err);

/* Backends built into this binary, for `kogei devices`. */
int kg_spectro_backend_count(void);
const char *kg_spectro_backend_scheme(int i);
const char *kg_spectro_backend_description(int i);

/* ---- readings and reflectance (reflectance.c) ---- */

/* One averaged reading on the device's own pixel grid. */
typedef struct kg_spectro_reading {
	int n;
	double *wl;        /* nm, per pixel */
	double *counts;    /* corrected, averaged and smoothed counts */
	int scans;
	uint32_t integration_us;
	int saturated;     /* pixels within 400-700 nm that saturated in any scan */
	double saturated_nm[2]; /* the wavelength range of those pixels (when saturated) */
	double peak;       /* highest raw count seen within 400-700 nm */
	double when;       /* seconds since the epoch when the reading finished */
} kg_spectro_reading;

typedef struct kg_acquire_options {
	int scans;           /* averaged, >= 1 */
	int boxcar;          /* boxcar half-width in pixels (window 2 b + 1), 0 = none */
	unsigned corrections; /* KG_CORRECT_* */
} kg_acquire_options;

/* scans 1, no smoothing, both corrections. */
void kg_acquire_options_default(kg_acquire_options *o);
/* Read o->scans spectra, correct, average and smooth them into *out (cleared first). */
int kg_spectro_acquire(kg_spectro *s, const kg_acquire_options *o, kg_spectro_reading *out,
                       kg_err *err);
void kg_spectro_reading_clear(kg_spectro_reading *r);
/* Boxcar mean over 2 half + 1 pixels, shrinking at the ends. in != out. */
void kg_boxcar(const double *in, double *out, int n, int half);

/* The white standard's certified reflectance: the first spectrum of a CGATS file
 * (ArgyllCMS .sp/.ti3, X-Rite exports), or flat 0.99 when path is NULL. */
int kg_white_reference_load(const char *path, kg_spectrum *out, kg_err *err);

/* R = (S - D) / (W - D) x R_white per pixel, resampled to the 61-band grid. Pixels
 * where the white is within 1 count of the dark carry no information and are left
 * out (their number in *dropped if not NULL); the readings must share a pixel grid
 * and integration time. */
int kg_reflectance(const kg_spectro_reading *dark, const kg_spectro_reading *white,
                   const kg_spectrum *white_reflectance, const kg_spectro_reading *sample,
                   kg_spectrum *out, int *dropped, kg_err *err);
/* Relative change of the white's signal (W - D) summed over 400-700 nm between two
 * white readings: (later - earlier) / earlier. */
double kg_white_drift(const kg_spectro_reading *dark, const kg_spectro_reading *earlier,
                      const kg_spectro_reading *later);

/* ---- a measurement session (measure_run.c) ----
 * Dark and white references, samples as reflectance, the output file: what `kogei
 * measure` guides an operator through and what runs unattended (`kogei demo`). */

/* A warning for the operator ("TCS01: 12 pixels saturated ..."), without "warning: ". */
typedef void (*kg_measure_warn_fn)(void *user, const char *message);

typedef struct kg_measure_session {
	kg_spectro *spectro;        /* opened and freed by the caller */
	const char *uri;            /* as opened: the output's SPECTROMETER keyword */
	kg_acquire_options acq;
	kg_spectrum white_refl;     /* the white standard's certified reflectance */
	const char *white_ref_path; /* its file; NULL for flat 0.99 */
	kg_spectro_reading dark, white; /* the current references */
	kg_measure_warn_fn warn;    /* pixels without white signal; NULL: not reported */
	void *warn_user;
} kg_measure_session;

/* Free the references (not the spectrometer). */
void kg_measure_session_clear(kg_measure_session *m);
/* Point the instrument at `target` ("dark", "white" or a sample id) and acquire with
 * m->acq into *out. A reading with pixels at full scale within 400-700 nm is refused
 * (KG_ERANGE, naming `what`, the wavelength range of the saturated pixels and the
 * integration time to shorten): its counts there, and so its reflectance, are wrong. */
int kg_measure_reading(kg_measure_session *m, const char *target, const char *what,
                       kg_spectro_reading *out, kg_err *err);
/* A sample's reflectance against m->dark and m->white (both measured); warns when
 * pixels had no white signal. */
int kg_measure_sample(kg_measure_session *m, const char *id, kg_spectrum *out, kg_err *err);
/* Write reflectance spectra as `kogei measure` does: SAMPLE_ID SPEC_400 ... SPEC_700
 * and the keywords ORIGINATOR (originator), INSTRUMENT, SERIAL_NUMBER, SPECTROMETER,
 * INTEGRATION_TIME_US, SCANS_AVERAGED, BOXCAR_HALF_WIDTH, WHITE_REFERENCE,
 * MEASUREMENT_MODE, CREATED, then `extra` (name, value pairs, NULL-terminated; may be
 * NULL). */
int kg_measure_write(const kg_measure_session *m, const char *path, const kg_patchset *ps,
                     const char *originator, const char *const *extra, kg_err *err);

/* Called after each patch of kg_spectro_measure_patches: i of n (0-based), its id and
 * reflectance. */
typedef void (*kg_measure_progress_fn)(void *user, int i, int n, const char *id,
                                       const kg_spectrum *reflectance);
/* Unattended: dark, white, then every id in order, into a new patch set of spectra
 * (*out, the ids as given). Meant for instruments that need no operator (sim, replay)
 * and for scripts; progress may be NULL. */
int kg_spectro_measure_patches(kg_measure_session *m, int n, const char *const *ids,
                               kg_measure_progress_fn progress, void *user,
                               kg_patchset **out, kg_err *err);

/* ---- USB id table (id_table.c) ----
 * The USB devices every spectrometer driver knows, whether or not the driver is built
 * into this binary: the source of udev/70-kogei.rules (kogei-gen-udev) and of the
 * attached-device scan in `kogei devices`. */
typedef struct kg_spectro_usb_id {
	const char *scheme; /* the driver's URI scheme: "usbspec" */
	uint16_t vid, pid;
	const char *model;
} kg_spectro_usb_id;

/* The table, *n entries (n may be NULL); static, never freed. */
const kg_spectro_usb_id *kg_spectro_usb_ids(int *n);

/* The device classes each camera backend opens, whether or not the backend is built:
 * cameras are matched by class (USB3 Vision interface, video4linux node), not by
 * vendor and product. The source of the camera rules in udev/70-kogei.rules. */
typedef struct kg_camera_device_class {
	const char *scheme;  /* the backend's URI scheme: "aravis", "v4l2" */
	const char *what;    /* for the rules' comment */
	const char *match;   /* udev match keys */
	const char *group;   /* the group given access besides the seat's user */
} kg_camera_device_class;

const kg_camera_device_class *kg_camera_device_classes(int *n);

#endif
