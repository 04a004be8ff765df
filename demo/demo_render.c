/* `kogei demo`, the rendering step: the demo object (render/kg_mesh.h, the tsuba) in
 * each material of the paper's Fig. 13 under a studio environment and a D65 light,
 * rendered with the offline renderer and laid out as one labelled contact sheet. */
#include <cairo.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "demo_private.h"
#include "kg_render.h"

#define SKY_W 512
#define SKY_H 256
#define TILE_W 320
#define TILE_H 240
#define TILE_SPP 16
#define LABEL_H 28
#define SHEET_COLS 4

/* Fig. 13 of the paper: the five shibuichi, gold, copper and lacquer. */
static const char *const fig13[] = {
	"shibuichi-nami", "shibuichi-shiro", "shibuichi-jo", "shibuichi-nami-uchisanbu",
	"shibuichi-nami-sotosanbu", "gold", "copper", "urushi",
};
#define FIG13_N ((int)(sizeof(fig13) / sizeof(fig13[0])))

/* An equirectangular studio (linear sRGB, +z up): a sky from pale blue at the zenith
 * to white at the horizon, two soft boxes that metals reflect as highlights, and a
 * dark warm floor. */
static int write_sky(const char *path, kg_err *err)
{
	kg_image *img = NULL;
	int ret = kg_image_new(SKY_W, SKY_H, 3, &img, err);
	if (ret)
		return ret;
	static const struct {
		double az, el, size, level;
	} boxes[] = {{-50.0, 35.0, 18.0, 8.0}, {140.0, 20.0, 25.0, 3.0}};
	for (int y = 0; y < SKY_H; y++) {
		double el = 90.0 - 180.0 * (y + 0.5) / SKY_H; /* elevation, degrees */
		for (int x = 0; x < SKY_W; x++) {
			double az = 360.0 * (x + 0.5) / SKY_W; /* from +x towards +y */
			float *p = img->data + 3 * ((size_t)y * SKY_W + (size_t)x);
			double rgb[3];
			if (el >= 0.0) {
				double t = el / 90.0;
				rgb[0] = 0.55 - 0.3 * t, rgb[1] = 0.58 - 0.25 * t, rgb[2] = 0.65 - 0.15 * t;
			} else {
				double t = fmin(1.0, -el / 30.0);
				double v = 0.12 - 0.08 * t;
				rgb[0] = v * 1.1, rgb[1] = v, rgb[2] = v * 0.85;
			}
			for (size_t b = 0; b < sizeof(boxes) / sizeof(boxes[0]); b++) {
				double da = fmod(fabs(az - fmod(boxes[b].az + 360.0, 360.0)), 360.0);
				da = fmin(da, 360.0 - da) * cos(el * M_PI / 180.0);
				double de = el - boxes[b].el;
				double r = sqrt(da * da + de * de) / boxes[b].size;
				if (r < 1.0)
					for (int c = 0; c < 3; c++)
						rgb[c] += boxes[b].level * (1.0 - r * r);
			}
			for (int c = 0; c < 3; c++)
				p[c] = (float)rgb[c];
		}
	}
	ret = kg_image_write_tiff(img, path, 32, err);
	kg_image_free(&img);
	return ret;
}

static int write_scene(const char *path, kg_err *err)
{
	json_t *scene = json_pack(
		"{s:s, s:s, s:{s:s, s:i}, s:{s:s}, s:{s:s, s:[f,f,f], s:f}, s:{s:s, s:s, s:f}, "
		"s:{s:[f,f,f], s:[f,f,f], s:f, s:i, s:i}, s:{s:i, s:i, s:i, s:i}}",
		"format", "kogei-scene/1",
		"note", "Written by kogei demo: the demo object (a tsuba) in one material under a "
		        "studio environment (render_sky.tif) and a D65 light. Try: kogei render "
		        "--scene render_scene.json --material copper -o copper.png",
		"mesh", "generator", "tsuba", "segments", 192,
		"materials", "material", fig13[0],
		"light", "illuminant", "D65", "direction", -0.6, -1.0, 1.6, "intensity", 1.2,
		"environment", "illuminant", "D65", "image", "render_sky.tif", "intensity", 0.6,
		"camera", "position", 0.0, -2.2, 1.85, "look_at", 0.0, 0.0, -0.05, "fov_deg", 36.0,
		"width", TILE_W, "height", TILE_H,
		"sampling", "spp", TILE_SPP, "wavelengths", 4, "bounces", 4, "seed", 1);
	if (!scene)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	int ret = kg_json_write(scene, path, err);
	json_decref(scene);
	return ret;
}

