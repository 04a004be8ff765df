/* Text written into other formats (core/escape.c): UTF-8 decoding; XML and HTML
 * escaping and what XML cannot hold; CSV quoting; JSON strings of messages that are
 * not UTF-8; CGATS cells and keyword values and ENVI header names written by kogei's
 * writers and read back by kogei's readers, the same or refused. The written files
 * are parsed by outside parsers in tests/formats/test_hostile_names.sh. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_core.h"
#include "kg_test.h"

/* Names that have broken writers: comment and CDATA terminators, markup, quotes, line
 * breaks, controls, non-BMP characters, bidi marks, braces, '#', reserved words. */
static const char *const hostile[] = {
	"x--><include filename=\"/etc/passwd\"/><!--",
	"a--b",
	"-",
	"ends-",
	"]]>",
	"<b>&amp;</b>",
	"\"double\" 'single'",
	"line\r\nbreak",
	"tab\there",
	"\xf0\x9f\x8d\xb5 tea \xe6\xbc\x86",        /* U+1F375, U+6F06 */
	"\xe2\x80\x8fRTL\xe2\x80\xae override",     /* U+200F, U+202E */
	"{braces}",
	"# not a comment",
	"END_DATA",
	"",
	" lead",
};
#define NHOSTILE ((int)(sizeof(hostile) / sizeof(hostile[0])))

typedef void (*put_fn)(FILE *, const char *);

/* What a put function writes, as a string (caller frees). */
static char *put_to_string(put_fn put, const char *s)
{
	char *out = NULL;
	size_t len = 0;
	FILE *f = open_memstream(&out, &len);
	put(f, s);
	fclose(f);
	return out;
}

static void check_put(put_fn put, const char *fmt, const char *in, const char *want)
{
	char *got = put_to_string(put, in);
	CHECK(strcmp(got, want) == 0, fmt, in, got, want);
	free(got);
}

static void test_utf8(void)
{
	uint32_t cp = 0;
	CHECK(kg_utf8_char("A", 1, &cp) == 1 && cp == 'A', "ASCII");
	CHECK(kg_utf8_char("\xc3\xa9", 2, &cp) == 2 && cp == 0xE9, "2 bytes: %X", cp);
	CHECK(kg_utf8_char("\xe6\xbc\x86", 3, &cp) == 3 && cp == 0x6F06, "3 bytes: %X", cp);
	CHECK(kg_utf8_char("\xf0\x9f\x8d\xb5", 4, &cp) == 4 && cp == 0x1F375, "4 bytes: %X", cp);
	CHECK(kg_utf8_char("\xf0\x9f\x8d\xb5", 3, &cp) == 0, "cut short");
	CHECK(kg_utf8_char("\xff", 1, &cp) == 0 && kg_utf8_char("\x80", 1, &cp) == 0,
	      "invalid lead bytes");
	CHECK(kg_utf8_char("\xc0\xaf", 2, &cp) == 0 && kg_utf8_char("\xe0\x80\xaf", 3, &cp) == 0,
	      "overlong forms");
	CHECK(kg_utf8_char("\xed\xa0\x80", 3, &cp) == 0, "a surrogate");
	CHECK(kg_utf8_char("\xf4\x90\x80\x80", 4, &cp) == 0, "above U+10FFFF");
	kg_err err = {{0}};
	CHECK(kg_utf8_check("f: k", "caf\xe9", "JSON", &err) == KG_EINVAL &&
	          strstr(err.msg, "f: k: byte 4 (0xE9) is not UTF-8"),
	      "%s", err.msg);
	CHECK(kg_text_check_controls("name", "a\x1b[31m", &err) == KG_EINVAL &&
	          strstr(err.msg, "name: U+001B at byte 2") && !strchr(err.msg, '\x1b'),
	      "a control character named, not echoed: %s", err.msg);
	CHECK(kg_text_check_controls("name", "a\xc2\x85", &err) == KG_EINVAL, "a C1 control");
	CHECK(kg_text_check_controls("name", hostile[0], &err) == 0 &&
	          kg_text_check_controls("name", hostile[9], &err) == 0 &&
	          kg_text_check_controls("name", hostile[10], &err) == 0,
	      "markup, non-BMP and bidi marks are no controls: %s", err.msg);
}

