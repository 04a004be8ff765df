/* `kogei render --camera`, its noise and the truth maps, end to end through the
 * program (its path is the first argument), with a synthetic camera written here
 * (Gaussian r, g, b sensitivities, 380-780 nm every 5 nm, so their values on the
 * 61-band grid are the formula's):
 *  - scale: a white Lambertian plane facing a directional light of illuminant A
 *    (the image's white set to D65, so the light and the white differ) reads
 *    --white-level 0.8 in its brightest channel and, in the others, 0.8 times
 *    sum S_c A / max_c sum S_c A, computed here from the formula and core's A
 *    (within 1 %); the same plane lit only by a uniform environment reads the same
 *    way against the environment's illuminant;
 *  - the weighted sum: a flat plate of gold, copper or shakudo lit by a D65 light in
 *    its mirror direction at 50 degrees: the ratios r/g, b/g of the camera values
 *    equal those of sum S_c D65 R(50 deg), R from optics/ (kg_material_reflectance),
 *    within 0.5 %, while the materials' own ratios differ by more than that;
 *  - the PNG is the same sRGB preview with and without --camera (byte for byte);
 *  - truth: tsuba_inlay.json (fixtures/scenes) gives a classification map with
 *    background and every library material in library order, nonzero counts for
 *    the four regions' materials and none for the others, background at the image
 *    corners and through the central hole; its angle map is NaN exactly on
 *    background, within 0..90, and on the flat plate equals the angle computed here
 *    from the camera pose by ray casting (within 0.3 degrees); the rim spans more
 *    than 40 degrees of incidence. A sphere on a ground plane marked "background":
 *    the plane's pixels (by ray casting here) are class 0, the sphere's gold. Strips
 *    of three materials whose borders cut pixel columns at a quarter: the columns
 *    take the majority's material;
 *  - noise: --noise 1000:10:12 on the white plane: the variance of noisy minus
 *    noise-free values is (v * 1000 + 10^2) / 1000^2 + q^2 / 12 within 20 %, the
 *    values are on the 12-bit grid, the same seed gives the same bytes at 1 and 2
 *    threads, another seed other bytes;
 *  - errors: --noise or --white-level without --camera, --white-level 0, a malformed
 *    --noise (usage, exit 2); a camera CSV not covering 400-700 nm, a missing camera
 *    file, a camera blind to the light, a truth map in a missing folder (exit 1, the
 *    file named): nothing written.
 * With a second argument "reference": the scale check with the Nikon D5100 of the
 * reference data (skipped, 77, when they are absent). */
#include <math.h>
#include <string.h>

#include "kg_render.h"
#include "kg_sim.h"
#include "kg_test.h"
#include "sim/sim_test_util.h"

static const char *kogei;
static char errbuf[8192];

static int run(const char *first, ...)
{
	char *argv[64];
	int n = 0;
	argv[n++] = (char *)kogei;
	argv[n++] = (char *)first;
	va_list ap;
	va_start(ap, first);
	for (char *a; n < 63 && (a = va_arg(ap, char *));)
		argv[n++] = a;
	va_end(ap);
	argv[n] = NULL;
	return sim_run(argv, errbuf, sizeof(errbuf));
}

#define RUN(...) run(__VA_ARGS__, (char *)NULL)

/* The synthetic camera's sensitivity of channel c at wl nm. */
static double sens(int c, double wl)
{
	switch (c) {
	case 0: return exp(-0.5 * pow((wl - 600) / 30.0, 2));
	case 1: return exp(-0.5 * pow((wl - 540) / 35.0, 2));
	default: return 0.7 * exp(-0.5 * pow((wl - 460) / 25.0, 2));
	}
}

static void write_camera(const char *path, int first, int last, int blind)
{
	FILE *fp = fopen(path, "w");
	if (!fp) {
		perror(path);
		exit(1);
	}
	fprintf(fp, "wavelength_nm,r,g,b\n");
	for (int wl = first; wl <= last; wl += 5)
		fprintf(fp, "%d,%.9f,%.9f,%.9f\n", wl, blind ? 0.0 : sens(0, wl),
		        blind ? 0.0 : sens(1, wl), blind ? 0.0 : sens(2, wl));
	fclose(fp);
}

/* sum over the grid of S_c(lambda) X(lambda) R(lambda) (R NULL: 1). */
static void camera_response(const kg_spectrum *x, const kg_spectrum *r, double out[3])
{
	for (int c = 0; c < 3; c++) {
		out[c] = 0.0;
		for (int i = 0; i < KG_NBANDS; i++)
			out[c] += sens(c, kg_band_nm(i)) * x->v[i] * (r ? r->v[i] : 1.0);
	}
}

static kg_image *read_image(const char *path)
{
	kg_image *img = NULL;
	kg_err err;
	if (kg_image_read(path, &img, &err) != 0) {
		fprintf(stderr, "%s\n", err.msg);
		return NULL;
	}
	return img;
}

static void mean_rgb(const kg_image *img, int x0, int y0, int x1, int y1, double m[3])
{
	m[0] = m[1] = m[2] = 0.0;
	for (int y = y0; y < y1; y++)
		for (int x = x0; x < x1; x++)
			for (int c = 0; c < 3; c++)
				m[c] += img->data[3 * ((size_t)y * (size_t)img->width + (size_t)x) + c];
	for (int c = 0; c < 3; c++)
		m[c] /= (double)(x1 - x0) * (y1 - y0);
}

