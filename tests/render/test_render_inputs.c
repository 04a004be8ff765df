/* The scene's inputs reach the image:
 *  - a PLY mesh (path relative to the scene) with per-face and per-vertex material
 *    ids: the upper half of a sphere in gold, the lower in silver, each half matching
 *    (CIEDE2000 < 1) the same view of the sphere rendered in that material alone;
 *  - a label map (ENVI classification) projected from a camera: left half gold, right
 *    half copper, seen from the label camera; seen from behind, the hidden triangles
 *    take the fallback (silver);
 *  - an environment image: a texel (1, 1, 1) is the environment's illuminant itself
 *    (the image of a uniform white map equals the uniform environment's within 1e-5),
 *    and a saturated texel seen directly comes back as the same linear sRGB within
 *    0.002 (the RGB upsampling reproduces the texel's XYZ exactly; the tolerance
 *    covers float rounding). */
#include "render_test.h"

#define DE_TOL 1.0

static kg_lab lab_of(const kg_image *img, kg_xyz white, int x0, int y0, int x1, int y1)
{
	return kg_xyz_to_lab(render_test_mean(img, x0, y0, x1, y1), white);
}

/* A region of two renders of the same view agree within DE_TOL. */
static void check_same(const char *what, const kg_image *a, const kg_image *b, kg_xyz white,
                       int x0, int y0, int x1, int y1)
{
	double de = kg_ciede2000(lab_of(a, white, x0, y0, x1, y1), lab_of(b, white, x0, y0, x1, y1));
	printf("%-44s dE00 %.3f\n", what, de);
	CHECK(de < DE_TOL, "%s: dE00 %.3f >= %g", what, de, DE_TOL);
}

static const char camera_front[] =
	"\"camera\": {\"position\": [0, -4, 0], \"look_at\": [0, 0, 0], \"fov_deg\": 32, "
	"\"width\": 32, \"height\": 32}";
static const char camera_back[] =
	"\"camera\": {\"position\": [0, 4, 0], \"look_at\": [0, 0, 0], \"fov_deg\": 32, "
	"\"width\": 32, \"height\": 32}";
static const char lights[] =
	"\"light\": {\"illuminant\": \"D65\", \"direction\": [0, -1, 0]},\n"
	"\"environment\": {\"illuminant\": \"D65\", \"intensity\": 0.5},\n"
	"\"sampling\": {\"spp\": 32, \"wavelengths\": \"all\", \"seed\": 2}";

static kg_image *render_uniform(const char *camera, const char *material, kg_xyz *white)
{
	char path[512];
	render_test_write(path, sizeof(path), "uniform.json",
	                  "{\"format\": \"kogei-scene/1\", \"mesh\": \"ball.ply\",\n"
	                  "\"materials\": {\"material\": \"%s\"},\n%s,\n%s}\n", material, camera,
	                  lights);
	return render_test_render(path, NULL, NULL, white);
}

static void check_ply_ids(void)
{
	kg_err err;
	kg_mesh *m = NULL;
	if (kg_mesh_icosphere(3, &m, &err)) {
		CHECK(0, "%s", err.msg);
		return;
	}
	/* ids 5 above z = 0, 7 below, for faces and vertices */
	if (!(m->tri_material = malloc(sizeof(int32_t) * m->ntris)) ||
	    !(m->vert_material = malloc(sizeof(int32_t) * m->nverts))) {
		CHECK(0, "out of memory");
		return;
	}
	for (size_t v = 0; v < m->nverts; v++)
		m->vert_material[v] = m->pos[3 * v + 2] >= 0.0f ? 5 : 7;
	for (size_t t = 0; t < m->ntris; t++) {
		float z = 0.0f;
		for (int k = 0; k < 3; k++)
			z += m->pos[3 * m->tri[3 * t + k] + 2];
		m->tri_material[t] = z >= 0.0f ? 5 : 7;
	}
	char ply[512];
	snprintf(ply, sizeof(ply), "%s/ball.ply", render_test_dir);
	int ret = kg_ply_write(m, ply, &err);
	kg_mesh_free(&m);
	CHECK(ret == 0, "%s", err.msg);
	if (ret)
		return;
	kg_xyz white;
	kg_image *gold = render_uniform(camera_front, "gold", &white);
	kg_image *silver = render_uniform(camera_front, "silver", NULL);
	static const char *const modes[] = {"face_ids", "vertex_ids"};
	for (int i = 0; i < 2; i++) {
		char path[512], what[64];
		render_test_write(path, sizeof(path), "ids.json",
		                  "{\"format\": \"kogei-scene/1\", \"mesh\": \"ball.ply\",\n"
		                  "\"materials\": {\"%s\": {\"5\": \"gold\", \"7\": \"silver\"}},\n"
		                  "%s,\n%s}\n", modes[i], camera_front, lights);
		kg_image *img = render_test_render(path, NULL, NULL, NULL);
		snprintf(what, sizeof(what), "PLY %s: upper half as gold", modes[i]);
		check_same(what, img, gold, white, 10, 4, 22, 12);
		snprintf(what, sizeof(what), "PLY %s: lower half as silver", modes[i]);
		check_same(what, img, silver, white, 10, 20, 22, 28);
		kg_image_free(&img);
	}
	kg_image_free(&gold);
	kg_image_free(&silver);
}

