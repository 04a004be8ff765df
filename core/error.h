/* Error convention for every kogei module.
 *
 * Functions return 0 on success or a negative errno-style code (KG_EINVAL for bad
 * input, KG_ENOMEM, KG_EIO for file or device failure, ...). They may also fill a
 * caller-owned kg_err whose message names the file, the field and what was expected.
 * A NULL kg_err is allowed everywhere. */
#ifndef KG_ERROR_H
#define KG_ERROR_H

#include <errno.h>
#include <stddef.h>

#define KG_EINVAL (-EINVAL)
#define KG_ENOMEM (-ENOMEM)
#define KG_EIO (-EIO)
#define KG_ERANGE (-ERANGE)
#define KG_ENOENT (-ENOENT)
#define KG_ENOTSUP (-ENOTSUP)
#define KG_ETIMEDOUT (-ETIMEDOUT)
#define KG_ENODEV (-ENODEV)
/* A folder is in use by another process (locked): the user's to wait for. */
#define KG_EBUSY (-EBUSY)
/* A write failed because the disk (or the quota) is full: the user's to fix, not a
 * device failure. */
#define KG_ENOSPC (-ENOSPC)

typedef struct kg_err {
	char msg[1024];
} kg_err;

#if defined(__GNUC__)
#define KG_PRINTF(a, b) __attribute__((format(printf, a, b)))
#else
#define KG_PRINTF(a, b)
#endif

/* Set err->msg (if err is not NULL) and return code, so callers can write
 * `return kg_fail(err, KG_EINVAL, "%s: line %d: field %s: expected a number", ...);` */
int kg_fail(kg_err *err, int code, const char *fmt, ...) KG_PRINTF(3, 4);

/* Prefix an existing message, e.g. with the name of the file being processed: the
 * result is "PREFIX: message" (a prefix that already ends in ": " keeps just that). */
void kg_err_prefix(kg_err *err, const char *fmt, ...) KG_PRINTF(2, 3);

/* Check an argument at a public boundary. */
#define kg_check_arg(cond, err)                                                        \
	do {                                                                               \
		if (!(cond))                                                                   \
			return kg_fail((err), KG_EINVAL, "%s: invalid argument: %s", __func__,     \
			               #cond);                                                     \
	} while (0)

#endif
