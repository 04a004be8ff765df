/* `kogei sim patches` and `kogei sim image` end to end, with inputs written here (a
 * synthetic camera, a small chart and a small material library), so no reference
 * data are needed:
 *  - bad inputs exit 1 with a message naming the culprit and leave no file behind;
 *  - bad usage exits 2;
 *  - the image, the truth cube and the label map read back through the core readers
 *    with the documented size, classes, labels and values.
 * Argument: the path of the kogei program. */
#include <math.h>
#include <string.h>

#include "kg_sim.h"
#include "kg_test.h"
#include "sim_test_util.h"

static const char *kogei;
static int baseline_entries;

static const char library_json[] =
    "{\"format\": \"kogei-materials/1\", \"materials\": [\n"
    " {\"name\": \"gold\", \"kind\": \"metal\", \"nk\": {\"model\": \"rakic1998-ld\", "
    "\"element\": \"Au\"}},\n"
    " {\"name\": \"silver\", \"kind\": \"metal\", \"nk\": {\"model\": \"rakic1998-ld\", "
    "\"element\": \"Ag\"}},\n"
    " {\"name\": \"copper\", \"kind\": \"metal\", \"nk\": {\"model\": \"rakic1998-ld\", "
    "\"element\": \"Cu\"}},\n"
    " {\"name\": \"shibuichi\", \"kind\": \"alloy\", \"components\": [\n"
    "   {\"material\": \"silver\", \"fraction\": 0.25},\n"
    "   {\"material\": \"copper\", \"fraction\": 0.75}]},\n"
    " {\"name\": \"urushi\", \"kind\": \"dielectric\", \"n\": 1.5, \"body\": 0.03}\n"
    "]}\n";

/* Gaussian r, g, b sensitivities; first..last nm every 5 nm. */
static void write_camera(const char *path, int first, int last)
{
	FILE *fp = fopen(path, "w");
	fprintf(fp, "wavelength_nm,r,g,b\n");
	for (int wl = first; wl <= last; wl += 5) {
		double r = exp(-0.5 * pow((wl - 600) / 30.0, 2));
		double g = exp(-0.5 * pow((wl - 540) / 35.0, 2));
		double b = 0.7 * exp(-0.5 * pow((wl - 460) / 25.0, 2));
		fprintf(fp, "%d,%.9f,%.9f,%.9f\n", wl, r, g, b);
	}
	fclose(fp);
}

#define NPATCH 5

static double patch_value(int p, int wl)
{
	return 0.05 + 0.15 * p + 0.1 * sin((wl - 400) / 60.0 + p);
}

static void write_chart(const char *path)
{
	FILE *fp = fopen(path, "w");
	fprintf(fp, "patch,name");
	for (int wl = 400; wl <= 700; wl += 10)
		fprintf(fp, ",%d", wl);
	fprintf(fp, "\n");
	for (int p = 0; p < NPATCH; p++) {
		fprintf(fp, "P%d,patch %d", p + 1, p + 1);
		for (int wl = 400; wl <= 700; wl += 10)
			fprintf(fp, ",%.6f", patch_value(p, wl));
		fprintf(fp, "\n");
	}
	fclose(fp);
}

/* Run kogei with the given arguments (NULL-terminated after argv[0]). */
static int run(char *errbuf, size_t len, ...)
{
	char *argv[64];
	int n = 0;
	argv[n++] = (char *)kogei;
	va_list ap;
	va_start(ap, len);
	for (char *a; n < 63 && (a = va_arg(ap, char *));)
		argv[n++] = a;
	va_end(ap);
	argv[n] = NULL;
	return sim_run(argv, errbuf, len);
}

#define RUN(...) run(errbuf, sizeof(errbuf), __VA_ARGS__, (char *)NULL)

static void expect_input_error(int rc, const char *errbuf, const char *needle,
                               const char *what)
{
	CHECK(rc == 1, "%s: exit %d, expected 1 (%s)", what, rc, errbuf);
	CHECK(strstr(errbuf, needle) != NULL, "%s: message does not mention '%s': %s", what,
	      needle, errbuf);
	CHECK(sim_scratch_count() == baseline_entries, "%s: left %d new files behind", what,
	      sim_scratch_count() - baseline_entries);
}

