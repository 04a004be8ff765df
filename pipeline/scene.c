/* kogei process: the render scene of an object capture (kogei-scene/1, docs/render.md).
 *
 * The camera's pose comes from the chart capture: the homography H (chart mm -> px) is
 * K [r1 r2 t] up to scale with K = [f 0 cx; 0 f cy; 0 0 1], the principal point at the
 * image centre and square pixels. The focal length follows from the two constraints
 * r1 . r2 = 0 and |r1| = |r2| (Zhang 2000, with only f unknown) in least squares; a
 * chart seen nearly face-on leaves f undetermined, and the default field of view is
 * used (said in the scene's note and as a warning). The object is taken to sit where
 * the chart sat (the camera on its stand between the two captures): a plane in the
 * chart's plane, or the mesh given, in the chart's frame (metres; x along the chart's
 * x, y against the chart's y, z towards the camera), with the label map projected from
 * that pose. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "kg_render.h"
#include "pipeline_private.h"

#define DEFAULT_VFOV_DEG 40.0
#define RENDER_MAX_SIDE 480

/* f^2 from the homography relative to the principal point, or NAN. */
static double focal_squared(const double H[9], double cx, double cy)
{
	/* columns of T H, T translating by (-cx, -cy) */
	double a[3] = {H[0] - cx * H[6], H[3] - cy * H[6], H[6]};
	double b[3] = {H[1] - cx * H[7], H[4] - cy * H[7], H[7]};
	double A1 = a[0] * b[0] + a[1] * b[1], B1 = a[2] * b[2];
	double A2 = a[0] * a[0] + a[1] * a[1] - b[0] * b[0] - b[1] * b[1],
	       B2 = a[2] * a[2] - b[2] * b[2];
	/* u = 1 / f^2: u A + B = 0 for both */
	double den = A1 * A1 + A2 * A2;
	if (!(den > 0))
		return NAN;
	double u = -(A1 * B1 + A2 * B2) / den;
	/* a perspective too weak to measure: the terms in B are tiny against A's */
	double strength = (fabs(B1) + fabs(B2)) / (fabs(A1) + fabs(A2)) * (cx * cx + cy * cy);
	if (!(u > 0) || strength < 1e-3)
		return NAN;
	return 1.0 / u;
}

static void normalise(double v[3])
{
	double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
	if (n > 0)
		v[0] /= n, v[1] /= n, v[2] /= n;
}

static void cross(const double a[3], const double b[3], double c[3])
{
	c[0] = a[1] * b[2] - a[2] * b[1];
	c[1] = a[2] * b[0] - a[0] * b[2];
	c[2] = a[0] * b[1] - a[1] * b[0];
}

/* Pose of the camera in the chart's frame (mm): centre C, viewing direction d, up u. */
typedef struct pose {
	double C[3], d[3], up[3];
	double f;        /* px */
	int f_measured;  /* from the homography, else the default field of view */
} pose;

