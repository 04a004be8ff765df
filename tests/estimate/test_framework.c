/* The framework: identical output for 1 and 2 threads and block sizes 1, 7, 64 and
 * the whole image, in memory and streamed to a sink; NaN/Inf/clipped pixels flagged
 * with NaN output and label 0; negative reflectance clamped and counted exactly;
 * refusals name their cause. */
#include "est_fixture.h"
#include "kg_test.h"

#define W 97
#define H 53

typedef struct image_out {
	unsigned char *data;
	float *conf;
	uint8_t *mask;
	kg_est_stats stats;
	size_t bytes;
} image_out;

static void out_alloc(image_out *o, const kg_est_kernel *k, kg_est_format f, int w, int h)
{
	o->bytes = (size_t)w * h * kg_est_format_bands(k, f) * kg_est_format_elem_size(f);
	o->data = calloc(o->bytes, 1);
	o->conf = calloc((size_t)w * h, sizeof(float));
	o->mask = calloc((size_t)w * h, 1);
}

static void out_free(image_out *o)
{
	free(o->data);
	free(o->conf);
	free(o->mask);
	memset(o, 0, sizeof(*o));
}

static int same(const image_out *a, const image_out *b, int w, int h)
{
	return memcmp(a->data, b->data, a->bytes) == 0 && memcmp(a->mask, b->mask, (size_t)w * h) == 0 &&
	       memcmp(a->conf, b->conf, (size_t)w * h * sizeof(float)) == 0 &&
	       memcmp(&a->stats, &b->stats, sizeof(a->stats)) == 0;
}

static int run_mem(const kg_est_job *job, const float *rgb, int w, int h, image_out *o)
{
	kg_err err = {{0}};
	out_alloc(o, job->kernel, job->format, w, h);
	int rc = kg_est_run(job, rgb, w, h, &(kg_est_dest){o->data, o->conf, o->mask}, &o->stats,
	                    &err);
	CHECK(rc == 0, "run: %s", err.msg);
	return rc;
}

/* A sink that puts blocks back together into a whole image. */
typedef struct assemble {
	image_out *o;
	int next_y, calls, fail_at, height;
	size_t elem;
} assemble;

static int assemble_sink(void *user, const kg_est_block *b, kg_err *err)
{
	assemble *a = user;
	if (a->calls++ == a->fail_at)
		return kg_fail(err, KG_EIO, "sink: disk full (planted)");
	CHECK(b->y0 == a->next_y, "blocks in row order: got %d, expected %d", b->y0, a->next_y);
	a->next_y = b->y0 + b->rows;
	size_t n = (size_t)b->rows * b->width, first = (size_t)b->y0 * b->width;
	if (b->format == KG_EST_F32_BSQ || b->format == KG_EST_F16_BSQ) {
		for (int p = 0; p < b->bands; p++)
			memcpy(a->o->data + ((size_t)p * b->width * a->height + first) * a->elem,
			       (const char *)b->data + (size_t)p * n * a->elem, n * a->elem);
	} else {
		memcpy(a->o->data + first * b->bands * a->elem, b->data, n * b->bands * a->elem);
	}
	memcpy(a->o->mask + first, b->mask, n);
	if (b->confidence)
		memcpy(a->o->conf + first, b->confidence, n * sizeof(float));
	return 0;
}

static void check_threads_and_blocks(const kg_est_kernel *k, const kg_est_classifier *cls,
                                     const float *rgb, const char *name)
{
	for (int f = 0; f < KG_EST_NFORMATS; f++) {
		if ((f == KG_EST_WEIGHTS || f == KG_EST_LABELS) && !kg_est_kernel_k(k))
			continue;
		kg_est_job job;
		kg_est_job_init(&job, k, (kg_est_format)f);
		job.classifier = cls;
		job.threads = 1;
		job.block_rows = H;
		image_out whole = {0};
		run_mem(&job, rgb, W, H, &whole);
		const int blocks[] = {1, 7, 64, H};
		for (int t = 1; t <= 2; t++)
			for (int b = 0; b < 4; b++)
				for (int stream = 0; stream < 2; stream++) {
					job.threads = t;
					job.block_rows = blocks[b];
					image_out o = {0};
					if (stream) {
						out_alloc(&o, k, job.format, W, H);
						assemble a = {&o, 0, 0, -1, H, kg_est_format_elem_size(job.format)};
						kg_err err = {{0}};
						int rc = kg_est_run_stream(&job, rgb, W, H, assemble_sink, &a, &o.stats, &err);
						CHECK(rc == 0 && a.next_y == H, "stream: %s", err.msg);
					} else {
						run_mem(&job, rgb, W, H, &o);
					}
					CHECK(same(&whole, &o, W, H), "%s format %d: %d threads, %d rows, %s differs", name,
					      f, t, blocks[b], stream ? "streamed" : "in memory");
					out_free(&o);
				}
		out_free(&whole);
	}
}

