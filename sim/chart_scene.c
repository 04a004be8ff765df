/* Chart scenes: printed cards with tags and patches under a pinhole camera, rendered
 * by inverse-mapping pixels through each card's homography (kg_sim.h, "Chart
 * scenes"). */
#include <inttypes.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "kg_sim.h"

#define MAX_THREADS 64
#define GRID 64 /* cells per side of a card's lookup grid */

static const double deg = 3.14159265358979323846 / 180.0;

/* ---- 3 x 3 homographies -------------------------------------------------------- */

static void mat3_mul(const double a[9], const double b[9], double out[9])
{
	double r[9];
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++)
			r[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
	memcpy(out, r, sizeof(r));
}

/* 0, or -1 when singular. */
static int mat3_inv(const double m[9], double out[9])
{
	double c00 = m[4] * m[8] - m[5] * m[7];
	double c01 = m[5] * m[6] - m[3] * m[8];
	double c02 = m[3] * m[7] - m[4] * m[6];
	double det = m[0] * c00 + m[1] * c01 + m[2] * c02;
	if (!(fabs(det) > 1e-300) || !isfinite(det))
		return -1;
	double r[9] = {
	    c00, m[2] * m[7] - m[1] * m[8], m[1] * m[5] - m[2] * m[4],
	    c01, m[0] * m[8] - m[2] * m[6], m[2] * m[3] - m[0] * m[5],
	    c02, m[1] * m[6] - m[0] * m[7], m[0] * m[4] - m[1] * m[3],
	};
	for (int i = 0; i < 9; i++)
		out[i] = r[i] / det;
	return 0;
}

void kg_sim_chart_project(const double H[9], const double in[2], double out[2])
{
	double w = H[6] * in[0] + H[7] * in[1] + H[8];
	out[0] = (H[0] * in[0] + H[1] * in[1] + H[2]) / w;
	out[1] = (H[3] * in[0] + H[4] * in[1] + H[5]) / w;
}

/* The projective map of the unit square onto a quad: (0,0) -> q[0], (1,0) -> q[1],
 * (1,1) -> q[2], (0,1) -> q[3] (Heckbert's square-to-quad). */
static int square_to_quad(const double q[4][2], double H[9])
{
	double x0 = q[0][0], y0 = q[0][1], x1 = q[1][0], y1 = q[1][1];
	double x2 = q[2][0], y2 = q[2][1], x3 = q[3][0], y3 = q[3][1];
	double sx = x0 - x1 + x2 - x3, sy = y0 - y1 + y2 - y3;
	double dx1 = x1 - x2, dx2 = x3 - x2, dy1 = y1 - y2, dy2 = y3 - y2;
	double den = dx1 * dy2 - dx2 * dy1;
	if (!(fabs(den) > 1e-12))
		return -1;
	double g = (sx * dy2 - dx2 * sy) / den;
	double h = (dx1 * sy - sx * dy1) / den;
	double m[9] = {
	    x1 - x0 + g * x1, x3 - x0 + h * x3, x0,
	    y1 - y0 + g * y1, y3 - y0 + h * y3, y0,
	    g, h, 1.0,
	};
	memcpy(H, m, sizeof(m));
	return 0;
}

double kg_sim_chart_focal_px(int width, double hfov_deg)
{
	return 0.5 * width / tan(0.5 * hfov_deg * deg);
}

/* Rotation of the card into camera coordinates: the in-plane rotation, then the
 * tilt about an axis in the card plane (Rodrigues). */
static void pose_rotation(const kg_sim_chart_pose *p, double R[9])
{
	double c = cos(p->rotate_deg * deg), s = sin(p->rotate_deg * deg);
	double Rz[9] = {c, -s, 0, s, c, 0, 0, 0, 1};
	double ax = cos(p->tilt_axis_deg * deg), ay = sin(p->tilt_axis_deg * deg);
	double ct = cos(p->tilt_deg * deg), st = sin(p->tilt_deg * deg), vt = 1.0 - ct;
	double Rt[9] = {
	    ct + vt * ax * ax, vt * ax * ay, st * ay,
	    vt * ax * ay, ct + vt * ay * ay, -st * ax,
	    -st * ay, st * ax, ct,
	};
	mat3_mul(Rt, Rz, R);
}

void kg_sim_chart_homography(const kg_sim_chart_pose *pose, const double size_mm[2],
                             double focal_px, int width, int height, double H[9])
{
	double R[9];
	pose_rotation(pose, R);
	double K[9] = {focal_px, 0, 0.5 * width, 0, focal_px, 0.5 * height, 0, 0, 1};
	double P[9] = {
	    R[0], R[1], pose->offset_mm[0],
	    R[3], R[4], pose->offset_mm[1],
	    R[6], R[7], pose->distance_mm,
	};
	double S[9] = {1, 0, -0.5 * size_mm[0], 0, 1, -0.5 * size_mm[1], 0, 0, 1};
	mat3_mul(K, P, H);
	mat3_mul(H, S, H);
	double n = H[8];
	for (int i = 0; i < 9; i++)
		H[i] /= n;
}

