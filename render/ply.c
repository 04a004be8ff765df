/* Placeholder until the PLY loader lands. */
#include <stdlib.h>

#include "kg_mesh.h"

int kg_ply_load_mem(const void *data, size_t len, const char *name, kg_mesh **out,
                    kg_err *err)
{
	return kg_fail(err, KG_ENOTSUP, "%s: the PLY loader is not implemented yet", name);
}

int kg_ply_load(const char *path, kg_mesh **out, kg_err *err)
{
	return kg_ply_load_mem(NULL, 0, path, out, err);
}

void kg_mesh_free(kg_mesh **m)
{
}
