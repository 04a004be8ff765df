/* The optimised kernels against the reference: for every method and output format,
 * with cached and streaming stores, aligned and misaligned destinations, on images
 * with NaN, Inf, clipped and negative pixels, and on extreme inputs (huge values
 * whose products overflow, subnormals, signed zeros) with clipping off. Sizes: an odd
 * width and height (203 x 37, no multiple of any vector width), one pixel, a row of
 * 13, a 112 x 6 image whose planes are 64-byte aligned (the streaming BSQ stores
 * write whole lines there; the second row block is only 32-byte aligned in f16) with
 * a partial last group, and a 100 x 32 image with 64-byte aligned planes whose first
 * block (500 pixels) ends in a chunk of 244, a vector of 4 pixels at its end. The comparison is exact (memcmp of every output byte, mask
 * and counter): every path performs the same IEEE operations in the same order, the
 * multiply-adds fused in all of them (fmaf in the reference), so any difference is a
 * bug, not rounding.
 *
 * The path is the program's argument: avx2 (the default) or avx512. A path the CPU
 * lacks must be refused with KG_ENOTSUP; the test then skips, saying so. */
#include "est_fixture.h"
#include "kg_test.h"

static int W = 203, H = 37;

typedef struct result {
	void *data;
	float *conf;
	uint8_t *mask;
	kg_est_stats stats;
	size_t bytes;
} result;

static void result_free(result *r)
{
	free(r->data);
	free(r->conf);
	free(r->mask);
	memset(r, 0, sizeof(*r));
}

/* Run and copy the output out of a buffer that starts `shift` elements past a
 * 64-byte boundary. */
static int run(const kg_est_kernel *k, kg_est_format f, const kg_est_classifier *cls,
               kg_est_isa isa, kg_est_stores stores, size_t shift, float clip, const float *rgb,
               result *out)
{
	kg_est_job job;
	kg_est_job_init(&job, k, f);
	job.classifier = cls;
	job.isa = isa;
	job.stores = stores;
	job.block_rows = 5;
	job.clip_level = clip;
	size_t es = kg_est_format_elem_size(f);
	out->bytes = (size_t)W * H * kg_est_format_bands(k, f) * es;
	char *buf = aligned_alloc(64, (out->bytes + shift * es + 63) & ~(size_t)63);
	memset(buf, 0xa5, out->bytes + shift * es);
	out->conf = calloc((size_t)W * H, sizeof(float));
	out->mask = calloc((size_t)W * H, 1);
	kg_est_dest dest = {buf + shift * es, out->conf, out->mask};
	kg_err err = {{0}};
	int rc = kg_est_run(&job, rgb, W, H, &dest, &out->stats, &err);
	CHECK(rc == 0, "run: %s", err.msg);
	out->data = malloc(out->bytes);
	memcpy(out->data, buf + shift * es, out->bytes);
	free(buf);
	return rc;
}

static void compare(const char *what, const result *a, const result *b, kg_est_format f)
{
	CHECK(memcmp(a->data, b->data, a->bytes) == 0, "%s: output differs", what);
	CHECK(memcmp(a->mask, b->mask, (size_t)W * H) == 0, "%s: mask differs", what);
	if (f == KG_EST_LABELS)
		CHECK(memcmp(a->conf, b->conf, (size_t)W * H * sizeof(float)) == 0, "%s: confidence differs",
		      what);
	CHECK(memcmp(&a->stats, &b->stats, sizeof(a->stats)) == 0,
	      "%s: stats differ: clamped %llu/%llu vs %llu/%llu", what,
	      (unsigned long long)a->stats.clamped_pixels,
	      (unsigned long long)a->stats.clamped_values,
	      (unsigned long long)b->stats.clamped_pixels,
	      (unsigned long long)b->stats.clamped_values);
}

/* Inputs beyond any camera's range, for runs with clipping off: huge values whose
 * products and sums overflow (Inf, then Inf - Inf = NaN), the largest float,
 * subnormals, signed zeros, huge negatives, mixed with ordinary values and the
 * non-finite ones. */
static float *extreme_image(fx_rng *r, size_t n)
{
	static const float odd[] = {1e30f, -1e30f, 3.4028235e38f, 1e-40f, 1.4e-45f, 0.0f, -0.0f,
	                            1e19f, -3e38f, NAN, INFINITY, 65519.0f, 1e-20f, 7.0f};
	const size_t nodd = sizeof(odd) / sizeof(odd[0]);
	float *rgb = fx_image(r, n, -0.2, 1.3, 0);
	for (size_t i = 0; i < 3 * n; i++)
		if (fx_next(r) % 3 == 0)
			rgb[i] = odd[fx_next(r) % nodd];
	return rgb;
}

typedef struct size_case {
	int w, h;
	int full; /* every store mode and shift, else cached and streaming at shift 0 */
} size_case;