static int files_equal(const char *a, const char *b)
{
	char cmd[9000];
	snprintf(cmd, sizeof(cmd), "cmp -s '%s' '%s'", a, b);
	return system(cmd) == 0;
}

static const char white_lib[] =
	"{\"format\": \"kogei-materials/1\", \"materials\": [\n"
	" {\"name\": \"white\", \"kind\": \"dielectric\", \"n\": 1.0, \"body\": 1.0,\n"
	"  \"gloss\": 0, \"mirror\": 0}]}\n";

/* A white Lambertian plane seen from above at an angle; lit by `lights` (JSON). */
static void write_white_scene(const char *path, const char *lights, int size)
{
	char text[2048];
	snprintf(text, sizeof(text),
	         "{\"format\": \"kogei-scene/1\",\n"
	         " \"mesh\": {\"generator\": \"plane\", \"half_size\": 3},\n"
	         " \"materials\": {\"library\": \"white.json\", \"material\": \"white\"},\n"
	         " %s,\n"
	         " \"camera\": {\"position\": [0, -1.5, 3], \"look_at\": [0, 0, 0],\n"
	         "            \"fov_deg\": 20, \"width\": %d, \"height\": %d,\n"
	         "            \"white\": \"D65\"},\n"
	         " \"sampling\": {\"spp\": 2, \"wavelengths\": \"all\", \"bounces\": 2,\n"
	         "              \"seed\": 5}}\n",
	         lights, size, size);
	sim_write_text(path, text);
}

/* (a) the white level against the light's spectrum. */
static void check_scale(const char *camera, int synthetic)
{
	static const struct {
		const char *lights, *illuminant, *what;
	} cases[] = {
		{"\"light\": {\"illuminant\": \"A\", \"direction\": [0, 0, 1]}", "A",
		 "light A"},
		{"\"environment\": {\"illuminant\": \"D50\", \"intensity\": 1}", "D50",
		 "environment D50"},
	};
	for (size_t k = 0; k < sizeof(cases) / sizeof(cases[0]); k++) {
		const char *scene = kg_test_path("white_scene.json"), *tif = kg_test_path("white.tif");
		write_white_scene(scene, cases[k].lights, 24);
		int rc = RUN("render", "--scene", scene, "-o", kg_test_path("white.png"), "--linear", tif,
		             "--camera", camera, "--white-level", "0.8", "--quiet");
		CHECK(rc == 0, "%s: exit %d: %s", cases[k].what, rc, errbuf);
		kg_image *img = rc == 0 ? read_image(tif) : NULL;
		CHECK(img != NULL, "%s: no linear image", cases[k].what);
		if (!img)
			continue;
		double got[3], want[3];
		mean_rgb(img, 4, 4, 20, 20, got);
		kg_image_free(&img);
		kg_illuminant *ill = NULL;
		kg_err err;
		if (kg_illuminant_by_name(cases[k].illuminant, &ill, &err) != 0) {
			CHECK(0, "illuminant %s: %s", cases[k].illuminant, err.msg);
			continue;
		}
		if (synthetic) {
			camera_response(&ill->spd, NULL, want);
		} else {
			kg_sim_camera cam;
			CHECK(kg_sim_camera_load(camera, 0, &cam, &err) == 0, "%s", err.msg);
			for (int c = 0; c < 3; c++)
				want[c] = kg_spectrum_dot(&cam.sens[c], &ill->spd);
		}
		kg_illuminant_free(&ill);
		double top = fmax(want[0], fmax(want[1], want[2]));
		for (int c = 0; c < 3; c++) {
			want[c] *= 0.8 / top;
			char what[128];
			snprintf(what, sizeof(what), "%s: white plane, channel %d", cases[k].what, c);
			CHECK_NEAR(got[c], want[c], 0.01 * want[c], what);
		}
		printf("scale, %s: white plane reads %.4f %.4f %.4f, expected %.4f %.4f %.4f\n",
		       cases[k].what, got[0], got[1], got[2], want[0], want[1], want[2]);
	}
}

