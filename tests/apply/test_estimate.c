/* `kogei estimate` end to end on the synthetic calibration of apply_fixture.h (no
 * reference data needed). Asserts:
 *  - the f32 cube equals a direct double-precision evaluation of the site map
 *    (kg_site_map_apply: s = offset + A x(P rho), negatives set to 0) to 1e-6, for
 *    pca and for rootpoly3 (whose M2 is applied to the pixels before the kernel),
 *    relative to max(1, the sum of the magnitudes of the terms added up), and a
 *    33-node LUT of pca (an affine map, which trilinear interpolation reproduces) to
 *    1e-5;
 *  - NaN/Inf inputs carry mask bit 1, clipped ones (>= 0.999 before M2) bit 2, both
 *    are NaN in every band; pixels estimated negative carry bit 4; the summary line
 *    counts them;
 *  - bsq and bip hold the same values; f16 (data type 12, 'kogei sample format =
 *    ieee-half') is within half precision (relative 2^-11) of f32; weights rebuilt
 *    with the header's basis and mean give the f32 spectra to 1e-6;
 *  - the files are identical for --threads 1 and 2 and --block-rows 1, 7 and the
 *    whole image. */
#include "apply_fixture.h"

#define W 37
#define H 23

static int kind[W * H];
static kg_image *img;
static kg_camera_calib *cam;

/* The direct evaluation of a method at pixel i; returns its minimum before clamping.
 * scale[l] receives |offset_l| + sum_j |A_lj x_j|, the size of the terms the float
 * kernel adds up: its rounding error is relative to that, not to the result (the
 * root-polynomial fits extrapolate far beyond the chart on this fixture's random
 * colours, with large cancelling terms). */
static double direct(kg_method m, int i, double *s, double *scale)
{
	const kg_site_map *map = NULL;
	kg_err err = {{0}};
	if (kg_camera_site_map(cam, m, &map, &err)) {
		fprintf(stderr, "%s\n", err.msg);
		exit(1);
	}
	double rgb[3] = {img->data[3 * i], img->data[3 * i + 1], img->data[3 * i + 2]};
	kg_spectrum out;
	kg_site_map_apply(map, rgb, &out);
	double pre_rgb[3], x[KG_CALIB_MAX_TERMS];
	for (int r = 0; r < 3; r++)
		pre_rgb[r] = map->pre[3 * r] * rgb[0] + map->pre[3 * r + 1] * rgb[1] +
		             map->pre[3 * r + 2] * rgb[2];
	kg_method_terms(m, pre_rgb, x);
	double lo = INFINITY;
	for (int l = 0; l < KG_NBANDS; l++) {
		lo = fmin(lo, out.v[l]);
		s[l] = out.v[l] < 0 ? 0 : out.v[l];
		scale[l] = fabs(map->offset[l]);
		for (int j = 0; j < map->nterms; j++)
			scale[l] += fabs(map->A[l * map->nterms + j] * x[j]);
	}
	return lo;
}

/* Check a f32 cube against the direct evaluation, and its mask. */
static void check_cube(const char *name, kg_method m, double tol)
{
	char hdr[600], mask[600];
	snprintf(hdr, sizeof(hdr), "%s.hdr", fx_path(name));
	snprintf(mask, sizeof(mask), "%s_mask.hdr", fx_path(name));
	float *v = fx_read_envi(hdr, NULL), *mk = fx_read_envi(mask, NULL);
	CHECK(v && mk, "%s: cube and mask read back", name);
	if (!v || !mk) {
		free(v);
		free(mk);
		return;
	}
	double worst = 0;
	int flag_errors = 0, clamp_seen = 0;
	for (int i = 0; i < W * H; i++) {
		int bits = (int)mk[i];
		int want = kind[i] == FX_NAN || kind[i] == FX_INF ? KG_EST_MASK_NONFINITE
		           : kind[i] == FX_CLIPPED               ? KG_EST_MASK_CLIPPED
		                                                 : 0;
		if (want) {
			if (bits != want)
				flag_errors++;
			for (int l = 0; l < KG_NBANDS; l++)
				if (!isnan(v[i * KG_NBANDS + l]))
					flag_errors++;
			continue;
		}
		double s[KG_NBANDS], scale[KG_NBANDS];
		double lo = direct(m, i, s, scale);
		double margin = 1e-5 * fmax(1.0, scale[0]);
		for (int l = 1; l < KG_NBANDS; l++)
			margin = fmax(margin, 1e-5 * fmax(1.0, scale[l]));
		if (lo < -margin && !(bits & KG_EST_MASK_CLAMPED))
			flag_errors++;
		if (lo > margin && (bits & KG_EST_MASK_CLAMPED))
			flag_errors++;
		clamp_seen += (bits & KG_EST_MASK_CLAMPED) != 0;
		if (bits & (KG_EST_MASK_NONFINITE | KG_EST_MASK_CLIPPED))
			flag_errors++;
		for (int l = 0; l < KG_NBANDS; l++) {
			double d = fabs(v[i * KG_NBANDS + l] - s[l]) / fmax(1.0, scale[l]);
			worst = fmax(worst, d);
		}
	}
	printf("%s: max |cube - direct| / max(1, term size) = %.3g (tolerance %.0e), %d clamped "
	       "pixels\n", name, worst,
	       tol, clamp_seen);
	CHECK(worst <= tol, "%s: cube differs from the direct evaluation by %.3g", name, worst);
	CHECK(flag_errors == 0, "%s: %d pixels flagged wrongly", name, flag_errors);
	CHECK(clamp_seen > 0, "%s: the fixture was meant to produce clamped pixels", name);
	free(v);
	free(mk);
}

