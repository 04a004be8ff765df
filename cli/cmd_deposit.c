/* kogei deposit: a BagIt bag of one processed session, and its check (pipeline/ does
 * the work and declares the options, kg_deposit_table; this file parses and reports). */
#include <signal.h>
#include <stdio.h>
#include <unistd.h>

#include "cli.h"
#include "kg_pipeline.h"

static int verify(const kg_deposit_options *o)
{
	kg_deposit_summary sum;
	kg_err err = {{0}};
	int ret = kg_bag_verify(o->verify, stderr, o->progress, &sum, &err);
	if (ret)
		return kg_cli_error(&err, ret);
	printf("%s: valid: %d files, %llu bytes\n", o->verify, sum.files, sum.bytes);
	return KG_EXIT_OK;
}

int kg_cmd_deposit(int argc, char **argv)
{
	const kg_opt_table *t = &kg_deposit_table;
	if (kg_cli_wants_help(argc, argv)) {
		kg_opt_print_help(stdout, t);
		return KG_EXIT_OK;
	}
	kg_deposit_options o;
	kg_deposit_options_default(&o);
	kg_err err = {{0}};
	if (kg_opt_parse_argv(t, argc, argv, &o, &err) || kg_deposit_check(&o, &err))
		return kg_cli_usage_error(t->synopsis, "%s", err.msg);
	if (o.show_progress || isatty(STDERR_FILENO))
		o.progress = stderr;
	if (o.verify)
		return verify(&o);
	kg_deposit_summary sum;
	kg_deposit_catch_signals();
	int ret = kg_deposit_run(&o, &sum, &err);
	int sig = kg_deposit_signal();
	if (ret && sig) {
		fprintf(stderr, "kogei deposit: %s\n", err.msg);
		signal(sig, SIG_DFL); /* end by the signal, as without the handler */
		raise(sig);
	}
	if (ret)
		return kg_cli_error(&err, ret);
	printf("kogei deposit: %s -> %s: %d files, %llu bytes (%d hard-linked, %d copied), %d "
	       "External-Identifier(s)\n", o.results, o.bag, sum.files, sum.bytes, sum.linked,
	       sum.copied, sum.identifiers);
	return KG_EXIT_OK;
}