/* (b) a flat plate of a library metal in the mirror direction of a D65 light. */
static void check_metal_ratios(const char *camera)
{
	static const char *const metals[] = {"gold", "copper", "shakudo"};
	const double theta = 50.0 * M_PI / 180.0;
	double ratio[3][2];
	kg_material_library *lib = NULL;
	char *lib_path = NULL;
	kg_err err;
	kg_illuminant *d65 = NULL;
	if (kg_material_library_resolve("default", &lib_path, &err) != 0 ||
	    kg_material_library_load(lib_path, &lib, &err) != 0 ||
	    kg_illuminant_by_name("D65", &d65, &err) != 0) {
		CHECK(0, "%s", err.msg);
		free(lib_path);
		kg_material_library_free(&lib);
		return;
	}
	for (int m = 0; m < 3; m++) {
		char text[2048];
		const char *scene = kg_test_path("plate.json"), *tif = kg_test_path("plate.tif");
		double d = 5.0;
		snprintf(text, sizeof(text),
		         "{\"format\": \"kogei-scene/1\",\n"
		         " \"mesh\": {\"generator\": \"plane\", \"half_size\": 2},\n"
		         " \"materials\": {\"material\": \"%s\"},\n"
		         " \"light\": {\"illuminant\": \"D65\", \"direction\": [0, %.17g, %.17g]},\n"
		         " \"camera\": {\"position\": [0, %.17g, %.17g], \"look_at\": [0, 0, 0],\n"
		         "            \"fov_deg\": 2, \"width\": 16, \"height\": 16},\n"
		         " \"sampling\": {\"spp\": 2, \"wavelengths\": \"all\", \"bounces\": 1}}\n",
		         metals[m], sin(theta), cos(theta), -d * sin(theta), d * cos(theta));
		sim_write_text(scene, text);
		int rc = RUN("render", "--scene", scene, "-o", kg_test_path("plate.png"), "--linear", tif,
		             "--camera", camera, "--quiet");
		CHECK(rc == 0, "plate %s: exit %d: %s", metals[m], rc, errbuf);
		kg_image *img = rc == 0 ? read_image(tif) : NULL;
		if (!img) {
			CHECK(0, "plate %s: no image", metals[m]);
			continue;
		}
		double got[3], want[3];
		mean_rgb(img, 6, 6, 10, 10, got);
		kg_image_free(&img);
		kg_spectrum r;
		const kg_material *mat = kg_material_library_find(lib, metals[m]);
		CHECK(mat && kg_material_reflectance(mat, theta, &r, &err) == 0, "%s: reflectance",
		      metals[m]);
		if (!mat)
			continue;
		camera_response(&d65->spd, &r, want);
		CHECK(got[1] > 0.01, "plate %s: lit (g %.4f)", metals[m], got[1]);
		double rg = got[0] / got[1], bg = got[2] / got[1];
		double wrg = want[0] / want[1], wbg = want[2] / want[1];
		char what[128];
		snprintf(what, sizeof(what), "%s plate at 50 degrees: r/g", metals[m]);
		CHECK_NEAR(rg, wrg, 0.005 * wrg, what);
		snprintf(what, sizeof(what), "%s plate at 50 degrees: b/g", metals[m]);
		CHECK_NEAR(bg, wbg, 0.005 * wbg, what);
		ratio[m][0] = wrg;
		ratio[m][1] = wbg;
		printf("plate %s: r/g %.5f (expected %.5f), b/g %.5f (expected %.5f)\n", metals[m],
		       rg, wrg, bg, wbg);
	}
	/* the check can tell the materials apart: each differs from the others by more
	 * than the tolerance */
	for (int a = 0; a < 3; a++)
		for (int b = a + 1; b < 3; b++)
			CHECK(fabs(ratio[a][0] / ratio[b][0] - 1.0) > 0.005 ||
			      fabs(ratio[a][1] / ratio[b][1] - 1.0) > 0.005,
			      "%s and %s have the same ratios within the tolerance", metals[a],
			      metals[b]);
	kg_illuminant_free(&d65);
	kg_material_library_free(&lib);
	free(lib_path);
}

/* The PNG is the XYZ preview whether or not a camera is given. */
static void check_png_unchanged(const char *camera, const char *src)
{
	char scene[4200];
	snprintf(scene, sizeof(scene), "%s/fixtures/scenes/tsuba_inlay.json", src);
	const char *a = kg_test_path("xyz.png"), *b = kg_test_path("cam.png");
	int rc = RUN("render", "--scene", scene, "--width", "64", "--height", "48", "--spp", "2",
	             "--wavelengths", "4", "-o", a, "--quiet");
	CHECK(rc == 0, "tsuba_inlay without camera: exit %d: %s", rc, errbuf);
	rc = RUN("render", "--scene", scene, "--width", "64", "--height", "48", "--spp", "2",
	         "--wavelengths", "4", "-o", b, "--camera", camera, "--noise", "1000:5:8",
	         "--linear", kg_test_path("cam.tif"), "--quiet");
	CHECK(rc == 0, "tsuba_inlay with camera: exit %d: %s", rc, errbuf);
	CHECK(files_equal(a, b), "the PNG changes with --camera");
	unlink(a);
	unlink(b);
	unlink(kg_test_path("cam.tif"));
}

/* ---- truth ------------------------------------------------------------------- */

typedef struct pose {
	double pos[3], fwd[3], right[3], up[3], tan_half;
	int width, height;
} pose;

static void normalize(double v[3])
{
	double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
	for (int i = 0; i < 3; i++)
		v[i] /= n;
}

/* A pinhole from position, look_at, vertical fov and +z up, as docs/render.md says. */
static void make_pose(pose *p, const double pos[3], const double look[3], double fov_deg,
                      int width, int height)
{
	memcpy(p->pos, pos, sizeof(p->pos));
	for (int i = 0; i < 3; i++)
		p->fwd[i] = look[i] - pos[i];
	normalize(p->fwd);
	const double z[3] = {0, 0, 1};
	p->right[0] = p->fwd[1] * z[2] - p->fwd[2] * z[1];
	p->right[1] = p->fwd[2] * z[0] - p->fwd[0] * z[2];
	p->right[2] = p->fwd[0] * z[1] - p->fwd[1] * z[0];
	normalize(p->right);
	p->up[0] = p->right[1] * p->fwd[2] - p->right[2] * p->fwd[1];
	p->up[1] = p->right[2] * p->fwd[0] - p->right[0] * p->fwd[2];
	p->up[2] = p->right[0] * p->fwd[1] - p->right[1] * p->fwd[0];
	p->tan_half = tan(fov_deg * M_PI / 360.0);
	p->width = width;
	p->height = height;
}

