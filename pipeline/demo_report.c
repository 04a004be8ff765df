/* The demo's report: the cube and the label map read back from their files and
 * compared with the simulated ground truth, as plots and a short summary.
 *
 * Every number comes from the files the pipeline wrote (cube.hdr, labels.hdr) and
 * from the scene's truth, so the report checks the outputs, not the code's memory. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "demo_private.h"
#include "kg_config.h"

/* How one material of the object came out. */
typedef struct material_eval {
	const char *name;
	long pixels;   /* sample pixels */
	long flagged;  /* of them, not estimated (NaN) */
	long correct;  /* labelled as this material */
	kg_spectrum truth;
	double sum[KG_NBANDS], sumsq[KG_NBANDS];
	double rmse_sum, de00_sum;
	kg_spectrum mean, sd; /* of the estimated spectra */
	double rmse, de00;    /* means over the estimated pixels */
} material_eval;

typedef struct report {
	int n;              /* materials */
	material_eval *m;
	long *confusion;    /* n x (n + 1): true row, predicted column, last = unclassified */
	long pixels, correct, unclassified;
	long mixed;         /* sample pixels at a border, mixed by demosaicing: not judged */
	int width, height;
	float *cube;        /* width * height * 61, BIP */
	kg_illuminant *d65;
	kg_xyz_weights xyz;
	kg_xyz white;
} report;

static const double black[3] = {0, 0, 0};
static const double true_colour[3] = {0.1, 0.1, 0.1};
static const double est_colour[3] = {0.85, 0.33, 0.10};
static const double band_colour[3] = {0.99, 0.84, 0.74};
static const double no_data[3] = {0.55, 0.55, 0.55};

static void report_free(report *r)
{
	free(r->m);
	free(r->confusion);
	free(r->cube);
	kg_illuminant_free(&r->d65);
}

static kg_lab lab_d65(const report *r, const kg_spectrum *s)
{
	return kg_xyz_to_lab(kg_xyz_from_weights(&r->xyz, s), r->white);
}

static void srgb_d65(const report *r, const kg_spectrum *s, double rgb[3])
{
	kg_rgb c = kg_srgb_encode(kg_xyz_to_linear_srgb(kg_xyz_from_weights(&r->xyz, s), r->white));
	rgb[0] = fmin(fmax(c.r, 0), 1);
	rgb[1] = fmin(fmax(c.g, 0), 1);
	rgb[2] = fmin(fmax(c.b, 0), 1);
}

/* The whole cube in BIP, after checking it is the 61-band cube of the object. */
static int read_cube(demo_ctx *d, report *r)
{
	char *path = demo_path(d, "site/" DEMO_CAPTURE_OBJECT "/cube.hdr");
	kg_envi *e = NULL;
	int ret = kg_envi_open(path, &e, &d->err);
	if (!ret && (e->meta.bands != KG_NBANDS || e->meta.samples != r->width ||
	             e->meta.lines != r->height))
		ret = kg_fail(&d->err, KG_EINVAL, "%s: %d x %d x %d: expected %d x %d x %d", path,
		              e->meta.samples, e->meta.lines, e->meta.bands, r->width, r->height,
		              KG_NBANDS);
	if (!ret && !(r->cube = malloc(sizeof(float) * KG_NBANDS * r->width * r->height)))
		ret = kg_fail(&d->err, KG_ENOMEM, "%s: out of memory", path);
	if (!ret)
		ret = kg_envi_read(e, 0, 0, r->width, r->height, KG_LAYOUT_BIP, r->cube, &d->err);
	kg_envi_close(&e);
	free(path);
	return ret;
}

/* Labels per pixel and, for each class of the label map, the bit set of the materials
 * it holds (bit j: r->m[j]; none for unclassified, unknown and background). */
