/* usbspec: Ocean Optics / Ocean Insight spectrometers speaking the FPGA command set,
 * over libusb. URI usbspec:<vid>:<pid>[:<serial>] with hexadecimal ids.
 *
 * Protocol (public SeaBreeze facts, see docs/measure.md): commands go to endpoint
 * 0x01 and their replies come on 0x81; spectra come on 0x82, except that a USB4000
 * on a high-speed link sends the first 2048 bytes on 0x86 and the rest on 0x82.
 *   0x01            initialise
 *   0x02 u32 LE     integration time in microseconds
 *   0x05 slot       query information slot; reply 17 bytes: 05 slot ASCII NUL...
 *                   (0 serial, 1-4 wavelength c0-c3, 6-13 nonlinearity k0-k7,
 *                   14 nonlinearity order)
 *   0x09            request a spectrum: 16-bit LE pixels then the sync byte 0x69
 *   0xFE            status, 16 bytes; byte 14 is 0x80 on a high-speed link
 * Every transfer has a timeout; nothing waits forever. Two habits of these FPGA units
 * are handled here: the first scan after the integration time changes was taken at
 * the old time, so it is read and thrown away; and a spectrum a crashed run requested
 * but never read is still queued on the spectrum endpoint, so open drains the
 * spectrum endpoint(s) (reads until nothing comes within DRAIN_TIMEOUT_MS) before the
 * first command. */
#include <libusb.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ocean_models.h"
#include "spectro_driver.h"

enum {
	EP_COMMAND = 0x01,
	EP_REPLY = 0x81,
	EP_SPECTRUM = 0x82,
	EP_SPECTRUM_FIRST = 0x86, /* USB4000 high speed: the first 2048 bytes */
	SPLIT_BYTES = 2048,
	SYNC_BYTE = 0x69,
	INFO_REPLY = 17,
	STATUS_REPLY = 16,
	COMMAND_TIMEOUT_MS = 1000,
	SPECTRUM_EXTRA_MS = 1000, /* beyond the integration time */
	DRAIN_TIMEOUT_MS = 50,    /* a queued spectrum is already there: it comes at once */
	DRAIN_MAX_PACKETS = 8,    /* more than a crashed run can have left */
};


typedef struct ocean_state {
	libusb_context *ctx;
	libusb_device_handle *h;
	const ocean_model *model;
	char serial[32];
	int high_speed;
	uint32_t integration_us;  /* 0 until set: the device's own is not trusted */
	int stale_scan;           /* the next scan was taken at the previous time */
	unsigned char *packet;
} ocean_state;

/* A libusb failure as a kogei error naming the device and the step. */
static int usb_fail(ocean_state *o, int rc, const char *what, unsigned ep, kg_err *err)
{
	const char *dev = o->model->name;
	switch (rc) {
	case LIBUSB_ERROR_TIMEOUT:
		return kg_fail(err, KG_ETIMEDOUT,
		               "usbspec %s %s: no reply to %s on endpoint 0x%02x in time",
		               dev, o->serial, what, ep);
	case LIBUSB_ERROR_NO_DEVICE:
		return kg_fail(err, KG_ENODEV,
		               "usbspec %s %s: device unplugged during %s: reconnect it and "
		               "measure again", dev, o->serial, what);
	case LIBUSB_ERROR_PIPE:
		return kg_fail(err, KG_EIO, "usbspec %s %s: endpoint 0x%02x stalled during %s",
		               dev, o->serial, ep, what);
	case LIBUSB_ERROR_OVERFLOW:
		return kg_fail(err, KG_EIO,
		               "usbspec %s %s: device sent more than expected during %s", dev,
		               o->serial, what);
	default:
		return kg_fail(err, KG_EIO,
		               "usbspec %s %s: USB error during %s on endpoint 0x%02x: %s (was the "
		               "device unplugged?)", dev, o->serial, what, ep, libusb_error_name(rc));
	}
}

static int send_command(ocean_state *o, const unsigned char *cmd, int len, const char *what,
                        kg_err *err)
{
	int sent = 0;
	int rc = libusb_bulk_transfer(o->h, EP_COMMAND, (unsigned char *)cmd, len, &sent,
	                              COMMAND_TIMEOUT_MS);
	if (rc)
		return usb_fail(o, rc, what, EP_COMMAND, err);
	if (sent != len)
		return kg_fail(err, KG_EIO, "usbspec %s %s: %s: sent %d of %d bytes",
		               o->model->name, o->serial, what, sent, len);
	return 0;
}

/* Read exactly len bytes from ep; *got says how many came. */
static int receive(ocean_state *o, unsigned ep, unsigned char *buf, int len, int *got,
                   unsigned timeout_ms, const char *what, kg_err *err)
{
	*got = 0;
	int rc = libusb_bulk_transfer(o->h, (unsigned char)ep, buf, len, got, timeout_ms);
	return rc ? usb_fail(o, rc, what, ep, err) : 0;
}

