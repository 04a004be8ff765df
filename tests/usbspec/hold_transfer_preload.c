/* LD_PRELOAD shim for the usbspec timeout test: a device that accepts a spectrum
 * request and never answers. umockdev's ioctl replay refuses (or, matching circularly,
 * answers) a URB that has no recorded reply at once, so it cannot keep a transfer
 * pending until libusb's timeout; this shim stands in front of libusb_bulk_transfer:
 * from the KG_HOLD_FROM-th (default 1) transfer on endpoint KG_HOLD_ENDPOINT (e.g.
 * 0x82) on, it waits out the transfer's timeout and returns LIBUSB_ERROR_TIMEOUT with
 * nothing transferred, as libusb does when a URB is cancelled on its timeout. Every
 * other transfer goes to the real libusb (and so to umockdev). */
#include <dlfcn.h>
#include <stdlib.h>
#include <time.h>

#include <libusb.h>

typedef int (*bulk_fn)(libusb_device_handle *, unsigned char, unsigned char *, int, int *,
                       unsigned int);

int libusb_bulk_transfer(libusb_device_handle *h, unsigned char ep, unsigned char *data,
                         int length, int *transferred, unsigned int timeout)
{
	static bulk_fn real;
	static long seen;
	if (!real)
		*(void **)&real = dlsym(RTLD_NEXT, "libusb_bulk_transfer");
	const char *hold = getenv("KG_HOLD_ENDPOINT"), *from = getenv("KG_HOLD_FROM");
	if (hold && strtol(hold, NULL, 0) == ep && ++seen >= (from ? strtol(from, NULL, 0) : 1)) {
		struct timespec ts = {(time_t)(timeout / 1000), (long)(timeout % 1000) * 1000000L};
		nanosleep(&ts, NULL);
		if (transferred)
			*transferred = 0;
		return LIBUSB_ERROR_TIMEOUT;
	}
	return real ? real(h, ep, data, length, transferred, timeout) : LIBUSB_ERROR_OTHER;
}
