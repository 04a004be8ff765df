/* The framework: an image is cut into row blocks, which a small pool of threads
 * (created for the run) takes in turn. Kernels see only runs of pixels; tiling and
 * threads live here. Every pixel is computed independently, so the output does not
 * depend on the block size or the thread count. Counters are per thread and summed
 * at the end (integer sums, so the order does not matter).
 *
 * In memory mode blocks are written in place into the caller's image. In stream mode
 * they go to a ring of 2 x threads block buffers and are handed to the sink in row
 * order by the calling thread; a worker waits while the ring is full. */
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "est_private.h"

#define OUTPUT_BYTES_PER_BLOCK (4u << 20)
#define STREAMING_THRESHOLD ((size_t)64 << 20)
#define MAX_THREADS 256

typedef struct slot {
	void *in; /* the block's input when the job pulls it (fill) */
	void *data;
	float *conf;
	uint8_t *mask;
	int block; /* block whose output the slot holds, -1 when none */
} slot;

typedef struct run_state {
	est_plan plan;
	est_block_fn fn;
	const float *rgb;
	int width, height, block_rows, nblocks, bands;
	size_t elem;
	const kg_est_dest *dest; /* memory mode */
	slot *slots;             /* stream mode */
	int nslots;
	int (*fill)(void *user, int y0, int rows, void *in, kg_err *err);
	void *fill_user;
	size_t in_bytes;
	void (*compute)(void *user, void *in, size_t n, uint8_t *labels, float *conf,
	                uint8_t *mask, uint64_t *nonfinite, uint64_t *clipped);
	void *compute_user;
	int fill_rc; /* the first fill error, its message in fill_err */
	kg_err fill_err;
	pthread_mutex_t mu;
	pthread_cond_t cv_space, cv_done;
	int next, consumed, abort;
} run_state;

typedef struct worker {
	run_state *run;
	est_scratch scratch;
	est_counts counts;
	pthread_t thread;
} worker;

void kg_est_job_init(kg_est_job *job, const kg_est_kernel *k, kg_est_format format)
{
	memset(job, 0, sizeof(*job));
	job->kernel = k;
	job->format = format;
	job->clip_level = 0.999f;
	job->isa = KG_EST_ISA_AUTO;
	job->stores = KG_EST_STORES_AUTO;
}

static int is_bsq(kg_est_format f) { return f == KG_EST_F32_BSQ || f == KG_EST_F16_BSQ; }

static int block_rows_of(const run_state *r, int b)
{
	int y0 = b * r->block_rows;
	return r->height - y0 < r->block_rows ? r->height - y0 : r->block_rows;
}

/* Pull block b's input into its slot (the caller keeps the blocks in row order).
 * A failure is kept for the run and stops it. */
static int fill_block(run_state *r, int b)
{
	if (!r->fill || r->fill_rc)
		return r->fill_rc;
	int rc = r->fill(r->fill_user, b * r->block_rows, block_rows_of(r, b),
	                 r->slots[b % r->nslots].in, &r->fill_err);
	if (rc) {
		r->fill_rc = rc > 0 ? KG_EIO : rc;
		r->abort = 1;
	}
	return r->fill_rc;
}

static void compute_block(run_state *r, worker *w, int b)
{
	size_t y0 = (size_t)b * r->block_rows;
	size_t rows = (size_t)block_rows_of(r, b);
	size_t W = (size_t)r->width, n = rows * W, first = y0 * W;
	const float *in = r->fill ? (const float *)r->slots[b % r->nslots].in : r->rgb + 3 * first;
	est_dst d;
	if (r->slots) {
		slot *s = &r->slots[b % r->nslots];
		d = (est_dst){s->data, n, s->conf, s->mask};
	} else {
		size_t per_pixel = is_bsq(r->plan.format) ? 1 : (size_t)r->bands;
		d = (est_dst){(char *)r->dest->data + first * per_pixel * r->elem,
		              W * (size_t)r->height,
		              r->dest->confidence ? r->dest->confidence + first : NULL,
		              r->dest->mask ? r->dest->mask + first : NULL};
	}
	if (r->compute)
		r->compute(r->compute_user, r->slots[b % r->nslots].in, n, d.data, d.conf, d.mask,
		           &w->counts.nonfinite, &w->counts.clipped);
	else
		r->fn(&r->plan, &w->scratch, in, n, &d, &w->counts);
}

