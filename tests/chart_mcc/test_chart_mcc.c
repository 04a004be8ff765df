/* Tagless chart detection (OpenCV mcc, calib/chart_mcc.cpp) against the truth of
 * simulated photographs. `kogei sim chart` renders an unframed ColorChecker 24 (the
 * real patch spectra, ../shared/reference) from ArgyllCMS's ColorChecker.cht on a
 * black card (--paper 0.03) at tilts 0 and 20 degrees and in-plane rotations 0, 90
 * and 180; kg_chart_detect in tagless mode must return all 24 ids, each patch within
 * 0.5 % of full scale of the truth (|measured - truth| <= 0.005 per channel), the
 * A1 patch where the truth puts it (so the orientation was resolved), and say in a
 * warning that the tagless detector chose the orientation. The ColorChecker frame
 * layout rendered on black paper (its tags vanish) must be found by falling back to
 * mcc without being asked. A picture with no chart is KG_ENOENT with a message
 * naming mcc, with and without --tagless. Also the CLI (DETECTOR opencv-mcc).
 * Skipped (77) when built without OpenCV mcc or without the reference spectra; the
 * .cht cases also need argyll-ref. Argument: the kogei program. */
#include <string.h>

#include "kg_calib.h"
#include "kg_test.h"
#include "../chart_sim/chart_sim_util.h"

#define TOLERANCE 0.005
#define CHT "/usr/share/color/argyll/ref/ColorChecker.cht"

static const char *kogei;
static char camera[4200], spectra_csv[4200], spectra_cht[4200], frame_layout[4200];

/* The reference spectra (ids 1..24, row-major from dark skin) with the ids of
 * ColorChecker.cht (A1..D6: row letter, column number). */
static void write_cht_spectra(const char *from, const char *to)
{
	FILE *in = fopen(from, "r"), *out = fopen(to, "w");
	if (!in || !out) {
		fprintf(stderr, "cannot copy %s to %s\n", from, to);
		exit(1);
	}
	char line[8192];
	for (int n = 0; fgets(line, sizeof(line), in); n++) {
		char *comma = strchr(line, ',');
		int id = atoi(line);
		if (n == 0 || !comma || id < 1 || id > 24)
			fputs(line, out);
		else
			fprintf(out, "%c%d%s", 'A' + (id - 1) / 6, (id - 1) % 6 + 1, comma);
	}
	fclose(in);
	fclose(out);
}

static int render(const char *layout, const char *spectra, const char *tilt,
                  const char *rotate, const char *depth, const char *img, const char *truth)
{
	char log[8192];
	char *argv[] = {(char *)kogei, "sim", "chart", "--layout", (char *)layout,
	                "--spectra", (char *)spectra, "--camera", camera, "--illuminant", "D65",
	                "--paper", "0.03", "--background", "0.3", "--width", "1600",
	                "--height", "1200", "--fill", "0.7", "--tilt", (char *)tilt,
	                "--rotate", (char *)rotate, "--depth", (char *)depth,
	                "--noise", "20000:5:12", "--blur", "0.8", "--seed", "5",
	                "-o", (char *)img, "--truth", (char *)truth, NULL};
	int rc = cs_run(argv, log, sizeof(log));
	CHECK(rc == 0, "sim chart exit %d: %s", rc, log);
	return rc;
}

/* decimate: the tagless detector's reduction (0: its default, 1 at these sizes). */
static int detect_at(const char *layout, const kg_image *im, int tagless, int decimate,
                     int threads, kg_chart_result **r, kg_err *err)
{
	kg_chart_layout *l = NULL;
	int ret = kg_chart_layout_load(layout, &l, err);
	if (!ret) {
		kg_chart_detect_options o;
		kg_chart_detect_options_default(&o);
		o.tagless = tagless;
		o.tagless_decimate = decimate;
		o.threads = threads;
		ret = kg_chart_detect(l, im, &o, r, err);
	}
	kg_chart_layout_free(&l);
	return ret;
}

static int detect(const char *layout, const kg_image *im, int tagless, kg_chart_result **r,
                  kg_err *err)
{
	return detect_at(layout, im, tagless, 0, 2, r, err);
}

static int has_warning(const kg_chart_result *r, const char *text)
{
	for (int i = 0; i < r->nwarnings; i++)
		if (strstr(r->warnings[i], text))
			return 1;
	return 0;
}

