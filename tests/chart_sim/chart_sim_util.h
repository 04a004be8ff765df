/* Helpers of the chart simulation tests: a scratch directory, running programs
 * (kogei, scanin) with their output captured, and the inputs every test writes
 * itself (a synthetic camera, a framed 24-patch layout, patch spectra), so no
 * reference data are needed. */
#ifndef CHART_SIM_UTIL_H
#define CHART_SIM_UTIL_H

#include <fcntl.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "kg_test.h"

/* The scratch folder by the names the chart detector's tests (tests/chart_mcc) use. */
static inline const char *cs_scratch_dir(const char *tag) { return kg_test_scratch_dir(tag); }
static inline void cs_scratch_remove(void) { kg_test_scratch_remove(); }
static inline const char *cs_path(const char *name) { return kg_test_path(name); }

/* Run argv (NULL-terminated) with stdout and stderr into out (NUL-terminated,
 * truncated to len); the exit status, or -1 when it did not exit normally. */
static inline int cs_run(char *const *argv, char *out, size_t len)
{
	char log[4300];
	snprintf(log, sizeof(log), "%s/run.log", kg_test_scratch());
	pid_t pid = fork();
	if (pid == 0) {
		int fd = open(log, O_WRONLY | O_CREAT | O_TRUNC, 0644);
		if (fd >= 0) {
			dup2(fd, 1);
			dup2(fd, 2);
		}
		execvp(argv[0], argv);
		_exit(127);
	}
	int st = 0;
	if (pid < 0 || waitpid(pid, &st, 0) < 0)
		return -1;
	FILE *fp = fopen(log, "r");
	size_t n = fp ? fread(out, 1, len - 1, fp) : 0;
	out[n] = '\0';
	if (fp)
		fclose(fp);
	return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

/* Gaussian r, g, b sensitivities, 380-780 nm every 5 nm. */
static inline void cs_write_camera(const char *path)
{
	FILE *fp = fopen(path, "w");
	fprintf(fp, "wavelength_nm,r,g,b\n");
	for (int wl = 380; wl <= 780; wl += 5)
		fprintf(fp, "%d,%.9f,%.9f,%.9f\n", wl, exp(-0.5 * pow((wl - 600) / 30.0, 2)),
		        exp(-0.5 * pow((wl - 540) / 35.0, 2)),
		        0.7 * exp(-0.5 * pow((wl - 460) / 25.0, 2)));
	fclose(fp);
}

#define CS_ROWS 4
#define CS_COLS 6
#define CS_NPATCH (CS_ROWS * CS_COLS)

/* A framed 24-patch chart: 300 x 220 mm, tags of tag36h11 (ids first_tag..+3, 24 mm
 * detected square, 30 mm printed) in the four corners, patches of 30 mm on a 36 mm
 * pitch, ids A01..D06 (row letter, column number). */
static inline void cs_write_layout(const char *path, const char *name, int first_tag)
{
	FILE *fp = fopen(path, "w");
	fprintf(fp, "{\"format\": \"kogei-chart/1\", \"name\": \"%s\",\n"
	            " \"frame_mm\": [300, 220], \"chart_area_mm\": [38, 32, 224, 156],\n"
	            " \"sample_fraction\": 0.5, \"tag_family\": \"tag36h11\",\n \"tags\": [\n",
	        name);
	static const double tc[4][2] = {{20, 20}, {280, 20}, {280, 200}, {20, 200}};
	for (int t = 0; t < 4; t++)
		fprintf(fp, "  {\"id\": %d, \"center_mm\": [%g, %g], \"size_mm\": 24}%s\n",
		        first_tag + t, tc[t][0], tc[t][1], t < 3 ? "," : "");
	fprintf(fp, " ],\n \"patches\": [\n");
	for (int r = 0; r < CS_ROWS; r++)
		for (int c = 0; c < CS_COLS; c++)
			fprintf(fp, "  {\"id\": \"%c%02d\", \"center_mm\": [%g, %g], \"size_mm\": [30, 30]}%s\n",
			        'A' + r, c + 1, 60.0 + 36.0 * c, 56.0 + 36.0 * r,
			        r * CS_COLS + c < CS_NPATCH - 1 ? "," : "");
	fprintf(fp, " ]}\n");
	fclose(fp);
}

/* Smooth reflectances for the 24 patches (CGATS, SAMPLE_ID as the layout). */
static inline void cs_write_spectra(const char *path)
{
	FILE *fp = fopen(path, "w");
	fprintf(fp, "CGATS.17\nNUMBER_OF_FIELDS 62\nBEGIN_DATA_FORMAT\nSAMPLE_ID");
	for (int wl = 400; wl <= 700; wl += 5)
		fprintf(fp, " SPEC_%d", wl);
	fprintf(fp, "\nEND_DATA_FORMAT\nNUMBER_OF_SETS %d\nBEGIN_DATA\n", CS_NPATCH);
	for (int p = 0; p < CS_NPATCH; p++) {
		fprintf(fp, "%c%02d", 'A' + p / CS_COLS, p % CS_COLS + 1);
		double centre = 420 + 12.0 * p, level = 0.04 + 0.035 * p;
		for (int wl = 400; wl <= 700; wl += 5)
			fprintf(fp, " %.6f",
			        fmin(0.95, level + 0.5 * exp(-0.5 * pow((wl - centre) / 40.0, 2))));
		fprintf(fp, "\n");
	}
	fprintf(fp, "END_DATA\n");
	fclose(fp);
}

#endif
