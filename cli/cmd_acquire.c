/* Placeholder until kogei acquire lands. */
#include <stdio.h>

#include "cli.h"

int kg_cmd_acquire(int argc, char **argv)
{
	fprintf(stderr, "kogei acquire: not implemented yet\n");
	return KG_EXIT_USAGE;
}