/* Depth (camera z) of a card point: positive in front of the camera. */
static double card_depth(const kg_sim_chart_pose *pose, const double size_mm[2], double x,
                         double y)
{
	double R[9];
	pose_rotation(pose, R);
	return R[6] * (x - 0.5 * size_mm[0]) + R[7] * (y - 0.5 * size_mm[1]) + pose->distance_mm;
}

int kg_sim_chart_pose_fit(kg_sim_chart_pose *pose, const double size_mm[2],
                          double focal_px, int width, int height, const double box[4],
                          double fill, kg_err *err)
{
	kg_check_arg(pose && size_mm && box && focal_px > 0 && width > 0 && height > 0, err);
	kg_check_arg(size_mm[0] > 0 && size_mm[1] > 0 && fill > 0 && fill <= 1, err);
	kg_check_arg(box[2] > box[0] && box[3] > box[1], err);
	if (!(fabs(pose->tilt_deg) < 80.0))
		return kg_fail(err, KG_EINVAL, "tilt %g degrees: expected less than 80",
		               pose->tilt_deg);
	double diag = hypot(size_mm[0], size_mm[1]);
	pose->distance_mm = focal_px * diag / fmin(box[2] - box[0], box[3] - box[1]);
	pose->offset_mm[0] = pose->offset_mm[1] = 0.0;
	double bx = 0.5 * (box[0] + box[2]), by = 0.5 * (box[1] + box[3]);
	for (int it = 0; it < 60; it++) {
		double corners[4][2] = {
		    {0, 0}, {size_mm[0], 0}, {size_mm[0], size_mm[1]}, {0, size_mm[1]}};
		double H[9];
		kg_sim_chart_homography(pose, size_mm, focal_px, width, height, H);
		double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
		for (int k = 0; k < 4; k++) {
			if (card_depth(pose, size_mm, corners[k][0], corners[k][1]) <= 0.0)
				return kg_fail(err, KG_EINVAL,
				               "card pose: the card reaches behind the camera");
			double px[2];
			kg_sim_chart_project(H, corners[k], px);
			for (int a = 0; a < 2; a++) {
				lo[a] = fmin(lo[a], px[a]);
				hi[a] = fmax(hi[a], px[a]);
			}
		}
		double scale = fmax((hi[0] - lo[0]) / (fill * (box[2] - box[0])),
		                    (hi[1] - lo[1]) / (fill * (box[3] - box[1])));
		double shift_x = bx - 0.5 * (lo[0] + hi[0]), shift_y = by - 0.5 * (lo[1] + hi[1]);
		pose->offset_mm[0] += shift_x * pose->distance_mm / focal_px;
		pose->offset_mm[1] += shift_y * pose->distance_mm / focal_px;
		pose->distance_mm *= scale;
		pose->offset_mm[0] *= scale;
		pose->offset_mm[1] *= scale;
		if (fabs(scale - 1.0) < 1e-9 && fabs(shift_x) < 1e-6 && fabs(shift_y) < 1e-6)
			break;
	}
	return 0;
}

/* ---- the scene prepared for lookup ------------------------------------------------ */

enum item_kind { ITEM_OCCLUDER, ITEM_TAG, ITEM_PATCH };

typedef struct item {
	enum item_kind kind;
	double x0, y0, x1, y1; /* bounding box in card mm */
	double rgb[3];         /* patch or occluder colour */
	double to_grid[9];     /* tags: card mm -> grid cells */
	int cells;
	const unsigned char *bits;
} item;

typedef struct card_rt {
	double to_card[9];     /* pixel -> card mm */
	double w, h;
	double paper[3], ink[3];
	int nitems;            /* occluders, then tags, then patches: the first hit wins */
	item *items;
	int *cell_start;       /* GRID*GRID + 1 */
	int *cell_items;
	const kg_sim_chart_glare *glare;
	int nglare;
} card_rt;

typedef struct scene_rt {
	const kg_sim_chart_desc *d;
	int ncards;
	card_rt *cards;
	double background[3];
	double vig_a, vig_r2; /* v = (1 + a r^2 / r2)^-2 */
	int has_glare;
	float *rgb;           /* width * height * 3 */
	float *tmp;           /* blur intermediate */
	double *kernel;       /* blur taps, 2 * radius + 1 */
	int radius;
	kg_image *out;
	int cfa_channel[4];   /* mosaic: channel at (y & 1) * 2 + (x & 1) */
	const kg_sim_noise *noise;
} scene_rt;

/* A uniform region of the scene and its colour. Keys: 0 background; card c paper
 * (c + 1) << 40; item k adds (k + 1) << 20; a tag cell adds its index + 1. */
typedef struct region {
	uint64_t key;
	const double *rgb;
	int card;  /* -1 outside every card */
	int item;  /* -1 for paper */
	double mm[2];
} region;

