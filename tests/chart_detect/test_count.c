/* The sampler's counted statistics (chart_count.c) against its selections
 * (chart_select.c: radix selection and quickselect): the same location, spread and
 * count above a level, bit for bit, for integer codes over 255 and 65535 and their
 * halves and quarters, sums of three codes as the sampler forms them, one value and a
 * few, ties, and ranges from a few codes to two far-apart clusters (a region across
 * two patches), all counted through one set of buffers, so that every count starts
 * from the previous one's cleared bins. A range too wide for its values is refused
 * (selection instead). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "chart_detect_private.h"
#include "kg_test.h"

static unsigned long long rng = 88172645463325252ULL;

static double uniform(void)
{
	rng ^= rng << 13;
	rng ^= rng >> 7;
	rng ^= rng << 17;
	return (double)(rng >> 11) / 9007199254740992.0;
}

static double gauss(void)
{
	double u = uniform(), v = uniform();
	return sqrt(-2 * log(u + 1e-300)) * cos(2 * M_PI * v);
}

static int same(double a, double b)
{
	return a == b || (isnan(a) && isnan(b));
}

/* A code near mean (in codes) with spread sd, in 0 .. top. */
static long code(double mean, double sd, long top)
{
	long c = lround(mean + sd * gauss());
	return c < 0 ? 0 : c > top ? top : c;
}

enum { MAXN = 50000 };

int main(void)
{
	static float v[MAXN], a[MAXN], work[MAXN];
	static uint32_t scratch[MAXN];
	sample_buffers b;
	memset(&b, 0, sizeof(b));
	CHECK(chart_buffers_reserve(&b, MAXN, 1) == 0, "buffers");
	static const long sizes[] = {1, 2, 3, 7, 64, 500, 1000, 5000, 41000};
	/* scale: codes of 8 and 16 bits, and quarters of 16-bit codes (demosaiced) */
	static const float scales[] = {255.0f, 65535.0f, 4 * 65535.0f};
	long counted = 0, wide = 0, cases = 0;
	for (int round = 0; round < 6; round++)
		for (int si = 0; si < 3; si++)
			for (size_t ni = 0; ni < sizeof(sizes) / sizeof(sizes[0]); ni++) {
				float scale = scales[si];
				long n = sizes[ni], top = (long)scale;
				/* round 0-1: one patch; 2-3: two far-apart clusters; 4-5: sums of three
				 * values of one or two clusters */
				int clusters = round % 2 ? 2 : 1, sums = round >= 4;
				if (round == 2 || round == 3)
					clusters = 2;
				double m0 = top * (0.05 + 0.3 * uniform()), m1 = top * (0.6 + 0.35 * uniform());
				double sd = round == 0 ? 0.3 : top * 0.002 * (1 + 4 * uniform());
				for (long i = 0; i < n; i++) {
					double m = clusters == 2 && uniform() < 0.4 ? m1 : m0;
					if (sums) {
						/* as sample_patch: three floats added in double, then rounded */
						double s = 0;
						for (int c = 0; c < 3; c++)
							s += (float)code(m, sd, top) / scale;
						v[i] = (float)s;
					} else {
						v[i] = (float)code(m, sd, top) / scale;
					}
				}
				for (int stat = 0; stat < 2; stat++)
					for (int qi = 0; qi < 2; qi++) {
						kg_chart_detect_options opt;
						kg_chart_detect_options_default(&opt);
						opt.statistic = stat ? KG_CHART_TRIMMED_MEAN : KG_CHART_MEDIAN;
						double quantum = qi && !sums ? 1.0 / scale : 0;
						double loc[3], sigma[3];
						memcpy(a, v, (size_t)n * sizeof(float));
						chart_robust_stats(a, work, scratch, n, &opt, quantum, 1, &loc[0],
						                   &sigma[0]);
						memcpy(a, v, (size_t)n * sizeof(float));
						chart_robust_stats(a, work, scratch, n, &opt, quantum, 0, &loc[1],
						                   &sigma[1]);
						CHECK(same(loc[0], loc[1]) && same(sigma[0], sigma[1]),
						      "round %d, scale %g, n %ld: radix %.9g %.9g, quickselect %.9g %.9g",
						      round, scale, n, loc[0], sigma[0], loc[1], sigma[1]);
						cases++;
						if (chart_count_values(v, n, scale, &b))
							continue;
						counted++;
						wide += b.nb > 4 * n + 65536;
						chart_counted_stats(&b, n, &opt, quantum, &loc[2], &sigma[2]);
						CHECK(same(loc[2], loc[0]) && same(sigma[2], sigma[0]),
						      "round %d, scale %g, n %ld, %s%s: counted %.9g %.9g, selected "
						      "%.9g %.9g", round, scale, n, stat ? "trimmed mean" : "median",
						      quantum > 0 ? ", grouped" : "", loc[2], sigma[2], loc[0],
						      sigma[0]);
						/* the glare count above a level: at a value, between values, above all */
						double levels[3] = {v[0], loc[0] + 0.5 * sigma[0] + 1e-7, 2.0};
						for (int k = 0; k < 3; k++) {
							long direct = 0;
							for (long i = 0; i < n; i++)
								direct += v[i] > levels[k];
							long c = chart_counted_above(&b, levels[k]);
							CHECK(c == direct, "round %d, n %ld: %ld above %.9g counted, %ld by "
							      "looking", round, n, c, levels[k], direct);
						}
					}
			}
	/* values spread over far more keys than 64 a value: refused, selection decides */
	for (long i = 0; i < 100; i++)
		v[i] = (float)(i % 2 ? 65535 : 0) / 65535.0f;
	CHECK(chart_count_values(v, 100, 65535.0f, &b) == -1,
	      "0 and 1 in 16-bit codes, 100 values: counted over %ld bins", b.nb);
	/* and the buffers still count afterwards */
	for (long i = 0; i < 100; i++)
		v[i] = (float)(1000 + i % 7) / 65535.0f;
	CHECK(chart_count_values(v, 100, 65535.0f, &b) == 0, "7 codes not counted");
	printf("%ld cases, %ld counted (%ld over ranges wider than 4 keys a value)\n", cases,
	       counted, wide);
	CHECK(counted > cases / 2, "only %ld of %ld cases counted", counted, cases);
	CHECK(wide > 0, "no range wider than 4 keys a value was counted");
	chart_buffers_free(&b);
	return kg_test_done("chart-detect-count");
}