/* The unit direction through the pixel position (x, y) (pixel centres at + 0.5). */
static void pixel_ray(const pose *p, double x, double y, double d[3])
{
	double aspect = (double)p->width / p->height;
	double px = (2.0 * x / p->width - 1.0) * p->tan_half * aspect;
	double py = (1.0 - 2.0 * y / p->height) * p->tan_half;
	for (int i = 0; i < 3; i++)
		d[i] = p->fwd[i] + px * p->right[i] + py * p->up[i];
	normalize(d);
}

/* The pixel a world point projects to. */
static void project(const pose *p, const double w[3], double *x, double *y)
{
	double d[3] = {w[0] - p->pos[0], w[1] - p->pos[1], w[2] - p->pos[2]};
	double zc = d[0] * p->fwd[0] + d[1] * p->fwd[1] + d[2] * p->fwd[2];
	double xc = (d[0] * p->right[0] + d[1] * p->right[1] + d[2] * p->right[2]) / zc;
	double yc = (d[0] * p->up[0] + d[1] * p->up[1] + d[2] * p->up[2]) / zc;
	double aspect = (double)p->width / p->height;
	*x = (xc / (p->tan_half * aspect) + 1.0) * 0.5 * p->width;
	*y = (1.0 - yc / p->tan_half) * 0.5 * p->height;
}

typedef struct envi_map {
	kg_envi *e;
	float *v;
	int w, h;
} envi_map;

static int read_map(const char *path, envi_map *m)
{
	kg_err err;
	memset(m, 0, sizeof(*m));
	if (kg_envi_open(path, &m->e, &err) != 0) {
		fprintf(stderr, "%s\n", err.msg);
		return -1;
	}
	m->w = m->e->meta.samples;
	m->h = m->e->meta.lines;
	m->v = malloc(sizeof(float) * (size_t)m->w * (size_t)m->h * (size_t)m->e->meta.bands);
	if (!m->v || kg_envi_read(m->e, 0, 0, m->w, m->h, KG_LAYOUT_BIP, m->v, &err) != 0) {
		fprintf(stderr, "%s: %s\n", path, m->v ? err.msg : "out of memory");
		return -1;
	}
	return 0;
}

static void free_map(envi_map *m)
{
	kg_envi_close(&m->e);
	free(m->v);
}