static void lookup(const scene_rt *s, double u, double v, region *r)
{
	for (int c = s->ncards - 1; c >= 0; c--) {
		const card_rt *cd = &s->cards[c];
		const double *M = cd->to_card;
		double w = M[6] * u + M[7] * v + M[8];
		if (!(w > 0.0))
			continue;
		double x = (M[0] * u + M[1] * v + M[2]) / w;
		double y = (M[3] * u + M[4] * v + M[5]) / w;
		if (!(x >= 0.0 && x < cd->w && y >= 0.0 && y < cd->h))
			continue;
		r->card = c;
		r->mm[0] = x;
		r->mm[1] = y;
		uint64_t base = (uint64_t)(c + 1) << 40;
		int gx = (int)(x / cd->w * GRID), gy = (int)(y / cd->h * GRID);
		int cell = gy * GRID + gx;
		for (int j = cd->cell_start[cell]; j < cd->cell_start[cell + 1]; j++) {
			int k = cd->cell_items[j];
			const item *it = &cd->items[k];
			if (!(x >= it->x0 && x < it->x1 && y >= it->y0 && y < it->y1))
				continue;
			uint64_t key = base | ((uint64_t)(k + 1) << 20);
			if (it->kind != ITEM_TAG) {
				r->key = key;
				r->rgb = it->rgb;
				r->item = k;
				return;
			}
			const double *T = it->to_grid;
			double tw = T[6] * x + T[7] * y + T[8];
			double gxf = (T[0] * x + T[1] * y + T[2]) / tw;
			double gyf = (T[3] * x + T[4] * y + T[5]) / tw;
			if (!(gxf >= 0.0 && gxf < it->cells && gyf >= 0.0 && gyf < it->cells))
				continue;
			int bx = (int)gxf, by = (int)gyf;
			int bit = by * it->cells + bx;
			r->key = key | (uint64_t)(bit + 1);
			r->rgb = it->bits[bit] ? cd->paper : cd->ink;
			r->item = k;
			return;
		}
		r->key = base;
		r->rgb = cd->paper;
		r->item = -1;
		return;
	}
	r->key = 0;
	r->rgb = s->background;
	r->card = -1;
	r->item = -1;
}

static double glare_at(const card_rt *cd, const double mm[2])
{
	double sum = 0.0;
	for (int g = 0; g < cd->nglare; g++) {
		const kg_sim_chart_glare *gl = &cd->glare[g];
		double dx = mm[0] - gl->centre_mm[0], dy = mm[1] - gl->centre_mm[1];
		double c = cos(gl->angle_deg * deg), s = sin(gl->angle_deg * deg);
		double u = (c * dx + s * dy) / gl->radius_mm[0];
		double v = (-s * dx + c * dy) / gl->radius_mm[1];
		double q = u * u + v * v;
		if (q < 9.0)
			sum += gl->amplitude * exp(-0.5 * q);
	}
	return sum;
}

static double vignetting_at(const scene_rt *s, double u, double v)
{
	if (s->vig_a == 0.0)
		return 1.0;
	double du = u - 0.5 * s->d->width, dv = v - 0.5 * s->d->height;
	double t = 1.0 + s->vig_a * (du * du + dv * dv) / s->vig_r2;
	return 1.0 / (t * t);
}

/* ---- threads over image rows ---------------------------------------------------- */

typedef void (*rows_fn)(scene_rt *s, int y0, int y1);

typedef struct band {
	scene_rt *s;
	rows_fn fn;
	int y0, y1;
} band;

static void *band_main(void *arg)
{
	band *b = arg;
	b->fn(b->s, b->y0, b->y1);
	return NULL;
}

static int run_rows(scene_rt *s, int threads, rows_fn fn)
{
	int h = s->d->height;
	if (threads > h)
		threads = h > 0 ? h : 1;
	band bands[MAX_THREADS];
	pthread_t tid[MAX_THREADS];
	int started = 0, ret = 0;
	for (int t = 0; t < threads; t++) {
		bands[t] = (band){s, fn, (int)((long)h * t / threads), (int)((long)h * (t + 1) / threads)};
	}
	for (int t = 1; t < threads; t++) {
		if (pthread_create(&tid[t], NULL, band_main, &bands[t]) != 0) {
			ret = -1;
			break;
		}
		started = t;
	}
	if (ret) {
		/* Run what could not be started here, in order. */
		for (int t = started + 1; t < threads; t++)
			fn(s, bands[t].y0, bands[t].y1);
		ret = 0;
	}
	fn(s, bands[0].y0, bands[0].y1);
	for (int t = 1; t <= started; t++)
		pthread_join(tid[t], NULL);
	return ret;
}

/* ---- the passes ---------------------------------------------------------------- */

/* Corners of row y of pixels (y integer), width + 1 of them. */
static void corner_row(const scene_rt *s, int y, region *row)
{
	for (int x = 0; x <= s->d->width; x++)
		lookup(s, x, y, &row[x]);
}