static int read_labels(demo_ctx *d, report *r, float **labels, int **class_to_material,
                       int *nclasses)
{
	char *path = demo_path(d, "site/" DEMO_CAPTURE_OBJECT "/labels.hdr");
	kg_envi *e = NULL;
	int ret = kg_envi_open(path, &e, &d->err);
	if (!ret && (e->meta.bands != 1 || e->meta.samples != r->width ||
	             e->meta.lines != r->height || e->meta.classes < 1 || !e->meta.class_names))
		ret = kg_fail(&d->err, KG_EINVAL,
		              "%s: expected a %d x %d ENVI classification file", path, r->width,
		              r->height);
	if (!ret) {
		*nclasses = e->meta.classes;
		*labels = malloc(sizeof(float) * r->width * r->height);
		*class_to_material = malloc(sizeof(int) * e->meta.classes);
		if (!*labels || !*class_to_material)
			ret = kg_fail(&d->err, KG_ENOMEM, "%s: out of memory", path);
	}
	/* a compound class "a|b" (materials the noise cannot split per pixel) maps to a
	 * bit set of its members; a pixel so labelled is right when its truth is one */
	for (int c = 0; !ret && c < e->meta.classes; c++) {
		int bits = 0;
		const char *name = e->meta.class_names[c];
		for (int j = 0; j < r->n && j < 30; j++) {
			size_t len = strlen(r->m[j].name);
			for (const char *q = name; (q = strstr(q, r->m[j].name)); q++)
				if ((q == name || q[-1] == '|') && (q[len] == '\0' || q[len] == '|'))
					bits |= 1 << j;
		}
		(*class_to_material)[c] = bits;
	}
	if (!ret)
		ret = kg_envi_read(e, 0, 0, r->width, r->height, KG_LAYOUT_BIP, *labels, &d->err);
	kg_envi_close(&e);
	free(path);
	return ret;
}

/* Compare every sample pixel with its truth. */
static int evaluate(demo_ctx *d, report *r)
{
	const kg_sim_scene *s = d->scene;
	r->width = s->width;
	r->height = s->height;
	r->n = s->nclasses - 1; /* class 0 is the background; the object has no chart */
	r->m = calloc(r->n, sizeof(*r->m));
	r->confusion = calloc((size_t)r->n * (r->n + 1), sizeof(long));
	if (!r->m || !r->confusion)
		return kg_fail(&d->err, KG_ENOMEM, "out of memory");
	int ret = kg_illuminant_by_name("D65", &r->d65, &d->err);
	if (ret)
		return ret;
	kg_xyz_weights_reflectance(r->d65, &r->xyz);
	r->white = kg_illuminant_white(r->d65);
	for (int j = 0; j < r->n; j++)
		r->m[j].name = s->class_names[j + 1];
	for (int i = 0; i < s->nsamples; i++)
		r->m[s->sample_class[i] - 1].truth = s->truth[i];

	float *labels = NULL;
	int *class_to_material = NULL, nclasses = 0;
	ret = read_cube(d, r);
	if (!ret)
		ret = read_labels(d, r, &labels, &class_to_material, &nclasses);
	for (long i = 0; !ret && i < (long)r->width * r->height; i++) {
		int t = s->label[i] - 1;
		if (t < 0)
			continue;
		/* A pixel at a sample's border is mixed with its surroundings by the
		 * demosaicing (bilinear: its 3 x 3 neighbourhood): no single material is its
		 * truth. Counted apart, not judged. */
		int x = (int)(i % r->width), y = (int)(i / r->width), mixed = 0;
		for (int dy = -1; dy <= 1 && !mixed; dy++)
			for (int dx = -1; dx <= 1 && !mixed; dx++) {
				int xx = x + dx, yy = y + dy;
				mixed = xx < 0 || yy < 0 || xx >= r->width || yy >= r->height ||
				        s->sample[(long)yy * r->width + xx] != s->sample[i];
			}
		if (mixed) {
			r->mixed++;
			continue;
		}
		material_eval *m = &r->m[t];
		int c = (int)labels[i];
		int bits = c >= 0 && c < nclasses ? class_to_material[c] : 0, p = r->n;
		if (bits & (1 << t))
			p = t;
		else
			for (int j = r->n - 1; j >= 0; j--)
				if (bits & (1 << j))
					p = j; /* the first member */
		m->pixels++;
		r->pixels++;
		r->confusion[(long)t * (r->n + 1) + p]++;
		if (p == t) {
			m->correct++;
			r->correct++;
		}
		if (p == r->n)
			r->unclassified++;
		kg_spectrum est;
		for (int b = 0; b < KG_NBANDS; b++)
			est.v[b] = r->cube[i * KG_NBANDS + b];
		if (!kg_spectrum_isfinite(&est)) {
			m->flagged++;
			continue;
		}
		for (int b = 0; b < KG_NBANDS; b++) {
			m->sum[b] += est.v[b];
			m->sumsq[b] += est.v[b] * est.v[b];
		}
		m->rmse_sum += kg_spectrum_rmse(&est, &m->truth);
		m->de00_sum += kg_ciede2000(lab_d65(r, &est), lab_d65(r, &m->truth));
	}
	for (int j = 0; !ret && j < r->n; j++) {
		material_eval *m = &r->m[j];
		double n = (double)(m->pixels - m->flagged);
		for (int b = 0; b < KG_NBANDS; b++) {
			m->mean.v[b] = n > 0 ? m->sum[b] / n : NAN;
			double var = n > 1 ? (m->sumsq[b] - n * m->mean.v[b] * m->mean.v[b]) / (n - 1) : 0;
			m->sd.v[b] = sqrt(fmax(var, 0));
		}
		m->rmse = n > 0 ? m->rmse_sum / n : NAN;
		m->de00 = n > 0 ? m->de00_sum / n : NAN;
	}
	free(labels);
	free(class_to_material);
	return ret;
}

