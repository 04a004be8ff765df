/* Placeholder until kogei render lands. */
#include <stdio.h>

#include "cli.h"

int kg_cmd_render(int argc, char **argv)
{
	fprintf(stderr, "kogei render: not implemented yet\n");
	return KG_EXIT_USAGE;
}
