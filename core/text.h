/* Text as a reader sees it: UTF-8 decoding, the code points that display differently
 * from their bytes (invisible and bidirectional format characters), and a copy of
 * untrusted text that is safe to print on a terminal.
 *
 * Format characters are Unicode's general category Cf (U+00AD soft hyphen, U+200B..U+200F
 * zero-width characters and marks, U+202A..U+202E bidirectional embeddings and
 * overrides, U+2060..U+206F, U+FEFF, the tag characters U+E0000..U+E007F, ...) plus the
 * line and paragraph separators U+2028 and U+2029 (categories Zl, Zp), as Unicode 15.0
 * assigns them.
 *
 * And the encoding of text input files (CGATS, CSV): whatever reaches JSON, HTML or the
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

/* Decode one UTF-8 character at s (n bytes available). Returns its length (1..4) and
 * sets *cp, or 0 when the bytes there are not well-formed UTF-8 (invalid lead or
 * continuation byte, truncated, overlong, a surrogate, above U+10FFFF); *why then says
 * which (a static phrase). */
int kg_utf8_decode(const unsigned char *s, size_t n, unsigned *cp, const char **why);

/* 1 when cp is an invisible or bidirectional format character (Cf, Zl, Zp). */
int kg_unicode_is_format(unsigned cp);

/* The name of a format character for messages ("RIGHT-TO-LEFT OVERRIDE"), or NULL. */
const char *kg_unicode_format_name(unsigned cp);

/* Copy s into out (size bytes, always terminated) so that printing it shows every
 * byte: C0 and C1 controls and bytes that are not UTF-8 become \xNN, a backslash stays
 * a backslash, format characters become \u{XXXX}; everything else is copied. A copy cut
 * short by size ends in "...". max_in bounds how many bytes of s are read (SIZE_MAX for
 * all). Returns out. */
char *kg_text_visible(const char *s, size_t max_in, char *out, size_t size);


/* Offset of the first byte of s[0..n) that does not start a well-formed UTF-8
 * character, or n when all of it is UTF-8. */
size_t kg_utf8_invalid_at(const char *s, size_t n);

/* The text of a file's bytes buf[0..len) as UTF-8 (rules above). *text and *text_len
 * give it: within buf when buf is UTF-8 already, else in *owned, which the caller
 * frees (NULL when nothing was converted). `name` names the file in messages. */
int kg_text_utf8(const char *buf, size_t len, const char *name, const char **text,
                 size_t *text_len, char **owned, kg_err *err);

#endif