static int is_f16_nan(uint16_t h) { return (h & 0x7c00) == 0x7c00 && (h & 0x3ff); }

static void check_flags(const fx_kernels *ks, const kg_est_classifier *cls)
{
	/* pixel: 0 fine, 1 NaN, 2 +Inf, 3 -Inf, 4 clipped, 5 exactly at the clip level,
	 * 6 just below it, 7 fine, 8 NaN and clipped (NaN wins) */
	const float clip = 0.999f;
	float rgb[9 * 3] = {0.2f, 0.3f, 0.4f, NAN,  0.3f, 0.4f,    0.2f, INFINITY, 0.4f,
	                    0.2f, 0.3f, -INFINITY, 0.2f, 1.0f, 0.4f, 0.2f, 0.3f,   clip,
	                    0.998f, 0.3f, 0.4f, 0.5f, 0.5f, 0.5f, NAN, 1.0f, 0.4f};
	const uint8_t expect[9] = {0,
	                           KG_EST_MASK_NONFINITE,
	                           KG_EST_MASK_NONFINITE,
	                           KG_EST_MASK_NONFINITE,
	                           KG_EST_MASK_CLIPPED,
	                           KG_EST_MASK_CLIPPED,
	                           0,
	                           0,
	                           KG_EST_MASK_NONFINITE};
	for (int isa = KG_EST_ISA_AUTO; isa <= KG_EST_ISA_C; isa++)
		for (int f = 0; f < KG_EST_NFORMATS; f++) {
			kg_est_job job;
			kg_est_job_init(&job, f == KG_EST_LABELS ? ks->lut : ks->pca, (kg_est_format)f);
			job.classifier = cls;
			job.isa = (kg_est_isa)isa;
			job.clip_level = clip;
			image_out o = {0};
			run_mem(&job, rgb, 9, 1, &o);
			int nb = kg_est_format_bands(job.kernel, job.format);
			for (int i = 0; i < 9; i++) {
				CHECK((o.mask[i] & 3) == expect[i], "format %d pixel %d: mask %u, expected %u", f, i,
				      o.mask[i], expect[i]);
				int flagged = expect[i] != 0;
				for (int b = 0; b < nb; b++) {
					int nan;
					switch (f) {
					case KG_EST_F32_BSQ:
						nan = isnan(((float *)o.data)[b * 9 + i]);
						break;
					case KG_EST_F16_BSQ:
						nan = is_f16_nan(((uint16_t *)o.data)[b * 9 + i]);
						break;
					case KG_EST_F16_BIP:
						nan = is_f16_nan(((uint16_t *)o.data)[i * nb + b]);
						break;
					case KG_EST_LABELS:
						nan = o.data[i] == KG_EST_LABEL_NONE && isnan(o.conf[i]);
						CHECK(flagged || (o.data[i] >= 1 && o.data[i] <= 16 && o.conf[i] >= 0),
						      "pixel %d classified: label %u", i, o.data[i]);
						break;
					default:
						nan = isnan(((float *)o.data)[i * nb + b]);
						break;
					}
					CHECK(nan == flagged, "format %d pixel %d band %d: NaN %d, flagged %d", f, i, b,
					      nan, flagged);
				}
			}
			CHECK(o.stats.nonfinite == 4 && o.stats.clipped == 2 && o.stats.pixels == 9,
			      "format %d: counted %llu non-finite, %llu clipped", f,
			      (unsigned long long)o.stats.nonfinite, (unsigned long long)o.stats.clipped);
			out_free(&o);
		}

	/* with clipping disabled only the non-finite pixels are flagged */
	kg_est_job job;
	kg_est_job_init(&job, ks->linear, KG_EST_F32_BIP);
	job.clip_level = INFINITY;
	image_out o = {0};
	run_mem(&job, rgb, 9, 1, &o);
	CHECK(o.stats.clipped == 0 && o.stats.nonfinite == 4, "clip level Inf");
	out_free(&o);
}

