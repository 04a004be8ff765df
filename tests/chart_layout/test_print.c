/* `kg_chart_print`: every bundled frame printed to PNG is detected by libapriltag
 * with all four tags where the layout says (corners within 1 px, in the layout's
 * corner order); a tagStandard41h12 frame too; SVG and PDF outputs are well-formed
 * and at true size; bad requests leave no file behind. Without libapriltag, printing
 * must refuse with KG_ENOTSUP and the test is skipped. */
#include "chart_test.h"

#if HAVE_APRILTAG
#include <apriltag/apriltag.h>
#include <apriltag/tag36h11.h>
#include <apriltag/tagStandard41h12.h>
#endif

static int count_files(const char *dir)
{
	char cmd[4300];
	snprintf(cmd, sizeof(cmd), "test $(ls -A '%s' | wc -l) -eq 0", dir);
	return system(cmd) == 0 ? 0 : 1;
}

#if HAVE_APRILTAG

static char *read_all(const char *path, size_t *len)
{
	char *buf = NULL;
	kg_err err = {{0}};
	if (kg_read_file(path, &buf, len, &err) != 0) {
		CHECK(0, "%s", err.msg);
		return NULL;
	}
	return buf;
}

/* Print, read back as 8-bit grey and detect; checks ids and corners. */
static void print_and_detect(const kg_chart_layout *l, const char *dir, double dpi)
{
	char path[4200];
	snprintf(path, sizeof(path), "%s/%s.png", dir, l->name);
	kg_err err = {{0}};
	int ret = kg_chart_print(l, path, dpi, &err);
	CHECK(ret == 0, "%s: print: %s", l->name, err.msg);
	if (ret)
		return;
	kg_image *img = NULL;
	ret = kg_image_read(path, &img, &err);
	CHECK(ret == 0, "%s: read back: %s", l->name, err.msg);
	if (ret)
		return;
	double mm = dpi / 25.4;
	int want_w = (int)ceil((l->width_mm + 2 * KG_CHART_PRINT_MARGIN_MM) * mm);
	CHECK(img->width == want_w, "%s: %d px wide, expected %d", l->name, img->width, want_w);

	image_u8_t im = {.width = img->width, .height = img->height, .stride = img->width};
	im.buf = malloc((size_t)img->width * img->height);
	for (long i = 0; i < (long)img->width * img->height; i++) {
		float v = img->data[i * img->channels];
		im.buf[i] = (uint8_t)lrintf(255.0f * fminf(fmaxf(v, 0.0f), 1.0f));
	}

	apriltag_family_t *fam = strcmp(l->family, "tag36h11") == 0 ? tag36h11_create()
	                                                            : tagStandard41h12_create();
	apriltag_detector_t *td = apriltag_detector_create();
	apriltag_detector_add_family(td, fam);
	td->quad_decimate = 1.0f;
	td->nthreads = 1; /* libapriltag 3.3's threads can crash (calib/chart_detect.c) */
	td->refine_edges = 1;
	zarray_t *dets = apriltag_detector_detect(td, &im);
	int found = 0;
	double worst = 0;
	for (int k = 0; k < zarray_size(dets); k++) {
		apriltag_detection_t *det;
		zarray_get(dets, k, &det);
		int t = kg_chart_layout_find_tag(l, det->id);
		CHECK(t >= 0, "%s: detected tag %d is not in the layout", l->name, det->id);
		if (t < 0)
			continue;
		found++;
		CHECK(det->hamming == 0, "%s: tag %d decoded with %d bit errors", l->name, det->id,
		      det->hamming);
		for (int c = 0; c < 4; c++) {
			double ex = (l->tags[t].corners_mm[c][0] + KG_CHART_PRINT_MARGIN_MM) * mm;
			double ey = (l->tags[t].corners_mm[c][1] + KG_CHART_PRINT_MARGIN_MM) * mm;
			double e = hypot(det->p[c][0] - ex, det->p[c][1] - ey);
			worst = fmax(worst, e);
			CHECK(e <= 1.0, "%s: tag %d corner %d at (%.2f, %.2f) px, expected (%.2f, %.2f)",
			      l->name, det->id, c, det->p[c][0], det->p[c][1], ex, ey);
		}
	}
	CHECK(found == l->ntags && zarray_size(dets) == l->ntags,
	      "%s: %d of %d tags found (%d detections)", l->name, found, l->ntags,
	      zarray_size(dets));
	printf("%s at %g dpi: %d/%d tags, worst corner error %.3f px\n", l->name, dpi, found,
	       l->ntags, worst);
	apriltag_detections_destroy(dets);
	apriltag_detector_destroy(td);
	if (strcmp(l->family, "tag36h11") == 0)
		tag36h11_destroy(fam);
	else
		tagStandard41h12_destroy(fam);
	free(im.buf);
	kg_image_free(&img);
}

