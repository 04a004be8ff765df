/* Figures a person looks at: the paper's Fig. 7 table and heat map, and the swatch
 * sheet of a material library. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "kg_optics.h"

int kg_model_table(const kg_material *mat, const double *angles_deg, int nangles,
                   double *table, kg_err *err)
{
	kg_check_arg(mat && angles_deg && table && nangles > 0, err);
	for (int j = 0; j < nangles; j++) {
		if (!(angles_deg[j] >= 0 && angles_deg[j] <= 90))
			return kg_fail(err, KG_EINVAL, "angle %g: expected 0..90 degrees", angles_deg[j]);
		kg_spectrum r;
		int ret = kg_material_reflectance(mat, angles_deg[j] * M_PI / 180, &r, err);
		if (ret)
			return ret;
		for (int b = 0; b < KG_NBANDS; b++)
			table[b * nangles + j] = r.v[b];
	}
	return 0;
}

int kg_model_table_write_csv(const char *path, const double *angles_deg, int nangles,
                             const double *table, kg_err *err)
{
	kg_outfile o;
	int ret = kg_outfile_open(&o, path, 1, err);
	if (ret)
		return ret;
	fputs("wavelength_nm", o.fp);
	for (int j = 0; j < nangles; j++)
		fprintf(o.fp, ",%g", angles_deg[j]);
	fputc('\n', o.fp);
	for (int b = 0; b < KG_NBANDS; b++) {
		fprintf(o.fp, "%g", kg_band_nm(b));
		for (int j = 0; j < nangles; j++)
			fprintf(o.fp, ",%.6f", table[b * nangles + j]);
		fputc('\n', o.fp);
	}
	return kg_outfile_commit(&o, err);
}

kg_rgb kg_reflectance_srgb(const kg_spectrum *r, const kg_illuminant *ill)
{
	kg_xyz c = kg_reflectance_to_xyz(r, ill);
	return kg_srgb_encode(kg_xyz_to_linear_srgb(c, kg_illuminant_white(ill)));
}

static void rgb_array(kg_rgb c, double out[3])
{
	kg_rgb k = {fmin(fmax(c.r, 0), 1), fmin(fmax(c.g, 0), 1), fmin(fmax(c.b, 0), 1)};
	out[0] = k.r;
	out[1] = k.g;
	out[2] = k.b;
}

int kg_model_figure(const char *path, const char *title, const double *angles_deg,
                    int nangles, const double *table, const kg_illuminant *ill,
                    kg_err *err)
{
	kg_check_arg(path && angles_deg && table && ill && nangles > 0, err);
	double vmin = INFINITY, vmax = -INFINITY;
	for (int i = 0; i < KG_NBANDS * nangles; i++) {
		vmin = fmin(vmin, table[i]);
		vmax = fmax(vmax, table[i]);
	}
	vmin = floor(vmin * 20) / 20;
	vmax = ceil(vmax * 20) / 20;
	if (vmax <= vmin)
		vmax = vmin + 0.05;

	kg_plot *p;
	int ret = kg_plot_new(900, 640, &p, err);
	if (ret)
		return ret;
	/* Each angle is a column centred on its value. */
	double step = nangles > 1 ? (angles_deg[nangles - 1] - angles_deg[0]) / (nangles - 1) : 1;
	double x0 = angles_deg[0] - step / 2, x1 = angles_deg[nangles - 1] + step / 2;
	kg_axes ax = kg_plot_axes(p, 90, 60, 640, 400, x0, x1, KG_LAMBDA_MIN - 2.5,
	                          KG_LAMBDA_MAX + 2.5, NULL, "wavelength (nm)",
	                          title ? title : "reflectance");
	kg_plot_heatmap(p, &ax, table, KG_NBANDS, nangles, vmin, vmax);
	kg_plot_axes(p, 90, 60, 640, 400, x0, x1, KG_LAMBDA_MIN - 2.5, KG_LAMBDA_MAX + 2.5,
	             NULL, NULL, NULL);
	kg_plot_colorbar(p, 760, 60, 24, 400, vmin, vmax, "reflectance");

	/* The colour of the reflected light at each angle, aligned with the columns. */
	double cw = ax.w / nangles, rgb[3];
	for (int j = 0; j < nangles; j++) {
		kg_spectrum r;
		for (int b = 0; b < KG_NBANDS; b++)
			r.v[b] = table[b * nangles + j];
		rgb_array(kg_reflectance_srgb(&r, ill), rgb);
		kg_plot_fill_rect(p, ax.x + j * cw, ax.y + ax.h + 28, cw + 0.5, 40, rgb);
	}
	static const double black[3] = {0, 0, 0};
	kg_plot_stroke_rect(p, ax.x, ax.y + ax.h + 28, ax.w, 40, black, 1);
	kg_plot_text(p, ax.x - 8, ax.y + ax.h + 53, 11, KG_ALIGN_RIGHT, NULL, "%s light",
	             ill->name);
	kg_plot_text(p, ax.x + ax.w / 2, ax.y + ax.h + 92, 13, KG_ALIGN_CENTER, NULL,
	             "incidence angle (degrees)");
	kg_plot_text(p, ax.x + ax.w / 2, ax.y + ax.h + 112, 11, KG_ALIGN_CENTER, NULL,
	             "bottom strip: sRGB colour of the reflected %s light at each angle",
	             ill->name);
	ret = kg_plot_save_png(p, path, err);
	kg_plot_free(&p);
	return ret;
}

