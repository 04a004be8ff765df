/* kogei process, the master: each object's reflectance cube rendered under D50 (or
 * --master-illuminant) into --master-space as OUTDIR/<object>/master.tif, a 16-bit
 * RGB TIFF with the space's ICC profile embedded (core/icc.c, LittleCMS), and beside
 * it master_linear.tif, the same colours linear in 32-bit float, unclipped; the
 * highlights above the diffuse white counted (objects[].highlights), warned and
 * mapped (highlights.png). */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "icc.h"
#include "plot.h"
#include "kg_config.h"
#include "pipeline_private.h"

static const char *space_arg(const proc *p)
{
	return p->o->master_space ? p->o->master_space : "ecirgb-v2";
}

/* The profiles' ICC version: v2 unless --icc-version 4 (checked by proc_master_check). */
static kg_icc_version icc_version(const proc *p)
{
	kg_icc_version v = KG_ICC_V2;
	if (p->o->icc_version)
		kg_icc_version_parse(p->o->icc_version, &v, NULL);
	return v;
}

static const char *ill_arg(const proc *p)
{
	return p->o->master_illuminant ? p->o->master_illuminant : "D50";
}

int proc_master_check(proc *p)
{
	kg_icc_space s;
	kg_icc_version v;
	int ret = kg_icc_space_parse(space_arg(p), &s, p->err);
	if (ret) {
		kg_err_prefix(p->err, "--master-space: ");
		return ret;
	}
	if (p->o->icc_version && (ret = kg_icc_version_parse(p->o->icc_version, &v, p->err))) {
		kg_err_prefix(p->err, "--icc-version: ");
		return ret;
	}
	kg_illuminant *ill = NULL;
	kg_err scratch;
	int named = kg_illuminant_by_name(ill_arg(p), &ill, &scratch) == 0;
	kg_illuminant_free(&ill);
	ret = kg_illuminant_lookup(ill_arg(p), &ill, p->err);
	if (ret)
		kg_err_prefix(p->err, "--master-illuminant: ");
	else if (!named) /* a spectrum file: an input, with its sha256 */
		ret = proc_input(p, "master_illuminant", ill_arg(p), NULL);
	kg_illuminant_free(&ill);
	return ret;
}

/* The highlight map as a figure (core/plot): the object's part of the map (the box of
 * its lit pixels, enlarged when small), a title with the share and a legend of the
 * colours with their counts. */
static int highlight_figure(const kg_master_extra *x, const char *space, const char *path,
                            const char *counted, kg_err *err)
{
	static const unsigned char colours[3][3] = {{KG_MASTER_MAP_ABOVE}, {KG_MASTER_MAP_TOP},
	                                            {KG_MASTER_MAP_LOW}};
	const kg_master_stats *s = &x->stats;
	double n = s->counted > 0 ? (double)s->counted : 1;
	/* the box, 8 map pixels around it, and a whole zoom that brings it to about 600 */
	int x0 = x->box[0] - 8 > 0 ? x->box[0] - 8 : 0, y0 = x->box[1] - 8 > 0 ? x->box[1] - 8 : 0;
	int x1 = x->box[2] + 8 < x->map_w ? x->box[2] + 8 : x->map_w;
	int y1 = x->box[3] + 8 < x->map_h ? x->box[3] + 8 : x->map_h;
	if (x->box[2] <= x->box[0] || x->box[3] <= x->box[1]) {
		x0 = y0 = 0;
		x1 = x->map_w;
		y1 = x->map_h;
	}
	int bw = x1 - x0, bh = y1 - y0, zoom = 1;
	while ((zoom + 1) * bw <= 600 && (zoom + 1) * bh <= 600 && zoom < 8)
		zoom++;
	int iw = zoom * bw, ih = zoom * bh;
	unsigned char *img = malloc(3 * (size_t)iw * (size_t)ih);
	if (!img)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int yy = 0; yy < ih; yy++)
		for (int xx = 0; xx < iw; xx++)
			memcpy(img + 3 * ((size_t)yy * iw + xx),
			       x->map + 3 * ((size_t)(y0 + yy / zoom) * x->map_w + x0 + xx / zoom), 3);
	enum { margin = 20, head = 64, line = 22 };
	int width = iw + 2 * margin < 640 ? 640 : iw + 2 * margin;
	int height = head + ih + 16 + 3 * line + margin;
	kg_plot *p = NULL;
	int ret = kg_plot_new(width, height, &p, err);
	if (ret) {
		free(img);
		return ret;
	}
	kg_plot_text(p, width / 2.0, 28, 16, KG_ALIGN_CENTER, NULL,
	             "Highlights above the diffuse white: %.1f %% of the %s",
	             100 * s->above_white / n, counted);
	kg_plot_text(p, width / 2.0, 50, 12, KG_ALIGN_CENTER, NULL,
	             "Y up to %.2f (1: the perfect diffuser); grey: the master's Y, 0..1%s", s->max_y,
	             zoom > 1 ? "; enlarged" : "");
	kg_plot_image(p, (width - iw) / 2.0, head, img, iw, ih);
	free(img);
	char label[3][200];
	snprintf(label[0], sizeof(label[0]), "above the diffuse white (Y > 1), at full scale in "
	         "master.tif: %ld (%.1f %%)", s->above_white, 100 * s->above_white / n);
	snprintf(label[1], sizeof(label[1]), "a channel at full scale in master.tif, Y <= 1 "
	         "(bright, saturated): %ld (%.1f %%)", s->clipped_top - s->above_clipped,
	         100 * (s->clipped_top - s->above_clipped) / n);
	snprintf(label[2], sizeof(label[2]), "a channel below 0: outside %s's primaries, clipped: "
	         "%ld (%.1f %%)", space, s->clipped_low, 100 * s->clipped_low / n);
	for (int k = 0; k < 3; k++) {
		double y = head + ih + 16 + k * line, rgb[3];
		for (int c = 0; c < 3; c++)
			rgb[c] = colours[k][c] / 255.0;
		kg_plot_fill_rect(p, margin, y, 16, 14, rgb);
		kg_plot_text(p, margin + 24, y + 12, 12, KG_ALIGN_LEFT, NULL, "%s", label[k]);
	}
	ret = kg_plot_save_png(p, path, err);
	kg_plot_free(&p);
	return ret;
}

