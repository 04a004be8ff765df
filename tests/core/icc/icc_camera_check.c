/* icc_camera_check CAMERA.icc CAMERA.ti3: opens the camera input profile with
 * LittleCMS, maps every patch's RGB of the .ti3 (0..100) to CIELAB D50 (relative
 * colorimetric) and compares it with the patch's XYZ there (CIEDE2000). Prints
 * "patches N mean M max X"; exit 77 without LittleCMS. The .ti3 is read here as
 * plain CGATS text: SAMPLE_ID RGB_R RGB_G RGB_B XYZ_X XYZ_Y XYZ_Z rows. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "colorimetry.h"
#include "kg_config.h"

#if HAVE_LCMS
#include <lcms2.h>

int main(int argc, char **argv)
{
	if (argc != 3) {
		fprintf(stderr, "usage: icc_camera_check CAMERA.icc CAMERA.ti3\n");
		return 2;
	}
	cmsHPROFILE prof = cmsOpenProfileFromFile(argv[1], "r"), lab = cmsCreateLab4Profile(NULL);
	if (!prof || cmsGetDeviceClass(prof) != cmsSigInputClass ||
	    cmsGetColorSpace(prof) != cmsSigRgbData) {
		fprintf(stderr, "%s: not an RGB input profile LittleCMS can open\n", argv[1]);
		return 1;
	}
	cmsHTRANSFORM x = cmsCreateTransform(prof, TYPE_RGB_DBL, lab, TYPE_Lab_DBL,
	                                     INTENT_RELATIVE_COLORIMETRIC, 0);
	FILE *f = fopen(argv[2], "r");
	if (!x || !f) {
		fprintf(stderr, "%s: no transform or no %s\n", argv[1], argv[2]);
		return 1;
	}
	char line[512];
	int in = 0, n = 0;
	double sum = 0, mx = 0;
	kg_xyz d50 = {96.42, 100, 82.49};
	while (fgets(line, sizeof(line), f)) {
		if (!strncmp(line, "BEGIN_DATA\n", 11)) {
			in = 1;
			continue;
		}
		if (!strncmp(line, "END_DATA\n", 9))
			break;
		char id[128];
		double v[6];
		if (!in || sscanf(line, "%127s %lf %lf %lf %lf %lf %lf", id, &v[0], &v[1], &v[2],
		                  &v[3], &v[4], &v[5]) != 7)
			continue;
		double rgb[3] = {v[0] / 100, v[1] / 100, v[2] / 100};
		cmsCIELab got;
		cmsDoTransform(x, rgb, &got, 1);
		kg_lab ref = kg_xyz_to_lab((kg_xyz){v[3], v[4], v[5]}, d50);
		double de = kg_ciede2000(ref, (kg_lab){got.L, got.a, got.b});
		sum += de;
		mx = de > mx ? de : mx;
		n++;
	}
	fclose(f);
	cmsDeleteTransform(x);
	cmsCloseProfile(prof);
	cmsCloseProfile(lab);
	printf("patches %d mean %.4f max %.4f\n", n, n ? sum / n : NAN, mx);
	return n >= 3 ? 0 : 1;
}
#else
int main(void)
{
	printf("built without LittleCMS: skipped\n");
	return 77;
}
#endif
