/* The renderer on Embree 3: one triangle geometry sharing the mesh's index buffer,
 * camera rays traced as 16-ray packets per 4 x 4 pixel block, and the block's 16
 * paths carried on together, depth by depth, with their shadow and bounce rays
 * traced as 16-ray packets too, with hero-wavelength spectral sampling (A. Wilkie,
 * S. Nawaz, M. Droske, A. Weidlich and J. Hanika, "Hero wavelength spectral
 * sampling", Computer Graphics Forum 33(4), 123-131, 2014), tiles handed to worker
 * threads from an atomic counter.
 *
 * Determinism: every sample of every pixel takes its jitter and its path's generator
 * from one hash of (seed, pixel, sample), a pixel is finished by one thread, and every
 * worker runs with the same floating-point modes, so the image does not depend on the
 * thread count or on which thread takes which tile. */
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>
#include <sys/mman.h>

#include <embree3/rtcore.h>
#if defined(__SSE2__)
#include <pmmintrin.h>
#include <xmmintrin.h>
#endif

#include "render_private.h"

#define TILE 16   /* pixels per tile side, a multiple of the 4 x 4 packet */
#define MAX_THREADS 256
#define MAX_CH 6  /* weighted channels: the observer's 3, then XYZ's when wanted */
#define LANES 16  /* rays per packet */

typedef struct rd_ctx {
	const kg_scene *s;
	RTCDevice dev;
	RTCScene scene;
	float *vbuf;            /* nverts x 4 (x, y, z, pad): Embree reads 16 bytes */
	rd_material *mat;
	int nmat;
	const uint16_t *tri_mat; /* NULL: material 0 everywhere */
	uint16_t *label_tri_mat; /* the label map projected onto the triangles */
	rd_frame frame;
	/* The camera in float, as the packets take it: a pixel position (x, y) plus
	 * jitter looks along fwd + ((x + jx) sx + ox) right + ((y + jy) sy + oy) up. */
	float cam_org[3], cam_fwd[3], cam_right[3], cam_up[3], cam_sx, cam_ox, cam_sy, cam_oy;
	int width, height, spp, nwl, bounces;
	uint64_t seed;
	uint64_t key_base;      /* the seed hashed once: the samples' keys start from it */
	kg_render_mode mode;
	double eps;             /* ray origin offset along the geometric normal */
	/* The observer: channel ch of a path is sum over bands of w[ch] L (the one place
	 * spectra become image values); channels 0-2 go to out[0], 3-5 to out[1]. */
	int nch;
	float w[MAX_CH][KG_NBANDS];
	double white_out[MAX_CH]; /* the white's reading (preview shading) */
	float *out[2];          /* width x height x 3 each; out[1] only when nch = 6 */
	/* Truth of the primary hits (want_truth): class per material, the maps, and per
	 * thread TILE x TILE x ncls sample counts and angle sums. */
	int truth, ncls;
	uint8_t *mat_class;     /* per renderer material: 1 + its library index */
	uint8_t *label;
	float *angle;
	uint32_t *tcount;
	double *tangle;
	int tiles_x, ntiles;
	atomic_int next_tile;
	pthread_mutex_t lock;   /* progress */
	int tiles_done;
	const kg_render_options *opt;
	/* rays by depth, summed from the workers' own counts under lock */
	uint64_t depth_rays[KG_RENDER_MAX_BOUNCES + 1], depth_shadow[KG_RENDER_MAX_BOUNCES];
	double depth_s[KG_RENDER_MAX_BOUNCES + 1];
	char embree_error[256];
} rd_ctx;

int kg_render_available(void)
{
	return 1;
}

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void embree_error(void *user, enum RTCError code, const char *str)
{
	rd_ctx *c = user;
	if (!c->embree_error[0])
		snprintf(c->embree_error, sizeof(c->embree_error), "Embree error %d: %s", (int)code,
		         str ? str : "");
}

/* Flush-to-zero and denormals-are-zero, in every thread that traces or shades
 * (Embree's advice, and the same arithmetic everywhere). */
static void set_fp_modes(void)
{
#if defined(__SSE2__)
	_MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
	_MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
#endif
}

/* A 64-bit mix (the finaliser of MurmurHash3) for the per-sample seeds. */
static uint64_t mix64(uint64_t x)
{
	x ^= x >> 33;
	x *= 0xff51afd7ed558ccdULL;
	x ^= x >> 33;
	x *= 0xc4ceb9fe1a85ec53ULL;
	x ^= x >> 33;
	return x;
}

static double dot3(const double a[3], const double b[3])
{
	return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* ---- Embree scene ---------------------------------------------------------------- */

static int build_scene(rd_ctx *c, int threads, kg_err *err)
{
	const kg_mesh *mesh = c->s->mesh;
	char cfg[64];
	snprintf(cfg, sizeof(cfg), "threads=%d", threads);
	c->dev = rtcNewDevice(cfg);
	if (!c->dev)
		return kg_fail(err, KG_EIO, "Embree: cannot create a device (error %d)",
		               (int)rtcGetDeviceError(NULL));
	rtcSetDeviceErrorFunction(c->dev, embree_error, c);
	c->vbuf = aligned_alloc(16, sizeof(float) * 4 * (mesh->nverts + 1));
	if (!c->vbuf)
		return kg_fail(err, KG_ENOMEM, "out of memory for %zu vertices", mesh->nverts);
	double extent = 0.0;
	for (size_t i = 0; i < mesh->nverts; i++) {
		for (int k = 0; k < 3; k++) {
			c->vbuf[4 * i + k] = mesh->pos[3 * i + k];
			if (isfinite(mesh->pos[3 * i + k]))
				extent = fmax(extent, fabs(mesh->pos[3 * i + k]));
		}
		c->vbuf[4 * i + 3] = 0.0f;
	}
	memset(c->vbuf + 4 * mesh->nverts, 0, 4 * sizeof(float));
	/* a few float ulps of the largest coordinate */
	c->eps = fmax(extent, 1e-3) * 2e-5;

	c->scene = rtcNewScene(c->dev);
	RTCGeometry g = rtcNewGeometry(c->dev, RTC_GEOMETRY_TYPE_TRIANGLE);
	if (c->scene && g) {
		rtcSetSceneBuildQuality(c->scene, RTC_BUILD_QUALITY_MEDIUM);
		rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, c->vbuf,
		                           0, 4 * sizeof(float), mesh->nverts);
		rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, mesh->tri,
		                           0, 3 * sizeof(uint32_t), mesh->ntris);
		rtcCommitGeometry(g);
		rtcAttachGeometry(c->scene, g);
	}
	if (g)
		rtcReleaseGeometry(g);
	if (c->scene)
		rtcCommitScene(c->scene);
	if (c->embree_error[0] || !c->scene || !g)
		return kg_fail(err, KG_EIO, "Embree: building the scene of %zu triangles: %s",
		               mesh->ntris, c->embree_error[0] ? c->embree_error : "failed");
	return 0;
}