static void check_truth_inlay(const char *camera, const char *src)
{
	char scene[4200];
	snprintf(scene, sizeof(scene), "%s/fixtures/scenes/tsuba_inlay.json", src);
	const char *labels = kg_test_path("labels.hdr"), *angle = kg_test_path("angle.hdr");
	int rc = RUN("render", "--scene", scene, "--width", "200", "--height", "150", "--spp",
	             "4", "-o", kg_test_path("inlay.png"), "--linear", kg_test_path("inlay.tif"),
	             "--camera", camera, "--truth-labels", labels, "--truth-angle", angle,
	             "--quiet");
	CHECK(rc == 0, "tsuba_inlay: exit %d: %s", rc, errbuf);
	if (rc)
		return;
	/* the scene's pose, read from the file */
	json_t *root = NULL;
	kg_err err;
	double pos[3], look[3], fov;
	if (kg_json_load(scene, &root, &err) != 0 ||
	    kg_json_get_numbers(scene, root, "camera.position", 3, pos, &err) != 0 ||
	    kg_json_get_numbers(scene, root, "camera.look_at", 3, look, &err) != 0 ||
	    kg_json_get_number(scene, root, "camera.fov_deg", &fov, &err) != 0) {
		CHECK(0, "%s", err.msg);
		json_decref(root);
		return;
	}
	json_decref(root);
	pose p;
	make_pose(&p, pos, look, fov, 200, 150);

	envi_map lm, am;
	if (read_map(labels, &lm) != 0 || read_map(angle, &am) != 0) {
		CHECK(0, "cannot read the truth maps");
		return;
	}
	const kg_envi_meta *meta = &lm.e->meta;
	CHECK(lm.w == 200 && lm.h == 150 && am.w == 200 && am.h == 150, "map sizes");
	CHECK(meta->data_type == KG_ENVI_U8 && meta->bands == 1, "labels: uint8, one band");
	CHECK(am.e->meta.data_type == KG_ENVI_F32 && am.e->meta.bands == 1,
	      "angle: float32, one band");
	/* classes: background, then the library in its order */
	kg_material_library *lib = NULL;
	char *lib_path = NULL;
	if (kg_material_library_resolve("default", &lib_path, &err) != 0 ||
	    kg_material_library_load(lib_path, &lib, &err) != 0) {
		CHECK(0, "%s", err.msg);
		free(lib_path);
		free_map(&lm);
		free_map(&am);
		return;
	}
	int nlib = kg_material_library_count(lib);
	CHECK(meta->classes == nlib + 1, "%d classes, expected %d", meta->classes, nlib + 1);
	CHECK(meta->class_names && strcmp(meta->class_names[0], "background") == 0,
	      "class 0 is background");
	CHECK(meta->class_lookup != NULL, "the map has lookup colours");
	for (int i = 0; meta->class_names && i < nlib && i + 1 < meta->classes; i++)
		CHECK(strcmp(meta->class_names[i + 1], kg_material_library_get(lib, i)->name) == 0,
		      "class %d is '%s', expected '%s'", i + 1, meta->class_names[i + 1],
		      kg_material_library_get(lib, i)->name);
	long count[256] = {0};
	int bad = 0, nan_ok = 1;
	for (int i = 0; i < lm.w * lm.h; i++) {
		float l = lm.v[i];
		if (!(l >= 0 && l < meta->classes)) {
			bad++;
			continue;
		}
		count[(int)l]++;
		float a = am.v[i];
		if ((l == 0) != (isnan(a) != 0) || (l != 0 && !(a >= 0.0f && a <= 90.0f)))
			nan_ok = 0;
	}
	CHECK(bad == 0, "%d labels out of range", bad);
	CHECK(nan_ok, "the angle is NaN exactly on background and 0..90 elsewhere");
	static const char *const used[] = {"shakudo", "copper", "gold", "silver"};
	long used_total = 0;
	for (int k = 0; k < 4; k++) {
		int cls = 0;
		for (int i = 0; i < nlib; i++)
			if (strcmp(kg_material_library_get(lib, i)->name, used[k]) == 0)
				cls = i + 1;
		CHECK(cls > 0 && count[cls] > 0, "no pixels of %s", used[k]);
		used_total += cls > 0 ? count[cls] : 0;
		printf("truth: %s (class %d): %ld pixels\n", used[k], cls, cls ? count[cls] : 0);
	}
	CHECK(count[0] + used_total == (long)lm.w * lm.h,
	      "pixels of materials the scene does not use: %ld",
	      (long)lm.w * lm.h - count[0] - used_total);
	CHECK(count[0] > 0 && count[0] < (long)lm.w * lm.h * 3 / 4, "background: %ld pixels",
	      count[0]);
	/* background where nothing is hit: the corners and the hole's middle */
	CHECK(lm.v[0] == 0 && lm.v[lm.w - 1] == 0 && lm.v[(lm.h - 1) * lm.w] == 0 &&
	          lm.v[lm.h * lm.w - 1] == 0,
	      "the corners are background");
	double hole[3] = {0, 0, 0.029}, hx, hy;
	project(&p, hole, &hx, &hy);
	int hi = (int)hy * lm.w + (int)hx;
	CHECK(hx >= 0 && hx < lm.w && hy >= 0 && hy < lm.h && lm.v[hi] == 0,
	      "the middle of the hole (pixel %.1f, %.1f) is background (label %g)", hx, hy,
	      hx >= 0 && hx < lm.w && hy >= 0 && hy < lm.h ? (double)lm.v[hi] : -1.0);

	/* The flat plate (z = 0.05, normal +z) away from its edges: the angle between +z and
	 * the direction to the camera from where the pixel's central ray meets z = 0.05. */
	int shakudo = 0, rim = 0;
	for (int i = 0; i < nlib; i++) {
		if (strcmp(kg_material_library_get(lib, i)->name, "shakudo") == 0)
			shakudo = i + 1;
		if (strcmp(kg_material_library_get(lib, i)->name, "copper") == 0)
			rim = i + 1;
	}
	int checked = 0;
	double worst = 0.0, rim_lo = 90.0, rim_hi = 0.0;
	for (int y = 1; y < lm.h - 1; y++)
		for (int x = 1; x < lm.w - 1; x++) {
			int i = y * lm.w + x;
			if (lm.v[i] == rim) {
				rim_lo = fmin(rim_lo, am.v[i]);
				rim_hi = fmax(rim_hi, am.v[i]);
			}
			int inside = 1;
			for (int dy = -1; dy <= 1; dy++)
				for (int dx = -1; dx <= 1; dx++)
					inside &= lm.v[i + dy * lm.w + dx] == shakudo;
			if (!inside)
				continue;
			double d[3];
			pixel_ray(&p, x + 0.5, y + 0.5, d);
			double t = (0.05 - p.pos[2]) / d[2];
			double hit[3], v[3];
			for (int k = 0; k < 3; k++) {
				hit[k] = p.pos[k] + t * d[k];
				v[k] = p.pos[k] - hit[k];
			}
			normalize(v);
			double r = hypot(hit[0], hit[1]);
			/* the plate's rings: between seppa-dai and relief, relief and rim */
			if (!((r > 0.31 && r < 0.37) || (r > 0.86 && r < 0.92)))
				continue;
			double want = acos(v[2]) * 180.0 / M_PI;
			worst = fmax(worst, fabs(am.v[i] - want));
			checked++;
		}
	CHECK(checked > 50, "only %d plate pixels to check", checked);
	CHECK(worst < 0.3, "plate incidence angle off by up to %.3f degrees", worst);
	CHECK(rim_hi - rim_lo > 40.0, "the rim spans %.1f to %.1f degrees", rim_lo, rim_hi);
	printf("truth: %d plate pixels within %.3f degrees of the ray-cast angle; rim %.1f to "
	       "%.1f degrees\n", checked, worst, rim_lo, rim_hi);
	kg_material_library_free(&lib);
	free(lib_path);
	free_map(&lm);
	free_map(&am);
}