/* objects[].highlights: the counts of kg_master_write, as fractions of the counted
 * (lit) pixels, and the map. */
static json_t *highlights_json(const kg_master_stats *s, const char *counted, const char *map)
{
	double n = s->counted > 0 ? (double)s->counted : NAN;
	json_t *h = json_pack("{s:I, s:s, s:I, s:I, s:I, s:I, s:I}", "counted",
	                      (json_int_t)s->counted, "counted_what", counted, "above_white",
	                      (json_int_t)s->above_white, "clipped_in_master",
	                      (json_int_t)s->clipped_top, "clipped_not_above_white",
	                      (json_int_t)(s->clipped_top - s->above_clipped), "outside_primaries",
	                      (json_int_t)s->clipped_low, "band_above_one",
	                      (json_int_t)s->band_above_one);
	if (!h)
		return NULL;
	struct { const char *key; double v; } num[] = {
		{"above_white_fraction", s->above_white / n},
		{"clipped_in_master_fraction", s->clipped_top / n},
		{"band_above_one_fraction", s->band_above_one / n},
		{"max_y", s->counted ? s->max_y : NAN},
		{"max_reflectance", s->counted ? s->max_reflectance : NAN},
	};
	for (size_t i = 0; i < sizeof(num) / sizeof(num[0]); i++)
		json_object_set_new(h, num[i].key, isfinite(num[i].v) ? json_real(num[i].v)
		                                                      : json_null());
	json_object_set_new(h, "map", map ? json_string(map) : json_null());
	return h;
}