/* 1 when nothing lies between org and org + tfar dir. */
static int unoccluded(rd_ctx *c, const double org[3], const double dir[3], float tfar)
{
	struct RTCIntersectContext ictx;
	rtcInitIntersectContext(&ictx);
	struct RTCRay r;
	r.org_x = (float)org[0], r.org_y = (float)org[1], r.org_z = (float)org[2];
	r.dir_x = (float)dir[0], r.dir_y = (float)dir[1], r.dir_z = (float)dir[2];
	r.tnear = 0.0f;
	r.tfar = tfar;
	r.time = 0.0f;
	r.mask = ~0u;
	r.id = 0;
	r.flags = 0;
	rtcOccluded1(c->scene, &ictx, &r);
	return r.tfar >= 0.0f;
}

static void ctx_free(rd_ctx *c);

/* ---- label map ------------------------------------------------------------------- */

/* Each triangle takes the label under its centroid as seen from the label camera when
 * the centroid is in view and nothing hides it; the fallback otherwise. */
static int project_labels(rd_ctx *c, uint64_t *rays, kg_err *err)
{
	const kg_scene *s = c->s;
	const rd_label_map *lm = &s->label;
	const kg_mesh *mesh = s->mesh;
	rd_frame f;
	rd_view_frame(&lm->view, &f);
	double aspect = (double)lm->width / lm->height;
	if (!(c->label_tri_mat = malloc(sizeof(uint16_t) * mesh->ntris)))
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (size_t t = 0; t < mesh->ntris; t++) {
		double p[3] = {0, 0, 0};
		for (int k = 0; k < 3; k++)
			for (int i = 0; i < 3; i++)
				p[i] += mesh->pos[3 * mesh->tri[3 * t + k] + i] / 3.0;
		int mat = lm->fallback;
		double d[3] = {p[0] - lm->view.pos[0], p[1] - lm->view.pos[1],
		               p[2] - lm->view.pos[2]};
		double z = dot3(d, f.fwd);
		if (z > 0.0) {
			double x = dot3(d, f.right) / (z * f.tan_half * aspect);
			double y = dot3(d, f.up) / (z * f.tan_half);
			double px = (x + 1.0) * 0.5 * lm->width, py = (1.0 - y) * 0.5 * lm->height;
			if (px >= 0.0 && px < lm->width && py >= 0.0 && py < lm->height) {
				double dist = sqrt(dot3(d, d)), back[3], org[3];
				for (int i = 0; i < 3; i++) {
					back[i] = -d[i] / dist;
					org[i] = p[i] + back[i] * c->eps;
				}
				(*rays)++;
				if (unoccluded(c, org, back, (float)(dist - 2.0 * c->eps))) {
					int label = lm->labels[(size_t)py * (size_t)lm->width + (size_t)px];
					if (lm->class_mat[label] >= 0)
						mat = lm->class_mat[label];
				}
			}
		}
		c->label_tri_mat[t] = (uint16_t)mat;
	}
	c->tri_mat = c->label_tri_mat;
	return 0;
}

int rd_scene_triangle_materials(const kg_scene *s, int threads, uint16_t **out, kg_err *err)
{
	if (s->assign != RD_ASSIGN_LABEL_MAP)
		return rd_scene_triangle_materials_plain(s, out, err);
	*out = NULL;
	rd_ctx c;
	memset(&c, 0, sizeof(c));
	c.s = s;
	if (threads <= 0)
		threads = kg_cpu_count(MAX_THREADS);
	threads = threads < 1 ? 1 : threads > MAX_THREADS ? MAX_THREADS : threads;
	uint64_t rays = 0;
	int ret = build_scene(&c, threads, err);
	if (!ret)
		ret = project_labels(&c, &rays, err);
	if (!ret) {
		*out = c.label_tri_mat;
		c.label_tri_mat = NULL;
	}
	ctx_free(&c);
	return ret;
}

/* ---- shading --------------------------------------------------------------------- */

