/* Fuzz targets for the loaders that take a path: the material library, chart layouts,
 * scenes, session manifests, camera recordings and images. One binary per loader:
 * KG_FUZZ_LOADER names its entry in the table below. Each input is written to a file
 * in the driver's per-run directory and loaded from there.
 *
 * The session loaders run inside a copy of fixtures/demo/session (KG_FUZZ_SESSION)
 * whose frame and capture files are sparse files of the recorded sizes (the
 * validators check sizes, not contents); the input replaces one file of it.
 *
 * Invariants checked on every input: a refusal is a negative code with a terminated,
 * non-empty message, and no object; a success gives an object, and everything is freed
 * (the sanitizers see leaks). */
#define _XOPEN_SOURCE 700
#include <fcntl.h>
#include <ftw.h>
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fuzz_driver.h"
#include "envi.h"
#include "image.h"
#include "json.h"
#include "kg_acquire.h"
#include "kg_calib.h"
#include "kg_optics.h"
#include "kg_render.h"
#include "mjpeg.h"
#include "raw.h"

static const char target_name[] = "fuzz-" KG_FUZZ_LOADER;

static void require(int cond, const char *what)
{
	kg_fuzz_require(target_name, cond, what);
}

/* Each loader returns its code and frees what it made; obj says whether it made one. */
static int load_material(const char *path, int *obj, kg_err *err)
{
	kg_material_library *lib = NULL;
	int r = kg_material_library_load(path, &lib, err);
	*obj = lib != NULL;
	kg_material_library_free(&lib);
	return r;
}

static int load_chart_layout(const char *path, int *obj, kg_err *err)
{
	kg_chart_layout *l = NULL;
	int r = kg_chart_layout_load(path, &l, err);
	*obj = l != NULL;
	kg_chart_layout_free(&l);
	return r;
}

static int load_scene(const char *path, int *obj, kg_err *err)
{
	kg_scene *s = NULL;
	int r = kg_scene_load(path, &s, err);
	*obj = s != NULL;
	kg_scene_free(&s);
	return r;
}

static int load_camera(const char *path, int *obj, kg_err *err)
{
	kg_camera_calib *cam = NULL;
	int r = kg_camera_load(path, &cam, err);
	*obj = cam != NULL;
	kg_camera_calib_free(&cam);
	return r;
}

static int load_reference(const char *path, int *obj, kg_err *err)
{
	kg_reference *ref = NULL;
	int r = kg_reference_load(path, &ref, err);
	*obj = ref != NULL;
	kg_reference_free(&ref);
	return r;
}

/* The header is the input; its data file (cube.img) is a sparse file large enough
 * for the seeds, so the reader reads a corner window of it too. */
#define ENVI_DATA_BYTES (128ll << 20)