static void check_same_values(const char *a, const char *b)
{
	kg_envi *ea = NULL, *eb = NULL;
	float *va = fx_read_envi(fx_path(a), &ea), *vb = fx_read_envi(fx_path(b), &eb);
	CHECK(va && vb, "%s, %s read back", a, b);
	if (va && vb) {
		CHECK(ea->meta.bands == eb->meta.bands, "%s, %s: bands", a, b);
		CHECK(memcmp(va, vb, sizeof(float) * W * H * ea->meta.bands) == 0,
		      "%s and %s hold different values", a, b);
	}
	free(va);
	free(vb);
	kg_envi_close(&ea);
	kg_envi_close(&eb);
}

static void check_f16(const char *name, const char *f32name)
{
	kg_envi *e = NULL;
	float *h = fx_read_envi(fx_path(name), &e), *f = fx_read_envi(fx_path(f32name), NULL);
	CHECK(h && f, "%s read back", name);
	if (!h || !f) {
		free(h);
		free(f);
		kg_envi_close(&e);
		return;
	}
	CHECK(e->meta.data_type == KG_ENVI_U16, "%s: data type %d, expected 12", name,
	      (int)e->meta.data_type);
	const char *fmt = kg_envi_get(e, "kogei sample format");
	CHECK(fmt && strcmp(fmt, "ieee-half") == 0, "%s: kogei sample format is %s", name,
	      fmt ? fmt : "(missing)");
	int bad = 0;
	double worst = 0;
	for (int i = 0; i < W * H * KG_NBANDS; i++) {
		float x = kg_f32_from_f16((uint16_t)h[i]);
		if (isnan(f[i])) {
			bad += !isnan(x);
			continue;
		}
		double d = fabs(x - f[i]);
		worst = fmax(worst, d / fmax(fabs(f[i]), 6.1e-5));
		bad += d > ldexp(fabs(f[i]), -11) + ldexp(1.0, -25);
	}
	printf("%s: max relative |f16 - f32| = %.3g (bound 2^-11 = %.3g)\n", name, worst,
	       ldexp(1.0, -11));
	CHECK(bad == 0, "%s: %d values beyond half precision", name, bad);
	free(h);
	free(f);
	kg_envi_close(&e);
}

static void check_weights(void)
{
	kg_envi *e = NULL;
	float *w = fx_read_envi(fx_path("w.hdr"), &e), *f = fx_read_envi(fx_path("a.hdr"), NULL);
	CHECK(w && f, "weights read back");
	if (!w || !f) {
		free(w);
		free(f);
		kg_envi_close(&e);
		return;
	}
	int K = e->meta.bands;
	double *B = NULL, *mean = NULL;
	int nb = 0, nm = 0;
	kg_err err = {{0}};
	CHECK(K == cam->K, "weights: %d bands, expected K = %d", K, cam->K);
	CHECK(kg_envi_get_numbers(e, "kogei basis", &B, &nb, &err) == 0 && nb == KG_NBANDS * K,
	      "weights: kogei basis has %d values: %s", nb, err.msg);
	CHECK(kg_envi_get_numbers(e, "kogei mean", &mean, &nm, &err) == 0 && nm == KG_NBANDS,
	      "weights: kogei mean has %d values: %s", nm, err.msg);
	if (B && mean && nb == KG_NBANDS * K && nm == KG_NBANDS) {
		double worst = 0;
		int bad = 0;
		for (int i = 0; i < W * H; i++)
			for (int l = 0; l < KG_NBANDS; l++) {
				double s = mean[l];
				for (int k = 0; k < K; k++)
					s += B[l * K + k] * w[i * K + k];
				s = s < 0 ? 0 : s;
				float ref = f[i * KG_NBANDS + l];
				if (isnan(ref) || isnan(s)) {
					bad += isnan(ref) != isnan(s);
					continue;
				}
				worst = fmax(worst, fabs(s - ref));
			}
		printf("weights: max |mean + B w - f32 cube| = %.3g\n", worst);
		CHECK(worst <= 1e-6, "weights rebuilt differ from the cube by %.3g", worst);
		CHECK(bad == 0, "weights: %d NaN mismatches", bad);
	}
	free(B);
	free(mean);
	free(w);
	free(f);
	kg_envi_close(&e);
}

