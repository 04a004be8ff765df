/* Text as a reader sees it, and text input encodings (text.h). */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
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

/* ---- text input encodings ---------------------------------------------------------- */

size_t kg_utf8_invalid_at(const char *s, size_t n)
{
	const unsigned char *u = (const unsigned char *)s;
	for (size_t i = 0; i < n;) {
		unsigned cp;
		int len = kg_utf8_decode(u + i, n - i, &cp, NULL);
		if (len == 0)
			return i;
		i += (size_t)len;
	}
	return n;
}

/* Windows-1252's characters at 0x80..0x9F (0: undefined); 0xA0..0xFF are U+00A0..U+00FF
 * as in ISO 8859-1. */
static const uint16_t cp1252_high[32] = {
	0x20AC, 0,      0x201A, 0x0192, 0x201E, 0x2026, 0x2020, 0x2021,
	0x02C6, 0x2030, 0x0160, 0x2039, 0x0152, 0,      0x017D, 0,
	0,      0x2018, 0x2019, 0x201C, 0x201D, 0x2022, 0x2013, 0x2014,
	0x02DC, 0x2122, 0x0161, 0x203A, 0x0153, 0,      0x017E, 0x0178,
};

/* The code point of a Windows-1252 byte, 0 for the five it leaves undefined (and NUL). */
static unsigned cp1252(unsigned char c)
{
	return c >= 0x80 && c < 0xA0 ? cp1252_high[c - 0x80] : c;
}

/* 1-based line of buf[off]. */
static int line_of(const char *buf, size_t off)
{
	int line = 1;
	for (const char *p = buf; (p = memchr(p, '\n', (size_t)(buf + off - p))); p++)
		line++;
	return line;
}

/* Offset of the first character of more than one byte in a well-formed UTF-8 run of
 * buf, or len: the file holds UTF-8 text there. */
static size_t first_utf8_multibyte(const char *buf, size_t len)
{
	const unsigned char *u = (const unsigned char *)buf;
	unsigned cp;
	for (size_t i = 0; i < len; i++)
		if (u[i] >= 0x80 && kg_utf8_decode(u + i, len - i, &cp, NULL) > 1)
			return i;
	return len;
}

static int refuse_mixed(const char *buf, const char *name, size_t bad, size_t good,
                        kg_err *err)
{
	return kg_fail(err, KG_EINVAL, "%s: line %d: byte 0x%02X (offset %zu in the file) is not "
	               "UTF-8, but line %d holds UTF-8 text: expected one encoding throughout "
	               "(UTF-8, or Windows-1252/Latin-1)", name, line_of(buf, bad),
	               (unsigned char)buf[bad], bad, line_of(buf, good));
}

/* Convert a Windows-1252 buffer whose every byte is defined. */
static int from_cp1252(const char *buf, size_t len, const char *name, char **owned,
                       size_t *out_len, kg_err *err)
{
	if (len > (SIZE_MAX - 1) / 3)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory converting from Windows-1252", name);
	char *o = malloc(3 * len + 1);
	if (!o)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory converting from Windows-1252", name);
	size_t m = 0;
	for (size_t i = 0; i < len; i++) {
		unsigned cp = cp1252((unsigned char)buf[i]);
		if (cp < 0x80) {
			o[m++] = (char)cp;
		} else if (cp < 0x800) {
			o[m++] = (char)(0xC0 | cp >> 6);
			o[m++] = (char)(0x80 | (cp & 0x3F));
		} else {
			o[m++] = (char)(0xE0 | cp >> 12);
			o[m++] = (char)(0x80 | (cp >> 6 & 0x3F));
			o[m++] = (char)(0x80 | (cp & 0x3F));
		}
	}
	o[m] = '\0';
	*owned = o;
	*out_len = m;
	return 0;
}

int kg_text_utf8(const char *buf, size_t len, const char *name, const char **text,
                 size_t *text_len, char **owned, kg_err *err)
{
	kg_check_arg((buf || len == 0) && text && text_len && owned, err);
	*owned = NULL;
	if (!name)
		name = "<memory>";
	size_t bad = kg_utf8_invalid_at(buf, len);
	if (bad == len) {
		int bom = len >= 3 && memcmp(buf, "\xEF\xBB\xBF", 3) == 0;
		*text = bom ? buf + 3 : buf;
		*text_len = bom ? len - 3 : len;
		return 0;
	}
	size_t good = first_utf8_multibyte(buf, len);
	if (good < len)
		return refuse_mixed(buf, name, bad, good, err);
	for (size_t i = bad; i < len; i++)
		if ((unsigned char)buf[i] >= 0x80 && cp1252((unsigned char)buf[i]) == 0)
			return kg_fail(err, KG_EINVAL, "%s: line %d: byte 0x%02X (offset %zu in the file) "
			               "is neither UTF-8 nor Windows-1252 text: expected the file in "
			               "UTF-8, or wholly in Windows-1252 (Latin-1)", name,
			               line_of(buf, i), (unsigned char)buf[i], i);
	int r = from_cp1252(buf, len, name, owned, text_len, err);
	*text = *owned;
	return r;
}