/* A gold sphere resting on a ground plane marked "background" (its material urushi). */
static void check_truth_background(void)
{
	const char *scene = kg_test_path("ground.json"), *labels = kg_test_path("ground.hdr");
	const double pos[3] = {0, -5, 2.5}, look[3] = {0, 0, 0.6};
	char text[2048];
	snprintf(text, sizeof(text),
	         "{\"format\": \"kogei-scene/1\",\n"
	         " \"mesh\": [{\"generator\": \"icosphere\", \"level\": 5,\n"
	         "            \"translate\": [0, 0, 1], \"face_id\": 1},\n"
	         "           {\"generator\": \"plane\", \"half_size\": 3, \"face_id\": 9,\n"
	         "            \"background\": true}],\n"
	         " \"materials\": {\"face_ids\": {\"1\": \"gold\", \"9\": \"urushi\"}},\n"
	         " \"environment\": {\"illuminant\": \"D65\"},\n"
	         " \"camera\": {\"position\": [%g, %g, %g], \"look_at\": [%g, %g, %g],\n"
	         "            \"fov_deg\": 50, \"width\": 64, \"height\": 48},\n"
	         " \"sampling\": {\"spp\": 4, \"bounces\": 1}}\n",
	         pos[0], pos[1], pos[2], look[0], look[1], look[2]);
	sim_write_text(scene, text);
	int rc = RUN("render", "--scene", scene, "-o", kg_test_path("ground.png"), "--truth-labels",
	             labels, "--preview", "--quiet");
	CHECK(rc == 0, "sphere on ground: exit %d: %s", rc, errbuf);
	envi_map lm;
	if (rc || read_map(labels, &lm) != 0) {
		CHECK(0, "cannot read %s", labels);
		return;
	}
	pose p;
	make_pose(&p, pos, look, 50, 64, 48);
	int gold = 0, urushi = 0;
	for (int c = 0; c < lm.e->meta.classes; c++) {
		if (strcmp(lm.e->meta.class_names[c], "gold") == 0)
			gold = c;
		if (strcmp(lm.e->meta.class_names[c], "urushi") == 0)
			urushi = c;
	}
	int plane_px = 0, sphere_px = 0, wrong = 0, any_urushi = 0;
	for (int y = 0; y < lm.h; y++)
		for (int x = 0; x < lm.w; x++) {
			double d[3];
			pixel_ray(&p, x + 0.5, y + 0.5, d);
			/* distance of the ray from the sphere's centre (0, 0, 1) */
			double s[3] = {-p.pos[0], -p.pos[1], 1.0 - p.pos[2]};
			double along = s[0] * d[0] + s[1] * d[1] + s[2] * d[2], miss = 0.0;
			for (int k = 0; k < 3; k++)
				miss += pow(s[k] - along * d[k], 2);
			miss = sqrt(miss);
			double t = -p.pos[2] / d[2];
			double gx = p.pos[0] + t * d[0], gy = p.pos[1] + t * d[1];
			int on_plane = t > 0 && fabs(gx) < 2.9 && fabs(gy) < 2.9;
			float l = lm.v[y * lm.w + x];
			any_urushi |= l == urushi;
			if (miss < 0.95) {
				sphere_px++;
				wrong += l != gold;
			} else if (miss > 1.05 && on_plane) {
				plane_px++;
				wrong += l != 0;
			}
		}
	CHECK(plane_px > 200 && sphere_px > 100, "%d plane and %d sphere pixels", plane_px,
	      sphere_px);
	CHECK(wrong == 0, "%d pixels of the wrong class", wrong);
	CHECK(!any_urushi, "the background part's material appears in the labels");
	printf("truth: sphere on a background plane: %d plane pixels background, %d sphere "
	       "pixels gold\n", plane_px, sphere_px);
	free_map(&lm);
}

/* Majority: planes of silver (x < 0.025), gold (0.025 < x < 0.225) and copper
 * (x > 0.225, a little above the gold) under a camera looking straight down whose
 * pixel columns are 0.1 wide from x = -0.4: column 4 is a quarter silver and takes
 * gold, column 6 is a quarter gold and takes copper (so neither the lowest nor the
 * highest class present wins by itself). 64 samples per pixel: a quarter-covered
 * pixel takes the other class with probability below 1e-5. */