static void *worker_main(void *arg)
{
	worker *w = arg;
	run_state *r = w->run;
	for (;;) {
		pthread_mutex_lock(&r->mu);
		while (r->slots && !r->abort && r->next < r->nblocks &&
		       r->next - r->consumed >= r->nslots)
			pthread_cond_wait(&r->cv_space, &r->mu);
		if (r->abort || r->next >= r->nblocks) {
			pthread_mutex_unlock(&r->mu);
			break;
		}
		int b = r->next++;
		/* pulled under the lock: blocks are claimed, and so read, in row order */
		if (fill_block(r, b)) {
			pthread_cond_broadcast(&r->cv_done);
			pthread_cond_broadcast(&r->cv_space);
			pthread_mutex_unlock(&r->mu);
			break;
		}
		pthread_mutex_unlock(&r->mu);
		compute_block(r, w, b);
		if (r->slots) {
			pthread_mutex_lock(&r->mu);
			r->slots[b % r->nslots].block = b;
			pthread_cond_broadcast(&r->cv_done);
			pthread_mutex_unlock(&r->mu);
		}
	}
	return NULL;
}

static int default_threads(void)
{
	return kg_cpu_count(MAX_THREADS);
}

static int same_doubles(const double *a, const double *b, size_t n)
{
	if (!a || !b)
		return a == b;
	return memcmp(a, b, n * sizeof(double)) == 0;
}

/* Check the job and resolve it into r (everything but threads and buffers). */
static int prepare(const kg_est_job *job, const float *rgb, int width, int height, int stream,
                   run_state *r, int *threads, kg_err *err)
{
	kg_check_arg(job && (job->kernel || job->compute) && (rgb || (stream && job->fill)), err);
	kg_check_arg(!job->compute || (stream && job->fill && job->format == KG_EST_LABELS), err);
	kg_check_arg(!job->fill || stream, err);
	kg_check_arg(!job->fill || !job->in_bytes || job->in_bytes >= 3 * sizeof(float), err);
	const kg_est_kernel *k = job->kernel;
	if (width <= 0 || height <= 0 || (size_t)width > SIZE_MAX / 64 / (size_t)height / 3)
		return kg_fail(err, KG_EINVAL, "estimate: image %dx%d: expected a positive size",
		               width, height);
	if ((int)job->format < 0 || job->format >= KG_EST_NFORMATS)
		return kg_fail(err, KG_EINVAL, "estimate: output format %d: unknown", (int)job->format);
	if (job->compute)
		; /* the caller's function makes the labels */
	else if ((job->format == KG_EST_WEIGHTS || job->format == KG_EST_LABELS) && !k->k)
		return kg_fail(err, KG_EINVAL,
		               "estimate: %s output needs a kernel with a K-dimensional basis",
		               job->format == KG_EST_WEIGHTS ? "weights" : "label");
	if (job->format == KG_EST_LABELS && !job->compute) {
		const kg_est_classifier *c = job->classifier;
		if (!c)
			return kg_fail(err, KG_EINVAL, "estimate: label output: no classifier given");
		if (c->k != k->k || !same_doubles(c->basis, k->basis, (size_t)KG_NBANDS * k->k) ||
		    !same_doubles(c->mean, k->mean, KG_NBANDS))
			return kg_fail(err, KG_EINVAL,
			               "estimate: classifier: its basis differs from the kernel's");
	}
	if (isnan(job->clip_level))
		return kg_fail(err, KG_EINVAL, "estimate: clip level: expected a number, not NaN");
	if (job->threads < 0 || job->block_rows < 0)
		return kg_fail(err, KG_EINVAL, "estimate: threads %d, block rows %d: expected >= 0",
		               job->threads, job->block_rows);

	est_dsp dsp;
	int isa_rc = est_dsp_init(&dsp, job->isa);
	if (isa_rc == KG_EINVAL)
		return kg_fail(err, KG_EINVAL, "estimate: implementation %d: unknown", (int)job->isa);
	if (isa_rc < 0)
		return kg_fail(err, KG_ENOTSUP, "estimate: this CPU lacks the requested %s",
		               job->isa == KG_EST_ISA_AVX512 ? "AVX-512F (with AVX2, FMA and F16C)"
		                                             : "AVX2, FMA and F16C");
	memset(r, 0, sizeof(*r));
	r->plan.k = k;
	r->plan.format = job->format;
	r->plan.map = !k ? NULL
	              : (job->format == KG_EST_WEIGHTS || job->format == KG_EST_LABELS) ? &k->wts
	                                                                                : &k->spec;
	r->plan.cls = job->format == KG_EST_LABELS ? job->classifier : NULL;
	r->plan.clip = job->clip_level;
	r->fn = k ? dsp.block[est_kind(k)][job->format] : NULL;
	r->compute = job->compute;
	r->compute_user = job->compute_user;
	r->rgb = rgb;
	r->fill = job->fill;
	r->fill_user = job->fill_user;
	r->in_bytes = job->fill ? (job->in_bytes ? job->in_bytes : 3 * sizeof(float)) : 0;
	r->width = width;
	r->height = height;
	r->bands = job->compute ? 1 : kg_est_format_bands(k, job->format);
	r->elem = kg_est_format_elem_size(job->format);

	int nt = job->threads ? (job->threads > MAX_THREADS ? MAX_THREADS : job->threads)
	                      : default_threads();
	/* a block's buffers: output, plus mask and confidence in stream mode */
	size_t px_bytes = (size_t)r->bands * r->elem + r->in_bytes +
	                  (stream ? 1 + (job->format == KG_EST_LABELS ? sizeof(float) : 0) : 0);
	size_t row_bytes = (size_t)width * px_bytes;
	size_t rows = job->block_rows ? (size_t)job->block_rows
	                              : (OUTPUT_BYTES_PER_BLOCK + row_bytes - 1) / row_bytes;
	if (!job->block_rows && !stream) {
		/* a few blocks per thread, for balance */
		size_t balance = ((size_t)height + 4 * (size_t)nt - 1) / (4 * (size_t)nt);
		if (rows > balance)
			rows = balance;
	}
	if (rows < 1)
		rows = 1;
	if (rows > (size_t)height)
		rows = (size_t)height;
	r->block_rows = (int)rows;
	r->nblocks = (int)(((size_t)height + rows - 1) / rows);
	if (nt > r->nblocks)
		nt = r->nblocks;
	*threads = nt;

	size_t total = (size_t)width * height * r->bands * r->elem;
	r->plan.stream = job->stores == KG_EST_STORES_STREAMING ||
	                 (job->stores == KG_EST_STORES_AUTO && !stream && total > STREAMING_THRESHOLD);
	return 0;
}

