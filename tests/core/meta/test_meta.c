/* Object records (core/meta.c): keys, UTF-8 values and their limits, KEY=VALUE
 * arguments, stored objects, and the report's key order. */
#include <string.h>

#include "kg_core.h"
#include "kg_test.h"

static int value_ok(const char *v) { return kg_meta_value_problem(v) == NULL; }

int main(void)
{
	/* keys */
	CHECK(kg_meta_key_ok("accession") && kg_meta_key_ok("x.y_z-9"), "plain keys");
	CHECK(!kg_meta_key_ok("") && !kg_meta_key_ok("a b") && !kg_meta_key_ok("a=b") &&
	          !kg_meta_key_ok("t\xc3\xa9"),
	      "empty, space, '=', non-ASCII keys refused");
	char key[KG_META_KEY_MAX + 2];
	memset(key, 'k', sizeof(key));
	key[KG_META_KEY_MAX] = 0;
	CHECK(kg_meta_key_ok(key), "a key of %d", KG_META_KEY_MAX);
	key[KG_META_KEY_MAX] = 'k';
	key[KG_META_KEY_MAX + 1] = 0;
	CHECK(!kg_meta_key_ok(key), "a key of %d refused", KG_META_KEY_MAX + 1);

	/* values: UTF-8, no controls, length */
	CHECK(value_ok("") && value_ok("Tea bowl, <b> & \"lid\""), "ASCII");
	CHECK(value_ok("\xe6\xbc\x86 \xe2\x80\x93 \xf0\x9f\x8d\xb5"), "3- and 4-byte UTF-8");
	CHECK(!value_ok("a\tb") && !value_ok("a\nb") && !value_ok("a\x7f") &&
	          !value_ok("a\xc2\x85"),
	      "C0, DEL and C1 controls refused");
	CHECK(!value_ok("\xc0\xaf") && !value_ok("\xe0\x80\xaf"), "overlong forms refused");
	CHECK(!value_ok("\xed\xa0\x80"), "a surrogate refused");
	CHECK(!value_ok("\xf4\x90\x80\x80"), "above U+10FFFF refused");
	CHECK(!value_ok("\xe6\xbc") && !value_ok("\xff") && !value_ok("\xe6x\x86"),
	      "truncated, invalid and broken sequences refused");
	/* format characters: a record must display as what it holds */
	const char *hidden[] = {"1987.12\xe2\x80\xae" "3", "a\xe2\x80\x8b" "b", "\xef\xbb\xbf" "x",
	                        "a\xe2\x80\xa8" "b", "a\xe2\x80\xa9" "b", "a\xe2\x81\xa6" "b",
	                        "a\xc2\xad" "b", "a\xf3\xa0\x81\x81" "b"};
	for (size_t i = 0; i < sizeof(hidden) / sizeof(hidden[0]); i++)
		CHECK(!value_ok(hidden[i]), "format character %zu refused", i);
	CHECK(value_ok("\xd8\xb3\xd9\x8a\xd9\x81 \xd7\xa9\xd7\x9c\xd7\x95\xd7\x9d"),
	      "right-to-left scripts themselves are text");
	static char big[KG_META_VALUE_MAX + 2];
	memset(big, 'a', KG_META_VALUE_MAX);
	CHECK(value_ok(big), "%d bytes", KG_META_VALUE_MAX);
	big[KG_META_VALUE_MAX] = 'a';
	CHECK(!value_ok(big), "%d bytes refused", KG_META_VALUE_MAX + 1);

	/* arguments */
	json_t *m = json_object();
	kg_err err = {{0}};
	CHECK(kg_meta_parse_arg(m, "--meta", "title=a=b", &err) == 0, "%s", err.msg);
	CHECK(!strcmp(json_string_value(json_object_get(m, "title")), "a=b"),
	      "the value is everything after the first '='");
	CHECK(kg_meta_parse_arg(m, "--meta", "notes=", &err) == 0, "an empty value: %s", err.msg);
	CHECK(kg_meta_parse_arg(m, "--meta", "title=c", &err) == KG_EINVAL &&
	          strstr(err.msg, "--meta 'title=c'") && strstr(err.msg, "twice"),
	      "a key given twice: %s", err.msg);
	CHECK(kg_meta_parse_arg(m, "--meta", "novalue", &err) == KG_EINVAL &&
	          strstr(err.msg, "KEY=VALUE"),
	      "no '=': %s", err.msg);
	CHECK(kg_meta_parse_arg(m, "--meta", "accession=1987\xe2\x80\xae" "321", &err) ==
	              KG_EINVAL &&
	          strstr(err.msg, "'accession=1987\\u{202E}321'") &&
	          strstr(err.msg, "U+202E RIGHT-TO-LEFT OVERRIDE at byte 5"),
	      "a bidi override refused, shown escaped and named: %s", err.msg);
	CHECK(kg_meta_parse_arg(m, "--meta", "title=\x1b]0;pwned\x07\x1b[2J", &err) == KG_EINVAL &&
	          !strchr(err.msg, '\x1b') && !strchr(err.msg, '\x07') &&
	          strstr(err.msg, "\\x1B]0;pwned\\x07"),
	      "terminal control sequences are echoed escaped: %s", err.msg);
	CHECK(json_object_size(m) == 2, "refused arguments add nothing (%zu keys)",
	      json_object_size(m));

	/* stored objects */
	CHECK(kg_meta_validate("f.json", "meta", m, &err) == 0, "%s", err.msg);
	json_t *bad = json_pack("{s:i}", "title", 3);
	CHECK(kg_meta_validate("f.json", "captures[2].meta", bad, &err) == KG_EINVAL &&
	          strstr(err.msg, "f.json: captures[2].meta.title: expected a string"),
	      "%s", err.msg);
	json_decref(bad);
	bad = json_string("x");
	CHECK(kg_meta_validate("f.json", "meta", bad, &err) == KG_EINVAL, "not an object");
	json_decref(bad);

	/* order: known keys in their order, then the others in byte order */
	json_t *o = json_pack("{s:s, s:s, s:s, s:s, s:s}", "zeta", "1", "notes", "2", "alpha",
	                      "3", "accession", "4", "title", "5");
	const char *keys[8];
	int n = kg_meta_ordered_keys(o, keys, 8);
	const char *want[] = {"accession", "title", "notes", "alpha", "zeta"};
	CHECK(n == 5, "%d keys", n);
	for (int i = 0; i < n && i < 5; i++)
		CHECK(!strcmp(keys[i], want[i]), "key %d: %s, expected %s", i, keys[i], want[i]);
	json_decref(o);
	json_decref(m);
	return kg_test_failures ? 1 : 0;
}
