/* `kogei classify` refuses what the declared materials do not explain: the unknown
 * and background classes, the mask, and the noise bound of the unknown test. Needs
 * ../shared/reference (skipped without it).
 *
 * Setup: fx_paper_calibration, and `kogei sim image` of the ten materials of the
 * paper (40 x 40 pixels each, normal incidence) on a black background (reflectance 0)
 * and on a dark one (reflectance 0.005), with the noise full well 20000 e-, read
 * noise 10 e- rms, 12 bits. The variance image is that noise model's variance per
 * pixel and channel, rho / 20000 + (10 / 20000)^2 + (1 / 4095)^2 / 12 with rho the
 * noise-free value (what acquire's variance.tif estimates from the frames).
 *
 * Asserts (floors below what this test measured when written, printed in its log):
 *  - background: every background pixel of both scenes is labelled background
 *    (before the background class they were all urushi), and urushi keeps recall
 *    >= 0.95 (measured 1.000);
 *  - unknown: with --only gold,silver the pixels of copper, urushi and the four
 *    shibuichi other than -shiro are >= 0.90 unknown each (measured: copper 0.952,
 *    the others 1.000), and gold and silver keep recall >= 0.98 (1.000 without the
 *    unknown test and with it); with all ten declared the accuracy stays >= 0.75
 *    (0.769 without the unknown test and with it). Shibuichi-shiro (a silver-rich
 *    alloy) is explained by silver and shakudo partly by gold: printed, not asserted;
 *  - the bound scales with the noise: among the pixels of the eight materials
 *    outside gold,silver, the variance divided by 16 (--frames 16) gives more unknown
 *    pixels than the variance as it is, and that more than 16 times the variance
 *    (measured 11066, 10873, 7997 of 12800);
 *  - a mask: pixels it marks 0 are background and all others keep the labels of the
 *    unmasked run; a mask of another size is refused naming both sizes and the file;
 *  - LABELS.json counts and fractions of unknown and background match the map, and
 *    their confidence is NaN. */
#include <jansson.h>

#include "apply_fixture.h"

#define NM 10
static const char only[] = "gold,silver,copper,shibuichi-nami,shibuichi-shiro,shibuichi-jo,"
                           "shibuichi-nami-uchisanbu,shibuichi-nami-sotosanbu,shakudo,urushi";
enum { GOLD = 1, SILVER, COPPER, NAMI, SHIRO, JO, UCHISANBU, SOTOSANBU, SHAKUDO, URUSHI };

typedef struct map {
	float *v;
	int w, h;
	char names[NM + 4][64];
	int nnames;
} map;

static int map_read(const char *hdr, map *m)
{
	kg_envi *e = NULL;
	memset(m, 0, sizeof(*m));
	m->v = fx_read_envi(hdr, &e);
	if (!m->v)
		return -1;
	m->w = e->meta.samples;
	m->h = e->meta.lines;
	for (int i = 0; i < e->meta.classes && i < NM + 4; i++)
		snprintf(m->names[m->nnames++], sizeof(m->names[0]), "%s", e->meta.class_names[i]);
	kg_envi_close(&e);
	return 0;
}

static void map_free(map *m)
{
	free(m->v);
	m->v = NULL;
}

static int label_of(const map *m, const char *name)
{
	for (int i = 0; i < m->nnames; i++)
		if (strcmp(m->names[i], name) == 0)
			return i;
	return -1;
}

/* Fraction of the pixels of truth class t (t < 0: every material) with label l. */
static double fraction(const map *lab, const map *truth, int t, int l, long *count)
{
	long n = 0, hit = 0;
	for (int i = 0; i < lab->w * lab->h; i++) {
		int ti = (int)truth->v[i];
		if (t >= 0 ? ti != t : ti == 0)
			continue;
		n++;
		hit += (int)lab->v[i] == l;
	}
	if (count)
		*count = hit;
	return n ? (double)hit / (double)n : 0.0;
}

