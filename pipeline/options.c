/* Options declared once, for every front end (kg_pipeline.h, "Options of an
 * operation"): the command line, --help and JSON requests go through the same table. */
#include <stdio.h>
#include <string.h>

#include "kg_pipeline.h"

#define HELP_WIDTH 88  /* columns of --help */
#define HELP_INDENT 24 /* where an option's help starts */

static void set_flag(void *opts, const kg_opt_spec *s, int on)
{
	*(int *)((char *)opts + s->offset) = on;
}

static void set_string(void *opts, const kg_opt_spec *s, const char *value)
{
	*(const char **)((char *)opts + s->offset) = value;
}

static const kg_opt_spec *find_long(const kg_opt_table *t, const char *name, size_t len)
{
	for (int i = 0; i < t->nspecs; i++)
		if (strlen(t->specs[i].name) == len && !strncmp(t->specs[i].name, name, len))
			return &t->specs[i];
	return NULL;
}

static const kg_opt_spec *find_letter(const kg_opt_table *t, char letter)
{
	for (int i = 0; i < t->nspecs; i++)
		if (t->specs[i].letter && t->specs[i].letter == letter)
			return &t->specs[i];
	return NULL;
}

/* The JSON key of s is its name with '_' for '-'. */
static int json_key_is(const kg_opt_spec *s, const char *key)
{
	size_t i = 0;
	for (; s->name[i] && key[i]; i++)
		if (key[i] != (s->name[i] == '-' ? '_' : s->name[i]))
			return 0;
	return !s->name[i] && !key[i];
}

/* One option at argv[*i] (a, which starts with '-'). */
static int parse_option(const kg_opt_table *t, int argc, char **argv, int *i, void *opts,
                        kg_err *err)
{
	const char *a = argv[*i], *value = NULL;
	const kg_opt_spec *s;
	char shown[80];
	if (a[1] == '-') {
		const char *eq = strchr(a + 2, '=');
		s = find_long(t, a + 2, eq ? (size_t)(eq - a - 2) : strlen(a + 2));
		value = eq ? eq + 1 : NULL;
		snprintf(shown, sizeof(shown), "--%.*s", eq ? (int)(eq - a - 2) : 60, a + 2);
	} else {
		s = find_letter(t, a[1]);
		value = a[2] ? a + 2 : NULL;
		snprintf(shown, sizeof(shown), "-%c", a[1]);
	}
	if (!s || (s->type == KG_OPT_FLAG && value && a[1] != '-'))
		return kg_fail(err, KG_EINVAL, "unknown option '%s'", a);
	if (s->type == KG_OPT_FLAG) {
		if (value)
			return kg_fail(err, KG_EINVAL, "%s takes no value", shown);
		set_flag(opts, s, 1);
		return 0;
	}
	if (!value) {
		if (*i + 1 >= argc)
			return kg_fail(err, KG_EINVAL, "%s: expected %s", shown, s->value);
		value = argv[++*i];
	}
	set_string(opts, s, value);
	return 0;
}

int kg_opt_parse_argv(const kg_opt_table *t, int argc, char **argv, void *opts, kg_err *err)
{
	kg_check_arg(t && argv && opts, err);
	int positional_given = 0, options_end = 0;
	for (int i = 1; i < argc; i++) {
		const char *a = argv[i];
		if (!options_end && !strcmp(a, "--")) {
			options_end = 1;
		} else if (!options_end && a[0] == '-' && a[1]) {
			int ret = parse_option(t, argc, argv, &i, opts, err);
			if (ret)
				return ret;
		} else if (t->positional && !positional_given) {
			*(const char **)((char *)opts + t->positional_offset) = a;
			positional_given = 1;
		} else {
			return kg_fail(err, KG_EINVAL, "unexpected argument '%s'", a);
		}
	}
	return 0;
}