static void sum_counts(const worker *w, int n, const run_state *r, kg_est_stats *stats)
{
	if (!stats)
		return;
	memset(stats, 0, sizeof(*stats));
	stats->pixels = (uint64_t)r->width * (uint64_t)r->height;
	for (int i = 0; i < n; i++) {
		stats->nonfinite += w[i].counts.nonfinite;
		stats->clipped += w[i].counts.clipped;
		stats->clamped_pixels += w[i].counts.clamped_pixels;
		stats->clamped_values += w[i].counts.clamped_values;
	}
}

static worker *workers_new(run_state *r, int n)
{
	worker *w = calloc((size_t)n, sizeof(*w));
	if (!w)
		return NULL;
	for (int i = 0; i < n; i++) {
		w[i].run = r;
		if (est_scratch_init(&w[i].scratch) < 0) {
			for (int j = 0; j < i; j++)
				est_scratch_fini(&w[j].scratch);
			free(w);
			return NULL;
		}
	}
	return w;
}

static void workers_free(worker *w, int n)
{
	for (int i = 0; i < n; i++)
		est_scratch_fini(&w[i].scratch);
	free(w);
}

int kg_est_run(const kg_est_job *job, const float *rgb, int width, int height,
               const kg_est_dest *dest, kg_est_stats *stats, kg_err *err)
{
	run_state r;
	int nt, rc = prepare(job, rgb, width, height, 0, &r, &nt, err);
	if (rc < 0)
		return rc;
	kg_check_arg(dest && dest->data, err);
	r.dest = dest;
	worker *w = workers_new(&r, nt);
	if (!w)
		return kg_fail(err, KG_ENOMEM, "estimate: out of memory for %d threads", nt);
	pthread_mutex_init(&r.mu, NULL);
	/* the calling thread is worker 0; a thread that cannot start leaves its share to
	 * the others */
	int started = 1;
	for (int i = 1; i < nt; i++)
		if (pthread_create(&w[i].thread, NULL, worker_main, &w[i]) == 0)
			started = i + 1;
		else
			break;
	worker_main(&w[0]);
	for (int i = 1; i < started; i++)
		pthread_join(w[i].thread, NULL);
	pthread_mutex_destroy(&r.mu);
	sum_counts(w, nt, &r, stats);
	workers_free(w, nt);
	return 0;
}

