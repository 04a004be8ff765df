/* The encoding of text input (core/text.h): UTF-8 taken as it is, Windows-1252
 * (Latin-1) converted, anything else refused naming the line, the offset and the byte;
 * and what the CGATS and CSV readers keep is UTF-8 whatever the file held. */
#include <string.h>

#include "kg_core.h"
#include "kg_test.h"

/* The UTF-8 encoding of code point cp (below U+10000) in out; its length. */
static size_t utf8_of(unsigned cp, char out[4])
{
	if (cp < 0x80) {
		out[0] = (char)cp;
		return 1;
	}
	if (cp < 0x800) {
		out[0] = (char)(0xC0 | cp >> 6);
		out[1] = (char)(0x80 | (cp & 0x3F));
		return 2;
	}
	out[0] = (char)(0xE0 | cp >> 12);
	out[1] = (char)(0x80 | (cp >> 6 & 0x3F));
	out[2] = (char)(0x80 | (cp & 0x3F));
	return 3;
}

static void test_utf8_validation(void)
{
	static const struct {
		const char *s;
		size_t bad; /* offset of the first invalid byte, or strlen(s) */
		const char *what;
	} cases[] = {
		{ "plain ASCII", 11, "ASCII" },
		{ "Caf\xC3\xA9 \xE2\x82\xAC \xF0\x9D\x84\x9E", 14, "2, 3 and 4-byte characters" },
		{ "a\x80", 1, "a lone continuation byte" },
		{ "a\xC0\xAF", 1, "an overlong '/'" },
		{ "a\xE0\x80\x80", 1, "an overlong NUL in 3 bytes" },
		{ "a\xED\xA0\x80", 1, "a surrogate" },
		{ "a\xF4\x90\x80\x80", 1, "above U+10FFFF" },
		{ "a\xF5\x80\x80\x80", 1, "a byte no UTF-8 uses" },
		{ "ab\xE2\x82", 2, "a character cut short at the end" },
		{ "Caf\xE9 25", 3, "Latin-1" },
	};
	for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
		size_t got = kg_utf8_invalid_at(cases[i].s, strlen(cases[i].s));
		CHECK(got == cases[i].bad, "%s: first invalid byte at %zu, expected %zu",
		      cases[i].what, got, cases[i].bad);
	}
}

/* Every byte 0x80..0xFF alone after "x": its Windows-1252 character, or refused. */
static void test_windows_1252(void)
{
	/* 0x80..0x9F as Windows-1252 defines them (0 where it does not). */
	static const unsigned high[32] = {
		0x20AC, 0, 0x201A, 0x0192, 0x201E, 0x2026, 0x2020, 0x2021, 0x02C6, 0x2030, 0x0160,
		0x2039, 0x0152, 0, 0x017D, 0, 0, 0x2018, 0x2019, 0x201C, 0x201D, 0x2022, 0x2013,
		0x2014, 0x02DC, 0x2122, 0x0161, 0x203A, 0x0153, 0, 0x017E, 0x0178,
	};
	int converted = 0, refused = 0;
	for (unsigned b = 0x80; b <= 0xFF; b++) {
		char in[8] = { 'x', '\n', 'y', (char)b, 'z' };
		const char *text = NULL;
		size_t len = 0;
		char *owned = NULL;
		kg_err err = { { 0 } };
		int r = kg_text_utf8(in, 5, "t.txt", &text, &len, &owned, &err);
		unsigned cp = b < 0xA0 ? high[b - 0x80] : b;
		if (cp == 0) {
			char want[64];
			snprintf(want, sizeof(want), "t.txt: line 2: byte 0x%02X (offset 3 in the file)", b);
			CHECK(r == KG_EINVAL && !owned && strstr(err.msg, want) &&
			          strstr(err.msg, "neither UTF-8 nor Windows-1252"),
			      "byte 0x%02X: expected a refusal with line and offset, got %d: %s", b, r,
			      err.msg);
			refused += r == KG_EINVAL;
			continue;
		}
		char want[16] = "x\ny";
		size_t n = 3 + utf8_of(cp, want + 3);
		want[n++] = 'z';
		CHECK(r == 0 && owned && text == owned && len == n && !memcmp(text, want, n),
		      "byte 0x%02X: expected U+%04X in UTF-8, got %d (%s)", b, cp, r, err.msg);
		CHECK(!owned || kg_utf8_invalid_at(owned, len) == len, "byte 0x%02X: UTF-8 out", b);
		converted += r == 0;
		free(owned);
	}
	CHECK(converted == 123 && refused == 5, "123 converted, 5 refused: %d, %d", converted,
	      refused);
}