static void env_radiance(const kg_scene *s, const double dir[3], const int *band, int n,
                         float *out)
{
	if (!s->has_env) {
		memset(out, 0, sizeof(float) * (size_t)n);
		return;
	}
	if (!s->env_coef) {
		for (int j = 0; j < n; j++)
			out[j] = s->env_radiance[band[j]];
		return;
	}
	/* equirectangular, +z up: the column from the azimuth atan2(y, x) (0 = +x, a
	 * quarter of the width = +y) plus the rotation, the row from the angle to +z (the
	 * top row straight up); bilinear in the texel coefficients */
	double phi = atan2(dir[1], dir[0]) + s->env_rotation_deg * M_PI / 180.0;
	double u = phi / (2.0 * M_PI);
	u -= floor(u);
	double v = acos(fmax(-1.0, fmin(1.0, dir[2]))) / M_PI;
	double x = u * s->env_width - 0.5, y = v * s->env_height - 0.5;
	double fx = floor(x), fy = floor(y);
	double tx = x - fx, ty = y - fy;
	int x0 = (int)fx, y0 = (int)fy;
	float coef[3] = {0, 0, 0};
	for (int k = 0; k < 4; k++) {
		int xi = x0 + (k & 1), yi = y0 + (k >> 1);
		xi = ((xi % s->env_width) + s->env_width) % s->env_width;
		yi = yi < 0 ? 0 : yi >= s->env_height ? s->env_height - 1 : yi;
		double w = ((k & 1) ? tx : 1.0 - tx) * ((k >> 1) ? ty : 1.0 - ty);
		const float *t = s->env_coef + 3 * ((size_t)yi * (size_t)s->env_width + (size_t)xi);
		for (int i = 0; i < 3; i++)
			coef[i] += (float)w * t[i];
	}
	for (int j = 0; j < n; j++) {
		int b = band[j];
		float r = coef[0] * s->env_up.basis[0][b] + coef[1] * s->env_up.basis[1][b] +
		          coef[2] * s->env_up.basis[2][b];
		out[j] = r > 0.0f ? r * s->env_radiance[b] : 0.0f;
	}
}

/* ---- packets ---------------------------------------------------------------------- */

/* 1 when any of the 16 lanes of a mask is set. */
static int lanes_any(const int *v)
{
	int any = 0;
	for (int l = 0; l < LANES; l++)
		any |= v[l];
	return any;
}

/* The hits of a 16-ray packet and their shading frames, as structures of arrays so
 * that the frame arithmetic runs as SIMD loops over the lanes. */
typedef struct rd_lanes {
	int hit[LANES];           /* the lane's ray was traced and hit the mesh */
	unsigned prim[LANES];     /* its triangle (0 when it missed: a safe index) */
	float t[LANES], u[LANES], v[LANES];
	float vx[LANES], vy[LANES], vz[LANES]; /* unit, back along the ray */
	float gx[LANES], gy[LANES], gz[LANES]; /* geometric normal: unit, viewer's side */
	float nx[LANES], ny[LANES], nz[LANES]; /* shading normal */
	uint32_t idx[3][LANES];   /* the triangle's vertices */
	float vn[3][3][LANES];    /* their normals: [corner][axis][lane] */
} rd_lanes;

/* Fill the fixed fields of the lanes of a packet of rays from the camera or from
 * surface points, and the hit fields Embree leaves alone on a miss; origins and
 * directions are the caller's. */
static void packet_init(struct RTCRayHit16 *rh)
{
	for (int l = 0; l < LANES; l++) {
		rh->hit.primID[l] = 0;
		rh->hit.u[l] = rh->hit.v[l] = 0.0f;
		rh->hit.Ng_x[l] = rh->hit.Ng_y[l] = rh->hit.Ng_z[l] = 0.0f;
		rh->ray.tnear[l] = 0.0f;
		rh->ray.tfar[l] = INFINITY;
		rh->ray.time[l] = 0.0f;
		rh->ray.mask[l] = ~0u;
		rh->ray.id[l] = (unsigned)l;
		rh->ray.flags[l] = 0;
		rh->hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
		rh->hit.instID[0][l] = RTC_INVALID_GEOMETRY_ID;
	}
}

/* The hits of a traced packet (lanes with valid[l] = 0 were not traced) with their
 * shading frames: geometric normal ng and shading normal ns, both on the side of the
 * viewer V; ns is the interpolated vertex normal when the mesh has normals and it
 * faces the viewer, else ng. Only the lanes with hit[l] mean anything. */
static void packet_hits(const rd_ctx *c, const int *valid,
                        const struct RTCRayHit16 *restrict rh, rd_lanes *restrict h)
{
	const kg_mesh *mesh = c->s->mesh;
	/* Branch-free lane loops (selects of computed values, divisions on safe operands)
	 * so that they vectorise; a missed lane keeps whatever its fields held (defined:
	 * packet_init), its triangle index 0. */
	for (int l = 0; l < LANES; l++) {
		int hit = (valid[l] != 0) & (rh->hit.geomID[l] != RTC_INVALID_GEOMETRY_ID);
		h->hit[l] = hit;
		h->prim[l] = rh->hit.primID[l] & -(unsigned)hit;
	}
	for (int l = 0; l < LANES; l++) {
		float vx = -rh->ray.dir_x[l], vy = -rh->ray.dir_y[l], vz = -rh->ray.dir_z[l];
		float x = rh->hit.Ng_x[l], y = rh->hit.Ng_y[l], z = rh->hit.Ng_z[l];
		h->t[l] = rh->ray.tfar[l];
		h->u[l] = rh->hit.u[l];
		h->v[l] = rh->hit.v[l];
		h->vx[l] = vx, h->vy[l] = vy, h->vz[l] = vz;
		float d = x * x + y * y + z * z;
		float r = 1.0f / sqrtf(d > 0.0f ? d : 1.0f);
		r = d > 0.0f ? r : 0.0f;
		r = x * vx + y * vy + z * vz < 0.0f ? -r : r;
		h->gx[l] = h->nx[l] = x * r;
		h->gy[l] = h->ny[l] = y * r;
		h->gz[l] = h->nz[l] = z * r;
	}
	if (!mesh->normal || !lanes_any(h->hit))
		return;
	/* the vertex indices of the lanes that hit, then their normals: two rounds of
	 * independent loads (the mesh's arrays are cold: Embree traverses its own copy);
	 * the other lanes keep earlier values and are computed for nothing */
	for (int l = 0; l < LANES; l++)
		if (h->hit[l]) {
			const uint32_t *tri = mesh->tri + 3 * (size_t)h->prim[l];
			h->idx[0][l] = tri[0], h->idx[1][l] = tri[1], h->idx[2][l] = tri[2];
		}
	for (int l = 0; l < LANES; l++)
		if (h->hit[l])
			for (int k = 0; k < 3; k++) {
				const float *vn = mesh->normal + 3 * (size_t)h->idx[k][l];
				h->vn[k][0][l] = vn[0], h->vn[k][1][l] = vn[1], h->vn[k][2][l] = vn[2];
			}
	for (int l = 0; l < LANES; l++) {
		float u = h->u[l], v = h->v[l], w = 1.0f - u - v;
		float x = w * h->vn[0][0][l] + u * h->vn[1][0][l] + v * h->vn[2][0][l];
		float y = w * h->vn[0][1][l] + u * h->vn[1][1][l] + v * h->vn[2][1][l];
		float z = w * h->vn[0][2][l] + u * h->vn[1][2][l] + v * h->vn[2][2][l];
		float d = x * x + y * y + z * z;
		float r = 1.0f / sqrtf(d > 0.0f ? d : 1.0f);
		r = d > 0.0f ? r : 0.0f;
		r = x * h->gx[l] + y * h->gy[l] + z * h->gz[l] < 0.0f ? -r : r;
		x *= r, y *= r, z *= r;
		/* facing the viewer, and finite (a unit vector's components are at most 1) */
		int use = (x * h->vx[l] + y * h->vy[l] + z * h->vz[l] > 0.0f) & (fabsf(x) <= 1.0f) &
		          (fabsf(y) <= 1.0f) & (fabsf(z) <= 1.0f);
		h->nx[l] = use ? x : h->nx[l];
		h->ny[l] = use ? y : h->ny[l];
		h->nz[l] = use ? z : h->nz[l];
	}
}