/* Column of a truth file's extra field. */
static int extra_column(const kg_patchset *ps, const char *name)
{
	for (int k = 0; k < ps->nextra; k++)
		if (!strcmp(ps->extra_names[k], name))
			return k;
	return -1;
}

/* Detect, compare with the truth; the worst error (NAN when not detected). */
static double check_case(const char *name, const char *layout, const char *spectra,
                         const char *tilt, const char *rotate, const char *depth, int tagless)
{
	char *img = strdup(cs_path("cc.tif")), *truth_path = strdup(cs_path("cc.cgats"));
	double worst = NAN;
	kg_image *im = NULL;
	kg_patchset *truth = NULL;
	kg_chart_result *r = NULL;
	kg_err err = {{0}};
	if (render(layout, spectra, tilt, rotate, depth, img, truth_path))
		goto done;
	int ret = kg_image_read(img, &im, &err);
	if (!ret)
		ret = kg_patchset_read(truth_path, 0, &truth, &err);
	CHECK(ret == 0, "%s: %s", name, err.msg);
	if (ret)
		goto done;
	/* mcc on the full image (the default at this size), then the patch-grid finder on
	 * a copy reduced 2 x 2 with its box refined at full resolution, at 2 and 1
	 * threads: the same tolerance, and the same numbers at either thread count. */
	static const int decimate[3] = {0, 2, 2}, threads[3] = {2, 2, 1};
	kg_chart_result *two = NULL;
	const char *base = name;
	for (int v = 0; v < 3; v++) {
		char what[160];
		snprintf(what, sizeof(what), "%s%s", base, v == 0 ? "" : v == 1 ? ", reduced 2 x 2" :
		         ", reduced 2 x 2, 1 thread");
		name = what;
		kg_chart_result_free(&r);
		ret = detect_at(layout, im, tagless, decimate[v], threads[v], &r, &err);
		CHECK(ret == 0, "%s: %s", name, err.msg);
		if (ret)
			break;
		if (v > 0)
			CHECK(r->tagless_decimate == 2 && has_warning(r, "refined on"),
			      "%s: reduction %d, the refinement not reported", name, r->tagless_decimate);
		CHECK(r->tagless == 1, "%s: not found by the tagless detector", name);
		/* on the full image mcc places the chart; on the reduced copy the patch-grid
		 * finder, which runs first there */
		if (v == 0)
			CHECK(!r->tagless_grid && has_warning(r, "tagless detector (OpenCV mcc"),
			      "%s: no warning names mcc", name);
		else
			CHECK(r->tagless_grid && has_warning(r, "tagless detector (its patch-grid finder"),
			      "%s: not placed by the patch-grid finder", name);
		/* The grid's box must start the refinement on the right patch edges: a box
		 * with its row of 6 patches on its short side (a mirrored lattice given the
		 * layout's winding by the wrong corner swap) is refined on few edges, several
		 * pixels off them. */
		double edge_rms = NAN;
		for (int i = 0; v > 0 && i < r->nwarnings; i++) {
			const char *at = strstr(r->warnings[i], "at full resolution (RMS ");
			if (at)
				edge_rms = atof(at + strlen("at full resolution (RMS "));
		}
		if (v > 0)
			CHECK(edge_rms < 1.0, "%s: the box refined to an RMS of %.2f px (< 1 px)", name,
			      edge_rms);
		CHECK(has_warning(r, "orientation chosen from the patches"),
		      "%s: the orientation decision is not reported", name);
		CHECK(!has_warning(r, "orientation uncertain"), "%s: orientation uncertain", name);
		/* The turns are screened on a sparse sample and only the best is sampled
		 * whole: the next best's misfit is the sparse one (a sparse sample once read as
		 * out of frame, so every turn was sampled whole). The .cht chart's patches are
		 * large enough here for a sparse sample; the frame layout's are not. */
		CHECK(!strstr(name, ".cht") || has_warning(r, "row and column)"),
		      "%s: the next best turn was sampled whole, not screened sparsely", name);
		if (!tagless)
			CHECK(has_warning(r, "fell back to the tagless detector"),
			      "%s: the fallback is not reported", name);
		CHECK(r->npatches == 24, "%s: %d patches", name, r->npatches);
		worst = 0;
		int n = 0, px = extra_column(truth, "PIXEL_X"), py = extra_column(truth, "PIXEL_Y");
		for (int i = 0; i < r->npatches; i++) {
			const kg_chart_sample *p = &r->patches[i];
			/* truth ids are the layout's own, or (frame layout) its aliases' spectra ids */
			int k = kg_patchset_find(truth, p->id);
			CHECK(k >= 0, "%s: patch %s not in the truth", name, p->id);
			CHECK(!(p->flags & KG_CHART_FLAG_REJECTED), "%s: patch %s rejected", name, p->id);
			if (k < 0 || (p->flags & KG_CHART_FLAG_REJECTED))
				continue;
			for (int c = 0; c < 3; c++) {
				double d = fabs(p->rgb[c] - truth->rgb[k][c]);
				worst = fmax(worst, d);
				CHECK(d <= TOLERANCE, "%s: patch %s channel %d: %.5f vs truth %.5f", name, p->id,
				      c, p->rgb[c], truth->rgb[k][c]);
			}
			if (px >= 0 && py >= 0) {
				double cx = 0, cy = 0;
				for (int q = 0; q < 4; q++) {
					cx += p->quad[q][0] / 4;
					cy += p->quad[q][1] / 4;
				}
				const double *e = truth->extra + (size_t)k * truth->nextra;
				double side = sqrt(fabs((p->quad[1][0] - p->quad[0][0]) * (p->quad[3][1] - p->quad[0][1]) -
				                        (p->quad[1][1] - p->quad[0][1]) * (p->quad[3][0] - p->quad[0][0])));
				CHECK(hypot(cx - e[px], cy - e[py]) < 0.25 * side,
				      "%s: patch %s sampled at (%.1f, %.1f), truth centre (%.1f, %.1f)", name,
				      p->id, cx, cy, e[px], e[py]);
			}
			n++;
		}
		CHECK(n == 24, "%s: %d patches compared", name, n);
		printf("| %-44s | %14.3f | %7.2f |\n", name, 100 * worst, r->tag_seconds);
		if (v == 1) {
			two = r;
			r = NULL;
		} else if (v == 2 && two) {
			int same = !memcmp(two->H, r->H, sizeof(r->H));
			for (int i = 0; i < 24 && same; i++)
				for (int c = 0; c < 3; c++)
					same = same && two->patches[i].rgb[c] == r->patches[i].rgb[c];
			CHECK(same, "%s: other patch values than at 2 threads", name);
		}
	}
	kg_chart_result_free(&two);
done:
	kg_chart_result_free(&r);
	kg_patchset_free(&truth);
	kg_image_free(&im);
	remove(img);
	remove(truth_path);
	free(img);
	free(truth_path);
	return worst;
}

