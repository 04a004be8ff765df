/* Object records (meta.h). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "meta.h"
#include "text.h"

const char *const kg_meta_known_keys[] = {"accession", "title", "operator", "lighting",
                                          "notes", NULL};

int kg_meta_key_ok(const char *key)
{
	size_t n = key ? strlen(key) : 0;
	if (n < 1 || n > KG_META_KEY_MAX)
		return 0;
	for (size_t i = 0; i < n; i++) {
		char c = key[i];
		if (!((c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
		      c == '_' || c == '.' || c == '-'))
			return 0;
	}
	return 1;
}

/* What is wrong with value (a static phrase), or NULL; where (size bytes, may be NULL)
 * gets the first refused character for the message, " (U+202E RIGHT-TO-LEFT OVERRIDE
 * at byte 7)" or " (byte 0xFF at byte 3)", or "". One walk serves both. */
static const char *value_check(const char *value, char *where, size_t size)
{
	if (where && size)
		where[0] = 0;
	if (!value)
		return "expected a value";
	const unsigned char *s = (const unsigned char *)value;
	size_t n = strlen(value);
	if (n > KG_META_VALUE_MAX)
		return "expected at most 4096 bytes of UTF-8";
	for (size_t i = 0; i < n;) {
		unsigned cp;
		const char *why;
		int len = kg_utf8_decode(s + i, n - i, &cp, &why);
		if (!len) {
			if (where)
				snprintf(where, size, " (byte 0x%02X at byte %zu)", s[i], i + 1);
			return why;
		}
		const char *name = kg_unicode_format_name(cp);
		int control = cp < 0x20 || (cp >= 0x7F && cp <= 0x9F);
		if (control || name) {
			if (where)
				snprintf(where, size, " (U+%04X%s%s at byte %zu)", cp, name ? " " : "",
				         name ? name : "", i + 1);
			return control ? "expected no control characters (tabs, line breaks and the "
			                 "like)"
			               : "expected no invisible or bidirectional format character (it "
			                 "would make the record display differently from what it holds)";
		}
		i += (size_t)len;
	}
	return NULL;
}

const char *kg_meta_value_problem(const char *value)
{
	return value_check(value, NULL, 0);
}

int kg_meta_set(json_t *obj, const char *what, const char *key, const char *value,
                kg_err *err)
{
	if (!kg_meta_key_ok(key))
		return kg_fail(err, KG_EINVAL,
		               "%s: key: expected 1 to %d of A-Z a-z 0-9 '_' '.' '-' (known keys: "
		               "accession, title, operator, lighting, notes)",
		               what, KG_META_KEY_MAX);
	char where[128];
	const char *why = value_check(value, where, sizeof(where));
	if (why)
		return kg_fail(err, KG_EINVAL, "%s: value: %s%s", what, why, where);
	if (json_object_get(obj, key))
		return kg_fail(err, KG_EINVAL, "%s: key '%s' given twice: expected each key once",
		               what, key);
	if (json_object_size(obj) >= KG_META_MAX_KEYS)
		return kg_fail(err, KG_EINVAL, "%s: expected at most %d keys", what,
		               KG_META_MAX_KEYS);
	if (json_object_set_new(obj, key, json_string(value)))
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", what);
	return 0;
}

int kg_meta_parse_arg(json_t *obj, const char *opt, const char *arg, kg_err *err)
{
	if (!arg)
		arg = "";
	if (!opt)
		opt = "--meta";
	/* the argument as the terminal should show it: controls and format characters
	 * escaped, at most 100 bytes of it */
	char shown[512], what[560];
	kg_text_visible(arg, 100, shown, sizeof(shown));
	snprintf(what, sizeof(what), "%s '%s'", opt, shown);
	const char *eq = strchr(arg, '=');
	if (!eq)
		return kg_fail(err, KG_EINVAL, "%s: expected KEY=VALUE (e.g. accession=1987.12.3)",
		               what);
	size_t kn = (size_t)(eq - arg);
	char key[KG_META_KEY_MAX + 2];
	if (kn > KG_META_KEY_MAX)
		kn = KG_META_KEY_MAX + 1; /* too long: refused by kg_meta_key_ok */
	memcpy(key, arg, kn);
	key[kn] = 0;
	return kg_meta_set(obj, what, key, eq + 1, err);
}

int kg_meta_validate(const char *file, const char *key, const json_t *meta, kg_err *err)
{
	if (!json_is_object(meta))
		return kg_fail(err, KG_EINVAL, "%s: %s: expected an object of KEY: \"value\" strings",
		               file, key);
	if (json_object_size(meta) > KG_META_MAX_KEYS)
		return kg_fail(err, KG_EINVAL, "%s: %s: expected at most %d keys", file, key,
		               KG_META_MAX_KEYS);
	const char *k;
	const json_t *v;
	json_object_foreach((json_t *)meta, k, v)
	{
		if (!kg_meta_key_ok(k)) {
			char shown[400];
			return kg_fail(err, KG_EINVAL,
			               "%s: %s: key '%s': expected 1 to %d of A-Z a-z 0-9 '_' '.' '-'",
			               file, key, kg_text_visible(k, 80, shown, sizeof(shown)),
			               KG_META_KEY_MAX);
		}
		char where[128] = "";
		const char *why = json_is_string(v) ? value_check(json_string_value(v), where,
		                                                  sizeof(where))
		                                    : "expected a string";
		if (why)
			return kg_fail(err, KG_EINVAL, "%s: %s.%s: %s%s", file, key, k, why, where);
	}
	return 0;
}

static int cmp_str(const void *a, const void *b)
{
	return strcmp(*(const char *const *)a, *(const char *const *)b);
}

int kg_meta_ordered_keys(const json_t *meta, const char **keys, int max)
{
	int n = 0;
	for (int i = 0; kg_meta_known_keys[i] && n < max; i++) {
		json_t *v = json_object_get(meta, kg_meta_known_keys[i]);
		if (json_is_string(v))
			keys[n++] = kg_meta_known_keys[i];
	}
	int first = n;
	const char *k;
	const json_t *v;
	json_object_foreach((json_t *)meta, k, v)
	{
		int known = 0;
		for (int i = 0; kg_meta_known_keys[i]; i++)
			known |= !strcmp(k, kg_meta_known_keys[i]);
		if (!known && json_is_string(v) && n < max)
			keys[n++] = k;
	}
	qsort(keys + first, (size_t)(n - first), sizeof(*keys), cmp_str);
	return n;
}