/* The cells match the family tables: classic border black, ring outside white. */
static void test_cells(void)
{
	unsigned char *c = NULL;
	int n = 0, b = 0;
	kg_err err = {{0}};
	CHECK(kg_chart_tag_cells("tag36h11", 0, &c, &n, &b, &err) == 0, "%s", err.msg);
	CHECK(n == 10 && b == 8, "tag36h11 10/8 (%d/%d)", n, b);
	for (int k = 0; c && k < n; k++) {
		CHECK(c[k] == 1 && c[(n - 1) * n + k] == 1 && c[k * n] == 1 && c[k * n + n - 1] == 1,
		      "outer ring white at %d", k);
		if (k >= 1 && k <= 8)
			CHECK(c[n + k] == 0 && c[8 * n + k] == 0 && c[k * n + 1] == 0 && c[k * n + 8] == 0,
			      "black border at %d", k);
	}
	free(c);
	c = NULL;
	CHECK(kg_chart_tag_cells("tagStandard41h12", 2114, &c, &n, &b, &err) == 0, "%s", err.msg);
	CHECK(n == 9 && b == 5, "tagStandard41h12 9/5 (%d/%d)", n, b);
	for (int k = 2; c && k <= 6; k++)
		CHECK(c[2 * n + k] == 1 && c[6 * n + k] == 1 && c[k * n + 2] == 1 && c[k * n + 6] == 1,
		      "white ring at %d", k);
	for (int k = 1; c && k <= 7; k++)
		CHECK(c[n + k] == 0 && c[7 * n + k] == 0, "black border at %d", k);
	free(c);
	CHECK(kg_chart_tag_cells("tag36h11", 587, &c, &n, &b, &err) == KG_EINVAL, "id range");
	CHECK(kg_chart_tag_cells("tag16h5", 0, &c, &n, &b, &err) == KG_EINVAL, "family");
}

/* A frame of tagStandard41h12 tags (reversed border: the detected square is the
 * white ring, the outer data ring lies outside it). */
static void test_41h12(const char *dir)
{
	kg_chart_tag tags[4];
	kg_chart_patch patch = {.id = "A01", .center_mm = {100, 60}, .size_mm = {40, 40}};
	static const double centres[4][2] = {{25, 25}, {175, 25}, {175, 95}, {25, 95}};
	for (int i = 0; i < 4; i++) {
		tags[i] = (kg_chart_tag){.id = 100 + 7 * i, .size_mm = 15,
		                         .center_mm = {centres[i][0], centres[i][1]}};
		static const double sx[4] = {-1, 1, 1, -1}, sy[4] = {1, 1, -1, -1};
		for (int k = 0; k < 4; k++) {
			tags[i].corners_mm[k][0] = centres[i][0] + 7.5 * sx[k];
			tags[i].corners_mm[k][1] = centres[i][1] + 7.5 * sy[k];
		}
	}
	kg_chart_layout l = {.name = "test-41h12", .family = "tagStandard41h12",
	                     .width_mm = 200, .height_mm = 120,
	                     .chart_area_mm = {50, 20, 100, 80}, .sample_fraction = 0.5,
	                     .ntags = 4, .tags = tags, .npatches = 1, .patches = &patch};
	kg_err err = {{0}};
	CHECK(kg_chart_layout_check(&l, &err) == 0, "%s", err.msg);
	print_and_detect(&l, dir, 200);
}

