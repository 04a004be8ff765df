/* write_dng PATH: writes the DNG of dng_fixture.h (the picture the PTP replay serves). */
#include <stdio.h>

#include "dng_fixture.h"

int main(int argc, char **argv)
{
	if (argc != 2) {
		fprintf(stderr, "usage: write_dng PATH\n");
		return 2;
	}
	return dng_fixture_write(argv[1]) ? 1 : 0;
}
