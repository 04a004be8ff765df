/* RGB texels of an environment image upsampled to spectra (render_private.h). */
#include <math.h>

#include "render_private.h"

static double smoothstep(double x)
{
	x = x < 0.0 ? 0.0 : x > 1.0 ? 1.0 : x;
	return x * x * (3.0 - 2.0 * x);
}

static int invert3(const double a[3][3], double out[3][3])
{
	double c[3][3];
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++) {
			int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
			c[j][i] = a[i1][j1] * a[i2][j2] - a[i1][j2] * a[i2][j1];
		}
	double det = a[0][0] * c[0][0] + a[0][1] * c[1][0] + a[0][2] * c[2][0];
	if (!(fabs(det) > 1e-12) || !isfinite(det))
		return -1;
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++)
			out[i][j] = c[i][j] / det;
	return 0;
}

int rd_upsampler_init(rd_upsampler *u, const kg_illuminant *ill, kg_err *err)
{
	kg_spectrum b[3];
	for (int i = 0; i < KG_NBANDS; i++) {
		double nm = kg_band_nm(i);
		double blue = 1.0 - smoothstep((nm - 470.0) / 40.0);
		double red = smoothstep((nm - 570.0) / 40.0);
		b[0].v[i] = blue;
		b[1].v[i] = 1.0 - blue - red;
		b[2].v[i] = red;
	}
	/* m: XYZ of each basis reflectance under the illuminant (columns); p: XYZ of the
	 * unit RGB primaries relative to the illuminant's white (columns). */
	kg_xyz white = kg_illuminant_white(ill);
	double m[3][3], p[3][3], minv[3][3];
	for (int k = 0; k < 3; k++) {
		kg_xyz x = kg_reflectance_to_xyz(&b[k], ill);
		kg_rgb unit = {k == 0, k == 1, k == 2};
		kg_xyz y = kg_linear_srgb_to_xyz(unit, white);
		m[0][k] = x.X, m[1][k] = x.Y, m[2][k] = x.Z;
		p[0][k] = y.X, p[1][k] = y.Y, p[2][k] = y.Z;
		for (int i = 0; i < KG_NBANDS; i++)
			u->basis[k][i] = (float)b[k].v[i];
	}
	if (invert3(m, minv))
		return kg_fail(err, KG_EINVAL, "illuminant %s: the RGB basis is singular under it "
		               "(no light in one of 400-470, 510-570, 610-700 nm)", ill->name);
	for (int i = 0; i < 3; i++)
		for (int j = 0; j < 3; j++)
			u->rgb_to_c[i][j] = minv[i][0] * p[0][j] + minv[i][1] * p[1][j] +
			                    minv[i][2] * p[2][j];
	return 0;
}

void rd_upsample(const rd_upsampler *u, const float rgb[3], float c[3])
{
	for (int i = 0; i < 3; i++)
		c[i] = (float)(u->rgb_to_c[i][0] * rgb[0] + u->rgb_to_c[i][1] * rgb[1] +
		               u->rgb_to_c[i][2] * rgb[2]);
}
