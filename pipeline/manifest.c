/* kogei process, each object's IIIF Presentation 3.0 manifest (OUTDIR/<object>/
 * manifest.json): the object's record as label and metadata, one Canvas of the master's
 * size painted with the access copy (access.c) through its IIIF Image API 3 service,
 * and the label map as a second painting annotation a viewer shows as a layer, its
 * legend in the metadata. Ids are --iiif-base and --files-base joined with the
 * object's path, or relative to the manifest when they are not given (and the
 * manifest says so). docs/formats.md, "IIIF manifest". */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline_private.h"

#define IIIF_CONTEXT "http://iiif.io/api/presentation/3/context.json"

/* base + "/" + rest, or rest alone without a base; the base's trailing '/' dropped. */
static char *url_join(const char *base, const char *rest)
{
	char *out = NULL;
	if (!base)
		return strdup(rest);
	size_t n = strlen(base);
	while (n && base[n - 1] == '/')
		n--;
	if (asprintf(&out, "%.*s/%s", (int)n, base, rest) < 0)
		return NULL;
	return out;
}

static json_t *lang(const char *code, const char *text)
{
	return json_pack("{s:[s]}", code, text ? text : "");
}

static void meta_add(json_t *md, const char *label, const char *code, json_t *values)
{
	json_t *value = json_object();
	json_object_set_new(value, code, values);
	json_array_append_new(md, json_pack("{s:o, s:o}", "label", lang("en", label), "value",
	                                    value));
}

static const char *record(const json_t *identity, const char *key)
{
	return json_string_value(json_object_get(json_object_get(identity, "record"), key));
}

/* The label layer: dir/labels.hdr (the pixels' classes) in its classes' colours, at
 * the canvas's size or reduced by a whole factor to at most LAYER_MAX pixels on the
 * long side (nearest pixel), no margin, no legend, as dir/labels_layer.png: an image
 * that lies on the canvas pixel for pixel (labels.png is a figure with a margin). */
#define LAYER_MAX 4096
static int label_layer(proc *p, const char *dir, int *lw, int *lh)
{
	char *hdr = kg_path_join(dir, "labels.hdr"), *png = kg_path_join(dir, "labels_layer.png");
	kg_envi *e = NULL;
	float *row = NULL;
	unsigned char *rgb = NULL;
	int ret = hdr && png ? kg_envi_open(hdr, &e, p->err) : kg_fail(p->err, KG_ENOMEM,
	                                                                "out of memory");
	if (!ret && (e->meta.bands != 1 || e->meta.classes < 1 || !e->meta.class_lookup))
		ret = kg_fail(p->err, KG_EINVAL, "%s: expected a classification with its colours",
		              hdr);
	int W = ret ? 0 : e->meta.samples, H = ret ? 0 : e->meta.lines;
	int step = 1;
	while ((W + step - 1) / step > LAYER_MAX || (H + step - 1) / step > LAYER_MAX)
		step++;
	int w = (W + step - 1) / step, h = (H + step - 1) / step;
	if (!ret && (!(row = malloc((size_t)W * sizeof(float))) ||
	             !(rgb = malloc((size_t)w * (size_t)h * 3))))
		ret = kg_fail(p->err, KG_ENOMEM, "out of memory");
	for (int y = 0; y < h && !ret; y++) {
		ret = kg_envi_read(e, 0, y * step, W, 1, KG_LAYOUT_BIP, row, p->err);
		for (int x = 0; x < w && !ret; x++) {
			float v = row[x * step];
			int c = v >= 0 && v < (float)e->meta.classes ? (int)v : 0;
			memcpy(rgb + ((size_t)y * (size_t)w + (size_t)x) * 3, e->meta.class_lookup + 3 * c,
			       3);
		}
	}
	if (!ret)
		ret = kg_png_write_rgb8(png, rgb, w, h, p->err);
	if (!ret) {
		*lw = w;
		*lh = h;
	}
	kg_envi_close(&e);
	free(row);
	free(rgb);
	free(hdr);
	free(png);
	return ret;
}

/* The materials found, largest share first, as "copper: 41.2 %"; the legend of the
 * label map as "copper: #b87333". */
