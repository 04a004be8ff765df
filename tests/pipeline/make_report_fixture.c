/* make_report_fixture OUTDIR: the synthetic processed session of report_fixture.h,
 * for the browser test (which then runs `kogei report OUTDIR`). */
#include "report_fixture.h"

int main(int argc, char **argv)
{
	if (argc != 2) {
		fprintf(stderr, "usage: make_report_fixture OUTDIR\n");
		return 2;
	}
	return fixture_write(argv[1]) ? 1 : 0;
}
