/* kogei materials learn: empirical templates from photographs of reference coupons.
 *
 * Each photograph shows one coupon of a known material, taken at the station with the
 * site camera the calibration describes (same exposure as its chart). Its pixels that
 * are finite, not clipped and not dark are mapped through M2 into the reference
 * camera's space; the coupon's own pixels are those within 4 robust sigmas (1.4826 x
 * the median absolute deviation) of the median in every channel, which drops the
 * background, edges and specks; their mean and covariance are the template's view at
 * the photograph's incidence angle. The output library is the base library with a
 * "template" on each named material: camera-space matching then predicts that
 * material's reading from its coupon rather than from the published n, k. */
#include <getopt.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

#include "cli.h"
#include "kg_calib.h"

static const char usage_learn[] =
	"kogei materials learn --calib CAM.json --images A.tif,B.tif --names a,b\n"
	"                      [--angles DEG,DEG] [--materials LIB] [--force] -o OUT.json";

static const char help_learn[] =
	"\n"
	"Empirical templates from photographs of reference coupons of known alloys, taken\n"
	"at the station by the camera CAM.json calibrates (at its chart's exposure). Each\n"
	"photograph (a linear 3-channel TIFF or PNG, 0..1 scale, like kogei classify's\n"
	"input) shows one coupon; --names gives its material (one of the library's), and\n"
	"--angles the incidence angle of the view (default 0); several photographs of one\n"
	"material at different angles give a template per angle. The coupon's pixels (not\n"
	"clipped, not below 1 % of full scale, within 4 robust sigmas of the median) are\n"
	"mapped through M2 into the reference camera's space; their mean and covariance\n"
	"are the template. OUT.json is the base library (--materials, default: the bundled\n"
	"one) with a \"template\" on each named material, which camera-space matching\n"
	"(kogei classify, kogei process) prefers to the published n, k. Templates hold the\n"
	"sha256 of the reference calibration; a site calibration against another reference\n"
	"is refused with them. Exit status 1 on bad input (nothing is written), 2 on bad\n"
	"usage.";

#define MIN_COUPON_PIXELS 100

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