static double map_x(const kg_axes *ax, double v)
{
	return ax->x + (v - ax->xmin) / (ax->xmax - ax->xmin) * ax->w;
}

static double map_y(const kg_axes *ax, double v)
{
	v = fmin(fmax(v, ax->ymin), ax->ymax);
	return ax->y + ax->h - (v - ax->ymin) / (ax->ymax - ax->ymin) * ax->h;
}

/* The paper's Figs. 11-12: one panel per material, true solid, mean estimate dashed
 * in a band of +-1 sd over the material's pixels. */
static int plot_spectra(demo_ctx *d, const report *r)
{
	const int cols = 5, cell_w = 310, cell_h = 300, left = 80, top = 120;
	int rows = (r->n + cols - 1) / cols;
	kg_plot *p = NULL;
	char *path = demo_path(d, "spectra_by_material.png");
	int ret = kg_plot_new(left + cols * cell_w, top + rows * cell_h, &p, &d->err);
	if (ret) {
		free(path);
		return ret;
	}
	double wl[KG_NBANDS];
	for (int b = 0; b < KG_NBANDS; b++)
		wl[b] = kg_band_nm(b);
	kg_plot_text(p, (left + cols * cell_w) / 2.0, 32, 18, KG_ALIGN_CENTER, NULL,
	             "Estimated against true reflectance per material (cf. the paper's Figs. 11-12)");
	kg_plot_text(p, (left + cols * cell_w) / 2.0, 56, 13, KG_ALIGN_CENTER, NULL,
	             "object at %g deg incidence, site camera under CIE %s, PCA K = %d, s = B M M2 rho; "
	             "statistics over each sample's pixels; swatches: true | estimated under D65; "
	             "each panel has its own scale",
	             DEMO_ANGLE_DEG, DEMO_SITE_ILLUMINANT, d->cam->K);
	double lx = (left + cols * cell_w) / 2.0 - 300;
	kg_plot_legend(p, lx, 84, true_colour, 0, "true");
	kg_plot_legend(p, lx + 150, 84, est_colour, 1, "estimated, mean");
	kg_plot_fill_rect(p, lx + 360, 78, 30, 12, band_colour);
	kg_plot_text(p, lx + 398, 89, 12, KG_ALIGN_LEFT, NULL, "estimated, +-1 sd");
	for (int j = 0; j < r->n; j++) {
		const material_eval *m = &r->m[j];
		double x = left + (j % cols) * cell_w, y = top + (j / cols) * cell_h + 20;
		/* Each panel's own scale, so dark materials (lacquer) show their shape too. */
		double top_value = 0;
		for (int b = 0; b < KG_NBANDS; b++)
			top_value = fmax(top_value, fmax(m->truth.v[b], m->mean.v[b] + m->sd.v[b]));
		double ymax = fmax(0.1, ceil(top_value * 1.05 * 10) / 10);
		kg_axes ax = kg_plot_axes(p, x, y, 240, 200, 400, 700, 0, ymax,
		                          j / cols == rows - 1 ? "wavelength (nm)" : NULL,
		                          j % cols == 0 ? "reflectance" : NULL, NULL);
		kg_plot_text(p, x, y - 10, 14, KG_ALIGN_LEFT, NULL, "%s", m->name);
		double sw[3];
		srgb_d65(r, &m->truth, sw);
		kg_plot_fill_rect(p, x + 196, y - 24, 22, 18, sw);
		srgb_d65(r, &m->mean, sw);
		kg_plot_fill_rect(p, x + 218, y - 24, 22, 18, sw);
		kg_plot_stroke_rect(p, x + 196, y - 24, 44, 18, black, 1);
		for (int b = 0; b < KG_NBANDS; b++) {
			double x0 = map_x(&ax, fmax(wl[b] - 2.5, 400)), x1 = map_x(&ax, fmin(wl[b] + 2.5, 700));
			double y0 = map_y(&ax, m->mean.v[b] + m->sd.v[b]);
			double y1 = map_y(&ax, m->mean.v[b] - m->sd.v[b]);
			if (isfinite(y0) && isfinite(y1))
				kg_plot_fill_rect(p, x0, y0, x1 - x0, y1 - y0, band_colour);
		}
		kg_plot_stroke_rect(p, ax.x, ax.y, ax.w, ax.h, black, 1);
		kg_plot_line(p, &ax, wl, m->truth.v, KG_NBANDS, true_colour, 2, 0);
		kg_plot_line(p, &ax, wl, m->mean.v, KG_NBANDS, est_colour, 2, 1);
		kg_plot_text(p, x + 8, y + 216 + (j / cols == rows - 1 ? 40 : 18), 12,
		             KG_ALIGN_LEFT, NULL, "RMSE %.3f  dE00 %.1f  labelled %.0f %%", m->rmse,
		             m->de00, m->pixels ? 100.0 * m->correct / m->pixels : 0.0);
	}
	ret = kg_plot_save_png(p, path, &d->err);
	if (!ret)
		demo_wrote(d, path, "estimated against true spectra, one panel per material");
	kg_plot_free(&p);
	free(path);
	return ret;
}

