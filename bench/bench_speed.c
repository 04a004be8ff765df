/* The speed part: kernels through kg_est_run, and the non-temporal write limit for
 * the same bytes. Every measurement is the median of repeated runs into the same,
 * already faulted-in buffer (page faults of a fresh buffer are not a kernel's cost). */
#include <fcntl.h>
#include <pthread.h>
#include <spawn.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "bench_private.h"

double kg_bench_now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int kg_bench_run_program(char *const *argv, int quiet)
{
	/* posix_spawn (a vfork underneath), not fork: a benchmark holding a 12 Mpix image
	 * would first copy its page tables, and the timed program would wait for that */
	posix_spawn_file_actions_t fa;
	if (posix_spawn_file_actions_init(&fa) != 0)
		return -1;
	if (quiet) {
		posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
		posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
	}
	pid_t pid;
	int rc = posix_spawn(&pid, argv[0], &fa, NULL, argv, environ);
	posix_spawn_file_actions_destroy(&fa);
	int st = 0;
	if (rc != 0 || waitpid(pid, &st, 0) < 0)
		return -1;
	return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

void bench_progress(const kg_bench_config *cfg, const char *fmt, ...)
{
	if (!cfg->progress)
		return;
	char line[512];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(line, sizeof(line), fmt, ap);
	va_end(ap);
	cfg->progress(cfg->progress_user, line);
}

const char *kg_bench_stream_kind(void)
{
#if defined(__SSE2__)
	return "SSE2 non-temporal stores (movntdq)";
#else
	return "memset (no non-temporal stores built in)";
#endif
}

/* Fill [p, p + n) with non-temporal 16-byte stores (ordinary stores for the unaligned
 * ends). The bytes are those of float 0.5, not zeros, like real output. */
static void stream_fill(char *p, size_t n)
{
#if defined(__SSE2__)
	size_t head = (16 - ((uintptr_t)p & 15)) & 15;
	if (head > n)
		head = n;
	memset(p, 0x3f, head);
	p += head;
	n -= head;
	const __m128i v = _mm_set1_epi32(0x3f000000);
	size_t blocks = n / 64;
	for (size_t i = 0; i < blocks; i++, p += 64) {
		_mm_stream_si128((__m128i *)p, v);
		_mm_stream_si128((__m128i *)(p + 16), v);
		_mm_stream_si128((__m128i *)(p + 32), v);
		_mm_stream_si128((__m128i *)(p + 48), v);
	}
	_mm_sfence();
	memset(p, 0x3f, n % 64);
#else
	memset(p, 0x3f, n);
#endif
}

typedef struct share {
	char *p;
	size_t n;
	pthread_t thread;
} share;

static void *share_main(void *arg)
{
	share *s = arg;
	stream_fill(s->p, s->n);
	return NULL;
}

double kg_bench_stream_seconds(void *buf, size_t bytes, int threads)
{
	share sh[64];
	int created[64] = {0};
	if (threads > 64)
		threads = 64;
	size_t per = (bytes / (size_t)threads + 63) & ~(size_t)63;
	for (int i = 0; i < threads; i++) {
		size_t off = per * (size_t)i;
		sh[i].p = (char *)buf + off;
		sh[i].n = off >= bytes ? 0 : (bytes - off < per ? bytes - off : per);
	}
	double t0 = kg_bench_now();
	for (int i = 1; i < threads; i++) {
		created[i] = pthread_create(&sh[i].thread, NULL, share_main, &sh[i]) == 0;
		if (!created[i])
			stream_fill(sh[i].p, sh[i].n); /* no thread: do its share here */
	}
	stream_fill(sh[0].p, sh[0].n);
	for (int i = 1; i < threads; i++)
		if (created[i])
			pthread_join(sh[i].thread, NULL);
	return kg_bench_now() - t0;
}

const char *kg_bench_format_name(kg_est_format f)
{
	static const char *const names[KG_EST_NFORMATS] = {
		"f32-bsq", "f32-bip", "f16-bsq", "f16-bip", "weights", "labels",
	};
	return f >= 0 && f < KG_EST_NFORMATS ? names[f] : "unknown";
}

const char *kg_bench_isa_name(kg_est_isa isa)
{
	switch (isa) {
	case KG_EST_ISA_C:
		return "c";
	case KG_EST_ISA_AVX2:
		return "avx2+fma";
	case KG_EST_ISA_AVX512:
		return "avx512";
	default:
		return "auto";
	}
}

int kg_bench_isa_available(kg_est_isa isa)
{
	static const double zero[KG_NBANDS * 3];
	kg_est_kernel *k = NULL;
	if (kg_est_kernel_new(&(kg_est_desc){KG_EST_LINEAR, 0, zero, NULL, NULL, NULL}, &k, NULL) < 0)
		return 0;
	kg_est_job job;
	kg_est_job_init(&job, k, KG_EST_F32_BIP);
	job.isa = isa;
	job.threads = 1;
	float px[3] = {0.5f, 0.5f, 0.5f}, out[KG_NBANDS];
	int ok = kg_est_run(&job, px, 1, 1, &(kg_est_dest){out, NULL, NULL}, NULL, NULL) == 0;
	kg_est_kernel_free(&k);
	return ok;
}

/* The write limit of each (bytes per pixel, threads) pair: the median of the limits
 * measured beside its speed rows. */
static int collect_limits(kg_bench_results *r, kg_err *err)
{
	double *v = malloc(sizeof(double) * (size_t)(r->nspeed > 0 ? r->nspeed : 1));
	if (!v)
		return kg_fail(err, KG_ENOMEM, "bench: out of memory");
	for (int i = 0; i < r->nspeed; i++) {
		const kg_bench_speed_row *a = &r->speed[i];
		int seen = 0;
		for (int j = 0; j < r->nlimit; j++)
			seen |= r->limit[j].bytes_per_pixel == a->bytes_per_pixel &&
			        r->limit[j].threads == a->threads;
		if (seen)
			continue;
		int n = 0;
		for (int j = i; j < r->nspeed; j++)
			if (r->speed[j].bytes_per_pixel == a->bytes_per_pixel &&
			    r->speed[j].threads == a->threads)
				v[n++] = r->speed[j].limit_gb_s;
		kg_bench_limit_row *l = realloc(r->limit, sizeof(*l) * (size_t)(r->nlimit + 1));
		if (!l) {
			free(v);
			return kg_fail(err, KG_ENOMEM, "bench: out of memory");
		}
		r->limit = l;
		l = &r->limit[r->nlimit++];
		l->bytes_per_pixel = a->bytes_per_pixel;
		l->threads = a->threads;
		l->measurements = n;
		l->gb_s = kg_bench_percentile(v, n, 0.5);
	}
	free(v);
	return 0;
}

/* The paths a (method, format) row is measured with: every optimised path the CPU
 * has, and the reference too for pca3's BSQ outputs (the reference is slow: its
 * fmaf is a library call on a build for any x86-64). Returns how many. */
static int row_paths(int m, kg_est_format fmt, const int *have, kg_est_isa *paths)
{
	int n = 0;
	if (m == KG_BENCH_PCA3 && (fmt == KG_EST_F32_BSQ || fmt == KG_EST_F16_BSQ))
		paths[n++] = KG_EST_ISA_C;
	if (have[KG_EST_ISA_AVX2])
		paths[n++] = KG_EST_ISA_AVX2;
	if (have[KG_EST_ISA_AVX512])
		paths[n++] = KG_EST_ISA_AVX512;
	if (!n)
		paths[n++] = KG_EST_ISA_C;
	return n;
}

int bench_speed_all(const kg_bench_config *cfg, kg_est_kernel *const *k,
                    const kg_est_classifier *cls, const float *rgb, int width, int height,
                    void *out, float *conf, kg_bench_results *r, kg_err *err)
{
	int have[KG_EST_NISAS] = {0};
	for (int i = KG_EST_ISA_C; i < KG_EST_NISAS; i++)
		have[i] = kg_bench_isa_available((kg_est_isa)i);
	kg_est_isa paths[KG_EST_NISAS];
	static const kg_est_format formats[] = {KG_EST_F32_BSQ, KG_EST_F16_BSQ, KG_EST_WEIGHTS,
	                                        KG_EST_LABELS};
	const int nformats = (int)(sizeof(formats) / sizeof(formats[0]));
	size_t npix = (size_t)width * (size_t)height;
	int reps = cfg->reps < 1 ? 1 : (cfg->reps > 64 ? 64 : cfg->reps);
	/* Count the measurements first, for the progress lines. */
	int total = 0, done = 0;
	for (int m = 0; m < KG_BENCH_NMETHODS; m++)
		for (int f = 0; f < nformats; f++)
			if (k[m] && (formats[f] == KG_EST_F32_BSQ || formats[f] == KG_EST_F16_BSQ ||
			             (formats[f] == KG_EST_WEIGHTS && kg_est_kernel_k(k[m]) > 0) ||
			             (formats[f] == KG_EST_LABELS && m == KG_BENCH_PCA3 && cls)))
				total += cfg->nthreads * row_paths(m, formats[f], have, paths);
	int ret = 0;
	for (int m = 0; m < KG_BENCH_NMETHODS && !ret; m++) {
		if (!k[m])
			continue;
		for (int f = 0; f < nformats && !ret; f++) {
			kg_est_format fmt = formats[f];
			if ((fmt == KG_EST_WEIGHTS && kg_est_kernel_k(k[m]) == 0) ||
			    (fmt == KG_EST_LABELS && (m != KG_BENCH_PCA3 || !cls)))
				continue;
			double bpp = (double)kg_est_format_bands(k[m], fmt) *
			             (double)kg_est_format_elem_size(fmt);
			if (fmt == KG_EST_LABELS)
				bpp += sizeof(float); /* the confidence beside the label */
			int npaths = row_paths(m, fmt, have, paths);
			for (int pt = 0; pt < npaths * cfg->nthreads && !ret; pt++) {
				int pi = pt / cfg->nthreads, threads = cfg->threads[pt % cfg->nthreads];
				kg_est_job job;
				kg_est_job_init(&job, k[m], fmt);
				job.threads = threads;
				job.isa = paths[pi];
				job.classifier = fmt == KG_EST_LABELS ? cls : NULL;
				kg_est_dest dest = {out, fmt == KG_EST_LABELS ? conf : NULL, NULL};
				/* Kernel runs and limit runs alternate, so both see the same
				 * state of the machine (it drifts, and other work may share it). */
				size_t bytes = (size_t)(bpp * (double)npix);
				double t[64], tl[64];
				ret = kg_est_run(&job, rgb, width, height, &dest, NULL, err); /* warm-up */
				kg_bench_stream_seconds(out, bytes, threads);
				for (int i = 0; i < reps && !ret; i++) {
					double t0 = kg_bench_now();
					ret = kg_est_run(&job, rgb, width, height, &dest, NULL, err);
					t[i] = kg_bench_now() - t0;
					tl[i] = kg_bench_stream_seconds(out, bytes, threads);
				}
				if (ret)
					break;
				double limit = (double)bytes / kg_bench_percentile(tl, reps, 0.5) * 1e-9;
				kg_bench_speed_row *row =
				    realloc(r->speed, sizeof(*row) * (size_t)(r->nspeed + 1));
				if (!row) {
					ret = kg_fail(err, KG_ENOMEM, "bench: out of memory");
					break;
				}
				r->speed = row;
				row = &r->speed[r->nspeed++];
				row->method = (kg_bench_method)m;
				row->format = fmt;
				row->isa = paths[pi];
				row->threads = threads;
				row->bytes_per_pixel = bpp;
				row->seconds = kg_bench_percentile(t, reps, 0.5);
				row->mpix_s = (double)npix / row->seconds * 1e-6;
				row->gb_s = (double)npix * bpp / row->seconds * 1e-9;
				row->limit_gb_s = limit;
				row->fraction = row->gb_s / limit;
				bench_progress(cfg,
				               "[speed %d/%d] %-10s %-8s %-8s %d thread%s: %7.1f Mpix/s, "
				               "%6.2f GB/s = %.2f of the write limit (%.1f GB/s)",
				               ++done, total, kg_bench_method_name(row->method),
				               kg_bench_format_name(fmt), kg_bench_isa_name(row->isa), threads,
				               threads == 1 ? " " : "s",
				               row->mpix_s, row->gb_s, row->fraction, limit);
			}
		}
	}
	return ret ? ret : collect_limits(r, err);
}