static void render_rows(scene_rt *s, int y0, int y1)
{
	int w = s->d->width, ss = s->d->supersample;
	region *a = malloc(sizeof(region) * (size_t)(w + 1));
	region *b = malloc(sizeof(region) * (size_t)(w + 1));
	if (!a || !b) {
		/* Without row buffers, sample every pixel fully (slower, same result). */
		free(a);
		free(b);
		a = b = NULL;
	}
	if (a)
		corner_row(s, y0, a);
	for (int y = y0; y < y1; y++) {
		if (b)
			corner_row(s, y + 1, b);
		for (int x = 0; x < w; x++) {
			double rgb[3];
			if (a && a[x].key == a[x + 1].key && a[x].key == b[x].key &&
			    a[x].key == b[x + 1].key) {
				for (int c = 0; c < 3; c++)
					rgb[c] = a[x].rgb[c];
			} else {
				rgb[0] = rgb[1] = rgb[2] = 0.0;
				for (int j = 0; j < ss; j++)
					for (int i = 0; i < ss; i++) {
						region r;
						lookup(s, x + (i + 0.5) / ss, y + (j + 0.5) / ss, &r);
						for (int c = 0; c < 3; c++)
							rgb[c] += r.rgb[c];
					}
				for (int c = 0; c < 3; c++)
					rgb[c] /= (double)ss * ss;
			}
			double u = x + 0.5, v = y + 0.5;
			if (s->has_glare) {
				region r;
				lookup(s, u, v, &r);
				if (r.card >= 0 && !(r.item >= 0 && s->cards[r.card].items[r.item].kind ==
				                                        ITEM_OCCLUDER)) {
					double g = glare_at(&s->cards[r.card], r.mm);
					for (int c = 0; c < 3; c++)
						rgb[c] += g;
				}
			}
			double vig = vignetting_at(s, u, v);
			float *p = s->rgb + ((size_t)y * w + x) * 3;
			for (int c = 0; c < 3; c++)
				p[c] = (float)(rgb[c] * vig);
		}
		region *t = a;
		a = b;
		b = t;
	}
	free(a);
	free(b);
}

static void blur_h_rows(scene_rt *s, int y0, int y1)
{
	int w = s->d->width, r = s->radius;
	for (int y = y0; y < y1; y++) {
		const float *src = s->rgb + (size_t)y * w * 3;
		float *dst = s->tmp + (size_t)y * w * 3;
		for (int x = 0; x < w; x++) {
			double acc[3] = {0, 0, 0};
			for (int k = -r; k <= r; k++) {
				int xx = x + k < 0 ? 0 : (x + k >= w ? w - 1 : x + k);
				double kv = s->kernel[k + r];
				for (int c = 0; c < 3; c++)
					acc[c] += kv * src[xx * 3 + c];
			}
			for (int c = 0; c < 3; c++)
				dst[x * 3 + c] = (float)acc[c];
		}
	}
}

static void blur_v_rows(scene_rt *s, int y0, int y1)
{
	int w = s->d->width, h = s->d->height, r = s->radius;
	size_t n = (size_t)w * 3;
	double *acc = malloc(sizeof(double) * n);
	for (int y = y0; y < y1; y++) {
		float *dst = s->rgb + (size_t)y * n;
		if (!acc) {
			/* No scratch row: accumulate in float directly. */
			for (size_t i = 0; i < n; i++) {
				float sum = 0.0f;
				for (int k = -r; k <= r; k++) {
					int yy = y + k < 0 ? 0 : (y + k >= h ? h - 1 : y + k);
					sum += (float)s->kernel[k + r] * s->tmp[(size_t)yy * n + i];
				}
				dst[i] = sum;
			}
			continue;
		}
		memset(acc, 0, sizeof(double) * n);
		for (int k = -r; k <= r; k++) {
			int yy = y + k < 0 ? 0 : (y + k >= h ? h - 1 : y + k);
			const float *src = s->tmp + (size_t)yy * n;
			double kv = s->kernel[k + r];
			for (size_t i = 0; i < n; i++)
				acc[i] += kv * src[i];
		}
		for (size_t i = 0; i < n; i++)
			dst[i] = (float)acc[i];
	}
	free(acc);
}

static void row_rng(kg_rng *rng, uint64_t seed, int y)
{
	kg_rng_seed(rng, seed ^ (0x9E3779B97F4A7C15ull * (uint64_t)(y + 1)));
}

/* Mosaic (when asked) and noise into the output image. */
static void output_rows(scene_rt *s, int y0, int y1)
{
	int w = s->d->width, ch = s->out->channels;
	int noisy = kg_sim_noise_enabled(s->noise);
	for (int y = y0; y < y1; y++) {
		kg_rng rng;
		row_rng(&rng, s->d->seed, y);
		const float *src = s->rgb + (size_t)y * w * 3;
		float *dst = s->out->data + (size_t)y * w * ch;
		for (int x = 0; x < w; x++) {
			if (ch == 1) {
				double v = src[x * 3 + s->cfa_channel[(y & 1) * 2 + (x & 1)]];
				dst[x] = (float)(noisy ? kg_sim_noise_apply(s->noise, v, &rng) : v);
			} else {
				for (int c = 0; c < 3; c++) {
					double v = src[x * 3 + c];
					dst[x * 3 + c] =
					    (float)(noisy ? kg_sim_noise_apply(s->noise, v, &rng) : v);
				}
			}
		}
	}
}

