/* kogei collection run|status (and the engine's own steps, task and finish): every
 * session of a collection (pipeline/ does the work and declares run's options,
 * kg_collection_table; this file parses and reports). */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "kg_pipeline.h"

static const char usage_task[] =
	"kogei collection task OUT INDEX [--job ID] [--threads N]   (run by the engine)\n"
	"       kogei collection finish OUT                          (run by the engine)";

static int cmd_run(int argc, char **argv)
{
	const kg_opt_table *t = &kg_collection_table;
	if (kg_cli_wants_help(argc, argv)) {
		kg_opt_print_help(stdout, t);
		return KG_EXIT_OK;
	}
	kg_collection_options o;
	kg_collection_options_default(&o);
	kg_err err = {{0}};
	if (kg_opt_parse_argv(t, argc, argv, &o, &err) || kg_collection_check(&o, &err))
		return kg_cli_usage_error(t->synopsis, "%s", err.msg);
	if (o.show_progress || isatty(STDERR_FILENO))
		o.progress = stderr;
	o.problems = stderr;
	kg_collection_counts c;
	int sig = 0;
	int ret = kg_collection_run(&o, &c, &sig, &err);
	if (ret && sig) {
		fprintf(stderr, "kogei collection: %s\n", err.msg);
		signal(sig, SIG_DFL);
		raise(sig);
	}
	if (ret == KG_EINVAL || ret == KG_EBUSY) { /* nothing run: a bad list, OUT in use */
		fprintf(stderr, "kogei: %s\n", err.msg);
		return KG_EXIT_USAGE;
	}
	if (ret == KG_ENODEV) {
		fprintf(stderr, "kogei: %s\n", err.msg);
		return KG_EXIT_DEVICE;
	}
	if (ret)
		return kg_cli_error(&err, ret);
	if (c.array_job[0] && o.no_wait) {
		printf("kogei collection: %s: submitted Slurm job array %s and job %s (the record); "
		       "kogei collection status %s\n", o.out, c.array_job, c.finish_job, o.out);
		return KG_EXIT_OK;
	}
	printf("kogei collection: %s: %d entries: %d done, %d failed, %d pending (%d run now)\n",
	       o.out, c.entries, c.done, c.failed, c.pending, c.ran);
	if (c.failed) {
		kg_collection_print_failures(o.out, stderr);
		return KG_EXIT_INPUT;
	}
	if (c.pending)
		fprintf(stderr, "kogei collection: %d entries not run (their logs are in "
		        "%s/.collection/logs/): run the same command again\n", c.pending, o.out);
	return c.pending ? KG_EXIT_INPUT : KG_EXIT_OK;
}

static int cmd_status(int argc, char **argv)
{
	static const char usage[] = "kogei collection status OUT";
	if (kg_cli_wants_help(argc, argv)) {
		printf("usage: %s\n\nThe counts of a collection's entries (done, failed, pending), "
		       "each failure with its\nreason, and a submitted Slurm job's tasks still queued "
		       "or running. Exit status 0 when\nevery entry is done, 1 otherwise.\n", usage);
		return KG_EXIT_OK;
	}
	if (argc != 2 || argv[1][0] == '-')
		return kg_cli_usage_error(usage, "expected OUT, the folder of kogei collection run -o");
	kg_collection_counts c;
	kg_err err = {{0}};
	int ret = kg_collection_status(argv[1], stdout, &c, &err);
	if (ret)
		return kg_cli_error(&err, ret);
	return c.done == c.entries ? KG_EXIT_OK : KG_EXIT_INPUT;
}

static int cmd_task(int argc, char **argv)
{
	if (argc < 3)
		return kg_cli_usage_error(usage_task, "expected OUT and INDEX");
	int index, threads = 0;
	const char *job = NULL;
	if (kg_cli_int(argv[2], 0, 1 << 30, &index))
		return kg_cli_usage_error(usage_task, "INDEX '%s': expected an entry's number", argv[2]);
	for (int i = 3; i < argc; i++) {
		if (!strcmp(argv[i], "--job") && i + 1 < argc)
			job = argv[++i];
		else if (!strcmp(argv[i], "--threads") && i + 1 < argc &&
		         !kg_cli_int(argv[i + 1], 1, 256, &threads))
			i++;
		else
			return kg_cli_usage_error(usage_task, "unexpected argument '%s'", argv[i]);
	}
	int done = 0;
	kg_err err = {{0}};
	int ret = kg_collection_task(argv[1], index, job, threads, NULL, &done, &err);
	if (ret == -EINTR) {
		fprintf(stderr, "kogei collection: %s\n", err.msg);
		return 128 + SIGTERM;
	}
	if (ret)
		return kg_cli_error(&err, ret);
	return done ? KG_EXIT_OK : KG_EXIT_INPUT;
}

static int cmd_finish(int argc, char **argv)
{
	if (argc != 2)
		return kg_cli_usage_error(usage_task, "expected OUT");
	kg_collection_counts c;
	kg_err err = {{0}};
	int ret = kg_collection_finish(argv[1], &c, &err);
	if (ret)
		return kg_cli_error(&err, ret);
	printf("kogei collection: %s: %d entries: %d done, %d failed, %d pending\n", argv[1],
	       c.entries, c.done, c.failed, c.pending);
	return KG_EXIT_OK;
}

int kg_cmd_collection(int argc, char **argv)
{
	static const struct {
		const char *name;
		int (*run)(int, char **);
	} subs[] = {{"run", cmd_run}, {"status", cmd_status}, {"task", cmd_task},
	            {"finish", cmd_finish}};
	if (argc >= 2)
		for (size_t i = 0; i < sizeof(subs) / sizeof(subs[0]); i++)
			if (!strcmp(argv[1], subs[i].name))
				return subs[i].run(argc - 1, argv + 1);
	if (argc >= 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))) {
		kg_opt_print_help(stdout, &kg_collection_table);
		return KG_EXIT_OK;
	}
	return kg_cli_usage_error(kg_collection_table.synopsis, "expected run or status");
}
