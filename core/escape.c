/* Text written into other formats (escape.h). */
#include <ctype.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "escape.h"

static const char replacement[] = "\xef\xbf\xbd"; /* U+FFFD */

int kg_utf8_char(const char *s, size_t n, uint32_t *cp)
{
	static const uint32_t minimum[5] = {0, 0, 0x80, 0x800, 0x10000};
	const unsigned char *u = (const unsigned char *)s;
	if (n == 0)
		return 0;
	unsigned c = u[0];
	int len = c < 0x80 ? 1 : (c & 0xE0) == 0xC0 ? 2 : (c & 0xF0) == 0xE0 ? 3
	          : (c & 0xF8) == 0xF0 ? 4 : 0;
	if (len == 0 || (size_t)len > n)
		return 0;
	uint32_t v = len == 1 ? c : c & (0x7Fu >> len);
	for (int k = 1; k < len; k++) {
		if ((u[k] & 0xC0) != 0x80)
			return 0;
		v = v << 6 | (u[k] & 0x3F);
	}
	if (v < minimum[len] || v > 0x10FFFF || (v >= 0xD800 && v <= 0xDFFF))
		return 0;
	*cp = v;
	return len;
}

/* The first character of s (length n) that `ok` refuses, or a byte that is not UTF-8:
 * its offset, with *cp the character (*len 0 for a byte). -1 when there is none. */
static long find_bad(const char *s, size_t n, int (*ok)(uint32_t, void *), void *arg,
                     uint32_t *cp, int *len)
{
	for (size_t i = 0; i < n;) {
		int l = kg_utf8_char(s + i, n - i, cp);
		if (l == 0 || (ok && !ok(*cp, arg))) {
			*len = l;
			if (l == 0)
				*cp = (unsigned char)s[i];
			return (long)i;
		}
		i += (size_t)l;
	}
	return -1;
}

/* The message for a refused character or byte at `at`. */
static int refuse(kg_err *err, const char *what, long at, uint32_t cp, int len,
                  const char *why)
{
	if (len == 0)
		return kg_fail(err, KG_EINVAL, "%s: byte %ld (0x%02X) is not UTF-8: %s", what, at + 1,
		               (unsigned)cp, why);
	return kg_fail(err, KG_EINVAL, "%s: U+%04lX at byte %ld: %s", what, (unsigned long)cp,
	               at + 1, why);
}

int kg_utf8_check(const char *what, const char *s, const char *format, kg_err *err)
{
	uint32_t cp;
	int len;
	long at = find_bad(s, strlen(s), NULL, NULL, &cp, &len);
	if (at < 0)
		return 0;
	char why[64];
	snprintf(why, sizeof(why), "%s text is UTF-8", format);
	return refuse(err, what, at, cp, len, why);
}

static int not_control(uint32_t cp, void *unused)
{
	(void)unused;
	return cp >= 0x20 && !(cp >= 0x7F && cp <= 0x9F);
}

int kg_text_check_controls(const char *what, const char *s, kg_err *err)
{
	uint32_t cp;
	int len;
	long at = find_bad(s, strlen(s), not_control, NULL, &cp, &len);
	if (at < 0)
		return 0;
	return refuse(err, what, at, cp, len,
	              len ? "expected no control characters (tabs, line breaks and the like)"
	                  : "expected UTF-8 text");
}

/* ---- XML ------------------------------------------------------------------------- */

static int xml_char(uint32_t cp, void *unused)
{
	(void)unused;
	return cp >= 0x20 ? cp != 0xFFFE && cp != 0xFFFF : cp == '\t' || cp == '\n' || cp == '\r';
}

int kg_xml_check(const char *what, const char *s, kg_err *err)
{
	uint32_t cp;
	int len;
	long at = find_bad(s, strlen(s), xml_char, NULL, &cp, &len);
	if (at < 0)
		return 0;
	return refuse(err, what, at, cp, len,
	              len ? "XML 1.0 cannot hold it (a control character, U+FFFE or U+FFFF)"
	                  : "XML text is UTF-8");
}

void kg_xml_put(FILE *fp, const char *s)
{
	size_t n = strlen(s);
	for (size_t i = 0; i < n;) {
		uint32_t cp;
		int len = kg_utf8_char(s + i, n - i, &cp);
		if (len == 0 || !xml_char(cp, NULL)) {
			fputs(replacement, fp);
			i += len ? (size_t)len : 1;
			continue;
		}
		switch (cp) {
		case '&': fputs("&amp;", fp); break;
		case '<': fputs("&lt;", fp); break;
		case '>': fputs("&gt;", fp); break;
		case '"': fputs("&quot;", fp); break;
		case '\'': fputs("&apos;", fp); break;
		case '\t': fputs("&#9;", fp); break;
		case '\n': fputs("&#10;", fp); break;
		case '\r': fputs("&#13;", fp); break;
		case '-':
			fputs(i > 0 && s[i - 1] == '-' ? "&#45;" : i + 1 == n ? "&#45;" : "-", fp);
			break;
		default: fwrite(s + i, 1, (size_t)len, fp);
		}
		i += (size_t)len;
	}
}

