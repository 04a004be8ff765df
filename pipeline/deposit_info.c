/* kogei deposit's options and what bag-info.txt says of the operator (kg_pipeline.h,
 * docs/deposit.md): the options table the command line and the console share
 * (kg_deposit_table), their check, and the config file of "Label: value" lines. */
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "pipeline_private.h"

/* ---- the options ----------------------------------------------------------------------- */

#define OPT(field) offsetof(kg_deposit_options, field)

static const kg_opt_spec deposit_specs[] = {
	{"output", 'o', "BAG", KG_OPT_STRING, OPT(bag), KG_OPT_CLI_ONLY,
	 "the bag to write: a new folder (its parent must exist), or with --force an earlier "
	 "bag to replace"},
	{"with-session", 0, NULL, KG_OPT_FLAG, OPT(with_session), 0,
	 "the session the results were made from too (process.json \"session\": its realpath, "
	 "else its path): RESULTS go to data/results/, the session to data/session/"},
	{"session", 0, "DIR", KG_OPT_STRING, OPT(session), KG_OPT_CLI_ONLY,
	 "that session's folder, when it was moved since it was processed (implies "
	 "--with-session; its session.json must have the id process.json records)"},
	{"source-organization", 0, "ORG", KG_OPT_STRING, OPT(source_organization), 0,
	 "bag-info.txt Source-Organization: the organisation transferring the content"},
	{"organization-address", 0, "ADDRESS", KG_OPT_STRING, OPT(organization_address), 0,
	 "bag-info.txt Organization-Address"},
	{"contact-name", 0, "NAME", KG_OPT_STRING, OPT(contact_name), 0,
	 "bag-info.txt Contact-Name: the person responsible for the deposit"},
	{"contact-phone", 0, "PHONE", KG_OPT_STRING, OPT(contact_phone), 0,
	 "bag-info.txt Contact-Phone"},
	{"contact-email", 0, "MAIL", KG_OPT_STRING, OPT(contact_email), 0,
	 "bag-info.txt Contact-Email"},
	{"external-description", 0, "TEXT", KG_OPT_STRING, OPT(external_description), 0,
	 "bag-info.txt External-Description: what the bag holds, for the repository"},
	{"config", 0, "FILE", KG_OPT_STRING, OPT(config), KG_OPT_CLI_ONLY,
	 "the values above from a file of \"Label: value\" lines as bag-info.txt writes them "
	 "(Source-Organization, Organization-Address, Contact-Name, Contact-Phone, "
	 "Contact-Email, External-Description; blank lines and lines starting with '#' are "
	 "skipped); an option overrides the file's line"},
	{"copy", 0, NULL, KG_OPT_FLAG, OPT(copy), 0,
	 "copy every payload file (default: a hard link to the file of RESULTS or the session "
	 "where they are on the same file system, a copy elsewhere)"},
	{"force", 0, NULL, KG_OPT_FLAG, OPT(force), 0,
	 "replace an existing bag at BAG (a folder holding bagit.txt), in one step; any other "
	 "folder or file at BAG is always refused"},
	{"verify", 0, "BAG", KG_OPT_STRING, OPT(verify), KG_OPT_CLI_ONLY,
	 "check BAG instead of writing one: bagit.txt, every file of each manifest present "
	 "with its checksum, no payload file missing from a manifest, the tag manifest, "
	 "Payload-Oxum. Exit 0 with \"BAG: valid: N files, X bytes\", else 1 naming each file "
	 "missing, extra or changed"},
	{"progress", 0, NULL, KG_OPT_FLAG, OPT(show_progress), KG_OPT_CLI_ONLY,
	 "a line per file on standard error also when it is not a terminal"},
};

