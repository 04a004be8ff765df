/* Full-range integration (kg_samples_to_xyz) against ArgyllCMS spec2cie, a peer that
 * integrates at 1 nm over the 1931 observer's 360-830 nm with the 1 nm CIE table.
 *
 * - emission: every colord illuminant file; spec2cie's absolute XYZ scaled to Y = 100
 *   against kg_illuminant_white_full() of the same file read by
 *   kg_illuminant_from_file();
 * - reflectance: the CIE test colour samples (colord ref/CIE-TCS.sp) under the
 *   built-in D65, D50 and A (spec2cie -i D65|D50|A, its own tables) and under colord's
 *   F2 and F11 files (spec2cie -i FILE).
 *
 * spec2cie needs MEAS_TYPE and plain SPEC_<nm> names, so the inputs are written anew
 * from the parsed files. Skipped (77) without spec2cie or /usr/share/colord. */
#include <dirent.h>
#include <math.h>
#include <string.h>
#include <unistd.h>

#include "kg_test.h"
#include "spectra_io.h"

static char tmpdir[] = "/tmp/kg_spec2cie_XXXXXX";
static double worst;
static char worst_what[256];

static void note_diff(double d, const char *what)
{
	if (d > worst) {
		worst = d;
		snprintf(worst_what, sizeof(worst_what), "%s", what);
	}
}

/* Write spectra as an ArgyllCMS .sp file. */
static void write_sp(const char *path, const char *meas_type, const test_spectra *s)
{
	FILE *fp = fopen(path, "w");
	if (!fp) {
		fprintf(stderr, "%s: cannot create\n", path);
		exit(1);
	}
	fprintf(fp, "SPECT\n\nDESCRIPTOR \"kogei colorimetry test\"\nMEAS_TYPE \"%s\"\n",
	        meas_type);
	fprintf(fp, "SPECTRAL_START_NM \"%g\"\nSPECTRAL_END_NM \"%g\"\nSPECTRAL_BANDS \"%d\"\n\n",
	        s->wl[0], s->wl[s->n - 1], s->n);
	fprintf(fp, "NUMBER_OF_FIELDS %d\nBEGIN_DATA_FORMAT\nSAMPLE_ID", s->n + 1);
	for (int i = 0; i < s->n; i++)
		fprintf(fp, " SPEC_%ld", lround(s->wl[i]));
	fprintf(fp, "\nEND_DATA_FORMAT\n\nNUMBER_OF_SETS %d\nBEGIN_DATA\n", s->nsets);
	for (int j = 0; j < s->nsets; j++) {
		fprintf(fp, "%s", s->ids[j][0] ? s->ids[j] : "S");
		for (int i = 0; i < s->n; i++)
			fprintf(fp, " %.10e", s->v[j * s->n + i]);
		fputc('\n', fp);
	}
	fprintf(fp, "END_DATA\n");
	if (fclose(fp) != 0) {
		fprintf(stderr, "%s: write failed\n", path);
		exit(1);
	}
}

/* Run spec2cie and read XYZ_X/Y/Z of each set from its output (n sets expected). */
static int run_spec2cie(const char *options, const char *in, const char *out,
                        double (*xyz)[3], int n)
{
	char cmd[2048];
	snprintf(cmd, sizeof(cmd), "spec2cie %s '%s' '%s' >'%s/log' 2>&1", options, in, out,
	         tmpdir);
	if (system(cmd) != 0) {
		fprintf(stderr, "failed: %s (see %s/log)\n", cmd, tmpdir);
		kg_test_failures++;
		return -1;
	}
	kg_cgats *cg = NULL;
	kg_err err = {{0}};
	if (kg_cgats_read(out, &cg, &err) != 0) {
		fprintf(stderr, "%s\n", err.msg);
		kg_test_failures++;
		return -1;
	}
	const kg_cgats_table *t = cg->tables[0];
	int f[3] = {kg_cgats_field(t, "XYZ_X"), kg_cgats_field(t, "XYZ_Y"),
	            kg_cgats_field(t, "XYZ_Z")};
	int ret = 0;
	if (f[0] < 0 || f[1] < 0 || f[2] < 0 || t->nsets != n) {
		fprintf(stderr, "%s: expected XYZ_X/Y/Z and %d sets, found %d sets\n", out, n,
		        t->nsets);
		kg_test_failures++;
		ret = -1;
	}
	for (int j = 0; ret == 0 && j < n; j++)
		for (int c = 0; c < 3; c++)
			if (kg_cgats_number(t, j, f[c], &xyz[j][c], &err) != 0) {
				fprintf(stderr, "%s\n", err.msg);
				kg_test_failures++;
				ret = -1;
			}
	kg_cgats_free(&cg);
	return ret;
}

