/* Image sizes outside what a detection stage supports are refused before the stage
 * runs, with a message naming the size and the limit: libapriltag reads out of bounds
 * when a decimated side is below 3 px (a side of 4 px or less at decimate 2) and
 * asserts on a decimated side of 32768 px or more. Tiny and huge-but-thin TIFF and
 * PNG files go through `kogei chart detect` (exit 1, no patch file, no crash) and the
 * same images through kg_chart_detect (KG_EINVAL); the automatic decimation grows to
 * take a wide image that decimate 2 cannot, and an explicit --decimate too small for
 * it is refused with a hint. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

#include "kg_calib.h"
#include "kg_test.h"

static const char *kogei, *layout_path;
static char dir[] = "/tmp/kogei-chart-sizes-XXXXXX";

static kg_image *grey_image(int w, int h)
{
	kg_image *img = NULL;
	kg_err err = {{0}};
	if (kg_image_new(w, h, 3, &img, &err)) {
		fprintf(stderr, "%d x %d: %s\n", w, h, err.msg);
		return NULL;
	}
	for (long i = 0; i < 3L * w * h; i++)
		img->data[i] = 0.3f + 0.2f * (float)((i * 7919) % 13) / 13;
	return img;
}

/* Status of `kogei chart detect` on the file (or -signal), its stderr in msg. */
static int detect_cli(const char *image, const char *extra, char *msg, size_t len)
{
	char cmd[4096], out[600], errf[600];
	snprintf(out, sizeof(out), "%s/p.cgats", dir);
	snprintf(errf, sizeof(errf), "%s/stderr", dir);
	snprintf(cmd, sizeof(cmd), "%s chart detect --layout %s %s %s -o %s 2> %s", kogei,
	         layout_path, extra, image, out, errf);
	int st = system(cmd);
	msg[0] = '\0';
	FILE *f = fopen(errf, "r");
	if (f) {
		msg[fread(msg, 1, len - 1, f)] = '\0';
		fclose(f);
	}
	fprintf(stderr, "$ %s\n%s", cmd, msg);
	CHECK(!kg_test_file_exists(out), "%s: a patch file was written", image);
	unlink(out);
	if (WIFSIGNALED(st) || (WIFEXITED(st) && WEXITSTATUS(st) > 128))
		return -(WIFSIGNALED(st) ? WTERMSIG(st) : WEXITSTATUS(st) - 128);
	return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* The image refused by the CLI (both file types) and the C API, naming its size. */
static void refused(const kg_chart_layout *layout, int w, int h, const char *limit)
{
	kg_image *img = grey_image(w, h);
	if (!img)
		return;
	char size[64], msg[8192], path[600];
	snprintf(size, sizeof(size), "image %d x %d px", w, h);
	kg_err err = {{0}};
	const char *ext[2] = {"tif", "png"};
	for (int t = 0; t < 2; t++) {
		snprintf(path, sizeof(path), "%s/img.%s", dir, ext[t]);
		CHECK(kg_image_write(img, path, 16, &err) == 0, "%s", err.msg);
		int rc = detect_cli(path, "", msg, sizeof(msg));
		CHECK(rc == 1, "%d x %d %s: exit %d, expected 1", w, h, ext[t], rc);
		CHECK(strstr(msg, size) && strstr(msg, limit), "%d x %d %s: message lacks '%s' and "
		      "'%s': %s", w, h, ext[t], size, limit, msg);
		unlink(path);
	}
	kg_chart_result *r = NULL;
	int rc = kg_chart_detect(layout, img, NULL, &r, &err);
	CHECK(rc == KG_EINVAL && !r, "%d x %d: kg_chart_detect gave %d", w, h, rc);
	CHECK(strstr(err.msg, size) && strstr(err.msg, limit), "%d x %d: C API message: %s", w,
	      h, err.msg);
	kg_chart_result_free(&r);
	kg_image_free(&img);
}

int main(int argc, char **argv)
{
	if (argc < 2)
		kg_test_skip("no kogei program given");
	kogei = argv[1];
	layout_path = KG_SOURCE_ROOT "/fixtures/charts/colorchecker24-frame.json";
	CHECK(mkdtemp(dir) != NULL, "mkdtemp");
	kg_chart_layout *layout = NULL;
	kg_err err = {{0}};
	CHECK(kg_chart_layout_load(layout_path, &layout, &err) == 0, "%s", err.msg);
	if (!layout)
		return kg_test_done("chart-detect-sizes");

	/* decimate 2 (the default below 4 Mpix): 5 to 65534 px per side */
	refused(layout, 4, 4, "needs 5 to 65534 px per side");
	refused(layout, 3, 200, "needs 5 to 65534 px per side");
	refused(layout, 200, 4, "needs 5 to 65534 px per side");
	refused(layout, 1, 1, "needs 5 to 65534 px per side");
	/* 100000 x 1: the automatic decimation takes the width (4), not the height */
	refused(layout, 100000, 1, "decimate 4) needs 9 to 131068 px per side");
	refused(layout, 1, 100000, "decimate 4) needs 9 to 131068 px per side");

	/* 70000 x 40: decimate 4 fits libapriltag; the detector runs and finds no tags */
	kg_image *wide = grey_image(70000, 40);
	char path[600], msg[8192];
	snprintf(path, sizeof(path), "%s/wide.png", dir);
	CHECK(wide && kg_image_write(wide, path, 8, &err) == 0, "%s", err.msg);
	int rc = detect_cli(path, "", msg, sizeof(msg));
	CHECK(rc == 1 && strstr(msg, "no tag36h11 tags found"), "70000 x 40: exit %d: %s", rc, msg);
	/* the same with --decimate 2: refused with the limit and a hint */
	rc = detect_cli(path, "--decimate 2", msg, sizeof(msg));
	CHECK(rc == 1 && strstr(msg, "image 70000 x 40 px") && strstr(msg, "65534") &&
	          strstr(msg, "larger --decimate"),
	      "70000 x 40, --decimate 2: exit %d: %s", rc, msg);
	kg_chart_detect_options opt;
	kg_chart_detect_options_default(&opt);
	opt.decimate = 1;
	kg_chart_result *r = NULL;
	rc = wide ? kg_chart_detect(layout, wide, &opt, &r, &err) : -1;
	CHECK(rc == KG_EINVAL && strstr(err.msg, "needs 3 to 32767 px per side"),
	      "70000 x 40, decimate 1: %d: %s", rc, err.msg);
	kg_chart_result_free(&r);
	kg_image_free(&wide);
	unlink(path);

	kg_chart_layout_free(&layout);
	char cmd[700];
	snprintf(cmd, sizeof(cmd), "rm -rf %s", dir);
	CHECK(system(cmd) == 0, "cleanup");
	return kg_test_done("chart-detect-sizes");
}
