/* Chart detection against the truth of simulated photographs (issue 4, item 6):
 * `kogei sim chart` renders a framed 24-patch chart under each condition, the image
 * is read back and kg_chart_detect samples it, and every patch value must be within
 * 0.5 % of full scale (|measured - truth| <= 0.005 on the 0..1 scale, per channel)
 * of the truth (the noise-free value times the vignetting at the patch centre),
 * the sampled value being the reported one times the light field it was divided by
 * (tests/cli light-field-cli tests the field itself).
 * Also: two tags covered (still found, and the warning says so), an image without a
 * chart and one with only foreign tags (KG_ENOENT with a message), two frames in one
 * image (the one whose ids match). Prints the largest error of each condition.
 * Argument: the kogei program. Skipped (77) when built without libapriltag. */
#include <string.h>

#include "kg_calib.h"
#include "kg_test.h"
#include "chart_sim_util.h"

#define TOLERANCE 0.005

static const char *kogei;

typedef struct condition {
	const char *name;
	const char *args[12]; /* extra sim chart arguments */
	int spectra;          /* use the spectra file, not built-in colours */
} condition;

static const condition conditions[] = {
    {"frontal, 16 bit", {NULL}, 0},
    {"spectra file", {NULL}, 1},
    {"tilt 15", {"--tilt", "15", NULL}, 0},
    {"tilt 30, axis 120", {"--tilt", "30", "--tilt-axis", "120", NULL}, 0},
    {"tilt 45", {"--tilt", "45", NULL}, 1},
    {"tilt 45, axis 90", {"--tilt", "45", "--tilt-axis", "90", NULL}, 0},
    {"rotate 37", {"--rotate", "37", NULL}, 0},
    {"rotate 90", {"--rotate", "90", NULL}, 0},
    {"rotate 180, tilt 20", {"--rotate", "180", "--tilt", "20", NULL}, 0},
    {"blur 2.5", {"--blur", "2.5", NULL}, 0},
    {"blur 1.5, tilt 35", {"--blur", "1.5", "--tilt", "35", NULL}, 1},
    {"noise 5000:10:12", {"--noise", "5000:10:12", NULL}, 0},
    {"vignetting 0.4", {"--vignetting", "0.4", NULL}, 0},
    {"vignetting 0.4, tilt 30, rotate 20", {"--vignetting", "0.4", "--tilt", "30", "--rotate", "20", NULL}, 1},
    {"8 bit", {"--depth", "8", NULL}, 0},
    {"8 bit, tilt 40, blur 1.5", {"--depth", "8", "--tilt", "40", "--blur", "1.5", NULL}, 0},
    {"float", {"--depth", "float", NULL}, 0},
#if HAVE_OPENCV
    {"Bayer RGGB", {"--cfa", "RGGB", NULL}, 0},
#endif
};

static char camera[4200], layout[4200], spectra[4200];

/* Render with the defaults of every case plus extra (NULL-terminated) arguments. */
static int render(const char *lay, const char *const *extra, int use_spectra, const char *img,
                  const char *truth, char *log, size_t len)
{
	char *argv[48];
	int n = 0;
	const char *base[] = {kogei, "sim", "chart", "--layout", lay, "--camera", camera,
	                      "--illuminant", "D65", "--width", "1600", "--height", "1200",
	                      "--noise", "20000:5:12", "--blur", "0.8", "--seed", "7", "-o", img,
	                      "--truth", truth};
	for (size_t i = 0; i < sizeof(base) / sizeof(base[0]); i++)
		argv[n++] = (char *)base[i];
	if (use_spectra) {
		argv[n++] = "--spectra";
		argv[n++] = spectra;
	}
	for (int i = 0; extra && extra[i]; i++)
		argv[n++] = (char *)extra[i];
	argv[n] = NULL;
	return cs_run(argv, log, len);
}