/* Rows: true material; columns: predicted, numbered as the rows. */
static int plot_confusion(demo_ctx *d, const report *r)
{
	int ncol = r->n + (r->unclassified > 0);
	const int cell = 62, left = 250, top = 110;
	kg_plot *p = NULL;
	char *path = demo_path(d, "confusion.png");
	int ret = kg_plot_new(left + ncol * cell + 110, top + r->n * cell + 70, &p, &d->err);
	if (ret) {
		free(path);
		return ret;
	}
	kg_plot_text(p, (left + ncol * cell + 110) / 2.0, 30, 17, KG_ALIGN_CENTER, NULL,
	             "Classification of the object's sample pixels (eq. 11, plain distance)");
	kg_plot_text(p, left + ncol * cell / 2.0, top - 40, 13, KG_ALIGN_CENTER, NULL,
	             "predicted material (numbered as the rows)%s",
	             r->unclassified ? "; u = unclassified" : "");
	kg_plot_text(p, left - 10, top - 12, 13, KG_ALIGN_RIGHT, NULL, "true material");
	kg_plot_text(p, left + ncol * cell + 55, top - 12, 13, KG_ALIGN_CENTER, NULL, "recall");
	for (int c = 0; c < ncol; c++) {
		if (c < r->n)
			kg_plot_text(p, left + c * cell + cell / 2.0, top - 12, 13, KG_ALIGN_CENTER,
			             NULL, "%d", c + 1);
		else
			kg_plot_text(p, left + c * cell + cell / 2.0, top - 12, 13, KG_ALIGN_CENTER,
			             NULL, "u");
	}
	for (int t = 0; t < r->n; t++) {
		const material_eval *m = &r->m[t];
		double y = top + t * cell;
		kg_plot_text(p, left - 10, y + cell / 2.0 + 5, 13, KG_ALIGN_RIGHT, NULL, "%d  %s",
		             t + 1, m->name);
		for (int c = 0; c < ncol; c++) {
			int col = c < r->n ? c : r->n;
			long count = r->confusion[(long)t * (r->n + 1) + col];
			double f = m->pixels ? (double)count / m->pixels : 0;
			double rgb[3] = {1 - 0.85 * f, 1 - 0.65 * f, 1 - 0.3 * f};
			double x = left + c * cell;
			kg_plot_fill_rect(p, x, y, cell, cell, rgb);
			kg_plot_stroke_rect(p, x, y, cell, cell, no_data, 0.5);
			if (count) {
				static const double white[3] = {1, 1, 1};
				const double *ink = f > 0.5 ? white : black;
				kg_plot_text(p, x + cell / 2.0, y + cell / 2.0, 13, KG_ALIGN_CENTER, ink,
				             "%ld", count);
				kg_plot_text(p, x + cell / 2.0, y + cell / 2.0 + 16, 10, KG_ALIGN_CENTER,
				             ink, "%.0f %%", 100 * f);
			}
		}
		kg_plot_stroke_rect(p, left + t * cell, y, cell, cell, black, 2);
		kg_plot_text(p, left + ncol * cell + 55, y + cell / 2.0 + 5, 13, KG_ALIGN_CENTER,
		             NULL, "%.1f %%", m->pixels ? 100.0 * m->correct / m->pixels : 0.0);
	}
	kg_plot_text(p, left, top + r->n * cell + 35, 14, KG_ALIGN_LEFT, NULL,
	             "accuracy %.1f %% of %ld sample pixels; the diagonal is outlined",
	             r->pixels ? 100.0 * r->correct / r->pixels : 0.0, r->pixels);
	ret = kg_plot_save_png(p, path, &d->err);
	if (!ret)
		demo_wrote(d, path, "confusion matrix (pixel counts, row fractions)");
	kg_plot_free(&p);
	free(path);
	return ret;
}

