/* kogei-bench-tiff: reading a 12 Mpix 16-bit TIFF as the tools a new user has write
 * it (uncompressed, LZW as ImageMagick and OpenCV write it, Deflate, tiled, one
 * strip), on one thread and on several, and the whole `kogei chart detect` of each.
 *
 * `kogei sim chart` renders the unframed ColorChecker 24 (layout colorchecker24-frame
 * on black paper, as kogei-bench-chart's "unframed, frontal": its synthetic camera and
 * spectra, D65, blur, vignetting and sensor noise) as a 16-bit TIFF; this program writes the
 * same codes again in each layout with libtiff. Per layout: the file size, the time of
 * kg_image_read with kg_image_set_read_threads(1) and with the default (the CPUs this
 * process may use), whether both give exactly the samples of the uncompressed file,
 * the time of kg_image_map (chart detect's reader: the file's 16-bit codes, mapped when
 * uncompressed, decoded when compressed), and the wall time and peak resident memory of the whole `kogei chart detect`
 * (a subprocess, default threads), also of a second kogei (--kogei-before, e.g. a
 * build of the previous commit) when given. Times are medians of --reps runs
 * (CLOCK_MONOTONIC, the page cache warm). Markdown goes to stdout.
 *
 *   kogei-bench-tiff [--kogei PATH] [--kogei-before PATH] [--width W --height H]
 *                    [--reps N] [--keep DIR] */
#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <math.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <tiffio.h>
#include <unistd.h>

#include "kg_bench.h"
#include "kg_config.h"

extern char **environ;

#define MAX_REPS 31

typedef struct layout {
	const char *name;
	const char *file;
	uint16_t compression, predictor;
	uint32_t rows_per_strip; /* 0: one strip */
	uint32_t tile;           /* 0: strips */
} layout;

static const layout layouts[] = {
    {"uncompressed, strips of 32 rows", "none.tif", COMPRESSION_NONE, 1, 32, 0},
    {"LZW + predictor, strips of 32 rows (ImageMagick's -compress lzw)", "lzw32.tif",
     COMPRESSION_LZW, PREDICTOR_HORIZONTAL, 32, 0},
    {"LZW + predictor, one row a strip (OpenCV's imwrite)", "lzw1.tif", COMPRESSION_LZW,
     PREDICTOR_HORIZONTAL, 1, 0},
    {"Deflate + predictor, strips of 32 rows", "zip32.tif", COMPRESSION_ADOBE_DEFLATE,
     PREDICTOR_HORIZONTAL, 32, 0},
    {"LZW + predictor, tiles of 256 x 256", "lzwtile.tif", COMPRESSION_LZW,
     PREDICTOR_HORIZONTAL, 0, 256},
    {"LZW + predictor, one strip", "lzwone.tif", COMPRESSION_LZW, PREDICTOR_HORIZONTAL, 0, 0},
};
enum { NLAYOUTS = sizeof(layouts) / sizeof(layouts[0]) };

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