static void test_utf8_kept(void)
{
	const char *in = "\xEF\xBB\xBF" "CGATS.17\nORIGINATOR \"Caf\xC3\xA9\"\n";
	const char *text = NULL;
	size_t len = 0;
	char *owned = (char *)1;
	kg_err err = { { 0 } };
	CHECK(kg_text_utf8(in, strlen(in), "u.txt", &text, &len, &owned, &err) == 0 &&
	          owned == NULL && text == in + 3 && len == strlen(in) - 3,
	      "UTF-8 used in place, the byte-order mark skipped: %s", err.msg);
	/* UTF-8 on line 2, a Latin-1 byte on line 3: refused, naming both. */
	const char *mixed = "CGATS.17\nORIGINATOR \"Caf\xC3\xA9\"\nDESCRIPTOR \"Caf\xE9\"\n";
	CHECK(kg_text_utf8(mixed, strlen(mixed), "m.txt", &text, &len, &owned, &err) ==
	              KG_EINVAL &&
	          !owned && strstr(err.msg, "m.txt: line 3: byte 0xE9") &&
	          strstr(err.msg, "line 2 holds UTF-8") && strstr(err.msg, "one encoding"),
	      "mixed: %s", err.msg);
}

/* The CGATS and CSV readers keep UTF-8: keywords, field names, ids, comments. */
static void test_readers(void)
{
	const char *cgats = "CGATS.17\nORIGINATOR \"Caf\xE9 25\xB0" "C\"\n"
	                    "# f\xFCr die Werkstatt\nKEYWORD \"NOTE\"\nNOTE \x93quoted\x94\n"
	                    "BEGIN_DATA_FORMAT\nSAMPLE_ID SAMPLE_NAME RGB_R RGB_G RGB_B\n"
	                    "END_DATA_FORMAT\nBEGIN_DATA\nA1 \"Gr\xFCn \x96 hell\" 0.1 0.2 0.3\n"
	                    "END_DATA\n";
	kg_err err = { { 0 } };
	kg_cgats *cg = NULL;
	CHECK(kg_cgats_parse(cgats, strlen(cgats), "l1.cgats", &cg, &err) == 0, "%s", err.msg);
	if (cg) {
		const kg_cgats_table *t = cg->tables[0];
		const char *o = kg_cgats_keyword(t, "ORIGINATOR"), *n = kg_cgats_keyword(t, "NOTE");
		CHECK(o && !strcmp(o, "Caf\xC3\xA9 25\xC2\xB0" "C"), "ORIGINATOR: %s", o ? o : "-");
		CHECK(n && !strcmp(n, "\xE2\x80\x9Cquoted\xE2\x80\x9D"), "NOTE: %s", n ? n : "-");
		const char *c = kg_cgats_cell(t, 0, kg_cgats_field(t, "SAMPLE_NAME"));
		CHECK(c && !strcmp(c, "Gr\xC3\xBCn \xE2\x80\x93 hell"), "SAMPLE_NAME: %s", c ? c : "-");
	}
	kg_cgats_free(&cg);
	const char *bad = "CGATS.17\nORIGINATOR \"x\"\nDESCRIPTOR \"\xE9\x9D\"\n";
	CHECK(kg_cgats_parse(bad, strlen(bad), "bad.cgats", &cg, &err) == KG_EINVAL && !cg &&
	          strstr(err.msg, "bad.cgats: line 3: byte 0x9D (offset 37 in the file)"),
	      "undefined byte: %s", err.msg);

	const char *csv = "patch,name,400,700\nP1,Gr\xFCn,0.1,0.2\n";
	kg_csv *t = NULL;
	CHECK(kg_csv_parse(csv, strlen(csv), "l1.csv", &t, &err) == 0, "%s", err.msg);
	const char *name = t ? kg_csv_cell(t, 0, kg_csv_column(t, "name")) : NULL;
	CHECK(name && !strcmp(name, "Gr\xC3\xBCn"), "CSV cell: %s", name ? name : "-");
	kg_csv_free(&t);
	const char *csv_bad = "patch,name\nP1,\x81\n";
	CHECK(kg_csv_parse(csv_bad, strlen(csv_bad), "bad.csv", &t, &err) == KG_EINVAL && !t &&
	          strstr(err.msg, "bad.csv: line 2: byte 0x81"),
	      "CSV undefined byte: %s", err.msg);
}

int main(void)
{
	test_utf8_validation();
	test_windows_1252();
	test_utf8_kept();
	test_readers();
	return kg_test_done("text-encoding");
}