static cairo_status_t write_stream(void *closure, const unsigned char *data,
                                   unsigned int length)
{
	return fwrite(data, 1, length, closure) == length ? CAIRO_STATUS_SUCCESS
	                                                  : CAIRO_STATUS_WRITE_ERROR;
}

/* Tiles (PNG files) in a grid, each with its material's name below. */
static int write_sheet(const char *path, char *const *tiles, kg_err *err)
{
	int rows = (FIG13_N + SHEET_COLS - 1) / SHEET_COLS;
	int W = SHEET_COLS * TILE_W, H = rows * (TILE_H + LABEL_H) + 36;
	cairo_surface_t *sheet = cairo_image_surface_create(CAIRO_FORMAT_RGB24, W, H);
	cairo_t *cr = cairo_create(sheet);
	cairo_set_source_rgb(cr, 1, 1, 1);
	cairo_paint(cr);
	cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL,
	                       CAIRO_FONT_WEIGHT_NORMAL);
	cairo_set_source_rgb(cr, 0, 0, 0);
	cairo_set_font_size(cr, 16);
	cairo_move_to(cr, 10, 24);
	cairo_show_text(cr, "Fig. 13: the demo object in each material (spectral render, "
	                    "Embree; D65 light and studio environment)");
	int ret = 0;
	for (int i = 0; i < FIG13_N && !ret; i++) {
		cairo_surface_t *tile = cairo_image_surface_create_from_png(tiles[i]);
		if (cairo_surface_status(tile) != CAIRO_STATUS_SUCCESS) {
			ret = kg_fail(err, KG_EIO, "%s: cannot read the rendered tile", tiles[i]);
		} else {
			double x = (i % SHEET_COLS) * TILE_W, y = 36 + (i / SHEET_COLS) * (TILE_H + LABEL_H);
			cairo_set_source_surface(cr, tile, x, y);
			cairo_paint(cr);
			cairo_text_extents_t ext;
			cairo_set_source_rgb(cr, 0, 0, 0);
			cairo_set_font_size(cr, 15);
			cairo_text_extents(cr, fig13[i], &ext);
			cairo_move_to(cr, x + (TILE_W - ext.width) / 2 - ext.x_bearing, y + TILE_H + 20);
			cairo_show_text(cr, fig13[i]);
		}
		cairo_surface_destroy(tile);
	}
	cairo_destroy(cr);
	kg_outfile o;
	if (!ret && !(ret = kg_outfile_open(&o, path, 0, err))) {
		if (cairo_surface_write_to_png_stream(sheet, write_stream, o.fp) !=
		    CAIRO_STATUS_SUCCESS) {
			kg_outfile_abort(&o);
			ret = kg_fail(err, KG_EIO, "%s: cannot write the PNG", path);
		} else {
			ret = kg_outfile_commit(&o, err);
		}
	}
	cairo_surface_destroy(sheet);
	return ret;
}

