#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "error.h"

int kg_fail(kg_err *err, int code, const char *fmt, ...)
{
	if (err) {
		va_list ap;
		va_start(ap, fmt);
		vsnprintf(err->msg, sizeof(err->msg), fmt, ap);
		va_end(ap);
	}
	return code;
}

void kg_err_prefix(kg_err *err, const char *fmt, ...)
{
	if (!err)
		return;
	char prefix[512], old[sizeof(err->msg)];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(prefix, sizeof(prefix), fmt, ap);
	va_end(ap);
	memcpy(old, err->msg, sizeof(old));
	size_t n = strlen(prefix);
	if (n > sizeof(err->msg) - 3)
		n = sizeof(err->msg) - 3;
	/* a prefix that already ends in ": " gets no second one */
	size_t sep = n >= 2 && prefix[n - 2] == ':' && prefix[n - 1] == ' ' ? 0 : 2;
	memcpy(err->msg, prefix, n);
	memcpy(err->msg + n, ": ", sep);
	size_t rest = sizeof(err->msg) - n - 3;
	size_t m = strnlen(old, rest);
	memcpy(err->msg + n + sep, old, m);
	err->msg[n + sep + m] = '\0';
}
