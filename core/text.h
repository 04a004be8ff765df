/* The encoding of text input files (CGATS, CSV): whatever reaches JSON, HTML or the
 * terminal from them is UTF-8.
 *
 * A file is taken as UTF-8 when it is well-formed UTF-8 (no overlong forms, no
 * surrogates, nothing above U+10FFFF); a leading byte-order mark is skipped. A file that
 * is not, and whose every byte is a Windows-1252 character (the superset of ISO 8859-1
 * that Windows tools write: "Caf\xe9 25\xb0C"), is converted from Windows-1252. Refused,
 * naming the line, the byte's offset in the file and its value: a byte that Windows-1252
 * leaves undefined (0x81, 0x8D, 0x8F, 0x90, 0x9D) in a file that is not UTF-8, and a file
 * that mixes the two (UTF-8 characters on one line, a byte that is not UTF-8 on
 * another), which no single conversion reads right. */
#ifndef KG_TEXT_H
#define KG_TEXT_H

#include <stddef.h>

#include "error.h"

/* Offset of the first byte of s[0..n) that does not start a well-formed UTF-8
 * character, or n when all of it is UTF-8. */
size_t kg_utf8_invalid_at(const char *s, size_t n);

/* The text of a file's bytes buf[0..len) as UTF-8 (rules above). *text and *text_len
 * give it: within buf when buf is UTF-8 already, else in *owned, which the caller
 * frees (NULL when nothing was converted). `name` names the file in messages. */
int kg_text_utf8(const char *buf, size_t len, const char *name, const char **text,
                 size_t *text_len, char **owned, kg_err *err);

#endif