static double median(double *v, int n)
{
	qsort(v, (size_t)n, sizeof(double), cmp_double);
	return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* Run argv quietly: wall seconds and peak resident KiB; -1 when it failed. The peak
 * comes from /usr/bin/time -f %M when it is there: Linux charges a child exec'd from a
 * vfork (posix_spawn) with its parent's peak, and this process holds the image. */
static double run_timed(char *const *argv, long *maxrss_kb, const char *rss_file)
{
	char *av[32];
	int n = 0, timed = access("/usr/bin/time", X_OK) == 0;
	if (timed) {
		av[n++] = "/usr/bin/time";
		av[n++] = "-f";
		av[n++] = "%M";
		av[n++] = "-o";
		av[n++] = (char *)rss_file;
	}
	for (int i = 0; argv[i] && n < 31; i++)
		av[n++] = argv[i];
	av[n] = NULL;
	posix_spawn_file_actions_t fa;
	if (posix_spawn_file_actions_init(&fa) != 0)
		return -1;
	posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
	posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
	double t0 = kg_bench_now();
	pid_t pid;
	int rc = posix_spawn(&pid, av[0], &fa, NULL, av, environ);
	posix_spawn_file_actions_destroy(&fa);
	int st = 0;
	struct rusage ru;
	if (rc != 0 || wait4(pid, &st, 0, &ru) < 0)
		return -1;
	double t = kg_bench_now() - t0;
	*maxrss_kb = 0;
	FILE *fp = timed ? fopen(rss_file, "r") : NULL;
	if (fp) {
		if (fscanf(fp, "%ld", maxrss_kb) != 1)
			*maxrss_kb = 0;
		fclose(fp);
		remove(rss_file);
	}
	return WIFEXITED(st) && WEXITSTATUS(st) == 0 ? t : -1;
}

/* The synthetic camera kogei-bench-chart renders with. */
static void write_camera(const char *path)
{
	kg_sim_camera cam;
	kg_bench_synthetic_camera(&cam);
	FILE *fp = fopen(path, "w");
	if (!fp)
		return;
	fprintf(fp, "wavelength_nm,r,g,b\n");
	for (int b = 0; b < KG_NBANDS; b++)
		fprintf(fp, "%g,%.9g,%.9g,%.9g\n", kg_band_nm(b), cam.sens[0].v[b], cam.sens[1].v[b],
		        cam.sens[2].v[b]);
	fclose(fp);
}

/* The image's codes (16-bit, exact: the file was 16-bit) in one layout. */
static int write_layout(const char *path, const kg_image *img, const layout *l)
{
	TIFF *tif = TIFFOpen(path, "w");
	if (!tif)
		return -1;
	uint32_t w = (uint32_t)img->width, h = (uint32_t)img->height;
	uint16_t C = (uint16_t)img->channels;
	TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, w);
	TIFFSetField(tif, TIFFTAG_IMAGELENGTH, h);
	TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, C);
	TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, (uint16_t)16);
	TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, C == 3 ? PHOTOMETRIC_RGB : PHOTOMETRIC_MINISBLACK);
	TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
	TIFFSetField(tif, TIFFTAG_COMPRESSION, l->compression);
	if (l->compression != COMPRESSION_NONE)
		TIFFSetField(tif, TIFFTAG_PREDICTOR, l->predictor);
	size_t row_n = (size_t)w * C;
	int ok = 1;
	if (l->tile) {
		TIFFSetField(tif, TIFFTAG_TILEWIDTH, l->tile);
		TIFFSetField(tif, TIFFTAG_TILELENGTH, l->tile);
		uint16_t *t = calloc((size_t)l->tile * l->tile * C, sizeof(uint16_t));
		for (uint32_t ty = 0; ok && t && ty < h; ty += l->tile)
			for (uint32_t tx = 0; ok && tx < w; tx += l->tile) {
				memset(t, 0, (size_t)l->tile * l->tile * C * sizeof(uint16_t));
				for (uint32_t y = ty; y < h && y < ty + l->tile; y++)
					for (uint32_t x = tx; x < w && x < tx + l->tile; x++)
						for (int c = 0; c < C; c++)
							t[((size_t)(y - ty) * l->tile + (x - tx)) * C + c] =
							    (uint16_t)lrintf(img->data[(size_t)y * row_n + x * C + c] *
							                     65535.0f);
				ok = TIFFWriteTile(tif, t, tx, ty, 0, 0) >= 0;
			}
		ok = ok && t;
		free(t);
	} else {
		TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, l->rows_per_strip ? l->rows_per_strip : h);
		uint16_t *row = malloc(row_n * sizeof(uint16_t));
		for (uint32_t y = 0; ok && row && y < h; y++) {
			for (size_t i = 0; i < row_n; i++)
				row[i] = (uint16_t)lrintf(img->data[(size_t)y * row_n + i] * 65535.0f);
			ok = TIFFWriteScanline(tif, row, y, 0) == 1;
		}
		ok = ok && row;
		free(row);
	}
	TIFFClose(tif);
	return ok ? 0 : -1;
}

/* Median seconds of kg_image_read of path on `threads` threads (0: default), and
 * whether every read gave exactly ref's samples. */
static double time_read(const char *path, int threads, int reps, const kg_image *ref,
                        int *same, char *why, size_t why_size)
{
	double t[MAX_REPS];
	int old = kg_image_set_read_threads(threads);
	*same = 1;
	for (int k = 0; k < reps; k++) {
		kg_image *img = NULL;
		kg_err err = {{0}};
		double t0 = kg_bench_now();
		int ret = kg_image_read(path, &img, &err);
		t[k] = kg_bench_now() - t0;
		if (ret) {
			snprintf(why, why_size, "%s", err.msg);
			*same = 0;
			kg_image_set_read_threads(old);
			return NAN;
		}
		size_t n = (size_t)img->width * img->height * img->channels;
		if (img->width != ref->width || img->height != ref->height ||
		    img->channels != ref->channels || memcmp(img->data, ref->data, n * sizeof(float)))
			*same = 0;
		kg_image_free(&img);
	}
	kg_image_set_read_threads(old);
	return median(t, reps);
}

/* Median seconds of kg_image_map (the chart check's reader: the codes of a 16-bit
 * file, mapped or decoded) on the default threads, and whether every code reads as
 * ref's float; NAN when the file is not for it. */
