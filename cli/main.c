#include <stdio.h>
#include <string.h>

#include "kg_config.h"
#include "kg_optics.h"

int main(int argc, char **argv)
{
	if (argc > 1 && strcmp(argv[1], "--version") == 0) {
		printf("kogei %s\n", KG_VERSION);
		return 0;
	}
	fprintf(stderr, "usage: kogei COMMAND ...\n");
	return 2;
}