static void test_vector(const char *dir)
{
	kg_chart_layout *l = NULL;
	kg_err err = {{0}};
	if (kg_chart_layout_load(bundled_path("colorchecker24-frame"), &l, &err) != 0) {
		CHECK(0, "%s", err.msg);
		return;
	}
	char path[4200];
	size_t len = 0;
	snprintf(path, sizeof(path), "%s/frame.svg", dir);
	CHECK(kg_chart_print(l, path, 0, &err) == 0, "svg: %s", err.msg);
	char *svg = read_all(path, &len);
	if (svg) {
		CHECK(len > 1000 && strncmp(svg, "<?xml", 5) == 0, "svg starts with <?xml");
		CHECK(strstr(svg, "<svg") && strstr(svg, "</svg>"), "svg element closed");
		CHECK(strstr(svg, "width=\"420mm\"") && strstr(svg, "height=\"297mm\""),
		      "svg at true size (420 x 297 mm)");
		free(svg);
	}
	snprintf(path, sizeof(path), "%s/frame.PDF", dir);
	CHECK(kg_chart_print(l, path, 0, &err) == 0, "pdf: %s", err.msg);
	char *pdf = read_all(path, &len);
	if (pdf) {
		CHECK(len > 1000 && memcmp(pdf, "%PDF-", 5) == 0, "pdf magic");
		CHECK(len > 6 && memmem(pdf + len - 7, 7, "%%EOF", 5), "pdf ends with %%%%EOF");
		/* A3 landscape in points: 420 mm = 1190.55 pt */
		CHECK(memmem(pdf, len, "MediaBox [ 0 0 1190.55", 22) != NULL, "pdf MediaBox at true size");
		free(pdf);
	}
	snprintf(path, sizeof(path), "%s/frame.png", dir);
	char *png = (kg_chart_print(l, path, 30, &err) == 0) ? read_all(path, &len) : NULL;
	CHECK(png && len > 8 && memcmp(png, "\x89PNG\r\n\x1a\n", 8) == 0, "png magic: %s",
	      err.msg);
	free(png);

	/* refusals leave nothing behind */
	char *empty = make_scratch();
	snprintf(path, sizeof(path), "%s/frame.jpg", empty);
	CHECK(kg_chart_print(l, path, 150, &err) == KG_EINVAL && strstr(err.msg, ".svg, .pdf"),
	      "unknown extension: %s", err.msg);
	snprintf(path, sizeof(path), "%s/frame.png", empty);
	CHECK(kg_chart_print(l, path, 5, &err) == KG_EINVAL && strstr(err.msg, "dpi"),
	      "dpi range: %s", err.msg);
	CHECK(kg_chart_print(l, "/nonexistent-dir/frame.svg", 0, &err) != 0, "unwritable path");
	CHECK(count_files(empty) == 0, "no file left after refusals");
	rm_scratch(empty);
	kg_chart_layout_free(&l);
}

#endif

int main(void)
{
	char *dir = make_scratch();
#if HAVE_APRILTAG
	test_cells();
	for (int k = 0; k < NBUNDLED; k++) {
		kg_chart_layout *l = NULL;
		kg_err err = {{0}};
		if (kg_chart_layout_load(bundled_path(bundled_layouts[k]), &l, &err) != 0) {
			CHECK(0, "%s", err.msg);
			continue;
		}
		print_and_detect(l, dir, 150);
		kg_chart_layout_free(&l);
	}
	test_41h12(dir);
	test_vector(dir);
	rm_scratch(dir);
	return kg_test_done("chart-print");
#else
	kg_chart_layout *l = NULL;
	kg_err err = {{0}};
	char path[4200];
	snprintf(path, sizeof(path), "%s/frame.svg", dir);
	CHECK(kg_chart_layout_load(bundled_path("colorchecker24-frame"), &l, &err) == 0, "%s",
	      err.msg);
	CHECK(kg_chart_print(l, path, 150, &err) == KG_ENOTSUP && strstr(err.msg, "libapriltag"),
	      "without libapriltag printing is refused: %s", err.msg);
	CHECK(count_files(dir) == 0, "nothing written");
	kg_chart_layout_free(&l);
	rm_scratch(dir);
	if (kg_test_failures)
		return kg_test_done("chart-print");
	kg_test_skip("built without libapriltag");
#endif
}