/* The object three ways: as the site camera recorded it, and the true and the
 * estimated reflectance rendered under D65. */
static int plot_object(demo_ctx *d, const report *r)
{
	const kg_sim_scene *s = d->scene;
	const int scale = 2, gap = 30, top = 70;
	int pw = s->width * scale, ph = s->height * scale;
	kg_plot *p = NULL;
	char *path = demo_path(d, "object_d65.png");
	int ret = kg_plot_new(3 * pw + 4 * gap, ph + top + 20, &p, &d->err);
	if (ret) {
		free(path);
		return ret;
	}
	static const char *titles[3] = {
		"site camera image (camera RGB, as recorded)",
		"true reflectance, rendered under D65",
		"estimated reflectance, rendered under D65",
	};
	for (int k = 0; k < 3; k++)
		kg_plot_text(p, gap + k * (pw + gap) + pw / 2.0, top - 16, 14, KG_ALIGN_CENTER, NULL,
		             "%s", titles[k]);
	for (int y = 0; y < s->height; y++) {
		for (int x = 0; x < s->width; x++) {
			long i = (long)y * s->width + x;
			double rgb[3][3];
			int known = s->sample[i] >= 0;
			kg_spectrum est;
			for (int b = 0; b < KG_NBANDS; b++)
				est.v[b] = r->cube[i * KG_NBANDS + b];
			if (known) {
				kg_rgb cam = kg_srgb_encode((kg_rgb){s->rgb[3 * i] / DEMO_WHITE_LEVEL,
				                                     s->rgb[3 * i + 1] / DEMO_WHITE_LEVEL,
				                                     s->rgb[3 * i + 2] / DEMO_WHITE_LEVEL});
				rgb[0][0] = fmin(fmax(cam.r, 0), 1);
				rgb[0][1] = fmin(fmax(cam.g, 0), 1);
				rgb[0][2] = fmin(fmax(cam.b, 0), 1);
				srgb_d65(r, &s->truth[s->sample[i]], rgb[1]);
			}
			if (known && kg_spectrum_isfinite(&est))
				srgb_d65(r, &est, rgb[2]);
			else
				memcpy(rgb[2], no_data, sizeof(no_data));
			for (int k = 0; k < 3; k++)
				kg_plot_fill_rect(p, gap + k * (pw + gap) + x * scale, top + y * scale, scale,
				                  scale, known ? rgb[k] : no_data);
		}
	}
	ret = kg_plot_save_png(p, path, &d->err);
	if (!ret)
		demo_wrote(d, path, "the object: camera image, true and estimated colour");
	kg_plot_free(&p);
	free(path);
	return ret;
}