/* The camera rays of the 4 x 4 block at (bx, by), sample smp, into rh (fixed fields
 * set by packet_init): lanes outside the image are invalid. Each sample's key is one
 * hash of (seed, pixel, sample): its top 48 bits are the jitter, and it seeds the
 * path's generator. Directions in float, as Embree takes them, in SIMD loops. */
static void camera_rays(const rd_ctx *c, int bx, int by, int smp, int *valid,
                        struct RTCRayHit16 *rh, uint64_t *key)
{
	float jx[LANES], jy[LANES];
	for (int l = 0; l < LANES; l++) {
		int x = bx + (l & 3), y = by + (l >> 2);
		valid[l] = -((x < c->width) & (y < c->height));
		uint64_t pixel = (uint64_t)y * (uint64_t)c->width + (uint64_t)x;
		uint64_t k = mix64(c->key_base ^ (pixel << 32 | (uint32_t)smp));
		key[l] = k;
		/* through int32_t: a uint64_t to float conversion branches on the top bit */
		jx[l] = (float)(int32_t)(k >> 40) * 0x1p-24f;
		jy[l] = (float)(int32_t)((k >> 16) & 0xffffff) * 0x1p-24f;
	}
	for (int l = 0; l < LANES; l++) {
		float px = ((float)(bx + (l & 3)) + jx[l]) * c->cam_sx + c->cam_ox;
		float py = ((float)(by + (l >> 2)) + jy[l]) * c->cam_sy + c->cam_oy;
		float x = c->cam_fwd[0] + px * c->cam_right[0] + py * c->cam_up[0];
		float y = c->cam_fwd[1] + px * c->cam_right[1] + py * c->cam_up[1];
		float z = c->cam_fwd[2] + px * c->cam_right[2] + py * c->cam_up[2];
		float r = 1.0f / sqrtf(x * x + y * y + z * z);
		rh->ray.org_x[l] = c->cam_org[0];
		rh->ray.org_y[l] = c->cam_org[1];
		rh->ray.org_z[l] = c->cam_org[2];
		rh->ray.dir_x[l] = x * r;
		rh->ray.dir_y[l] = y * r;
		rh->ray.dir_z[l] = z * r;
		rh->ray.tfar[l] = INFINITY;
		rh->hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
	}
}

/* ---- paths ------------------------------------------------------------------------ */

typedef struct rd_counts {
	uint64_t rays[KG_RENDER_MAX_BOUNCES + 1], shadow[KG_RENDER_MAX_BOUNCES];
	double secs[KG_RENDER_MAX_BOUNCES + 1]; /* kg_render_stats.depth_s */
} rd_counts;

/* The paths of a camera packet (its hits in h), carried on together depth by depth:
 * the shadow rays of a depth as one packet (towards the light: coherent), then the
 * bounce rays as another. Each lane draws from its own generator in the order a
 * lone path would, so a pixel's value does not depend on its packet's other lanes.
 * Adds each lane's c->nch channels to acc[ch][pix[l]]; t is the clock when the
 * camera packet was done (the time from there on goes to the depths). */