/* "a, b and c": the keys a request may hold. */
static void json_keys(const kg_opt_table *t, char *out, size_t size)
{
	size_t at = 0;
	out[0] = 0;
	for (int i = 0; i < t->nspecs && at < size; i++) {
		const kg_opt_spec *s = &t->specs[i];
		if (s->flags & KG_OPT_CLI_ONLY)
			continue;
		at += (size_t)snprintf(out + at, size - at, "%s", at ? ", " : "");
		for (const char *c = s->name; *c && at + 1 < size; c++)
			out[at++] = *c == '-' ? '_' : *c;
		out[at < size ? at : size - 1] = 0;
	}
}

int kg_opt_from_json(const kg_opt_table *t, const json_t *obj, void *opts, kg_err *err)
{
	kg_check_arg(t && opts, err);
	if (!json_is_object(obj))
		return kg_fail(err, KG_EINVAL, "expected a JSON object of options");
	const char *key;
	const json_t *v;
	json_object_foreach((json_t *)obj, key, v)
	{
		const kg_opt_spec *s = NULL;
		for (int i = 0; i < t->nspecs && !s; i++)
			if (!(t->specs[i].flags & KG_OPT_CLI_ONLY) && json_key_is(&t->specs[i], key))
				s = &t->specs[i];
		if (!s) {
			char keys[1024];
			json_keys(t, keys, sizeof(keys));
			return kg_fail(err, KG_EINVAL, "'%.64s': unknown option (expected %s)", key, keys);
		}
		if (s->type == KG_OPT_FLAG && !json_is_boolean(v))
			return kg_fail(err, KG_EINVAL, "'%s': expected true or false", key);
		if (s->type == KG_OPT_STRING && !json_is_string(v))
			return kg_fail(err, KG_EINVAL, "'%s': expected a string", key);
		if (s->type == KG_OPT_FLAG)
			set_flag(opts, s, json_is_true(v));
		else
			set_string(opts, s, json_string_value(v));
	}
	return 0;
}

/* text's words from column HELP_INDENT on, wrapped at HELP_WIDTH, each line after the
 * first indented to HELP_INDENT. */
static void print_wrapped(FILE *fp, const char *text)
{
	int col = HELP_INDENT;
	for (const char *w = text; *w;) {
		while (*w == ' ')
			w++;
		int len = (int)strcspn(w, " ");
		if (!len)
			break;
		if (col > HELP_INDENT && col + 1 + len > HELP_WIDTH) {
			fprintf(fp, "\n%*s", HELP_INDENT, "");
			col = HELP_INDENT;
		} else if (col > HELP_INDENT) {
			fputc(' ', fp);
			col++;
		}
		fprintf(fp, "%.*s", len, w);
		col += len;
		w += len;
	}
	fputc('\n', fp);
}

void kg_opt_set(const kg_opt_spec *s, void *opts, const char *value)
{
	if (s->type == KG_OPT_FLAG)
		set_flag(opts, s, 1);
	else
		set_string(opts, s, value);
}

void kg_opt_print_help(FILE *fp, const kg_opt_table *t)
{
	fprintf(fp, "usage: %s\n\n%s\n\nOptions:\n", t->synopsis, t->description);
	kg_opt_print_options(fp, t);
}

void kg_opt_print_options(FILE *fp, const kg_opt_table *t)
{
	for (int i = 0; i < t->nspecs; i++) {
		const kg_opt_spec *s = &t->specs[i];
		char head[128];
		/* names line up whether or not they have a short form */
		int n = s->letter ? snprintf(head, sizeof(head), "  -%c, --%s", s->letter, s->name)
		                  : snprintf(head, sizeof(head), "      --%s", s->name);
		if (s->value && n > 0 && (size_t)n < sizeof(head))
			n += snprintf(head + n, sizeof(head) - (size_t)n, " %s", s->value);
		fputs(head, fp);
		if (n + 2 > HELP_INDENT)
			fprintf(fp, "\n%*s", HELP_INDENT, "");
		else
			fprintf(fp, "%*s", HELP_INDENT - n, "");
		print_wrapped(fp, s->help);
	}
}
