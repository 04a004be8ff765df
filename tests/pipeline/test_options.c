/* Options declared once (kg_pipeline.h, "Options of an operation"): a table of a test's
 * own and kogei deposit's, parsed from argv and filled from JSON into the same struct,
 * the usage errors and JSON refusals naming the option, --help printed from the table,
 * and kg_deposit_check on what either front end gives. */
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_pipeline.h"
#include "kg_test.h"

typedef struct demo_opts {
	const char *input;
	const char *out;
	const char *label_text;
	int verbose;
	int dry_run;
} demo_opts;

static const kg_opt_spec demo_specs[] = {
	{"output", 'o', "OUT", KG_OPT_STRING, offsetof(demo_opts, out), KG_OPT_CLI_ONLY,
	 "where it goes"},
	{"label-text", 0, "TEXT", KG_OPT_STRING, offsetof(demo_opts, label_text), 0,
	 "a text that is long enough to be wrapped over more than one line of the help, so "
	 "the wrapping is seen to keep every word of it and to indent what follows"},
	{"verbose", 'v', NULL, KG_OPT_FLAG, offsetof(demo_opts, verbose), 0, "say more"},
	{"dry-run", 0, NULL, KG_OPT_FLAG, offsetof(demo_opts, dry_run), 0, "change nothing"},
};
static const kg_opt_table demo = {
	.synopsis = "demo INPUT -o OUT",
	.description = "A demonstration.",
	.positional = "INPUT",
	.positional_offset = offsetof(demo_opts, input),
	.specs = demo_specs,
	.nspecs = 4,
};

static int parse(const kg_opt_table *t, void *opts, kg_err *err, int argc, ...)
{
	char *argv[16];
	va_list ap;
	va_start(ap, argc);
	for (int i = 0; i < argc && i < 16; i++)
		argv[i] = va_arg(ap, char *);
	va_end(ap);
	return kg_opt_parse_argv(t, argc, argv, opts, err);
}

static json_t *json(const char *text)
{
	json_error_t je;
	json_t *j = json_loads(text, 0, &je);
	CHECK(j != NULL, "test JSON %s: %s", text, je.text);
	return j;
}

static void test_argv(void)
{
	demo_opts o = {0};
	kg_err err = {{0}};
	int ret = parse(&demo, &o, &err, 7, "demo", "in", "-o", "a", "--label-text=x y", "-v",
	                "--dry-run");
	CHECK(ret == 0, "parse: %s", err.msg);
	CHECK(o.input && !strcmp(o.input, "in"), "positional %s", o.input);
	CHECK(o.out && !strcmp(o.out, "a"), "-o %s", o.out);
	CHECK(o.label_text && !strcmp(o.label_text, "x y"), "--label-text= %s", o.label_text);
	CHECK(o.verbose == 1 && o.dry_run == 1, "flags %d %d", o.verbose, o.dry_run);

	memset(&o, 0, sizeof(o));
	ret = parse(&demo, &o, &err, 6, "demo", "--output", "b", "-oc", "--", "-in");
	CHECK(ret == 0 && o.out && !strcmp(o.out, "c") && o.input && !strcmp(o.input, "-in"),
	      "-oVALUE, a later value wins, -- before a positional: %d %s %s", ret, o.out, o.input);

	static const struct {
		int argc;
		const char *argv[4];
		const char *says;
	} bad[] = {
		{2, {"demo", "--nope"}, "unknown option '--nope'"},
		{2, {"demo", "-x"}, "unknown option '-x'"},
		{2, {"demo", "-o"}, "-o: expected OUT"},
		{2, {"demo", "--label-text"}, "--label-text: expected TEXT"},
		{2, {"demo", "--verbose=1"}, "--verbose takes no value"},
		{3, {"demo", "a", "b"}, "unexpected argument 'b'"},
	};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		memset(&o, 0, sizeof(o));
		err.msg[0] = 0;
		ret = kg_opt_parse_argv(&demo, bad[i].argc, (char **)bad[i].argv, &o, &err);
		CHECK(ret == KG_EINVAL && strstr(err.msg, bad[i].says), "%s %s: %d '%s', expected '%s'",
		      bad[i].argv[1], bad[i].argc > 2 ? bad[i].argv[2] : "", ret, err.msg, bad[i].says);
	}
}

