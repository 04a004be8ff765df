/* `kogei bench`: runs the benchmark program kogei-bench (bench/), which sits above
 * every module, with the same arguments. */
#include <errno.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "kg_config.h"

int kg_cmd_bench(int argc, char **argv)
{
	/* The installed program, else the one in this build tree. */
	const char *path = access(KG_BENCH_INSTALLED, X_OK) == 0 ? KG_BENCH_INSTALLED
	                                                         : KG_BENCH_BUILT;
	(void)argc;
	execv(path, argv); /* argv[0] is "bench": the report records "kogei bench ..." */
	fprintf(stderr, "kogei bench: cannot run %s: %s\n", path, strerror(errno));
	return KG_EXIT_INPUT;
}
