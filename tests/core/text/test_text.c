/* Text as a reader sees it (core/text.c): UTF-8 decoding, format characters and the
 * terminal-safe copy. With --dump, prints every code point kg_unicode_is_format takes,
 * one hexadecimal number a line, for text_unicode.py to compare with Python's
 * unicodedata (an outside table). */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "kg_core.h"
#include "kg_test.h"

static const char *visible(const char *s, size_t max_in)
{
	static char out[256];
	return kg_text_visible(s, max_in, out, sizeof(out));
}

int main(int argc, char **argv)
{
	if (argc > 1 && !strcmp(argv[1], "--dump")) {
		for (unsigned cp = 0; cp <= 0x10FFFF; cp++)
			if (kg_unicode_is_format(cp))
				printf("%X\n", cp);
		return 0;
	}
	unsigned cp;
	const char *why = NULL;
	CHECK(kg_utf8_decode((const unsigned char *)"\xe2\x80\xae", 3, &cp, &why) == 3 &&
	          cp == 0x202E,
	      "U+202E decodes");
	CHECK(kg_utf8_decode((const unsigned char *)"\xe2\x80", 2, &cp, &why) == 0 &&
	          strstr(why, "truncated"),
	      "a truncated character: %s", why);
	CHECK(kg_unicode_is_format(0x202E) && kg_unicode_is_format(0x200B) &&
	          kg_unicode_is_format(0xFEFF) && kg_unicode_is_format(0x2028) &&
	          kg_unicode_is_format(0x2029) && kg_unicode_is_format(0xE0041),
	      "bidi override, zero width space, BOM, separators, tags are format characters");
	CHECK(!kg_unicode_is_format('a') && !kg_unicode_is_format(0x6F06) &&
	          !kg_unicode_is_format(0x2013) && !kg_unicode_is_format(0x1F375),
	      "letters, CJK, dashes and emoji are not");

	/* the terminal-safe copy */
	CHECK(!strcmp(visible("plain \xe6\xbc\x86", SIZE_MAX), "plain \xe6\xbc\x86"),
	      "text is kept: %s", visible("plain \xe6\xbc\x86", SIZE_MAX));
	CHECK(!strcmp(visible("a\x1b[31mred", SIZE_MAX), "a\\x1B[31mred"),
	      "an escape sequence is shown, not sent: %s", visible("a\x1b[31mred", SIZE_MAX));
	CHECK(!strcmp(visible("1987\xe2\x80\xae" "321", SIZE_MAX), "1987\\u{202E}321"),
	      "a bidi override is shown: %s", visible("1987\xe2\x80\xae" "321", SIZE_MAX));
	CHECK(!strcmp(visible("x\xc2\x9by\xffz", SIZE_MAX), "x\\xC2\\x9By\\xFFz"),
	      "a C1 control and a byte that is not UTF-8: %s",
	      visible("x\xc2\x9by\xffz", SIZE_MAX));
	CHECK(!strcmp(visible("abcdef", 3), "abc..."), "cut at max_in: %s", visible("abcdef", 3));
	char small[8];
	kg_text_visible("\x1b\x1b\x1b\x1b", SIZE_MAX, small, sizeof(small));
	CHECK(strlen(small) < sizeof(small) && strstr(small, "..."), "cut at size: %s", small);
	return kg_test_failures ? 1 : 0;
}
