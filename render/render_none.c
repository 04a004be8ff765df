/* The renderer without Embree: scenes still load and check; rendering is refused. */
#include <string.h>

#include "kg_render.h"

int kg_render_available(void)
{
	return 0;
}

int kg_render(const kg_scene *s, const kg_render_options *opt, kg_image **xyz,
              kg_render_stats *stats, kg_err *err)
{
	return kg_fail(err, KG_ENOTSUP, "rendering needs Embree 3, which was not found when "
	               "kogei was built (Debian: libembree-dev)");
}

int kg_render_full(const kg_scene *s, const kg_render_options *opt, kg_render_result *out,
                   kg_render_stats *stats, kg_err *err)
{
	if (out)
		memset(out, 0, sizeof(*out));
	return kg_render(s, opt, NULL, stats, err);
}
