/* Files written atomically: data goes to a temporary name beside the target and is
 * renamed over it only when complete, so a reader never sees a half-written file. */
#ifndef KG_FSUTIL_H
#define KG_FSUTIL_H

#include <stdio.h>

#include "error.h"

typedef struct kg_outfile {
	FILE *fp;
	char *path;     /* final name; "-" means standard output */
	char *tmp_path; /* temporary name, NULL for standard output */
} kg_outfile;

/* Open path for writing (binary). "-" writes to stdout when allow_stdout is set. */
int kg_outfile_open(kg_outfile *o, const char *path, int allow_stdout, kg_err *err);
/* Flush, fsync and rename into place. On failure the temporary file is removed. */
int kg_outfile_commit(kg_outfile *o, kg_err *err);
/* Abandon: close and remove the temporary file. Safe to call after commit. */
void kg_outfile_abort(kg_outfile *o);

/* Read a whole file into a NUL-terminated buffer (caller frees). */
int kg_read_file(const char *path, char **buf, size_t *len, kg_err *err);
/* Create a directory and its parents (like mkdir -p). */
int kg_mkdir_p(const char *path, kg_err *err);
/* A bundled data file (e.g. "materials/default.json"): $KOGEI_DATA_DIR, then the
 * installed data directory, then the source tree's fixtures/. Caller frees. */
char *kg_data_path(const char *name);
/* Join dir and name into a newly allocated path. */
char *kg_path_join(const char *dir, const char *name);

/* CPUs this process may run on (its affinity mask: taskset, cgroups' cpusets), at
 * least 1 and at most max: the default thread count of every parallel loop. */
int kg_cpu_count(int max);

#endif