static int pose_from_homography(const double H[9], int width, int height, pose *ps)
{
	double cx = 0.5 * width, cy = 0.5 * height;
	double f2 = focal_squared(H, cx, cy);
	ps->f_measured = isfinite(f2);
	ps->f = ps->f_measured ? sqrt(f2) : 0.5 * height / tan(0.5 * DEFAULT_VFOV_DEG * M_PI / 180);
	double m[3][3]; /* K^-1 T H, columns m1 m2 m3 */
	for (int c = 0; c < 3; c++) {
		m[0][c] = (H[c] - cx * H[6 + c]) / ps->f;
		m[1][c] = (H[3 + c] - cy * H[6 + c]) / ps->f;
		m[2][c] = H[6 + c];
	}
	double r1[3] = {m[0][0], m[1][0], m[2][0]}, r2[3] = {m[0][1], m[1][1], m[2][1]};
	double t[3] = {m[0][2], m[1][2], m[2][2]};
	double n1 = sqrt(r1[0] * r1[0] + r1[1] * r1[1] + r1[2] * r1[2]);
	double n2 = sqrt(r2[0] * r2[0] + r2[1] * r2[1] + r2[2] * r2[2]);
	if (!(n1 > 0 && n2 > 0))
		return KG_EINVAL;
	double lambda = 2.0 / (n1 + n2);
	if (t[2] * lambda < 0)
		lambda = -lambda; /* the chart is in front of the camera */
	for (int k = 0; k < 3; k++)
		r1[k] *= lambda, r2[k] *= lambda, t[k] *= lambda;
	/* nearest rotation: r1, then r2 made orthogonal to it */
	normalise(r1);
	double dot = r1[0] * r2[0] + r1[1] * r2[1] + r1[2] * r2[2];
	for (int k = 0; k < 3; k++)
		r2[k] -= dot * r1[k];
	normalise(r2);
	double r3[3];
	cross(r1, r2, r3);
	/* R = [r1 r2 r3] maps chart to camera: X_cam = R X + t; C = -R^T t */
	double R[3][3] = {{r1[0], r2[0], r3[0]}, {r1[1], r2[1], r3[1]}, {r1[2], r2[2], r3[2]}};
	for (int i = 0; i < 3; i++) {
		ps->C[i] = -(R[0][i] * t[0] + R[1][i] * t[1] + R[2][i] * t[2]);
		ps->d[i] = R[2][i];  /* R^T (0, 0, 1) */
		ps->up[i] = -R[1][i]; /* R^T (0, -1, 0): image rows run down */
	}
	return 0;
}

/* chart mm -> scene metres: x, -y, -z */
static void to_world(const double v[3], double scale, double out[3])
{
	out[0] = v[0] * scale;
	out[1] = -v[1] * scale;
	out[2] = -v[2] * scale;
}