static void test_json(void)
{
	demo_opts o = {0};
	kg_err err = {{0}};
	json_t *j = json("{\"label_text\": \"t\", \"verbose\": true, \"dry_run\": false}");
	o.dry_run = 1;
	int ret = kg_opt_from_json(&demo, j, &o, &err);
	CHECK(ret == 0, "from_json: %s", err.msg);
	CHECK(o.label_text && !strcmp(o.label_text, "t") && o.verbose == 1 && o.dry_run == 0,
	      "from_json: %s %d %d", o.label_text, o.verbose, o.dry_run);
	json_decref(j);

	static const struct {
		const char *json, *says;
	} bad[] = {
		{"{\"output\": \"x\"}", "'output': unknown option (expected label_text, verbose, "
		                        "dry_run)"},
		{"{\"label-text\": \"x\"}", "'label-text': unknown option"},
		{"{\"verbose\": 1}", "'verbose': expected true or false"},
		{"{\"label_text\": 3}", "'label_text': expected a string"},
		{"[1]", "expected a JSON object"},
	};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		j = json(bad[i].json);
		err.msg[0] = 0;
		ret = kg_opt_from_json(&demo, j, &o, &err);
		CHECK(ret == KG_EINVAL && strstr(err.msg, bad[i].says), "%s: %d '%s', expected '%s'",
		      bad[i].json, ret, err.msg, bad[i].says);
		json_decref(j);
	}
}

static void test_help(void)
{
	char *text = NULL;
	size_t len = 0;
	FILE *f = open_memstream(&text, &len);
	kg_opt_print_help(f, &demo);
	fclose(f);
	CHECK(strstr(text, "usage: demo INPUT -o OUT\n\nA demonstration.\n"), "%s", text);
	CHECK(strstr(text, "  -o, --output OUT      where it goes\n"), "%s", text);
	CHECK(strstr(text, "  -v, --verbose         say more\n"), "%s", text);
	CHECK(strstr(text, "      --dry-run         change nothing\n"), "%s", text);
	/* no line over 88 columns; the long help wrapped with every word kept, each line
	 * after its first indented by 24 */
	for (char *line = text, *next; *line; line = next) {
		next = line + strcspn(line, "\n");
		CHECK(next - line <= 88, "a help line of %d columns", (int)(next - line));
		next += *next == '\n';
	}
	const char *h = strstr(text, "--label-text TEXT");
	const char *end = h ? strstr(h, "  -v, --verbose") : NULL;
	CHECK(h && end, "%s", text);
	char words[512];
	size_t k = 0;
	int space = 0, lines = 0;
	for (const char *s = h ? h + 17 : ""; s < end && k + 2 < sizeof(words); s++) {
		if (*s == '\n') {
			lines++;
			CHECK(s + 1 == end || (strspn(s + 1, " ") == 24 && s[25] != ' '),
			      "a continued line not indented by 24");
		}
		if (*s == ' ' || *s == '\n') {
			space = k > 0;
			continue;
		}
		if (space)
			words[k++] = ' ';
		space = 0;
		words[k++] = *s;
	}
	words[k] = 0;
	CHECK(!strcmp(words, demo_specs[1].help), "wrapped help '%s'", words);
	CHECK(lines >= 2, "the long help on %d lines", lines);
	free(text);

	/* kogei deposit's help names every option of its table */
	text = NULL;
	f = open_memstream(&text, &len);
	kg_opt_print_help(f, &kg_deposit_table);
	fclose(f);
	for (int i = 0; i < kg_deposit_table.nspecs; i++) {
		char opt[64];
		snprintf(opt, sizeof(opt), "--%s", kg_deposit_table.specs[i].name);
		CHECK(strstr(text, opt), "kogei deposit --help lacks %s", opt);
	}
	free(text);
}