int demo_render(demo_ctx *d)
{
	if (!kg_render_available()) {
		printf("  skipped: kogei was built without Embree 3 (libembree-dev)\n");
		return 0;
	}
	char *sky = demo_path(d, "render_sky.tif");
	char *scene_path = demo_path(d, "render_scene.json");
	char *tile_dir = demo_path(d, "render");
	char *sheet = demo_path(d, "render_fig13.png");
	char *tiles[FIG13_N] = {0};
	kg_scene *scene = NULL;
	int ret = sky && scene_path && tile_dir && sheet ? 0 : kg_fail(&d->err, KG_ENOMEM,
	                                                                "out of memory");
	if (!ret && !(ret = write_sky(sky, &d->err)))
		demo_wrote(d, sky, "studio environment (equirectangular float TIFF)");
	if (!ret && !(ret = write_scene(scene_path, &d->err)))
		demo_wrote(d, scene_path, "the render scene (kogei render --scene ...)");
	if (!ret)
		ret = kg_mkdir_p(tile_dir, &d->err);
	if (!ret)
		ret = kg_scene_load(scene_path, &scene, &d->err);
	for (int i = 0; i < FIG13_N && !ret; i++) {
		char name[96];
		snprintf(name, sizeof(name), "%s.png", fig13[i]);
		if (!(tiles[i] = kg_path_join(tile_dir, name))) {
			ret = kg_fail(&d->err, KG_ENOMEM, "out of memory");
			break;
		}
		kg_image *xyz = NULL;
		kg_render_stats st;
		ret = kg_scene_set_material(scene, fig13[i], &d->err);
		if (!ret)
			ret = kg_render(scene, NULL, &xyz, &st, &d->err);
		if (!ret)
			ret = kg_render_write_png(xyz, kg_scene_white(scene), tiles[i], &d->err);
		if (!ret)
			printf("  rendered %-26s %d x %d, %d spp, %.2f s\n", fig13[i], st.width,
			       st.height, st.spp, st.render_s);
		kg_image_free(&xyz);
	}
	if (!ret && !(ret = write_sheet(sheet, tiles, &d->err))) {
		demo_wrote(d, tile_dir, "one render per material (PNG)");
		demo_wrote(d, sheet, "Fig. 13 contact sheet: the object in each material");
	}
	kg_scene_free(&scene);
	for (int i = 0; i < FIG13_N; i++)
		free(tiles[i]);
	free(sky);
	free(scene_path);
	free(tile_dir);
	free(sheet);
	return ret;
}

/* ---- the re-render from the estimated labels (step 7) ----------------------------- */

void demo_rerender_result_clear(demo_rerender_result *r)
{
	kg_image_free(&r->truth);
	kg_image_free(&r->estimate);
	free(r->de00);
	memset(r, 0, sizeof(*r));
}

/* A byte-for-byte copy of src at dst (atomic). */
static int copy_file(const char *src, const char *dst, kg_err *err)
{
	char *buf = NULL;
	size_t len = 0;
	kg_outfile o;
	int ret = kg_read_file(src, &buf, &len, err);
	if (!ret)
		ret = kg_outfile_open(&o, dst, 0, err);
	if (!ret) {
		if (fwrite(buf, 1, len, o.fp) != len) {
			kg_outfile_abort(&o);
			ret = kg_fail(err, KG_EIO, "%s: write failed", dst);
		} else {
			ret = kg_outfile_commit(&o, err);
		}
	}
	free(buf);
	return ret;
}

/* The object's scene (root, the fixture as read) under D65 at the re-render's size
 * and sampling, each region in material[k] (library index, d->region_* order), as
 * DIR/rerender/<name>.json. The environment's image is copied beside it. */
static int write_rerender_scene(demo_ctx *d, json_t *root, const int *material,
                                const char *note, const char *path)
{
	json_t *ids = json_object(), *env = kg_json_find(root, "environment");
	json_t *camera = kg_json_find(root, "camera"), *sampling = json_object();
	json_t *materials = kg_json_find(root, "materials");
	if (!ids || !sampling || !json_is_object(env) || !json_is_object(camera) ||
	    !json_is_object(materials)) {
		json_decref(ids);
		json_decref(sampling);
		return kg_fail(&d->err, KG_EINVAL, "%s: expected the keys materials, environment "
		               "and camera", DEMO_OBJECT_SCENE);
	}
	for (int k = 0; k < d->nregions; k++) {
		char key[16];
		snprintf(key, sizeof(key), "%d", d->region_id[k]);
		json_object_set_new(ids, key, json_string(kg_material_library_get(d->lib,
		                                                                   material[k])->name));
	}
	json_object_set_new(root, "note", json_string(note));
	json_object_set_new(materials, "face_ids", ids);
	json_object_set_new(env, "illuminant", json_string("D65"));
	json_object_set_new(camera, "width", json_integer(DEMO_RERENDER_WIDTH));
	json_object_set_new(camera, "height", json_integer(DEMO_RERENDER_HEIGHT));
	json_object_set_new(sampling, "spp", json_integer(DEMO_RERENDER_SPP));
	json_object_set_new(sampling, "wavelengths", json_string("all"));
	json_object_set_new(sampling, "bounces", json_integer(4));
	json_object_set_new(sampling, "seed", json_integer(1));
	json_object_set_new(root, "sampling", sampling);
	return kg_json_write(root, path, &d->err);
}