/* Detect on an image; 0 or the error code (message in err). */
static int detect(const char *lay, const char *img, kg_chart_result **res, kg_err *err)
{
	kg_chart_layout *l = NULL;
	kg_image *im = NULL;
	int ret = kg_chart_layout_load(lay, &l, err);
	if (!ret)
		ret = kg_image_read(img, &im, err);
	if (!ret) {
		kg_chart_detect_options o;
		kg_chart_detect_options_default(&o);
		ret = kg_chart_detect(l, im, &o, res, err);
	}
	kg_image_free(&im);
	kg_chart_layout_free(&l);
	return ret;
}

/* Largest |measured - truth| over the patches not touched by occluders or glare;
 * -1 when a patch is missing. */
static double compare(const char *what, const kg_chart_result *r, const char *truth_path,
                      int *compared)
{
	kg_err err = {{0}};
	kg_patchset *truth = NULL;
	if (kg_patchset_read(truth_path, 0, &truth, &err)) {
		CHECK(0, "%s: truth: %s", what, err.msg);
		return -1;
	}
	int occ = kg_patchset_extra_index(truth, "OCCLUDED");
	int gl = kg_patchset_extra_index(truth, "GLARE");
	double worst = 0.0;
	*compared = 0;
	for (int i = 0; i < truth->n; i++) {
		if (truth->extra[i * truth->nextra + occ] != 0 || truth->extra[i * truth->nextra + gl] != 0)
			continue;
		const kg_chart_sample *s = NULL;
		for (int k = 0; k < r->npatches; k++)
			if (strcmp(r->patches[k].id, truth->ids[i]) == 0)
				s = &r->patches[k];
		if (!s || (s->flags & KG_CHART_FLAG_REJECTED)) {
			CHECK(0, "%s: patch %s not sampled", what, truth->ids[i]);
			worst = -1;
			continue;
		}
		for (int c = 0; c < 3; c++) {
			double v = s->rgb[c] * s->light; /* as sampled */
			double d = fabs(v - truth->rgb[i][c]);
			if (worst >= 0 && d > worst)
				worst = d;
			CHECK(d <= TOLERANCE, "%s: patch %s channel %d: %.5f vs truth %.5f", what,
			      truth->ids[i], c, v, truth->rgb[i][c]);
		}
		++*compared;
	}
	kg_patchset_free(&truth);
	return worst;
}

static void run_condition(const char *name, const char *const *extra, int use_spectra)
{
	char log[8192];
	const char *img = kg_test_path("image.tif"), *truth = kg_test_path("truth.cgats");
	int rc = render(layout, extra, use_spectra, img, truth, log, sizeof(log));
	CHECK(rc == 0, "%s: sim chart exit %d: %s", name, rc, log);
	if (rc)
		return;
	kg_chart_result *r = NULL;
	kg_err err = {{0}};
	int ret = detect(layout, img, &r, &err);
	CHECK(ret == 0, "%s: detection failed: %s", name, err.msg);
	if (ret)
		return;
	int n = 0;
	double worst = compare(name, r, truth, &n);
	printf("| %-36s | %3d | %8.5f | %5.3f |\n", name, n, worst, 100.0 * worst);
	kg_chart_result_free(&r);
}

static int any_warning(const kg_chart_result *r, const char *const *needles)
{
	for (int w = 0; w < r->nwarnings; w++)
		for (int k = 0; needles[k]; k++)
			if (strcasestr(r->warnings[w], needles[k]))
				return 1;
	return 0;
}