static void test_xml(void)
{
	const char *fmt = "XML of '%s': '%s', expected '%s'";
	check_put(kg_xml_put, fmt, hostile[0],
	          "x-&#45;&gt;&lt;include filename=&quot;/etc/passwd&quot;/&gt;&lt;!-&#45;");
	check_put(kg_xml_put, fmt, "a---b", "a-&#45;&#45;b");
	check_put(kg_xml_put, fmt, "ends-", "ends&#45;");
	check_put(kg_xml_put, fmt, "]]>", "]]&gt;");
	check_put(kg_xml_put, fmt, "'\t\r\n", "&apos;&#9;&#13;&#10;");
	check_put(kg_xml_put, fmt, hostile[9], hostile[9]);
	check_put(kg_xml_put, fmt, "a\x01" "b\xff", "a\xef\xbf\xbd" "b\xef\xbf\xbd");
	/* in a comment: no "--", no '-' before the closing "-->" */
	for (int i = 0; i < NHOSTILE; i++) {
		char *x = put_to_string(kg_xml_put, hostile[i]);
		size_t n = strlen(x);
		CHECK(!strstr(x, "--") && !(n && x[n - 1] == '-') && !strchr(x, '<'),
		      "'%s' as '%s'", hostile[i], x);
		free(x);
	}
	kg_err err = {{0}};
	for (int i = 0; i < NHOSTILE; i++)
		CHECK(kg_xml_check("n", hostile[i], &err) == 0, "'%s': %s", hostile[i], err.msg);
	CHECK(kg_xml_check("f.xml: name", "a\x0c", &err) == KG_EINVAL &&
	          strstr(err.msg, "f.xml: name: U+000C at byte 2: XML 1.0 cannot hold it"),
	      "%s", err.msg);
	CHECK(kg_xml_check("n", "\xef\xbf\xbe", &err) == KG_EINVAL, "U+FFFE");
	CHECK(kg_xml_check("n", "\xc3", &err) == KG_EINVAL && strstr(err.msg, "0xC3"), "%s",
	      err.msg);
}

static void test_html(void)
{
	const char *fmt = "HTML of '%s': '%s', expected '%s'";
	check_put(kg_html_put, fmt, "<b>&amp;</b>", "&lt;b&gt;&amp;amp;&lt;/b&gt;");
	check_put(kg_html_put, fmt, "\"a\" 'b'", "&quot;a&quot; &#39;b&#39;");
	check_put(kg_html_put, fmt, "a\r\nb--c", "a&#13;\nb--c");
	check_put(kg_html_put, fmt, hostile[10], hostile[10]);
	check_put(kg_html_put, fmt, "caf\xe9", "caf\xef\xbf\xbd");
	/* formatted text has no length limit and is never cut inside a character */
	char *got = NULL;
	size_t len = 0;
	FILE *f = open_memstream(&got, &len);
	kg_html_putf(f, "%04000d%s", 7, "\xe6\xbc\x86<");
	fclose(f);
	CHECK(len == 4000 + 3 + 4 && strcmp(got + 4000, "\xe6\xbc\x86&lt;") == 0,
	      "%zu bytes", len);
	free(got);
}

static void test_csv(void)
{
	const char *fmt = "CSV of '%s': '%s', expected '%s'";
	check_put(kg_csv_put, fmt, "gold|copper", "gold|copper");
	check_put(kg_csv_put, fmt, "\"double\" 'single'", "\"\"\"double\"\" 'single'\"");
	check_put(kg_csv_put, fmt, "a,b", "\"a,b\"");
	check_put(kg_csv_put, fmt, " lead", "\" lead\"");
	check_put(kg_csv_put, fmt, "two\nlines", "\"two\nlines\"");
	check_put(kg_csv_put, fmt, hostile[0], "\"x--><include filename=\"\"/etc/passwd\"\"/><!--\"");
}