static void test_bad_inputs(void)
{
	char errbuf[4096];
	char *cam = (char *)kg_test_path("cam.csv"), *chart = (char *)kg_test_path("chart.csv");
	char *lib = (char *)kg_test_path("lib.json"), *out = (char *)kg_test_path("out.cgats");
	char *tif = (char *)kg_test_path("scene.tif");
	int rc;

	rc = RUN("sim", "patches", "--spectra", chart, "--camera", (char *)kg_test_path("nope.csv"),
	         "--illuminant", "D65", "-o", out);
	expect_input_error(rc, errbuf, "nope.csv", "missing camera file");

	rc = RUN("sim", "patches", "--spectra", chart, "--camera",
	         (char *)kg_test_path("short.csv"), "--illuminant", "D65", "-o", out);
	expect_input_error(rc, errbuf, "short.csv", "camera not covering 400-700 nm");
	CHECK(strstr(errbuf, "420") != NULL, "message does not give the range found: %s",
	      errbuf);

	rc = RUN("sim", "patches", "--spectra", chart, "--camera", cam, "--illuminant", "D65x",
	         "-o", out);
	expect_input_error(rc, errbuf, "D65x", "unknown illuminant");

	rc = RUN("sim", "patches", "--spectra", (char *)kg_test_path("none.cgats"), "--camera", cam,
	         "--illuminant", "D65", "-o", out);
	expect_input_error(rc, errbuf, "none.cgats", "missing spectra file");

	rc = RUN("sim", "image", "--materials", lib, "--only", "gold,unobtainium", "--camera",
	         cam, "--illuminant", "D65", "-o", tif);
	expect_input_error(rc, errbuf, "unobtainium", "unknown material");
	CHECK(strstr(errbuf, "shibuichi") != NULL, "message does not list the materials: %s",
	      errbuf);

	rc = RUN("sim", "image", "--materials", (char *)kg_test_path("nolib.json"), "--camera", cam,
	         "--illuminant", "D65", "-o", tif);
	expect_input_error(rc, errbuf, "nolib.json", "missing material library");

	/* A later output that cannot be written takes the earlier ones with it. */
	rc = RUN("sim", "image", "--materials", lib, "--camera", cam, "--illuminant", "D65",
	         "-o", tif, "--truth-cube", (char *)kg_test_path("truth.hdr"), "--truth-labels",
	         (char *)kg_test_path("no/such/dir/labels.hdr"));
	expect_input_error(rc, errbuf, "labels", "unwritable label map");

	/* --extrapolate accepts the short camera. */
	rc = RUN("sim", "patches", "--spectra", chart, "--camera", (char *)kg_test_path("short.csv"),
	         "--illuminant", "D65", "--extrapolate", "-o", out);
	CHECK(rc == 0, "--extrapolate: exit %d: %s", rc, errbuf);
	CHECK(kg_test_file_exists(out), "--extrapolate: no output");
	unlink(out);
}

static void test_usage(void)
{
	char errbuf[4096];
	char *cam = (char *)kg_test_path("cam.csv"), *chart = (char *)kg_test_path("chart.csv");
	char *lib = (char *)kg_test_path("lib.json"), *out = (char *)kg_test_path("out.cgats");
	int rc;
	rc = RUN("sim", "patches", "--spectra", chart, "--camera", cam, "--illuminant", "D65");
	CHECK(rc == 2 && strstr(errbuf, "-o"), "missing -o: exit %d: %s", rc, errbuf);
	rc = RUN("sim", "patches", "--spectra", chart, "--camera", cam, "--illuminant", "D65",
	         "--noise", "1000:2", "-o", out);
	CHECK(rc == 2 && strstr(errbuf, "FULLWELL"), "bad --noise: exit %d: %s", rc, errbuf);
	rc = RUN("sim", "patches", "--spectra", chart, "--camera", cam, "--illuminant", "D65",
	         "--seed", "-4", "-o", out);
	CHECK(rc == 2 && strstr(errbuf, "--seed"), "bad --seed: exit %d: %s", rc, errbuf);
	rc = RUN("sim", "patches", "--spectra", chart, "--camera", cam, "--illuminant", "D65",
	         "--frobnicate", "-o", out);
	CHECK(rc == 2 && strstr(errbuf, "--frobnicate"), "unknown option: exit %d: %s", rc,
	      errbuf);
	rc = RUN("sim", "image", "--materials", lib, "--camera", cam, "--illuminant", "D65",
	         "--depth", "12", "-o", (char *)kg_test_path("x.tif"));
	CHECK(rc == 2 && strstr(errbuf, "depth"), "bad --depth: exit %d: %s", rc, errbuf);
	rc = RUN("sim", "image", "--camera", cam, "--illuminant", "D65", "-o",
	         (char *)kg_test_path("x.tif"));
	CHECK(rc == 2, "image without materials or spectra: exit %d", rc);
	rc = RUN("sim", "patches", "--help");
	CHECK(rc == 0, "--help: exit %d", rc);
	CHECK(sim_scratch_count() == baseline_entries, "usage errors left files behind");
}