/* The command line and a JSON request give kogei deposit the same options. */
static void test_deposit_fronts(void)
{
	kg_deposit_options a, b;
	kg_deposit_options_default(&a);
	kg_deposit_options_default(&b);
	kg_err err = {{0}};
	char *argv[] = {"deposit", "R", "-o", "B", "--with-session", "--copy", "--force",
	                "--source-organization", "Museum", "--contact-name", "Ann",
	                "--contact-email", "a@b.c", "--external-description", "two bowls"};
	int ret = kg_opt_parse_argv(&kg_deposit_table, 15, argv, &a, &err);
	CHECK(ret == 0 && kg_deposit_check(&a, &err) == 0, "deposit argv: %s", err.msg);
	json_t *j = json("{\"with_session\": true, \"copy\": true, \"force\": true, "
	                 "\"source_organization\": \"Museum\", \"contact_name\": \"Ann\", "
	                 "\"contact_email\": \"a@b.c\", \"external_description\": \"two bowls\"}");
	b.results = "R";
	b.bag = "B";
	ret = kg_opt_from_json(&kg_deposit_table, j, &b, &err);
	CHECK(ret == 0 && kg_deposit_check(&b, &err) == 0, "deposit JSON: %s", err.msg);
	CHECK(a.with_session == b.with_session && a.copy == b.copy && a.force == b.force &&
	      a.with_session == 1 && a.copy == 1 && a.force == 1, "flags");
	const char *const *sa[] = {&a.source_organization, &a.contact_name, &a.contact_email,
	                           &a.external_description, &a.results, &a.bag};
	const char *const *sb[] = {&b.source_organization, &b.contact_name, &b.contact_email,
	                           &b.external_description, &b.results, &b.bag};
	for (int i = 0; i < 6; i++)
		CHECK(*sa[i] && *sb[i] && !strcmp(*sa[i], *sb[i]), "field %d: %s vs %s", i, *sa[i],
		      *sb[i]);
	json_decref(j); /* b's strings were borrowed from it */
	kg_deposit_options_default(&b);
	b.results = "R";
	b.bag = "B";

	/* paths on the operator's machine are the command line's only */
	static const char *const cli_only[] = {"{\"output\": \"/x\"}", "{\"config\": \"/x\"}",
	                                       "{\"session\": \"/x\"}", "{\"verify\": \"/x\"}",
	                                       "{\"results\": \"/x\"}"};
	for (int i = 0; i < 5; i++) {
		j = json(cli_only[i]);
		CHECK(kg_opt_from_json(&kg_deposit_table, j, &b, &err) == KG_EINVAL &&
		      strstr(err.msg, "unknown option"), "%s: %s", cli_only[i], err.msg);
		json_decref(j);
	}

	/* a bag-info value is one line: refused naming the option, from either front */
	j = json("{\"contact_name\": \"Ann\\nBob\"}");
	ret = kg_opt_from_json(&kg_deposit_table, j, &b, &err);
	CHECK(ret == 0, "from_json takes any string: %s", err.msg);
	ret = kg_deposit_check(&b, &err);
	CHECK(ret == KG_EINVAL && strstr(err.msg, "--contact-name") &&
	      strstr(err.msg, "a line break"), "a newline: %d %s", ret, err.msg);
	json_decref(j);
	b.contact_name = NULL;
	CHECK(kg_deposit_check(&b, &err) == 0, "without it: %s", err.msg);
	b.contact_name = "x\ry";
	CHECK(kg_deposit_check(&b, &err) == KG_EINVAL && strstr(err.msg, "--contact-name"),
	      "a CR: %s", err.msg);
	b.contact_name = NULL;
	b.source_organization = "";
	CHECK(kg_deposit_check(&b, &err) == KG_EINVAL && strstr(err.msg, "--source-organization"),
	      "an empty value: %s", err.msg);

	kg_deposit_options c;
	kg_deposit_options_default(&c);
	c.bag = "B";
	CHECK(kg_deposit_check(&c, &err) == KG_EINVAL && strstr(err.msg, "RESULTS"), "%s", err.msg);
	c.results = "R";
	c.bag = NULL;
	CHECK(kg_deposit_check(&c, &err) == KG_EINVAL && strstr(err.msg, "-o BAG"), "%s", err.msg);
	c.verify = "B";
	CHECK(kg_deposit_check(&c, &err) == KG_EINVAL && strstr(err.msg, "--verify"), "%s", err.msg);
	c.results = NULL;
	CHECK(kg_deposit_check(&c, &err) == 0, "--verify alone: %s", err.msg);
}

