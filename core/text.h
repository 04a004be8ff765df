/* Text as a reader sees it: UTF-8 decoding, the code points that display differently
 * from their bytes (invisible and bidirectional format characters), and a copy of
 * untrusted text that is safe to print on a terminal.
 *
 * Format characters are Unicode's general category Cf (U+00AD soft hyphen, U+200B..U+200F
 * zero-width characters and marks, U+202A..U+202E bidirectional embeddings and
 * overrides, U+2060..U+206F, U+FEFF, the tag characters U+E0000..U+E007F, ...) plus the
 * line and paragraph separators U+2028 and U+2029 (categories Zl, Zp), as Unicode 15.0
 * assigns them. */
#ifndef KG_TEXT_H
#define KG_TEXT_H

#include <stddef.h>

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

#endif
