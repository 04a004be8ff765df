/* kogei process, the access copy: each object's master.tif as OUTDIR/<object>/access.tif,
 * the copy an image server (IIPImage) serves through IIIF: sRGB, 8-bit, tiled 256 x 256
 * and pyramidal (each level half the one before, down to one tile), JPEG tiles at
 * --access-quality (or deflate), the object's identity in XMP as the master's
 * (identity.c). The pyramid is libvips's (vips tiffsave --tile --pyramid); without
 * libvips (-Dvips) there is no access copy, and the run says so. Also the options of
 * the access copy and the manifests, one table for the command line and the console. */
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_config.h"
#include "pipeline_private.h"

#if HAVE_VIPS
#include <vips/vips.h>
#endif

/* ---- the options ----------------------------------------------------------------------- */

#define OPT(field) offsetof(kg_process_options, field)

static const kg_opt_spec access_specs[] = {
	{"access-compression", 0, "jpeg|deflate", KG_OPT_STRING, OPT(access_compression), 0,
	 "the tiles of each object's access.tif (the IIIF access copy): jpeg (the default) or "
	 "deflate (lossless, several times larger)"},
	{"access-quality", 0, "Q", KG_OPT_STRING, OPT(access_quality), 0,
	 "the JPEG quality of access.tif's tiles, 1-100 (default 90)"},
	{"iiif-base", 0, "URL", KG_OPT_STRING, OPT(iiif_base), 0,
	 "the IIIF Image API base under which an image server serves OUTDIR (e.g. "
	 "https://images.example.org/iiif/objects): each manifest.json's image service is "
	 "URL/<object>/access.tif (default: ids relative to the manifest, and it says so)"},
	{"iiif-image-api", 0, "3|2", KG_OPT_STRING, OPT(iiif_image_api), 0,
	 "the IIIF Image API version of that image server, the manifests' service type: 3 "
	 "(ImageService3, the default: iipsrv 1.2 and later) or 2 (ImageService2: Debian "
	 "12's iipsrv 1.1)"},
	{"files-base", 0, "URL", KG_OPT_STRING, OPT(files_base), 0,
	 "the URL at which OUTDIR's files are published: the manifest's own id and its label "
	 "map (default: relative to the manifest)"},
};

const kg_opt_table kg_process_access_table = {
	.synopsis = "kogei process ... [--access-compression jpeg|deflate] [--access-quality Q]\n"
	            "              [--iiif-base URL] [--iiif-image-api 3|2] [--files-base URL]",
	.description = "The IIIF access copy (access.tif) and manifest.json of each object.",
	.specs = access_specs,
	.nspecs = (int)(sizeof(access_specs) / sizeof(access_specs[0])),
};

/* A base URL: http:// or https://, printable ASCII without blanks, quotes, '<', '>',
 * '\\', '?' or '#' (it is joined with paths). */
static int url_ok(const char *u)
{
	if (strncmp(u, "http://", 7) && strncmp(u, "https://", 8))
		return 0;
	const char *host = u + (u[4] == 's' ? 8 : 7);
	if (!*host || *host == '/')
		return 0;
	for (const char *c = u; *c; c++)
		if (*c <= ' ' || *c >= 127 || strchr("\"'<>\\?#`{}|^", *c))
			return 0;
	return 1;
}

int kg_process_access_check(const kg_process_options *o, kg_err *err)
{
	kg_check_arg(o, err);
	const char *c = o->access_compression;
	if (c && strcmp(c, "jpeg") && strcmp(c, "deflate"))
		return kg_fail(err, KG_EINVAL, "--access-compression %.64s: expected jpeg or deflate",
		               c);
	if (o->access_quality) {
		char *end;
		long q = strtol(o->access_quality, &end, 10);
		if (end == o->access_quality || *end || q < 1 || q > 100)
			return kg_fail(err, KG_EINVAL, "--access-quality %.64s: expected a whole number "
			               "1-100", o->access_quality);
	}
	const char *api = o->iiif_image_api;
	if (api && strcmp(api, "2") && strcmp(api, "3"))
		return kg_fail(err, KG_EINVAL, "--iiif-image-api %.64s: expected 3 or 2", api);
	const char *names[2] = {"--iiif-base", "--files-base"};
	const char *urls[2] = {o->iiif_base, o->files_base};
	for (int i = 0; i < 2; i++)
		if (urls[i] && (!url_ok(urls[i]) || strlen(urls[i]) > 1024))
			return kg_fail(err, KG_EINVAL, "%s %.128s: expected an http:// or https:// URL "
			               "(up to 1024 characters, no blanks, quotes, '?' or '#')", names[i],
			               urls[i]);
	return 0;
}

int proc_access_quality(const proc *p)
{
	return p->o->access_quality ? atoi(p->o->access_quality) : 90;
}

const char *proc_access_compression(const proc *p)
{
	return p->o->access_compression ? p->o->access_compression : "jpeg";
}

int kg_access_available(void)
{
	return HAVE_VIPS;
}

/* ---- the copy -------------------------------------------------------------------------- */

#if HAVE_VIPS
static void vips_end(void)
{
	vips_shutdown();
}

/* libvips once per process, shut down at exit (its caches and threads, so the leak
 * checker sees none). */
static int vips_ready(kg_err *err)
{
	static int state; /* 0 not yet, 1 ready, -1 failed */
	if (!state) {
		state = VIPS_INIT("kogei") == 0 ? 1 : -1;
		if (state > 0) {
			atexit(vips_end);
			/* no operation cache: each copy is made once */
			vips_cache_set_max(0);
		}
	}
	if (state < 0)
		return kg_fail(err, KG_EIO, "libvips: %s", vips_error_buffer());
	return 0;
}

