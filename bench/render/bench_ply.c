/* kogei-bench-ply: PLY load speed on a 1-million-triangle mesh (issue 7, item 2).
 *
 * The icosphere of level 8 (1,310,720 triangles, 655,362 vertices with normals) is
 * written to a temporary directory as binary little-endian, binary big-endian and
 * ASCII PLY (kg_ply_write_format), then each file is loaded repeatedly with
 * kg_ply_load (map the file, parse) and with kg_ply_load_mem (parse only, from a
 * buffer read beforehand). Printed: file size, median time, MB/s of file and Mtri/s,
 * beside the time to read the file into memory (the I/O floor; the files are in the
 * page cache, having just been written). Every load is checked against the mesh
 * written. A measurement, never a test. */
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "kg_mesh.h"

static double now(void)
{
	struct timespec ts;
	clock_gettime(CLOCK_MONOTONIC, &ts);
	return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int cmp_double(const void *a, const void *b)
{
	double x = *(const double *)a, y = *(const double *)b;
	return x < y ? -1 : x > y;
}

static double median(double *t, int n)
{
	qsort(t, (size_t)n, sizeof(double), cmp_double);
	return n % 2 ? t[n / 2] : 0.5 * (t[n / 2 - 1] + t[n / 2]);
}

static int same(const kg_mesh *a, const kg_mesh *b)
{
	return a->nverts == b->nverts && a->ntris == b->ntris && b->normal &&
	       memcmp(a->pos, b->pos, a->nverts * 3 * sizeof(float)) == 0 &&
	       memcmp(a->normal, b->normal, a->nverts * 3 * sizeof(float)) == 0 &&
	       memcmp(a->tri, b->tri, a->ntris * 3 * sizeof(uint32_t)) == 0;
}

static void usage(FILE *fp)
{
	fprintf(fp,
	        "usage: kogei-bench-ply [--level L] [--repeat N]\n"
	        "Load speed of binary LE, binary BE and ASCII PLY on an icosphere of level L\n"
	        "(default 8: 1,310,720 triangles), median of N loads (default 7; ASCII: N/2+1).\n");
}

int main(int argc, char **argv)
{
	int level = 8, repeat = 7;
	static const struct option opts[] = {
		{ "level", required_argument, NULL, 'l' },
		{ "repeat", required_argument, NULL, 'r' },
		{ "help", no_argument, NULL, 'h' },
		{ NULL, 0, NULL, 0 },
	};
	int c;
	while ((c = getopt_long(argc, argv, "l:r:h", opts, NULL)) != -1) {
		if (c == 'l')
			level = atoi(optarg);
		else if (c == 'r')
			repeat = atoi(optarg);
		else if (c == 'h') {
			usage(stdout);
			return 0;
		} else {
			usage(stderr);
			return 2;
		}
	}
	if (optind != argc || level < 0 || level > 10 || repeat < 1 || repeat > 1000) {
		usage(stderr);
		return 2;
	}
	kg_err err = { { 0 } };
	kg_mesh *mesh = NULL;
	if (kg_mesh_icosphere((unsigned)level, &mesh, &err) != 0) {
		fprintf(stderr, "kogei-bench-ply: %s\n", err.msg);
		return 1;
	}
	char dir[] = "/tmp/kogei-bench-ply-XXXXXX";
	if (!mkdtemp(dir)) {
		perror("kogei-bench-ply: mkdtemp");
		kg_mesh_free(&mesh);
		return 1;
	}
	static const struct {
		const char *name, *file;
		kg_ply_format format;
	} enc[] = {
		{ "binary LE", "le.ply", KG_PLY_BINARY_LE },
		{ "binary BE", "be.ply", KG_PLY_BINARY_BE },
		{ "ASCII", "ascii.ply", KG_PLY_ASCII },
	};
	printf("PLY load, icosphere level %d: %zu triangles, %zu vertices with normals\n", level,
	       mesh->ntris, mesh->nverts);
	printf("%-10s %9s %10s %9s %8s %10s %9s %8s %9s\n", "encoding", "MB", "load ms", "MB/s",
	       "Mtri/s", "parse ms", "MB/s", "Mtri/s", "read ms");
	int status = 0;
	for (size_t e = 0; e < sizeof(enc) / sizeof(enc[0]); e++) {
		char *path = kg_path_join(dir, enc[e].file);
		if (kg_ply_write_format(mesh, path, enc[e].format, &err) != 0) {
			fprintf(stderr, "kogei-bench-ply: %s\n", err.msg);
			free(path);
			status = 1;
			break;
		}
		struct stat st;
		stat(path, &st);
		double mb = (double)st.st_size / 1e6;
		int n = enc[e].format == KG_PLY_ASCII ? repeat / 2 + 1 : repeat;
		double *t_load = malloc((size_t)n * sizeof(double)),
		       *t_parse = malloc((size_t)n * sizeof(double)),
		       *t_read = malloc((size_t)n * sizeof(double));
		for (int i = 0; i < n && status == 0; i++) {
			kg_mesh *m = NULL;
			double t0 = now();
			int r = kg_ply_load(path, &m, &err);
			t_load[i] = now() - t0;
			if (r != 0 || !same(mesh, m)) {
				fprintf(stderr, "kogei-bench-ply: %s: %s\n", path,
				        r ? err.msg : "loaded mesh differs from the one written");
				status = 1;
			}
			kg_mesh_free(&m);
			char *buf = NULL;
			size_t len = 0;
			t0 = now();
			r = kg_read_file(path, &buf, &len, &err);
			t_read[i] = now() - t0;
			t0 = now();
			if (r == 0)
				r = kg_ply_load_mem(buf, len, path, &m, &err);
			t_parse[i] = now() - t0;
			if (r != 0) {
				fprintf(stderr, "kogei-bench-ply: %s\n", err.msg);
				status = 1;
			}
			kg_mesh_free(&m);
			free(buf);
		}
		if (status == 0) {
			double tl = median(t_load, n), tp = median(t_parse, n), tr = median(t_read, n);
			double mtri = (double)mesh->ntris / 1e6;
			printf("%-10s %9.1f %10.1f %9.0f %8.2f %10.1f %9.0f %8.2f %9.1f\n", enc[e].name,
			       mb, tl * 1e3, mb / tl, mtri / tl, tp * 1e3, mb / tp, mtri / tp, tr * 1e3);
		}
		free(t_load);
		free(t_parse);
		free(t_read);
		unlink(path);
		free(path);
		if (status)
			break;
	}
	rmdir(dir);
	kg_mesh_free(&mesh);
	return status;
}
