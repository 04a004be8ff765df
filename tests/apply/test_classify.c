/* `kogei classify` on simulated scenes of the paper's materials, with real camera
 * sensitivities and chart spectra from ../shared/reference (skipped without it).
 *
 * Setup: fx_paper_calibration (reference camera Nikon D5100 and site camera Canon EOS
 * 5D Mark II, both under D65, calibrated on the ColorChecker 24 (BabelColor average)
 * through `kogei sim patches` (noise-free), `kogei calib reference` (pca, K = 3) and
 * `kogei calib camera`).
 * Scene: `kogei sim image` of gold, silver, copper, the five shibuichi, shakudo and
 * urushi at normal incidence, 40 x 40 pixels each, seen by the site camera with
 * noise: full well 20000 e-, read noise 10 e- rms, 12 bits (shot-noise SNR 100 at
 * half scale), seed 1. Classified with --only the same ten, plain and scale-free
 * distances. The background is not scored.
 *
 * Asserts floors set below the accuracies measured when this test was written (see
 * docs/estimate.md for the matrices): overall accuracy (noisy, plain distance)
 * >= ACC_FLOOR and per class recall >= class_floor[]. Gold, silver, shibuichi-shiro,
 * shibuichi-sotosanbu and urushi separate well; copper/shakudo and shibuichi-nami/
 * -uchisanbu/-sotosanbu are close in spectrum, and the 3-dimensional estimate's
 * bias puts copper, shibuichi-nami and -uchisanbu entirely on a neighbour even
 * without noise (printed too, not asserted, like the scale-free distance, which
 * discards the brightness that separates silver from shibuichi-shiro). Also: LABELS.json, LABELS.png and the confidence
 * band exist, the JSON's pixel counts agree with the label map, and the margins of
 * classified pixels are >= 0. */
#include <jansson.h>

#include "apply_fixture.h"

#define NM 10
static const char *materials[NM] = {
	"gold", "silver", "copper", "shibuichi-nami", "shibuichi-shiro", "shibuichi-jo",
	"shibuichi-nami-uchisanbu", "shibuichi-nami-sotosanbu", "shakudo", "urushi",
};
static const char only[] = "gold,silver,copper,shibuichi-nami,shibuichi-shiro,shibuichi-jo,"
                           "shibuichi-nami-uchisanbu,shibuichi-nami-sotosanbu,shakudo,urushi";

/* Floors (fractions of the class's pixels), set with margin below what this test
 * measured when written (noisy, plain distance): overall 0.769; recall gold 1.000,
 * silver 1.000, copper 0.273, shibuichi-nami 0.176, shibuichi-shiro 1.000,
 * shibuichi-jo 0.904, shibuichi-nami-uchisanbu 0.416, shibuichi-nami-sotosanbu
 * 0.998, shakudo 0.922, urushi 1.000. */
#define ACC_FLOOR 0.70
static const double class_floor[NM] = {0.95, 0.95, 0.15, 0.05, 0.95, 0.75,
                                       0.25, 0.90, 0.80, 0.95};

/* Index of a class name among the materials, -1 for anything else. */
static int material_index(const char *name)
{
	for (int j = 0; j < NM; j++)
		if (strcmp(name, materials[j]) == 0)
			return j;
	return -1;
}

/* Map each label value of an ENVI classification file to a material index. */
static int class_map(const kg_envi *e, int *map, int nmap)
{
	const char *names = kg_envi_get(e, "class names");
	if (!names)
		return -1;
	char buf[4096];
	snprintf(buf, sizeof(buf), "%s", names);
	int n = 0;
	for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok && n < nmap;
	     tok = strtok_r(NULL, ",", &save)) {
		while (*tok == ' ' || *tok == '\n')
			tok++;
		char *end = tok + strlen(tok);
		while (end > tok && (end[-1] == ' ' || end[-1] == '\n'))
			*--end = '\0';
		map[n++] = material_index(tok);
	}
	return n;
}