static void check_label_map(void)
{
	enum { W = 64, H = 64 };
	static float labels[W * H];
	for (int y = 0; y < H; y++)
		for (int x = 0; x < W; x++)
			labels[y * W + x] = x < W / 2 ? 1.0f : 2.0f;
	static const char *const names[] = {"Unclassified", "gold", "copper"};
	kg_envi_meta meta = {.samples = W, .lines = H, .bands = 1, .data_type = KG_ENVI_U8,
	                     .classes = 3, .class_names = names};
	char hdr[512], path[512];
	snprintf(hdr, sizeof(hdr), "%s/labels.hdr", render_test_dir);
	kg_err err;
	int ret = kg_envi_write(hdr, &meta, KG_LAYOUT_BIP, labels, &err);
	CHECK(ret == 0, "%s", err.msg);
	if (ret)
		return;
	static const char *const cameras[] = {camera_front, camera_back};
	for (int c = 0; c < 2; c++) {
		render_test_write(path, sizeof(path), "labels.json",
		                  "{\"format\": \"kogei-scene/1\", \"mesh\": \"ball.ply\",\n"
		                  "\"materials\": {\"label_map\": {\"file\": \"labels.hdr\",\n"
		                  "  \"camera\": {\"position\": [0, -4, 0], \"look_at\": [0, 0, 0],\n"
		                  "             \"fov_deg\": 32},\n"
		                  "  \"fallback\": \"silver\"}},\n%s,\n%s}\n", cameras[c], lights);
		kg_image *img = render_test_render(path, NULL, NULL, NULL);
		kg_xyz white;
		if (c == 0) {
			kg_image *gold = render_uniform(cameras[c], "gold", &white);
			kg_image *copper = render_uniform(cameras[c], "copper", NULL);
			check_same("label map: left half as gold", img, gold, white, 4, 10, 13, 22);
			check_same("label map: right half as copper", img, copper, white, 19, 10, 28,
			           22);
			kg_image_free(&gold);
			kg_image_free(&copper);
		} else {
			kg_image *silver = render_uniform(cameras[c], "silver", &white);
			check_same("label map: hidden side as the fallback", img, silver, white, 6, 6,
			           26, 26);
			kg_image_free(&silver);
		}
		kg_image_free(&img);
	}
}

