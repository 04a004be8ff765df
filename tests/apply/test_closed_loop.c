/* The closed loop (issue 14 item 7): a curved object rendered into a camera photograph
 * and labelled back. `kogei render` photographs fixtures/scenes/tsuba_inlay.json (the
 * demo's sword guard: plate shakudo, rim copper, relief gold, seppa-dai silver, in a
 * uniform D65 environment, seen obliquely so every pixel has its own incidence angle)
 * through the Canon EOS 5D Mark II's sensitivities with sensor noise (full well 20000
 * e-, read noise 5 e-, 14 bits: about 40 dB at white), with its truth label map;
 * fx_paper_calibration gives the site calibration (reference Nikon D5100); `kogei
 * classify` (camera space, every library material declared, angle and intensity
 * unknown) labels the photograph with the sensor's variance. Judged on the object's
 * pixels at the incidence angles searched, 0-70 degrees (the truth's angle map; the
 * environment seen past the object and the rim's grazing pixels are counted apart):
 *   - per truth material, the share of its pixels whose label holds it; over all
 *     object pixels at least 0.85;
 *   - copper and shakudo are one class;
 *   - every region of 100 pixels or more whose pixels are mostly object, mostly at
 *     0-70 degrees, gets a label holding its majority material.
 * The paper's eq. 11 (scale-free, at 30 degrees) on the same photograph is printed.
 * Skipped without ../shared/reference or without the renderer (Embree). */
#include <jansson.h>

#include "apply_fixture.h"

#define FULLWELL 20000.0
#define READ_E 5.0