static int load_envi(const char *path, int *obj, kg_err *err)
{
	static int data_made;
	if (!data_made) {
		char data[256];
		snprintf(data, sizeof(data), "%s/cube.img", kg_fuzz_dir());
		int fd = open(data, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
		require(fd >= 0 && ftruncate(fd, ENVI_DATA_BYTES) == 0, "the ENVI data file is made");
		close(fd);
		data_made = 1;
	}
	kg_envi *e = NULL;
	int r = kg_envi_open(path, &e, err);
	*obj = e != NULL;
	if (r == 0) {
		int w = e->meta.samples < 4 ? e->meta.samples : 4;
		int h = e->meta.lines < 4 ? e->meta.lines : 4;
		float *px = malloc((size_t)w * (size_t)h * (size_t)e->meta.bands * sizeof(float));
		require(px != NULL, "memory for a window");
		r = kg_envi_read(e, 0, 0, w, h, KG_LAYOUT_BIP, px, err);
		free(px);
	}
	kg_envi_close(&e);
	return r;
}

/* Images up to this many pixels (64 Kpix) are read whole (kg_image_read); larger ones
 * through the row reader for their first rows only: decoding a legitimately large
 * image is slow, not a fault, and would starve the fuzzer of inputs. */
#define FUZZ_IMAGE_WHOLE_PIXELS (1L << 16)

static int load_image(const char *path, int *obj, kg_err *err)
{
	kg_image_rows *rows = NULL;
	int r = kg_image_rows_open(path, &rows, err);
	*obj = rows != NULL;
	if (r)
		return r;
	const kg_image *h = kg_image_rows_header(rows);
	require(h->width >= 1 && h->height >= 1 && !h->data, "a header without pixels");
	if ((long)h->width * h->height <= FUZZ_IMAGE_WHOLE_PIXELS) {
		kg_image_rows_free(&rows);
		kg_image *img = NULL;
		r = kg_image_read(path, &img, err);
		*obj = img != NULL;
		kg_image_free(&img);
		return r;
	}
	int n = (int)(FUZZ_IMAGE_WHOLE_PIXELS / h->width);
	n = n < 1 ? 1 : n > h->height ? h->height : n;
	float *band = malloc(sizeof(float) * (size_t)n * (size_t)h->width * (size_t)h->channels);
	require(band != NULL, "memory for a band of rows");
	r = kg_image_rows_read(rows, n, band, err);
	*obj = r == 0; /* the rows read: the object a caller gets */
	free(band);
	kg_image_rows_free(&rows);
	return r;
}

static int load_session(const char *path, int *obj, kg_err *err)
{
	json_t *root = NULL;
	int r = kg_json_load(path, &root, err);
	if (r == 0)
		r = kg_session_manifest_validate(path, root, err);
	json_decref(root);
	*obj = r == 0;
	return r;
}

static int load_recording(const char *path, int *obj, kg_err *err)
{
	(void)path;
	char dir[256];
	snprintf(dir, sizeof(dir), "%s/session", kg_fuzz_dir());
	int r = kg_camera_recording_validate(dir, err);
	*obj = r == 0;
	return r;
}

/* MJPEG frames come from memory, not files: the frame size is the seed's
 * (tests/fuzz/corpus_loaders/chart_48x36.jpg). */
static int decode_mjpeg(const uint8_t *data, size_t size, int *obj, kg_err *err)
{
	uint8_t *rgb = malloc(48 * 36 * 3);
	require(rgb != NULL, "memory for a frame");
	int r = kg_mjpeg_decode(data, size, 48, 36, rgb, err);
	free(rgb);
	*obj = r == 0;
	return r;
}

/* A camera raw file (core/raw.c, LibRaw): from the file (files:) and from memory
 * (gphoto2:), which must both refuse or both decode to the same samples. */
static int load_raw(const char *path, int *obj, kg_err *err)
{
	kg_image *a = NULL, *b = NULL;
	kg_raw_meta m;
	int r = kg_raw_read(path, &a, &m, err);
	char *bytes = NULL;
	size_t len = 0;
	kg_err e2 = { { 0 } };
	if (kg_read_file(path, &bytes, &len, &e2) == 0) {
		int r2 = len ? kg_raw_read_memory(bytes, len, "fuzz input", &b, NULL, &e2) : KG_EINVAL;
		require((r == 0) == (r2 == 0), "file and memory decoding disagree");
		if (!r && !r2)
			require(a->width == b->width && a->height == b->height &&
			                !memcmp(a->data, b->data,
			                        sizeof(float) * (size_t)a->width * (size_t)a->height),
			        "file and memory decode to different samples");
		if (r2)
			require(r2 < 0 && e2.msg[0] && !b, "memory refusal without a message");
	}
	free(bytes);
	*obj = a != NULL;
	if (a)
		require(a->channels == 1 && a->cfa && strlen(a->cfa) == 4, "a raw image without its CFA");
	kg_image_free(&a);
	kg_image_free(&b);
	return r;
}

typedef struct loader {
	const char *name;
	const char *leaf; /* where the input goes in the per-run directory */
	int session;      /* the leaf lies inside the copied session */
	int (*load)(const char *path, int *obj, kg_err *err);
	int (*decode)(const uint8_t *data, size_t size, int *obj, kg_err *err); /* no leaf */
} loader;

static const loader loaders[] = {
	{ "material", "materials.json", 0, load_material, NULL },
	{ "chart-layout", "layout.json", 0, load_chart_layout, NULL },
	{ "chart-cht", "layout.cht", 0, load_chart_layout, NULL },
	{ "scene", "scene.json", 0, load_scene, NULL },
	{ "image", "image", 0, load_image, NULL },
	{ "raw", "shot.dng", 0, load_raw, NULL },
	{ "camera", "camera.json", 0, load_camera, NULL },
	{ "reference", "reference.json", 0, load_reference, NULL },
	{ "envi", "cube.hdr", 0, load_envi, NULL },
	{ "session", "session/session.json", 1, load_session, NULL },
	{ "recording-index", "session/frames/index.jsonl", 1, load_recording, NULL },
	{ "recording-camera", "session/frames/camera.json", 1, load_recording, NULL },
	{ "mjpeg", NULL, 0, NULL, decode_mjpeg },
};

/* ---- the session copy -------------------------------------------------------------- */

static int copy_entry(const char *path, const struct stat *st, int flag, struct FTW *ftw)
{
	(void)ftw;
	char dst[4096];
	snprintf(dst, sizeof(dst), "%s/session%s", kg_fuzz_dir(), path + strlen(KG_FUZZ_SESSION));
	if (flag == FTW_D)
		return mkdir(dst, 0700) == 0 ? 0 : -1;
	if (flag != FTW_F)
		return 0;
	const char *ext = strrchr(path, '.');
	if (ext && (strcmp(ext, ".json") == 0 || strcmp(ext, ".jsonl") == 0)) {
		char *text;
		size_t len;
		kg_err err = { { 0 } };
		if (kg_read_file(path, &text, &len, &err) != 0)
			return -1;
		kg_fuzz_write(dst + strlen(kg_fuzz_dir()) + 1, (const uint8_t *)text, len);
		free(text);
		return 0;
	}
	int fd = open(dst, O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
	int ok = fd >= 0 && ftruncate(fd, st->st_size) == 0;
	if (fd >= 0)
		close(fd);
	return ok ? 0 : -1;
}

/* The manifest's capture outputs (captures/<name>/...) are made by the demo's script,
 * not stored: each becomes an empty file. */
static void touch_files(const json_t *j)
{
	const char *key;
	const json_t *v;
	size_t i;
	if (json_is_object(j)) {
		json_object_foreach((json_t *)j, key, v) {
			if (strcmp(key, "file") == 0 && json_is_string(v)) {
				char leaf[512], path[1024];
				snprintf(leaf, sizeof(leaf), "session/%s", json_string_value(v));
				snprintf(path, sizeof(path), "%s/%s", kg_fuzz_dir(), leaf);
				if (access(path, F_OK) != 0 && strncmp(json_string_value(v), "captures/", 9) == 0)
					kg_fuzz_write(leaf, (const uint8_t *)"", 0);
			} else
				touch_files(v);
		}
	} else if (json_is_array(j))
		json_array_foreach(j, i, v) touch_files(v);
}

static void copy_session(void)
{
	kg_err err = { { 0 } };
	json_t *root = NULL;
	if (nftw(KG_FUZZ_SESSION, copy_entry, 16, FTW_PHYS) != 0 ||
	    kg_json_load(KG_FUZZ_SESSION "/session.json", &root, &err) != 0) {
		fprintf(stderr, "%s: cannot copy %s %s\n", target_name, KG_FUZZ_SESSION, err.msg);
		exit(1);
	}
	touch_files(root);
	json_decref(root);
}

/* ---- the target ------------------------------------------------------------------------ */

static const loader *chosen(void)
{
	static const loader *l;
	if (!l) {
		for (size_t i = 0; i < sizeof(loaders) / sizeof(loaders[0]); i++)
			if (strcmp(loaders[i].name, KG_FUZZ_LOADER) == 0)
				l = &loaders[i];
		require(l != NULL, "KG_FUZZ_LOADER names a loader");
		if (l->session)
			copy_session();
	}
	return l;
}

static int fuzz_loader_run(const uint8_t *data, size_t size)
{
	const loader *l = chosen();
	kg_err err = { { 0 } };
	int obj = 0;
	int r = l->leaf ? l->load(kg_fuzz_write(l->leaf, data, size), &obj, &err)
	                : l->decode(data, size, &obj, &err);
	if (r != 0) {
		require(r < 0, "a refusal is a negative code");
		require(!obj, "no object on failure");
		require(memchr(err.msg, '\0', sizeof(err.msg)) != NULL, "message is terminated");
		require(err.msg[0] != '\0', "a refusal has a message");
	} else
		require(obj, "an object on success");
	return r != 0;
}

static const char *const words[] = {
	"{", "}", "[", "]", ",", ":", "\"", "\\u0000", "\\", "null", "true", "false", "0",
	"-1", "1e999", "-0", "1.5", "4294967296", "9223372036854775808", "\"\"",
	"\"x\": 1", "\"format\": ", "\"file\": \"../x\"", "\"name\": ", "\"id\": ", "\n",
	"\"/etc/passwd\"", "\"a/../../b\"", "[[[[[[[[", "\xff", "IHDR", "IDAT", "IEND",
	"II*", "MM", "BOXES ", "BOX_SHRINK ", "X ", "Y ", "D ", "\nEXPECTED XYZ ",
	"_ ", "\xff\xd8", "\xff\xd9", "\xff\xc0", "\xff\xc4", "\xff\xda", "\xff\xdb",
};

static const kg_fuzz_target fuzz_loader = {
	.name = target_name,
	.run = fuzz_loader_run,
	.words = words,
	.nwords = sizeof(words) / sizeof(words[0]),
	.structural = "{}[],:\"\\ -.e0\n\xff",
	.mutations = 500,
};

KG_FUZZ_TARGET(fuzz_loader)