int proc_master(proc *p, const proc_capture *c, const char *dir, const char *cube,
                const unsigned char *lit, const json_t *identity, json_t *object)
{
	kg_icc_space s;
	json_t *warnings = json_object_get(object, "warnings");
	json_object_set_new(object, "master", json_null());
	json_object_set_new(object, "master_linear", json_null());
	json_object_set_new(object, "highlights", json_null());
	if (kg_icc_space_parse(space_arg(p), &s, p->err))
		return KG_EINVAL; /* checked before: not reached */
	if (s == KG_ICC_NONE)
		return 0;
	if (!kg_icc_available()) {
		proc_warn(p, warnings, "%s: no master.tif: kogei was built without LittleCMS "
		          "(-Dlcms)", c->name);
		return 0;
	}
	if (!cube || !strcmp(proc_cube_name(p), "weights")) {
		proc_warn(p, warnings, "%s: no master.tif: it is rendered from the reflectance cube, "
		          "and --cube %s writes none", c->name, proc_cube_name(p));
		return 0;
	}
	kg_illuminant *ill = NULL;
	int ret = kg_illuminant_lookup(ill_arg(p), &ill, p->err);
	char *path = ret ? NULL : kg_path_join(dir, "master.tif");
	char *lpath = ret ? NULL : kg_path_join(dir, "master_linear.tif");
	char *mpath = ret ? NULL : kg_path_join(dir, "highlights.png");
	if (!ret && (!path || !lpath || !mpath))
		ret = kg_fail(p->err, KG_ENOMEM, "out of memory");
	kg_master_extra x = {.linear_path = lpath, .map_max_side = 800};
	/* its identity: the TIFF tags and the XMP packet (identity.c) */
	char *xmp = NULL, datetime[20];
	size_t xmp_len = 0;
	kg_tiff_identity tid;
	if (!ret && identity)
		ret = proc_identity_xmp(identity, &xmp, &xmp_len, p->err);
	if (!ret)
		proc_identity_tiff(identity, xmp, xmp_len, datetime, &tid);
	if (!ret) {
		proc_progress(p, "%s: master.tif and master_linear.tif (%s, %s)", c->name,
		              kg_icc_space_description(s), ill->name);
		ret = kg_master_write(cube, ill, s, icc_version(p), path, lit, &tid, &x, p->err);
	}
	free(xmp);
	const kg_master_stats *st = &x.stats;
	const char *counted = lit ? "lit pixels" : "pixels";
	/* the map, when there is something to show */
	int mapped = !ret && x.map && (st->above_white > 0 || st->clipped > 0);
	if (mapped)
		ret = highlight_figure(&x, kg_icc_space_description(s), mpath, counted, p->err);
	if (!ret) {
		char rel[300], lrel[300], mrel[300];
		snprintf(rel, sizeof(rel), "%s/master.tif", c->name);
		snprintf(lrel, sizeof(lrel), "%s/master_linear.tif", c->name);
		snprintf(mrel, sizeof(mrel), "%s/highlights.png", c->name);
		json_object_set_new(object, "master",
		                    json_pack("{s:s, s:s, s:s, s:s, s:s, s:I, s:s}", "path", rel,
		                              "space", kg_icc_space_name(s), "profile",
		                              kg_icc_space_description(s), "illuminant", ill_arg(p),
		                              "intent", "relative colorimetric", "clipped_pixels",
		                              (json_int_t)st->clipped, "clipped_counted", counted));
		char lprof[200];
		snprintf(lprof, sizeof(lprof), "%s linear (scene-referred, diffuse white 1.0)",
		         kg_icc_space_description(s));
		json_object_set_new(object, "master_linear",
		                    json_pack("{s:s, s:s, s:s, s:s, s:s, s:s, s:f}", "path", lrel,
		                              "space", kg_icc_space_name(s), "profile", lprof,
		                              "illuminant", ill_arg(p), "sample_format",
		                              "32-bit IEEE float", "encoding",
		                              "linear, scene-referred: the diffuse white (the perfect "
		                              "diffuser under the illuminant) at 1.0, unclipped",
		                              "white", 1.0));
		json_object_set_new(object, "highlights",
		                    highlights_json(st, counted, mapped ? mrel : NULL));
		double n = st->counted > 0 ? (double)st->counted : 1;
		long top_only = st->clipped_top - st->above_clipped;
		if (st->above_white > 0)
			proc_warn(p, warnings, "%s: highlights above the diffuse white: %.1f %% of the "
			          "%s (%ld of %ld) are brighter than the perfect diffuser under %s "
			          "(Y up to %.2f): specular reflection (polished metal, glaze) or more "
			          "light on the object than on the chart, not a colour error; master.tif "
			          "holds them at full scale, master_linear.tif keeps their values (float, "
			          "diffuse white 1.0)", c->name, 100 * st->above_white / n, counted,
			          st->above_white, st->counted, ill_arg(p), st->max_y);
		if (top_only > 0)
			proc_warn(p, warnings, "%s: master.tif: %ld %s (%.1f %%) at full scale in a "
			          "channel though no brighter than the diffuse white: bright saturated "
			          "colours, above %s's white in that channel (a band's reflectance "
			          "estimate is above 1 in %.1f %% of the %s, up to %.2f); "
			          "master_linear.tif keeps them", c->name, top_only, counted,
			          100 * top_only / n, kg_icc_space_description(s),
			          100 * st->band_above_one / n, counted, st->max_reflectance);
		if (st->clipped_low > 0)
			proc_warn(p, warnings, "%s: master.tif: %ld %s outside %s (a channel below 0: "
			          "outside its primaries), clipped; master_linear.tif keeps them",
			          c->name, st->clipped_low, counted, kg_icc_space_description(s));
	}
	free(x.map);
	kg_illuminant_free(&ill);
	free(path);
	free(lpath);
	free(mpath);
	return ret;
}

