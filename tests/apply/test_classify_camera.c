/* `kogei classify` with camera-space matching (the default method) on a simulated
 * curved object: real camera sensitivities and chart spectra from ../shared/reference
 * (skipped without it).
 *
 * Setup: fx_paper_calibration (reference camera Nikon D5100, site camera Canon EOS 5D
 * Mark II, both under D65, ColorChecker 24). The object: the ten library materials as
 * 48 x 48 pixel domes on a black ground, each pixel at its own incidence angle (0 at
 * a dome's centre to 70 degrees at its corners) and its own intensity (0.3 to 1.0 across
 * the dome, the unknown shading of the geometry), read by the site camera through its
 * sensitivities with Gaussian noise of sigma 0.009 per channel (40 dB: 1 % of the
 * white's 0.9), whose variance is given as the variance image. Nothing of the truth
 * (angles, intensities) is given to the classifier, which searches 0-70 degrees and
 * 0.3-1.0.
 *
 * Asserts what the method promises: (1) copper and shakudo, 0.5 % apart in RGB, are
 * one class at this noise; (2) per-pixel accuracy over the classes (the label's members
 * hold the true material) >= 0.85; (3) every region of 100 pixels or more gets a label
 * (material or compound) that holds its pixels' majority true material; (4) the mean
 * posterior agrees with the accuracy within 0.05; (5) with only gold, silver,
 * shibuichi-shiro and urushi declared, at least half of copper's and shakudo's pixels at
 * intensity 0.7 or more are 'unknown' (80 % when written: a pixel's own noise leaves
 * the rest within reach of gold or shibuichi-shiro), fewer than 1 % of the declared
 * materials' pixels are, every region of 100 pixels or more of copper or shakudo is
 * 'unknown' (the pooled test) and every such region of a declared material keeps its
 * label; (6) the fitted angle and intensity bands lie in the searched ranges; (7) the
 * composition: each metal dome's region has its library Ag and Cu fractions within 3
 * of its standard deviations, and every fitted pixel of the --composition cube lies
 * on the simplex (fractions >= 0, summing to 1 where gold is given); (8) a user region
 * map decides each dome as one region under its own number; bad --angles, --regions
 * with eq11 and a 3-channel region map are refused. The
 * paper's eq. 11 (scale-free) on the same photograph is printed for comparison. */
#include <jansson.h>

#include "apply_fixture.h"
#include "kg_test_camera.h"

#define NMAT 10
#define BLOCK 48
#define GAP 6
#define COLS 5
#define SIGMA 0.009

static const char *mats[NMAT] = {
	"gold", "silver", "copper", "shakudo", "shibuichi-nami", "shibuichi-shiro",
	"shibuichi-jo", "shibuichi-nami-uchisanbu", "shibuichi-nami-sotosanbu", "urushi",
};

