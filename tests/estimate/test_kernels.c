/* The optimised kernels against the reference: for every method and output format,
 * with cached and streaming stores, aligned and misaligned destinations, on an image
 * of odd size with NaN, Inf, clipped and negative pixels. The comparison is exact
 * (memcmp of every output byte, mask and counter): both paths perform the same IEEE
 * operations in the same order, so any difference is a bug, not rounding. */
#include "est_fixture.h"
#include "kg_test.h"

#define W 203
#define H 37

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
               kg_est_isa isa, kg_est_stores stores, size_t shift, const float *rgb, result *out)
{
	kg_est_job job;
	kg_est_job_init(&job, k, f);
	job.classifier = cls;
	job.isa = isa;
	job.stores = stores;
	job.block_rows = 5;
	size_t es = kg_est_format_elem_size(f);
	out->bytes = (size_t)W * H * kg_est_format_bands(k, f) * es;
	char *buf = aligned_alloc(64, (out->bytes + shift * es + 63) & ~(size_t)63);
	memset(buf, 0xa5, out->bytes + shift * es);
	out->conf = calloc(W * H, sizeof(float));
	out->mask = calloc(W * H, 1);
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
	CHECK(memcmp(a->mask, b->mask, W * H) == 0, "%s: mask differs", what);
	if (f == KG_EST_LABELS)
		CHECK(memcmp(a->conf, b->conf, W * H * sizeof(float)) == 0, "%s: confidence differs",
		      what);
	CHECK(memcmp(&a->stats, &b->stats, sizeof(a->stats)) == 0,
	      "%s: stats differ: clamped %llu/%llu vs %llu/%llu", what,
	      (unsigned long long)a->stats.clamped_pixels,
	      (unsigned long long)a->stats.clamped_values,
	      (unsigned long long)b->stats.clamped_pixels,
	      (unsigned long long)b->stats.clamped_values);
}

int main(void)
{
	kg_est_job probe;
	fx_kernels ks;
	CHECK(fx_kernels_make(&ks, 7) == 0, "kernels");
	kg_est_job_init(&probe, ks.linear, KG_EST_F32_BIP);
	probe.isa = KG_EST_ISA_AVX2;
	float px[3] = {0.5f, 0.5f, 0.5f}, out[KG_NBANDS];
	if (kg_est_run(&probe, px, 1, 1, &(kg_est_dest){out, NULL, NULL}, NULL, NULL) ==
	    KG_ENOTSUP) {
		fx_kernels_free(&ks);
		kg_test_skip("this CPU has no AVX2/F16C: there is no optimised kernel to compare");
	}

	fx_rng rng = {11};
	/* up to 1.2 so that clipping and out-of-LUT inputs occur besides the planted cases */
	float *rgb = fx_image(&rng, (size_t)W * H, -0.05, 1.2, 1);
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
	int compared = 0;
	for (size_t ki = 0; ki < sizeof(kernels) / sizeof(kernels[0]); ki++) {
		const kg_est_kernel *k = kernels[ki].k;
		for (int f = 0; f < KG_EST_NFORMATS; f++) {
			if ((f == KG_EST_WEIGHTS || f == KG_EST_LABELS) && !kg_est_kernel_k(k))
				continue;
			for (int dist = 0; dist < (f == KG_EST_LABELS ? 2 : 1); dist++) {
				kg_est_classifier *cls = NULL;
				if (f == KG_EST_LABELS) {
					kg_err err = {{0}};
					int rc = kg_est_classifier_new(k, mats, 16, (kg_est_distance)dist, &cls, &err);
					CHECK(rc == 0, "classifier: %s", err.msg);
				}
				result ref = {0};
				run(k, (kg_est_format)f, cls, KG_EST_ISA_C, KG_EST_STORES_CACHED, 0, rgb, &ref);
				CHECK(ref.stats.nonfinite > 0 && ref.stats.clipped > 0, "hard cases present");
				for (int stores = 1; stores <= 2; stores++)
					for (size_t shift = 0; shift < 2; shift++) {
						char what[128];
						snprintf(what, sizeof(what), "%s %s%s %s, shift %zu", kernels[ki].name,
						         fmt_names[f], f == KG_EST_LABELS ? (dist ? " scale-free" : " plain") : "",
						         stores == 1 ? "cached" : "streaming", shift);
						result opt = {0};
						run(k, (kg_est_format)f, cls, KG_EST_ISA_AVX2, (kg_est_stores)stores, shift,
						    rgb, &opt);
						compare(what, &ref, &opt, (kg_est_format)f);
						result_free(&opt);
						compared++;
					}
				result_free(&ref);
				kg_est_classifier_free(&cls);
			}
		}
	}
	printf("%d optimised runs compared with the reference\n", compared);
	CHECK(compared == 4 * (6 * 4 + 4 + 4 * 2), "every combination ran: %d", compared);
	free(rgb);
	fx_kernels_free(&ks);
	return kg_test_done("estimate kernels: optimised == reference");
}