/* ---- building -------------------------------------------------------------------- */

static void flat_rgb(const kg_sim_capture *c, double reflectance, double rgb[3])
{
	kg_spectrum s = kg_spectrum_const(reflectance);
	kg_sim_capture_mean(c, &s, rgb);
}

static void card_free(card_rt *cd)
{
	free(cd->items);
	free(cd->cell_start);
	free(cd->cell_items);
}

static int check_card(const kg_sim_chart_card *cd, int index, kg_err *err)
{
	if (!(cd->size_mm[0] > 0 && cd->size_mm[1] > 0 && isfinite(cd->size_mm[0]) &&
	      isfinite(cd->size_mm[1])))
		return kg_fail(err, KG_EINVAL, "chart card %d: size %g x %g mm: expected positive",
		               index, cd->size_mm[0], cd->size_mm[1]);
	if ((cd->ntags < 0 || cd->npatches < 0 || cd->noccluders < 0 || cd->nglare < 0) ||
	    (cd->ntags && !cd->tags) || (cd->npatches && !cd->patches) ||
	    (cd->noccluders && !cd->occluders) || (cd->nglare && !cd->glare))
		return kg_fail(err, KG_EINVAL, "chart card %d: item counts and arrays disagree",
		               index);
	for (int t = 0; t < cd->ntags; t++)
		if (cd->tags[t].cells < 1 || cd->tags[t].cells > 64 || !cd->tags[t].bits)
			return kg_fail(err, KG_EINVAL,
			               "chart card %d: tag %d: expected 1 to 64 cells and a bit grid",
			               index, t);
	for (int p = 0; p < cd->npatches; p++)
		if (!(cd->patches[p].size_mm[0] > 0 && cd->patches[p].size_mm[1] > 0))
			return kg_fail(err, KG_EINVAL, "chart card %d: patch %d: size must be positive",
			               index, p);
	for (int g = 0; g < cd->nglare; g++)
		if (!(cd->glare[g].radius_mm[0] > 0 && cd->glare[g].radius_mm[1] > 0))
			return kg_fail(err, KG_EINVAL, "chart card %d: glare %d: radii must be positive",
			               index, g);
	if (!(cd->pose.distance_mm > 0))
		return kg_fail(err, KG_EINVAL,
		               "chart card %d: distance %g mm: expected positive (see "
		               "kg_sim_chart_pose_fit)",
		               index, cd->pose.distance_mm);
	return 0;
}