static void check_clamping(void)
{
	/* bands 0..19: r - g (negative when g > r); bands 20..60: 0.5 r. Weights keep
	 * their sign. */
	double a[KG_NBANDS * 3] = {0}, basis[KG_NBANDS * 2] = {0}, m[2 * 3] = {1, -1, 0, 0, 0, 1};
	for (int o = 0; o < KG_NBANDS; o++) {
		a[o * 3 + 0] = o < 20 ? 1.0 : 0.5;
		a[o * 3 + 1] = o < 20 ? -1.0 : 0.0;
	}
	basis[0] = 1; /* e_0 and e_1: orthonormal */
	basis[1 * 2 + 1] = 1;
	kg_est_kernel *k = NULL, *kw = NULL;
	CHECK(kg_est_kernel_new(&(kg_est_desc){KG_EST_LINEAR, 0, a, NULL, NULL, NULL}, &k, NULL) == 0,
	      "kernel");
	CHECK(kg_est_kernel_new(&(kg_est_desc){KG_EST_LINEAR, 2, m, NULL, basis, NULL}, &kw, NULL) == 0,
	      "kernel with basis");
	enum { N = 50 };
	float rgb[N * 3];
	int negatives = 0;
	for (int i = 0; i < N; i++) {
		int neg = i % 3 == 1;
		negatives += neg;
		rgb[3 * i + 0] = 0.2f;
		rgb[3 * i + 1] = neg ? 0.5f : 0.1f;
		rgb[3 * i + 2] = 0.3f;
	}
	for (int isa = KG_EST_ISA_AUTO; isa <= KG_EST_ISA_C; isa++)
		for (int f = 0; f < KG_EST_NFORMATS; f++) {
			if (f == KG_EST_LABELS)
				continue;
			kg_est_job job;
			kg_est_job_init(&job, f == KG_EST_WEIGHTS ? kw : k, (kg_est_format)f);
			job.isa = (kg_est_isa)isa;
			image_out o = {0};
			run_mem(&job, rgb, N, 1, &o);
			if (f == KG_EST_WEIGHTS) {
				CHECK(o.stats.clamped_values == 0 && o.stats.clamped_pixels == 0,
				      "weights are not clamped");
				for (int i = 0; i < N; i++)
					CHECK(((float *)o.data)[2 * i] == rgb[3 * i] - rgb[3 * i + 1],
					      "weight keeps its sign");
			} else {
				CHECK(o.stats.clamped_pixels == (uint64_t)negatives &&
				          o.stats.clamped_values == (uint64_t)negatives * 20,
				      "format %d isa %d: clamped %llu pixels, %llu values; expected %d, %d", f, isa,
				      (unsigned long long)o.stats.clamped_pixels,
				      (unsigned long long)o.stats.clamped_values, negatives, negatives * 20);
				for (int i = 0; i < N; i++) {
					CHECK(!!(o.mask[i] & KG_EST_MASK_CLAMPED) == (i % 3 == 1), "pixel %d mask", i);
					float v0 = f == KG_EST_F32_BSQ   ? ((float *)o.data)[i]
					           : f == KG_EST_F32_BIP ? ((float *)o.data)[i * KG_NBANDS]
					           : f == KG_EST_F16_BSQ ? kg_f32_from_f16(((uint16_t *)o.data)[i])
					                                 : kg_f32_from_f16(((uint16_t *)o.data)[i * KG_NBANDS]);
					CHECK(v0 >= 0.0f, "clamped value is %g", (double)v0);
				}
			}
			out_free(&o);
		}
	kg_est_kernel_free(&k);
	kg_est_kernel_free(&kw);
}

