/* Text written into other formats (escape.h). */
#include <ctype.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "escape.h"
#include "text.h"

static const char replacement[] = "\xef\xbf\xbd"; /* U+FFFD */

int kg_utf8_char(const char *s, size_t n, uint32_t *cp)
{
	unsigned v;
	int len = kg_utf8_decode((const unsigned char *)s, n, &v, NULL);
	if (len)
		*cp = v;
	return len;
}

/* 0 when s is UTF-8 and `ok` (if any) takes each of its characters; else KG_EINVAL
 * naming the first character it refuses (why_char) or byte that is not UTF-8
 * (why_byte). */
static int check_chars(kg_err *err, const char *what, const char *s, int (*ok)(uint32_t),
                       const char *why_char, const char *why_byte)
{
	size_t n = strlen(s);
	for (size_t i = 0; i < n;) {
		uint32_t cp;
		int len = kg_utf8_char(s + i, n - i, &cp);
		if (len == 0)
			return kg_fail(err, KG_EINVAL, "%s: byte %zu (0x%02X) is not UTF-8: %s", what,
			               i + 1, (unsigned)(unsigned char)s[i], why_byte);
		if (ok && !ok(cp))
			return kg_fail(err, KG_EINVAL, "%s: U+%04lX at byte %zu: %s", what,
			               (unsigned long)cp, i + 1, why_char);
		i += (size_t)len;
	}
	return 0;
}

int kg_utf8_check(const char *what, const char *s, const char *format, kg_err *err)
{
	char why[64];
	snprintf(why, sizeof(why), "%s text is UTF-8", format);
	return check_chars(err, what, s, NULL, NULL, why);
}

static int not_control(uint32_t cp)
{
	return cp >= 0x20 && !(cp >= 0x7F && cp <= 0x9F);
}

int kg_text_check_controls(const char *what, const char *s, kg_err *err)
{
	return check_chars(err, what, s, not_control,
	                   "expected no control characters (tabs, line breaks and the like)",
	                   "expected UTF-8 text");
}

/* ---- XML ------------------------------------------------------------------------- */

static int xml_char(uint32_t cp)
{
	return cp >= 0x20 ? cp != 0xFFFE && cp != 0xFFFF : cp == '\t' || cp == '\n' || cp == '\r';
}

int kg_xml_check(const char *what, const char *s, kg_err *err)
{
	return check_chars(err, what, s, xml_char,
	                   "XML 1.0 cannot hold it (a control character, U+FFFE or U+FFFF)",
	                   "XML text is UTF-8");
}

/* s written with each character `entity` gives a replacement for replaced (a byte
 * that is not UTF-8: U+FFFD), the runs between written as they are. */
typedef const char *(*entity_fn)(const char *s, size_t i, size_t n, uint32_t cp);

static void put_escaped(FILE *fp, const char *s, entity_fn entity)
{
	if (!s)
		return;
	size_t n = strlen(s), run = 0;
	for (size_t i = 0; i < n;) {
		uint32_t cp;
		int len = kg_utf8_char(s + i, n - i, &cp);
		const char *e = len ? entity(s, i, n, cp) : replacement;
		if (e) {
			fwrite(s + run, 1, i - run, fp);
			fputs(e, fp);
		}
		i += len ? (size_t)len : 1;
		if (e)
			run = i;
	}
	fwrite(s + run, 1, n - run, fp);
}

static const char *xml_entity(const char *s, size_t i, size_t n, uint32_t cp)
{
	if (!xml_char(cp))
		return replacement;
	switch (cp) {
	case '&': return "&amp;";
	case '<': return "&lt;";
	case '>': return "&gt;";
	case '"': return "&quot;";
	case '\'': return "&apos;";
	case '\t': return "&#9;";
	case '\n': return "&#10;";
	case '\r': return "&#13;";
	case '-': return (i > 0 && s[i - 1] == '-') || i + 1 == n ? "&#45;" : NULL;
	default: return NULL;
	}
}

void kg_xml_put(FILE *fp, const char *s)
{
	put_escaped(fp, s, xml_entity);
}

/* ---- HTML ------------------------------------------------------------------------ */

static const char *html_entity(const char *s, size_t i, size_t n, uint32_t cp)
{
	(void)s, (void)i, (void)n;
	switch (cp) {
	case '&': return "&amp;";
	case '<': return "&lt;";
	case '>': return "&gt;";
	case '"': return "&quot;";
	case '\'': return "&#39;";
	case '\r': return "&#13;";
	default: return NULL;
	}
}

void kg_html_put(FILE *fp, const char *s)
{
	put_escaped(fp, s, html_entity);
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

static const char *no_entity(const char *s, size_t i, size_t n, uint32_t cp)
{
	(void)s, (void)i, (void)n, (void)cp;
	return NULL;
}

json_t *kg_json_message(const char *s)
{
	char *text = NULL;
	size_t len = 0;
	FILE *f = open_memstream(&text, &len);
	if (!f)
		return NULL;
	put_escaped(f, s, no_entity);
	json_t *j = fclose(f) == 0 ? json_stringn(text, len) : NULL;
	free(text);
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

/* ---- CSV ------------------------------------------------------------------------- */

void kg_csv_put(FILE *fp, const char *s)
{
	size_t n = strlen(s);
	if (!strpbrk(s, ",\"\r\n") && !(n && (isspace((unsigned char)s[0]) ||
	                                      isspace((unsigned char)s[n - 1])))) {
		fputs(s, fp);
		return;
	}
	fputc('"', fp);
	for (const char *p = s; *p; p++) {
		if (*p == '"')
			fputc('"', fp);
		fputc(*p, fp);
	}
	fputc('"', fp);
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

static const char *envi_json_entity(const char *s, size_t i, size_t n, uint32_t cp)
{
	static _Thread_local char buf[8];
	(void)s, (void)i, (void)n;
	switch (cp) {
	case '"': return "\\\"";
	case '\\': return "\\\\";
	case '{': return "\\u007b";
	case '}': return "\\u007d";
	case '\n': return "\\n";
	case '\r': return "\\r";
	case '\t': return "\\t";
	default:
		if (cp < 0x20 || cp == 0x7F) {
			snprintf(buf, sizeof(buf), "\\u%04x", (unsigned)cp);
			return buf;
		}
		return NULL;
	}
}

void kg_envi_put_quoted(FILE *fp, const char *s)
{
	fputc('"', fp);
	put_escaped(fp, s ? s : "", envi_json_entity);
	fputc('"', fp);
}