static void check_truth_majority(void)
{
	const char *scene = kg_test_path("strips.json"), *labels = kg_test_path("strips.hdr");
	/* 32 rows of 0.1 (half the height 1.6) at distance 10; 8 columns: x -0.4 .. 0.4 */
	double fov = 2.0 * atan(1.6 / 10.0) * 180.0 / M_PI;
	char text[2048];
	snprintf(text, sizeof(text),
	         "{\"format\": \"kogei-scene/1\",\n"
	         " \"mesh\": [\n"
	         "  {\"generator\": \"plane\", \"half_size\": 2,\n"
	         "   \"translate\": [-1.975, 0, 0], \"face_id\": 1},\n"
	         "  {\"generator\": \"plane\", \"half_size\": 2,\n"
	         "   \"translate\": [2.025, 0, 0], \"face_id\": 2},\n"
	         "  {\"generator\": \"plane\", \"half_size\": 2,\n"
	         "   \"translate\": [2.225, 0, 0.001], \"face_id\": 3}],\n"
	         " \"materials\": {\"face_ids\": {\"1\": \"silver\", \"2\": \"gold\",\n"
	         "                             \"3\": \"copper\"}},\n"
	         " \"environment\": {\"illuminant\": \"D65\"},\n"
	         " \"camera\": {\"position\": [0, 0, 10], \"look_at\": [0, 0, 0],\n"
	         "            \"up\": [0, 1, 0],\n"
	         "            \"fov_deg\": %.17g, \"width\": 8, \"height\": 32},\n"
	         " \"sampling\": {\"spp\": 64}}\n",
	         fov);
	sim_write_text(scene, text);
	int rc = RUN("render", "--scene", scene, "-o", kg_test_path("strips.png"), "--truth-labels",
	             labels, "--preview", "--quiet");
	CHECK(rc == 0, "strips: exit %d: %s", rc, errbuf);
	envi_map lm;
	if (rc || read_map(labels, &lm) != 0) {
		CHECK(0, "cannot read %s", labels);
		return;
	}
	int cls[3] = {0, 0, 0};
	static const char *const names[3] = {"silver", "gold", "copper"};
	for (int c = 0; c < lm.e->meta.classes; c++)
		for (int k = 0; k < 3; k++)
			if (strcmp(lm.e->meta.class_names[c], names[k]) == 0)
				cls[k] = c;
	CHECK(cls[0] > cls[1] && cls[2] > cls[1], "library order: silver, gold, copper classes "
	      "%d %d %d", cls[0], cls[1], cls[2]);
	int wrong = 0;
	for (int y = 0; y < lm.h; y++)
		for (int x = 0; x < lm.w; x++)
			wrong += lm.v[y * lm.w + x] != cls[x <= 3 ? 0 : x <= 5 ? 1 : 2];
	CHECK(wrong == 0, "strips: %d pixels not of their majority material", wrong);
	free_map(&lm);
}

/* ---- noise ------------------------------------------------------------------- */

static void check_noise(const char *camera)
{
	const char *scene = kg_test_path("noise.json");
	const char *clean = kg_test_path("clean.tif"), *n1 = kg_test_path("n1.tif");
	const char *n2 = kg_test_path("n2.tif"), *n3 = kg_test_path("n3.tif");
	write_white_scene(scene, "\"light\": {\"illuminant\": \"D65\", \"direction\": [0, 0, 1]}",
	                  64);
	int rc = RUN("render", "--scene", scene, "-o", kg_test_path("n.png"), "--linear", clean,
	             "--camera", camera, "--quiet");
	CHECK(rc == 0, "noise-free: exit %d: %s", rc, errbuf);
	rc = RUN("render", "--scene", scene, "-o", kg_test_path("n.png"), "--linear", n1, "--camera",
	         camera, "--noise", "1000:10:12", "--seed", "7", "--threads", "1", "--quiet");
	CHECK(rc == 0, "noisy: exit %d: %s", rc, errbuf);
	rc = RUN("render", "--scene", scene, "-o", kg_test_path("n.png"), "--linear", n2, "--camera",
	         camera, "--noise", "1000:10:12", "--seed", "7", "--threads", "2", "--quiet");
	CHECK(rc == 0, "noisy, 2 threads: exit %d: %s", rc, errbuf);
	rc = RUN("render", "--scene", scene, "-o", kg_test_path("n.png"), "--linear", n3, "--camera",
	         camera, "--noise", "1000:10:12", "--seed", "8", "--quiet");
	CHECK(rc == 0, "noisy, seed 8: exit %d: %s", rc, errbuf);
	CHECK(files_equal(n1, n2), "the same seed gives other bytes (1 and 2 threads)");
	CHECK(!files_equal(n1, n3), "another seed gives the same bytes");
	kg_image *a = read_image(clean), *b = read_image(n1);
	if (!a || !b) {
		CHECK(0, "cannot read the noise images");
		kg_image_free(&a);
		kg_image_free(&b);
		return;
	}
	const double fw = 1000.0, rn = 10.0, q = 1.0 / 4095.0;
	int off_grid = 0;
	for (int c = 0; c < 3; c++) {
		double sum = 0.0, sum2 = 0.0, v = 0.0;
		int n = 0;
		for (int y = 8; y < 56; y++)
			for (int x = 8; x < 56; x++) {
				size_t i = 3 * ((size_t)y * 64 + (size_t)x) + (size_t)c;
				double d = (double)b->data[i] - a->data[i];
				double codes = b->data[i] * 4095.0;
				off_grid += fabs(codes - nearbyint(codes)) > 1e-3;
				sum += d;
				sum2 += d * d;
				v += a->data[i];
				n++;
			}
		v /= n;
		double mean = sum / n, var = sum2 / n - mean * mean;
		double want = (v * fw + rn * rn) / (fw * fw) + q * q / 12.0;
		printf("noise, channel %d: v %.4f, variance %.4g (model %.4g), mean offset %.2g\n",
		       c, v, var, want, mean);
		CHECK(fabs(var / want - 1.0) < 0.2, "channel %d: variance %.4g, model %.4g", c, var,
		      want);
		CHECK(fabs(mean) < 4.0 * sqrt(want / n) + q, "channel %d: noise mean %.3g", c, mean);
	}
	CHECK(off_grid == 0, "%d values off the 12-bit grid", off_grid);
	kg_image_free(&a);
	kg_image_free(&b);
}