/* Reflectance of a conductor at incidence theta straight from the Fresnel formula. */
static kg_spectrum fresnel_of(const char *element, double theta)
{
	kg_nk nk;
	kg_spectrum r = kg_spectrum_const(NAN);
	if (kg_nk_rakic1998_ld(element, &nk, NULL) != 0)
		return r;
	for (int i = 0; i < KG_NBANDS; i++)
		r.v[i] = kg_fresnel_conductor(nk.n.v[i], nk.k.v[i], 1.0, cos(theta));
	return r;
}

static void test_image(void)
{
	char errbuf[4096];
	char *cam = (char *)kg_test_path("cam.csv"), *chart = (char *)kg_test_path("chart.csv");
	char *lib = (char *)kg_test_path("lib.json");
	char *tif = (char *)kg_test_path("scene.tif"), *ftif = (char *)kg_test_path("scene_f.tif");
	char *truth = (char *)kg_test_path("truth.hdr"), *labels = (char *)kg_test_path("labels.hdr");
	int rc = RUN("sim", "image", "--spectra", chart, "--materials", lib, "--camera", cam,
	             "--illuminant", "D50", "--angle", "30", "--patch-size", "8", "--gap", "2",
	             "--columns", "4", "--background", "0.02", "-o", tif, "--truth-cube", truth,
	             "--truth-labels", labels);
	CHECK(rc == 0, "sim image: exit %d: %s", rc, errbuf);
	rc = RUN("sim", "image", "--spectra", chart, "--materials", lib, "--camera", cam,
	         "--illuminant", "D50", "--angle", "30", "--patch-size", "8", "--gap", "2",
	         "--columns", "4", "--background", "0.02", "--depth", "float", "-o", ftif);
	CHECK(rc == 0, "sim image --depth float: exit %d: %s", rc, errbuf);
	if (rc)
		return;

	/* Expected values from the library code path. */
	kg_err err = {{0}};
	kg_sim_capture c;
	CHECK(kg_sim_capture_load(&c, cam, "D50", 0.9, NULL, 0, &err) == 0, "%s", err.msg);
	kg_patchset *ps = NULL;
	kg_sim_material_set *ms = NULL;
	CHECK(kg_sim_read_spectra(chart, 0, &ps, &err) == 0, "%s", err.msg);
	CHECK(kg_sim_material_set_load(lib, NULL, 30.0, &ms, &err) == 0, "%s", err.msg);
	if (!ps || !ms)
		goto done;
	/* 4 columns of (8 + 2) + 2; patches in 2 rows, 5 materials in 2 more */
	const int W = 42, H = 42, NS = NPATCH + 5;
	/* The sim takes the material's reflectance at the stated angle, in degrees. */
	kg_spectrum gold = fresnel_of("Au", 30.0 * M_PI / 180.0);
	double worst = 0.0;
	for (int i = 0; i < KG_NBANDS; i++)
		worst = fmax(worst, fabs(gold.v[i] - ms->reflectance[0].v[i]));
	CHECK(worst < 1e-12, "gold at 30 degrees differs from Fresnel by %g", worst);

	kg_image *img = NULL, *fimg = NULL;
	CHECK(kg_image_read(tif, &img, &err) == 0, "%s", err.msg);
	CHECK(kg_image_read(ftif, &fimg, &err) == 0, "%s", err.msg);
	kg_envi *cube = NULL, *lab = NULL;
	CHECK(kg_envi_open(truth, &cube, &err) == 0, "%s", err.msg);
	CHECK(kg_envi_open(labels, &lab, &err) == 0, "%s", err.msg);
	if (!img || !fimg || !cube || !lab)
		goto close;
	CHECK(img->width == W && img->height == H && img->channels == 3 && img->bits == 16,
	      "image %dx%dx%d, %d bits; expected %dx%dx3, 16", img->width, img->height,
	      img->channels, img->bits, W, H);
	CHECK(fimg->is_float && fimg->width == W && fimg->height == H, "float image");
	CHECK(cube->meta.samples == W && cube->meta.lines == H && cube->meta.bands == KG_NBANDS &&
	          cube->meta.data_type == KG_ENVI_F32,
	      "truth cube %dx%dx%d type %d", cube->meta.samples, cube->meta.lines,
	      cube->meta.bands, (int)cube->meta.data_type);
	CHECK(cube->meta.wavelength && cube->meta.wavelength[0] == 400.0 &&
	          cube->meta.wavelength[60] == 700.0,
	      "truth cube wavelengths");
	static const char *const classes[] = {"unclassified", "gold",   "silver", "copper",
	                                      "shibuichi",    "urushi", "chart"};
	CHECK(lab->meta.classes == 7, "%d classes, expected 7", lab->meta.classes);
	for (int k = 0; k < 7 && k < lab->meta.classes && lab->meta.class_names; k++)
		CHECK(strcmp(lab->meta.class_names[k], classes[k]) == 0, "class %d: %s, expected %s",
		      k, lab->meta.class_names[k], classes[k]);
	if (img->width != W || img->height != H || cube->meta.bands != KG_NBANDS ||
	    lab->meta.samples != W || lab->meta.lines != H || cube->meta.samples != W ||
	    cube->meta.lines != H)
		goto close;

	float *truth_px = malloc((size_t)W * H * KG_NBANDS * sizeof(float));
	float *label_px = malloc((size_t)W * H * sizeof(float));
	CHECK(kg_envi_read(cube, 0, 0, W, H, KG_LAYOUT_BIP, truth_px, &err) == 0, "%s", err.msg);
	CHECK(kg_envi_read(lab, 0, 0, W, H, KG_LAYOUT_BIP, label_px, &err) == 0, "%s", err.msg);
	for (int s = 0; s < NS; s++) {
		int row = s < NPATCH ? s / 4 : 2 + (s - NPATCH) / 4;
		int col = s < NPATCH ? s % 4 : (s - NPATCH) % 4;
		int x = 2 + col * 10 + 4, y = 2 + row * 10 + 3;
		size_t p = (size_t)y * W + (size_t)x;
		const kg_spectrum *r = s < NPATCH ? &ps->spectra[s] : &ms->reflectance[s - NPATCH];
		int cls = s < NPATCH ? 6 : 1 + (s - NPATCH);
		CHECK(label_px[p] == cls, "sample %d: label %g, expected %d", s, label_px[p], cls);
		double tw = 0.0;
		for (int i = 0; i < KG_NBANDS; i++)
			tw = fmax(tw, fabs(truth_px[p * KG_NBANDS + (size_t)i] - (float)r->v[i]));
		CHECK(tw == 0.0, "sample %d: truth cube differs from its spectrum by %g", s, tw);
		if (s < NPATCH)
			CHECK(fabs(truth_px[p * KG_NBANDS + 2] - patch_value(s, 410)) < 1e-6,
			      "patch %d at 410 nm: %g, expected %g", s, truth_px[p * KG_NBANDS + 2],
			      patch_value(s, 410));
		double m[3];
		kg_sim_capture_mean(&c, r, m);
		for (int ch = 0; ch < 3; ch++) {
			CHECK_NEAR(img->data[3 * p + (size_t)ch], m[ch], 0.5 / 65535 + 1e-7,
			           "16-bit pixel");
			CHECK(fimg->data[3 * p + (size_t)ch] == (float)m[ch],
			      "float pixel of sample %d: %.9g, expected %.9g", s,
			      fimg->data[3 * p + (size_t)ch], (float)m[ch]);
		}
	}
	/* background: label 0, truth 0.02, empty last tile of the chart rows too */
	size_t corner = 0, hole = (size_t)(2 + 1 * 10 + 4) * W + (size_t)(2 + 3 * 10 + 4);
	CHECK(label_px[corner] == 0 && label_px[hole] == 0, "background labels %g %g",
	      label_px[corner], label_px[hole]);
	CHECK(truth_px[hole * KG_NBANDS + 30] == 0.02f, "background truth %g",
	      truth_px[hole * KG_NBANDS + 30]);
	free(truth_px);
	free(label_px);
close:
	kg_image_free(&img);
	kg_image_free(&fimg);
	kg_envi_close(&cube);
	kg_envi_close(&lab);
done:
	kg_patchset_free(&ps);
	kg_sim_material_set_free(&ms);
}