int kg_swatch_sheet(const char *path, const kg_material_library *lib,
                    const kg_illuminant *ill, kg_err *err)
{
	kg_check_arg(path && lib && ill, err);
	int n = kg_material_library_count(lib);
	if (n <= 0)
		return kg_fail(err, KG_EINVAL, "swatch sheet: the material library is empty");
	const int cols = 4, cell_w = 330, cell_h = 250;
	int rows = (n + cols - 1) / cols;
	kg_plot *p;
	int ret = kg_plot_new(cols * cell_w + 20, rows * cell_h + 60, &p, err);
	if (ret)
		return ret;
	kg_plot_text(p, (cols * cell_w + 20) / 2.0, 30, 16, KG_ALIGN_CENTER, NULL,
	             "Material library at normal incidence under %s", ill->name);
	static const double curve[3] = {0.1, 0.1, 0.1}, black[3] = {0, 0, 0};
	double wl[KG_NBANDS];
	for (int b = 0; b < KG_NBANDS; b++)
		wl[b] = kg_band_nm(b);
	for (int i = 0; i < n && ret == 0; i++) {
		const kg_material *m = kg_material_library_get(lib, i);
		kg_spectrum r;
		ret = kg_material_reflectance(m, 0, &r, err);
		if (ret)
			break;
		double rgb[3];
		rgb_array(kg_reflectance_srgb(&r, ill), rgb);
		double x = 20 + (i % cols) * cell_w, y = 50 + (i / cols) * cell_h;
		kg_plot_fill_rect(p, x, y, 90, 90, rgb);
		kg_plot_stroke_rect(p, x, y, 90, 90, black, 1);
		kg_plot_text(p, x + 100, y + 16, 13, KG_ALIGN_LEFT, NULL, "%s", m->name);
		kg_plot_text(p, x + 100, y + 36, 11, KG_ALIGN_LEFT, NULL, "%s",
		             m->kind == KG_MATERIAL_METAL   ? "metal"
		             : m->kind == KG_MATERIAL_ALLOY ? "alloy"
		                                            : "dielectric");
		kg_plot_text(p, x + 100, y + 56, 11, KG_ALIGN_LEFT, NULL, "sRGB %d %d %d",
		             (int)lround(rgb[0] * 255), (int)lround(rgb[1] * 255),
		             (int)lround(rgb[2] * 255));
		kg_axes ax = kg_plot_axes(p, x + 40, y + 105, 190, 95, 400, 700, 0, 1, NULL, NULL,
		                          NULL);
		kg_plot_line(p, &ax, wl, r.v, KG_NBANDS, curve, 1.5, 0);
	}
	if (ret == 0)
		ret = kg_plot_save_png(p, path, err);
	kg_plot_free(&p);
	return ret;
}
