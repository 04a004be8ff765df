/* Every id in kg_spectro_usb_ids is one its driver knows: opening it without the
 * device attached fails with KG_ENODEV (or KG_EIO when USB cannot be scanned), never
 * KG_EINVAL "not a model this driver knows". Only with the driver built. */
#include <stdio.h>
#include <string.h>

#include "kg_config.h"
#include "kg_devices.h"

int main(void)
{
	int n, fail = 0;
	const kg_spectro_usb_id *ids = kg_spectro_usb_ids(&n);
	if (n < 1) {
		printf("FAIL: empty id table\n");
		return 1;
	}
	for (int i = 0; i < n; i++) {
		if (!ids[i].scheme || !ids[i].model || !ids[i].vid) {
			printf("FAIL: entry %d incomplete\n", i);
			fail = 1;
			continue;
		}
		for (int j = 0; j < i; j++)
			if (ids[j].vid == ids[i].vid && ids[j].pid == ids[i].pid) {
				printf("FAIL: %04x:%04x listed twice\n", ids[i].vid, ids[i].pid);
				fail = 1;
			}
#if HAVE_LIBUSB
		char uri[64];
		snprintf(uri, sizeof(uri), "%s:%04x:%04x", ids[i].scheme, ids[i].vid, ids[i].pid);
		kg_spectro *s = NULL;
		kg_err err = {0};
		int r = kg_spectro_open(uri, &s, &err);
		if (r == KG_EINVAL || r == KG_ENOTSUP) {
			printf("FAIL: %s (%s): driver refuses it: %s\n", uri, ids[i].model, err.msg);
			fail = 1;
		}
		kg_spectro_free(&s);
#endif
	}
	if (!fail)
		printf("ok: %d ids\n", n);
	return fail;
}