static void check_summary(void)
{
	int nonfinite = 0, clipped = 0;
	for (int i = 0; i < W * H; i++) {
		nonfinite += kind[i] == FX_NAN || kind[i] == FX_INF;
		clipped += kind[i] == FX_CLIPPED;
	}
	char want[128];
	snprintf(want, sizeof(want), "pixels %d, clipped %d (", W * H, clipped);
	CHECK(strstr(fx_errs, want), "summary line lacks '%s'", want);
	snprintf(want, sizeof(want), "non-finite %d (", nonfinite);
	CHECK(strstr(fx_errs, want), "summary line lacks '%s'", want);
	CHECK(strstr(fx_errs, "clamped "), "summary line lacks the clamped count");
}

int main(int argc, char **argv)
{
	fx_setup(argc, argv);
	const char *cam_path = fx_path("cam.json");
	cam = fx_make_camera(cam_path);
	img = fx_image(W, H, kind);
	kg_err err = {{0}};
	CHECK(cam && img, "fixture");
	if (!cam || !img)
		return kg_test_done("apply-estimate");
	const char *tif = fx_path("img.tif");
	CHECK(kg_image_write_tiff(img, tif, 32, &err) == 0, "write %s: %s", tif, err.msg);
	printf("camera: default method %s, K = %d\n", kg_method_name(cam->method), cam->K);

	/* f32 bsq against the direct evaluation */
	CHECK(FX_RUN("estimate", "--calib", cam_path, tif, "-o", fx_path("a.hdr")) == 0,
	      "estimate f32: %s", fx_errs);
	check_summary();
	check_cube("a", KG_METHOD_PCA, 1e-6);

	/* interleaves and formats */
	CHECK(FX_RUN("estimate", "--calib", cam_path, tif, "-o", fx_path("b.hdr"), "--interleave",
	             "bip") == 0,
	      "estimate bip: %s", fx_errs);
	check_same_values("a.hdr", "b.hdr");
	CHECK(FX_RUN("estimate", "--calib", cam_path, tif, "-o", fx_path("h.hdr"), "--format",
	             "f16") == 0,
	      "estimate f16: %s", fx_errs);
	CHECK(FX_RUN("estimate", "--calib", cam_path, tif, "-o", fx_path("hb.hdr"), "--format", "f16",
	             "--interleave", "bip") == 0,
	      "estimate f16 bip: %s", fx_errs);
	check_f16("h.hdr", "a.hdr");
	check_same_values("h.hdr", "hb.hdr");
	CHECK(FX_RUN("estimate", "--calib", cam_path, tif, "-o", fx_path("w.hdr"), "--format",
	             "weights") == 0,
	      "estimate weights: %s", fx_errs);
	check_weights();

	/* threads and block sizes: identical bytes */
	char whole[16];
	snprintf(whole, sizeof(whole), "%d", H);
	const char *variants[][4] = {
		{"t1", "--threads", "1", NULL}, {"t2", "--threads", "2", NULL},
		{"r1", "--block-rows", "1", NULL}, {"r7", "--block-rows", "7", NULL},
		{"rH", "--block-rows", whole, NULL},
	};
	for (size_t v = 0; v < sizeof(variants) / sizeof(variants[0]); v++) {
		char out[600];
		snprintf(out, sizeof(out), "%s.hdr", fx_path(variants[v][0]));
		CHECK(FX_RUN("estimate", "--calib", cam_path, tif, "-o", out, variants[v][1],
		             variants[v][2], "--threads", v == 1 ? "2" : "1") == 0,
		      "estimate %s: %s", variants[v][0], fx_errs);
		char a[600], b[600];
		snprintf(a, sizeof(a), "%s.img", fx_path("a"));
		snprintf(b, sizeof(b), "%s.img", fx_path(variants[v][0]));
		CHECK(kg_test_same_file(a, b), "%s differs from the default run", b);
		snprintf(a, sizeof(a), "%s_mask.img", fx_path("a"));
		snprintf(b, sizeof(b), "%s_mask.img", fx_path(variants[v][0]));
		CHECK(kg_test_same_file(a, b), "%s differs from the default run", b);
	}

	/* rootpoly3: M2 applied to the pixels first; and a LUT of pca */
	CHECK(FX_RUN("estimate", "--calib", cam_path, tif, "-o", fx_path("rp.hdr"), "--method",
	             "rootpoly3") == 0,
	      "estimate rootpoly3: %s", fx_errs);
	check_cube("rp", KG_METHOD_ROOTPOLY3, 1e-6);
	CHECK(FX_RUN("estimate", "--calib", cam_path, tif, "-o", fx_path("lut.hdr"), "--method",
	             "lut", "--lut-size", "33") == 0,
	      "estimate lut: %s", fx_errs);
	check_cube("lut", KG_METHOD_PCA, 1e-5);

	kg_image_free(&img);
	kg_camera_calib_free(&cam);
	int rc = kg_test_done("apply-estimate");
	if (rc == 0)
		fx_cleanup();
	else
		fprintf(stderr, "files kept in %s\n", fx_dir);
	return rc;
}