/* ---- HTML ------------------------------------------------------------------------ */

void kg_html_put(FILE *fp, const char *s)
{
	size_t n = s ? strlen(s) : 0;
	for (size_t i = 0; i < n;) {
		uint32_t cp;
		int len = kg_utf8_char(s + i, n - i, &cp);
		if (len == 0) {
			fputs(replacement, fp);
			i++;
			continue;
		}
		switch (cp) {
		case '&': fputs("&amp;", fp); break;
		case '<': fputs("&lt;", fp); break;
		case '>': fputs("&gt;", fp); break;
		case '"': fputs("&quot;", fp); break;
		case '\'': fputs("&#39;", fp); break;
		case '\r': fputs("&#13;", fp); break;
		default: fwrite(s + i, 1, (size_t)len, fp);
		}
		i += (size_t)len;
	}
}

void kg_html_putf(FILE *fp, const char *fmt, ...)
{
	char *text = NULL;
	va_list ap;
	va_start(ap, fmt);
	int n = vasprintf(&text, fmt, ap);
	va_end(ap);
	if (n >= 0)
		kg_html_put(fp, text);
	else
		fputs(replacement, fp); /* out of memory: the gap is shown */
	free(text);
}

/* ---- JSON ------------------------------------------------------------------------ */

json_t *kg_json_text(const char *what, const char *s, kg_err *err)
{
	int ret = kg_utf8_check(what, s, "JSON", err);
	if (ret)
		return NULL;
	json_t *j = json_string(s);
	if (!j)
		kg_fail(err, KG_ENOMEM, "%s: out of memory", what);
	return j;
}

json_t *kg_json_message(const char *s)
{
	size_t n = strlen(s);
	char *fixed = malloc(3 * n + 1);
	if (!fixed)
		return NULL;
	size_t o = 0;
	for (size_t i = 0; i < n;) {
		uint32_t cp;
		int len = kg_utf8_char(s + i, n - i, &cp);
		const char *from = len ? s + i : replacement;
		size_t k = len ? (size_t)len : 3;
		memcpy(fixed + o, from, k);
		o += k;
		i += len ? (size_t)len : 1;
	}
	json_t *j = json_stringn(fixed, o);
	free(fixed);
	return j;
}

/* ---- CGATS ----------------------------------------------------------------------- */

int kg_cgats_reserved(const char *s)
{
	static const char *const words[] = {"BEGIN_DATA_FORMAT", "END_DATA_FORMAT", "BEGIN_DATA",
	                                    "END_DATA", "NUMBER_OF_FIELDS", "NUMBER_OF_SETS",
	                                    "KEYWORD"};
	for (size_t i = 0; i < sizeof(words) / sizeof(words[0]); i++)
		if (strcmp(s, words[i]) == 0)
			return 1;
	return 0;
}

int kg_cgats_check(const char *what, const char *s, kg_err *err)
{
	const char *bad = strpbrk(s, "\"\r\n");
	if (!bad)
		return 0;
	return kg_fail(err, KG_EINVAL, "%s: %s at byte %ld: CGATS cannot hold it (text stands "
	               "between double quotes, with no escape inside them)", what,
	               *bad == '"' ? "a double quote" : *bad == '\n' ? "a line feed"
	                                                             : "a carriage return",
	               (long)(bad - s) + 1);
}

void kg_cgats_put(FILE *fp, const char *s, int quoted)
{
	int plain = !quoted && *s && !kg_cgats_reserved(s) && !strchr(s, '#');
	for (const char *p = s; plain && *p; p++)
		plain = !isspace((unsigned char)*p);
	fprintf(fp, plain ? "%s" : "\"%s\"", s);
}

/* ---- ENVI ------------------------------------------------------------------------ */

static const char *envi_cut(char c)
{
	switch (c) {
	case ',': return "a comma separates the elements of a list";
	case '\n': return "a line break ends a list element";
	case '\r': return "readers take a carriage return for a line break";
	default: return "a brace ends the value";
	}
}

int kg_envi_check(const char *what, const char *s, int list, kg_err *err)
{
	const char *why = NULL;
	size_t n = strlen(s), at = strcspn(s, list ? "{},\r\n" : "{}\r");
	if (at < n)
		why = envi_cut(s[at]);
	else if (n && isspace((unsigned char)s[0]))
		at = 0, why = "readers trim white space at the start";
	else if (n && isspace((unsigned char)s[n - 1]))
		at = n - 1, why = "readers trim white space at the end";
	else if (list && n == 0)
		return kg_fail(err, KG_EINVAL, "%s: empty: ENVI header: expected a name (readers "
		               "drop an empty element at the end of a list)", what);
	if (!why)
		return 0;
	return kg_fail(err, KG_EINVAL, "%s: byte %zu (0x%02X): ENVI header: %s", what, at + 1,
	               (unsigned)(unsigned char)s[at], why);
}
