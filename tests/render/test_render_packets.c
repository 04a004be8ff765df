/* The renderer's packets (16 camera rays per 4 x 4 block, the block's paths carried on
 * together) and its per-depth counts:
 *  - the preview is the white's reading times N.V: a unit sphere seen from 3 units
 *    gives Y = N.V of the analytic sphere at the pixel (64 jittered samples, within
 *    0.01: the spread of N.V over one pixel), 0 off the sphere, and the same bytes at
 *    1 and 2 threads;
 *  - a sphere over a plane, path traced: the same bytes at 1 and 2 threads, the same
 *    per-depth counts, their sums equal to the totals, depth 0 = the camera rays,
 *    no depth tracing more rays than the hits of the depth before it could send, and
 *    rays past the first bounce (the plane and the sphere see each other). */
#include <math.h>

#include "render_test.h"

static kg_image *render(const kg_scene *s, const kg_render_options *opt,
                        kg_render_stats *st)
{
	kg_err err = {{0}};
	kg_image *img = NULL;
	if (kg_render(s, opt, &img, st, &err)) {
		fprintf(stderr, "render: %s\n", err.msg);
		exit(1);
	}
	return img;
}

static int same_bytes(const kg_image *a, const kg_image *b)
{
	return a->width == b->width && a->height == b->height &&
	       memcmp(a->data, b->data, sizeof(float) * 3 * (size_t)a->width * a->height) == 0;
}

static kg_scene *load(const char *path)
{
	kg_err err = {{0}};
	kg_scene *s = NULL;
	if (kg_scene_load(path, &s, &err)) {
		fprintf(stderr, "%s\n", err.msg);
		exit(1);
	}
	return s;
}

static void check_preview(void)
{
	char path[512];
	const int W = 64, H = 48;
	const double fov = 40.0, dist = 3.0;
	render_test_write(path, sizeof(path), "preview.json",
		"{\"format\": \"kogei-scene/1\",\n"
		" \"mesh\": {\"generator\": \"icosphere\", \"level\": 7},\n"
		" \"materials\": {\"material\": \"gold\"},\n"
		" \"light\": {\"illuminant\": \"D65\", \"direction\": [1, -1, 1]},\n"
		" \"camera\": {\"position\": [0, -%g, 0], \"look_at\": [0, 0, 0], \"fov_deg\": %g,\n"
		"            \"width\": %d, \"height\": %d},\n"
		" \"sampling\": {\"spp\": 64, \"seed\": 3}}\n", dist, fov, W, H);
	kg_scene *s = load(path);
	kg_render_options o1 = {.threads = 1, .mode = KG_RENDER_PREVIEW};
	kg_render_options o2 = {.threads = 2, .mode = KG_RENDER_PREVIEW};
	kg_render_stats st;
	kg_image *a = render(s, &o1, &st), *b = render(s, &o2, NULL);
	kg_xyz white = kg_scene_white(s);
	CHECK(same_bytes(a, b), "preview: 1 and 2 threads differ");
	CHECK(st.depth_rays[0] == (uint64_t)W * H * 64 && st.rays == st.depth_rays[0] &&
	      st.shadow_rays == 0, "preview: %llu rays, %llu at depth 0, %llu shadow rays; "
	      "expected %d camera rays only", (unsigned long long)st.rays,
	      (unsigned long long)st.depth_rays[0], (unsigned long long)st.shadow_rays,
	      W * H * 64);
	/* the analytic sphere through each pixel centre: N.V at the first hit */
	double t = tan(fov * M_PI / 360.0), aspect = (double)W / H, worst = 0.0;
	int on = 0, off = 0;
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++) {
			double d[3] = {(2.0 * (x + 0.5) / W - 1.0) * t * aspect, 1.0,
			               (1.0 - 2.0 * (y + 0.5) / H) * t};
			double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
			for (int i = 0; i < 3; i++)
				d[i] /= n;
			/* |o + s d| = 1 with o = (0, -dist, 0) */
			double bq = -dist * d[1], cq = dist * dist - 1.0, disc = bq * bq - cq;
			double y_img = a->data[3 * ((size_t)y * W + x) + 1] / white.Y;
			if (disc < 0.3) { /* away from the silhouette only */
				if (disc < -0.1) {
					off++;
					worst = fmax(worst, fabs(y_img));
				}
				continue;
			}
			double sd = -bq - sqrt(disc), p[3] = {sd * d[0], -dist + sd * d[1], sd * d[2]};
			double nv = -(p[0] * d[0] + p[1] * d[1] + p[2] * d[2]);
			worst = fmax(worst, fabs(y_img - nv));
			on++;
		}
	printf("preview: %d pixels on the sphere, %d off it, worst |Y - N.V| %.5f\n", on, off,
	       worst);
	CHECK(on > 100 && off > 100, "preview: %d pixels on the sphere, %d off", on, off);
	CHECK(worst <= 0.01, "preview: Y differs from the analytic N.V by %.5f", worst);
	kg_image_free(&a);
	kg_image_free(&b);
	kg_scene_free(&s);
}