/* Query an information slot into text (NUL-terminated, at most 15 characters). */
static int query_slot(ocean_state *o, int slot, char text[16], kg_err *err)
{
	unsigned char cmd[2] = {0x05, (unsigned char)slot}, reply[INFO_REPLY];
	char what[48];
	snprintf(what, sizeof(what), "query of information slot %d", slot);
	int got, r = send_command(o, cmd, 2, what, err);
	if (!r)
		r = receive(o, EP_REPLY, reply, INFO_REPLY, &got, COMMAND_TIMEOUT_MS, what, err);
	if (r)
		return r;
	if (got != INFO_REPLY || reply[0] != 0x05 || reply[1] != slot)
		return kg_fail(err, KG_EIO,
		               "usbspec %s %s: %s: expected a %d-byte reply starting 05 %02x, got %d "
		               "bytes starting %02x %02x", o->model->name, o->serial, what,
		               INFO_REPLY, slot, got, got > 0 ? reply[0] : 0, got > 1 ? reply[1] : 0);
	memcpy(text, reply + 2, 15);
	text[15] = 0;
	return 0;
}

static int slot_number(ocean_state *o, int slot, const char *name, double *out, kg_err *err)
{
	char text[16], *end;
	int r = query_slot(o, slot, text, err);
	if (r)
		return r;
	*out = strtod(text, &end);
	while (*end == ' ')
		end++;
	if (end == text || *end || !isfinite(*out))
		return kg_fail(err, KG_EIO,
		               "usbspec %s %s: information slot %d (%s): expected a number, got "
		               "'%s'", o->model->name, o->serial, slot, name, text);
	return 0;
}

static int parse_hex16(const char *s, size_t len, uint16_t *out)
{
	if (len >= 2 && s[0] == '0' && (s[1] == 'x' || s[1] == 'X')) {
		s += 2;
		len -= 2;
	}
	if (len < 1 || len > 4)
		return -1;
	unsigned v = 0;
	for (size_t i = 0; i < len; i++) {
		char c = s[i];
		int d = c >= '0' && c <= '9' ? c - '0' : c >= 'a' && c <= 'f' ? c - 'a' + 10
		        : c >= 'A' && c <= 'F' ? c - 'A' + 10 : -1;
		if (d < 0)
			return -1;
		v = v * 16 + (unsigned)d;
	}
	*out = (uint16_t)v;
	return 0;
}

static void ocean_close(void *state)
{
	ocean_state *o = state;
	if (o->h) {
		libusb_release_interface(o->h, 0);
		libusb_close(o->h);
	}
	if (o->ctx)
		libusb_exit(o->ctx);
	free(o->packet);
	free(o);
}

/* Read and drop whatever is queued on ep (len bytes a packet). Nothing queued shows as
 * a timeout; a transfer that completes with no data (a replayed timed-out URB) also
 * ends the drain. An unplugged device is an error. */
static int drain(ocean_state *o, unsigned ep, int len, kg_err *err)
{
	for (int n = 0; n < DRAIN_MAX_PACKETS; n++) {
		int got = 0;
		int rc = libusb_bulk_transfer(o->h, (unsigned char)ep, o->packet, len, &got,
		                              DRAIN_TIMEOUT_MS);
		if (rc == LIBUSB_ERROR_NO_DEVICE)
			return usb_fail(o, rc, "draining the spectrum endpoint", ep, err);
		if (rc == LIBUSB_ERROR_TIMEOUT || got == 0)
			return 0;
	}
	return kg_fail(err, KG_EIO,
	               "usbspec %s: endpoint 0x%02x still delivers data after %d packets were "
	               "drained at open: the device is streaming; power-cycle it",
	               o->model->name, ep, DRAIN_MAX_PACKETS);
}