/* kogei collection run's table: argv and JSON give the same options; the paths (-o,
 * --sbatch-args) are the command line's only; kg_collection_check's refusals name the
 * option. */
static void test_collection_fronts(void)
{
	kg_collection_options a, b;
	kg_collection_options_default(&a);
	kg_collection_options_default(&b);
	kg_err err = {{0}};
	char *argv[] = {"run", "L.csv", "-o", "OUT", "--engine", "slurm", "-j", "4",
	                "--partition", "short", "--no-wait"};
	int ret = kg_opt_parse_argv(&kg_collection_table, 11, argv, &a, &err);
	CHECK(ret == 0 && kg_collection_check(&a, &err) == 0, "collection argv: %s", err.msg);
	json_t *j = json("{\"engine\": \"slurm\", \"jobs\": \"4\", \"partition\": "
	                 "\"short\", \"no_wait\": true}");
	b.list = "L.csv";
	b.out = "OUT";
	ret = kg_opt_from_json(&kg_collection_table, j, &b, &err);
	CHECK(ret == 0 && kg_collection_check(&b, &err) == 0, "collection JSON: %s", err.msg);
	CHECK(a.njobs == 4 && b.njobs == 4 && a.no_wait && b.no_wait &&
	      !strcmp(a.engine, b.engine) && !strcmp(a.partition, b.partition) &&
	      !strcmp(a.list, "L.csv") && !strcmp(a.out, "OUT"), "the same options from both");
	json_decref(j);
	static const char *const cli_only[] = {"{\"output\": \"/x\"}",
	                                       "{\"sbatch_args\": \"--x\"}"};
	for (int i = 0; i < 2; i++) {
		kg_collection_options_default(&b);
		j = json(cli_only[i]);
		CHECK(kg_opt_from_json(&kg_collection_table, j, &b, &err) == KG_EINVAL &&
		      strstr(err.msg, "unknown option"), "%s: %s", cli_only[i], err.msg);
		json_decref(j);
	}
	struct {
		const char *engine, *jobs, *partition;
		int no_wait;
		const char *says;
	} bad[] = {{"cloud", NULL, NULL, 0, "--engine"},  {NULL, "0", NULL, 0, "--jobs"},
	           {NULL, "2x", NULL, 0, "--jobs"},       {NULL, NULL, "p", 0, "--partition"},
	           {NULL, NULL, NULL, 1, "--no-wait"},    {"slurm", NULL, "a b", 0, "--partition"}};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		kg_collection_options c;
		kg_collection_options_default(&c);
		c.list = "L.csv";
		c.out = "OUT";
		c.engine = bad[i].engine;
		c.jobs = bad[i].jobs;
		c.partition = bad[i].partition;
		c.no_wait = bad[i].no_wait;
		CHECK(kg_collection_check(&c, &err) == KG_EINVAL && strstr(err.msg, bad[i].says),
		      "refusal %zu: %s", i, err.msg);
	}
}