static void classes_meta(const json_t *object, json_t *found, json_t *legend)
{
	const json_t *classes = json_object_get(object, "classes");
	size_t n = json_array_size(classes);
	int *order = n ? malloc(n * sizeof(int)) : NULL;
	if (n && !order)
		return;
	for (size_t i = 0; i < n; i++)
		order[i] = (int)i;
	for (size_t i = 1; i < n; i++) /* insertion sort by share, descending */
		for (size_t j = i; j > 0; j--) {
			double a = json_number_value(
				json_object_get(json_array_get(classes, (size_t)order[j - 1]), "fraction"));
			double b = json_number_value(
				json_object_get(json_array_get(classes, (size_t)order[j]), "fraction"));
			if (b <= a)
				break;
			int t = order[j];
			order[j] = order[j - 1];
			order[j - 1] = t;
		}
	for (size_t i = 0; i < n; i++) {
		const json_t *c = json_array_get(classes, (size_t)order[i]);
		const char *name = json_string_value(json_object_get(c, "name"));
		double frac = json_number_value(json_object_get(c, "fraction"));
		const json_t *col = json_object_get(c, "colour");
		char line[256];
		if (!name)
			continue;
		if (strcmp(name, "background") && strcmp(name, "unknown")) {
			snprintf(line, sizeof(line), "%s: %.1f %%", name, 100 * frac);
			json_array_append_new(found, json_string(line));
		}
		if (json_array_size(col) == 3) {
			snprintf(line, sizeof(line), "%s: #%02x%02x%02x (%.1f %%)", name,
			         (unsigned)json_integer_value(json_array_get(col, 0)) & 255,
			         (unsigned)json_integer_value(json_array_get(col, 1)) & 255,
			         (unsigned)json_integer_value(json_array_get(col, 2)) & 255, 100 * frac);
			json_array_append_new(legend, json_string(line));
		}
	}
	free(order);
}

static json_t *metadata(const json_t *identity, const json_t *object)
{
	json_t *md = json_array(), *found = json_array(), *legend = json_array();
	const char *acc = record(identity, "accession");
	meta_add(md, "Accession", "none", json_pack("[s]", acc ? acc : "not recorded"));
	classes_meta(object, found, legend);
	meta_add(md, "Materials found (share of the image)", "en", found);
	const json_t *col = json_object_get(identity, "colour_accuracy");
	char line[256];
	if (json_is_object(col))
		snprintf(line, sizeof(line), "mean %.2f, 90th percentile %.2f, max %.2f (%s, %d "
		         "patches, D50)", json_number_value(json_object_get(col, "de00_mean")),
		         json_number_value(json_object_get(col, "de00_p90")),
		         json_number_value(json_object_get(col, "de00_max")),
		         json_string_value(json_object_get(col, "basis")),
		         (int)json_integer_value(json_object_get(col, "patches")));
	else
		snprintf(line, sizeof(line), "not measured");
	meta_add(md, "Held-out colour error (CIEDE2000)", "en", json_pack("[s]", line));
	const char *date = record(identity, "date");
	const char *captured = json_string_value(json_object_get(identity, "captured"));
	meta_add(md, "Date", "none", json_pack("[s]", date ? date : captured ? captured
	                                                                      : "not recorded"));
	if (date && captured)
		meta_add(md, "Captured", "none", json_pack("[s]", captured));
	const char *op = record(identity, "operator");
	meta_add(md, "Operator", "none", json_pack("[s]", op ? op : "not recorded"));
	meta_add(md, "Label map legend (class: colour, share)", "en", legend);
	return md;
}

