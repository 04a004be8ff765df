/* Images to files: LABELS.json of a classification, and its preview image. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "apply_private.h"

/* A number, or null where JSON has none (NaN, +-Inf). */
json_t *ap_json_num(double v)
{
	return isfinite(v) ? json_real(v) : json_null();
}

/* LABELS.json's format and inputs (method: the method's name, or NULL). */
void ap_labels_json_inputs(json_t *root, const kg_classify_info *info, const char *method)
{
	json_object_set_new(root, "format", json_string("kogei-labels/1"));
	const char *keys[4] = {"image", "calib", "materials", "method"};
	const char *vals[4] = {info ? info->image : NULL, info ? info->calib : NULL,
	                       info ? info->materials : NULL, method};
	for (int i = 0; i < 4; i++)
		json_object_set_new(root, keys[i], vals[i] ? json_string(vals[i]) : json_null());
	if (info && info->identity)
		json_object_set_new(root, "identity", json_deep_copy(info->identity));
	if (info && info->spectral_uncertainty)
		json_object_set_new(root, "spectral_uncertainty",
		                    json_deep_copy(info->spectral_uncertainty));
}

/* LABELS.json's clip levels and the image's size and pixel count. */
void ap_labels_json_image(json_t *root, const kg_apply_options *opt, const kg_row_source *img,
                          const kg_classify_result *res)
{
	json_object_set_new(root, "clip_level", ap_json_num(opt->clip_level));
	{ /* per channel: the clip level, or the saturation found from the data below it */
		json_t *cl = json_array();
		for (int c = 0; c < 3; c++)
			json_array_append_new(cl, ap_json_num(opt->clip_rgb[c] > 0 &&
			                                      opt->clip_rgb[c] < opt->clip_level
			                                          ? opt->clip_rgb[c] : opt->clip_level));
		json_object_set_new(root, "clip_levels", cl);
	}
	json_object_set_new(root, "width", json_integer(img->width));
	json_object_set_new(root, "height", json_integer(img->height));
	json_object_set_new(root, "pixels", json_integer((json_int_t)res->stats.pixels));
}

const char *ap_distance_name(kg_est_distance d)
{
	return d == KG_EST_DIST_SCALE_FREE ? "scale-free" : "plain";
}

/* How unknown and background were decided, for LABELS.json. */
static json_t *refusal_json(const kg_classify_options *copt, const kg_classify_info *info,
                            const kg_classify_result *res)
{
	json_t *r = json_object();
	json_t *bg = json_object();
	json_object_set_new(bg, "level", copt->background_level > 0
	                                     ? json_real(copt->background_level)
	                                     : json_null());
	json_object_set_new(bg, "signal",
	                    json_string("largest channel of the image, 0..1 full scale"));
	json_object_set_new(bg, "mask", copt->mask ? json_string(info && info->mask ? info->mask
	                                                                            : "given")
	                                           : json_null());
	json_object_set_new(r, "background", bg);
	json_t *u = json_object();
	int on = isfinite(res->unknown_threshold);
	json_object_set_new(u, "enabled", json_boolean(on));
	json_object_set_new(u, "statistic",
	                    json_string("chi2 = r^T (sigma_w + (o_j / K) I)^-1 r of the best "
	                                "material j: r its residual in the K weights, o_j the "
	                                "distance's part outside the basis, sigma_w the noise "
	                                "and calibration error propagated through the weight "
	                                "matrix"));
	json_object_set_new(u, "threshold", ap_json_num(res->unknown_threshold));
	json_object_set_new(u, "dof", json_integer(res->dof));
	json_object_set_new(u, "probability",
	                    on && copt->unknown_threshold == 0 ? json_real(0.999) : json_null());
	json_object_set_new(u, "residual_relative", json_real(copt->residual_relative));
	if (copt->variance) {
		json_object_set_new(u, "noise", json_string("variance image"));
		json_object_set_new(u, "variance", json_string(info && info->variance ? info->variance
		                                                                      : "given"));
		json_object_set_new(u, "frames", json_integer(copt->frames));
	} else {
		json_object_set_new(u, "noise", json_string("model"));
		json_object_set_new(u, "noise_relative", json_real(copt->noise_relative));
		json_object_set_new(u, "noise_floor", json_real(copt->noise_floor));
		json_object_set_new(u, "note",
		                    json_string("no variance image: assumed per channel sigma^2 = "
		                                "noise_floor^2 + (noise_relative rho)^2"));
	}
	json_object_set_new(r, "unknown", u);
	return r;
}

json_t *ap_refusal_class(const kg_est_material_set *set, int label, uint64_t pixels,
                             uint64_t total)
{
	unsigned char col[3];
	ap_label_colour(set, label, col);
	json_t *o = json_object();
	json_object_set_new(o, "label", json_integer(label));
	json_object_set_new(o, "name", json_string(ap_label_name(set, label)));
	json_object_set_new(o, "pixels", json_integer((json_int_t)pixels));
	json_object_set_new(o, "fraction", json_real(total ? (double)pixels / (double)total : 0.0));
	json_object_set_new(o, "colour", json_pack("[iii]", col[0], col[1], col[2]));
	json_object_set_new(o, "mean_spectrum", json_null());
	json_object_set_new(o, "confidence", json_null());
	return o;
}

