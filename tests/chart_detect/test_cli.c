/* kogei chart detect end to end: the printed frame of the bundled ColorChecker 24
 * layout (kogei chart print) is found; a blank image exits 1 with a clear message. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

#include "kg_calib.h"
#include "kg_test.h"

static int run(const char *cmd)
{
	int st = system(cmd);
	return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

int main(int argc, char **argv)
{
	if (argc < 2)
		kg_test_skip("no kogei program given");
	const char *kogei = argv[1];
	char dir[] = "/tmp/kogei-chart-detect-XXXXXX", cmd[16384];
	CHECK(mkdtemp(dir) != NULL, "mkdtemp");
	const char *layout = KG_SOURCE_ROOT "/fixtures/charts/colorchecker24-frame.json";
	if (!kg_test_file_exists(layout))
		kg_test_skip("fixtures/charts/colorchecker24-frame.json is missing");
	snprintf(cmd, sizeof(cmd), "%s chart print --layout %s -o %s/frame.png", kogei, layout, dir);
	if (run(cmd) != 0)
		kg_test_skip("kogei chart print could not draw the frame");
	snprintf(cmd, sizeof(cmd),
	         "%s chart detect --layout %s %s/frame.png -o %s/p.cgats --overlay %s/o.png "
	         "2> %s/stderr", kogei, layout, dir, dir, dir, dir);
	CHECK(run(cmd) == 0, "detect on the printed frame failed");
	char path[4200];
	snprintf(path, sizeof(path), "%s/p.cgats", dir);
	kg_patchset *ps = NULL;
	kg_err err = {{0}};
	CHECK(kg_patchset_read(path, 0, &ps, &err) == 0, "%s", err.msg);
	if (ps) {
		CHECK(ps->n == 24 && ps->rgb, "%d patches", ps->n);
		CHECK(kg_patchset_extra_index(ps, "CLIPPED_FRACTION") >= 0 &&
		      kg_patchset_extra_index(ps, "RGB_G_SD") >= 0, "spread and clipping columns");
	}
	kg_patchset_free(&ps);
	snprintf(path, sizeof(path), "%s/o.png", dir);
	CHECK(kg_test_file_exists(path), "overlay written");

	/* The same frame as a 16-bit TIFF, which chart detect maps rather than reads
	 * unless the overlay is asked for: both give the same patch file. */
	kg_image *frame = NULL;
	snprintf(path, sizeof(path), "%s/frame.png", dir);
	CHECK(kg_image_read(path, &frame, &err) == 0, "%s", err.msg);
	snprintf(path, sizeof(path), "%s/frame16.tif", dir);
	CHECK(frame && kg_image_write(frame, path, 16, &err) == 0, "%s", err.msg);
	kg_image_free(&frame);
	snprintf(cmd, sizeof(cmd), "%s chart detect --layout %s %s -o %s/m.cgats 2>/dev/null && "
	         "%s chart detect --layout %s %s -o %s/r.cgats --overlay %s/o16.png 2>/dev/null && "
	         "cmp -s %s/m.cgats %s/r.cgats", kogei, layout, path, dir, kogei, layout, path, dir,
	         dir, dir, dir);
	CHECK(run(cmd) == 0, "16-bit TIFF: the mapped image's patch file differs from the "
	      "read one's (or detection failed)");

	/* Low-contrast tags: exposed at 2 % of full scale with sensor noise, and printed
	 * in grey ink (0.6 on 0.85 paper). The tag detector leaves tiles of less than 10
	 * codes' contrast unsegmented (against the specks of a dark background's noise):
	 * these tags must stay well above that. */
	static const char *hard[] = {"--white-level 0.02 --noise 20000:5:12", "--ink 0.6",
	                             "--ink 0.5 --white-level 0.1 --noise 20000:5:12 --blur 2"};
	for (int k = 0; k < 3; k++) {
		snprintf(cmd, sizeof(cmd), "%s sim chart --layout %s --camera demo-reference "
		         "--illuminant D65 --width 1600 --height 1200 --tilt 30 %s -o %s/hard%d.tif "
		         ">/dev/null 2>&1 && %s chart detect --layout %s %s/hard%d.tif -o %s/hard%d.cgats "
		         "2>%s/hard%d.err && grep -q 'chart colorchecker24-frame: 4 tags used' "
		         "%s/hard%d.err", kogei, layout, hard[k], dir, k, kogei, layout, dir, k, dir, k,
		         dir, k, dir, k);
		CHECK(run(cmd) == 0, "low-contrast tags (%s): not all 4 found", hard[k]);
	}

	/* a picture with no chart: exit 1, a message, no patch file */
	kg_image *img = NULL;
	kg_image_new(320, 240, 3, &img, NULL);
	for (int i = 0; i < 320 * 240 * 3; i++)
		img->data[i] = 0.3f + 0.2f * (float)((i * 7919) % 13) / 13;
	snprintf(path, sizeof(path), "%s/blank.png", dir);
	CHECK(kg_image_write(img, path, 8, &err) == 0, "%s", err.msg);
	kg_image_free(&img);
	snprintf(cmd, sizeof(cmd),
	         "%s chart detect --layout %s %s/blank.png -o %s/none.cgats 2> %s/stderr2", kogei,
	         layout, dir, dir, dir);
	CHECK(run(cmd) == 1, "a picture without a chart must exit 1");
	snprintf(path, sizeof(path), "%s/none.cgats", dir);
	CHECK(!kg_test_file_exists(path), "no patch file when the chart is not found");
	char *text = NULL;
	size_t len = 0;
	snprintf(path, sizeof(path), "%s/stderr2", dir);
	if (kg_read_file(path, &text, &len, &err) == 0) {
		CHECK(strstr(text, "not found") && strstr(text, "no tag36h11 tags found"),
		      "message: %s", text);
		free(text);
	}
	snprintf(cmd, sizeof(cmd), "%s chart detect --layout %s 2>/dev/null", kogei, layout);
	CHECK(run(cmd) == 2, "usage error");
	snprintf(cmd, sizeof(cmd), "rm -rf %s", dir);
	run(cmd);
	return kg_test_done("chart-detect-cli");
}