/* A libvips failure, with what it said. */
static int vips_failed(kg_err *err, const char *what)
{
	const char *msg = vips_error_buffer();
	size_t n = strlen(msg);
	while (n && msg[n - 1] == '\n')
		n--;
	kg_fail(err, KG_EIO, "%s: %.*s", what, (int)n, msg);
	vips_error_clear();
	return KG_EIO;
}

/* master (an RGB TIFF with its ICC profile) as an 8-bit sRGB pyramid at path. */
static int write_pyramid(proc *p, const char *master, const char *path, const char *xmp,
                         size_t xmp_len, const char *description, int *levels, int *w, int *h)
{
	VipsImage *in = NULL, *srgb = NULL;
	int ret = 0;
	if (p->o->threads > 0)
		vips_concurrency_set(p->o->threads);
	if (vips_tiffload(master, &in, "access", VIPS_ACCESS_SEQUENTIAL, NULL))
		return vips_failed(p->err, master);
	/* through the master's own profile to sRGB, relative colorimetric, 8 bits */
	if (vips_icc_transform(in, &srgb, "srgb", "embedded", TRUE, "intent",
	                       VIPS_INTENT_RELATIVE, "depth", 8, NULL))
		ret = vips_failed(p->err, master);
	if (!ret) {
		/* the identity, as the master carries it; no other metadata of the master */
		vips_image_set_blob_copy(srgb, VIPS_META_XMP_NAME, xmp, xmp_len);
		if (vips_image_get_typeof(srgb, VIPS_META_EXIF_NAME))
			vips_image_remove(srgb, VIPS_META_EXIF_NAME);
		if (vips_image_get_typeof(srgb, VIPS_META_IPTC_NAME))
			vips_image_remove(srgb, VIPS_META_IPTC_NAME);
		if (description)
			vips_image_set_string(srgb, VIPS_META_IMAGEDESCRIPTION, description);
		else if (vips_image_get_typeof(srgb, VIPS_META_IMAGEDESCRIPTION))
			vips_image_remove(srgb, VIPS_META_IMAGEDESCRIPTION);
	}
	int deflate = !strcmp(proc_access_compression(p), "deflate");
	if (!ret && vips_tiffsave(srgb, path, "tile", TRUE, "tile_width", 256, "tile_height", 256,
	                          "pyramid", TRUE, "compression",
	                          deflate ? VIPS_FOREIGN_TIFF_COMPRESSION_DEFLATE
	                                  : VIPS_FOREIGN_TIFF_COMPRESSION_JPEG,
	                          "Q", proc_access_quality(p), "predictor",
	                          deflate ? VIPS_FOREIGN_TIFF_PREDICTOR_HORIZONTAL
	                                  : VIPS_FOREIGN_TIFF_PREDICTOR_NONE,
	                          "region_shrink", VIPS_REGION_SHRINK_MEAN, NULL))
		ret = vips_failed(p->err, path);
	if (!ret) {
		*w = vips_image_get_width(srgb);
		*h = vips_image_get_height(srgb);
		/* the levels as written: the file's pages */
		VipsImage *back = vips_image_new_from_file(path, NULL);
		if (!back)
			ret = vips_failed(p->err, path);
		else {
			*levels = vips_image_get_n_pages(back);
			g_object_unref(back);
		}
	}
	if (srgb)
		g_object_unref(srgb);
	if (in)
		g_object_unref(in);
	return ret;
}
#endif

int proc_access(proc *p, const proc_capture *c, const char *dir, const json_t *identity,
                json_t *object)
{
	json_t *warnings = json_object_get(object, "warnings");
	json_object_set_new(object, "access", json_null());
#if !HAVE_VIPS
	(void)dir;
	(void)identity;
	proc_warn(p, warnings, "%s: no access.tif (the IIIF access copy) and no manifest.json: "
	          "kogei was built without libvips (-Dvips)", c->name);
	return 0;
#else
	if (!json_is_object(json_object_get(object, "master"))) {
		proc_warn(p, warnings, "%s: no access.tif (the IIIF access copy): it is made from "
		          "master.tif, which this run did not write", c->name);
		return 0;
	}
	char *master = kg_path_join(dir, "master.tif"), *path = kg_path_join(dir, "access.tif");
	char *xmp = NULL;
	size_t xmp_len = 0;
	int ret = master && path ? 0 : kg_fail(p->err, KG_ENOMEM, "out of memory");
	if (!ret)
		ret = vips_ready(p->err);
	if (!ret && identity)
		ret = proc_identity_xmp(identity, &xmp, &xmp_len, p->err);
	int levels = 0, w = 0, h = 0;
	if (!ret) {
		proc_progress(p, "%s: access.tif (sRGB, 8-bit, 256 x 256 tiles, %s)", c->name,
		              proc_access_compression(p));
		ret = write_pyramid(p, master, path, xmp, xmp_len,
		                    identity ? proc_identity_description(identity) : NULL, &levels, &w,
		                    &h);
	}
	if (ret)
		kg_err_prefix(p->err, "%s: access.tif: ", c->name);
	if (!ret) {
		char rel[300];
		snprintf(rel, sizeof(rel), "%s/access.tif", c->name);
		int deflate = !strcmp(proc_access_compression(p), "deflate");
		json_object_set_new(object, "access",
		                    json_pack("{s:s, s:i, s:i, s:s, s:i, s:i, s:i, s:s, s:o}", "path",
		                              rel, "width", w, "height", h, "space", "sRGB", "bits", 8,
		                              "tile", 256, "levels", levels, "compression",
		                              proc_access_compression(p), "quality",
		                              deflate ? json_null()
		                                      : json_integer(proc_access_quality(p))));
	}
	free(xmp);
	free(master);
	free(path);
	return ret;
#endif
}