int main(int argc, char **argv)
{
	const char *path = argc > 1 ? argv[1] : "avx2";
	kg_est_isa isa = !strcmp(path, "avx512") ? KG_EST_ISA_AVX512 : KG_EST_ISA_AVX2;
	kg_est_job probe;
	fx_kernels ks;
	CHECK(fx_kernels_make(&ks, 7) == 0, "kernels");
	kg_est_job_init(&probe, ks.linear, KG_EST_F32_BIP);
	float px[3] = {0.5f, 0.5f, 0.5f}, out[KG_NBANDS];
	probe.isa = KG_EST_NISAS;
	CHECK(kg_est_run(&probe, px, 1, 1, &(kg_est_dest){out, NULL, NULL}, NULL, NULL) == KG_EINVAL,
	      "an implementation out of range is refused");
	probe.isa = isa;
	int rc = kg_est_run(&probe, px, 1, 1, &(kg_est_dest){out, NULL, NULL}, NULL, NULL);
	CHECK(rc == 0 || rc == KG_ENOTSUP, "probe of the %s path: %d", path, rc);
	if (rc == KG_ENOTSUP) {
		fx_kernels_free(&ks);
		printf("the %s path is refused with KG_ENOTSUP on this CPU\n", path);
		kg_test_skip(isa == KG_EST_ISA_AVX512
		                 ? "this CPU has no AVX-512F: the AVX-512 path cannot run here"
		                 : "this CPU has no AVX2/FMA/F16C: there is no optimised kernel to compare");
	}

	fx_rng rng = {11};
	double spectra[16 * KG_NBANDS];
	fx_materials(&rng, 16, spectra);
	kg_est_material mats[16];
	char names[16][8];
	for (int j = 0; j < 16; j++) {
		snprintf(names[j], sizeof(names[j]), "m%d", j);
		mats[j] = (kg_est_material){names[j], spectra + j * KG_NBANDS};
	}

	const struct {
		const char *name;
		kg_est_kernel *k;
	} kernels[] = {{"linear", ks.linear},       {"pca", ks.pca},
	               {"centred", ks.centred},     {"rootpoly2", ks.rootpoly2},
	               {"rootpoly3", ks.rootpoly3}, {"lut", ks.lut}};
	const char *fmt_names[] = {"f32-bsq", "f32-bip", "f16-bsq", "f16-bip", "weights", "labels"};
	const size_case sizes[] = {{203, 37, 1}, {1, 1, 0}, {13, 1, 0}, {112, 6, 1}, {100, 32, 1}};
	int compared = 0, expected = 0;
	for (size_t si = 0; si < sizeof(sizes) / sizeof(sizes[0]); si++)
		for (int extreme = 0; extreme < 2; extreme++) {
			W = sizes[si].w;
			H = sizes[si].h;
			size_t npx = (size_t)W * H;
			/* up to 1.2 so that clipping and out-of-LUT inputs occur besides the planted
			 * cases; the extreme inputs run with clipping off */
			float *rgb = extreme ? extreme_image(&rng, npx) : fx_image(&rng, npx, -0.05, 1.2, 1);
			float clip = extreme ? INFINITY : 0.999f;
			if (npx == 1 && !extreme)
				rgb[0] = -0.01f; /* a negative channel in the lone pixel */
			for (size_t ki = 0; ki < sizeof(kernels) / sizeof(kernels[0]); ki++) {
				const kg_est_kernel *k = kernels[ki].k;
				for (int f = 0; f < KG_EST_NFORMATS; f++) {
					if ((f == KG_EST_WEIGHTS || f == KG_EST_LABELS) && !kg_est_kernel_k(k))
						continue;
					for (int dist = 0; dist < (f == KG_EST_LABELS ? 2 : 1); dist++) {
						kg_est_classifier *cls = NULL;
						if (f == KG_EST_LABELS) {
							kg_err err = {{0}};
							int crc =
							    kg_est_classifier_new(k, mats, 16, (kg_est_distance)dist, &cls, &err);
							CHECK(crc == 0, "classifier: %s", err.msg);
						}
						result ref = {0};
						run(k, (kg_est_format)f, cls, KG_EST_ISA_C, KG_EST_STORES_CACHED, 0, clip, rgb,
						    &ref);
						if (si == 0 && !extreme)
							CHECK(ref.stats.nonfinite > 0 && ref.stats.clipped > 0,
							      "hard cases present");
						if (si == 0 && extreme)
							CHECK(ref.stats.nonfinite > 0 && ref.stats.clipped == 0,
							      "extreme cases present, none clipped");
						for (int stores = 1; stores <= 2; stores++)
							for (size_t shift = 0; shift < (sizes[si].full ? 2u : 1u); shift++) {
								char what[160];
								snprintf(what, sizeof(what), "%s: %dx%d%s %s %s%s %s, shift %zu", path, W,
								         H, extreme ? " extreme" : "", kernels[ki].name, fmt_names[f],
								         f == KG_EST_LABELS ? (dist ? " scale-free" : " plain") : "",
								         stores == 1 ? "cached" : "streaming", shift);
								result opt = {0};
								run(k, (kg_est_format)f, cls, isa, (kg_est_stores)stores, shift, clip, rgb,
								    &opt);
								compare(what, &ref, &opt, (kg_est_format)f);
								result_free(&opt);
								compared++;
							}
						expected += sizes[si].full ? 4 : 2;
						result_free(&ref);
						kg_est_classifier_free(&cls);
					}
				}
			}
			free(rgb);
		}
	printf("%d %s runs compared with the reference\n", compared, path);
	/* per input (2) and size: 4 runs (sizes with every mode) or 2, each over 6 kernels x
	 * 4 formats, 4 with weights, 4 x 2 label distances */
	CHECK(compared == expected && expected == 2 * (4 + 2 + 2 + 4 + 4) * (6 * 4 + 4 + 4 * 2),
	      "every combination ran: %d of %d", compared, expected);
	fx_kernels_free(&ks);
	return kg_test_done(isa == KG_EST_ISA_AVX512 ? "estimate kernels: AVX-512 == reference"
	                                             : "estimate kernels: AVX2+FMA == reference");
}
