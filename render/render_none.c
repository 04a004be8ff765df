/* The renderer without Embree: scenes still load and check; rendering is refused. */
#include <string.h>

#include "render_private.h"

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

int rd_scene_triangle_materials(const kg_scene *s, int threads, uint16_t **out, kg_err *err)
{
	(void)threads;
	if (s->assign == RD_ASSIGN_LABEL_MAP) {
		*out = NULL;
		return kg_fail(err, KG_ENOTSUP, "%s: projecting its label map onto the mesh needs "
		               "Embree 3, which was not found when kogei was built (Debian: "
		               "libembree-dev)", s->path);
	}
	return rd_scene_triangle_materials_plain(s, out, err);
}