int main(int argc, char **argv)
{
	fx_setup(argc, argv);
	char cam[4096], site_camera[8192];
	snprintf(cam, sizeof(cam), "%s", fx_path("cam.json"));
	int rc = fx_paper_calibration(cam, site_camera, sizeof(site_camera));
	if (rc == 77) {
		fx_cleanup();
		kg_test_skip("ColorChecker or camera files missing from ../shared/reference");
	}
	CHECK(rc == 1, "paper calibration: %s", fx_errs);
	kg_err err = {{0}};
	kg_spectrum w[3];
	char lib_path[4096];
	snprintf(lib_path, sizeof(lib_path), "%s/fixtures/materials/default.json", KG_SOURCE_ROOT);
	kg_material_library *lib = NULL;
	CHECK(kg_test_camera_weights(kg_test_reference_dir(), "cameras/Canon_EOS_5D_Mark_II.csv",
	                             "D65", w, &err) == 0 &&
	          kg_material_library_load(lib_path, &lib, &err) == 0,
	      "%s", err.msg);
	if (!lib) {
		fx_cleanup();
		return kg_test_done("apply-classify-camera");
	}

	/* the object */
	const int W = COLS * (BLOCK + GAP) + GAP, H = 2 * (BLOCK + GAP) + GAP;
	kg_image *img = NULL, *var = NULL;
	CHECK(kg_image_new(W, H, 3, &img, &err) == 0 && kg_image_new(W, H, 3, &var, &err) == 0,
	      "%s", err.msg);
	int *truth = malloc(sizeof(int) * (size_t)W * H);
	float *level = calloc((size_t)W * H, sizeof(float));
	uint64_t st = 2026;
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			size_t i = (size_t)y * W + x;
			float *p = img->data + 3 * i;
			int bx = (x - GAP) / (BLOCK + GAP), by = (y - GAP) / (BLOCK + GAP);
			int ux = (x - GAP) % (BLOCK + GAP), uy = (y - GAP) % (BLOCK + GAP);
			int inside = x >= GAP && y >= GAP && ux < BLOCK && uy < BLOCK && bx < COLS && by < 2;
			truth[i] = inside ? by * COLS + bx : -1;
			double rgb[3] = {0, 0, 0};
			if (inside) {
				double u = (ux + 0.5) / BLOCK - 0.5, v = (uy + 0.5) / BLOCK - 0.5;
				double theta = 70.0 * sqrt((u * u + v * v) / 0.5);
				double a = 0.3 + 0.7 * (0.5 + 0.5 * cos(M_PI * (u + 0.5) * 0.9 + v));
				level[i] = (float)a;
				kg_spectrum r;
				const kg_material *m = kg_material_library_find(lib, mats[truth[i]]);
				CHECK(m && kg_material_reflectance(m, theta * M_PI / 180, &r, &err) == 0, "%s",
				      mats[truth[i]]);
				for (int c = 0; c < 3; c++)
					rgb[c] = a * kg_spectrum_dot(&w[c], &r);
			}
			for (int c = 0; c < 3; c++) {
				p[c] = (float)(rgb[c] + SIGMA * kg_test_gauss(&st));
				var->data[3 * i + c] = (float)(SIGMA * SIGMA);
			}
		}
	const char *obj = fx_path("object.tif"), *vpath = fx_path("variance.tif");
	CHECK(kg_image_write(img, obj, 32, &err) == 0 && kg_image_write(var, vpath, 32, &err) == 0,
	      "%s", err.msg);

	const char *lab_hdr = fx_path("labels.hdr");
	CHECK(FX_RUN("classify", "--calib", cam, "--materials", lib_path, "--variance", vpath, obj,
	             "-o", lab_hdr, "--composition", fx_path("comp.hdr")) == 0,
	      "classify: %s", fx_errs);
	printf("%s", fx_out);
	kg_envi *el = NULL;
	float *lab = fx_read_envi(lab_hdr, &el);
	char names[KG_EST_MAX_MATERIALS + 3][KG_EST_CLASS_NAME_MAX];
	int nn = el ? fx_class_names(el, names, KG_EST_MAX_MATERIALS + 3) : 0;
	kg_envi_close(&el);
	CHECK(lab && nn >= 3, "labels read back with %d class names", nn);

	/* (1) copper|shakudo */
	int merged = 0;
	for (int c = 1; c < nn; c++)
		merged |= kg_class_holds(names[c], "copper") && kg_class_holds(names[c], "shakudo");
	CHECK(merged, "copper and shakudo are one class at 40 dB");

	/* (2) per-pixel accuracy, per class */
	long right = 0, total = 0, per_right[NMAT] = {0}, per_total[NMAT] = {0};
	for (size_t i = 0; lab && i < (size_t)W * H; i++) {
		if (truth[i] < 0)
			continue;
		int l = (int)lab[i];
		int ok = l > 0 && l < nn && kg_class_holds(names[l], mats[truth[i]]);
		right += ok;
		total++;
		per_right[truth[i]] += ok;
		per_total[truth[i]]++;
	}
	double acc = total ? (double)right / total : 0;
	printf("camera space, angle 0-70 and intensity 0.3-1.0 unknown, 40 dB: per-pixel accuracy "
	       "over the classes %.4f\n", acc);
	for (int j = 0; j < NMAT; j++)
		printf("  %-26s %.4f\n", mats[j], (double)per_right[j] / per_total[j]);
	CHECK(acc >= 0.85, "per-pixel accuracy %.4f < 0.85", acc);

	/* (3) regions of 100 pixels or more */
	kg_envi *er = NULL;
	float *reg = fx_read_envi(fx_path("labels_regions.hdr"), &er);
	kg_envi_close(&er);
	CHECK(reg != NULL, "labels_regions.hdr read back");
	FILE *fp = fopen(fx_path("labels_regions.csv"), "r");
	CHECK(fp != NULL, "labels_regions.csv");
	char line[2048];
	int big = 0, big_right = 0, comp_checked = 0;
	while (fp && reg && fgets(line, sizeof(line), fp)) {
		unsigned id;
		unsigned long long px;
		char cls[KG_EST_CLASS_NAME_MAX], label[KG_EST_CLASS_NAME_MAX];
		if (sscanf(line, "%u,%llu,%255[^,],%255[^,],", &id, &px, cls, label) != 4 || px < 100)
			continue;
		long votes[NMAT] = {0}, counted = 0;
		for (size_t i = 0; i < (size_t)W * H; i++)
			if ((unsigned)reg[i] == id) {
				counted++;
				if (truth[i] >= 0)
					votes[truth[i]]++;
			}
		int maj = 0;
		for (int j = 1; j < NMAT; j++)
			if (votes[j] > votes[maj])
				maj = j;
		big++;
		big_right += kg_class_holds(label, mats[maj]);
		CHECK(counted == (long)px, "region %u: %llu pixels in the table, %ld in the map", id, px,
		      counted);
		CHECK(kg_class_holds(label, mats[maj]), "region %u (%llu pixels) labelled %s, truth %s", id, px,
		      label, mats[maj]);
		/* (7) composition: the region's Ag and Cu fractions within 3 sd of the truth's */
		double c[6];
		const char *p = line;
		for (int f = 0; f < 6 && p; f++)
			p = strchr(p + 1, ',');
		int nc = p ? sscanf(p, ",%lf,%lf,%lf,%lf,%lf,%lf", &c[0], &c[1], &c[2], &c[3], &c[4],
		                    &c[5])
		           : 0;
		const kg_material *tm = kg_material_library_find(lib, mats[maj]);
		double tag = 0, tcu = 0;
		if (tm && tm->kind == KG_MATERIAL_ALLOY)
			for (int q = 0; q < tm->ncomponents; q++) {
				tag += !strcmp(tm->component[q].name, "silver") * tm->component[q].fraction;
				tcu += !strcmp(tm->component[q].name, "copper") * tm->component[q].fraction;
			}
		else if (tm) {
			tag = !strcmp(tm->name, "silver");
			tcu = !strcmp(tm->name, "copper");
		}
		if (tm && tm->kind != KG_MATERIAL_DIELECTRIC) {
			CHECK(nc >= 5, "region %u (%s): composition in the table", id, mats[maj]);
			if (nc >= 5) {
				printf("  region %u %-26s Ag %.3f +- %.3f (truth %.3f), Cu %.3f +- %.3f "
				       "(truth %.3f)\n", id, mats[maj], c[0], c[3], tag, c[1], c[4], tcu);
				comp_checked++;
				CHECK(fabs(c[0] - tag) <= 3 * c[3] && fabs(c[1] - tcu) <= 3 * c[4],
				      "region %u (%s): Ag %.3f +- %.3f against %.3f, Cu %.3f +- %.3f against "
				      "%.3f", id, mats[maj], c[0], c[3], tag, c[1], c[4], tcu);
			}
		}
	}
	if (fp)
		fclose(fp);
	printf("regions of 100 pixels or more: %d, %d with their true label\n", big, big_right);
	CHECK(big >= NMAT, "%d regions of 100 pixels or more, expected one per dome", big);
	CHECK(comp_checked >= NMAT - 1, "%d metal regions with a composition", comp_checked);
	kg_envi *ecp = NULL;
	float *comp = fx_read_envi(fx_path("comp.hdr"), &ecp);
	CHECK(comp && ecp && ecp->meta.bands == 6, "the composition cube has 6 bands");
	long sum_bad = 0, fitted = 0;
	for (size_t i = 0; comp && i < (size_t)W * H; i++) {
		const float *c = comp + 6 * i;
		if (!isfinite(c[0]))
			continue;
		fitted++;
		double t = c[0] + c[1] + (isfinite(c[2]) ? c[2] : 0);
		sum_bad += c[0] < 0 || c[1] < 0 || (isfinite(c[2]) && (c[2] < 0 || fabs(t - 1) > 1e-4));
	}
	printf("composition cube: %ld pixels fitted, %ld with fractions out of the simplex\n",
	       fitted, sum_bad);
	CHECK(fitted > 0 && sum_bad == 0, "%ld of %ld fitted pixels off the simplex", sum_bad,
	      fitted);
	kg_envi_close(&ecp);
	free(comp);

	/* (4) posterior against accuracy, (6) the fitted bands */
	kg_envi *ec = NULL;
	float *conf = fx_read_envi(fx_path("labels_confidence.hdr"), &ec);
	CHECK(conf && ec && ec->meta.bands == 4, "4 confidence bands");
	kg_envi_close(&ec);
	double post_sum = 0;
	long npost = 0, out_of_range = 0;
	for (size_t i = 0; conf && lab && i < (size_t)W * H; i++) {
		int l = (int)lab[i];
		if (l < 1 || l >= nn - 2)
			continue;
		const float *c4 = conf + 4 * i;
		post_sum += c4[1];
		npost++;
		out_of_range += !(c4[1] > 0 && c4[1] <= 1 && c4[2] >= 0 && c4[2] <= 70 &&
		                  c4[3] >= 0.3f - 1e-6f && c4[3] <= 1.0f + 1e-6f && c4[0] >= 0);
	}
	double mean_post = npost ? post_sum / npost : 0;
	printf("mean posterior %.4f against accuracy %.4f\n", mean_post, acc);
	CHECK(fabs(mean_post - acc) < 0.05, "mean posterior %.4f, accuracy %.4f", mean_post, acc);
	CHECK(out_of_range == 0, "%ld pixels with a band out of its range", out_of_range);

	/* eq. 11 for comparison (printed) */
	const char *eq_hdr = fx_path("eq11.hdr");
	if (FX_RUN("classify", "--method", "eq11", "--distance", "scale-free", "--angle", "30",
	           "--calib", cam, "--materials", lib_path, "--variance", vpath, obj, "-o",
	           eq_hdr) == 0) {
		kg_envi *ee = NULL;
		float *eq = fx_read_envi(eq_hdr, &ee);
		char en[KG_EST_MAX_MATERIALS + 3][KG_EST_CLASS_NAME_MAX];
		int ne = ee ? fx_class_names(ee, en, KG_EST_MAX_MATERIALS + 3) : 0;
		kg_envi_close(&ee);
		long r_exact = 0, n_exact = 0;
		for (size_t i = 0; eq && i < (size_t)W * H; i++)
			if (truth[i] >= 0) {
				int l = (int)eq[i];
				r_exact += l > 0 && l < ne && strcmp(en[l], mats[truth[i]]) == 0;
				n_exact++;
			}
		printf("eq. 11 scale-free at 30 degrees on the same photograph: per-pixel material "
		       "accuracy %.4f\n", n_exact ? (double)r_exact / n_exact : 0.0);
		free(eq);
	}

	/* (5) unknown: only gold, silver, shibuichi-shiro and urushi declared */
	const char *unk_hdr = fx_path("unk.hdr");
	static const int declared[NMAT] = {1, 1, 0, 0, 0, 1, 0, 0, 0, 1};
	CHECK(FX_RUN("classify", "--calib", cam, "--materials", lib_path, "--only",
	             "gold,silver,shibuichi-shiro,urushi", "--variance", vpath, obj, "-o",
	             unk_hdr) == 0,
	      "classify --only: %s", fx_errs);
	kg_envi *eu = NULL;
	float *unk = fx_read_envi(unk_hdr, &eu);
	char un[KG_EST_MAX_MATERIALS + 3][KG_EST_CLASS_NAME_MAX];
	int nu = eu ? fx_class_names(eu, un, KG_EST_MAX_MATERIALS + 3) : 0;
	kg_envi_close(&eu);
	long bright = 0, bright_unknown = 0, kept = 0, kept_right = 0;
	static long kept_as[NMAT][KG_EST_MAX_MATERIALS + 3];
	for (size_t i = 0; unk && i < (size_t)W * H; i++) {
		if (truth[i] < 0)
			continue;
		int l = (int)unk[i];
		const char *name = l >= 0 && l < nu ? un[l] : "";
		if ((truth[i] == 2 || truth[i] == 3) && level[i] >= 0.7) {
			bright++;
			bright_unknown += strcmp(name, "unknown") == 0;
		} else if (declared[truth[i]]) {
			kept++;
			kept_right += strcmp(name, "unknown") != 0;
			kept_as[truth[i]][l >= 0 && l < nu ? l : 0]++;
		}
	}
	for (int j = 0; j < NMAT; j++)
		for (int l = 0; l < nu; l++)
			if (kept_as[j][l])
				printf("  declared %s labelled %s: %ld\n", mats[j], un[l], kept_as[j][l]);
	printf("copper and shakudo at intensity >= 0.7: %.4f of their pixels unknown; declared "
	       "ones %.4f not unknown\n", bright ? (double)bright_unknown / bright : 0.0,
	       kept ? (double)kept_right / kept : 0.0);
	CHECK(bright && bright_unknown >= 0.5 * bright, "bright copper and shakudo pixels unknown: "
	      "%ld of %ld", bright_unknown, bright);
	CHECK(kept && kept_right >= 0.99 * kept, "declared materials not unknown: %ld of %ld",
	      kept_right, kept);
	/* every region of 100 pixels or more: unknown when its material was not declared */
	kg_envi *eur = NULL;
	float *ureg = fx_read_envi(fx_path("unk_regions.hdr"), &eur);
	kg_envi_close(&eur);
	FILE *ucsv = fopen(fx_path("unk_regions.csv"), "r");
	int ubig = 0;
	while (ureg && ucsv && fgets(line, sizeof(line), ucsv)) {
		unsigned id;
		unsigned long long px;
		char cls[KG_EST_CLASS_NAME_MAX], label[KG_EST_CLASS_NAME_MAX];
		if (sscanf(line, "%u,%llu,%255[^,],%255[^,],", &id, &px, cls, label) != 4 || px < 100)
			continue;
		long votes[NMAT] = {0};
		for (size_t i = 0; i < (size_t)W * H; i++)
			if ((unsigned)ureg[i] == id && truth[i] >= 0)
				votes[truth[i]]++;
		int maj = 0;
		for (int j = 1; j < NMAT; j++)
			if (votes[j] > votes[maj])
				maj = j;
		ubig++;
		printf("  --only: region %u, %llu pixels, truth %s: %s\n", id, px, mats[maj], label);
		/* declared: its own label; copper and shakudo, far from every declared material:
		 * unknown (the shibuichi alloys near shibuichi-shiro are printed only) */
		const char *want = declared[maj] ? mats[maj] : maj == 2 || maj == 3 ? "unknown" : NULL;
		if (want)
			CHECK(strcmp(label, want) == 0, "--only: region %u (%llu pixels, truth %s) labelled "
			      "%s, expected %s", id, px, mats[maj], label, want);
	}
	if (ucsv)
		fclose(ucsv);
	CHECK(ubig >= NMAT, "--only: %d regions of 100 pixels or more", ubig);
	free(ureg);

	/* (8) a user region map (16-bit PNG of the dome numbers 1-10, 0 between): each dome
	 * decided as one region, numbered as in the map */
	kg_image *map = NULL;
	CHECK(kg_image_new(W, H, 1, &map, &err) == 0, "%s", err.msg);
	for (size_t i = 0; map && i < (size_t)W * H; i++)
		map->data[i] = truth[i] < 0 ? 0.0f : (float)(truth[i] + 1) / 65535.0f;
	const char *map_path = fx_path("domes.png"), *ur_hdr = fx_path("user.hdr");
	CHECK(map && kg_image_write(map, map_path, 16, &err) == 0, "%s", err.msg);
	kg_image_free(&map);
	CHECK(FX_RUN("classify", "--calib", cam, "--materials", lib_path, "--variance", vpath, obj,
	             "--regions", map_path, "-o", ur_hdr) == 0,
	      "classify --regions: %s", fx_errs);
	FILE *uf = fopen(fx_path("user_regions.csv"), "r");
	int user_regions = 0, user_right = 0;
	while (uf && fgets(line, sizeof(line), uf)) {
		unsigned id;
		unsigned long long px;
		char cls[KG_EST_CLASS_NAME_MAX], label[KG_EST_CLASS_NAME_MAX];
		if (sscanf(line, "%u,%llu,%255[^,],%255[^,],", &id, &px, cls, label) != 4)
			continue;
		user_regions++;
		user_right += id >= 1 && id <= NMAT && kg_class_holds(label, mats[id - 1]);
	}
	if (uf)
		fclose(uf);
	printf("user region map: %d regions, %d with their dome's material\n", user_regions,
	       user_right);
	CHECK(user_regions == NMAT && user_right == NMAT, "user regions: %d of %d right",
	      user_right, user_regions);
	/* bad usage and bad input */
	CHECK(FX_RUN("classify", "--calib", cam, "--materials", lib_path, obj, "-o",
	             fx_path("x.hdr"), "--angles", "10:95") == 2 && strstr(fx_errs, "--angles"),
	      "--angles beyond 90 refused: %s", fx_errs);
	CHECK(FX_RUN("classify", "--method", "eq11", "--calib", cam, "--materials", lib_path, obj,
	             "-o", fx_path("x.hdr"), "--regions", map_path) == 2,
	      "--regions with eq11 refused");
	CHECK(FX_RUN("classify", "--calib", cam, "--materials", lib_path, obj, "-o",
	             fx_path("x.hdr"), "--regions", vpath) == 1 && strstr(fx_errs, "region map"),
	      "a 3-channel region map refused: %s", fx_errs);
	kg_image *half = NULL;
	CHECK(kg_image_new(W, H, 1, &half, &err) == 0, "%s", err.msg);
	for (size_t i = 0; half && i < (size_t)W * H; i++)
		half->data[i] = 0.5f;
	const char *half_path = fx_path("half.tif");
	CHECK(half && kg_image_write(half, half_path, 32, &err) == 0, "%s", err.msg);
	kg_image_free(&half);
	CHECK(FX_RUN("classify", "--calib", cam, "--materials", lib_path, obj, "-o",
	             fx_path("x.hdr"), "--regions", half_path) == 1 &&
	          strstr(fx_errs, "half.tif") && strstr(fx_errs, "whole region number"),
	      "a region map of fractions refused, naming it: %s", fx_errs);

	/* a calibration from before the camera response existed: the camera method is
	 * refused (naming the file and the field), eq. 11 still works */
	json_t *cj = json_load_file(cam, 0, NULL);
	CHECK(cj != NULL, "%s read back", cam);
	if (cj) {
		json_object_del(cj, "response");
		json_dump_file(cj, fx_path("old.json"), 0);
		json_decref(cj);
	}
	CHECK(FX_RUN("classify", "--calib", fx_path("old.json"), "--materials", lib_path, obj, "-o",
	             fx_path("x.hdr")) == 1 && strstr(fx_errs, "old.json") &&
	          strstr(fx_errs, "response"),
	      "a calibration without a response refused: %s", fx_errs);
	CHECK(FX_RUN("classify", "--method", "eq11", "--calib", fx_path("old.json"), "--materials",
	             lib_path, obj, "-o", fx_path("x.hdr")) == 0,
	      "eq11 with it: %s", fx_errs);

	/* LABELS.json: the separability table and the merges */
	json_t *j = json_load_file(fx_path("labels.json"), 0, NULL);
	json_t *sep = j ? json_object_get(j, "separability") : NULL;
	if (sep) {
		json_t *nz = json_object_get(json_object_get(j, "camera_space"), "noise");
		printf("separability at the survey's level %.3f:\n",
		       json_number_value(json_object_get(nz, "level")));
		json_t *dist = json_object_get(sep, "distance");
		for (int a = 0; a < NMAT; a++) {
			printf("  %-26s", mats[a]);
			for (int b = 0; b < NMAT; b++)
				printf(" %6.2f", json_number_value(json_array_get(json_array_get(dist, a), b)));
			printf("\n");
		}
		char *m = json_dumps(json_object_get(j, "merges"), JSON_COMPACT);
		printf("merges: %s\n", m ? m : "?");
		free(m);
	}
	CHECK(sep && json_array_size(json_object_get(sep, "distance")) == NMAT &&
	          json_array_size(json_object_get(j, "merges")) >= 1,
	      "labels.json has a 10 x 10 separability table and the merges");
	json_decref(j);

	free(lab);
	free(reg);
	free(conf);
	free(unk);
	free(truth);
	free(level);
	kg_image_free(&img);
	kg_image_free(&var);
	kg_material_library_free(&lib);
	fx_cleanup();
	return kg_test_done("apply-classify-camera");
}