/* kogei process's access copy and manifest options (kg_process_access_table): the same
 * struct from kg_opt_set (how kogei process's own parser takes them) and from JSON (the
 * console's process job), checked alike; bad values refused naming the option. */
static void test_access_fronts(void)
{
	const kg_opt_table *t = &kg_process_access_table;
	kg_process_options a, b;
	kg_process_options_default(&a);
	kg_process_options_default(&b);
	kg_err err = {{0}};
	const char *values[][2] = {{"access-compression", "deflate"},
	                           {"access-quality", "80"},
	                           {"iiif-base", "https://img.example.org/iiif"},
	                           {"iiif-image-api", "2"},
	                           {"files-base", "https://img.example.org/files/"}};
	int n = (int)(sizeof(values) / sizeof(values[0]));
	CHECK(t->nspecs == n, "access table: %d options, expected %d", t->nspecs, n);
	json_t *j = json_object();
	for (int i = 0; i < n; i++) {
		const kg_opt_spec *s = NULL;
		for (int k = 0; k < t->nspecs; k++)
			if (!strcmp(t->specs[k].name, values[i][0]))
				s = &t->specs[k];
		CHECK(s != NULL, "no option %s", values[i][0]);
		if (s)
			kg_opt_set(s, &a, values[i][1]);
		char key[64];
		snprintf(key, sizeof(key), "%s", values[i][0]);
		for (char *c = key; *c; c++)
			*c = *c == '-' ? '_' : *c;
		json_object_set_new(j, key, json_string(values[i][1]));
	}
	int ret = kg_opt_from_json(t, j, &b, &err);
	CHECK(ret == 0 && kg_process_access_check(&b, &err) == 0, "access JSON: %s", err.msg);
	CHECK(kg_process_access_check(&a, &err) == 0, "access argv: %s", err.msg);
	CHECK(a.access_compression && b.access_compression &&
	      !strcmp(a.access_compression, b.access_compression) &&
	      !strcmp(a.access_quality, b.access_quality) && !strcmp(a.iiif_base, b.iiif_base) &&
	      !strcmp(a.iiif_image_api, b.iiif_image_api) && !strcmp(a.files_base, b.files_base),
	      "the same access options from both");
	json_decref(j);
	struct {
		const char *key, *value, *says;
	} bad[] = {{"access_quality", "0", "--access-quality"},
	           {"access_quality", "101", "--access-quality"},
	           {"access_quality", "9x", "--access-quality"},
	           {"access_compression", "lzw", "--access-compression"},
	           {"iiif_base", "ftp://x/iiif", "--iiif-base"},
	           {"iiif_base", "http:///x", "--iiif-base"},
	           {"files_base", "http://x/a b", "--files-base"},
	           {"files_base", "http://x/?q", "--files-base"},
	           {"iiif_image_api", "4", "--iiif-image-api"}};
	for (size_t i = 0; i < sizeof(bad) / sizeof(bad[0]); i++) {
		kg_process_options c;
		kg_process_options_default(&c);
		j = json_pack("{s:s}", bad[i].key, bad[i].value);
		ret = kg_opt_from_json(t, j, &c, &err);
		CHECK(ret == 0 && kg_process_access_check(&c, &err) == KG_EINVAL &&
		      strstr(err.msg, bad[i].says), "refusal %zu: %s", i, err.msg);
		json_decref(j);
	}
	j = json("{\"render\": false}");
	CHECK(kg_opt_from_json(t, j, &b, &err) == KG_EINVAL && strstr(err.msg, "unknown option"),
	      "the console's own key is not the table's: %s", err.msg);
	json_decref(j);
}

int main(void)
{
	test_argv();
	test_json();
	test_help();
	test_deposit_fronts();
	test_collection_fronts();
	test_access_fronts();
	return kg_test_done("options");
}