static void test_emission(void)
{
	const char *names[] = {"A",  "B",  "C",  "D50", "D55", "D65", "D93",
	                       "E",  "F1", "F2", "F3",  "F4",  "F5",  "F6",
	                       "F7", "F8", "F9", "F10", "F11", "F12"};
	double file_worst = 0.0;
	for (size_t k = 0; k < sizeof(names) / sizeof(names[0]); k++) {
		char path[256], in[512], out[512];
		snprintf(path, sizeof(path), COLORD_DIR "/illuminant/CIE-%s.sp", names[k]);
		if (!kg_test_file_exists(path))
			continue;
		test_spectra s = test_spectra_read(path);
		snprintf(in, sizeof(in), "%s/%s.sp", tmpdir, names[k]);
		snprintf(out, sizeof(out), "%s/%s_xyz.sp", tmpdir, names[k]);
		write_sp(in, "EMISSION", &s);
		double ref[1][3];
		if (run_spec2cie("", in, out, ref, 1) == 0) {
			kg_illuminant *ill = NULL;
			kg_err err = {{0}};
			CHECK(kg_illuminant_from_file(path, &ill, &err) == 0, "%s", err.msg);
			kg_xyz w = ill ? kg_illuminant_white_full(ill) : (kg_xyz){0, 0, 0};
			double ours[3] = {w.X, w.Y, w.Z};
			for (int c = 0; c < 3; c++) {
				double r = 100.0 * ref[0][c] / ref[0][1];
				char what[128];
				snprintf(what, sizeof(what), "white of colord CIE-%s.sp, %c", names[k],
				         "XYZ"[c]);
				CHECK_NEAR(ours[c], r, 0.01, what);
				note_diff(fabs(ours[c] - r), what);
				if (fabs(ours[c] - r) > file_worst)
					file_worst = fabs(ours[c] - r);
			}
			kg_illuminant_free(&ill);
		}
		test_spectra_free(&s);
	}
	printf("emission (20 colord illuminants, Y = 100): max |diff| vs spec2cie %.3g\n",
	       file_worst);
}

/* TCS under an illuminant: `option` is spec2cie's -i argument. */
static void test_reflectance(const test_spectra *tcs, const char *tcs_in, const char *label,
                             const char *option, const kg_illuminant *ill)
{
	static int run;
	double(*ref)[3] = malloc(sizeof(*ref) * (size_t)tcs->nsets);
	char out[512], opt[512];
	snprintf(out, sizeof(out), "%s/tcs_xyz_%d.sp", tmpdir, run++);
	snprintf(opt, sizeof(opt), "-i '%s'", option);
	double max_diff = 0.0;
	if (ref && run_spec2cie(opt, tcs_in, out, ref, tcs->nsets) == 0) {
		for (int j = 0; j < tcs->nsets; j++) {
			kg_xyz x;
			kg_err err = {{0}};
			CHECK(kg_samples_to_xyz(tcs->wl, tcs->v + j * tcs->n, tcs->n, ill, &x, &err) ==
			          0,
			      "%s", err.msg);
			double ours[3] = {x.X, x.Y, x.Z};
			for (int c = 0; c < 3; c++) {
				char what[128];
				snprintf(what, sizeof(what), "%s under %s, %c", tcs->ids[j], label,
				         "XYZ"[c]);
				double r = 100.0 * ref[j][c];
				CHECK_NEAR(ours[c], r, 0.01, what);
				note_diff(fabs(ours[c] - r), what);
				if (fabs(ours[c] - r) > max_diff)
					max_diff = fabs(ours[c] - r);
			}
		}
	}
	printf("reflectance (%d CIE TCS) under %s: max |diff| vs spec2cie %.3g\n", tcs->nsets,
	       label, max_diff);
	free(ref);
}

static void remove_tmpdir(void)
{
	DIR *d = opendir(tmpdir);
	struct dirent *e;
	while (d && (e = readdir(d))) {
		if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0)
			continue;
		char *p = kg_path_join(tmpdir, e->d_name);
		if (p)
			unlink(p);
		free(p);
	}
	if (d)
		closedir(d);
	rmdir(tmpdir);
}

int main(void)
{
	struct stat st;
	if (stat(COLORD_DIR, &st) != 0)
		kg_test_skip(COLORD_DIR " is not present (package colord-data)");
	if (system("command -v spec2cie >/dev/null 2>&1") != 0)
		kg_test_skip("spec2cie (ArgyllCMS, package argyll) is not installed");
	if (!mkdtemp(tmpdir)) {
		fprintf(stderr, "cannot create a temporary directory\n");
		return 1;
	}

	test_emission();

	test_spectra tcs = test_spectra_read(COLORD_DIR "/ref/CIE-TCS.sp");
	char tcs_in[512];
	snprintf(tcs_in, sizeof(tcs_in), "%s/tcs.sp", tmpdir);
	write_sp(tcs_in, "REFLECTIVE", &tcs);
	const char *builtin[] = {"D65", "D50", "A"};
	for (int i = 0; i < 3; i++) {
		kg_illuminant *ill = NULL;
		kg_err err = {{0}};
		if (kg_illuminant_by_name(builtin[i], &ill, &err) != 0) {
			fprintf(stderr, "%s\n", err.msg);
			return 1;
		}
		test_reflectance(&tcs, tcs_in, builtin[i], builtin[i], ill);
		kg_illuminant_free(&ill);
	}
	const char *files[] = {"F2", "F11"};
	for (int i = 0; i < 2; i++) {
		char path[256], in[512];
		snprintf(path, sizeof(path), COLORD_DIR "/illuminant/CIE-%s.sp", files[i]);
		snprintf(in, sizeof(in), "%s/illum_%s.sp", tmpdir, files[i]);
		test_spectra s = test_spectra_read(path);
		write_sp(in, "EMISSION", &s);
		test_spectra_free(&s);
		kg_illuminant *ill = NULL;
		kg_err err = {{0}};
		if (kg_illuminant_from_file(path, &ill, &err) != 0) {
			fprintf(stderr, "%s\n", err.msg);
			return 1;
		}
		char label[64];
		snprintf(label, sizeof(label), "colord CIE-%s.sp", files[i]);
		test_reflectance(&tcs, tcs_in, label, in, ill);
		kg_illuminant_free(&ill);
	}
	test_spectra_free(&tcs);

	printf("spec2cie: largest |difference| %.3g (%s), tolerance 0.01 on the Y = 100 "
	       "scale\n",
	       worst, worst_what);
	remove_tmpdir();
	return kg_test_done("colorimetry_spec2cie");
}