/* ---- OUTDIR/camera.icc and camera.ti3 -------------------------------------------- */

static int write_bytes(const char *path, const unsigned char *buf, size_t len, kg_err *err)
{
	kg_outfile o;
	int ret = kg_outfile_open(&o, path, 0, err);
	if (ret)
		return ret;
	if (fwrite(buf, 1, len, o.fp) != len) {
		kg_outfile_abort(&o);
		return kg_fail_write(err, errno, path, "cannot write");
	}
	return kg_outfile_commit(&o, err);
}

/* ArgyllCMS's colprof input: CGATS CTI3 (COLOR_REP XYZ_RGB as its scanin writes for
 * an input device), device RGB and XYZ both 0..100; the ids as CGATS writes text
 * (kg_cgats_put). */
static int write_ti3(const char *path, char **ids, const double (*rgb)[3],
                     const double (*xyz)[3], int n, double scale, kg_err *err)
{
	static const char *const fields[7] = {"SAMPLE_ID", "RGB_R", "RGB_G", "RGB_B",
	                                      "XYZ_X",     "XYZ_Y", "XYZ_Z"};
	static const char *const keywords[][2] = {
		{"DESCRIPTOR", "Argyll Calibration Target chart information 3"},
		{"ORIGINATOR", "kogei " KG_VERSION},
		{"DEVICE_CLASS", "INPUT"},
		{"COLOR_REP", "XYZ_RGB"},
	};
	kg_cgats *cg = NULL;
	int ret = kg_cgats_new("CTI3", &cg, err);
	kg_cgats_table *t = ret ? NULL : cg->tables[0];
	for (size_t k = 0; !ret && k < sizeof(keywords) / sizeof(keywords[0]); k++)
		ret = kg_cgats_set_keyword(t, keywords[k][0], keywords[k][1], err);
	if (!ret)
		ret = kg_cgats_set_keyword_number(t, "KOGEI_RGB_SCALE", scale, err);
	if (!ret)
		ret = kg_cgats_set_keyword(t, "KOGEI_ILLUMINANT", "D50", err);
	if (!ret)
		ret = kg_cgats_set_fields(t, fields, 7, err);
	for (int i = 0; !ret && i < n; i++) {
		double v[6] = {100 * rgb[i][0], 100 * rgb[i][1], 100 * rgb[i][2],
		               100 * xyz[i][0], 100 * xyz[i][1], 100 * xyz[i][2]};
		ret = kg_cgats_add_row_numbers(t, ids[i], v, 6, err);
	}
	if (!ret)
		ret = kg_cgats_write(cg, path, err);
	kg_cgats_free(&cg);
	return ret;
}

/* CIEDE2000 (D50) of a patch through the camera profile's matrix against its XYZ. */
static double matrix_de00(const double M[9], const double rgb[3], const double xyz[3],
                          kg_xyz d50)
{
	kg_xyz f, r = {100 * xyz[0], 100 * xyz[1], 100 * xyz[2]};
	f.X = 100 * (M[0] * rgb[0] + M[1] * rgb[1] + M[2] * rgb[2]);
	f.Y = 100 * (M[3] * rgb[0] + M[4] * rgb[1] + M[5] * rgb[2]);
	f.Z = 100 * (M[6] * rgb[0] + M[7] * rgb[1] + M[8] * rgb[2]);
	return kg_ciede2000(kg_xyz_to_lab(f, d50), kg_xyz_to_lab(r, d50));
}

