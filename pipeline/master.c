/* kogei process, the master: each object's reflectance cube rendered under D50 (or
 * --master-illuminant) into --master-space as OUTDIR/<object>/master.tif, a 16-bit
 * RGB TIFF with the space's ICC profile embedded (core/icc.c, LittleCMS). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "icc.h"
#include "pipeline_private.h"

static const char *space_arg(const proc *p)
{
	return p->o->master_space ? p->o->master_space : "ecirgb-v2";
}

static const char *ill_arg(const proc *p)
{
	return p->o->master_illuminant ? p->o->master_illuminant : "D50";
}

int proc_master_check(proc *p)
{
	kg_icc_space s;
	int ret = kg_icc_space_parse(space_arg(p), &s, p->err);
	if (ret) {
		kg_err_prefix(p->err, "--master-space: ");
		return ret;
	}
	kg_illuminant *ill = NULL;
	ret = kg_illuminant_lookup(ill_arg(p), &ill, p->err);
	if (ret)
		kg_err_prefix(p->err, "--master-illuminant: ");
	kg_illuminant_free(&ill);
	return ret;
}

int proc_master(proc *p, const proc_capture *c, const char *dir, const char *cube,
                json_t *object)
{
	kg_icc_space s;
	json_t *warnings = json_object_get(object, "warnings");
	json_object_set_new(object, "master", json_null());
	if (kg_icc_space_parse(space_arg(p), &s, p->err))
		return KG_EINVAL; /* checked before: not reached */
	if (s == KG_ICC_NONE)
		return 0;
	if (!kg_icc_available()) {
		proc_warn(p, warnings, "%s: no master.tif: kogei was built without LittleCMS "
		          "(-Dlcms)", c->name);
		return 0;
	}
	if (!cube || !strcmp(proc_cube_name(p), "weights")) {
		proc_warn(p, warnings, "%s: no master.tif: it is rendered from the reflectance cube, "
		          "and --cube %s writes none", c->name, proc_cube_name(p));
		return 0;
	}
	kg_illuminant *ill = NULL;
	int ret = kg_illuminant_lookup(ill_arg(p), &ill, p->err);
	char *path = ret ? NULL : kg_path_join(dir, "master.tif");
	if (!ret && !path)
		ret = kg_fail(p->err, KG_ENOMEM, "out of memory");
	long clipped = 0;
	if (!ret) {
		proc_progress(p, "%s: master.tif (%s, %s)", c->name, kg_icc_space_description(s),
		              ill->name);
		ret = kg_master_write(cube, ill, s, path, &clipped, p->err);
	}
	if (!ret) {
		char rel[300];
		snprintf(rel, sizeof(rel), "%s/master.tif", c->name);
		json_object_set_new(object, "master",
		                    json_pack("{s:s, s:s, s:s, s:s, s:s, s:I}", "path", rel, "space",
		                              kg_icc_space_name(s), "profile",
		                              kg_icc_space_description(s), "illuminant", ill_arg(p),
		                              "intent", "relative colorimetric", "clipped_pixels",
		                              (json_int_t)clipped));
		if (clipped > 0)
			proc_warn(p, warnings, "%s: master.tif: %ld pixels outside %s, clipped",
			          c->name, clipped, kg_icc_space_description(s));
	}
	kg_illuminant_free(&ill);
	free(path);
	return ret;
}