int proc_manifest(proc *p, const proc_capture *c, const char *dir, const json_t *identity,
                  json_t *object)
{
	json_object_set_new(object, "manifest", json_null());
	const json_t *access = json_object_get(object, "access");
	if (!json_is_object(access))
		return 0; /* no image to show: access.c said why */
	const kg_process_options *o = p->o;
	char *path = kg_path_join(dir, "manifest.json");
	char rel[512];
	int lw = 0, lh = 0;
	int ret = label_layer(p, dir, &lw, &lh);
	if (ret) {
		kg_err_prefix(p->err, "%s: labels_layer.png: ", c->name);
		free(path);
		return ret;
	}
	/* ids: absolute under the bases, else relative to the manifest (in <object>/) */
	snprintf(rel, sizeof(rel), "%s/manifest.json", c->name);
	char *id = o->files_base ? url_join(o->files_base, rel) : strdup("manifest.json");
	snprintf(rel, sizeof(rel), "%s/access.tif", c->name);
	char *service = o->iiif_base ? url_join(o->iiif_base, rel) : strdup("access.tif");
	snprintf(rel, sizeof(rel), "%s/labels_layer.png", c->name);
	char *lurl = o->files_base ? url_join(o->files_base, rel) : strdup("labels_layer.png");
	int v2 = o->iiif_image_api && !strcmp(o->iiif_image_api, "2");
	char *full = service ? url_join(service, v2 ? "full/full/0/default.jpg"
	                                            : "full/max/0/default.jpg") : NULL;
	char *objurl = o->files_base ? url_join(o->files_base, c->name) : NULL;
	char *canvas = url_join(objurl, "canvas/1");
	char *page = canvas ? url_join(canvas, "page/1") : NULL;
	char *a_image = canvas ? url_join(canvas, "annotation/image") : NULL;
	char *a_labels = canvas ? url_join(canvas, "annotation/labels") : NULL;
	ret = (objurl || !o->files_base) && path && id && service && lurl && full && canvas &&
	              page && a_image && a_labels
	          ? 0 : kg_fail(p->err, KG_ENOMEM, "out of memory");
	json_t *m = NULL;
	const char *title = record(identity, "title");
	int w = (int)json_integer_value(json_object_get(access, "width"));
	int h = (int)json_integer_value(json_object_get(access, "height"));
	char note[1024];
	if (o->iiif_base && o->files_base)
		snprintf(note, sizeof(note), "Object %s of session %s, processed by kogei: the "
		         "photograph as a colour-managed sRGB access copy, and the material label map "
		         "as a second layer.", c->name,
		         json_string_value(json_object_get(identity, "session")));
	else
		snprintf(note, sizeof(note), "Object %s of session %s, processed by kogei. Its ids "
		         "are relative to this manifest's location (%s%s not given to kogei "
		         "process): a viewer resolves them against the manifest's URL, and the "
		         "image service must be published at <this folder>/access.tif or the "
		         "manifest written again with the bases.", c->name,
		         json_string_value(json_object_get(identity, "session")),
		         !o->iiif_base ? "--iiif-base" : "",
		         !o->iiif_base && !o->files_base ? " and --files-base"
		                                         : !o->files_base ? "--files-base" : "");
	if (!ret) {
		json_t *annos = json_array();
		json_array_append_new(
			annos,
			json_pack("{s:s, s:s, s:s, s:o, s:{s:s, s:s, s:s, s:i, s:i, s:[o]}, s:s}", "id",
			          a_image, "type", "Annotation", "motivation", "painting", "label",
			          lang("en", "Photograph (sRGB access copy)"), "body", "id", full, "type",
			          "Image", "format", "image/jpeg", "width", w, "height", h, "service",
			          /* Image API 2 services keep their JSON-LD keys (Presentation 3,
			           * "Linking Properties", service) */
			          v2 ? json_pack("{s:s, s:s, s:s}", "@id", service, "@type",
			                         "ImageService2", "profile", "level1")
			             : json_pack("{s:s, s:s, s:s}", "id", service, "type",
			                         "ImageService3", "profile", "level1"),
			          "target", canvas));
		/* the label map, a layer a viewer can show or hide */
		json_array_append_new(
			annos, json_pack("{s:s, s:s, s:s, s:o, s:{s:s, s:s, s:s, s:i, s:i}, s:s}", "id",
			                 a_labels, "type", "Annotation", "motivation", "painting",
			                 "label", lang("en", "Material labels (legend in the metadata)"),
			                 "body", "id", lurl, "type", "Image", "format", "image/png",
			                 "width", lw, "height", lh, "target", canvas));
		m = json_pack("{s:s, s:s, s:s, s:o, s:o, s:o, s:[{s:s, s:s, s:o, s:i, s:i, "
		              "s:[{s:s, s:s, s:o}]}]}",
		              "@context", IIIF_CONTEXT, "id", id, "type", "Manifest", "label",
		              lang("none", title ? title : c->name), "summary", lang("en", note),
		              "metadata", metadata(identity, object), "items", "id", canvas, "type",
		              "Canvas", "label", lang("none", c->name), "width", w, "height", h,
		              "items", "id", page, "type", "AnnotationPage", "items", annos);
		if (!m)
			ret = kg_fail(p->err, KG_ENOMEM, "out of memory");
	}
	if (!ret && (ret = kg_json_write(m, path, p->err)))
		kg_err_prefix(p->err, "%s: ", c->name);
	if (!ret) {
		char layer[300];
		snprintf(layer, sizeof(layer), "%s/labels_layer.png", c->name);
		snprintf(rel, sizeof(rel), "%s/manifest.json", c->name);
		json_object_set_new(object, "manifest",
		                    json_pack("{s:s, s:s, s:s, s:s, s:s, s:s*}", "path", rel, "id", id,
		                              "image_service", service, "service_type",
		                              v2 ? "ImageService2" : "ImageService3", "label_layer",
		                              layer,
		                              "note", o->iiif_base && o->files_base ? NULL : note));
		if (!o->iiif_base || !o->files_base)
			proc_progress(p, "%s: manifest.json with relative ids (no %s): see its summary",
			              c->name, !o->iiif_base ? "--iiif-base" : "--files-base");
	}
	json_decref(m);
	free(path);
	free(id);
	free(service);
	free(lurl);
	free(full);
	free(objurl);
	free(canvas);
	free(page);
	free(a_image);
	free(a_labels);
	return ret;
}