static int card_build(const kg_sim_chart_card *src, const double H[9],
                      const kg_sim_capture *cap, card_rt *cd, kg_err *err)
{
	memset(cd, 0, sizeof(*cd));
	if (mat3_inv(H, cd->to_card))
		return kg_fail(err, KG_EINVAL, "chart card: the pose gives a singular homography");
	cd->w = src->size_mm[0];
	cd->h = src->size_mm[1];
	flat_rgb(cap, src->paper, cd->paper);
	flat_rgb(cap, src->ink, cd->ink);
	cd->glare = src->glare;
	cd->nglare = src->nglare;
	cd->nitems = src->noccluders + src->ntags + src->npatches;
	cd->items = calloc((size_t)(cd->nitems ? cd->nitems : 1), sizeof(item));
	cd->cell_start = calloc(GRID * GRID + 1, sizeof(int));
	if (!cd->items || !cd->cell_start)
		return kg_fail(err, KG_ENOMEM, "chart scene: out of memory");
	int k = 0;
	for (int i = 0; i < src->noccluders; i++, k++) {
		const kg_sim_chart_occluder *o = &src->occluders[i];
		item *it = &cd->items[k];
		it->kind = ITEM_OCCLUDER;
		it->x0 = fmin(o->x0_mm, o->x1_mm);
		it->x1 = fmax(o->x0_mm, o->x1_mm);
		it->y0 = fmin(o->y0_mm, o->y1_mm);
		it->y1 = fmax(o->y0_mm, o->y1_mm);
		flat_rgb(cap, o->reflectance, it->rgb);
	}
	for (int i = 0; i < src->ntags; i++, k++) {
		const kg_sim_chart_tag *t = &src->tags[i];
		item *it = &cd->items[k];
		it->kind = ITEM_TAG;
		it->x0 = it->y0 = INFINITY;
		it->x1 = it->y1 = -INFINITY;
		for (int c = 0; c < 4; c++) {
			it->x0 = fmin(it->x0, t->corner_mm[c][0]);
			it->x1 = fmax(it->x1, t->corner_mm[c][0]);
			it->y0 = fmin(it->y0, t->corner_mm[c][1]);
			it->y1 = fmax(it->y1, t->corner_mm[c][1]);
		}
		double sq[9], inv[9];
		if (square_to_quad(t->corner_mm, sq) || mat3_inv(sq, inv))
			return kg_fail(err, KG_EINVAL, "chart card: tag %d: degenerate corners", i);
		double scale[9] = {t->cells, 0, 0, 0, t->cells, 0, 0, 0, 1};
		mat3_mul(scale, inv, it->to_grid);
		it->cells = t->cells;
		it->bits = t->bits;
	}
	for (int i = 0; i < src->npatches; i++, k++) {
		const kg_sim_chart_patch *p = &src->patches[i];
		item *it = &cd->items[k];
		it->kind = ITEM_PATCH;
		it->x0 = p->centre_mm[0] - 0.5 * p->size_mm[0];
		it->x1 = p->centre_mm[0] + 0.5 * p->size_mm[0];
		it->y0 = p->centre_mm[1] - 0.5 * p->size_mm[1];
		it->y1 = p->centre_mm[1] + 0.5 * p->size_mm[1];
		if (p->reflectance)
			kg_sim_capture_mean(cap, p->reflectance, it->rgb);
		else
			memcpy(it->rgb, p->rgb, sizeof(it->rgb));
	}
	/* Bin the items over the grid (counting sort keeps each cell's items in
	 * priority order). */
	for (int pass = 0; pass < 2; pass++) {
		int *fill = NULL;
		if (pass == 1) {
			for (int c = 0; c < GRID * GRID; c++)
				cd->cell_start[c + 1] += cd->cell_start[c];
			cd->cell_items = malloc(sizeof(int) * (size_t)(cd->cell_start[GRID * GRID] + 1));
			fill = malloc(sizeof(int) * GRID * GRID);
			if (!cd->cell_items || !fill) {
				free(fill);
				return kg_fail(err, KG_ENOMEM, "chart scene: out of memory");
			}
			memcpy(fill, cd->cell_start, sizeof(int) * GRID * GRID);
		}
		for (int i = 0; i < cd->nitems; i++) {
			const item *it = &cd->items[i];
			int gx0 = (int)floor(it->x0 / cd->w * GRID), gx1 = (int)floor(it->x1 / cd->w * GRID);
			int gy0 = (int)floor(it->y0 / cd->h * GRID), gy1 = (int)floor(it->y1 / cd->h * GRID);
			gx0 = gx0 < 0 ? 0 : gx0;
			gy0 = gy0 < 0 ? 0 : gy0;
			gx1 = gx1 >= GRID ? GRID - 1 : gx1;
			gy1 = gy1 >= GRID ? GRID - 1 : gy1;
			for (int gy = gy0; gy <= gy1; gy++)
				for (int gx = gx0; gx <= gx1; gx++) {
					if (pass == 0)
						cd->cell_start[gy * GRID + gx + 1]++;
					else
						cd->cell_items[fill[gy * GRID + gx]++] = i;
				}
		}
		free(fill);
	}
	return 0;
}

static int rects_overlap(double ax0, double ay0, double ax1, double ay1, double bx0,
                         double by0, double bx1, double by1)
{
	return ax0 < bx1 && bx0 < ax1 && ay0 < by1 && by0 < ay1;
}

void kg_sim_chart_result_free(kg_sim_chart_result **pr)
{
	if (!pr || !*pr)
		return;
	kg_sim_chart_result *r = *pr;
	kg_image_free(&r->image);
	free(r->homography);
	free(r->truth);
	free(r);
	*pr = NULL;
}

static int parse_cfa(const char *cfa, int ch[4], kg_err *err)
{
	static const char *const ok[] = {"RGGB", "BGGR", "GRBG", "GBRG"};
	for (size_t i = 0; i < sizeof(ok) / sizeof(ok[0]); i++)
		if (strcmp(cfa, ok[i]) == 0) {
			for (int k = 0; k < 4; k++)
				ch[k] = cfa[k] == 'R' ? 0 : (cfa[k] == 'G' ? 1 : 2);
			return 0;
		}
	return kg_fail(err, KG_EINVAL, "CFA pattern '%s': expected RGGB, BGGR, GRBG or GBRG",
	               cfa);
}

static int default_threads(void)
{
	return kg_cpu_count(MAX_THREADS);
}