static void write_summary(demo_ctx *d, const report *r, FILE *fp)
{
	const kg_reference *ref = d->ref;
	const kg_camera_calib *cam = d->cam;
	const kg_spectral_map *map = &ref->maps[cam->method];
	fprintf(fp, "# kogei demo: a simulated session\n\n");
	fprintf(fp, "Written by `kogei demo` (kogei %s). Everything below was simulated with "
	            "fixed seeds, so every run gives the same numbers.\n\n", KG_VERSION);
	fprintf(fp, "## What was run\n\n");
	const demo_chart_shot *rs = &d->shots[0], *ss = &d->shots[1];
	const demo_spectro_run *sr = &d->spectro;
	fprintf(fp, "1. **Chart spectra** (measure -> `%s`): the %d patches of the chart measured "
	            "one by one with the simulated spectrophotometer `%s` (%s, serial %s): dark "
	            "reference, white reference (flat 0.99 standard), then each patch; %.0f ms "
	            "integration, %d scans averaged, electrical dark subtracted, reflectance "
	            "(S - D) / (W - D) x 0.99 resampled to 400-700 nm every 5 nm.\n",
	        DEMO_CHART_SPECTRA, sr->npatches, DEMO_SPECTRO, sr->model, sr->serial,
	        sr->integration_us / 1e3, sr->scans);
	fprintf(fp, "0. **The sessions** (`lab-session/`, `site-session/`): the bundled "
	            "recording `fixtures/%s` (raw frames from the simulated sensor, recorded by "
	            "`fixtures/demo/make_session.sh` with `kogei acquire`) replayed through the "
	            "`replay:` camera and averaged again by acquire/; each capture's mean is "
	            "checked against the sha256 the recording's manifest holds. Both are then "
	            "processed as `kogei process` processes a session.\n",
	        DEMO_SESSION);
	fprintf(fp, "2. **Reference calibration** (`kogei process lab-session --spectra` -> "
	            "`lab/reference.json`): the %d "
	            "CIE 13.3 test colour samples of `%s` (colord-data), mounted in the AprilTag "
	            "frame `%s` (`fixtures/%s`), photographed by the model camera `%s` under %s "
	            "(the session's capture `%s`: tilt %g deg, blur %g px, vignetting %g, noise "
	            "%s (full well:read noise:bits), seed %llu); the chart found by its tags and "
	            "sampled (`lab/chart_overlay.png`); S: the "
	            "measured spectra of `%s`.\n",
	        d->npatches, DEMO_CHART, d->layout_name, DEMO_CHART_LAYOUT,
	        DEMO_REFERENCE_CAMERA, DEMO_REFERENCE_ILLUMINANT, DEMO_CAPTURE_REFERENCE,
	        rs->tilt_deg, rs->blur_px, rs->vignetting, rs->noise,
	        (unsigned long long)rs->seed, DEMO_CHART_SPECTRA);
	fprintf(fp, "3. **Site calibration** (`kogei process site-session --reference "
	            "lab/reference.json` -> `site/camera.json`): the same chart "
	            "photographed by another model camera, `%s`, under CIE %s "
	            "(the session's capture `" DEMO_CAPTURE_SITE "`: tilt %g deg, rotated %g deg, blur %g px, vignetting %g, "
	            "noise %s, seed %llu), found and sampled the same way "
	            "(`site/chart_overlay.png`).\n",
	        DEMO_SITE_CAMERA, DEMO_SITE_ILLUMINANT, ss->tilt_deg, ss->rotate_deg, ss->blur_px,
	        ss->vignetting, ss->noise, (unsigned long long)ss->seed);
	fprintf(fp, "4. **Object** (the session's capture `" DEMO_CAPTURE_OBJECT "`, as "
	            "`object.tif`; truth in `object_truth.hdr` and "
	            "`object_truth_labels.hdr`): one %dx%d px sample of each of the %d materials "
	            "of the default library, seen in the specular direction at %g deg incidence "
	            "by the site camera under CIE %s, noise %s, seed %d, on a black ground "
	            "(classified as background).\n",
	        DEMO_TILE, DEMO_TILE, r->n, DEMO_ANGLE_DEG, DEMO_SITE_ILLUMINANT, DEMO_SITE_NOISE,
	        DEMO_SEED_OBJECT);
	fprintf(fp, "5. **Estimate** (`site/object/cube.hdr`, ENVI float32 BSQ, 61 bands "
	            "400-700 nm) and **classify** (`site/object/labels.hdr`, `.json`, `.png`), "
	            "the scene and the operator's report `site/report.html`, by kogei process.\n\n");

	fprintf(fp, "## Chart spectra (spectrophotometer)\n\n");
	fprintf(fp, "The spectra the calibration uses, as measured, against the tabulated "
	            "spectra of `%s` that the simulated instrument measured (its lamp, detector, "
	            "dark current and noise in between), on the 61-band grid.\n\n",
	        DEMO_CHART);
	fprintf(fp, "Measured vs file: RMSE **%.4f** mean over the %d patches, worst %.4f (%s); "
	            "largest |difference| %.4f (%s at %.0f nm); %d warning(s); %.0f ms for dark, "
	            "white and the patches.\n\n",
	        sr->rmse_mean, sr->npatches, sr->rmse_max, d->patch_ids[sr->rmse_max_at],
	        sr->diff_max, d->patch_ids[sr->diff_max_at], sr->diff_max_nm, sr->nwarnings,
	        sr->ms);
	fprintf(fp, "| patch | RMSE | max abs diff |\n|---|---:|---:|\n");
	for (int i = 0; i < sr->npatches && i < DEMO_MAX_PATCHES; i++)
		fprintf(fp, "| %s %s | %.4f | %.4f |\n", d->patch_ids[i], d->patch_names[i],
		        sr->rmse[i], sr->max_diff[i]);
	fprintf(fp, "\n");

	fprintf(fp, "## Chart detection\n\n");
	fprintf(fp, "`kg_chart_detect` with its defaults on each photograph as written: AprilTag "
	            "%s frame, homography from every tag corner found, each patch's median over "
	            "its centred %g x %g. Spread: 1.4826 x MAD of a patch's pixels, the largest "
	            "of any patch and channel. Error: the largest |detected - noise-free truth| "
	            "of any patch and channel, %% of full scale (the truth, "
	            "`fixtures/demo/<role>_chart_truth.cgats`, is what the session was rendered "
	            "from and includes the vignetting at the patch).\n\n",
	        d->layout_family, d->sample_fraction, d->sample_fraction);
	fprintf(fp, "| image | tags used | homography RMS (px) | patches | worst patch spread "
	            "| error vs truth | time |\n");
	fprintf(fp, "|---|---|---:|---:|---|---:|---:|\n");
	for (int k = 0; k < 2; k++) {
		const demo_chart_shot *sh = &d->shots[k];
		fprintf(fp, "| %s chart | %d (%s) | %.3f | %d of %d%s | %.4f (%s %c) | %.3f %% "
		            "| %.0f ms (decimate %d) |\n",
		        sh->role, sh->ntags_used, sh->tags_used, sh->rms_px, sh->nsampled,
		        sh->npatches, sh->nflagged ? " (some flagged)" : "", sh->worst_sd,
		        sh->worst_id, sh->worst_channel, sh->max_error, sh->detect_ms, sh->decimate);
	}
	fprintf(fp, "\n");
	fprintf(fp, "## Calibration\n\n");
	fprintf(fp, "- Method: **%s**, K = **%d** (uncentred PCA, %.4f of the chart's energy), "
	            "s = B M M2 rho.\n",
	        kg_method_name(cam->method), cam->K, ref->energy[ref->K - 1]);
	fprintf(fp, "- Reference chart: fit RMSE %.4f, leave-one-out RMSE %.4f, leave-one-out "
	            "dE00 %.2f (D65).\n",
	        map->fit_rmse, map->loo_rmse, map->loo_de00);
	fprintf(fp, "- M2 (site -> reference camera): condition number of M2 **%.3g**; of the "
	            "site chart rho_r %.3g (unit-RMS channels %.3g); residual %.2f %% of "
	            "||rho0||.\n",
	        d->cond_m2, cam->cond, cam->cond_equilibrated, 100.0 * cam->residual_relative);
	fprintf(fp, "- Cube: %ld sample pixels judged against the truth; of all pixels %llu "
	            "flagged no data, %llu with negative bands clamped to 0.\n\n",
	        r->pixels, (unsigned long long)d->est_stats.nonfinite,
	        (unsigned long long)d->est_stats.clamped_pixels);

	fprintf(fp, "## Per material (means over each sample's pixels)\n\n");
	fprintf(fp, "| # | material | pixels | spectral RMSE | dE00 (D65) | labelled correctly |\n");
	fprintf(fp, "|---|---|---:|---:|---:|---:|\n");
	for (int j = 0; j < r->n; j++) {
		const material_eval *m = &r->m[j];
		fprintf(fp, "| %d | %s | %ld | %.4f | %.2f | %.1f %% |\n", j + 1, m->name, m->pixels,
		        m->rmse, m->de00, m->pixels ? 100.0 * m->correct / m->pixels : 0.0);
	}
	fprintf(fp, "\n## Classification\n\n");
	fprintf(fp, "Classification accuracy: **%.2f %%** (%ld of %ld sample pixels), "
	            "camera-space matching among the %d materials of the library, angle and "
	            "intensity unknown (searched 0-70 deg, 0.3-1.0); a pixel is right when its "
	            "label holds its true material (a material, or a compound class 'a|b' of "
	            "materials the capture's noise cannot tell apart per pixel: see "
	            "`site/object/labels.json`, separability). The %ld pixels at the samples' "
	            "borders, which the demosaicing of the raw frames mixes with the black "
	            "ground, are not judged.\n\n",
	        r->pixels ? 100.0 * r->correct / r->pixels : 0.0, r->correct, r->pixels, r->n,
	        r->mixed);
	fprintf(fp, "Confusion matrix (rows: true material, columns: predicted, numbered as "
	            "above; a compound label counts on the diagonal when it holds the truth, "
	            "else under its first member%s):\n\n",
	        r->unclassified ? "; u: unclassified, unknown or background" : "");
	int ncol = r->n + (r->unclassified > 0);
	fprintf(fp, "| true \\ predicted |");
	for (int c = 0; c < ncol; c++)
		c < r->n ? fprintf(fp, " %d |", c + 1) : fprintf(fp, " u |");
	fprintf(fp, "\n|---|");
	for (int c = 0; c < ncol; c++)
		fprintf(fp, "---:|");
	fprintf(fp, "\n");
	for (int t = 0; t < r->n; t++) {
		fprintf(fp, "| %d %s |", t + 1, r->m[t].name);
		for (int c = 0; c < ncol; c++) {
			long v = r->confusion[(long)t * (r->n + 1) + (c < r->n ? c : r->n)];
			fprintf(fp, c == t ? " **%ld** |" : " %ld |", v);
		}
		fprintf(fp, "\n");
	}
	fprintf(fp, "\n## Files\n\n"
	            "`spectra_by_material.png` (estimated against true spectra), `confusion.png`, "
	            "`object_d65.png` (camera image, true and estimated colour); `lab/` and "
	            "`site/`, what kogei process wrote for each session (`reference.json`, "
	            "`camera.json`, `chart_overlay.png`, `process.json`, `report.html`, and "
	            "`site/object/` with the cube, the labels, the scene and its render); the "
	            "chart's measured spectra `chart_spectra.cgats`; the sessions replayed "
	            "(`lab-session/`, `site-session/`); the library's "
	            "`fig7_shibuichi-nami.csv`/`.png` and `materials_d65.png`. See docs/demo.md.\n");
}