int ap_write_labels_json(const char *path, const kg_est_material_set *set,
                      const kg_classify_options *copt, const kg_row_source *img,
                      const kg_apply_options *opt, const kg_classify_info *info,
                      const char *const files[4], const kg_classify_result *res, kg_err *err)
{
	json_t *root = json_object();
	json_t *classes = json_array();
	json_t *wl = json_array();
	if (!root || !classes || !wl) {
		json_decref(root);
		json_decref(classes);
		json_decref(wl);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	ap_labels_json_inputs(root, info, info ? info->method : NULL);
	json_object_set_new(root, "distance", json_string(ap_distance_name(copt->distance)));
	json_object_set_new(root, "angle_deg", json_real(set->angle_deg));
	ap_labels_json_image(root, opt, img, res);
	json_t *fl = json_object();
	json_object_set_new(fl, "unclassified", json_integer((json_int_t)res->unclassified));
	json_object_set_new(fl, "nonfinite", json_integer((json_int_t)res->stats.nonfinite));
	json_object_set_new(fl, "clipped", json_integer((json_int_t)res->stats.clipped));
	json_object_set_new(root, "flagged", fl);
	json_object_set_new(root, "refusal", refusal_json(copt, info, res));
	json_t *fs = json_object();
	const char *fkeys[4] = {"labels", "confidence", "mask", "preview"};
	for (int i = 0; i < 4; i++)
		json_object_set_new(fs, fkeys[i], json_string(kg_path_below(files[i], copt->record_dir)));
	json_object_set_new(root, "files", fs);
	json_object_set_new(root, "confidence",
	                    json_string("margin: distance to the runner-up minus distance to the "
	                                "chosen material (squared reflectance over 61 bands); "
	                                "none for unknown and background"));
	for (int l = 0; l < KG_NBANDS; l++)
		json_array_append_new(wl, json_real(kg_band_nm(l)));
	json_object_set_new(root, "wavelength_nm", wl);
	json_t *c0 = json_object();
	json_object_set_new(c0, "label", json_integer(0));
	json_object_set_new(c0, "name", json_string("unclassified"));
	json_object_set_new(c0, "pixels", json_integer((json_int_t)res->unclassified));
	json_object_set_new(c0, "fraction",
	                    json_real(res->stats.pixels
	                                  ? (double)res->unclassified / (double)res->stats.pixels
	                                  : 0.0));
	json_array_append_new(classes, c0);
	for (int j = 0; j < res->nclasses; j++) {
		const kg_class_summary *c = &res->classes[j];
		json_t *o = json_object();
		unsigned char col[3];
		ap_label_colour(set, j + 1, col);
		json_object_set_new(o, "label", json_integer(j + 1));
		json_object_set_new(o, "name", json_string(c->name));
		json_object_set_new(o, "pixels", json_integer((json_int_t)c->pixels));
		json_object_set_new(o, "fraction", json_real(c->fraction));
		json_object_set_new(o, "colour", json_pack("[iii]", col[0], col[1], col[2]));
		json_t *ms = json_null();
		if (c->pixels) {
			ms = json_array();
			for (int l = 0; l < KG_NBANDS; l++)
				json_array_append_new(ms, ap_json_num(c->mean_spectrum[l]));
		}
		json_object_set_new(o, "mean_spectrum", ms);
		json_t *conf = json_object();
		json_object_set_new(conf, "mean", ap_json_num(c->margin_mean));
		json_object_set_new(conf, "median", ap_json_num(c->margin_median));
		json_object_set_new(conf, "p5", ap_json_num(c->margin_p5));
		json_object_set_new(o, "confidence", conf);
		json_array_append_new(classes, o);
	}
	json_array_append_new(classes, ap_refusal_class(set, ap_label_unknown(set), res->unknown,
	                                             res->stats.pixels));
	json_array_append_new(classes, ap_refusal_class(set, ap_label_background(set), res->background,
	                                             res->stats.pixels));
	json_object_set_new(root, "classes", classes);
	int rc = kg_json_write(root, path, err);
	json_decref(root);
	if (rc)
		kg_err_prefix(err, "%s: ", path);
	return rc;
}

/* The label map with class colours (flagged pixels grey, unknown magenta, background
 * near-black), at most 720 pixels on its longer side (nearest sample), and a legend
 * with each class's share. */
void ap_preview_size(int width, int height, int *pw, int *ph)
{
	double scale = 720.0 / (width > height ? width : height);
	*pw = (int)lround(width * scale);
	*ph = (int)lround(height * scale);
	*pw = *pw < 1 ? 1 : *pw;
	*ph = *ph < 1 ? 1 : *ph;
}

/* The preview's rows (pw x ph labels, nearest sample) that block b of labels lab
 * reaches, from *next_py on; height: the image's. */
void ap_preview_rows(uint8_t *preview, int pw, int ph, int *next_py, int height,
                     const kg_est_block *b, const uint8_t *lab)
{
	for (; *next_py < ph; (*next_py)++) {
		int sy = (int)((long)*next_py * height / ph);
		if (sy >= b->y0 + b->rows)
			break;
		const uint8_t *row = lab + (size_t)(sy - b->y0) * b->width;
		for (int x = 0; x < pw; x++)
			preview[(size_t)*next_py * pw + x] = row[(long)x * b->width / pw];
	}
}

/* labels: the pw x ph nearest samples the sink kept (ap_preview_size). */
int ap_write_preview(const char *path, const kg_est_material_set *set,
                         const uint8_t *labels, int pw, int ph,
                         const kg_classify_result *res, int legend, kg_err *err)
{
	/* The legend in full: a compound class's members one per line (no name is cut
	 * off), 14 px text, the legend as wide as its longest line (about 0.62 em a
	 * character for the sans-serif face) */
	const int margin = 10, line_h = 19, gap = 6, font = 14;
	const int nlabels = set->n + 3;
	int lines = 0;
	size_t longest = 0;
	for (int j = 0; j < nlabels; j++) {
		const char *name = j ? ap_label_name(set, j) : "flagged (unclassified)";
		for (const char *q = name; q;) {
			const char *bar = strchr(q, '|');
			/* " |  100.0 %" on the first line, an indent and " |" on the others */
			size_t len = (bar ? (size_t)(bar - q) : strlen(q)) + (q == name ? 12 : 4);
			longest = len > longest ? len : longest;
			lines++;
			q = bar ? bar + 1 : NULL;
		}
	}
	int legend_w = 30 + (int)ceil(0.62 * font * (double)longest) + margin;
	legend_w = !legend ? 0 : legend_w < 260 ? 260 : legend_w;
	int legend_h = legend ? line_h * lines + gap * nlabels + 2 * margin : 0;
	int fig_h = (ph + 2 * margin > legend_h ? ph + 2 * margin : legend_h);
	kg_plot *p = NULL;
	int rc = kg_plot_new(pw + legend_w + 2 * margin, fig_h, &p, err);
	if (rc)
		return rc;
	unsigned char (*pal)[3] = malloc(sizeof(*pal) * 256);
	if (!pal) {
		kg_plot_free(&p);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	for (int l = 0; l < 256; l++)
		ap_label_colour(set, l < nlabels ? l : 0, pal[l]);
	for (int y = 0; y < ph; y++) {
		const uint8_t *row = labels + (size_t)y * pw;
		for (int x0 = 0; x0 < pw;) {
			uint8_t l = row[x0];
			int x1 = x0 + 1;
			while (x1 < pw && row[x1] == l)
				x1++;
			double c[3] = {pal[l][0] / 255.0, pal[l][1] / 255.0, pal[l][2] / 255.0};
			kg_plot_fill_rect(p, margin + x0, margin + y, x1 - x0, 1, c);
			x0 = x1;
		}
	}
	const double black[3] = {0, 0, 0}, edge[3] = {0.5, 0.5, 0.5};
	double lx = pw + 2 * margin, y = margin;
	for (int j = 0; legend && j < nlabels; j++) {
		double c[3] = {pal[j][0] / 255.0, pal[j][1] / 255.0, pal[j][2] / 255.0};
		kg_plot_fill_rect(p, lx, y + 2, 16, 16, c);
		kg_plot_stroke_rect(p, lx, y + 2, 16, 16, edge, 1);
		uint64_t count = j == 0                        ? res->unclassified
		                 : j == ap_label_unknown(set)     ? res->unknown
		                 : j == ap_label_background(set)  ? res->background
		                                               : res->classes[j - 1].pixels;
		double frac =
			res->stats.pixels ? 100.0 * (double)count / (double)res->stats.pixels : 0.0;
		const char *name = j ? ap_label_name(set, j) : "flagged (unclassified)";
		for (const char *q = name; q;) {
			const char *bar = strchr(q, '|');
			if (q == name && !bar)
				kg_plot_text(p, lx + 24, y + 15, font, KG_ALIGN_LEFT, black, "%s  %.1f %%", q,
				             frac);
			else if (q == name)
				kg_plot_text(p, lx + 24, y + 15, font, KG_ALIGN_LEFT, black, "%.*s |  %.1f %%",
				             (int)(bar - q), q, frac);
			else if (bar)
				kg_plot_text(p, lx + 36, y + 15, font, KG_ALIGN_LEFT, black, "%.*s |",
				             (int)(bar - q), q);
			else
				kg_plot_text(p, lx + 36, y + 15, font, KG_ALIGN_LEFT, black, "%s", q);
			y += line_h;
			q = bar ? bar + 1 : NULL;
		}
		y += gap;
	}
	free(pal);
	rc = kg_plot_save_png(p, path, err);
	kg_plot_free(&p);
	if (rc)
		kg_err_prefix(err, "%s: ", path);
	return rc;
}