int kg_sim_chart_render(const kg_sim_chart_desc *d, const kg_sim_capture *cap,
                        kg_sim_chart_result **out, kg_err *err)
{
	kg_check_arg(d && cap && out, err);
	*out = NULL;
	if (d->width < 1 || d->height < 1 ||
	    (long)d->width * d->height > KG_IMAGE_MAX_PIXELS / 3)
		return kg_fail(err, KG_EINVAL, "chart scene: image %d x %d: expected 1 to %ld pixels",
		               d->width, d->height, KG_IMAGE_MAX_PIXELS / 3);
	if (!(d->focal_px > 0 && isfinite(d->focal_px)))
		return kg_fail(err, KG_EINVAL, "chart scene: focal length %g px: expected positive",
		               d->focal_px);
	if (d->supersample < 1 || d->supersample > 16)
		return kg_fail(err, KG_EINVAL, "chart scene: supersample %d: expected 1 to 16",
		               d->supersample);
	if (!(d->blur_sigma >= 0 && d->blur_sigma <= 100))
		return kg_fail(err, KG_EINVAL, "chart scene: blur %g px: expected 0 to 100",
		               d->blur_sigma);
	if (!(d->vignetting >= 0 && d->vignetting < 1))
		return kg_fail(err, KG_EINVAL,
		               "chart scene: vignetting %g: expected 0 or more and below 1",
		               d->vignetting);
	if (d->ncards < 0 || (d->ncards && !d->cards) || d->threads < 0)
		return kg_fail(err, KG_EINVAL, "chart scene: invalid card list or thread count");
	for (int c = 0; c < d->ncards; c++) {
		int ret = check_card(&d->cards[c], c, err);
		if (ret)
			return ret;
	}

	struct timespec t0, t1;
	clock_gettime(CLOCK_MONOTONIC, &t0);
	int ret = 0;
	scene_rt s;
	memset(&s, 0, sizeof(s));
	s.d = d;
	s.noise = &cap->noise;
	flat_rgb(cap, d->background, s.background);
	if (d->vignetting > 0) {
		s.vig_a = 1.0 / sqrt(1.0 - d->vignetting) - 1.0;
		s.vig_r2 = 0.25 * ((double)d->width * d->width + (double)d->height * d->height);
	}
	kg_sim_chart_result *r = calloc(1, sizeof(*r));
	if (!r)
		return kg_fail(err, KG_ENOMEM, "chart scene: out of memory");
	r->ncards = d->ncards;
	size_t ntruth = 0, ncards = (size_t)d->ncards;
	for (int c = 0; c < d->ncards; c++)
		ntruth += (size_t)d->cards[c].npatches;
	r->homography = calloc(ncards + 1, sizeof(*r->homography));
	r->truth = calloc(ntruth + 1, sizeof(*r->truth));
	s.cards = calloc(ncards + 1, sizeof(card_rt));
	int channels = d->cfa ? 1 : 3;
	if (d->cfa && (ret = parse_cfa(d->cfa, s.cfa_channel, err)))
		goto done;
	if (!r->homography || !r->truth || !s.cards) {
		ret = kg_fail(err, KG_ENOMEM, "chart scene: out of memory");
		goto done;
	}
	for (int c = 0; c < d->ncards; c++) {
		const kg_sim_chart_card *cd = &d->cards[c];
		kg_sim_chart_homography(&cd->pose, cd->size_mm, d->focal_px, d->width, d->height,
		                        r->homography[c]);
		s.ncards = c + 1;
		if ((ret = card_build(cd, r->homography[c], cap, &s.cards[c], err)))
			goto done;
		if (cd->nglare)
			s.has_glare = 1;
	}
	s.rgb = malloc(sizeof(float) * 3 * (size_t)d->width * d->height);
	if (!s.rgb) {
		ret = kg_fail(err, KG_ENOMEM, "chart scene: out of memory for %d x %d pixels",
		              d->width, d->height);
		goto done;
	}
	if ((ret = kg_image_new(d->width, d->height, channels, &s.out, err)))
		goto done;
	if (d->cfa && (ret = kg_image_set_cfa(s.out, d->cfa, 2, 2, err)))
		goto done;
	int threads = d->threads ? d->threads : default_threads();
	if (threads > MAX_THREADS)
		threads = MAX_THREADS;

	run_rows(&s, threads, render_rows);
	if (d->blur_sigma > 0) {
		s.radius = (int)ceil(3.5 * d->blur_sigma);
		s.kernel = malloc(sizeof(double) * (size_t)(2 * s.radius + 1));
		s.tmp = malloc(sizeof(float) * 3 * (size_t)d->width * d->height);
		if (!s.kernel || !s.tmp) {
			ret = kg_fail(err, KG_ENOMEM, "chart scene: out of memory for the blur");
			goto done;
		}
		double sum = 0.0;
		for (int k = -s.radius; k <= s.radius; k++)
			sum += s.kernel[k + s.radius] = exp(-0.5 * k * k / (d->blur_sigma * d->blur_sigma));
		for (int k = 0; k <= 2 * s.radius; k++)
			s.kernel[k] /= sum;
		run_rows(&s, threads, blur_h_rows);
		run_rows(&s, threads, blur_v_rows);
	}
	run_rows(&s, threads, output_rows);

	/* The truth. */
	int t = 0;
	for (int c = 0; c < d->ncards; c++) {
		const kg_sim_chart_card *cd = &d->cards[c];
		for (int p = 0; p < cd->npatches; p++, t++) {
			const kg_sim_chart_patch *pa = &cd->patches[p];
			const item *it = &s.cards[c].items[cd->noccluders + cd->ntags + p];
			kg_sim_chart_truth *tr = &r->truth[t];
			tr->card = c;
			tr->patch = p;
			kg_sim_chart_project(r->homography[c], pa->centre_mm, tr->centre_px);
			tr->vignetting = vignetting_at(&s, tr->centre_px[0], tr->centre_px[1]);
			for (int ch = 0; ch < 3; ch++) {
				tr->flat_rgb[ch] = it->rgb[ch];
				tr->rgb[ch] = it->rgb[ch] * tr->vignetting;
			}
			tr->visible = card_depth(&cd->pose, cd->size_mm, pa->centre_mm[0],
			                         pa->centre_mm[1]) > 0 &&
			              tr->centre_px[0] >= 0 && tr->centre_px[0] < d->width &&
			              tr->centre_px[1] >= 0 && tr->centre_px[1] < d->height;
			for (int o = 0; o < cd->noccluders; o++) {
				const item *oc = &s.cards[c].items[o];
				if (rects_overlap(it->x0, it->y0, it->x1, it->y1, oc->x0, oc->y0, oc->x1, oc->y1))
					tr->occluded = 1;
			}
			for (int g = 0; g < cd->nglare; g++) {
				const kg_sim_chart_glare *gl = &cd->glare[g];
				double rr = 3.0 * fmax(gl->radius_mm[0], gl->radius_mm[1]);
				if (rects_overlap(it->x0, it->y0, it->x1, it->y1, gl->centre_mm[0] - rr,
				                  gl->centre_mm[1] - rr, gl->centre_mm[0] + rr,
				                  gl->centre_mm[1] + rr))
					tr->glare = 1;
			}
		}
	}
	r->ntruth = (int)ntruth;
	r->image = s.out;
	s.out = NULL;
	clock_gettime(CLOCK_MONOTONIC, &t1);
	r->seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);