static void test_json(void)
{
	json_t *m = kg_json_message("f\xe9: x\xe6\xbc");
	const char *v = json_string_value(m);
	CHECK(v && strcmp(v, "f\xef\xbf\xbd: x\xef\xbf\xbd\xef\xbf\xbd") == 0,
	      "a message with bytes that are not UTF-8, each as U+FFFD: %s", v ? v : "(dropped)");
	json_decref(m);
	kg_err err = {{0}};
	CHECK(kg_json_text("o.glb: asset.extras.kogei.scene", "s\xff.json", &err) == NULL &&
	          strstr(err.msg, "o.glb: asset.extras.kogei.scene: byte 2 (0xFF)"),
	      "%s", err.msg);
	json_t *ok = kg_json_text("n", hostile[0], &err);
	CHECK(ok && !strcmp(json_string_value(ok), hostile[0]), "UTF-8 taken as it is");
	json_decref(ok);
}

/* Cells and keyword values through kg_cgats_write and back through kg_cgats_read. */
static void test_cgats(const char *dir)
{
	char path[4096];
	snprintf(path, sizeof(path), "%s/names.cgats", dir);
	kg_err err = {{0}};
	kg_cgats *cg = NULL;
	kg_cgats_table *t = NULL;
	const char *fields[2] = {"SAMPLE_ID", "SAMPLE_NAME"};
	int n = 0;
	const char *kept[NHOSTILE];
	CHECK(kg_cgats_new(NULL, &cg, &err) == 0, "%s", err.msg);
	t = cg->tables[0];
	CHECK(kg_cgats_set_fields(t, fields, 2, &err) == 0, "%s", err.msg);
	for (int i = 0; i < NHOSTILE; i++) {
		int refused = kg_cgats_check("n", hostile[i], &err) != 0;
		CHECK(refused == (strpbrk(hostile[i], "\"\r\n") != NULL), "'%s': %s", hostile[i],
		      err.msg);
		if (refused)
			continue;
		const char *row[2] = {hostile[i], hostile[i]};
		CHECK(kg_cgats_add_row(t, row, &err) == 0, "%s", err.msg);
		char kw[32];
		snprintf(kw, sizeof(kw), "KOGEI_NAME_%d", n);
		CHECK(kg_cgats_set_keyword(t, kw, hostile[i], &err) == 0, "%s", err.msg);
		kept[n++] = hostile[i];
	}
	CHECK(kg_cgats_write(cg, path, &err) == 0, "%s", err.msg);
	kg_cgats_free(&cg);
	CHECK(kg_cgats_read(path, &cg, &err) == 0, "%s", err.msg);
	t = cg ? cg->tables[0] : NULL;
	CHECK(t && t->nsets == n, "%d sets read back, %d written", t ? t->nsets : -1, n);
	for (int i = 0; t && i < n && i < t->nsets; i++) {
		char kw[32];
		snprintf(kw, sizeof(kw), "KOGEI_NAME_%d", i);
		const char *v = kg_cgats_keyword(t, kw);
		CHECK(!strcmp(kg_cgats_cell(t, i, 0), kept[i]) && !strcmp(kg_cgats_cell(t, i, 1), kept[i]),
		      "cell '%s' read back as '%s'", kept[i], kg_cgats_cell(t, i, 0));
		CHECK(v && !strcmp(v, kept[i]), "keyword '%s' read back as '%s'", kept[i], v ? v : "");
	}
	kg_cgats_free(&cg);

	snprintf(path, sizeof(path), "%s/refused.cgats", dir);
	CHECK(kg_cgats_new(NULL, &cg, &err) == 0, "%s", err.msg);
	t = cg->tables[0];
	CHECK(kg_cgats_set_keyword(t, "DESCRIPTOR", "a \"b\"", &err) == KG_EINVAL &&
	          strstr(err.msg, "keyword DESCRIPTOR: value: a double quote at byte 3"),
	      "%s", err.msg);
	CHECK(kg_cgats_set_fields(t, fields, 1, &err) == 0, "%s", err.msg);
	const char *row[1] = {"two\nlines"};
	CHECK(kg_cgats_add_row(t, row, &err) == 0, "%s", err.msg);
	CHECK(kg_cgats_write(cg, path, &err) == KG_EINVAL &&
	          strstr(err.msg, "set 1: field SAMPLE_ID: a line feed") && !kg_test_file_exists(path),
	      "%s", err.msg);
	kg_cgats_free(&cg);
}