/* Noisy images: the same seed gives the same pixels, another seed others. */
static void test_image_seed(void)
{
	char errbuf[4096];
	char *cam = (char *)kg_test_path("cam.csv"), *lib = (char *)kg_test_path("lib.json");
	const char *outs[3] = {kg_test_path("s1.tif"), kg_test_path("s2.tif"), kg_test_path("s3.tif")};
	const char *seeds[3] = {"5", "5", "6"};
	kg_image *img[3] = {NULL, NULL, NULL};
	for (int k = 0; k < 3; k++) {
		int rc = RUN("sim", "image", "--materials", lib, "--only", "urushi, gold", "--camera",
		             cam, "--illuminant", "A", "--noise", "15000:6:12", "--seed",
		             (char *)seeds[k], "--patch-size", "16", "-o", (char *)outs[k]);
		CHECK(rc == 0, "noisy image %d: exit %d: %s", k, rc, errbuf);
		CHECK(kg_image_read(outs[k], &img[k], NULL) == 0, "read %s", outs[k]);
	}
	if (img[0] && img[1] && img[2]) {
		size_t n = (size_t)img[0]->width * img[0]->height * 3 * sizeof(float);
		CHECK(memcmp(img[0]->data, img[1]->data, n) == 0, "seed 5 twice: pixels differ");
		CHECK(memcmp(img[0]->data, img[2]->data, n) != 0, "seeds 5 and 6: same pixels");
		/* --only order: urushi first (dark), then gold */
		int W = img[0]->width;
		float u = img[0]->data[3 * (size_t)(4 + 8 * W + 8) + 1];
		float g = img[0]->data[3 * (size_t)(4 + 8 * W + 28) + 1];
		CHECK(u < g, "--only order not kept: first tile G %g, second %g", u, g);
	}
	for (int k = 0; k < 3; k++)
		kg_image_free(&img[k]);
}