/* ---- errors ------------------------------------------------------------------ */

static void expect_error(int rc, int code, const char *needle, int before, const char *what)
{
	CHECK(rc == code, "%s: exit %d, expected %d (%s)", what, rc, code, errbuf);
	CHECK(!needle || strstr(errbuf, needle), "%s: the message does not name '%s': %s", what,
	      needle, errbuf);
	CHECK(sim_scratch_count() == before, "%s: left %d files behind", what,
	      sim_scratch_count() - before);
}

static void check_errors(const char *camera, const char *src)
{
	char scene[4200];
	snprintf(scene, sizeof(scene), "%s/fixtures/scenes/tsuba_inlay.json", src);
	write_camera(kg_test_path("short.csv"), 420, 520, 0);
	write_camera(kg_test_path("blind.csv"), 380, 780, 1);
	int before = sim_scratch_count();
	const char *png = kg_test_path("e.png"), *tif = kg_test_path("e.tif"), *lab = kg_test_path("e.hdr");
	int rc = RUN("render", "--scene", scene, "-o", png, "--linear", tif, "--noise",
	             "1000:5:12", "--quiet");
	expect_error(rc, 2, "--noise", before, "--noise without --camera");
	rc = RUN("render", "--scene", scene, "-o", png, "--linear", tif, "--white-level", "0.5",
	         "--quiet");
	expect_error(rc, 2, "--white-level", before, "--white-level without --camera");
	rc = RUN("render", "--scene", scene, "-o", png, "--camera", camera, "--white-level", "0",
	         "--quiet");
	expect_error(rc, 2, "--white-level", before, "--white-level 0");
	rc = RUN("render", "--scene", scene, "-o", png, "--camera", camera, "--noise", "1000:5",
	         "--quiet");
	expect_error(rc, 2, "FULLWELL", before, "a bad --noise");
	rc = RUN("render", "--scene", scene, "-o", png, "--linear", tif, "--truth-labels", lab,
	         "--camera", kg_test_path("short.csv"), "--quiet");
	expect_error(rc, 1, "short.csv", before, "a camera not covering 400-700 nm");
	CHECK(strstr(errbuf, "420") && strstr(errbuf, "400-700"),
	      "the message gives the range found and the one expected: %s", errbuf);
	rc = RUN("render", "--scene", scene, "-o", png, "--linear", tif, "--camera",
	         kg_test_path("nope.csv"), "--quiet");
	expect_error(rc, 1, "nope.csv", before, "a missing camera file");
	rc = RUN("render", "--scene", scene, "-o", png, "--linear", tif, "--camera",
	         kg_test_path("blind.csv"), "--quiet");
	expect_error(rc, 1, "blind.csv", before, "a camera blind to the light");
	rc = RUN("render", "--scene", scene, "-o", png, "--truth-angle",
	         kg_test_path("no/such/dir/a.hdr"), "--quiet");
	expect_error(rc, 1, "no/such/dir", before, "a truth map in a missing folder");
}

int main(int argc, char **argv)
{
	if (argc < 2) {
		fprintf(stderr, "usage: %s KOGEI [reference]\n", argv[0]);
		return 2;
	}
	if (!kg_render_available())
		kg_test_skip("the renderer was built without Embree 3 (libembree-dev)");
	kogei = argv[1];
	const char *src = getenv("KOGEI_SOURCE_ROOT");
	if (!src || !*src)
		src = KG_SOURCE_ROOT;
	if (argc > 2 && strcmp(argv[2], "reference") == 0) {
		char nikon[4200];
		snprintf(nikon, sizeof(nikon), "%s/cameras/Nikon_D5100.csv", kg_test_reference_dir());
		if (!kg_test_file_exists(nikon))
			kg_test_skip("the Nikon D5100 sensitivities are not in the reference data");
		kg_test_scratch_dir("render-camera-ref");
		sim_write_text(kg_test_path("white.json"), white_lib);
		check_scale(nikon, 0);
		kg_test_scratch_remove();
		return kg_test_done("render-camera-reference");
	}
	kg_test_scratch_dir("render-camera");
	const char *camera = kg_test_path("camera.csv");
	char cam[4352];
	snprintf(cam, sizeof(cam), "%s", camera);
	write_camera(cam, 380, 780, 0);
	sim_write_text(kg_test_path("white.json"), white_lib);
	check_scale(cam, 1);
	check_metal_ratios(cam);
	check_png_unchanged(cam, src);
	check_truth_inlay(cam, src);
	check_truth_background();
	check_truth_majority();
	check_noise(cam);
	check_errors(cam, src);
	kg_test_scratch_remove();
	return kg_test_done("render-camera");
}