static int summary(demo_ctx *d, const report *r)
{
	char *path = demo_path(d, "summary.md");
	char *text = NULL;
	size_t len = 0;
	kg_outfile out;
	FILE *mem = open_memstream(&text, &len);
	int ret = mem ? 0 : kg_fail(&d->err, KG_ENOMEM, "summary: out of memory");
	if (!ret) {
		write_summary(d, r, mem);
		if (fclose(mem) != 0)
			ret = kg_fail(&d->err, KG_ENOMEM, "summary: out of memory");
	}
	if (!ret)
		ret = kg_outfile_open(&out, path, 0, &d->err);
	if (!ret) {
		if (fwrite(text, 1, len, out.fp) != len) {
			kg_outfile_abort(&out);
			ret = kg_fail(&d->err, KG_EIO, "%s: write failed", path);
		} else {
			ret = kg_outfile_commit(&out, &d->err);
		}
	}
	if (!ret) {
		demo_wrote(d, path, "what was run and how well it did (below)");
		printf("\n%s", text);
	}
	free(text);
	free(path);
	return ret;
}

int demo_report(demo_ctx *d)
{
	report r = {0};
	int ret = evaluate(d, &r);
	if (!ret)
		ret = plot_spectra(d, &r);
	if (!ret)
		ret = plot_confusion(d, &r);
	if (!ret)
		ret = plot_object(d, &r);
	if (!ret)
		ret = summary(d, &r);
	report_free(&r);
	return ret;
}