done:
	for (int c = 0; c < s.ncards; c++)
		card_free(&s.cards[c]);
	free(s.cards);
	free(s.rgb);
	free(s.tmp);
	free(s.kernel);
	kg_image_free(&s.out);
	if (ret)
		kg_sim_chart_result_free(&r);
	*out = r;
	return ret;
}

int kg_sim_chart_write_truth(const kg_sim_chart_result *r, const kg_sim_chart_desc *d,
                             int card, const char *path, const char *const *keywords,
                             kg_err *err)
{
	kg_check_arg(r && d && path && card >= 0 && card < r->ncards && card < d->ncards, err);
	static const char *const fields[] = {
	    "SAMPLE_ID", "RGB_R", "RGB_G", "RGB_B", "FLAT_R", "FLAT_G", "FLAT_B",
	    "VIGNETTING", "PIXEL_X", "PIXEL_Y", "OCCLUDED", "GLARE",
	};
	kg_cgats *cg = NULL;
	int ret = kg_cgats_new("CGATS.17", &cg, err);
	if (ret)
		return ret;
	kg_cgats_table *t = cg->tables[0];
	char hbuf[512];
	const double *H = r->homography[card];
	snprintf(hbuf, sizeof(hbuf), "%.12g %.12g %.12g %.12g %.12g %.12g %.12g %.12g %.12g",
	         H[0], H[1], H[2], H[3], H[4], H[5], H[6], H[7], H[8]);
	ret = kg_cgats_set_keyword(t, "DESCRIPTOR",
	                           "simulated chart truth: noise-free patch means (linear, 0..1)",
	                           err);
	if (!ret)
		ret = kg_cgats_set_keyword(t, "HOMOGRAPHY", hbuf, err);
	for (int k = 0; !ret && keywords && keywords[k] && keywords[k + 1]; k += 2)
		ret = kg_cgats_set_keyword(t, keywords[k], keywords[k + 1], err);
	if (!ret)
		ret = kg_cgats_set_fields(t, fields, (int)(sizeof(fields) / sizeof(fields[0])), err);
	for (int i = 0; !ret && i < r->ntruth; i++) {
		const kg_sim_chart_truth *tr = &r->truth[i];
		if (tr->card != card)
			continue;
		const kg_sim_chart_patch *p = &d->cards[card].patches[tr->patch];
		char idbuf[32];
		const char *id = p->id;
		if (!id) {
			snprintf(idbuf, sizeof(idbuf), "%d", tr->patch + 1);
			id = idbuf;
		}
		double vals[11] = {
		    tr->rgb[0], tr->rgb[1], tr->rgb[2], tr->flat_rgb[0], tr->flat_rgb[1],
		    tr->flat_rgb[2], tr->vignetting, tr->centre_px[0], tr->centre_px[1],
		    tr->occluded, tr->glare,
		};
		ret = kg_cgats_add_row_numbers(t, id, vals, 11, err);
	}
	if (!ret)
		ret = kg_cgats_write(cg, path, err);
	kg_cgats_free(&cg);
	return ret;
}
