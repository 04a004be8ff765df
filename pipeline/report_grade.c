/* Aggregates and grades of the colour accuracy table (kg_pipeline.h). */
#include <math.h>
#include <stdlib.h>

#include "kg_pipeline.h"

static int compare_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return (x > y) - (x < y);
}

int kg_de_summarise(const double *v, int n, kg_de_summary *out, kg_err *err)
{
	kg_check_arg(n >= 0 && (v || n == 0) && out, err);
	double *sorted = malloc(sizeof(double) * (n > 0 ? n : 1));
	if (!sorted)
		return kg_fail(err, KG_ENOMEM, "colour difference summary: out of memory");
	int m = 0;
	double sum = 0;
	for (int i = 0; i < n; i++) {
		if (isnan(v[i]))
			continue;
		if (!(v[i] >= 0) || isinf(v[i])) {
			free(sorted);
			return kg_fail(err, KG_EINVAL,
			               "colour difference %d: %g: expected a finite value >= 0", i, v[i]);
		}
		sorted[m++] = v[i];
		sum += v[i];
	}
	if (m == 0) {
		free(sorted);
		return kg_fail(err, KG_EINVAL, "colour differences: expected at least one value");
	}
	qsort(sorted, m, sizeof(double), compare_double);
	/* Nearest rank: ceil(0.9 m) computed in integers (9 m / 10 rounded up), so that
	 * m = 10 gives rank 9 exactly rather than a rounding of 0.9 * 10. */
	int rank = (9 * m + 9) / 10;
	out->n = m;
	out->mean = sum / m;
	out->p90 = sorted[rank - 1];
	out->max = sorted[m - 1];
	free(sorted);
	return 0;
}

int kg_grade_fadgi4(const kg_de_summary *s)
{
	return s->n > 0 && s->mean < KG_FADGI4_MEAN_BELOW && s->p90 < KG_FADGI4_P90_BELOW;
}

int kg_grade_iso19264_a(const kg_de_summary *s)
{
	return s->n > 0 && s->mean <= KG_ISO19264_A_MEAN_AT_MOST &&
	       s->max <= KG_ISO19264_A_MAX_AT_MOST;
}