static int by_value(const void *a, const void *b)
{
	float x = *(const float *)a, y = *(const float *)b;
	return (x > y) - (x < y);
}

int demo_rerender(demo_ctx *d, const int *estimate_material, demo_rerender_result *out)
{
	memset(out, 0, sizeof(*out));
	if (!kg_render_available()) {
		printf("  re-render skipped: kogei was built without Embree 3 (libembree-dev)\n");
		return 0;
	}
	char *fixture = kg_data_path(DEMO_OBJECT_SCENE);
	char *dir = demo_path(d, "rerender");
	char *truth_json = dir ? kg_path_join(dir, "truth.json") : NULL;
	char *est_json = dir ? kg_path_join(dir, "estimate.json") : NULL;
	char *truth_png = dir ? kg_path_join(dir, "truth.png") : NULL;
	char *est_png = dir ? kg_path_join(dir, "estimate.png") : NULL;
	char *de_tif = dir ? kg_path_join(dir, "de00.tif") : NULL;
	char *env_src = NULL, *env_dst = NULL;
	json_t *root[2] = {NULL, NULL};
	kg_scene *scene[2] = {NULL, NULL};
	kg_render_result res[2];
	memset(res, 0, sizeof(res));
	float *sorted = NULL;
	struct timespec t0, t1;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	int ret = fixture && dir && truth_json && est_json && truth_png && est_png && de_tif
	              ? kg_mkdir_p(dir, &d->err)
	              : kg_fail(&d->err, KG_ENOMEM, "out of memory");
	for (int k = 0; k < 2 && !ret; k++)
		ret = kg_json_load(fixture, &root[k], &d->err);
	/* the environment's image, beside the scenes (paths are relative to a scene) */
	const char *env_name = ret ? NULL
	                           : json_string_value(kg_json_find(root[0], "environment.image"));
	if (!ret && env_name) {
		const char *slash = strrchr(fixture, '/');
		size_t n = slash ? (size_t)(slash - fixture) : 0;
		char *fixture_dir = strndup(fixture, n ? n : 1);
		const char *base = strrchr(env_name, '/') ? strrchr(env_name, '/') + 1 : env_name;
		env_src = fixture_dir ? kg_path_join(n ? fixture_dir : ".", env_name) : NULL;
		env_dst = kg_path_join(dir, base);
		free(fixture_dir);
		ret = env_src && env_dst ? copy_file(env_src, env_dst, &d->err)
		                         : kg_fail(&d->err, KG_ENOMEM, "out of memory");
		/* base points into root[0]'s string, which the first set replaces */
		for (int k = 1; !ret && k >= 0; k--)
			json_object_set_new(kg_json_find(root[k], "environment"), "image", json_string(base));
	}
	if (!ret)
		ret = write_rerender_scene(d, root[0], d->region_material,
		                           "Written by kogei demo: the object of fixtures/"
		                           DEMO_OBJECT_SCENE " under D65, each region in its "
		                           "true material.", truth_json);
	if (!ret)
		ret = write_rerender_scene(d, root[1], estimate_material,
		                           "Written by kogei demo: the object of fixtures/"
		                           DEMO_OBJECT_SCENE " under D65, each region in the "
		                           "material its estimated labels give (summary.md, "
		                           "Re-render).", est_json);
	const char *jsons[2] = {truth_json, est_json}, *pngs[2] = {truth_png, est_png};
	for (int k = 0; k < 2 && !ret; k++) {
		kg_render_options opt = {.want_truth = k == 0};
		kg_render_stats st;
		ret = kg_scene_load(jsons[k], &scene[k], &d->err);
		if (!ret)
			ret = kg_render_full(scene[k], &opt, &res[k], &st, &d->err);
		if (!ret)
			ret = kg_render_write_png(res[k].image, kg_scene_white(scene[k]), pngs[k], &d->err);
		if (!ret)
			printf("  rendered %-9s %d x %d, %d spp, all bands, %.2f s\n",
			       k ? "estimate" : "truth", st.width, st.height, st.spp, st.render_s);
	}
	size_t n = (size_t)DEMO_RERENDER_WIDTH * DEMO_RERENDER_HEIGHT;
	kg_image *de = NULL;
	if (!ret && (res[0].image->width != DEMO_RERENDER_WIDTH ||
	             res[1].image->width != DEMO_RERENDER_WIDTH ||
	             res[0].image->height != DEMO_RERENDER_HEIGHT ||
	             res[1].image->height != DEMO_RERENDER_HEIGHT))
		ret = kg_fail(&d->err, KG_EINVAL, "the re-renders are not %dx%d",
		              DEMO_RERENDER_WIDTH, DEMO_RERENDER_HEIGHT);
	if (!ret)
		ret = kg_image_new(DEMO_RERENDER_WIDTH, DEMO_RERENDER_HEIGHT, 1, &de, &d->err);
	if (!ret && !(sorted = malloc(sizeof(float) * n)))
		ret = kg_fail(&d->err, KG_ENOMEM, "out of memory");
	if (!ret) {
		/* CIELAB of both relative to the scene's white (D65, Y = 1 on both), per pixel
		 * of the object as the truth render hit it */
		kg_xyz white = kg_scene_white(scene[0]);
		double sum = 0;
		for (size_t i = 0; i < n; i++) {
			if (!res[0].truth->label[i]) {
				de->data[i] = NAN;
				continue;
			}
			const float *a = res[0].image->data + 3 * i, *b = res[1].image->data + 3 * i;
			kg_lab la = kg_xyz_to_lab((kg_xyz){a[0], a[1], a[2]}, white);
			kg_lab lb = kg_xyz_to_lab((kg_xyz){b[0], b[1], b[2]}, white);
			double e = kg_ciede2000(la, lb);
			de->data[i] = (float)e;
			sorted[out->pixels++] = (float)e;
			sum += e;
		}
		if (out->pixels) {
			qsort(sorted, (size_t)out->pixels, sizeof(float), by_value);
			out->de00_mean = sum / (double)out->pixels;
			out->de00_p90 = sorted[(size_t)ceil(0.9 * (double)out->pixels) - 1];
			out->de00_max = sorted[out->pixels - 1];
		}
		ret = kg_image_write_tiff(de, de_tif, 32, &d->err);
	}
	clock_gettime(CLOCK_MONOTONIC, &t1);
	if (!ret) {
		out->available = 1;
		out->width = DEMO_RERENDER_WIDTH;
		out->height = DEMO_RERENDER_HEIGHT;
		out->truth = res[0].image;
		out->estimate = res[1].image;
		res[0].image = res[1].image = NULL;
		out->de00 = malloc(sizeof(float) * n);
		if (!out->de00)
			ret = kg_fail(&d->err, KG_ENOMEM, "out of memory");
		else
			memcpy(out->de00, de->data, sizeof(float) * n);
		out->seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
	}
	if (!ret) {
		printf("  CIEDE2000 between them over the %ld object pixels: mean %.2f, 90th "
		       "percentile %.2f, largest %.1f\n",
		       out->pixels, out->de00_mean, out->de00_p90, out->de00_max);
		demo_wrote(d, truth_json, "the object's scene under D65 in its true materials");
		demo_wrote(d, est_json, "the same in the materials the labels give");
		demo_wrote(d, truth_png, "its render from the truth");
		demo_wrote(d, est_png, "its re-render from the estimated labels");
		demo_wrote(d, de_tif, "CIEDE2000 between the two per pixel (float TIFF, NaN off "
		                      "the object)");
	} else {
		demo_rerender_result_clear(out);
	}
	kg_image_free(&de);
	free(sorted);
	for (int k = 0; k < 2; k++) {
		kg_render_result_clear(&res[k]);
		kg_scene_free(&scene[k]);
		json_decref(root[k]);
	}
	free(fixture);
	free(dir);
	free(truth_json);
	free(est_json);
	free(truth_png);
	free(est_png);
	free(de_tif);
	free(env_src);
	free(env_dst);
	return ret;
}