int proc_camera_icc(proc *p, const kg_patchset *measured)
{
	json_t *cal = p->calibration;
	json_object_set_new(cal, "camera_icc", json_null());
	if (!kg_icc_available()) {
		proc_warn(p, NULL, "no camera.icc: kogei was built without LittleCMS (-Dlcms)");
		return 0;
	}
	if (!measured || !measured->spectra) {
		proc_warn(p, NULL, "no camera.icc: it needs the chart's measured spectra (--spectra)");
		return 0;
	}
	const kg_camera_calib *cam = p->cam;
	int n = 0, ret = 0;
	double (*rgb)[3] = calloc((size_t)cam->k + 1, sizeof(*rgb));
	double (*xyz)[3] = calloc((size_t)cam->k + 1, sizeof(*xyz));
	char **ids = calloc((size_t)cam->k + 1, sizeof(char *));
	kg_illuminant *d50 = NULL;
	unsigned char *icc = NULL;
	size_t len = 0;
	char *icc_path = kg_path_join(p->stage, "camera.icc");
	char *ti3_path = kg_path_join(p->stage, "camera.ti3");
	if (!rgb || !xyz || !ids || !icc_path || !ti3_path)
		ret = kg_fail(p->err, KG_ENOMEM, "out of memory");
	if (!ret)
		ret = kg_illuminant_by_name("D50", &d50, p->err);
	kg_xyz white = {0, 0, 0}, icc_d50 = {96.42, 100, 82.49};
	if (!ret)
		white = kg_illuminant_white(d50);
	double scale = 0;
	for (int i = 0; !ret && i < cam->k; i++) {
		int j = 0;
		while (j < measured->n && strcmp(measured->ids[j], cam->ids[i]))
			j++;
		if (j == measured->n)
			continue;
		kg_xyz c = kg_bradford_adapt(kg_reflectance_to_xyz(&measured->spectra[j], d50), white,
		                             icc_d50);
		ids[n] = cam->ids[i];
		for (int ch = 0; ch < 3; ch++) {
			rgb[n][ch] = cam->rho_r[i][ch];
			if (rgb[n][ch] > scale)
				scale = rgb[n][ch];
		}
		xyz[n][0] = c.X / 100;
		xyz[n][1] = c.Y / 100;
		xyz[n][2] = c.Z / 100;
		n++;
	}
	if (!ret && (n < 3 || !(scale > 0))) {
		proc_warn(p, NULL, "no camera.icc: %d of the chart's patches have measured spectra "
		          "and camera values, expected at least 3", n);
		goto done;
	}
	for (int i = 0; i < n; i++)
		for (int ch = 0; ch < 3; ch++)
			rgb[i][ch] /= scale;
	double M[9];
	char desc[320];
	snprintf(desc, sizeof(desc), "kogei camera %s %s (linear RGB / %.6g)",
	         cam->identity.model[0] ? cam->identity.model : "camera", cam->identity.serial, scale);
	if (!ret)
		ret = kg_icc_camera_profile((const double (*)[3])rgb, (const double (*)[3])xyz, n, desc,
		                            icc_version(p), M, &icc, &len, p->err);
	if (!ret)
		ret = write_bytes(icc_path, icc, len, p->err);
	if (!ret)
		ret = write_ti3(ti3_path, ids, (const double (*)[3])rgb, (const double (*)[3])xyz, n,
		                scale, p->err);
	if (!ret) {
		/* the fit, in sample: CIEDE2000 of M rgb against the reference, D50; and held
		 * out: each patch through the matrix fitted on the others */
		double sum = 0, mx = 0, lsum = 0, lmx = 0;
		int nloo = 0;
		for (int i = 0; i < n; i++) {
			double de = matrix_de00(M, rgb[i], xyz[i], icc_d50), Ml[9];
			sum += de;
			mx = de > mx ? de : mx;
			kg_err le;
			if (n > 3 && !kg_icc_camera_matrix((const double (*)[3])rgb,
			                                   (const double (*)[3])xyz, n, i, Ml, &le)) {
				de = matrix_de00(Ml, rgb[i], xyz[i], icc_d50);
				lsum += de;
				lmx = de > lmx ? de : lmx;
				nloo++;
			}
		}
		json_object_set_new(cal, "camera_icc",
		                    json_pack("{s:s, s:i, s:s, s:i, s:f, s:[fffffffff], s:f, s:f}",
		                              "path", "camera.icc", "icc_version", (int)icc_version(p),
		                              "ti3", "camera.ti3", "patches", n,
		                              "rgb_scale", scale, "matrix", M[0], M[1], M[2], M[3], M[4],
		                              M[5], M[6], M[7], M[8], "fit_de00_mean", sum / n,
		                              "fit_de00_max", mx));
		json_t *ci = json_object_get(cal, "camera_icc");
		json_object_set_new(ci, "loo_de00_mean", nloo == n ? json_real(lsum / n) : json_null());
		json_object_set_new(ci, "loo_de00_max", nloo == n ? json_real(lmx) : json_null());
		proc_progress(p, "camera input profile: %s/camera.icc (%d patches, in-sample dE00 "
		              "mean %.2f, max %.2f; leave-one-out mean %.2f, max %.2f)", p->o->outdir,
		              n, sum / n, mx, nloo ? lsum / nloo : NAN, lmx);
	}
done:
	kg_illuminant_free(&d50);
	free(rgb);
	free(xyz);
	free(ids);
	free(icc);
	free(icc_path);
	free(ti3_path);
	return ret;
}