/* Class names and the description through the ENVI writer and back through its reader. */
static void test_envi(const char *dir)
{
	char path[4096];
	snprintf(path, sizeof(path), "%s/labels.hdr", dir);
	kg_err err = {{0}};
	const char *names[NHOSTILE];
	int n = 0;
	for (int i = 0; i < NHOSTILE; i++) {
		const char *s = hostile[i];
		size_t len = strlen(s);
		int expect = !strpbrk(s, "{},\r\n") && len && s[0] != ' ' && s[len - 1] != ' ';
		int ok = kg_envi_check("n", s, 1, &err) == 0;
		CHECK(ok == expect, "'%s': %s", s, ok ? "taken" : err.msg);
		if (ok)
			names[n++] = s;
	}
	float labels[4] = {0, 1, 2, 3};
	const char *desc = "kogei test: \"names\"\nsecond line -->";
	CHECK(kg_envi_write_label_map(path, 2, 2, labels, n, names, desc, &err) == 0, "%s",
	      err.msg);
	kg_envi *e = NULL;
	CHECK(kg_envi_open(path, &e, &err) == 0, "%s", err.msg);
	CHECK(e && e->meta.classes == n, "%d classes read back, %d written",
	      e ? e->meta.classes : -1, n);
	for (int i = 0; e && i < n && i < e->meta.classes; i++)
		CHECK(!strcmp(e->meta.class_names[i], names[i]), "class '%s' read back as '%s'",
		      names[i], e->meta.class_names[i]);
	CHECK(e && e->meta.description && !strcmp(e->meta.description, desc),
	      "description read back as '%s'", e && e->meta.description ? e->meta.description : "");
	kg_envi_close(&e);

	/* free text in a description: a JSON string without braces or line breaks, which
	 * the header takes and a JSON parser reads back */
	check_put(kg_envi_put_quoted, "ENVI quoted '%s': '%s', expected '%s'", "{a}\"\\\n\x01",
	          "\"\\u007ba\\u007d\\\"\\\\\\n\\u0001\"");
	for (int i = 0; i < NHOSTILE; i++) {
		char *q = put_to_string(kg_envi_put_quoted, hostile[i]);
		json_error_t je;
		json_t *back = json_loads(q, JSON_DECODE_ANY, &je);
		CHECK(kg_envi_check("d", q, 0, &err) == 0 && !strpbrk(q, "{}\r\n"), "'%s' as '%s': %s",
		      hostile[i], q, err.msg);
		CHECK(json_is_string(back) && !strcmp(json_string_value(back), hostile[i]),
		      "'%s' quoted '%s' read back as '%s'", hostile[i], q,
		      json_is_string(back) ? json_string_value(back) : je.text);
		json_decref(back);
		free(q);
	}

	const char *bad[2] = {"gold", "copper}"};
	CHECK(kg_envi_write_label_map(path, 2, 2, labels, 2, bad, NULL, &err) == KG_EINVAL &&
	          strstr(err.msg, "class name 2 'copper}': byte 7 (0x7D)"),
	      "%s", err.msg);
	bad[1] = "gold ";
	CHECK(kg_envi_write_label_map(path, 2, 2, labels, 2, bad, NULL, &err) == KG_EINVAL &&
	          strstr(err.msg, "trim"),
	      "%s", err.msg);
	CHECK(kg_envi_write_label_map(path, 2, 2, labels, 1, bad, " lead", &err) == KG_EINVAL &&
	          strstr(err.msg, "description"),
	      "%s", err.msg);
}

int main(void)
{
	const char *dir = kg_test_scratch_dir("escape");
	test_utf8();
	test_xml();
	test_html();
	test_csv();
	test_json();
	test_cgats(dir);
	test_envi(dir);
	kg_test_scratch_remove();
	return kg_test_done("escape");
}