static void slots_free(slot *s, int n)
{
	if (!s)
		return;
	for (int i = 0; i < n; i++) {
		free(s[i].in);
		free(s[i].data);
		free(s[i].conf);
		free(s[i].mask);
	}
	free(s);
}

static slot *slots_new(const run_state *r, int n)
{
	slot *s = calloc((size_t)n, sizeof(*s));
	if (!s)
		return NULL;
	size_t px = (size_t)r->block_rows * r->width;
	size_t bytes = px * r->bands * r->elem;
	for (int i = 0; i < n; i++) {
		s[i].block = -1;
		s[i].data = est_alloc_zeroed(bytes);
		s[i].mask = malloc(px);
		if (r->plan.format == KG_EST_LABELS)
			s[i].conf = malloc(px * sizeof(float));
		if (r->fill)
			s[i].in = malloc(px * r->in_bytes);
		if (!s[i].data || !s[i].mask || (r->plan.format == KG_EST_LABELS && !s[i].conf) ||
		    (r->fill && !s[i].in)) {
			slots_free(s, n);
			return NULL;
		}
	}
	return s;
}

int kg_est_run_stream(const kg_est_job *job, const float *rgb, int width, int height,
                      kg_est_sink_fn sink, void *user, kg_est_stats *stats, kg_err *err)
{
	run_state r;
	int nt, rc = prepare(job, rgb, width, height, 1, &r, &nt, err);
	if (rc < 0)
		return rc;
	kg_check_arg(sink, err);
	/* worker 0 belongs to the calling thread and computes only when no thread starts */
	worker *w = workers_new(&r, nt + 1);
	r.nslots = 2 * nt;
	r.slots = slots_new(&r, r.nslots);
	if (!w || !r.slots) {
		if (w)
			workers_free(w, nt + 1);
		slots_free(r.slots, r.nslots);
		return kg_fail(err, KG_ENOMEM, "estimate: out of memory for %d blocks of %d rows",
		               r.nslots, r.block_rows);
	}
	pthread_mutex_init(&r.mu, NULL);
	pthread_cond_init(&r.cv_space, NULL);
	pthread_cond_init(&r.cv_done, NULL);
	int started = 0;
	for (int i = 1; i <= nt; i++)
		if (pthread_create(&w[i].thread, NULL, worker_main, &w[i]) == 0)
			started = i;
		else
			break;
	if (!started) {
		r.nslots = 1;
		r.next = r.nblocks; /* nothing left for workers; the loop below computes */
	}
	rc = 0;
	for (int b = 0; b < r.nblocks && rc == 0; b++) {
		slot *s = &r.slots[b % r.nslots];
		int fill_rc;
		if (!started) {
			if (!(fill_rc = fill_block(&r, b)))
				compute_block(&r, &w[0], b);
		} else {
			pthread_mutex_lock(&r.mu);
			while (s->block != b && !r.fill_rc)
				pthread_cond_wait(&r.cv_done, &r.mu);
			fill_rc = s->block == b ? 0 : r.fill_rc;
			pthread_mutex_unlock(&r.mu);
		}
		if (fill_rc) {
			rc = fill_rc;
			if (err)
				*err = r.fill_err;
			break;
		}
		kg_est_block blk = {b * r.block_rows, block_rows_of(&r, b), width, r.bands,
		                    job->format, s->data, s->conf, s->mask, s->in};
		rc = sink(user, &blk, err);
		pthread_mutex_lock(&r.mu);
		r.consumed = b + 1;
		if (rc)
			r.abort = 1;
		pthread_cond_broadcast(&r.cv_space);
		pthread_mutex_unlock(&r.mu);
	}
	for (int i = 1; i <= started; i++)
		pthread_join(w[i].thread, NULL);
	pthread_cond_destroy(&r.cv_done);
	pthread_cond_destroy(&r.cv_space);
	pthread_mutex_destroy(&r.mu);
	sum_counts(w, nt + 1, &r, stats);
	workers_free(w, nt + 1);
	slots_free(r.slots, 2 * nt);
	if (rc > 0)
		rc = KG_EIO;
	return rc;
}