const kg_opt_table kg_deposit_table = {
	.synopsis = "kogei deposit RESULTS -o BAG [--with-session | --session DIR] [--copy] "
	            "[--force]\n"
	            "                     [--source-organization ORG] [--contact-name NAME] "
	            "[--contact-email MAIL]\n"
	            "                     [--config FILE] [--progress] ...\n"
	            "       kogei deposit --verify BAG [--progress]",
	.description =
		"A BagIt 1.0 bag (RFC 8493) of one processed session for a repository: BAG/data/\n"
		"holds every file of RESULTS (the output folder of kogei process), or with\n"
		"--with-session RESULTS in data/results/ and the session in data/session/;\n"
		"manifest-sha512.txt lists every payload file with its sha512, bag-info.txt gives\n"
		"Source-Organization, Contact-Name, Contact-Email (options or --config), one\n"
		"External-Identifier per accession of process.json, the session's id\n"
		"(Internal-Sender-Identifier), Bagging-Date, Payload-Oxum and Bag-Software-Agent;\n"
		"tagmanifest-sha512.txt covers the tag files. Payload files are hard links to the\n"
		"files of RESULTS where the file system allows (the bag's files then ARE those\n"
		"files: kogei never changes a file in place, but another program that does changes\n"
		"both; --copy for a bag of its own). The bag is staged in BAG's parent as\n"
		".BAG.kogei-tmp.PID and renamed into place when complete: a failure or an\n"
		"interruption leaves nothing at BAG. RESULTS is locked while it is read (a kogei\n"
		"process into it waits), and a half-done commit of a killed run is completed first.",
	.positional = "RESULTS",
	.positional_offset = OPT(results),
	.specs = deposit_specs,
	.nspecs = (int)(sizeof(deposit_specs) / sizeof(deposit_specs[0])),
};

/* The bag-info.txt labels the operator gives, in the order bag-info.txt lists them;
 * each is also the option of its name in lower case (--source-organization). */
static const struct given_label {
	const char *label;
	size_t offset;
} given[] = {
	{"Source-Organization", OPT(source_organization)},
	{"Organization-Address", OPT(organization_address)},
	{"Contact-Name", OPT(contact_name)},
	{"Contact-Phone", OPT(contact_phone)},
	{"Contact-Email", OPT(contact_email)},
	{"External-Description", OPT(external_description)},
};
_Static_assert(sizeof(given) / sizeof(given[0]) == DEPOSIT_NGIVEN, "one value per label");
enum { NGIVEN = DEPOSIT_NGIVEN };

/* The labels kogei deposit writes itself. */
static const char *const computed[] = {
	"Bagging-Date", "Payload-Oxum", "Bag-Size", "External-Identifier",
	"Internal-Sender-Identifier", "Internal-Sender-Description", "Bag-Software-Agent",
};

static const char *given_value(const kg_deposit_options *o, int i)
{
	return *(const char *const *)((const char *)o + given[i].offset);
}

void kg_deposit_options_default(kg_deposit_options *o)
{
	memset(o, 0, sizeof(*o));
}

/* "--source-organization" for a label. */
static void option_name(const char *label, char *out, size_t size)
{
	size_t i = 0;
	for (; label[i] && i + 3 < size; i++)
		out[i + 2] = (char)(label[i] >= 'A' && label[i] <= 'Z' ? label[i] + 32 : label[i]);
	out[0] = out[1] = '-';
	out[i + 2] = 0;
}

const char *deposit_value_problem(const char *value)
{
	if (!*value)
		return "expected a value";
	if (strpbrk(value, "\r\n"))
		return "holds a line break";
	return kg_meta_value_problem(value);
}