static void trace_paths(rd_ctx *c, kg_rng *rng, const int *valid, struct RTCRayHit16 *rh,
                        rd_lanes *h, double acc[][TILE * TILE], const int *pix,
                        double t, rd_counts *cnt)
{
	const kg_scene *s = c->s;
	int n = c->nwl;
	int alive[LANES], band[LANES][KG_NBANDS];
	float T[LANES][KG_NBANDS], L[LANES][KG_NBANDS], sun[LANES][KG_NBANDS];
	float tmp[KG_NBANDS];
	double org[LANES][3], dir[LANES][3];
	for (int l = 0; l < LANES; l++) {
		alive[l] = valid[l];
		if (!alive[l])
			continue;
		int hero = (int)(kg_rng_uniform(&rng[l]) * KG_NBANDS);
		for (int j = 0; j < n; j++) {
			band[l][j] = (hero + j * KG_NBANDS / n) % KG_NBANDS;
			T[l][j] = 1.0f;
			L[l][j] = 0.0f;
		}
		for (int i = 0; i < 3; i++)
			org[l][i] = s->view.pos[i];
		dir[l][0] = rh->ray.dir_x[l], dir[l][1] = rh->ray.dir_y[l], dir[l][2] = rh->ray.dir_z[l];
	}
	struct RTCIntersectContext ictx;
	rtcInitIntersectContext(&ictx);
	_Alignas(64) int sv[LANES], bv[LANES];
	struct RTCRay16 sh;
	memset(&sh, 0, sizeof(sh)); /* Embree may load the lanes it leaves alone */
	int depth = 0;
	for (;; depth++) {
		for (int l = 0; l < LANES; l++)
			if (alive[l] && !h->hit[l]) {
				env_radiance(s, dir[l], band[l], n, tmp);
				for (int j = 0; j < n; j++)
					L[l][j] += T[l][j] * tmp[j];
				alive[l] = 0;
			}
		if (depth == c->bounces || !lanes_any(alive))
			break;
		for (int l = 0; l < LANES; l++) {
			sv[l] = bv[l] = 0;
			if (!alive[l])
				continue;
			double P[3], V[3] = {h->vx[l], h->vy[l], h->vz[l]};
			double ng[3] = {h->gx[l], h->gy[l], h->gz[l]};
			double ns[3] = {h->nx[l], h->ny[l], h->nz[l]};
			for (int i = 0; i < 3; i++)
				P[i] = org[l][i] + h->t[l] * dir[l][i];
			const rd_material *m = &c->mat[c->tri_mat ? c->tri_mat[h->prim[l]] : 0];
			if (s->has_sun && dot3(ng, s->sun_dir) > 0.0 &&
			    rd_eval(m, ns, V, s->sun_dir, band[l], n, tmp)) {
				for (int j = 0; j < n; j++)
					sun[l][j] = T[l][j] * tmp[j] * s->sun_irradiance[band[l][j]];
				sv[l] = -1;
				sh.org_x[l] = (float)(P[0] + c->eps * ng[0]);
				sh.org_y[l] = (float)(P[1] + c->eps * ng[1]);
				sh.org_z[l] = (float)(P[2] + c->eps * ng[2]);
				sh.dir_x[l] = (float)s->sun_dir[0];
				sh.dir_y[l] = (float)s->sun_dir[1];
				sh.dir_z[l] = (float)s->sun_dir[2];
				sh.tnear[l] = 0.0f;
				sh.tfar[l] = INFINITY;
				sh.time[l] = 0.0f;
				sh.mask[l] = ~0u;
				sh.id[l] = (unsigned)l;
				sh.flags[l] = 0;
				cnt->shadow[depth]++;
			}
			double u[3] = {kg_rng_uniform(&rng[l]), kg_rng_uniform(&rng[l]),
			               kg_rng_uniform(&rng[l])};
			double Lo[3];
			if (!rd_sample(m, ns, V, u, band[l], n, Lo, tmp))
				continue;
			/* A shading normal can send a sample under the surface (about one path in
			 * 10^4 on a level-4 sphere): mirror it about the surface's plane, keeping
			 * its weight, rather than end the path and lose its energy (the furnace
			 * test sees such a loss). */
			double side = dot3(ng, Lo);
			if (side <= 0.0)
				for (int i = 0; i < 3; i++)
					Lo[i] -= 2.0 * side * ng[i];
			if (!(dot3(ng, Lo) > 0.0))
				continue;
			for (int j = 0; j < n; j++)
				T[l][j] *= tmp[j];
			for (int i = 0; i < 3; i++) {
				org[l][i] = P[i] + c->eps * ng[i];
				dir[l][i] = Lo[i];
			}
			bv[l] = -1;
			rh->ray.org_x[l] = (float)org[l][0];
			rh->ray.org_y[l] = (float)org[l][1];
			rh->ray.org_z[l] = (float)org[l][2];
			rh->ray.dir_x[l] = (float)Lo[0];
			rh->ray.dir_y[l] = (float)Lo[1];
			rh->ray.dir_z[l] = (float)Lo[2];
			rh->ray.tfar[l] = INFINITY;
			rh->hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
			cnt->rays[depth + 1]++;
		}
		if (lanes_any(sv)) {
			ictx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
			rtcOccluded16(sv, c->scene, &ictx, &sh);
			for (int l = 0; l < LANES; l++)
				if (sv[l] && sh.tfar[l] >= 0.0f)
					for (int j = 0; j < n; j++)
						L[l][j] += sun[l][j];
		}
		for (int l = 0; l < LANES; l++)
			alive[l] = bv[l];
		if (!lanes_any(bv))
			break;
		double t1 = now_s();
		cnt->secs[depth] += t1 - t;
		ictx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
		rtcIntersect16(bv, c->scene, &ictx, rh);
		packet_hits(c, bv, rh, h);
		t = now_s();
		cnt->secs[depth + 1] += t - t1;
	}
	/* the observer (eq. 12 for XYZ) estimated from the path's bands: each stands for
	 * KG_NBANDS / n of them */
	double k = (double)KG_NBANDS / n;
	for (int l = 0; l < LANES; l++) {
		if (!valid[l])
			continue;
		for (int ch = 0; ch < c->nch; ch++) {
			double sum = 0.0;
			for (int j = 0; j < n; j++)
				sum += (double)c->w[ch][band[l][j]] * L[l][j];
			acc[ch][pix[l]] += k * sum;
		}
	}
	cnt->secs[depth] += now_s() - t;
}

/* The truth class of lane l's hit (0: nothing, or a background part). */
static int hit_class(const rd_ctx *c, const rd_lanes *h, int l)
{
	if (!h->hit[l] || (c->s->tri_background && c->s->tri_background[h->prim[l]]))
		return 0;
	return c->mat_class[c->tri_mat ? c->tri_mat[h->prim[l]] : 0];
}