/* Confusion matrix of labels against truth; returns overall accuracy. */
static double confusion(const char *title, const char *labels_hdr, const char *truth_hdr,
                        double recall[NM])
{
	kg_envi *el = NULL, *et = NULL;
	float *lab = fx_read_envi(labels_hdr, &el), *tru = fx_read_envi(truth_hdr, &et);
	CHECK(lab && tru, "%s: label maps read back", title);
	if (!lab || !tru) {
		free(lab);
		free(tru);
		kg_envi_close(&el);
		kg_envi_close(&et);
		return 0;
	}
	int lmap[256], tmap[256];
	int nl = class_map(el, lmap, 256), nt = class_map(et, tmap, 256);
	CHECK(nl == NM + 3 && nt >= NM + 1, "%s: %d and %d classes", title, nl, nt);
	long cm[NM][NM] = {{0}}, row[NM] = {0}, correct = 0, total = 0, unclassified = 0;
	size_t n = (size_t)el->meta.samples * el->meta.lines;
	for (size_t i = 0; i < n; i++) {
		int t = (int)tru[i] < nt ? tmap[(int)tru[i]] : -1;
		if (t < 0)
			continue; /* background */
		int l = (int)lab[i] < nl ? lmap[(int)lab[i]] : -1;
		total++;
		row[t]++;
		if (l < 0) {
			unclassified++;
			continue;
		}
		cm[t][l]++;
		correct += l == t;
	}
	printf("\n%s: confusion matrix (rows: true material, columns: label; %ld pixels, "
	       "%ld unclassified, unknown or background)\n%-26s",
	       title, total, unclassified, "");
	for (int j = 0; j < NM; j++)
		printf(" %5.5s", materials[j] + (strncmp(materials[j], "shibuichi-", 10) ? 0 : 10));
	printf(" %7s\n", "recall");
	for (int t = 0; t < NM; t++) {
		printf("%-26s", materials[t]);
		for (int j = 0; j < NM; j++)
			printf(" %5ld", cm[t][j]);
		recall[t] = row[t] ? (double)cm[t][t] / (double)row[t] : 0;
		printf(" %7.3f\n", recall[t]);
	}
	double acc = total ? (double)correct / (double)total : 0;
	printf("%s: overall accuracy %.4f\n", title, acc);
	free(lab);
	free(tru);
	kg_envi_close(&el);
	kg_envi_close(&et);
	return acc;
}

static void check_side_files(const char *stem)
{
	char p[600];
	snprintf(p, sizeof(p), "%s.png", fx_path(stem));
	CHECK(kg_test_file_exists(p), "%s missing", p);
	snprintf(p, sizeof(p), "%s_confidence.hdr", fx_path(stem));
	kg_envi *e = NULL;
	float *conf = fx_read_envi(p, &e);
	snprintf(p, sizeof(p), "%s.hdr", fx_path(stem));
	float *lab = fx_read_envi(p, NULL);
	CHECK(conf && lab, "%s: confidence and labels read back", stem);
	long counts[NM + 3] = {0};
	if (conf && lab) {
		int bad = 0;
		size_t n = (size_t)e->meta.samples * e->meta.lines;
		for (size_t i = 0; i < n; i++) {
			int l = (int)lab[i];
			if (l >= 0 && l <= NM + 2)
				counts[l]++;
			bad += l > 0 && l <= NM && !(conf[i] >= 0);
			bad += (l == 0 || l > NM) && !isnan(conf[i]);
		}
		CHECK(bad == 0, "%s: %d margins negative or misplaced", stem, bad);
	}
	snprintf(p, sizeof(p), "%s.json", fx_path(stem));
	json_t *root = NULL;
	kg_err err = {{0}};
	CHECK(kg_json_load(p, &root, &err) == 0, "%s: %s", p, err.msg);
	json_t *classes = root ? json_object_get(root, "classes") : NULL;
	CHECK(json_is_array(classes) && json_array_size(classes) == NM + 3,
	      "%s: expected %d classes", p, NM + 3);
	for (size_t j = 0; classes && j < json_array_size(classes); j++) {
		json_t *c = json_array_get(classes, j);
		long px = (long)json_integer_value(json_object_get(c, "pixels"));
		CHECK(j > NM + 2 || px == counts[j], "%s: class %zu: %ld pixels, the map has %ld", p, j,
		      px, j <= NM + 2 ? counts[j] : -1L);
		if (j > 0 && j <= NM && px > 0) {
			json_t *ms = json_object_get(c, "mean_spectrum");
			CHECK(json_is_array(ms) && json_array_size(ms) == KG_NBANDS,
			      "%s: class %zu: mean spectrum", p, j);
			CHECK(json_is_number(json_object_get(json_object_get(c, "confidence"), "median")),
			      "%s: class %zu: median margin", p, j);
		}
	}
	json_decref(root);
	free(conf);
	free(lab);
	kg_envi_close(&e);
}