int main(int argc, char **argv)
{
	fx_setup(argc, argv);
	char cam[4096], site_camera[8192], scene[4096];
	snprintf(cam, sizeof(cam), "%s", fx_path("cam.json"));
	snprintf(scene, sizeof(scene), "%s/fixtures/scenes/tsuba_inlay.json", KG_SOURCE_ROOT);
	int rc = fx_paper_calibration(cam, site_camera, sizeof(site_camera));
	if (rc == 77) {
		fx_cleanup();
		kg_test_skip("ColorChecker or camera files missing from ../shared/reference");
	}
	CHECK(rc == 1, "paper calibration: %s", fx_errs);
	const char *photo = fx_path("tsuba.tif"), *truth_hdr = fx_path("truth.hdr");
	rc = FX_RUN("render", "--scene", scene, "-o", fx_path("tsuba.png"), "--linear", photo,
	            "--camera", site_camera, "--noise", "20000:5:14", "--seed", "7",
	            "--truth-labels", truth_hdr, "--truth-angle", fx_path("angle.hdr"), "--quiet");
	if (rc != 0 && strstr(fx_errs, "Embree")) {
		fx_cleanup();
		kg_test_skip("the renderer was built without Embree");
	}
	CHECK(rc == 0, "render: %s", fx_errs);
	/* the sensor's variance per pixel: shot noise of the signal, read noise */
	kg_err err = {{0}};
	kg_image *img = NULL, *var = NULL;
	CHECK(kg_image_read(photo, &img, &err) == 0, "%s", err.msg);
	if (!img) {
		fx_cleanup();
		return kg_test_done("apply-closed-loop");
	}
	const int W = img->width, H = img->height;
	CHECK(kg_image_new(W, H, 3, &var, &err) == 0, "%s", err.msg);
	for (size_t i = 0; i < 3 * (size_t)W * H; i++) {
		double v = img->data[i] > 0 ? img->data[i] : 0;
		var->data[i] = (float)(v / FULLWELL + (READ_E / FULLWELL) * (READ_E / FULLWELL) +
		                       1.0 / (12.0 * 16383.0 * 16383.0));
	}
	const char *vpath = fx_path("variance.tif");
	CHECK(kg_image_write(var, vpath, 32, &err) == 0, "%s", err.msg);
	kg_image_free(&var);
	kg_image_free(&img);
	char lib[4096];
	snprintf(lib, sizeof(lib), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	const char *lab_hdr = fx_path("labels.hdr");
	CHECK(FX_RUN("classify", "--calib", cam, "--materials", lib, "--variance", vpath, photo,
	             "-o", lab_hdr, "--force") == 0,
	      "classify: %s", fx_errs);

	kg_envi *el = NULL, *et = NULL, *er = NULL;
	float *lab = fx_read_envi(lab_hdr, &el), *tru = fx_read_envi(truth_hdr, &et);
	float *ang = fx_read_envi(fx_path("angle.hdr"), NULL);
	float *reg = fx_read_envi(fx_path("labels_regions.hdr"), &er);
	static char ln[KG_EST_MAX_MATERIALS + 3][KG_EST_CLASS_NAME_MAX];
	static char tn[KG_EST_MAX_MATERIALS + 3][KG_EST_CLASS_NAME_MAX];
	int nl = el ? fx_class_names(el, ln, KG_EST_MAX_MATERIALS + 3) : 0;
	int nt = et ? fx_class_names(et, tn, KG_EST_MAX_MATERIALS + 3) : 0;
	kg_envi_close(&el);
	kg_envi_close(&et);
	kg_envi_close(&er);
	CHECK(lab && tru && reg && ang && nl >= 3 && nt >= 2,
	      "labels, truth, angles and regions read back");
	if (!lab || !tru || !reg || !ang) {
		free(ang);
		free(lab);
		free(tru);
		free(reg);
		fx_cleanup();
		return kg_test_done("apply-closed-loop");
	}
	int merged = 0;
	for (int c = 1; c < nl; c++)
		merged |= kg_class_holds(ln[c], "copper") && kg_class_holds(ln[c], "shakudo");
	CHECK(merged, "copper and shakudo are one class");

	/* judged: object pixels at the incidence angles searched (0-70 degrees); the rim's
	 * grazing pixels beyond are counted apart */
	long right = 0, total = 0, per_right[KG_EST_MAX_MATERIALS + 3] = {0},
	     per_total[KG_EST_MAX_MATERIALS + 3] = {0}, grazing = 0, grazing_right = 0;
	for (size_t i = 0; i < (size_t)W * H; i++) {
		int t = (int)tru[i], l = (int)lab[i];
		if (t <= 0 || t >= nt)
			continue;
		int ok = l > 0 && l < nl && kg_class_holds(ln[l], tn[t]);
		if (!(ang[i] <= 70.0f)) {
			grazing++;
			grazing_right += ok;
			continue;
		}
		right += ok;
		total++;
		per_right[t] += ok;
		per_total[t]++;
	}
	double acc = total ? (double)right / total : 0;
	printf("closed loop, rendered tsuba, %ld object pixels at 0-70 degrees: accuracy over the "
	       "classes %.4f (%ld grazing pixels beyond 70 degrees: %.4f)\n", total, acc, grazing,
	       grazing ? (double)grazing_right / grazing : 0.0);
	for (int t = 1; t < nt; t++)
		if (per_total[t])
			printf("  %-26s %6ld pixels  %.4f\n", tn[t], per_total[t],
			       (double)per_right[t] / per_total[t]);
	CHECK(total > 10000, "%ld object pixels", total);
	CHECK(acc >= 0.85, "closed-loop accuracy %.4f < 0.85", acc);

	FILE *fp = fopen(fx_path("labels_regions.csv"), "r");
	char line[2048];
	int big = 0, big_right = 0;
	while (fp && fgets(line, sizeof(line), fp)) {
		unsigned id;
		unsigned long long px;
		char cls[KG_EST_CLASS_NAME_MAX], label[KG_EST_CLASS_NAME_MAX];
		if (sscanf(line, "%u,%llu,%255[^,],%255[^,],", &id, &px, cls, label) != 4 || px < 100)
			continue;
		long votes[KG_EST_MAX_MATERIALS + 3] = {0}, object = 0, searched = 0;
		for (size_t i = 0; i < (size_t)W * H; i++)
			if ((unsigned)reg[i] == id && tru[i] >= 0 && tru[i] < nt) {
				votes[(int)tru[i]]++;
				object += tru[i] > 0;
				searched += tru[i] > 0 && ang[i] <= 70.0f;
			}
		if (2 * object < (long)px || 2 * searched < object) {
			printf("  region %u: %llu pixels, %ld of the object, %ld at 0-70 degrees, labelled "
			       "%s: not judged\n", id, px, object, searched, label);
			continue; /* the environment seen past the object, or grazing */
		}
		int maj = 1;
		for (int t = 2; t < nt; t++)
			if (votes[t] > votes[maj])
				maj = t;
		big++;
		big_right += kg_class_holds(label, tn[maj]);
		printf("  region %u: %llu pixels, truth %s, labelled %s\n", id, px, tn[maj], label);
		CHECK(kg_class_holds(label, tn[maj]), "region %u (%llu pixels) labelled %s, truth %s", id, px,
		      label, tn[maj]);
	}
	if (fp)
		fclose(fp);
	printf("object regions of 100 pixels or more: %d, %d with their true label\n", big,
	       big_right);
	CHECK(big >= 4, "%d object regions of 100 pixels or more, expected at least the 4 parts",
	      big);

	/* eq. 11 on the same photograph, for comparison */
	const char *eq_hdr = fx_path("eq11.hdr");
	if (FX_RUN("classify", "--method", "eq11", "--distance", "scale-free", "--angle", "30",
	           "--calib", cam, "--materials", lib, photo, "-o", eq_hdr, "--force") == 0) {
		kg_envi *ee = NULL;
		float *eq = fx_read_envi(eq_hdr, &ee);
		static char en[KG_EST_MAX_MATERIALS + 3][KG_EST_CLASS_NAME_MAX];
		int ne = ee ? fx_class_names(ee, en, KG_EST_MAX_MATERIALS + 3) : 0;
		kg_envi_close(&ee);
		long r_exact = 0;
		for (size_t i = 0; eq && i < (size_t)W * H; i++) {
			int t = (int)tru[i], l = (int)eq[i];
			if (t > 0 && t < nt)
				r_exact += l > 0 && l < ne && strcmp(en[l], tn[t]) == 0;
		}
		printf("eq. 11 scale-free at 30 degrees: per-pixel material accuracy %.4f\n",
		       total ? (double)r_exact / total : 0.0);
		free(eq);
	}
	free(lab);
	free(tru);
	free(reg);
	free(ang);
	fx_cleanup();
	return kg_test_done("apply-closed-loop");
}
