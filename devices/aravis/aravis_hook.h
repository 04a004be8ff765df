/* A test seam of the Aravis backend (private to devices/aravis and tests/aravis).
 *
 * The in-process fake camera (`aravis:Fake_1`) is created inside Aravis when the
 * backend opens it, so a test cannot reach it from outside. The hook below is called
 * with every ArvCamera the backend opens, before the backend reads anything from it;
 * a test uses it to reach the ArvFakeCamera (arv_fake_device_get_fake_camera) and
 * install a fill pattern that injects known frames. */
#ifndef KG_ARAVIS_HOOK_H
#define KG_ARAVIS_HOOK_H

#include <arv.h>

typedef void (*kg_aravis_open_hook)(void *user, ArvCamera *camera);

/* Install hook for cameras opened from now on; NULL removes it. Not thread-safe:
 * tests call it before opening anything. */
void kg_aravis_set_open_hook(kg_aravis_open_hook hook, void *user);

#endif
