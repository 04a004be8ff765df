/* kogei-bench-render: the renderer's speed, a program (never a test).
 *
 *  1. BVH build (Embree, build quality medium, as kg_render builds it) of the
 *     icosphere of level 8 (1,310,720 triangles) at 1 and 2 threads;
 *  2. path-traced rays per second on that mesh (closest-hit plus shadow rays; a
 *     gold sphere under a light and an environment), 1 and 2 threads; and split by
 *     depth on the demo scene of 4. (a convex sphere sends no ray past its first
 *     bounce) at 1 spp: the renderer's per-depth ray counts and times;
 *  3. camera rays per second through the renderer (kg_render preview mode: 4 x 4
 *     packets per sample, seeding, jitter, shading by N.V, output) beside the raw
 *     Embree rate of rtcIntersect16 on the same mesh, camera and threads, measured in
 *     the same run (pixel-centre rays, no shading), and their ratio;
 *  4. a 1080p render of the demo object (tsuba, 256 segments) on a ground plane at a
 *     stated quality.
 * Each figure is the median of --reps runs (default 3). Prints a Markdown table. */
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <embree3/rtcore.h>
#if defined(__SSE2__)
#include <pmmintrin.h>
#include <xmmintrin.h>
#endif

#include "kg_render.h"

static const char usage[] =
	"kogei-bench-render [--reps N] [--quick] [-o REPORT.md]\n"
	"  BVH build and ray rates on a 1.3-million-triangle icosphere at 1 and 2 threads,\n"
	"  the renderer's camera-ray rate beside Embree's raw rtcIntersect16 rate, and a\n"
	"  1080p render of the demo object. --quick: 1 repetition, 540p, fewer samples.\n"
	"  The Markdown report goes to standard output and, with -o, to a file.";

static double now_s(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return (x > y) - (x < y);
}

