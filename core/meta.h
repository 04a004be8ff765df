/* Object records: KEY=VALUE pairs describing what was photographed (docs/formats.md,
 * "Object records"), given with --meta on acquire and process and in the console's
 * capture form, stored as a "meta" object of strings.
 *
 * A key is 1 to KG_META_KEY_MAX of [A-Za-z0-9_.-]; the known keys (accession, title,
 * operator, lighting, notes) come first in the report, free keys after them. A value is
 * UTF-8 (well formed, no surrogates, no overlong forms) of at most KG_META_VALUE_MAX
 * bytes with no control character (U+0000..U+001F, U+007F..U+009F) and no invisible or
 * bidirectional format character (text.h: U+200B, U+202E, U+FEFF, U+2028, ...), so a
 * record displays as what it holds. At most KG_META_MAX_KEYS keys. */
#ifndef KG_META_H
#define KG_META_H

#include <jansson.h>

#include "error.h"

#define KG_META_KEY_MAX 64
#define KG_META_VALUE_MAX 4096
#define KG_META_MAX_KEYS 64

/* The known keys, NULL-terminated, in the order the report shows them. */
extern const char *const kg_meta_known_keys[];

/* 1 when key is a valid key. */
int kg_meta_key_ok(const char *key);
/* NULL when value is a valid value, else what is wrong with it (a static phrase). */
const char *kg_meta_value_problem(const char *value);
/* Check a KEY and VALUE and set them in obj (a JSON object). A key already in obj is
 * refused. `what` names the argument in the message (e.g. "--meta 'title=x'"). KG_EINVAL
 * with "<what>: expected ...". */
int kg_meta_set(json_t *obj, const char *what, const char *key, const char *value,
                kg_err *err);
/* Parse one "KEY=VALUE" argument into obj (kg_meta_set); the message names
 * "<opt> '<arg>'". */
int kg_meta_parse_arg(json_t *obj, const char *opt, const char *arg, kg_err *err);
/* Check a stored "meta" object (read from file at key, e.g. "captures[2].meta"):
 * an object of at most KG_META_MAX_KEYS valid keys with valid string values. */
int kg_meta_validate(const char *file, const char *key, const json_t *meta, kg_err *err);
/* The keys of meta in display order: the known keys present, then the others in byte
 * order. Fills keys (borrowed from meta) and returns how many (<= max). */
int kg_meta_ordered_keys(const json_t *meta, const char **keys, int max);

#endif