int main(int argc, char **argv)
{
	fx_setup(argc, argv);
	char sitecam[8192], lib[4096];
	snprintf(lib, sizeof(lib), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	const char *cam = fx_path("cam.json");
	const char *scene = fx_path("scene.tif"), *truth = fx_path("truth.hdr");
	const char *scene0 = fx_path("scene0.tif"), *truth0 = fx_path("truth0.hdr");
	int ok = fx_paper_calibration(cam, sitecam, sizeof(sitecam));
	if (ok == 77)
		kg_test_skip("ColorChecker or camera files missing from ../shared/reference");
	ok = ok &&
	     FX_RUN("sim", "image", "--materials", lib, "--only", only, "--camera", sitecam,
	            "--illuminant", "D65", "--patch-size", "40", "--depth", "16", "--noise",
	            "20000:10:12", "--seed", "1", "-o", scene, "--truth-labels", truth) == 0 &&
	     FX_RUN("sim", "image", "--materials", lib, "--only", only, "--camera", sitecam,
	            "--illuminant", "D65", "--patch-size", "40", "--depth", "float", "-o", scene0,
	            "--truth-labels", truth0) == 0;
	CHECK(ok, "simulation and calibration: %s", fx_errs);
	if (!ok)
		return kg_test_done("apply-classify");

	double recall[NM], recall_sf[NM], recall0[NM];
	CHECK(FX_RUN("classify", "--method", "eq11", "--calib", cam, "--materials", lib, "--only", only, scene0, "-o",
	             fx_path("labels0.hdr")) == 0,
	      "classify noise-free: %s", fx_errs);
	double acc0 = confusion("noise-free, plain distance", fx_path("labels0.hdr"), truth0, recall0);
	CHECK(FX_RUN("classify", "--method", "eq11", "--calib", cam, "--materials", lib, "--only", only, scene, "-o",
	             fx_path("labels.hdr")) == 0,
	      "classify: %s", fx_errs);
	printf("%s", fx_out);
	double acc = confusion("full well 20000 e-, read noise 10 e-, 12 bits; plain distance",
	                       fx_path("labels.hdr"), truth, recall);
	CHECK(FX_RUN("classify", "--method", "eq11", "--calib", cam, "--materials", lib, "--only", only, "--distance",
	             "scale-free", scene, "-o", fx_path("labels_sf.hdr")) == 0,
	      "classify scale-free: %s", fx_errs);
	double acc_sf = confusion("full well 20000 e-, read noise 10 e-, 12 bits; scale-free",
	                          fx_path("labels_sf.hdr"), truth, recall_sf);
	printf("\noverall accuracy: noise-free %.4f, noisy plain %.4f, noisy scale-free %.4f\n",
	       acc0, acc, acc_sf);

	CHECK(acc >= ACC_FLOOR, "noisy plain accuracy %.4f < floor %.2f", acc, ACC_FLOOR);
	for (int j = 0; j < NM; j++)
		CHECK(recall[j] >= class_floor[j], "%s: recall %.3f < floor %.2f", materials[j],
		      recall[j], class_floor[j]);
	check_side_files("labels");

	int rc = kg_test_done("apply-classify");
	if (rc == 0)
		fx_cleanup();
	else
		fprintf(stderr, "files kept in %s\n", fx_dir);
	return rc;
}
