#include <string.h>

#include "device_uri.h"

int kg_uri_scheme_is(const char *uri, size_t n, const char *scheme)
{
	return strlen(scheme) == n && strncmp(scheme, uri, n) == 0;
}

int kg_uri_scheme_unknown(const char *what, const char *uri, size_t n,
                          const char *const *known, const char *hint, kg_err *err)
{
	for (int i = 0; known[i]; i++)
		if (kg_uri_scheme_is(uri, n, known[i]))
			return kg_fail(err, KG_ENOTSUP,
			               "%s '%s': the %s backend is not built into this kogei (see `kogei "
			               "devices`)",
			               what, uri, known[i]);
	return kg_fail(err, KG_EINVAL, "%s '%s': unknown scheme '%.*s' (%s)", what, uri, (int)n,
	               uri, hint);
}