/* The tile's truth from the counts: each pixel's most frequent class (the lower on a
 * tie) and the mean incidence angle of its samples of that class. */
static void finish_truth(rd_ctx *c, int tx0, int ty0, const uint32_t *count,
                         const double *angle)
{
	for (int y = ty0; y < ty0 + TILE && y < c->height; y++)
		for (int x = tx0; x < tx0 + TILE && x < c->width; x++) {
			size_t base = (size_t)((y - ty0) * TILE + (x - tx0)) * (size_t)c->ncls;
			int best = 0;
			for (int k = 1; k < c->ncls; k++)
				if (count[base + (size_t)k] > count[base + (size_t)best])
					best = k;
			size_t i = (size_t)y * (size_t)c->width + (size_t)x;
			c->label[i] = (uint8_t)best;
			c->angle[i] = best ? (float)(angle[base + (size_t)best] /
			                             count[base + (size_t)best])
			                   : NAN;
		}
}

static void render_tile(rd_ctx *c, int tile, int worker_idx, rd_counts *cnt)
{
	int tx0 = (tile % c->tiles_x) * TILE, ty0 = (tile / c->tiles_x) * TILE;
	/* per channel, per pixel of the tile; the preview sums N.V in channel 0 and
	 * scales the white's reading by it at the end */
	double acc[MAX_CH][TILE * TILE];
	int nacc = c->mode == KG_RENDER_PREVIEW ? 1 : c->nch;
	memset(acc, 0, sizeof(acc[0]) * (size_t)nacc);
	size_t tsize = (size_t)TILE * TILE * (size_t)c->ncls;
	uint32_t *tcount = c->truth ? c->tcount + (size_t)worker_idx * tsize : NULL;
	double *tangle = c->truth ? c->tangle + (size_t)worker_idx * tsize : NULL;
	if (c->truth) {
		memset(tcount, 0, sizeof(*tcount) * tsize);
		memset(tangle, 0, sizeof(*tangle) * tsize);
	}
	struct RTCIntersectContext ictx;
	rtcInitIntersectContext(&ictx);
	ictx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
	_Alignas(64) int valid[LANES];
	struct RTCRayHit16 rh;
	rd_lanes h;
	memset(&h, 0, sizeof(h)); /* lanes that never hit are computed on, never used */
	uint64_t key[LANES];
	kg_rng rng[LANES];
	int pix[LANES];

	for (int by = ty0; by < ty0 + TILE && by < c->height; by += 4)
		for (int bx = tx0; bx < tx0 + TILE && bx < c->width; bx += 4) {
			for (int l = 0; l < LANES; l++)
				pix[l] = (by - ty0 + (l >> 2)) * TILE + (bx - tx0 + (l & 3));
			packet_init(&rh);
			for (int smp = 0; smp < c->spp; smp++) {
				double t0 = c->mode == KG_RENDER_PREVIEW ? 0.0 : now_s();
				camera_rays(c, bx, by, smp, valid, &rh, key);
				for (int l = 0; l < LANES; l++)
					cnt->rays[0] += valid[l] != 0;
				rtcIntersect16(valid, c->scene, &ictx, &rh);
				packet_hits(c, valid, &rh, &h);
				if (c->truth)
					for (int l = 0; l < LANES; l++) {
						if (!valid[l])
							continue;
						int cls = hit_class(c, &h, l);
						double ang = 0.0;
						if (cls) {
							double nv = h.nx[l] * h.vx[l] + h.ny[l] * h.vy[l] + h.nz[l] * h.vz[l];
							ang = acos(fmax(-1.0, fmin(1.0, nv))) * (180.0 / M_PI);
						}
						size_t k = (size_t)pix[l] * (size_t)c->ncls + (size_t)cls;
						tcount[k]++;
						tangle[k] += ang;
					}
				if (c->mode == KG_RENDER_PREVIEW) {
					for (int l = 0; l < LANES; l++)
						if (h.hit[l])
							acc[0][pix[l]] += h.nx[l] * h.vx[l] + h.ny[l] * h.vy[l] +
							                  h.nz[l] * h.vz[l];
					continue;
				}
				for (int l = 0; l < LANES; l++)
					if (valid[l])
						kg_rng_seed(&rng[l], key[l]);
				double t1 = now_s();
				cnt->secs[0] += t1 - t0;
				trace_paths(c, rng, valid, &rh, &h, acc, pix, t1, cnt);
			}
		}
	/* the tile's rows, each a run of 3 x nx floats of each image */
	double k = c->s->exposure / c->spp, wk[MAX_CH];
	for (int ch = 0; ch < c->nch; ch++)
		wk[ch] = c->mode == KG_RENDER_PREVIEW ? c->white_out[ch] * k : k;
	int nx = c->width - tx0 < TILE ? c->width - tx0 : TILE;
	for (int y = ty0; y < ty0 + TILE && y < c->height; y++) {
		int p = (y - ty0) * TILE;
		size_t o = 3 * ((size_t)y * (size_t)c->width + (size_t)tx0);
		for (int img = 0; img < c->nch / 3; img++) {
			float *out = c->out[img] + o;
			for (int i = 0; i < 3; i++) {
				const double *a = acc[nacc == 1 ? 0 : 3 * img + i] + p;
				double w = wk[3 * img + i];
				for (int x = 0; x < nx; x++)
					out[3 * x + i] = (float)(a[x] * w);
			}
		}
	}
	if (c->truth)
		finish_truth(c, tx0, ty0, tcount, tangle);
}

typedef struct rd_worker {
	rd_ctx *c;
	int idx; /* its truth scratch */
} rd_worker;

