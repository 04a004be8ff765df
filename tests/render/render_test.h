/* Helpers of the render tests: scenes written to a temporary folder, rendered into
 * memory, and the mean XYZ over a rectangle. */
#ifndef KG_RENDER_TEST_H
#define KG_RENDER_TEST_H

#include <stdarg.h>
#include <string.h>
#include <unistd.h>

#include "kg_render.h"
#include "kg_test.h"

static char render_test_dir[256];

/* A temporary folder (removed with its files by render_test_cleanup), or skip when
 * Embree was not built. */
static inline void render_test_init(void)
{
	if (!kg_render_available())
		kg_test_skip("the renderer was built without Embree 3 (libembree-dev)");
	snprintf(render_test_dir, sizeof(render_test_dir), "/tmp/kg-render-test-XXXXXX");
	if (!mkdtemp(render_test_dir)) {
		perror("mkdtemp");
		exit(1);
	}
}

static inline void render_test_cleanup(void)
{
	char cmd[300];
	snprintf(cmd, sizeof(cmd), "rm -rf '%s'", render_test_dir);
	if (system(cmd) != 0)
		fprintf(stderr, "could not remove %s\n", render_test_dir);
}

/* Write text (printf format) to DIR/name; returns the path (static buffer per call
 * site is not enough, so the caller's buffer). */
static inline void render_test_write(char *path, size_t size, const char *name,
                                     const char *fmt, ...) KG_PRINTF(4, 5);
static inline void render_test_write(char *path, size_t size, const char *name,
                                     const char *fmt, ...)
{
	snprintf(path, size, "%s/%s", render_test_dir, name);
	FILE *fp = fopen(path, "w");
	if (!fp) {
		perror(path);
		exit(1);
	}
	va_list ap;
	va_start(ap, fmt);
	vfprintf(fp, fmt, ap);
	va_end(ap);
	fclose(fp);
}

/* Load and render a scene; exits the test on failure. */
static inline kg_image *render_test_render(const char *scene_path, const char *material,
                                           const kg_render_options *opt, kg_xyz *white)
{
	kg_err err = {{0}};
	kg_scene *s = NULL;
	kg_image *img = NULL;
	int ret = kg_scene_load(scene_path, &s, &err);
	if (!ret && material)
		ret = kg_scene_set_material(s, material, &err);
	if (!ret)
		ret = kg_render(s, opt, &img, NULL, &err);
	if (ret) {
		fprintf(stderr, "rendering %s: %s\n", scene_path, err.msg);
		exit(1);
	}
	if (white)
		*white = kg_scene_white(s);
	kg_scene_free(&s);
	return img;
}

/* Mean XYZ over the pixels x0 <= x < x1, y0 <= y < y1. */
static inline kg_xyz render_test_mean(const kg_image *img, int x0, int y0, int x1, int y1)
{
	double acc[3] = {0, 0, 0};
	for (int y = y0; y < y1; y++)
		for (int x = x0; x < x1; x++)
			for (int c = 0; c < 3; c++)
				acc[c] += img->data[3 * ((size_t)y * (size_t)img->width + (size_t)x) + c];
	double n = (double)(x1 - x0) * (y1 - y0);
	return (kg_xyz){acc[0] / n, acc[1] / n, acc[2] / n};
}

#endif