static double median_of(double *v, size_t n)
{
	qsort(v, n, sizeof(double), cmp_double);
	return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* The coupon's view from one photograph. */
static int learn_view(const kg_camera_calib *cam, const char *path, double mean[3],
                      double cov[9], long *pixels, kg_err *err)
{
	kg_image *img = NULL;
	int rc = kg_cli_read_photograph(path, &img, err);
	if (rc)
		return rc;
	if (img->channels != 3) {
		int channels = img->channels; /* for the message: img is freed (and NULL) first */
		kg_image_free(&img);
		return kg_fail(err, KG_EINVAL, "%s: %d channel(s): expected a 3-channel linear RGB "
		               "image (a raw frame must be demosaiced first)", path, channels);
	}
	size_t np = (size_t)img->width * img->height, m = 0;
	double *x = malloc(sizeof(double) * 3 * np), *tmp = malloc(sizeof(double) * np);
	if (!x || !tmp) {
		free(x);
		free(tmp);
		kg_image_free(&img);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	for (size_t i = 0; i < np; i++) {
		const float *p = img->data + 3 * i;
		if (!isfinite(p[0] + p[1] + p[2]) || p[0] >= 0.999f || p[1] >= 0.999f ||
		    p[2] >= 0.999f || fmaxf(p[0], fmaxf(p[1], p[2])) < 0.01f)
			continue;
		for (int a = 0; a < 3; a++)
			x[3 * m + a] = cam->M2[3 * a] * p[0] + cam->M2[3 * a + 1] * p[1] +
			               cam->M2[3 * a + 2] * p[2];
		m++;
	}
	double med[3], mad[3];
	for (int c = 0; c < 3 && m; c++) {
		for (size_t i = 0; i < m; i++)
			tmp[i] = x[3 * i + c];
		med[c] = median_of(tmp, m);
		for (size_t i = 0; i < m; i++)
			tmp[i] = fabs(x[3 * i + c] - med[c]);
		mad[c] = 1.4826 * median_of(tmp, m);
	}
	double sum[3] = {0}, sq[9] = {0};
	long k = 0;
	for (size_t i = 0; i < m; i++) {
		const double *v = x + 3 * i;
		int in = 1;
		for (int c = 0; c < 3; c++)
			in &= fabs(v[c] - med[c]) <= 4 * mad[c];
		if (!in)
			continue;
		k++;
		for (int a = 0; a < 3; a++) {
			sum[a] += v[a];
			for (int b = 0; b < 3; b++)
				sq[3 * a + b] += v[a] * v[b];
		}
	}
	free(x);
	free(tmp);
	int w = img->width, h = img->height;
	kg_image_free(&img);
	if (k < MIN_COUPON_PIXELS)
		return kg_fail(err, KG_EINVAL, "%s: %ld coupon pixels of %d x %d (not clipped, not "
		               "dark, near the median): expected at least %d", path, k, w, h,
		               MIN_COUPON_PIXELS);
	for (int a = 0; a < 3; a++)
		mean[a] = sum[a] / (double)k;
	for (int a = 0; a < 3; a++)
		for (int b = 0; b < 3; b++)
			cov[3 * a + b] = (sq[3 * a + b] - (double)k * mean[a] * mean[b]) / (double)(k - 1);
	*pixels = k;
	return 0;
}

/* Relative "nk" file paths of the base library made absolute, so the new library
 * works from any folder. */
static void absolute_nk(json_t *materials, const char *base_path)
{
	char *dir = strdup(base_path);
	if (!dir)
		return;
	char *slash = strrchr(dir, '/');
	if (slash)
		*slash = '\0';
	else
		strcpy(dir, ".");
	size_t i;
	json_t *e;
	json_array_foreach(materials, i, e) {
		json_t *nk = json_object_get(e, "nk");
		if (!json_is_string(nk) || json_string_value(nk)[0] == '/')
			continue;
		char *joined = kg_path_join(dir, json_string_value(nk));
		char *abs = joined ? realpath(joined, NULL) : NULL;
		if (abs)
			json_object_set_new(e, "nk", json_string(abs));
		free(abs);
		free(joined);
	}
	free(dir);
}

int kg_cmd_materials_learn(int argc, char **argv)
{
	const char *calib = NULL, *out = NULL, *library = "default";
	char *images_arg = NULL, *names_arg = NULL, *angles_arg = NULL;
	int force = 0;
	static const struct option opts[] = {
		{"calib", required_argument, NULL, 'C'},    {"images", required_argument, NULL, 'i'},
		{"names", required_argument, NULL, 'n'},    {"angles", required_argument, NULL, 'a'},
		{"materials", required_argument, NULL, 'M'}, {"force", no_argument, NULL, 'F'},
		{"output", required_argument, NULL, 'o'},   {"help", no_argument, NULL, 'h'},
		{0, 0, 0, 0},
	};
	int c;
	optind = 1;
	while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
		switch (c) {
		case 'C': calib = optarg; break;
		case 'i': images_arg = optarg; break;
		case 'n': names_arg = optarg; break;
		case 'a': angles_arg = optarg; break;
		case 'M': library = optarg; break;
		case 'F': force = 1; break;
		case 'o': out = optarg; break;
		case 'h': printf("usage: %s\n%s\n", usage_learn, help_learn); return KG_EXIT_OK;
		default: return kg_cli_usage_error(usage_learn, "bad option");
		}
	}
	if (optind != argc)
		return kg_cli_usage_error(usage_learn, "unexpected argument '%s'", argv[optind]);
	if (!calib || !images_arg || !names_arg || !out)
		return kg_cli_usage_error(usage_learn, "--calib, --images, --names and -o are required");
	enum { MAXV = 64 };
	char *images[MAXV], *names[MAXV], *angles_s[MAXV];
	char *ic = strdup(images_arg), *nc = strdup(names_arg),
	     *ac = angles_arg ? strdup(angles_arg) : NULL;
	int ni = -1, nn = -1, na = 0;
	if (!ic || kg_cli_split_names(ic, images, MAXV, &ni))
		ni = -1;
	if (!nc || kg_cli_split_names(nc, names, MAXV, &nn))
		nn = -1;
	if (ac && kg_cli_split_names(ac, angles_s, MAXV, &na))
		na = -1;
	double angles[MAXV];
	int bad = ni < 1 || nn != ni || (angles_arg && na != ni);
	for (int i = 0; !bad && i < ni; i++) {
		char *end = NULL;
		angles[i] = angles_arg ? strtod(angles_s[i], &end) : 0;
		if (angles_arg && (!end || end == angles_s[i] || *end || !(angles[i] >= 0 && angles[i] < 90)))
			bad = 2;
	}
	if (bad) {
		free(ic);
		free(nc);
		free(ac);
		return kg_cli_usage_error(usage_learn, bad == 2 ? "--angles %s: expected degrees in "
		                          "[0, 90), one per image" : "--images %s and --names: expected "
		                          "one material name per image, separated by commas%s",
		                          bad == 2 ? angles_arg : images_arg,
		                          bad == 2 ? "" : " (and as many --angles)");
	}
	kg_err err = {{0}};
	kg_camera_calib *cam = NULL;
	kg_material_library *lib = NULL;
	char *lib_path = NULL;
	json_t *root = NULL;
	int rc = kg_camera_load(calib, &cam, &err);
	if (!rc)
		rc = kg_material_library_resolve(library, &lib_path, &err);
	if (!rc)
		rc = kg_material_library_load(lib_path, &lib, &err);
	for (int i = 0; !rc && i < ni; i++) {
		if (!kg_material_library_find(lib, names[i]))
			rc = kg_fail(&err, KG_EINVAL, "--names: '%s' is not a material of %s", names[i],
			             lib_path);
		for (int j = 0; !rc && j < i; j++)
			if (!strcmp(names[i], names[j]) && angles[i] == angles[j])
				rc = kg_fail(&err, KG_EINVAL, "%s and %s: both views of %s at %g degrees",
				             images[j], images[i], names[i], angles[i]);
	}
	for (int i = 0; !rc && i < ni; i++)
		rc = kg_cli_check_camera(cam, calib, images[i], force, &err);
	if (!rc)
		rc = kg_json_load(lib_path, &root, &err);
	json_t *materials = root ? json_object_get(root, "materials") : NULL;
	/* the views, per material, in increasing angle */
	for (int i = 0; !rc && i < ni; i++) {
		/* learn_view fills them on success only; GCC cannot see kg_fail is nonzero */
		double mean[3] = {0}, cov[9] = {0};
		long pixels = 0;
		if ((rc = learn_view(cam, images[i], mean, cov, &pixels, &err)))
			break;
		printf("%-26s %5.1f deg  %8ld pixels  reading %.4f %.4f %.4f  sd %.4f %.4f %.4f  (%s)\n",
		       names[i], angles[i], pixels, mean[0], mean[1], mean[2], sqrt(cov[0]), sqrt(cov[4]),
		       sqrt(cov[8]), images[i]);
		size_t k;
		json_t *e = NULL, *x;
		json_array_foreach(materials, k, x)
			if (!strcmp(json_string_value(json_object_get(x, "name")) ?
			            json_string_value(json_object_get(x, "name")) : "", names[i]))
				e = x;
		json_t *t = json_object_get(e, "template");
		if (!t || json_object_get(t, "learned_now") == NULL) {
			t = json_pack("{s:s,s:s,s:[],s:b}", "reference", kg_camera_reference_sha256(cam),
			              "calibration", calib, "views", "learned_now", 1);
			json_object_set_new(e, "template", t);
		}
		json_t *views = json_object_get(t, "views"), *view = json_pack(
			"{s:f,s:[fff],s:[fffffffff],s:I,s:s}", "angle_deg", angles[i], "mean", mean[0],
			mean[1], mean[2], "cov", cov[0], cov[1], cov[2], cov[3], cov[4], cov[5], cov[6],
			cov[7], cov[8], "pixels", (json_int_t)pixels, "image", images[i]);
		size_t at = 0;
		while (at < json_array_size(views) &&
		       json_number_value(json_object_get(json_array_get(views, at), "angle_deg")) <
		           angles[i])
			at++;
		json_array_insert_new(views, at, view);
		if (json_array_size(views) > KG_TEMPLATE_MAX_VIEWS)
			rc = kg_fail(&err, KG_EINVAL, "%s: more than %d views", names[i],
			             KG_TEMPLATE_MAX_VIEWS);
	}
	if (!rc) {
		size_t k;
		json_t *x;
		json_array_foreach(materials, k, x)
			json_object_del(json_object_get(x, "template"), "learned_now");
		absolute_nk(materials, lib_path);
		char note[512];
		snprintf(note, sizeof(note), "%s with coupon templates learned by kogei materials "
		         "learn through %s", lib_path, calib);
		json_object_set_new(root, "note", json_string(note));
		if ((rc = kg_json_write(root, out, &err)) == 0) {
			/* read back: the file must load as a library */
			kg_material_library *check = NULL;
			rc = kg_material_library_load(out, &check, &err);
			kg_material_library_free(&check);
			if (rc)
				remove(out);
			else
				printf("wrote %s (%d view%s)\n", out, ni, ni == 1 ? "" : "s");
		}
	}
	json_decref(root);
	kg_material_library_free(&lib);
	free(lib_path);
	kg_camera_calib_free(&cam);
	free(ic);
	free(nc);
	free(ac);
	return rc ? kg_cli_error(&err, rc) : KG_EXIT_OK;
}
