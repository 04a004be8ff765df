/* The exposure helper's chart measure (kg_pipeline.h). */
#include <math.h>

#include "kg_pipeline.h"

/* The level of the brightest patch: the largest channel of any sampled patch. */
int kg_chart_brightest_patch(void *user, const kg_image *frame, double *level, kg_err *err)
{
	kg_chart_level *m = user;
	kg_chart_result *r = NULL;
	int ret = kg_chart_detect(m->layout, frame, &m->opt, &r, err);
	if (ret)
		return ret == KG_ENOENT ? KG_ENOENT : ret;
	double best = -INFINITY;
	for (int i = 0; i < r->npatches; i++) {
		const kg_chart_sample *p = &r->patches[i];
		if (p->flags & KG_CHART_FLAG_REJECTED)
			continue;
		for (int c = 0; c < 3; c++)
			if (isfinite(p->rgb[c]) && p->rgb[c] > best)
				best = p->rgb[c];
	}
	kg_chart_result_free(&r);
	if (!isfinite(best))
		return kg_fail(err, KG_ENOENT, "chart %s found but no patch could be sampled",
		               m->layout->name);
	*level = best;
	return 0;
}