static double median(double *v, int n)
{
	qsort(v, (size_t)n, sizeof(double), cmp_double);
	return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

static char dir[] = "/tmp/kogei-bench-render-XXXXXX";

/* Bounces of the per-depth split. */
#define MAX_BOUNCE 4

static int write_scene(const char *name, const char *text, char *path, size_t size)
{
	snprintf(path, size, "%s/%s", dir, name);
	FILE *fp = fopen(path, "w");
	if (!fp || fputs(text, fp) < 0 || fclose(fp) != 0) {
		perror(path);
		return -1;
	}
	return 0;
}

/* ---- raw Embree: rtcIntersect16 over the camera's pixel centres ---------------- */

typedef struct raw_ctx {
	RTCScene scene;
	int width, height;
	double pos[3], fwd[3], right[3], up[3], tan_half;
	atomic_int next_row; /* rows of 4 pixels */
	atomic_ullong hits;
} raw_ctx;

static void *raw_worker(void *arg)
{
	raw_ctx *c = arg;
#if defined(__SSE2__)
	_MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
	_MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
#endif
	struct RTCIntersectContext ictx;
	rtcInitIntersectContext(&ictx);
	ictx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
	double aspect = (double)c->width / c->height;
	unsigned long long hits = 0;
	for (;;) {
		int by = 4 * atomic_fetch_add(&c->next_row, 1);
		if (by >= c->height)
			break;
		for (int bx = 0; bx < c->width; bx += 4) {
			_Alignas(64) int valid[16];
			struct RTCRayHit16 rh;
			for (int l = 0; l < 16; l++) {
				int x = bx + (l & 3), y = by + (l >> 2);
				valid[l] = x < c->width && y < c->height ? -1 : 0;
				double px = (2.0 * (x + 0.5) / c->width - 1.0) * c->tan_half * aspect;
				double py = (1.0 - 2.0 * (y + 0.5) / c->height) * c->tan_half;
				double d[3];
				for (int i = 0; i < 3; i++)
					d[i] = c->fwd[i] + px * c->right[i] + py * c->up[i];
				double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
				rh.ray.org_x[l] = (float)c->pos[0];
				rh.ray.org_y[l] = (float)c->pos[1];
				rh.ray.org_z[l] = (float)c->pos[2];
				rh.ray.dir_x[l] = (float)(d[0] / n);
				rh.ray.dir_y[l] = (float)(d[1] / n);
				rh.ray.dir_z[l] = (float)(d[2] / n);
				rh.ray.tnear[l] = 0.0f;
				rh.ray.tfar[l] = INFINITY;
				rh.ray.time[l] = 0.0f;
				rh.ray.mask[l] = ~0u;
				rh.ray.id[l] = (unsigned)l;
				rh.ray.flags[l] = 0;
				rh.hit.geomID[l] = RTC_INVALID_GEOMETRY_ID;
				rh.hit.instID[0][l] = RTC_INVALID_GEOMETRY_ID;
			}
			rtcIntersect16(valid, c->scene, &ictx, &rh);
			for (int l = 0; l < 16; l++)
				hits += valid[l] && rh.hit.geomID[l] != RTC_INVALID_GEOMETRY_ID;
		}
	}
	atomic_fetch_add(&c->hits, hits);
	return NULL;
}

/* Rays per second of rtcIntersect16 alone; *hit_fraction of the rays hit. */
static int raw_packet_rate(const kg_mesh *mesh, int threads, int width, int height,
                           int reps, double *rate, double *hit_fraction)
{
	char cfg[32];
	snprintf(cfg, sizeof(cfg), "threads=%d", threads);
	RTCDevice dev = rtcNewDevice(cfg);
	if (!dev)
		return -1;
	float *v = aligned_alloc(16, sizeof(float) * 4 * (mesh->nverts + 1));
	if (!v) {
		rtcReleaseDevice(dev);
		return -1;
	}
	for (size_t i = 0; i < mesh->nverts; i++) {
		memcpy(v + 4 * i, mesh->pos + 3 * i, 3 * sizeof(float));
		v[4 * i + 3] = 0.0f;
	}
	memset(v + 4 * mesh->nverts, 0, 4 * sizeof(float));
	RTCScene scene = rtcNewScene(dev);
	rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_MEDIUM);
	RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
	rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, v, 0,
	                           4 * sizeof(float), mesh->nverts);
	rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, mesh->tri, 0,
	                           3 * sizeof(uint32_t), mesh->ntris);
	rtcCommitGeometry(g);
	rtcAttachGeometry(scene, g);
	rtcReleaseGeometry(g);
	rtcCommitScene(scene);

	/* the camera of the sphere scene below */
	raw_ctx c = {.scene = scene, .width = width, .height = height,
	             .pos = {0, -3, 0}, .fwd = {0, 1, 0}, .right = {1, 0, 0}, .up = {0, 0, 1},
	             .tan_half = tan(45.0 * M_PI / 360.0)};
	double t[16];
	for (int r = 0; r < reps; r++) {
		atomic_init(&c.next_row, 0);
		atomic_init(&c.hits, 0);
		pthread_t tid[8];
		double t0 = now_s();
		for (int i = 0; i < threads; i++)
			pthread_create(&tid[i], NULL, raw_worker, &c);
		for (int i = 0; i < threads; i++)
			pthread_join(tid[i], NULL);
		t[r] = now_s() - t0;
	}
	*rate = (double)width * height / median(t, reps);
	*hit_fraction = (double)atomic_load(&c.hits) / ((double)width * height);
	rtcReleaseScene(scene);
	rtcReleaseDevice(dev);
	free(v);
	return 0;
}

/* ---- through the renderer --------------------------------------------------------- */

typedef struct run_result {
	double build_s, render_s, rays_per_s, primary_per_s;
	kg_render_stats st; /* the last run's (the ray counts are the same in every run) */
} run_result;