/* Claim, initialise and read the serial of one candidate device. */
static int ocean_start(ocean_state *o, libusb_device *dev, kg_err *err)
{
	int rc = libusb_open(dev, &o->h);
	if (rc == LIBUSB_ERROR_ACCESS)
		return kg_fail(err, KG_EIO,
		               "usbspec %s: permission denied opening bus %d device %d: install "
		               "kogei's udev rules and join the colord group", o->model->name,
		               libusb_get_bus_number(dev), libusb_get_device_address(dev));
	if (rc) {
		o->h = NULL;
		return usb_fail(o, rc, "open", 0, err);
	}
	if ((rc = libusb_claim_interface(o->h, 0)) != 0)
		return usb_fail(o, rc, "claiming interface 0", 0, err);
	static const unsigned char init[1] = {0x01}, status[1] = {0xFE};
	unsigned char reply[STATUS_REPLY];
	char text[16];
	int bytes = o->model->npixels * 2 + 1;
	int got, r = o->model->split_high_speed
	                 ? drain(o, EP_SPECTRUM_FIRST, SPLIT_BYTES, err)
	                 : 0;
	if (!r)
		r = drain(o, EP_SPECTRUM,
		          o->model->split_high_speed ? bytes - SPLIT_BYTES : bytes, err);
	if (!r)
		r = send_command(o, init, 1, "initialisation", err);
	if (!r)
		r = send_command(o, status, 1, "status query", err);
	if (!r)
		r = receive(o, EP_REPLY, reply, STATUS_REPLY, &got, COMMAND_TIMEOUT_MS,
		            "status query", err);
	if (!r && got != STATUS_REPLY)
		r = kg_fail(err, KG_EIO, "usbspec %s: status query: expected %d bytes, got %d",
		            o->model->name, STATUS_REPLY, got);
	if (r)
		return r;
	o->high_speed = reply[14] == 0x80;
	if ((r = query_slot(o, 0, text, err)) != 0)
		return r;
	snprintf(o->serial, sizeof(o->serial), "%s", text);
	return 0;
}

static int ocean_open(const char *target, void **state, kg_err *err)
{
	const char *c1 = strchr(target, ':');
	const char *c2 = c1 ? strchr(c1 + 1, ':') : NULL;
	uint16_t vid, pid;
	if (!c1 || parse_hex16(target, (size_t)(c1 - target), &vid) ||
	    parse_hex16(c1 + 1, c2 ? (size_t)(c2 - c1 - 1) : strlen(c1 + 1), &pid))
		return kg_fail(err, KG_EINVAL,
		               "usbspec:%s: expected usbspec:<vid>:<pid>[:<serial>] with hexadecimal "
		               "ids, e.g. usbspec:2457:101e", target);
	const char *want_serial = c2 && c2[1] ? c2 + 1 : NULL;
	const ocean_model *model = NULL;
	for (int i = 0; i < kg_ocean_nmodels; i++)
		if (kg_ocean_models[i].vid == vid && kg_ocean_models[i].pid == pid)
			model = &kg_ocean_models[i];
	if (!model)
		return kg_fail(err, KG_EINVAL,
		               "usbspec:%s: %04x:%04x is not a model this driver knows (expected "
		               "2457:101e USB2000+/Flame-S, 2457:1022 USB4000, 2457:1012 HR4000)",
		               target, vid, pid);

	ocean_state *o = calloc(1, sizeof(*o));
	if (!o || !(o->packet = malloc((size_t)model->npixels * 2 + 1))) {
		free(o);
		return KG_ENOMEM;
	}
	o->model = model;
	snprintf(o->serial, sizeof(o->serial), "?");
	int rc = libusb_init(&o->ctx);
	if (rc) {
		o->ctx = NULL;
		ocean_close(o);
		return kg_fail(err, KG_EIO, "usbspec: libusb_init failed: %s",
		               libusb_error_name(rc));
	}
	libusb_device **list = NULL;
	ssize_t n = libusb_get_device_list(o->ctx, &list);
	int r = KG_ENODEV, seen = 0;
	for (ssize_t i = 0; i < n && r == KG_ENODEV; i++) {
		struct libusb_device_descriptor d;
		if (libusb_get_device_descriptor(list[i], &d) || d.idVendor != vid ||
		    d.idProduct != pid)
			continue;
		seen++;
		r = ocean_start(o, list[i], err);
		if (!r && want_serial && strcmp(o->serial, want_serial)) {
			r = KG_ENODEV;
			libusb_release_interface(o->h, 0);
		}
		if (r && o->h) {
			libusb_close(o->h);
			o->h = NULL;
		}
	}
	if (list) /* allocated even when empty */
		libusb_free_device_list(list, 1);
	if (r == KG_ENODEV) {
		if (want_serial && seen)
			kg_fail(err, KG_ENODEV,
			        "usbspec:%s: %d %s attached, none with serial %s", target, seen,
			        model->name, want_serial);
		else
			kg_fail(err, KG_ENODEV, "usbspec:%s: no %s (%04x:%04x) attached", target,
			        model->name, vid, pid);
	}
	if (r) {
		ocean_close(o);
		return r;
	}
	*state = o;
	return 0;
}

static int ocean_identify(void *state, kg_spectro_info *info, kg_err *err)
{
	ocean_state *o = state;
	snprintf(info->model, sizeof(info->model), "%s", o->model->name);
	snprintf(info->serial, sizeof(info->serial), "%s", o->serial);
	info->npixels = o->model->npixels;
	info->saturation = o->model->saturation;
	info->min_integration_us = o->model->min_us;
	info->max_integration_us = o->model->max_us;
	info->high_speed = o->high_speed;
	return 0;
}