static void check_refusals(const fx_kernels *ks, const kg_est_classifier *cls)
{
	kg_err err = {{0}};
	float rgb[3] = {0.1f, 0.2f, 0.3f}, out[KG_NBANDS];
	uint8_t lab;
	kg_est_job job;
	kg_est_job_init(&job, ks->linear, KG_EST_WEIGHTS);
	int rc = kg_est_run(&job, rgb, 1, 1, &(kg_est_dest){out, NULL, NULL}, NULL, &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "basis"), "weights without a basis: %s", err.msg);
	kg_est_job_init(&job, ks->pca, KG_EST_LABELS);
	rc = kg_est_run(&job, rgb, 1, 1, &(kg_est_dest){&lab, NULL, NULL}, NULL, &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "classifier"), "labels without classifier: %s",
	      err.msg);
	job.kernel = ks->centred; /* cls was made for pca's basis */
	job.classifier = cls;
	rc = kg_est_run(&job, rgb, 1, 1, &(kg_est_dest){&lab, NULL, NULL}, NULL, &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "basis"), "classifier of another basis: %s", err.msg);
	kg_est_job_init(&job, ks->pca, KG_EST_F32_BIP);
	rc = kg_est_run(&job, rgb, 0, 1, &(kg_est_dest){out, NULL, NULL}, NULL, &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "size"), "empty image: %s", err.msg);
	job.clip_level = NAN;
	rc = kg_est_run(&job, rgb, 1, 1, &(kg_est_dest){out, NULL, NULL}, NULL, &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "clip"), "NaN clip level: %s", err.msg);

	double a[KG_NBANDS * 3] = {0}, basis[KG_NBANDS * 2] = {0}, m[6] = {0};
	a[5] = NAN;
	kg_est_kernel *k = NULL;
	rc = kg_est_kernel_new(&(kg_est_desc){KG_EST_LINEAR, 0, a, NULL, NULL, NULL}, &k, &err);
	CHECK(rc == KG_EINVAL && !k && strstr(err.msg, "finite"), "NaN matrix: %s", err.msg);
	rc = kg_est_kernel_new(&(kg_est_desc){KG_EST_LUT, 0, m, NULL, NULL, NULL}, &k, &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "LUT"), "LUT by description: %s", err.msg);
	rc = kg_est_kernel_new_lut(ks->pca, 1, 0, 1, &k, &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "nodes"), "1-node LUT: %s", err.msg);
	rc = kg_est_kernel_new_lut(ks->lut, 9, 0, 1, &k, &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "not a LUT"), "LUT of a LUT: %s", err.msg);

	/* a basis that is not orthonormal cannot classify in the subspace */
	for (int o = 0; o < KG_NBANDS; o++) {
		basis[o * 2] = 0.2;
		basis[o * 2 + 1] = o < 30 ? 0.2 : -0.2;
	}
	rc = kg_est_kernel_new(&(kg_est_desc){KG_EST_LINEAR, 2, m, NULL, basis, NULL}, &k, &err);
	CHECK(rc == 0, "kernel: %s", err.msg);
	double spec[KG_NBANDS] = {0};
	kg_est_classifier *c = NULL;
	rc = kg_est_classifier_new(k, &(kg_est_material){"gold", spec}, 1, KG_EST_DIST_PLAIN, &c, &err);
	CHECK(rc == KG_EINVAL && !c && strstr(err.msg, "orthonormal"), "non-orthonormal basis: %s",
	      err.msg);
	rc = kg_est_classifier_new(ks->linear, &(kg_est_material){"gold", spec}, 1,
	                           KG_EST_DIST_PLAIN, &c, &err);
	CHECK(rc == KG_EINVAL && strstr(err.msg, "basis"), "classifier without basis: %s", err.msg);
	kg_est_kernel_free(&k);
}

static int fail_sink_calls;
static int failing_sink(void *user, const kg_est_block *b, kg_err *err)
{
	assemble *a = user;
	fail_sink_calls++;
	return assemble_sink(a, b, err);
}

static void check_sink_error(const fx_kernels *ks, const float *rgb)
{
	for (int t = 1; t <= 2; t++) {
		kg_est_job job;
		kg_est_job_init(&job, ks->pca, KG_EST_F32_BSQ);
		job.threads = t;
		job.block_rows = 4;
		image_out o = {0};
		out_alloc(&o, ks->pca, job.format, W, H);
		assemble a = {&o, 0, 0, 2, H, 4};
		kg_err err = {{0}};
		fail_sink_calls = 0;
		int rc = kg_est_run_stream(&job, rgb, W, H, failing_sink, &a, NULL, &err);
		CHECK(rc == KG_EIO && strstr(err.msg, "disk full") && fail_sink_calls == 3,
		      "sink error stops the run: rc %d, %d calls, %s", rc, fail_sink_calls, err.msg);
		out_free(&o);
	}
}

int main(void)
{
	fx_kernels ks;
	CHECK(fx_kernels_make(&ks, 3) == 0, "kernels");
	fx_rng rng = {5};
	float *rgb = fx_image(&rng, (size_t)W * H, -0.05, 1.1, 1);
	double spectra[16 * KG_NBANDS];
	fx_materials(&rng, 16, spectra);
	kg_est_material mats[16];
	char names[16][8];
	for (int j = 0; j < 16; j++) {
		snprintf(names[j], sizeof(names[j]), "m%d", j);
		mats[j] = (kg_est_material){names[j], spectra + j * KG_NBANDS};
	}
	kg_est_classifier *cls_pca = NULL, *cls_lut = NULL;
	CHECK(kg_est_classifier_new(ks.pca, mats, 16, KG_EST_DIST_SCALE_FREE, &cls_pca, NULL) == 0,
	      "classifier");
	CHECK(kg_est_classifier_new(ks.lut, mats, 16, KG_EST_DIST_PLAIN, &cls_lut, NULL) == 0,
	      "classifier");

	check_threads_and_blocks(ks.pca, cls_pca, rgb, "pca");
	check_threads_and_blocks(ks.lut, cls_lut, rgb, "lut");
	check_threads_and_blocks(ks.rootpoly3, NULL, rgb, "rootpoly3");
	check_flags(&ks, cls_lut);
	check_clamping();
	check_refusals(&ks, cls_pca);
	check_sink_error(&ks, rgb);

	kg_est_classifier_free(&cls_pca);
	kg_est_classifier_free(&cls_lut);
	free(rgb);
	fx_kernels_free(&ks);
	return kg_test_done("estimate framework");
}