/* No chart: a grey gradient with noise. */
static void check_no_chart(void)
{
	kg_image *im = NULL;
	kg_err err = {{0}};
	if (kg_image_new(1200, 900, 3, &im, &err)) {
		CHECK(0, "%s", err.msg);
		return;
	}
	unsigned s = 12345;
	for (long i = 0; i < 1200L * 900 * 3; i++) {
		s = s * 1103515245u + 12345u;
		im->data[i] = (float)(0.2 + 0.3 * (i / 3 % 1200) / 1200.0 + 0.01 * ((s >> 16) & 255) / 255.0);
	}
	kg_chart_result *r = NULL;
	int ret = detect(frame_layout, im, 1, &r, &err);
	CHECK(ret == KG_ENOENT, "no chart (--tagless): code %d, expected KG_ENOENT (%s)", ret,
	      err.msg);
	CHECK(strstr(err.msg, "mcc") && strstr(err.msg, "ColorChecker"),
	      "no chart (--tagless): message: %s", err.msg);
	printf("  no chart, tagless: %s\n", err.msg);
	kg_chart_result_free(&r);
	/* refused on the reduced copy, then on the full image, as before */
	ret = detect_at(frame_layout, im, 1, 2, 2, &r, &err);
	CHECK(ret == KG_ENOENT && strstr(err.msg, "mcc"),
	      "no chart (--tagless, reduced 2 x 2): code %d, expected KG_ENOENT (%s)", ret, err.msg);
	kg_chart_result_free(&r);
	ret = detect(frame_layout, im, 0, &r, &err);
	CHECK(ret == KG_ENOENT, "no chart: code %d, expected KG_ENOENT (%s)", ret, err.msg);
	CHECK(strstr(err.msg, "tag") && strstr(err.msg, "mcc"),
	      "no chart: the message should name both detectors: %s", err.msg);
	printf("  no chart, tags then mcc: %s\n", err.msg);
	kg_chart_result_free(&r);
	kg_image_free(&im);
}