/* The bundled layouts (fixtures/charts), tilted and rotated, at 6 Mpix. */
static void test_fixture_layouts(void)
{
	static const char *const names[] = {"colorchecker24-frame.json",
	                                    "colorchecker-passport-frame.json",
	                                    "colorchecker-sg-frame.json"};
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++) {
		char lay[4200], title[128], log[8192];
		snprintf(lay, sizeof(lay), "%s/fixtures/charts/%s", KG_SOURCE_ROOT, names[i]);
		if (!kg_test_file_exists(lay)) {
			printf("  %s: not in this checkout\n", names[i]);
			continue;
		}
		const char *img = kg_test_path("fixture.tif"), *truth = kg_test_path("fixture.cgats");
		const char *extra[] = {"--tilt", "30", "--rotate", "15", "--vignetting", "0.2",
		                       "--width", "3000", "--height", "2000", NULL};
		int rc = render(lay, extra, 0, img, truth, log, sizeof(log));
		CHECK(rc == 0, "%s: sim chart exit %d: %s", names[i], rc, log);
		kg_chart_result *r = NULL;
		kg_err err = {{0}};
		int ret = rc ? -1 : detect(lay, img, &r, &err);
		CHECK(ret == 0, "%s: detection failed: %s", names[i], err.msg);
		if (ret)
			continue;
		int n = 0;
		snprintf(title, sizeof(title), "%.*s, tilt 30, rot 15", (int)strlen(names[i]) - 5,
		         names[i]);
		double worst = compare(title, r, truth, &n);
		printf("| %-36.36s | %3d | %8.5f | %5.3f |\n", title, n, worst, 100.0 * worst);
		kg_chart_result_free(&r);
	}
}

static void test_occluded_tags(void)
{
	char log[8192];
	const char *img = kg_test_path("occ.tif"), *truth = kg_test_path("occ.cgats");
	const char *extra[] = {"--occlude", "tags", "--tilt", "25", NULL};
	int rc = render(layout, extra, 0, img, truth, log, sizeof(log));
	CHECK(rc == 0, "occlusion: sim chart exit %d: %s", rc, log);
	kg_chart_result *r = NULL;
	kg_err err = {{0}};
	int ret = rc ? -1 : detect(layout, img, &r, &err);
	CHECK(ret == 0, "two tags covered: detection failed: %s", err.msg);
	if (ret)
		return;
	CHECK(r->ntags_used == 2, "two tags covered: %d tags used, expected 2", r->ntags_used);
	static const char *const words[] = {"occlu", "missing", "not found", NULL};
	CHECK(any_warning(r, words), "two tags covered: no warning names the missing tags");
	for (int w = 0; w < r->nwarnings; w++)
		printf("  warning (two tags covered): %s\n", r->warnings[w]);
	int n = 0;
	double worst = compare("two tags covered", r, truth, &n);
	printf("| %-36s | %3d | %8.5f | %5.3f |\n", "two of four tags covered, tilt 25", n, worst,
	       100.0 * worst);
	kg_chart_result_free(&r);
}

static void test_glare_and_covered_patches(void)
{
	char log[8192];
	const char *img = kg_test_path("glare.tif"), *truth = kg_test_path("glare.cgats");
	const char *extra[] = {"--glare", "--occlude", "patches", NULL};
	int rc = render(layout, extra, 0, img, truth, log, sizeof(log));
	CHECK(rc == 0, "glare: sim chart exit %d: %s", rc, log);
	kg_chart_result *r = NULL;
	kg_err err = {{0}};
	int ret = rc ? -1 : detect(layout, img, &r, &err);
	CHECK(ret == 0, "glare and covered patches: detection failed: %s", err.msg);
	if (ret)
		return;
	/* The glare patch (the middle one) is flagged; the others are within tolerance. */
	const kg_chart_sample *g = &r->patches[CS_NPATCH / 2];
	CHECK(g->flags & (KG_CHART_FLAG_GLARE | KG_CHART_FLAG_NONUNIFORM | KG_CHART_FLAG_CLIPPED),
	      "glare patch %s not flagged (flags %#x)", g->id, g->flags);
	printf("  glare patch %s: flags %#x (%s)\n", g->id, g->flags, g->warning);
	int n = 0;
	double worst = compare("glare, two patches covered", r, truth, &n);
	printf("| %-36s | %3d | %8.5f | %5.3f |\n", "glare + 2 patches covered (others)", n,
	       worst, 100.0 * worst);
	kg_chart_result_free(&r);
}

