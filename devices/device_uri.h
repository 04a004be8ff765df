/* The scheme of a device URI SCHEME:TARGET, shared by the camera and spectrometer
 * registries (private to devices/). */
#ifndef KG_DEVICE_URI_H
#define KG_DEVICE_URI_H

#include <stddef.h>

#include "kg_core.h"

/* 1 when the scheme of uri, its first n characters, is scheme. */
int kg_uri_scheme_is(const char *uri, size_t n, const char *scheme);
/* The refusal of a scheme no built driver has. One of known (NULL-terminated: every
 * backend kogei has, built or not): KG_ENOTSUP, "WHAT 'URI': the SCHEME backend is not
 * built into this kogei (see `kogei devices`)"; any other: KG_EINVAL, "WHAT 'URI':
 * unknown scheme 'SCHEME' (HINT)". */
int kg_uri_scheme_unknown(const char *what, const char *uri, size_t n,
                          const char *const *known, const char *hint, kg_err *err);

#endif