static int run(const kg_scene *s, const kg_render_options *opt, int reps, run_result *out)
{
	double build[16], render[16], rays[16], primary[16];
	kg_err err;
	for (int r = 0; r < reps; r++) {
		kg_image *img = NULL;
		if (kg_render(s, opt, &img, &out->st, &err)) {
			fprintf(stderr, "kogei-bench-render: %s\n", err.msg);
			return -1;
		}
		kg_image_free(&img);
		build[r] = out->st.build_s;
		render[r] = out->st.render_s;
		rays[r] = (double)(out->st.rays + out->st.shadow_rays) / out->st.render_s;
		primary[r] = (double)out->st.primary_rays / out->st.render_s;
	}
	out->build_s = median(build, reps);
	out->render_s = median(render, reps);
	out->rays_per_s = median(rays, reps);
	out->primary_per_s = median(primary, reps);
	return 0;
}

int main(int argc, char **argv)
{
	int reps = 3, quick = 0;
	const char *report = NULL;
	for (int i = 1; i < argc; i++) {
		if (strcmp(argv[i], "-o") == 0 && i + 1 < argc) {
			report = argv[++i];
		} else if (strcmp(argv[i], "--quick") == 0) {
			quick = 1;
			reps = 1;
		} else if (strcmp(argv[i], "--reps") == 0 && i + 1 < argc) {
			reps = atoi(argv[++i]);
			if (reps < 1 || reps > 16) {
				fprintf(stderr, "kogei-bench-render: --reps: expected 1 to 16\n%s\n", usage);
				return 2;
			}
		} else if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
			puts(usage);
			return 0;
		} else {
			fprintf(stderr, "kogei-bench-render: unexpected argument '%s'\n%s\n", argv[i],
			        usage);
			return 2;
		}
	}
	if (!kg_render_available()) {
		fprintf(stderr, "kogei-bench-render: built without Embree\n");
		return 1;
	}
	if (!mkdtemp(dir)) {
		perror("mkdtemp");
		return 1;
	}
	int W = quick ? 960 : 1920, H = quick ? 540 : 1080;
	char sphere_path[512], tsuba_path[512], text[2048];
	snprintf(text, sizeof(text),
		"{\"format\": \"kogei-scene/1\",\n"
		" \"mesh\": {\"generator\": \"icosphere\", \"level\": 8},\n"
		" \"materials\": {\"material\": \"gold\"},\n"
		" \"light\": {\"illuminant\": \"D65\", \"direction\": [1, -1, 1.5]},\n"
		" \"environment\": {\"illuminant\": \"D65\", \"intensity\": 0.4},\n"
		" \"camera\": {\"position\": [0, -3, 0], \"look_at\": [0, 0, 0], \"fov_deg\": 45,\n"
		"            \"width\": %d, \"height\": %d},\n"
		" \"sampling\": {\"spp\": 1, \"wavelengths\": 4, \"bounces\": 4, \"seed\": 1}}\n",
		W, H);
	int ret = write_scene("sphere.json", text, sphere_path, sizeof(sphere_path));
	int spp = quick ? 4 : 16;
	snprintf(text, sizeof(text),
		"{\"format\": \"kogei-scene/1\",\n"
		" \"mesh\": [{\"generator\": \"tsuba\", \"segments\": 256},\n"
		"          {\"generator\": \"plane\", \"half_size\": 4, \"face_id\": 9,\n"
		"           \"translate\": [0, 0, -0.002]}],\n"
		" \"materials\": {\"face_ids\": {\"0\": \"shakudo\", \"1\": \"gold\",\n"
		"   \"2\": \"shibuichi-shiro\", \"3\": \"copper\", \"9\": \"urushi\"}},\n"
		" \"light\": {\"illuminant\": \"D65\", \"direction\": [1, -1, 2], \"intensity\": 1.5},\n"
		" \"environment\": {\"illuminant\": \"D65\", \"intensity\": 0.5},\n"
		" \"camera\": {\"position\": [0, -2.6, 2.2], \"look_at\": [0, 0, 0], \"fov_deg\": 35,\n"
		"            \"width\": %d, \"height\": %d},\n"
		" \"sampling\": {\"spp\": %d, \"wavelengths\": 4, \"bounces\": 4, \"seed\": 1}}\n",
		W, H, spp);
	if (!ret)
		ret = write_scene("tsuba.json", text, tsuba_path, sizeof(tsuba_path));
	kg_scene *sphere = NULL, *tsuba = NULL;
	kg_err err;
	if (!ret && (kg_scene_load(sphere_path, &sphere, &err) ||
	             kg_scene_load(tsuba_path, &tsuba, &err))) {
		fprintf(stderr, "kogei-bench-render: %s\n", err.msg);
		ret = -1;
	}
	char *text_buf = NULL;
	size_t text_len = 0;
	FILE *out = open_memstream(&text_buf, &text_len);
	if (!out)
		ret = -1;
	if (!ret) {
		const kg_mesh *m = kg_scene_mesh(sphere);
		time_t now = time(NULL);
		char date[32];
		strftime(date, sizeof(date), "%Y-%m-%d %H:%M UTC", gmtime(&now));
		fprintf(out, "# kogei-bench-render: Embree BVH build, ray rates, a 1080p render\n\n");
		fprintf(out, "Command: `kogei-bench-render%s%s%s`  \n", quick ? " --quick" : "",
		        report ? " -o " : "", report ? report : "");
		fprintf(out, "Run: %s, %ld online CPUs, Embree %d.%d.%d; median of %d run%s.\n\n",
		        date, sysconf(_SC_NPROCESSORS_ONLN), RTC_VERSION_MAJOR, RTC_VERSION_MINOR,
		        RTC_VERSION_PATCH, reps, reps == 1 ? "" : "s");
		fprintf(out, "## How to read\n\n"
		        "- Mesh: the icosphere of level 8 (%zu triangles, %zu vertices), radius 1, "
		        "seen from 3 units at a vertical field of view of 45 deg, %d x %d; the "
		        "sphere covers the fraction of the image in the last column.\n"
		        "- **BVH build**: kg_render's Embree scene build (vertex copy, build quality "
		        "medium) with the Embree device limited to that many threads.\n"
		        "- **path-traced rays**: closest-hit and shadow rays per second of a full "
		        "render (gold, D65 light and environment, 1 spp, 4 wavelengths, 4 bounces).\n"
		        "- **camera rays, renderer**: kg_render in preview mode (16-ray packets "
		        "with per-sample seeding, jitter, N.V shading and output) beside "
		        "**rtcIntersect16 raw**: the same mesh, camera and thread count, "
		        "pixel-centre 4 x 4 packets and nothing else, in the same run; "
		        "**camera / raw** is their ratio.\n"
		        "- **Path tracing by depth**: the demo scene of the last table (a convex "
		        "sphere sends no ray past its first bounce) at 1 spp, 4 bounces, as the "
		        "renderer counts it (kg_render_stats): at depth d, the closest-hit rays of "
		        "depth d (0: the camera's) and the shadow rays from their hits; the time "
		        "is the workers' time on them, their shading and the choice of the next "
		        "direction (depth 0: making the camera rays too), divided by the thread "
		        "count (a share of the render time); rays/s = both rays over that time.\n"
		        "- The machine drifts 15-30 %% between sessions and its 2 cores may be "
		        "shared: compare numbers within one run.\n\n", m->ntris, m->nverts, W, H);
		fprintf(out, "## Rays\n\n");
		fprintf(out, "| threads | BVH build (s) | path-traced rays (M/s) | camera rays, "
		       "renderer (M/s) | rtcIntersect16 raw (M/s) | camera / raw | raw hit "
		       "fraction |\n");
		fprintf(out, "|---|---|---|---|---|---|---|\n");
	}
	for (int threads = 1; !ret && threads <= 2; threads++) {
		run_result path, prim;
		kg_render_options po = {.threads = threads, .spp = 1};
		kg_render_options pv = {.threads = threads, .spp = 1, .mode = KG_RENDER_PREVIEW};
		double raw, hit;
		if (run(sphere, &po, reps, &path) || run(sphere, &pv, reps, &prim) ||
		    raw_packet_rate(kg_scene_mesh(sphere), threads, W, H, reps, &raw, &hit)) {
			ret = -1;
			break;
		}
		fprintf(out, "| %d | %.3f | %.2f | %.2f | %.2f | %.2f | %.3f |\n", threads,
		        path.build_s, path.rays_per_s / 1e6, prim.primary_per_s / 1e6, raw / 1e6,
		        prim.primary_per_s / raw, hit);
	}
	run_result depth[3];
	for (int threads = 1; !ret && threads <= 2; threads++) {
		kg_render_options po = {.threads = threads, .spp = 1, .bounces = MAX_BOUNCE};
		ret = run(tsuba, &po, reps, &depth[threads]);
	}
	if (!ret) {
		fprintf(out, "\n## Path tracing by depth\n\nThe demo scene of the render-time "
		        "table below at %d x %d, 1 spp, %d bounces; M = 10^6 rays.\n\n", W, H,
		        MAX_BOUNCE);
		fprintf(out, "| threads | depth | closest-hit rays (M) | shadow rays (M) | time (s) | "
		        "M rays/s |\n");
		fprintf(out, "|---|---|---|---|---|---|\n");
		for (int threads = 1; threads <= 2; threads++) {
			const kg_render_stats *st = &depth[threads].st;
			for (int d = 0; d <= MAX_BOUNCE; d++) {
				double closest = (double)st->depth_rays[d];
				double shadow = d < MAX_BOUNCE ? (double)st->depth_shadow_rays[d] : 0.0;
				double t = st->depth_s[d] / threads;
				fprintf(out, "| %d | %d%s | %.3f | %.3f | %.3f | %.2f |\n", threads, d,
				        d ? "" : " (camera)", closest / 1e6, shadow / 1e6, t,
				        t > 0.0 ? (closest + shadow) / t / 1e6 : 0.0);
			}
			fprintf(out, "| %d | all | %.3f | %.3f | %.3f | %.2f |\n", threads,
			        (double)st->rays / 1e6, (double)st->shadow_rays / 1e6, st->render_s,
			        (double)(st->rays + st->shadow_rays) / st->render_s / 1e6);
		}
	}
	if (!ret) {
		run_result r;
		kg_render_options o = {.threads = 2};
		if (run(tsuba, &o, 1, &r) == 0) {
			const kg_mesh *m = kg_scene_mesh(tsuba);
			fprintf(out, "\n## Render time\n\nThe demo object (tsuba, 256 segments) on a "
			        "ground plane, five materials, D65 light and environment.\n\n");
			fprintf(out, "| render | triangles | size | spp | wavelengths/path | bounces | "
			       "threads | BVH (s) | time (s) | rays + shadow rays (M/s) |\n");
			fprintf(out, "|---|---|---|---|---|---|---|---|---|---|\n");
			fprintf(out, "| tsuba + ground plane | %zu | %d x %d | %d | %d | %d | %d | %.3f | %.2f | "
			       "%.2f |\n", m->ntris, r.st.width, r.st.height, r.st.spp,
			       r.st.wavelengths, r.st.bounces, r.st.threads, r.build_s, r.render_s,
			       r.rays_per_s / 1e6);
		} else {
			ret = -1;
		}
	}
	if (out && fclose(out) == 0 && !ret) {
		fputs(text_buf, stdout);
		kg_outfile o;
		if (report && (kg_outfile_open(&o, report, 0, &err) ||
		               (fputs(text_buf, o.fp), kg_outfile_commit(&o, &err)))) {
			fprintf(stderr, "kogei-bench-render: %s\n", err.msg);
			ret = -1;
		}
	}
	free(text_buf);
	kg_scene_free(&sphere);
	kg_scene_free(&tsuba);
	unlink(sphere_path);
	unlink(tsuba_path);
	rmdir(dir);
	return ret ? 1 : 0;
}
