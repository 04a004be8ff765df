/* Text input encodings (text.h). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "text.h"

/* Length of the well-formed UTF-8 character at s (n bytes left), 0 if there is none. */
static size_t utf8_char_len(const unsigned char *s, size_t n)
{
	unsigned c = s[0], cp, min;
	size_t len;
	if (c < 0x80)
		return 1;
	if ((c & 0xE0) == 0xC0) {
		len = 2;
		cp = c & 0x1F;
		min = 0x80;
	} else if ((c & 0xF0) == 0xE0) {
		len = 3;
		cp = c & 0x0F;
		min = 0x800;
	} else if ((c & 0xF8) == 0xF0) {
		len = 4;
		cp = c & 0x07;
		min = 0x10000;
	} else {
		return 0;
	}
	if (len > n)
		return 0;
	for (size_t k = 1; k < len; k++) {
		if ((s[k] & 0xC0) != 0x80)
			return 0;
		cp = cp << 6 | (s[k] & 0x3F);
	}
	if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))
		return 0;
	return len;
}

size_t kg_utf8_invalid_at(const char *s, size_t n)
{
	const unsigned char *u = (const unsigned char *)s;
	for (size_t i = 0; i < n;) {
		size_t len = utf8_char_len(u + i, n - i);
		if (len == 0)
			return i;
		i += len;
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
	for (size_t i = 0; i < len; i++)
		if (u[i] >= 0x80 && utf8_char_len(u + i, len - i) > 1)
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
