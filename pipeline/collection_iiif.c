/* kogei collection, OUT/collection-manifest.json: a IIIF Presentation 3.0 Collection of
 * the manifests kogei process wrote for the done entries' objects (manifest.c), in the
 * list's order. Its ids are under --files-base (the plan's files_base) or relative to
 * OUT, and then it says so. docs/formats.md, "A collection". */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "collection_private.h"

int coll_url_join(const char *base, const char *name, char **url)
{
	size_t n = strlen(base);
	while (n && base[n - 1] == '/')
		n--;
	*url = NULL;
	return asprintf(url, "%.*s/%s", (int)n, base, name) < 0 ? -1 : 0;
}

/* id of rel (a path below OUT): under base, or rel itself. */
static json_t *id_of(const char *base, const char *rel)
{
	char *url = NULL;
	if (!base)
		return json_string(rel);
	if (coll_url_join(base, rel, &url))
		return NULL;
	json_t *s = json_string(url);
	free(url);
	return s;
}

int coll_iiif_write(const char *out, const json_t *plan, const json_t *record, kg_err *err)
{
	const char *base = json_string_value(json_object_get(plan, "files_base"));
	json_t *items = json_array();
	size_t i, k;
	const json_t *e, *o;
	json_array_foreach(json_object_get(record, "entries"), i, e)
	{
		const char *name = json_string_value(json_object_get(e, "name"));
		json_array_foreach(json_object_get(e, "objects"), k, o)
		{
			const char *man = json_string_value(json_object_get(o, "manifest"));
			const char *title = json_string_value(json_object_get(o, "title"));
			const char *obj = json_string_value(json_object_get(o, "name"));
			char *rel = NULL, label[512];
			if (!name || !man || asprintf(&rel, "%s/%s", name, man) < 0)
				continue;
			snprintf(label, sizeof(label), "%s%s%s", title ? title : name,
			         title ? "" : " / ", title ? "" : obj ? obj : "");
			json_t *it = json_pack("{s:o, s:s, s:{s:[s]}}", "id", id_of(base, rel), "type",
			                       "Manifest", "label", "none", label);
			if (it)
				json_array_append_new(items, it);
			free(rel);
		}
	}
	const char *list = json_string_value(json_object_get(plan, "list"));
	json_t *c = json_pack("{s:s, s:o, s:s, s:{s:[s]}, s:o}", "@context",
	                      "http://iiif.io/api/presentation/3/context.json", "id",
	                      id_of(base, "collection-manifest.json"), "type", "Collection",
	                      "label", "none", list ? list : "kogei collection", "items", items);
	if (c && !base)
		json_object_set_new(c, "summary",
		                    json_pack("{s:[s]}", "en", "Ids relative to this file's location "
		                              "(kogei collection run without --files-base): a viewer "
		                              "resolves them against its URL."));
	char *path = kg_path_join(out, "collection-manifest.json");
	int ret = c && path ? kg_json_write(c, path, err) : kg_fail(err, KG_ENOMEM, "out of memory");
	json_decref(c);
	free(path);
	return ret;
}