static void check_environment_image(void)
{
	enum { W = 64, H = 32 };
	static const float sky[3] = {0.2f, 0.4f, 1.0f}, ground[3] = {1.0f, 0.5f, 0.2f};
	kg_image *env = NULL, *ones = NULL;
	kg_err err;
	if (kg_image_new(W, H, 3, &env, &err) || kg_image_new(W, H, 3, &ones, &err)) {
		CHECK(0, "%s", err.msg);
		return;
	}
	for (int i = 0; i < W * H; i++)
		for (int k = 0; k < 3; k++) {
			env->data[3 * i + k] = i < W * H / 2 ? sky[k] : ground[k];
			ones->data[3 * i + k] = 1.0f;
		}
	char sky_path[512], ones_path[512], path[512];
	snprintf(sky_path, sizeof(sky_path), "%s/sky.tif", render_test_dir);
	snprintf(ones_path, sizeof(ones_path), "%s/ones.tif", render_test_dir);
	int ret = kg_image_write_tiff(env, sky_path, 32, &err);
	if (!ret)
		ret = kg_image_write_tiff(ones, ones_path, 32, &err);
	kg_image_free(&env);
	kg_image_free(&ones);
	CHECK(ret == 0, "%s", err.msg);
	if (ret)
		return;

	/* a white map is the uniform environment */
	static const char *const envs[] = {"\"image\": \"ones.tif\", ", ""};
	kg_image *img[2];
	for (int i = 0; i < 2; i++) {
		render_test_write(path, sizeof(path), "env.json",
		                  "{\"format\": \"kogei-scene/1\", \"mesh\": \"ball.ply\",\n"
		                  "\"materials\": {\"material\": \"copper\"},\n"
		                  "\"environment\": {%s\"illuminant\": \"D50\", \"intensity\": 0.7},\n"
		                  "%s,\n\"sampling\": {\"spp\": 4, \"seed\": 1}}\n", envs[i],
		                  camera_front);
		img[i] = render_test_render(path, NULL, NULL, NULL);
	}
	double worst = 0.0;
	for (size_t i = 0; i < (size_t)img[0]->width * img[0]->height * 3; i++)
		worst = fmax(worst, fabs(img[0]->data[i] - img[1]->data[i]));
	printf("%-44s largest difference %.2e\n", "white map against uniform environment", worst);
	CHECK(worst <= 1e-5, "an all-white map differs from the uniform environment by %g",
	      worst);
	kg_image_free(&img[0]);
	kg_image_free(&img[1]);

	/* texels seen directly: straight up (sky) and straight down (ground), the ball
	 * far out of view */
	static const char *const looks[] = {"[0, 0, 10]", "[0, 0, -10]"};
	for (int i = 0; i < 2; i++) {
		render_test_write(path, sizeof(path), "env.json",
		                  "{\"format\": \"kogei-scene/1\",\n"
		                  "\"mesh\": {\"ply\": \"ball.ply\", \"scale\": 0.01, "
		                  "\"translate\": [100, 0, 0]},\n"
		                  "\"materials\": {\"material\": \"gold\"},\n"
		                  "\"environment\": {\"image\": \"sky.tif\"},\n"
		                  "\"camera\": {\"position\": [0, 0, 0], \"look_at\": %s, "
		                  "\"up\": [0, 1, 0], \"fov_deg\": 20, \"width\": 8, \"height\": 8},\n"
		                  "\"sampling\": {\"spp\": 1, \"wavelengths\": \"all\"}}\n", looks[i]);
		kg_xyz white;
		kg_image *view = render_test_render(path, NULL, NULL, &white);
		kg_xyz c = render_test_mean(view, 0, 0, 8, 8);
		kg_image_free(&view);
		kg_rgb rgb = kg_xyz_to_linear_srgb((kg_xyz){100 * c.X, 100 * c.Y, 100 * c.Z},
		                                   (kg_xyz){100 * white.X, 100 * white.Y,
		                                            100 * white.Z});
		const float *want = i ? ground : sky;
		printf("%-44s RGB %.4f %.4f %.4f (texel %.2f %.2f %.2f)\n",
		       i ? "environment seen straight down" : "environment seen straight up", rgb.r,
		       rgb.g, rgb.b, (double)want[0], (double)want[1], (double)want[2]);
		CHECK(fabs(rgb.r - want[0]) <= 0.002 && fabs(rgb.g - want[1]) <= 0.002 &&
		      fabs(rgb.b - want[2]) <= 0.002, "texel (%g, %g, %g) came back as (%.4f, "
		      "%.4f, %.4f)", (double)want[0], (double)want[1], (double)want[2], rgb.r, rgb.g,
		      rgb.b);
	}
}

int main(void)
{
	render_test_init();
	check_ply_ids();
	check_label_map();
	check_environment_image();
	render_test_cleanup();
	return kg_test_done("render-inputs");
}