static int ocean_wavelengths(void *state, double coeffs[4], kg_err *err)
{
	static const char *names[4] = {"wavelength c0", "wavelength c1", "wavelength c2",
	                               "wavelength c3"};
	for (int k = 0; k < 4; k++) {
		int r = slot_number(state, 1 + k, names[k], &coeffs[k], err);
		if (r)
			return r;
	}
	return 0;
}

static void ocean_dark_pixels(void *state, int *first, int *last)
{
	ocean_state *o = state;
	*first = o->model->dark_first;
	*last = o->model->dark_last;
}

static int ocean_nonlinearity(void *state, double coeffs[KG_SPECTRO_MAX_NL], int *order,
                              kg_err *err)
{
	ocean_state *o = state;
	double v;
	int r = slot_number(o, 14, "nonlinearity order", &v, err);
	if (r)
		return r;
	if (v != (int)v || v < 0 || v > KG_SPECTRO_MAX_NL - 1)
		return kg_fail(err, KG_EIO,
		               "usbspec %s %s: information slot 14 (nonlinearity order): expected "
		               "0 to %d, got %g", o->model->name, o->serial, KG_SPECTRO_MAX_NL - 1, v);
	*order = (int)v;
	for (int k = 0; k <= *order; k++) {
		char name[32];
		snprintf(name, sizeof(name), "nonlinearity k%d", k);
		if ((r = slot_number(o, 6 + k, name, &coeffs[k], err)) != 0)
			return r;
	}
	return 0;
}

static int ocean_set_integration(void *state, uint32_t us, kg_err *err)
{
	ocean_state *o = state;
	unsigned char cmd[5] = {0x02, (unsigned char)us, (unsigned char)(us >> 8),
	                        (unsigned char)(us >> 16), (unsigned char)(us >> 24)};
	int r = send_command(o, cmd, 5, "setting the integration time", err);
	if (!r && us != o->integration_us)
		o->stale_scan = 1;
	if (!r)
		o->integration_us = us;
	return r;
}

/* Request one spectrum and read it into o->packet, checked (length, sync byte). */
static int read_packet(ocean_state *o, kg_err *err)
{
	static const unsigned char request[1] = {0x09};
	int bytes = o->model->npixels * 2 + 1, got = 0, first = 0;
	unsigned timeout = o->integration_us / 1000 + SPECTRUM_EXTRA_MS;
	int r = send_command(o, request, 1, "spectrum request", err);
	if (!r && o->model->split_high_speed && o->high_speed) {
		r = receive(o, EP_SPECTRUM_FIRST, o->packet, SPLIT_BYTES, &first, timeout,
		            "spectrum read", err);
		if (!r && first == SPLIT_BYTES)
			r = receive(o, EP_SPECTRUM, o->packet + SPLIT_BYTES, bytes - SPLIT_BYTES, &got,
			            timeout, "spectrum read", err);
	} else if (!r) {
		r = receive(o, EP_SPECTRUM, o->packet, bytes, &got, timeout, "spectrum read", err);
	}
	if (r)
		return r;
	got += first;
	if (got != bytes)
		return kg_fail(err, KG_EIO,
		               "usbspec %s %s: short spectrum packet: %d of %d bytes", o->model->name,
		               o->serial, got, bytes);
	if (o->packet[bytes - 1] != SYNC_BYTE)
		return kg_fail(err, KG_EIO,
		               "usbspec %s %s: spectrum ends with 0x%02x, expected the sync byte "
		               "0x%02x: the transfer is out of step", o->model->name, o->serial,
		               o->packet[bytes - 1], SYNC_BYTE);
	return 0;
}

static int ocean_read_raw(void *state, double *counts, kg_err *err)
{
	ocean_state *o = state;
	int r = 0;
	if (o->stale_scan && !(r = read_packet(o, err))) /* taken at the old time: dropped */
		o->stale_scan = 0;
	if (!r)
		r = read_packet(o, err);
	if (r)
		return r;
	for (int p = 0; p < o->model->npixels; p++)
		counts[p] = o->packet[2 * p] | (o->packet[2 * p + 1] << 8);
	return 0;
}

const kg_spectro_driver kg_spectro_ocean_fpga_driver = {
	.scheme = "usbspec",
	.description = "Ocean Optics FPGA spectrometers over libusb (USB2000+, Flame-S, "
	               "USB4000, HR4000)",
	.open = ocean_open,
	.identify = ocean_identify,
	.wavelength_calibration = ocean_wavelengths,
	.dark_pixels = ocean_dark_pixels,
	.nonlinearity = ocean_nonlinearity,
	.set_integration = ocean_set_integration,
	.read_raw = ocean_read_raw,
	.set_target = NULL,
	.close = ocean_close,
};