int kg_deposit_check(const kg_deposit_options *o, kg_err *err)
{
	kg_check_arg(o, err);
	int values = 0;
	for (int i = 0; i < NGIVEN; i++) {
		const char *v = given_value(o, i);
		const char *why = v ? deposit_value_problem(v) : NULL;
		char opt[64];
		option_name(given[i].label, opt, sizeof(opt));
		if (why)
			return kg_fail(err, KG_EINVAL, "%s: %s (a bag-info.txt %s is one line of text)",
			               opt, why, given[i].label);
		values += v != NULL;
	}
	if (o->verify) {
		if (o->results || o->bag || o->with_session || o->session || o->copy || o->force ||
		    o->config || values)
			return kg_fail(err, KG_EINVAL, "--verify BAG checks a bag: no RESULTS, -o or other "
			               "option with it (--progress aside)");
		return 0;
	}
	if (!o->results)
		return kg_fail(err, KG_EINVAL, "expected RESULTS, the output folder of kogei process");
	if (!o->bag)
		return kg_fail(err, KG_EINVAL, "-o BAG is required");
	return 0;
}

/* ---- the config file -------------------------------------------------------------------- */

/* One "Label: value" line of file (cut in place). */
static int config_line(deposit_info *in, const char *file, char *line, int lineno, kg_err *err)
{
	char *colon = strchr(line, ':');
	if (!colon || colon == line || line[0] == ' ' || line[0] == '\t')
		return kg_fail(err, KG_EINVAL, "%s: line %d: expected \"Label: value\" (one line, "
		               "as in bag-info.txt)", file, lineno);
	*colon = 0;
	char *value = colon + 1 + strspn(colon + 1, " \t");
	size_t n = strlen(value);
	while (n && (value[n - 1] == ' ' || value[n - 1] == '\t' || value[n - 1] == '\r'))
		value[--n] = 0;
	for (size_t i = 0; i < sizeof(computed) / sizeof(computed[0]); i++)
		if (!strcasecmp(line, computed[i]))
			return kg_fail(err, KG_EINVAL, "%s: line %d: %s is written by kogei deposit, "
			               "not taken from a configuration", file, lineno, computed[i]);
	for (int i = 0; i < NGIVEN; i++) {
		if (strcasecmp(line, given[i].label))
			continue;
		const char *why = deposit_value_problem(value);
		if (why)
			return kg_fail(err, KG_EINVAL, "%s: line %d: %s: %s (a bag-info.txt value is "
			               "one line of text)", file, lineno, given[i].label, why);
		if (in->values[i])
			return kg_fail(err, KG_EINVAL, "%s: line %d: %s given a second time", file,
			               lineno, given[i].label);
		in->values[i] = value;
		return 0;
	}
	return kg_fail(err, KG_EINVAL, "%s: line %d: '%.64s': not a label kogei deposit takes "
	               "(expected Source-Organization, Organization-Address, Contact-Name, "
	               "Contact-Phone, Contact-Email or External-Description)", file, lineno, line);
}

int deposit_info_load(deposit_info *in, const kg_deposit_options *o, kg_err *err)
{
	size_t len;
	memset(in, 0, sizeof(*in));
	int ret = o->config ? kg_read_file(o->config, &in->config_text, &len, err) : 0;
	if (!ret && in->config_text && strlen(in->config_text) != len)
		ret = kg_fail(err, KG_EINVAL, "%s: holds a NUL byte: expected text", o->config);
	int lineno = 0;
	for (char *s = in->config_text, *next; !ret && s && *s; s = next) {
		next = s + strcspn(s, "\n");
		if (*next)
			*next++ = 0;
		lineno++;
		const char *t = s + strspn(s, " \t\r");
		if (*t && *t != '#')
			ret = config_line(in, o->config, s, lineno, err);
	}
	for (int i = 0; !ret && i < NGIVEN; i++)
		if (given_value(o, i))
			in->values[i] = given_value(o, i);
	return ret;
}

void deposit_info_print(const deposit_info *in, FILE *f)
{
	for (int i = 0; i < NGIVEN; i++)
		if (in->values[i])
			fprintf(f, "%s: %s\n", given[i].label, in->values[i]);
}

void deposit_info_clear(deposit_info *in)
{
	free(in->config_text);
	memset(in, 0, sizeof(*in));
}