static void *worker(void *arg)
{
	rd_worker *wk = arg;
	rd_ctx *c = wk->c;
	set_fp_modes();
	rd_counts cnt = {0};
	for (;;) {
		int tile = atomic_fetch_add(&c->next_tile, 1);
		if (tile >= c->ntiles)
			break;
		render_tile(c, tile, wk->idx, &cnt);
		if (c->opt && c->opt->progress) {
			pthread_mutex_lock(&c->lock);
			c->tiles_done++;
			c->opt->progress(c->opt->progress_user, c->tiles_done, c->ntiles);
			pthread_mutex_unlock(&c->lock);
		}
	}
	pthread_mutex_lock(&c->lock);
	for (int d = 0; d <= c->bounces; d++) {
		c->depth_rays[d] += cnt.rays[d];
		c->depth_s[d] += cnt.secs[d];
	}
	for (int d = 0; d < c->bounces; d++)
		c->depth_shadow[d] += cnt.shadow[d];
	pthread_mutex_unlock(&c->lock);
	return NULL;
}

static void ctx_free(rd_ctx *c)
{
	if (c->scene)
		rtcReleaseScene(c->scene);
	if (c->dev)
		rtcReleaseDevice(c->dev);
	free(c->vbuf);
	for (int i = 0; c->mat && i < c->nmat; i++)
		rd_material_clear(&c->mat[i]);
	free(c->mat);
	free(c->label_tri_mat);
	free(c->mat_class);
	free(c->tcount);
	free(c->tangle);
}

/* The observer's weights (the scene's XYZ without one) and the white's reading. */
static int setup_observer(rd_ctx *c, const kg_render_options *opt, kg_err *err)
{
	const kg_scene *s = c->s;
	c->nch = 3;
	for (int ch = 0; ch < 3; ch++)
		for (int i = 0; i < KG_NBANDS; i++) {
			if (opt->observer) {
				double v = opt->observer[ch].v[i];
				if (!isfinite(v))
					return kg_fail(err, KG_EINVAL, "observer channel %d at %g nm: %g: "
					               "expected a finite weight", ch, kg_band_nm(i), v);
				c->w[ch][i] = (float)v;
			} else {
				c->w[ch][i] = s->xyz_w[ch][i];
			}
		}
	if (opt->observer && opt->want_xyz) {
		memcpy(c->w[3], s->xyz_w, sizeof(s->xyz_w));
		c->nch = 6;
	}
	/* XYZ channels take the white point itself (the same bytes as ever), an observer's
	 * its reading of the white's spectrum */
	const double white[3] = {s->white.X, s->white.Y, s->white.Z};
	for (int ch = 0; ch < c->nch; ch++) {
		double sum = 0.0;
		for (int i = 0; i < KG_NBANDS; i++)
			sum += (double)c->w[ch][i] * s->white_spd[i];
		c->white_out[ch] = ch >= 3 || !opt->observer ? white[ch % 3] : sum;
	}
	return 0;
}

/* Classes and maps of the truth; the scratch for `threads` workers. */
static int setup_truth(rd_ctx *c, int threads, kg_render_truth **out, kg_err *err)
{
	const kg_scene *s = c->s;
	int nlib = kg_material_library_count(s->lib);
	if (nlib > 255)
		return kg_fail(err, KG_EINVAL, "truth labels: the library %s has %d materials: "
		               "a label map holds at most 255 (and background)", s->library_path,
		               nlib);
	kg_render_truth *t = calloc(1, sizeof(*t));
	if (!t)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	*out = t;
	t->width = c->width;
	t->height = c->height;
	t->nclasses = c->ncls = nlib + 1;
	size_t npix = (size_t)c->width * (size_t)c->height;
	size_t tsize = (size_t)TILE * TILE * (size_t)c->ncls * (size_t)threads;
	t->class_names = calloc((size_t)t->nclasses, sizeof(char *));
	t->label = malloc(npix);
	t->angle_deg = malloc(sizeof(float) * npix);
	c->mat_class = calloc((size_t)(s->nmat ? s->nmat : 1), 1);
	c->tcount = malloc(sizeof(*c->tcount) * tsize);
	c->tangle = malloc(sizeof(*c->tangle) * tsize);
	if (!t->class_names || !t->label || !t->angle_deg || !c->mat_class || !c->tcount ||
	    !c->tangle)
		return kg_fail(err, KG_ENOMEM, "out of memory for the truth maps");
	for (int i = 0; i < t->nclasses; i++)
		if (!(t->class_names[i] = strdup(i ? kg_material_library_get(s->lib, i - 1)->name
		                                   : "background")))
			return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int m = 0; m < s->nmat; m++)
		for (int j = 0; j < nlib; j++)
			if (kg_material_library_get(s->lib, j) == s->mat[m])
				c->mat_class[m] = (uint8_t)(j + 1);
	c->label = t->label;
	c->angle = t->angle_deg;
	c->truth = 1;
	return 0;
}

int kg_render(const kg_scene *s, const kg_render_options *opt, kg_image **xyz,
              kg_render_stats *stats, kg_err *err)
{
	kg_check_arg(s && xyz, err);
	*xyz = NULL;
	kg_render_options o = {0};
	if (opt)
		o = *opt;
	o.want_xyz = o.want_truth = 0;
	kg_render_result r;
	int ret = kg_render_full(s, &o, &r, stats, err);
	*xyz = r.image;
	return ret;
}

