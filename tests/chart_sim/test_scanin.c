/* A peer for the simulated photographs and for chart sampling: ArgyllCMS scanin
 * reads the same images. `kogei sim chart` renders an unframed ColorChecker 24 from
 * Argyll's own recognition template (ColorChecker.cht: black card, 24 patches) at a
 * few poses; `scanin -o -a -p` recognises it and writes its patch means (.val, on a
 * 0..255 scale for any input depth); they must match the truth within 0.5 % of full
 * scale. Where kogei's tagless detection (OpenCV mcc) is built in, its values on
 * the same image are compared with scanin's as well. Skipped (77) without scanin,
 * without argyll-ref's template, or when scanin cannot find the chart.
 * Argument: the kogei program. */
#include <string.h>

#include "kg_calib.h"
#include "kg_test.h"
#include "chart_sim_util.h"

#define TOLERANCE 0.005
#define CHT "/usr/share/color/argyll/ref/ColorChecker.cht"

static const char *kogei;

static double max_diff(const kg_patchset *a, const kg_patchset *b, double scale_b,
                       const char *what, int *n)
{
	double worst = 0.0;
	*n = 0;
	for (int i = 0; i < a->n; i++) {
		int k = kg_patchset_find(b, a->ids[i]);
		CHECK(k >= 0, "%s: patch %s missing", what, a->ids[i]);
		if (k < 0)
			continue;
		for (int c = 0; c < 3; c++) {
			double d = fabs(a->rgb[i][c] - b->rgb[k][c] * scale_b);
			worst = fmax(worst, d);
			CHECK(d <= TOLERANCE, "%s: patch %s channel %d: %.5f vs %.5f", what, a->ids[i], c,
			      a->rgb[i][c], b->rgb[k][c] * scale_b);
		}
		++*n;
	}
	return worst;
}

/* Our tagless detection on the image; NULL (with the reason printed) when not
 * available. */
static kg_patchset *detect_tagless(const char *img)
{
	kg_err err = {{0}};
	kg_chart_layout *l = NULL;
	kg_image *im = NULL;
	kg_chart_result *r = NULL;
	kg_patchset *ps = NULL;
	int ret = kg_chart_layout_load(CHT, &l, &err);
	if (!ret)
		ret = kg_image_read(img, &im, &err);
	if (!ret) {
		kg_chart_detect_options o;
		kg_chart_detect_options_default(&o);
		o.tagless = 1;
		ret = kg_chart_detect(l, im, &o, &r, &err);
	}
	if (!ret)
		ret = kg_chart_result_patchset(r, &ps, &err);
	if (ret)
		printf("  kogei tagless detection: not compared (%s)\n", err.msg);
	kg_chart_result_free(&r);
	kg_image_free(&im);
	kg_chart_layout_free(&l);
	return ps;
}

int main(int argc, char **argv)
{
	if (argc < 2) {
		fprintf(stderr, "usage: %s KOGEI\n", argv[0]);
		return 2;
	}
	kogei = argv[1];
	if (system("scanin >/dev/null 2>&1 </dev/null; command -v scanin >/dev/null") != 0)
		kg_test_skip("ArgyllCMS scanin is not installed (package argyll)");
	if (!kg_test_file_exists(CHT))
		kg_test_skip(CHT " is missing (package argyll-ref)");
	kg_test_scratch_dir("chart-scanin");
	char *camera = strdup(kg_test_path("camera.csv"));
	cs_write_camera(camera);

	static const struct {
		const char *name, *tilt, *rotate, *depth;
	} poses[] = {
	    {"frontal, 16 bit", "0", "0", "16"},
	    {"tilt 20, rotate 4, 16 bit", "20", "4", "16"},
	    {"tilt 10, rotate -3, 8 bit", "10", "-3", "8"},
	};
	int found = 0;
	printf("| image                         | scanin vs truth | kogei vs truth | kogei vs scanin |\n"
	       "|-------------------------------|-----------------|----------------|-----------------|\n");
	for (size_t p = 0; p < sizeof(poses) / sizeof(poses[0]); p++) {
		char log[8192];
		char *img = strdup(kg_test_path("cc.tif")), *truth_path = strdup(kg_test_path("cc.cgats"));
		char *val = strdup(kg_test_path("cc.val"));
		char *sim[] = {(char *)kogei, "sim", "chart", "--layout", CHT, "--camera", camera,
		               "--illuminant", "D65", "--paper", "0.03", "--background", "0.3",
		               "--width", "2000", "--height", "1500", "--fill", "0.8",
		               "--tilt", (char *)poses[p].tilt, "--rotate", (char *)poses[p].rotate,
		               "--depth", (char *)poses[p].depth, "--noise", "20000:5:12",
		               "--blur", "0.8", "-o", img, "--truth", truth_path, NULL};
		int rc = cs_run(sim, log, sizeof(log));
		CHECK(rc == 0, "%s: sim chart exit %d: %s", poses[p].name, rc, log);
		char *scan[] = {"scanin", "-o", "-a", "-p", "-O", val, img, CHT, NULL};
		rc = rc ? rc : cs_run(scan, log, sizeof(log));
		kg_patchset *truth = NULL, *peer = NULL;
		kg_err err = {{0}};
		if (rc != 0 || kg_patchset_read(val, 0, &peer, &err) != 0 || !peer->rgb) {
			printf("  %s: scanin did not find the chart (exit %d): %.300s\n", poses[p].name,
			       rc, log);
		} else if (kg_patchset_read(truth_path, 0, &truth, &err) != 0) {
			CHECK(0, "truth: %s", err.msg);
		} else {
			found++;
			int n;
			double d_peer = max_diff(truth, peer, 1.0 / 255.0, poses[p].name, &n);
			CHECK(n == 24, "%s: %d patches compared", poses[p].name, n);
			kg_patchset *ours = detect_tagless(img);
			if (ours) {
				double d_ours = max_diff(truth, ours, 1.0, poses[p].name, &n);
				double d_both = max_diff(ours, peer, 1.0 / 255.0, poses[p].name, &n);
				printf("| %-29s | %15.5f | %14.5f | %15.5f |\n", poses[p].name, d_peer, d_ours,
				       d_both);
			} else {
				printf("| %-29s | %15.5f | %14s | %15s |\n", poses[p].name, d_peer, "-", "-");
			}
			kg_patchset_free(&ours);
		}
		kg_patchset_free(&truth);
		kg_patchset_free(&peer);
		free(img);
		free(truth_path);
		free(val);
	}
	free(camera);
	if (!found) {
		kg_test_scratch_remove();
		kg_test_skip("scanin found the chart in none of the images");
	}
	if (!kg_test_failures)
		kg_test_scratch_remove();
	return kg_test_done("chart-scanin");
}