static double time_map(const char *path, int reps, const kg_image *ref, int *same)
{
	double t[MAX_REPS];
	const float *lut = kg_image_u16_lut();
	*same = 1;
	for (int k = 0; k < reps; k++) {
		kg_image *img = NULL;
		kg_err err = {{0}};
		double t0 = kg_bench_now();
		int ret = kg_image_map(path, &img, &err);
		t[k] = kg_bench_now() - t0;
		if (ret) {
			*same = 0;
			return NAN;
		}
		size_t n = (size_t)img->width * img->height * img->channels;
		for (size_t i = 0; *same && i < n; i++)
			*same = lut[img->u16[i]] == ref->data[i];
		kg_image_free(&img);
	}
	return median(t, reps);
}

int main(int argc, char **argv)
{
	char kogei_built[4096];
	{
		/* the kogei beside this program's build folder */
		char self[4096];
		ssize_t n = readlink("/proc/self/exe", self, sizeof(self) - 1);
		self[n > 0 ? n : 0] = '\0';
		snprintf(kogei_built, sizeof(kogei_built), "%s/../cli/kogei", dirname(self));
	}
	const char *kogei = kogei_built, *before = NULL, *keep = NULL;
	int width = 4000, height = 3000, reps = 5;
	for (int i = 1; i < argc; i++) {
		const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
		if (!strcmp(a, "--kogei") && v)
			kogei = argv[++i];
		else if (!strcmp(a, "--kogei-before") && v)
			before = argv[++i];
		else if (!strcmp(a, "--width") && v)
			width = atoi(argv[++i]);
		else if (!strcmp(a, "--height") && v)
			height = atoi(argv[++i]);
		else if (!strcmp(a, "--reps") && v)
			reps = atoi(argv[++i]);
		else if (!strcmp(a, "--keep") && v)
			keep = argv[++i];
		else {
			fprintf(stderr, "usage: kogei-bench-tiff [--kogei PATH] [--kogei-before PATH] "
			        "[--width W --height H] [--reps N] [--keep DIR]\n");
			return 2;
		}
	}
	if (reps < 1 || reps > MAX_REPS || width < 64 || height < 64) {
		fprintf(stderr, "kogei-bench-tiff: --reps 1 to %d, --width and --height 64 or more\n",
		        MAX_REPS);
		return 2;
	}
	char dir[4096];
	if (keep) {
		snprintf(dir, sizeof(dir), "%s", keep);
		if (mkdir(dir, 0755) != 0 && errno != EEXIST) {
			fprintf(stderr, "kogei-bench-tiff: --keep %s: %s\n", dir, strerror(errno));
			return 1;
		}
	} else {
		const char *tmp = getenv("TMPDIR");
		snprintf(dir, sizeof(dir), "%s/kogei-bench-tiff-XXXXXX", tmp && *tmp ? tmp : "/tmp");
		if (!mkdtemp(dir)) {
			perror("mkdtemp");
			return 1;
		}
	}
	char src[4200], camera[4200], spectra[4200], wtext[16], htext[16];
	snprintf(src, sizeof(src), "%s/chart.tif", dir);
	snprintf(camera, sizeof(camera), "%s/camera.csv", dir);
	snprintf(spectra, sizeof(spectra),
	         "%s/../shared/reference/charts/colorchecker24_babelcolor_avg.csv", KG_SOURCE_ROOT);
	int have_spectra = access(spectra, R_OK) == 0;
	snprintf(wtext, sizeof(wtext), "%d", width);
	snprintf(htext, sizeof(htext), "%d", height);
	if (access(src, R_OK) != 0) {
		write_camera(camera);
		char *sim[] = {(char *)kogei, "sim", "chart", "--layout", "colorchecker24-frame",
		               "--camera", camera, "--illuminant", "D65", "--width", wtext,
		               "--height", htext, "--blur", "1.0", "--vignetting", "0.2", "--noise",
		               "20000:5:12", "--depth", "16", "--seed", "11", "--paper", "0.03",
		               "-o", src, have_spectra ? "--spectra" : NULL, spectra, NULL};
		fprintf(stderr, "kogei-bench-tiff: rendering %s\n", src);
		if (kg_bench_run_program(sim, 1) != 0) {
			fprintf(stderr, "kogei-bench-tiff: %s sim chart failed\n", kogei);
			return 1;
		}
	}
	kg_err err = {{0}};
	kg_image *ref = NULL;
	if (kg_image_read(src, &ref, &err)) {
		fprintf(stderr, "kogei-bench-tiff: %s\n", err.msg);
		return 1;
	}
	int cpus = kg_cpu_count(8);
	printf("Reading a %d x %d (%.1f Mpix) 16-bit RGB TIFF (kogei sim chart: the unframed "
	       "ColorChecker), written again in each layout with libtiff; kg_image_read on 1 "
	       "thread and on the default %d (the CPUs this process may use), and the whole "
	       "`kogei chart detect --layout colorchecker24-frame` (a subprocess, wall time, "
	       "peak RSS); median of %d runs, page cache warm. Identical: both reads give "
	       "exactly the samples of the uncompressed file, and the codes (kg_image_map, "
	       "what chart detect reads) read as them.\n\n",
	       width, height, width * (double)height / 1e6, cpus,
	       reps);
	printf("| layout | file (MB) | read, 1 thread (ms) | read, %d threads (ms) | speed-up | "
	       "identical | codes, %d threads (ms) | chart detect (ms) | peak RSS (MiB) |%s\n",
	       cpus, cpus, before ? " chart detect, --kogei-before (ms) | peak RSS, before (MiB) |" : "");
	printf("|---|--:|--:|--:|--:|---|--:|--:|--:|%s\n", before ? "--:|--:|" : "");
	for (int i = 0; i < NLAYOUTS; i++) {
		const layout *l = &layouts[i];
		char path[4300], cgats[4300], rss_file[4300], why[1100] = "";
		snprintf(path, sizeof(path), "%s/%s", dir, l->file);
		snprintf(cgats, sizeof(cgats), "%s/%s.cgats", dir, l->file);
		snprintf(rss_file, sizeof(rss_file), "%s/%s.rss", dir, l->file);
		if (access(path, R_OK) != 0 && write_layout(path, ref, l) != 0) {
			fprintf(stderr, "kogei-bench-tiff: cannot write %s\n", path);
			return 1;
		}
		struct stat st;
		double mb = stat(path, &st) == 0 ? st.st_size / 1e6 : NAN;
		int same1 = 0, sameN = 0;
		double t1 = time_read(path, 1, reps, ref, &same1, why, sizeof(why));
		double tN = time_read(path, 0, reps, ref, &sameN, why, sizeof(why));
		int same_codes = 0;
		double tm = time_map(path, reps, ref, &same_codes);
		double whole[MAX_REPS], whole_b[MAX_REPS], wm = NAN, wbm = NAN;
		long rss = 0, rss_max = 0, rss_before = 0;
		char *cmd[] = {(char *)kogei, "chart", "detect", "--layout", "colorchecker24-frame",
		               "--quiet", path, "-o", cgats, NULL};
		int ok = 1;
		for (int k = 0; k < reps && ok; k++) {
			whole[k] = run_timed(cmd, &rss, rss_file);
			ok = whole[k] >= 0;
			if (rss > rss_max)
				rss_max = rss;
		}
		if (ok)
			wm = median(whole, reps);
		if (before) {
			cmd[0] = (char *)before;
			ok = 1;
			for (int k = 0; k < reps && ok; k++) {
				whole_b[k] = run_timed(cmd, &rss, rss_file);
				ok = whole_b[k] >= 0;
				if (rss > rss_before)
					rss_before = rss;
			}
			if (ok)
				wbm = median(whole_b, reps);
		}
		fprintf(stderr, "kogei-bench-tiff: %s: read %.3f s / %.3f s, chart detect %.3f s%s\n",
		        l->name, t1, tN, wm, why[0] ? why : "");
		printf("| %s | %.1f | %.1f | %.1f | %.2f x | %s | ", l->name, mb, 1e3 * t1, 1e3 * tN,
		       t1 / tN, same1 && sameN && (same_codes || !isfinite(tm)) ? "yes" : "NO");
		if (isfinite(tm))
			printf("%.1f%s | ", 1e3 * tm, l->compression == COMPRESSION_NONE ? " (mapped)" : "");
		else
			printf("- | ");
		if (isfinite(wm) && rss_max > 0)
			printf("%.1f | %.0f |", 1e3 * wm, rss_max / 1024.0);
		else if (isfinite(wm))
			printf("%.1f | - |", 1e3 * wm);
		else
			printf("failed | - |");
		if (before && isfinite(wbm) && rss_before > 0)
			printf(" %.1f | %.0f |", 1e3 * wbm, rss_before / 1024.0);
		else if (before && isfinite(wbm))
			printf(" %.1f | - |", 1e3 * wbm);
		else if (before)
			printf(" failed | - |");
		printf("\n");
	}
	kg_image_free(&ref);
	if (!keep) {
		for (int i = 0; i < NLAYOUTS; i++) {
			char path[4300];
			snprintf(path, sizeof(path), "%s/%s", dir, layouts[i].file);
			remove(path);
			snprintf(path, sizeof(path), "%s/%s.cgats", dir, layouts[i].file);
			remove(path);
		}
		remove(src);
		remove(camera);
		rmdir(dir);
	}
	return 0;
}