int proc_scene_write(proc *p, const char *path, const char *labels_file, int width,
                     int height, const json_t *class_map, const char *fallback, json_t *object)
{
	pose ps;
	/* the chart's homography is for the chart capture's size; the object's map is
	 * assumed the same framing (the same camera on its stand) */
	if (pose_from_homography(p->chart_H, p->chart_width, p->chart_height, &ps))
		return kg_fail(p->err, KG_EINVAL, "capture %s: the chart's homography gives no "
		               "camera pose", p->chart->name);
	if (width != p->chart_width || height != p->chart_height)
		proc_warn(p, json_object_get(object, "warnings"),
		          "%s: its image (%dx%d) differs in size from the chart capture's (%dx%d); the "
		          "label map is projected with the chart's pose scaled to it",
		          json_string_value(json_object_get(object, "capture")), width, height,
		          p->chart_width, p->chart_height);
	double vfov = 2.0 * atan(0.5 * p->chart_height / ps.f) * 180.0 / M_PI;
	if (!ps.f_measured)
		proc_warn(p, json_object_get(object, "warnings"),
		          "%s: the chart was seen too nearly face-on to measure the focal length; the "
		          "scene assumes a vertical field of view of %.0f degrees",
		          json_string_value(json_object_get(object, "capture")), DEFAULT_VFOV_DEG);
	const double mm = 1e-3;
	double C[3], d[3], up[3], look[3];
	to_world(ps.C, mm, C);
	to_world(ps.d, 1, d);
	to_world(ps.up, 1, up);
	/* where the optical axis meets the chart's plane (z = 0) */
	double s = d[2] != 0 ? -C[2] / d[2] : NAN;
	if (!(s > 0))
		return kg_fail(p->err, KG_EINVAL, "capture %s: the camera does not look at the "
		               "chart's plane", p->chart->name);
	for (int k = 0; k < 3; k++)
		look[k] = C[k] + s * d[k];
	/* the plane covers what the camera sees of it: the image corners' rays */
	double half = 0;
	double cx = 0.5 * p->chart_width, cy = 0.5 * p->chart_height;
	double right[3];
	cross(d, up, right);
	for (int k = 0; k < 4; k++) {
		double px = (k & 1) ? p->chart_width : 0, py = (k & 2) ? p->chart_height : 0;
		double ray[3];
		for (int i = 0; i < 3; i++)
			ray[i] = d[i] * ps.f + right[i] * (px - cx) - up[i] * (py - cy);
		double sk = ray[2] < 0 ? -C[2] / ray[2] : INFINITY;
		double hx = fabs(C[0] + sk * ray[0] - look[0]), hy = fabs(C[1] + sk * ray[1] - look[1]);
		half = fmax(half, fmax(hx, hy));
	}
	double dist = sqrt((C[0] - look[0]) * (C[0] - look[0]) + (C[1] - look[1]) * (C[1] - look[1]) +
	                   (C[2] - look[2]) * (C[2] - look[2]));
	half = isfinite(half) ? fmin(half, 4 * dist) : 4 * dist;
	int segments = (width > height ? width : height) / 2;
	segments = segments < 16 ? 16 : segments > 512 ? 512 : segments;
	int rw = width, rh = height;
	if (rw > RENDER_MAX_SIDE || rh > RENDER_MAX_SIDE) {
		double k = (double)RENDER_MAX_SIDE / (rw > rh ? rw : rh);
		rw = (int)lround(rw * k), rh = (int)lround(rh * k);
	}
	json_t *mesh;
	if (p->o->mesh)
		mesh = json_pack("[{s:s}]", "ply", p->o->mesh);
	else
		mesh = json_pack("[{s:s, s:f, s:i, s:[fff]}]", "generator", "plane", "half_size", half,
		                 "segments", segments, "translate", look[0], look[1], 0.0);
	json_t *camera = json_pack("{s:[fff], s:[fff], s:[fff], s:f}", "position", C[0], C[1], C[2],
	                           "look_at", look[0], look[1], look[2], "up", up[0], up[1], up[2],
	                           "fov_deg", vfov);
	json_t *render_camera = json_deep_copy(camera);
	json_object_set_new(render_camera, "width", json_integer(rw));
	json_object_set_new(render_camera, "height", json_integer(rh));
	char note[2048];
	int regions = strcmp(labels_file, "labels.hdr") != 0;
	snprintf(note, sizeof(note),
	         "kogei process: %s's %s projected from the chart capture %s's camera pose "
	         "(%s focal length %.0f px); the object is taken to lie in the chart's plane "
	         "(%s). A compound class (a|b) renders as its first member. Pixels labelled "
	         "unknown or background, unclassified pixels and what the map does not see are "
	         "no library material: they render as %s, a Lambertian grey of reflectance "
	         "%.2f. Units: metres, the chart's frame.",
	         json_string_value(json_object_get(object, "capture")),
	         regions ? "material map (each label-map region's decided material; the pixels' "
	                   "classes are labels.hdr)"
	                 : "label map (the pixels' classes: no regions were formed)",
	         p->chart->name, ps.f_measured ? "measured" : "assumed", ps.f,
	         p->o->mesh ? "the mesh given, in that frame" : "a plane", fallback,
	         KG_SCENE_NEUTRAL_GREY_LEVEL);
	json_t *classes = json_deep_copy(class_map);
	/* the light comes from behind the camera, raised */
	double light[3] = {-d[0] + 0.3 * up[0], -d[1] + 0.3 * up[1], -d[2] + 0.3 * up[2]};
	json_t *scene = json_pack(
		"{s:s, s:s, s:o, s:{s:s, s:{s:s, s:o, s:o, s:s}}, s:{s:s, s:[fff], s:f}, "
		"s:{s:s, s:f}, s:o, s:{s:i, s:i, s:i, s:i}}",
		"format", "kogei-scene/1", "note", note, "mesh", mesh, "materials", "library",
		p->library_path, "label_map", "file", labels_file, "camera", camera, "classes", classes,
		"fallback", fallback, "light", "illuminant", "D65", "direction", light[0], light[1],
		light[2], "intensity", 1.2, "environment", "illuminant", "D65", "intensity", 0.4,
		"camera", render_camera, "sampling", "spp", 8, "wavelengths", 4, "bounces", 2, "seed",
		1);
	if (!scene)
		return kg_fail(p->err, KG_ENOMEM, "out of memory");
	int ret = kg_json_write(scene, path, p->err);
	json_decref(scene);
	return ret;
}
