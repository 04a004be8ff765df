/* Text as a reader sees it (text.h). */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "text.h"

int kg_utf8_decode(const unsigned char *s, size_t n, unsigned *cp, const char **why)
{
	static const unsigned minimum[5] = {0, 0, 0x80, 0x800, 0x10000};
	const char *dummy;
	if (!why)
		why = &dummy;
	if (n == 0) {
		*why = "expected UTF-8 text (a truncated character)";
		return 0;
	}
	unsigned c = s[0], v, len;
	if (c < 0x80) {
		*cp = c;
		return 1;
	} else if ((c & 0xE0) == 0xC0) {
		v = c & 0x1F;
		len = 2;
	} else if ((c & 0xF0) == 0xE0) {
		v = c & 0x0F;
		len = 3;
	} else if ((c & 0xF8) == 0xF0) {
		v = c & 0x07;
		len = 4;
	} else {
		*why = "expected UTF-8 text (an invalid byte)";
		return 0;
	}
	if (len > n) {
		*why = "expected UTF-8 text (a truncated character)";
		return 0;
	}
	for (unsigned k = 1; k < len; k++) {
		if ((s[k] & 0xC0) != 0x80) {
			*why = "expected UTF-8 text (an invalid continuation byte)";
			return 0;
		}
		v = v << 6 | (s[k] & 0x3F);
	}
	if (v < minimum[len] || v > 0x10FFFF || (v >= 0xD800 && v <= 0xDFFF)) {
		*why = "expected UTF-8 text (an overlong form or a code point out of range)";
		return 0;
	}
	*cp = v;
	return (int)len;
}

/* Unicode 15.0 general categories Cf, Zl and Zp, as ranges (tests/core/text checks
 * them against Python's unicodedata), each with a name for messages. */
static const struct {
	unsigned lo, hi;
	const char *name;
} format_ranges[] = {
	{0x00AD, 0x00AD, "SOFT HYPHEN"},
	{0x0600, 0x0605, "ARABIC NUMBER SIGN"},
	{0x061C, 0x061C, "ARABIC LETTER MARK"},
	{0x06DD, 0x06DD, "ARABIC END OF AYAH"},
	{0x070F, 0x070F, "SYRIAC ABBREVIATION MARK"},
	{0x0890, 0x0891, "ARABIC POUND MARK ABOVE"},
	{0x08E2, 0x08E2, "ARABIC DISPUTED END OF AYAH"},
	{0x180E, 0x180E, "MONGOLIAN VOWEL SEPARATOR"},
	{0x200B, 0x200B, "ZERO WIDTH SPACE"},
	{0x200C, 0x200C, "ZERO WIDTH NON-JOINER"},
	{0x200D, 0x200D, "ZERO WIDTH JOINER"},
	{0x200E, 0x200E, "LEFT-TO-RIGHT MARK"},
	{0x200F, 0x200F, "RIGHT-TO-LEFT MARK"},
	{0x2028, 0x2028, "LINE SEPARATOR"},
	{0x2029, 0x2029, "PARAGRAPH SEPARATOR"},
	{0x202A, 0x202A, "LEFT-TO-RIGHT EMBEDDING"},
	{0x202B, 0x202B, "RIGHT-TO-LEFT EMBEDDING"},
	{0x202C, 0x202C, "POP DIRECTIONAL FORMATTING"},
	{0x202D, 0x202D, "LEFT-TO-RIGHT OVERRIDE"},
	{0x202E, 0x202E, "RIGHT-TO-LEFT OVERRIDE"},
	{0x2060, 0x2060, "WORD JOINER"},
	{0x2061, 0x2064, "INVISIBLE OPERATOR"},
	{0x2066, 0x2066, "LEFT-TO-RIGHT ISOLATE"},
	{0x2067, 0x2067, "RIGHT-TO-LEFT ISOLATE"},
	{0x2068, 0x2068, "FIRST STRONG ISOLATE"},
	{0x2069, 0x2069, "POP DIRECTIONAL ISOLATE"},
	{0x206A, 0x206F, "DEPRECATED FORMAT CHARACTER"},
	{0xFEFF, 0xFEFF, "ZERO WIDTH NO-BREAK SPACE (BYTE ORDER MARK)"},
	{0xFFF9, 0xFFFB, "INTERLINEAR ANNOTATION CHARACTER"},
	{0x110BD, 0x110BD, "KAITHI NUMBER SIGN"},
	{0x110CD, 0x110CD, "KAITHI NUMBER SIGN ABOVE"},
	{0x13430, 0x1343F, "EGYPTIAN HIEROGLYPH FORMAT CONTROL"},
	{0x1BCA0, 0x1BCA3, "SHORTHAND FORMAT CONTROL"},
	{0x1D173, 0x1D17A, "MUSICAL SYMBOL FORMAT CONTROL"},
	{0xE0001, 0xE0001, "LANGUAGE TAG"},
	{0xE0020, 0xE007F, "TAG CHARACTER"},
};

const char *kg_unicode_format_name(unsigned cp)
{
	size_t lo = 0, hi = sizeof(format_ranges) / sizeof(format_ranges[0]);
	while (lo < hi) {
		size_t mid = (lo + hi) / 2;
		if (cp < format_ranges[mid].lo)
			hi = mid;
		else if (cp > format_ranges[mid].hi)
			lo = mid + 1;
		else
			return format_ranges[mid].name;
	}
	return NULL;
}

int kg_unicode_is_format(unsigned cp)
{
	return kg_unicode_format_name(cp) != NULL;
}

/* Append piece (len bytes) to out at *at, keeping room for "..." and the NUL. */
static int put(char *out, size_t size, size_t *at, const char *piece, size_t len)
{
	if (*at + len + 4 > size)
		return 0;
	memcpy(out + *at, piece, len);
	*at += len;
	return 1;
}

char *kg_text_visible(const char *s, size_t max_in, char *out, size_t size)
{
	if (!out || size == 0)
		return out;
	out[0] = 0;
	if (!s)
		return out;
	size_t n = strnlen(s, max_in), at = 0, i = 0;
	const unsigned char *u = (const unsigned char *)s;
	int cut = 0;
	while (i < n && !cut) {
		char esc[16];
		unsigned cp;
		int len = kg_utf8_decode(u + i, n - i, &cp, NULL);
		if (len == 0 || cp < 0x20 || (cp >= 0x7F && cp <= 0x9F)) {
			/* a control character: each of its bytes shown as \xNN */
			int nb = len ? len : 1;
			for (int k = 0; k < nb && !cut; k++) {
				snprintf(esc, sizeof(esc), "\\x%02X", u[i + (size_t)k]);
				cut = !put(out, size, &at, esc, 4);
			}
			i += (size_t)nb;
		} else if (kg_unicode_is_format(cp)) {
			int m = snprintf(esc, sizeof(esc), "\\u{%04X}", cp);
			cut = !put(out, size, &at, esc, (size_t)m);
			i += (size_t)len;
		} else {
			cut = !put(out, size, &at, s + i, (size_t)len);
			i += (size_t)len;
		}
	}
	int longer = max_in != SIZE_MAX && strnlen(s, max_in + 1) > max_in;
	if ((cut || longer) && at + 4 <= size) {
		memcpy(out + at, "...", 3);
		at += 3;
	}
	out[at] = 0;
	return out;
}