/* kogei classify with the calibration and library of the test, then the options. */
static int classify(const char *out, const char *scene, const char *set, ...)
{
	static char lib[4096];
	snprintf(lib, sizeof(lib), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	const char *args[40] = {"classify", "--method", "eq11", "--calib", fx_path("cam.json"),
	                        "--materials", lib, "--only", set, scene, "-o", out};
	int n = 12;
	va_list ap;
	va_start(ap, set);
	for (const char *a; n < 40 && (a = va_arg(ap, const char *));)
		args[n++] = a;
	va_end(ap);
	return fx_runv(args, n);
}
#define CLASSIFY(...) classify(__VA_ARGS__, (char *)NULL)

/* The noise model's variance of the noisy scene, from the noise-free one. */
static int write_variance(const char *scene0, const char *path, double scale)
{
	kg_image *img = NULL;
	kg_err err = {{0}};
	int rc = kg_image_read(scene0, &img, &err);
	if (!rc) {
		size_t n = (size_t)img->width * img->height * 3;
		const double q = 1.0 / 4095.0;
		for (size_t i = 0; i < n; i++) {
			double rho = img->data[i] > 0 ? img->data[i] : 0.0;
			img->data[i] = (float)(scale * (rho / 20000.0 + pow(10.0 / 20000.0, 2) +
			                                q * q / 12));
		}
		rc = kg_image_write(img, path, 32, &err);
	}
	if (rc)
		fprintf(stderr, "%s: %s\n", path, err.msg);
	kg_image_free(&img);
	return rc;
}

/* A grey mask of w x h: 0 on the left half of the columns, 1 elsewhere. */
static int write_mask(const char *path, int w, int h, int bits)
{
	kg_image *m = NULL;
	kg_err err = {{0}};
	int rc = kg_image_new(w, h, 1, &m, &err);
	for (int i = 0; !rc && i < w * h; i++)
		m->data[i] = i % w < w / 2 ? 0.0f : 1.0f;
	if (!rc)
		rc = kg_image_write(m, path, bits, &err);
	if (rc)
		fprintf(stderr, "%s: %s\n", path, err.msg);
	kg_image_free(&m);
	return rc;
}

static void check_background(const char *scene, const char *truth_hdr, const char *what)
{
	const char *out = fx_path(what);
	CHECK(CLASSIFY(out, scene, only) == 0, "%s: %s", what, fx_errs);
	map lab, truth;
	if (map_read(out, &lab) || map_read(truth_hdr, &truth))
		return;
	int bg = label_of(&lab, "background");
	CHECK(bg == NM + 2 && label_of(&lab, "unknown") == NM + 1,
	      "%s: classes unknown %d and background %d, expected %d and %d", what,
	      label_of(&lab, "unknown"), bg, NM + 1, NM + 2);
	long n = 0, as_urushi = 0;
	double f = fraction(&lab, &truth, 0, bg, &n);
	fraction(&lab, &truth, 0, URUSHI, &as_urushi);
	double urushi = fraction(&lab, &truth, URUSHI, URUSHI, NULL);
	printf("%s: background pixels labelled background %.4f (%ld), urushi %ld; urushi "
	       "recall %.4f\n",
	       what, f, n, as_urushi, urushi);
	CHECK(f == 1.0, "%s: %.4f of the background labelled background", what, f);
	CHECK(urushi >= 0.95, "%s: urushi recall %.4f < 0.95", what, urushi);
	map_free(&lab);
	map_free(&truth);
}

/* Unknown pixels among those of materials outside gold, silver. */
static long unknown_outside(const char *out, const map *truth)
{
	map lab;
	if (map_read(out, &lab))
		return -1;
	long n = 0;
	int unk = label_of(&lab, "unknown");
	for (int i = 0; i < lab.w * lab.h; i++)
		n += (int)truth->v[i] > SILVER && (int)lab.v[i] == unk;
	map_free(&lab);
	return n;
}

/* LABELS.json of stem agrees with its map lab; noise is "variance image" or "model". */
static void check_json(const char *stem, const map *lab, const char *noise)
{
	char p[600];
	snprintf(p, sizeof(p), "%s.json", fx_path(stem));
	json_t *root = NULL;
	kg_err err = {{0}};
	CHECK(kg_json_load(p, &root, &err) == 0, "%s: %s", p, err.msg);
	json_t *classes = json_object_get(root, "classes");
	long npix = (long)lab->w * lab->h;
	for (size_t j = 0; j < json_array_size(classes); j++) {
		json_t *c = json_array_get(classes, j);
		const char *name = json_string_value(json_object_get(c, "name"));
		if (!name || (strcmp(name, "unknown") && strcmp(name, "background")))
			continue;
		long label = (long)json_integer_value(json_object_get(c, "label")), count = 0;
		for (long i = 0; i < npix; i++)
			count += (long)lab->v[i] == label;
		long px = (long)json_integer_value(json_object_get(c, "pixels"));
		double fr = json_real_value(json_object_get(c, "fraction"));
		CHECK(px == count && fabs(fr - (double)count / (double)npix) < 1e-12,
		      "%s: %s: %ld pixels (fraction %g), the map has %ld", p, name, px, fr, count);
	}
	json_t *u = json_object_get(json_object_get(root, "refusal"), "unknown");
	const char *said = json_string_value(json_object_get(u, "noise"));
	CHECK(json_is_number(json_object_get(u, "threshold")) &&
	              json_integer_value(json_object_get(u, "dof")) == 3 && said &&
	              strcmp(said, noise) == 0,
	      "%s: refusal.unknown: threshold, dof 3 and noise '%s' (says '%s')", p, noise,
	      said ? said : "nothing");
	json_decref(root);
	snprintf(p, sizeof(p), "%s_confidence.hdr", fx_path(stem));
	float *conf = fx_read_envi(p, NULL);
	long bad = 0;
	for (long i = 0; conf && i < npix; i++)
		bad += (long)lab->v[i] > 2 && !isnan(conf[i]);
	CHECK(conf && bad == 0, "%s: %ld unknown or background pixels with a confidence", p, bad);
	free(conf);
}

int main(int argc, char **argv)
{
	fx_setup(argc, argv);
	char sitecam[8192], lib[4096];
	snprintf(lib, sizeof(lib), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	const char *scene = fx_path("scene.tif"), *truth_hdr = fx_path("truth.hdr");
	const char *dark = fx_path("dark.tif"), *dark_truth = fx_path("dark_truth.hdr");
	const char *scene0 = fx_path("scene0.tif"), *var = fx_path("var.tif");
	const char *var16 = fx_path("var16.tif");
	int ok = fx_paper_calibration(fx_path("cam.json"), sitecam, sizeof(sitecam));
	if (ok == 77)
		kg_test_skip("ColorChecker or camera files missing from ../shared/reference");
	ok = ok &&
	     FX_RUN("sim", "image", "--materials", lib, "--only", only, "--camera", sitecam,
	            "--illuminant", "D65", "--patch-size", "40", "--depth", "16", "--noise",
	            "20000:10:12", "--seed", "1", "-o", scene, "--truth-labels", truth_hdr) == 0 &&
	     FX_RUN("sim", "image", "--materials", lib, "--only", only, "--camera", sitecam,
	            "--illuminant", "D65", "--patch-size", "40", "--depth", "16", "--noise",
	            "20000:10:12", "--seed", "2", "--background", "0.005", "-o", dark,
	            "--truth-labels", dark_truth) == 0 &&
	     FX_RUN("sim", "image", "--materials", lib, "--only", only, "--camera", sitecam,
	            "--illuminant", "D65", "--patch-size", "40", "--depth", "float", "-o",
	            scene0) == 0 &&
	     write_variance(scene0, var, 1.0) == 0 && write_variance(scene0, var16, 16.0) == 0;
	CHECK(ok, "simulation and calibration: %s", fx_errs);
	if (!ok)
		return kg_test_done("apply-refuse");

	check_background(scene, truth_hdr, "black.hdr");
	check_background(dark, dark_truth, "dark.hdr");

	map truth, lab;
	if (map_read(truth_hdr, &truth))
		return kg_test_done("apply-refuse");

	/* Materials outside the declared set become unknown. */
	const char *gs = fx_path("gs.hdr");
	CHECK(CLASSIFY(gs, scene, "gold,silver", "--variance", var) == 0, "gold,silver: %s",
	      fx_errs);
	if (map_read(gs, &lab) == 0) {
		int unk = label_of(&lab, "unknown");
		CHECK(unk == 3 && label_of(&lab, "background") == 4, "gold,silver: classes");
		const int outside[] = {COPPER, NAMI, JO, UCHISANBU, SOTOSANBU, URUSHI};
		const char *outside_name[] = {"copper",     "shibuichi-nami", "shibuichi-jo",
		                              "-uchisanbu", "-sotosanbu",     "urushi"};
		for (int i = 0; i < 6; i++) {
			double f = fraction(&lab, &truth, outside[i], unk, NULL);
			printf("gold,silver: %s pixels unknown %.4f\n", outside_name[i], f);
			CHECK(f >= 0.90, "gold,silver: %s pixels unknown %.4f < 0.90",
			      outside_name[i], f);
		}
		printf("gold,silver: shibuichi-shiro unknown %.4f, shakudo unknown %.4f "
		       "(not asserted)\n",
		       fraction(&lab, &truth, SHIRO, unk, NULL),
		       fraction(&lab, &truth, SHAKUDO, unk, NULL));
		double rg = fraction(&lab, &truth, GOLD, 1, NULL),
		       rs = fraction(&lab, &truth, SILVER, 2, NULL);
		printf("gold,silver: recall gold %.4f, silver %.4f\n", rg, rs);
		CHECK(rg >= 0.98 && rs >= 0.98, "gold,silver: recall gold %.4f, silver %.4f < 0.98",
		      rg, rs);
		check_json("gs", &lab, "variance image");
		map_free(&lab);
	}
	/* Without a variance image the stated noise model, and LABELS.json says so. */
	const char *gs_model = fx_path("gs_model.hdr");
	CHECK(CLASSIFY(gs_model, scene, "gold,silver") == 0, "gold,silver, no variance: %s",
	      fx_errs);
	if (map_read(gs_model, &lab) == 0) {
		printf("gold,silver without --variance: unknown among the 12800 pixels outside %ld\n",
		       unknown_outside(gs_model, &truth));
		check_json("gs_model", &lab, "model");
		map_free(&lab);
	}

	/* The declared set keeps its accuracy. */
	const char *all = fx_path("all.hdr");
	CHECK(CLASSIFY(all, scene, only, "--variance", var) == 0, "all: %s", fx_errs);
	if (map_read(all, &lab) == 0) {
		long n = 0, right = 0, unknown = 0;
		for (int i = 0; i < lab.w * lab.h; i++) {
			int t = (int)truth.v[i];
			if (t == 0)
				continue;
			n++;
			right += (int)lab.v[i] == t;
			unknown += (int)lab.v[i] == NM + 1;
		}
		double acc = (double)right / (double)n;
		printf("all ten declared: accuracy %.4f, unknown %ld of %ld\n", acc, unknown, n);
		CHECK(acc >= 0.75, "all ten declared: accuracy %.4f < 0.75", acc);
		map_free(&lab);
	}

	/* More noise, a looser bound: fewer unknown among the same off-library
	 * pixels. */
	const char *f16 = fx_path("gs_frames16.hdr"), *v16 = fx_path("gs_var16.hdr");
	CHECK(CLASSIFY(f16, scene, "gold,silver", "--variance", var, "--frames", "16") == 0 &&
	              CLASSIFY(v16, scene, "gold,silver", "--variance", var16) == 0,
	      "noise levels: %s", fx_errs);
	long u_low = unknown_outside(f16, &truth), u_mid = unknown_outside(gs, &truth),
	     u_high = unknown_outside(v16, &truth);
	printf("unknown among the %d pixels outside gold,silver: variance / 16 %ld, "
	       "variance %ld, "
	       "variance x 16 %ld\n",
	       8 * 1600, u_low, u_mid, u_high);
	CHECK(u_low > u_mid && u_mid > u_high && u_high >= 0,
	      "unknown counts %ld, %ld, %ld: expected fewer with more noise", u_low, u_mid, u_high);

	/* A mask keeps out what it marks, and nothing else changes. */
	const char *mask = fx_path("mask.png"), *bad_mask = fx_path("bad_mask.tif");
	const char *masked = fx_path("masked.hdr");
	CHECK(write_mask(mask, truth.w, truth.h, 8) == 0 &&
	              write_mask(bad_mask, truth.w - 1, truth.h, 16) == 0,
	      "masks written");
	CHECK(CLASSIFY(masked, scene, "gold,silver", "--variance", var, "--mask", mask) == 0,
	      "masked: %s", fx_errs);
	map ref;
	if (map_read(masked, &lab) == 0 && map_read(gs, &ref) == 0) {
		long wrong_bg = 0, changed = 0;
		for (int i = 0; i < lab.w * lab.h; i++) {
			if (i % lab.w < lab.w / 2)
				wrong_bg += (int)lab.v[i] != 4;
			else
				changed += lab.v[i] != ref.v[i];
		}
		CHECK(wrong_bg == 0 && changed == 0,
		      "masked: %ld masked pixels not background, %ld others changed", wrong_bg,
		      changed);
		map_free(&lab);
		map_free(&ref);
	}
	char want[2][64];
	snprintf(want[0], sizeof(want[0]), "%d x %d", truth.w - 1, truth.h);
	snprintf(want[1], sizeof(want[1]), "%d x %d", truth.w, truth.h);
	int before = fx_count_files();
	int rc = CLASSIFY(fx_path("refused.hdr"), scene, "gold,silver", "--mask", bad_mask);
	CHECK(rc == 1 && strstr(fx_errs, want[0]) && strstr(fx_errs, want[1]) &&
	              strstr(fx_errs, "bad_mask.tif"),
	      "wrong-size mask: exit %d, message '%s' should name %s, %s and the file", rc, fx_errs,
	      want[0], want[1]);
	CHECK(fx_count_files() == before, "wrong-size mask: files left behind");
	map_free(&truth);

	rc = kg_test_done("apply-refuse");
	if (rc == 0)
		fx_cleanup();
	else
		fprintf(stderr, "files kept in %s\n", fx_dir);
	return rc;
}