int kg_render_full(const kg_scene *s, const kg_render_options *opt, kg_render_result *res,
                   kg_render_stats *stats, kg_err *err)
{
	kg_check_arg(s && res, err);
	memset(res, 0, sizeof(*res));
	static const kg_render_options defaults;
	if (!opt)
		opt = &defaults;
	rd_ctx c = {.s = s, .opt = opt, .mode = opt->mode};
	c.width = opt->width > 0 ? opt->width : s->view.width;
	c.height = opt->height > 0 ? opt->height : s->view.height;
	c.spp = opt->spp > 0 ? opt->spp : s->spp;
	c.nwl = opt->wavelengths > 0 ? opt->wavelengths : s->wavelengths;
	c.bounces = opt->bounces > 0 ? opt->bounces : s->bounces;
	c.seed = opt->seed_set ? opt->seed : s->seed;
	int threads = opt->threads > 0 ? opt->threads : kg_cpu_count(MAX_THREADS);
	if (threads < 1)
		threads = 1;
	if (threads > MAX_THREADS)
		threads = MAX_THREADS;
	if (c.bounces > KG_RENDER_MAX_BOUNCES)
		return kg_fail(err, KG_EINVAL, "bounces: %d: expected 1 to %d", c.bounces,
		               KG_RENDER_MAX_BOUNCES);
	if (c.nwl > KG_RENDER_ALL_BANDS)
		return kg_fail(err, KG_EINVAL, "wavelengths per path: %d: expected 1 to %d", c.nwl,
		               KG_RENDER_ALL_BANDS);
	if (c.width > 16384 || c.height > 16384)
		return kg_fail(err, KG_EINVAL, "image size %d x %d: expected at most 16384 per side",
		               c.width, c.height);
	rd_view_frame(&s->view, &c.frame);
	c.key_base = mix64(c.seed ^ 0x6b67656900000000ULL);
	double aspect = (double)c.width / c.height;
	for (int i = 0; i < 3; i++) {
		c.cam_org[i] = (float)s->view.pos[i];
		c.cam_fwd[i] = (float)c.frame.fwd[i];
		c.cam_right[i] = (float)c.frame.right[i];
		c.cam_up[i] = (float)c.frame.up[i];
	}
	c.cam_sx = (float)(2.0 * c.frame.tan_half * aspect / c.width);
	c.cam_ox = (float)(-c.frame.tan_half * aspect);
	c.cam_sy = (float)(-2.0 * c.frame.tan_half / c.height);
	c.cam_oy = (float)c.frame.tan_half;
	kg_render_truth *truth = NULL;
	int ret = setup_observer(&c, opt, err);
	if (!ret && opt->want_truth)
		ret = setup_truth(&c, threads, &truth, err);
	if (ret) {
		kg_render_truth_free(&truth);
		ctx_free(&c);
		return ret;
	}

	set_fp_modes();
	double t0 = now_s();
	ret = build_scene(&c, threads, err);
	double t1 = now_s();
	uint64_t label_rays = 0;
	if (!ret && s->assign == RD_ASSIGN_LABEL_MAP)
		ret = project_labels(&c, &label_rays, err);
	else
		c.tri_mat = s->tri_mat;
	if (!ret && !(c.mat = calloc((size_t)s->nmat, sizeof(*c.mat))))
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; !ret && i < s->nmat; i++, c.nmat++)
		ret = rd_material_init(&c.mat[i], s->mat[i], err);
	kg_image *img = NULL, *xyz = NULL;
	if (!ret)
		ret = kg_image_new(c.width, c.height, 3, &img, err);
	if (!ret && c.nch == 6)
		ret = kg_image_new(c.width, c.height, 3, &xyz, err);
	if (ret) {
		kg_image_free(&img);
		kg_render_truth_free(&truth);
		ctx_free(&c);
		return ret;
	}
	c.out[0] = img->data;
	c.out[1] = xyz ? xyz->data : NULL;
	for (int i = 0; i < 2 && c.out[i]; i++)
		/* first touched by the workers as they store the tiles */
		kg_advise_huge_pages(c.out[i], sizeof(float) * 3 * (size_t)c.width * (size_t)c.height);
	c.tiles_x = (c.width + TILE - 1) / TILE;
	c.ntiles = c.tiles_x * ((c.height + TILE - 1) / TILE);
	atomic_init(&c.next_tile, 0);
	pthread_mutex_init(&c.lock, NULL);
	pthread_t tid[MAX_THREADS];
	rd_worker wk[MAX_THREADS];
	int started = 0;
	double t2 = now_s();
	for (; started < threads; started++) {
		wk[started] = (rd_worker){.c = &c, .idx = started};
		if (pthread_create(&tid[started], NULL, worker, &wk[started]) != 0)
			break;
	}
	if (started == 0) {
		wk[0] = (rd_worker){.c = &c, .idx = 0};
		worker(&wk[0]); /* no thread could be started: render here */
	}
	for (int i = 0; i < started; i++)
		pthread_join(tid[i], NULL);
	double t3 = now_s();
	pthread_mutex_destroy(&c.lock);
	if (c.embree_error[0])
		ret = kg_fail(err, KG_EIO, "%s", c.embree_error);
	if (!ret && stats) {
		*stats = (kg_render_stats){
			.width = c.width, .height = c.height, .spp = c.spp, .wavelengths = c.nwl,
			.bounces = c.bounces, .threads = threads, .seed = c.seed, .build_s = t1 - t0,
			.render_s = t3 - t2, .primary_rays = c.depth_rays[0], .label_rays = label_rays,
		};
		for (int d = 0; d <= c.bounces; d++) {
			stats->depth_rays[d] = c.depth_rays[d];
			stats->depth_s[d] = c.depth_s[d];
			stats->rays += c.depth_rays[d];
		}
		for (int d = 0; d < c.bounces; d++) {
			stats->depth_shadow_rays[d] = c.depth_shadow[d];
			stats->shadow_rays += c.depth_shadow[d];
		}
	}
	ctx_free(&c);
	if (ret) {
		kg_image_free(&img);
		kg_image_free(&xyz);
		kg_render_truth_free(&truth);
	}
	res->image = img;
	res->xyz = xyz;
	res->truth = truth;
	return ret;
}