static void test_two_charts(void)
{
	char log[8192];
	const char *img = kg_test_path("two.tif"), *truth = kg_test_path("two.cgats");
	const char *extra[] = {"--decoy", "--tilt", "20", NULL};
	int rc = render(layout, extra, 0, img, truth, log, sizeof(log));
	CHECK(rc == 0, "two charts: sim chart exit %d: %s", rc, log);
	kg_chart_result *r = NULL;
	kg_err err = {{0}};
	int ret = rc ? -1 : detect(layout, img, &r, &err);
	CHECK(ret == 0, "two charts: detection failed: %s", err.msg);
	if (ret)
		return;
	int n = 0;
	double worst = compare("two charts", r, truth, &n);
	printf("| %-36s | %3d | %8.5f | %5.3f |\n", "two frames, other ids beside", n, worst,
	       100.0 * worst);
	kg_chart_result_free(&r);
}

static void test_no_chart(void)
{
	kg_err err = {{0}};
	/* A grey image with nothing in it. */
	kg_image *im = NULL;
	CHECK(kg_image_new(640, 480, 3, &im, &err) == 0, "image: %s", err.msg);
	for (long i = 0; i < 640L * 480 * 3; i++)
		im->data[i] = 0.2f + 0.01f * (float)((i * 7919) % 13) / 13.0f;
	const char *img = kg_test_path("empty.tif");
	CHECK(kg_image_write(im, img, 16, &err) == 0, "write: %s", err.msg);
	kg_image_free(&im);
	kg_chart_result *r = NULL;
	int ret = detect(layout, img, &r, &err);
	CHECK(ret == KG_ENOENT, "no chart: code %d, expected KG_ENOENT (%s)", ret, err.msg);
	CHECK(strcasestr(err.msg, "tag") != NULL, "no chart: message does not mention tags: %s",
	      err.msg);
	printf("  no chart: %s\n", err.msg);
	kg_chart_result_free(&r);

	/* Only a frame whose tags are not the layout's. */
	char log[8192];
	const char *other = kg_test_path("other.json");
	cs_write_layout(other, "other ids", 20);
	int rc = render(other, NULL, 0, kg_test_path("foreign.tif"), kg_test_path("foreign.cgats"), log,
	                sizeof(log));
	CHECK(rc == 0, "foreign: sim chart exit %d: %s", rc, log);
	memset(&err, 0, sizeof(err));
	ret = detect(layout, kg_test_path("foreign.tif"), &r, &err);
	CHECK(ret == KG_ENOENT, "foreign tags: code %d, expected KG_ENOENT (%s)", ret, err.msg);
	CHECK(err.msg[0] != '\0', "foreign tags: no message");
	printf("  foreign tags only: %s\n", err.msg);
	kg_chart_result_free(&r);
}

int main(int argc, char **argv)
{
#if !HAVE_APRILTAG
	(void)argc;
	(void)argv;
	kg_test_skip("built without libapriltag: chart detection is not available");
#else
	if (argc < 2) {
		fprintf(stderr, "usage: %s KOGEI\n", argv[0]);
		return 2;
	}
	kogei = argv[1];
	kg_test_scratch_dir("chart-accuracy");
	snprintf(camera, sizeof(camera), "%s", kg_test_path("camera.csv"));
	snprintf(layout, sizeof(layout), "%s", kg_test_path("frame24.json"));
	snprintf(spectra, sizeof(spectra), "%s", kg_test_path("spectra.cgats"));
	cs_write_camera(camera);
	cs_write_layout(layout, "frame24", 0);
	cs_write_spectra(spectra);

	printf("| condition                            |   n | max |err| | %% FS  |\n"
	       "|--------------------------------------|-----|----------|-------|\n");
	for (size_t i = 0; i < sizeof(conditions) / sizeof(conditions[0]); i++)
		run_condition(conditions[i].name, conditions[i].args, conditions[i].spectra);
	test_fixture_layouts();
	test_occluded_tags();
	test_glare_and_covered_patches();
	test_two_charts();
	test_no_chart();
	if (!kg_test_failures)
		kg_test_scratch_remove();
	else
		fprintf(stderr, "inputs kept in %s\n", kg_test_scratch());
	return kg_test_done("chart-accuracy");
#endif
}
