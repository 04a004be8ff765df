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
	kg_outfile o;
	int ret = kg_outfile_open(&o, path, 0, err);
	if (ret)
		return ret;
	fprintf(o.fp,
	        "{\n"
	        "  \"format\": \"kogei-scene/1\",\n"
	        "  \"note\": \"Written by kogei demo: the demo object (a tsuba) in one material "
	        "under a studio environment (render_sky.tif) and a D65 light. Try: kogei render "
	        "--scene render_scene.json --material copper -o copper.png\",\n"
	        "  \"mesh\": {\"generator\": \"tsuba\", \"segments\": 192},\n"
	        "  \"materials\": {\"material\": \"%s\"},\n"
	        "  \"light\": {\"illuminant\": \"D65\", \"direction\": [-0.6, -1, 1.6], "
	        "\"intensity\": 1.2},\n"
	        "  \"environment\": {\"illuminant\": \"D65\", \"image\": \"render_sky.tif\", "
	        "\"intensity\": 0.6},\n"
	        "  \"camera\": {\"position\": [0, -2.2, 1.85], \"look_at\": [0, 0, -0.05], "
	        "\"fov_deg\": 36, \"width\": %d, \"height\": %d},\n"
	        "  \"sampling\": {\"spp\": %d, \"wavelengths\": 4, \"bounces\": 4, \"seed\": 1}\n"
	        "}\n", fig13[0], TILE_W, TILE_H, TILE_SPP);
	return kg_outfile_commit(&o, err);
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
