/* Files written atomically: data go to a file that has no name until it is complete
 * and is then put in place under its final name in one rename, so a reader never sees
 * a half-written file and an interrupted writer leaves nothing behind.
 *
 * Temporaries (kg_atomicfile, under kg_outfile and the ENVI writer): on Linux the data go
 * to an anonymous file (open(dir, O_TMPFILE)) that vanishes with the process however
 * it ends, SIGKILL included; when complete it is linked to a hidden unique name beside
 * the target and renamed over it. Where the file system has no O_TMPFILE, or
 * KOGEI_TMPFILE=named asks for it (tests), the data go to a hidden name of kogei's own
 * pattern, ".<name>.kogei-tmp.<pid>.<6 characters>", which a handler of SIGINT, SIGTERM
 * and SIGHUP removes before the signal takes its default course (handlers installed
 * once, only where the signal still has its default action; a front end that handles a
 * signal itself aborts its writers). Temporaries of that pattern whose process is gone
 * (killed with SIGKILL, or a crash) are removed when a writer next opens a file in
 * their directory.
 *
 * No command overwrites what it reads. Every reader in core (kg_read_file, and through
 * it the CGATS, CSV and layout readers; kg_json_load; the TIFF and PNG readers; both
 * files of an ENVI cube) and the PLY loader note the file they opened, by device and
 * inode, in one process-wide registry of inputs. Every writer checks its final name
 * against it before it writes anything and again before it renames into place
 * (kg_outfile_open and kg_outfile_commit, through which the CGATS, CSV, JSON, TIFF,
 * PNG, plot, SVG/PDF and PLY writers go; the ENVI writer; a session's frame files), so
 * -o naming an input, a hard link to one or a symbolic link to one fails with KG_EINVAL
 * and leaves the input as it was. A name that does not exist yet cannot collide; a
 * writer of several files (a cube and its header, a label map and its .json and .png)
 * checks every name before the first is renamed into place. */
#ifndef KG_FSUTIL_H
#define KG_FSUTIL_H

#include <stdio.h>

#include "error.h"

/* A file under construction: fd is open for reading and writing; nothing appears
 * under path until kg_atomicfile_commit. */
typedef struct kg_atomicfile {
	int fd;         /* -1 when closed */
	char *path;     /* final name */
	char *tmp_path; /* the named temporary (fallback), NULL while anonymous */
	int slot;       /* its entry in the registry of live temporaries, -1 if none */
} kg_atomicfile;

/* Start a file that will be named path (permissions 0644). Checks path against the
 * inputs and first removes the dead processes' temporaries in its directory. */
int kg_atomicfile_open(kg_atomicfile *t, const char *path, kg_err *err);
/* kg_atomicfile_open with flags: KG_ATOMICFILE_NO_SWEEP leaves the directory's stale
 * temporaries alone (a writer of many files in one directory, such as a frame recorder,
 * sweeps once with kg_atomicfile_sweep instead of at every file). */
enum { KG_ATOMICFILE_NO_SWEEP = 1u << 0 };
int kg_atomicfile_open_flags(kg_atomicfile *t, const char *path, unsigned flags, kg_err *err);
/* Remove the temporaries of kogei's pattern in dir whose process is gone. */
void kg_atomicfile_sweep(const char *dir);
/* Close fd (the caller has written and, if it wants durability, fsynced it) and put
 * the file in place under path, replacing any file of that name. On failure nothing
 * is left behind. Either way t is cleared. */
int kg_atomicfile_commit(kg_atomicfile *t, kg_err *err);
/* Abandon: close and remove the temporary. Safe on a cleared or committed t. */
void kg_atomicfile_abort(kg_atomicfile *t);

typedef struct kg_outfile {
	FILE *fp;
	char *path;     /* final name; "-" means standard output */
	kg_atomicfile tmp; /* the file under construction (fd -1 for standard output) */
} kg_outfile;

/* Open path for writing (binary). "-" writes to stdout when allow_stdout is set. */
int kg_outfile_open(kg_outfile *o, const char *path, int allow_stdout, kg_err *err);
/* Flush, fsync and rename into place. On failure the temporary file is removed. */
int kg_outfile_commit(kg_outfile *o, kg_err *err);
/* Abandon: close and remove the temporary file. Safe to call after commit. */
void kg_outfile_abort(kg_outfile *o);

/* Note path (opened for reading through fd, or -1 to stat the name) as an input of
 * this process. A file that cannot be stat'ed is not noted. Thread-safe. */
void kg_inputs_add(const char *path, int fd);
/* A file read only to be rewritten by its owner (a session's manifest, a recording's
 * index) is not an input: drop it from the registry. */
