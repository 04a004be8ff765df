#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "kg_config.h"

int kg_cli_parse_range(const char *text, double **values, int *n, kg_err *err)
{
	double a, b, s;
	char tail;
	if (sscanf(text, "%lf:%lf:%lf%c", &a, &b, &s, &tail) != 3 || !isfinite(a) ||
	    !isfinite(b) || !isfinite(s) || s <= 0 || b < a)
		return kg_fail(err, KG_EINVAL,
		               "range '%s': expected start:stop:step with start <= stop and step > 0",
		               text);
	int count = (int)floor((b - a) / s + 1e-9) + 1;
	if (count > 10000)
		return kg_fail(err, KG_EINVAL, "range '%s': more than 10000 values", text);
	double *v = malloc(sizeof(double) * count);
	if (!v)
		return KG_ENOMEM;
	for (int i = 0; i < count; i++)
		v[i] = a + i * s;
	*values = v;
	*n = count;
	return 0;
}