/* The bundled library: every material of fixtures/materials/default.json becomes its
 * own class, in library order, and a grazing angle still gives reflectances in [0, 1]. */
static void test_default_library(void)
{
	char lib[4200], errbuf[4096];
	snprintf(lib, sizeof(lib), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	if (!kg_test_file_exists(lib)) {
		printf("no %s: default library not checked\n", lib);
		return;
	}
	char *labels = (char *)kg_test_path("default_labels.hdr");
	int rc = RUN("sim", "image", "--materials", lib, "--camera", (char *)kg_test_path("cam.csv"),
	             "--illuminant", "D65", "--angle", "80", "--patch-size", "4", "-o",
	             (char *)kg_test_path("default.tif"), "--truth-labels", labels);
	CHECK(rc == 0, "default library: exit %d: %s", rc, errbuf);
	static const char *const names[] = {
	    "gold", "silver", "copper", "shakudo", "shibuichi-nami", "shibuichi-shiro",
	    "shibuichi-jo", "shibuichi-nami-uchisanbu", "shibuichi-nami-sotosanbu", "urushi"};
	kg_envi *e = NULL;
	kg_err err = {{0}};
	CHECK(rc != 0 || kg_envi_open(labels, &e, &err) == 0, "%s", err.msg);
	if (e) {
		for (size_t k = 0; k < sizeof(names) / sizeof(names[0]); k++) {
			int found = 0;
			for (int c = 1; c < e->meta.classes && e->meta.class_names; c++)
				found |= strcmp(e->meta.class_names[c], names[k]) == 0;
			CHECK(found, "default library: no class %s", names[k]);
		}
		kg_envi_close(&e);
	}
	kg_sim_material_set *ms = NULL;
	CHECK(kg_sim_material_set_load(lib, NULL, 89.0, &ms, &err) == 0, "%s", err.msg);
	for (int m = 0; ms && m < ms->n; m++)
		for (int i = 0; i < KG_NBANDS; i++)
			CHECK(ms->reflectance[m].v[i] >= 0.0 && ms->reflectance[m].v[i] <= 1.0,
			      "%s at 89 degrees, %g nm: %g", ms->names[m], kg_band_nm(i),
			      ms->reflectance[m].v[i]);
	kg_sim_material_set_free(&ms);
}

int main(int argc, char **argv)
{
	if (argc < 2) {
		fprintf(stderr, "usage: test_sim_cli PATH-OF-KOGEI\n");
		return 1;
	}
	kogei = argv[1];
	kg_test_scratch_dir("simcli");
	write_camera(kg_test_path("cam.csv"), 380, 780);
	write_camera(kg_test_path("short.csv"), 420, 700);
	write_chart(kg_test_path("chart.csv"));
	sim_write_text(kg_test_path("lib.json"), library_json);
	baseline_entries = sim_scratch_count();
	test_bad_inputs();
	test_usage();
	test_image();
	test_image_seed();
	test_default_library();
	kg_test_scratch_remove();
	return kg_test_done("sim/cli");
}