void kg_inputs_forget(const char *path);
/* 0 if writing path cannot replace an input of this process, else KG_EINVAL with
 * "<path>: is an input of this command (<input>); choose another output name". "-"
 * (standard output) never collides. */
int kg_inputs_check_output(const char *path, kg_err *err);
/* Empty the registry: a front end that runs one job after another (the console, a test
 * that writes what it read) starts each job with no inputs. */
void kg_inputs_reset(void);

/* All n bytes of buf to fd, a write interrupted by a signal (EINTR) tried again: 0, or
 * -1 with errno set. */
int kg_write_all(int fd, const void *buf, size_t n);
/* Read a whole file into a NUL-terminated buffer (caller frees); the file is noted as
 * an input. */
int kg_read_file(const char *path, char **buf, size_t *len, kg_err *err);
/* Create a directory and its parents (like mkdir -p). */
int kg_mkdir_p(const char *path, kg_err *err);
/* A bundled data file (e.g. "materials/default.json"): $KOGEI_DATA_DIR, then the
 * installed data directory, then the source tree's fixtures/. Caller frees. */
char *kg_data_path(const char *name);
/* A bundled data file known by name: "colorchecker24-frame" is charts/....json. */
typedef struct kg_data_name {
	const char *name;
	const char *file; /* for kg_data_path */
} kg_data_name;
/* What a command-line argument naming a data file means: arg itself when a file of that
 * name exists or it contains a '/'; else the bundled file whose name is arg (a ".json"
 * suffix is allowed) among the n of table. An unknown name fails with KG_ENOENT and a
 * message that lists the bundled names of this kind (what: "chart layout"). *path is
 * newly allocated. */
int kg_data_resolve(const char *arg, const char *what, const kg_data_name *table, int n,
                    char **path, kg_err *err);
/* A name that stays one path component everywhere (capture names, recorded frame
 * folders): 1 to max_len - 1 characters of [A-Za-z0-9._-], not starting with '.'. */
int kg_name_is_safe(const char *name, size_t max_len);
/* A relative path that cannot leave the directory it is relative to: components
 * separated by single '/', each a kg_name_is_safe name of at most max_len - 1
 * characters (so no "", ".", ".." component, no absolute path, no backslash). */
int kg_relpath_is_safe(const char *rel, size_t max_len);
/* A failed write of path as an error: KG_ENOSPC, with a message naming ENOSPC, when
 * errnum says the disk (or the quota) is full; KG_EIO otherwise. what names the step
 * ("write failed", "cannot create"). Returns the code. */
int kg_fail_write(kg_err *err, int errnum, const char *path, const char *what);

/* Paths below a root (a session, an output folder) with no symbolic link on the way:
 * rel is walked one component at a time from root with openat(O_NOFOLLOW), so neither a
 * folder of rel nor its last component may be a symbolic link (root itself may be). A
 * link fails with KG_EINVAL and "<root>/<rel up to the link>: is a symbolic link; ...";
 * an absolute rel or a "..", "." or empty component fails with KG_EINVAL.
 *
 * kg_open_below: open root/rel with flags (O_NOFOLLOW and O_CLOEXEC added; with O_CREAT
 * the missing folders of rel are made too); the fd, or minus the error code. */
int kg_open_below(const char *root, const char *rel, int flags, int mode, kg_err *err);
/* lstat of root/rel (KG_ENOENT, with a message, when it does not exist). */
struct stat;
int kg_stat_below(const char *root, const char *rel, struct stat *st, kg_err *err);
/* 0 when root/rel does not exist or is reached and is no symbolic link; else the error. */
int kg_check_below(const char *root, const char *rel, kg_err *err);
/* Make root/rel and its missing parents below root (like mkdir -p); each must be a
 * real folder. */
int kg_mkdir_below(const char *root, const char *rel, kg_err *err);
/* kg_read_file of root/rel, opened as kg_open_below does (noted as an input). */
int kg_read_below(const char *root, const char *rel, char **buf, size_t *len, kg_err *err);

/* The directory part of a path, newly allocated: "." when there is none, "/" for a
 * path directly below the root. */
char *kg_path_dir(const char *path);

/* Join dir and name into a newly allocated path. */
char *kg_path_join(const char *dir, const char *name);

/* path relative to dir when it lies below it ("dir/a/b" -> "a/b", compared as written,
 * no file system access), else path itself; dir NULL or empty: path. Points into path. */
const char *kg_path_below(const char *path, const char *dir);

/* CPUs this process may run on (its affinity mask: taskset, cgroups' cpusets), at
 * least 1 and at most max: the default thread count of every parallel loop. */
int kg_cpu_count(int max);

#endif