static void check_cli(void)
{
	char log[8192];
	char *img = strdup(cs_path("cli.tif")), *truth = strdup(cs_path("cli.truth.cgats"));
	char *out = strdup(cs_path("cli.cgats"));
	if (render(CHT, spectra_cht, "10", "0", "8", img, truth) == 0) {
		char *argv[] = {(char *)kogei, "chart", "detect", "--layout", CHT, "--tagless", img,
		                "-o", out, NULL};
		int rc = cs_run(argv, log, sizeof(log));
		CHECK(rc == 0, "chart detect --tagless: exit %d: %s", rc, log);
		CHECK(strstr(log, "tagless detector"), "chart detect --tagless: no warning: %s", log);
		FILE *fp = fopen(out, "r");
		char text[16384] = "";
		size_t n = fp ? fread(text, 1, sizeof(text) - 1, fp) : 0;
		text[n] = '\0';
		if (fp)
			fclose(fp);
		CHECK(strstr(text, "opencv-mcc") != NULL, "patch file does not name the detector");
	}
	free(img);
	free(truth);
	free(out);
}

int main(int argc, char **argv)
{
	if (argc < 2) {
		fprintf(stderr, "usage: %s KOGEI\n", argv[0]);
		return 2;
	}
	kogei = argv[1];
	snprintf(frame_layout, sizeof(frame_layout), "%s/fixtures/charts/colorchecker24-frame.json",
	         KG_SOURCE_ROOT);
	{
		/* Built without the tagless detector: skip. */
		kg_image *im = NULL;
		kg_chart_result *r = NULL;
		kg_err err = {{0}};
		int ret = kg_image_new(64, 64, 3, &im, &err);
		if (!ret)
			ret = detect(frame_layout, im, 1, &r, &err);
		kg_chart_result_free(&r);
		kg_image_free(&im);
		if (ret == KG_ENOTSUP)
			kg_test_skip("built without OpenCV mcc: no tagless detection");
	}
	check_no_chart();
	const char *ref = kg_test_reference_dir();
	snprintf(spectra_csv, sizeof(spectra_csv), "%s/charts/colorchecker24_babelcolor_avg.csv",
	         ref);
	if (!kg_test_file_exists(spectra_csv))
		kg_test_skip("reference ColorChecker spectra are missing");
	cs_scratch_dir("chart-mcc");
	snprintf(camera, sizeof(camera), "%s", cs_path("camera.csv"));
	cs_write_camera(camera);
	snprintf(spectra_cht, sizeof(spectra_cht), "%s", cs_path("cc-cht.csv"));
	write_cht_spectra(spectra_csv, spectra_cht);

	printf("| %-44s | max err (%% FS) | detector (s) |\n|%s|----------------|--------------|\n",
	       "image", "----------------------------------------------");
	if (kg_test_file_exists(CHT)) {
		static const char *tilts[] = {"0", "20"}, *rotations[] = {"0", "90", "180"};
		for (int t = 0; t < 2; t++)
			for (int k = 0; k < 3; k++) {
				char name[96];
				snprintf(name, sizeof(name), "ColorChecker.cht, tilt %s, rotate %s", tilts[t],
				         rotations[k]);
				check_case(name, CHT, spectra_cht, tilts[t], rotations[k], "16", 1);
			}
		check_case("ColorChecker.cht, tilt 20, rotate 30, 8 bit", CHT, spectra_cht, "20", "30",
		           "8", 1);
		check_cli();
	} else {
		printf("  %s missing (package argyll-ref): .cht cases skipped\n", CHT);
	}
	check_case("frame layout, black paper, fallback", frame_layout, spectra_csv, "20", "90",
	           "16", 0);
	cs_scratch_remove();
	return kg_test_done("chart-mcc");
}