static void check_depths(void)
{
	char path[512];
	render_test_write(path, sizeof(path), "depths.json",
		"{\"format\": \"kogei-scene/1\",\n"
		" \"mesh\": [{\"generator\": \"icosphere\", \"level\": 4, \"translate\": [0, 0, 1]},\n"
		"          {\"generator\": \"plane\", \"half_size\": 3}],\n"
		" \"materials\": {\"material\": \"silver\"},\n"
		" \"light\": {\"illuminant\": \"D65\", \"direction\": [1, -1, 1.5]},\n"
		" \"environment\": {\"illuminant\": \"D65\", \"intensity\": 0.5},\n"
		" \"camera\": {\"position\": [0, -5, 2.5], \"look_at\": [0, 0, 0.7], \"fov_deg\": 40,\n"
		"            \"width\": 37, \"height\": 29},\n"
		" \"sampling\": {\"spp\": 8, \"wavelengths\": 4, \"bounces\": 6, \"seed\": 9}}\n");
	kg_scene *s = load(path);
	kg_render_options o1 = {.threads = 1}, o2 = {.threads = 2};
	kg_render_stats s1, s2;
	kg_image *a = render(s, &o1, &s1), *b = render(s, &o2, &s2);
	CHECK(same_bytes(a, b), "path tracing: 1 and 2 threads differ");
	uint64_t rays = 0, shadow = 0;
	int same = 1, bounded = 1;
	double secs = 0.0;
	for (int d = 0; d <= s1.bounces; d++) {
		rays += s1.depth_rays[d];
		same &= s1.depth_rays[d] == s2.depth_rays[d];
		bounded &= s1.depth_s[d] >= 0.0;
		secs += s1.depth_s[d];
		if (d < s1.bounces) {
			shadow += s1.depth_shadow_rays[d];
			same &= s1.depth_shadow_rays[d] == s2.depth_shadow_rays[d];
			/* each ray of depth d sends at most one shadow ray and one ray on */
			bounded &= s1.depth_rays[d + 1] <= s1.depth_rays[d] &&
			           s1.depth_shadow_rays[d] <= s1.depth_rays[d];
		}
		printf("depth %d: %llu rays, %llu shadow rays, %.4f s\n", d,
		       (unsigned long long)s1.depth_rays[d],
		       d < s1.bounces ? (unsigned long long)s1.depth_shadow_rays[d] : 0ULL,
		       s1.depth_s[d]);
	}
	CHECK(same, "per-depth counts differ between 1 and 2 threads");
	CHECK(bounded && secs > 0.0, "per-depth counts or times out of bounds");
	CHECK(rays == s1.rays && shadow == s1.shadow_rays, "per-depth sums %llu, %llu; totals "
	      "%llu, %llu", (unsigned long long)rays, (unsigned long long)shadow,
	      (unsigned long long)s1.rays, (unsigned long long)s1.shadow_rays);
	CHECK(s1.depth_rays[0] == 37ULL * 29 * 8 && s1.primary_rays == s1.depth_rays[0],
	      "depth 0: %llu rays, expected the %d camera rays",
	      (unsigned long long)s1.depth_rays[0], 37 * 29 * 8);
	CHECK(s1.depth_rays[2] > 0, "no ray past the first bounce between sphere and plane");
	kg_image_free(&a);
	kg_image_free(&b);
	kg_scene_free(&s);
}

int main(void)
{
	render_test_init();
	check_preview();
	check_depths();
	render_test_cleanup();
	return kg_test_done("render-packets");
}
