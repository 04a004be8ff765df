#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "fsutil.h"
#include "memutil.h"
#include "kg_config.h"

/* The process's inputs: a short list (a command reads a handful of files), searched
 * linearly. The one process-level registry of core, so that every writer checks the
 * same thing whatever front end called it. */
typedef struct input_file {
	dev_t dev;
	ino_t ino;
	char *path;
} input_file;

static struct {
	pthread_mutex_t lock;
	input_file *files;
	size_t n, cap;
} inputs = {PTHREAD_MUTEX_INITIALIZER, NULL, 0, 0};

void kg_inputs_add(const char *path, int fd)
{
	struct stat st;
	if (!path || (fd >= 0 ? fstat(fd, &st) : stat(path, &st)) != 0 || !S_ISREG(st.st_mode))
		return;
	pthread_mutex_lock(&inputs.lock);
	int known = 0;
	for (size_t i = 0; i < inputs.n && !known; i++)
		known = inputs.files[i].dev == st.st_dev && inputs.files[i].ino == st.st_ino;
	if (!known && inputs.n == inputs.cap) {
		size_t cap = inputs.cap ? 2 * inputs.cap : 16;
		input_file *f = realloc(inputs.files, cap * sizeof(*f));
		if (f) {
			inputs.files = f;
			inputs.cap = cap;
		}
	}
	char *copy = known || inputs.n == inputs.cap ? NULL : strdup(path);
	if (copy)
		inputs.files[inputs.n++] = (input_file){st.st_dev, st.st_ino, copy};
	pthread_mutex_unlock(&inputs.lock);
}

void kg_inputs_forget(const char *path)
{
	struct stat st;
	if (!path || stat(path, &st) != 0)
		return;
	pthread_mutex_lock(&inputs.lock);
	for (size_t i = 0; i < inputs.n; i++)
		if (inputs.files[i].dev == st.st_dev && inputs.files[i].ino == st.st_ino) {
			free(inputs.files[i].path);
			inputs.files[i] = inputs.files[--inputs.n];
			break;
		}
	pthread_mutex_unlock(&inputs.lock);
}

int kg_inputs_check_output(const char *path, kg_err *err)
{
	struct stat st;
	if (!path || !strcmp(path, "-") || stat(path, &st) != 0)
		return 0;
	int ret = 0;
	pthread_mutex_lock(&inputs.lock);
	for (size_t i = 0; i < inputs.n && !ret; i++)
		if (inputs.files[i].dev == st.st_dev && inputs.files[i].ino == st.st_ino)
			ret = kg_fail(err, KG_EINVAL,
			              "%s: is an input of this command (%s); choose another output name",
			              path, inputs.files[i].path);
	pthread_mutex_unlock(&inputs.lock);
	return ret;
}

void kg_inputs_reset(void)
{
	pthread_mutex_lock(&inputs.lock);
	for (size_t i = 0; i < inputs.n; i++)
		free(inputs.files[i].path);
	free(inputs.files);
	inputs.files = NULL;
	inputs.n = inputs.cap = 0;
	pthread_mutex_unlock(&inputs.lock);
}

/* ---- temporaries ------------------------------------------------------------------ */

#define TMP_TAG ".kogei-tmp."

/* The named temporaries of this process that a signal must not leave behind. A fixed
 * table of atomic pointers, so that the handler reads it without locks or allocation;
 * a temporary that finds the table full is still removed by its writer's abort, and
 * after a signal by the next writer in its directory (the sweep below). */
enum { LIVE_MAX = 64 };
static char *_Atomic live_tmp[LIVE_MAX];
static pthread_once_t handlers_once = PTHREAD_ONCE_INIT;
static const int cleanup_signals[] = {SIGINT, SIGTERM, SIGHUP};

static void on_fatal_signal(int sig)
{
	int saved = errno;
	for (int i = 0; i < LIVE_MAX; i++) {
		char *p = atomic_load(&live_tmp[i]);
		if (p)
			unlink(p);
	}
	errno = saved;
	/* SA_RESETHAND has restored the default action; the signal is blocked until the
	 * handler returns and then ends the process as it would have. */
	raise(sig);
}

static void install_handlers(void)
{
	for (size_t i = 0; i < sizeof(cleanup_signals) / sizeof(cleanup_signals[0]); i++) {
		struct sigaction old, sa;
		if (sigaction(cleanup_signals[i], NULL, &old) != 0 ||
		    (old.sa_flags & SA_SIGINFO) || old.sa_handler != SIG_DFL)
			continue; /* ignored, or the front end's own handler */
		memset(&sa, 0, sizeof(sa));
		sa.sa_handler = on_fatal_signal;
		sa.sa_flags = SA_RESETHAND;
		sigemptyset(&sa.sa_mask);
		sigaction(cleanup_signals[i], &sa, NULL);
	}
}

static int live_add(char *path)
{
	pthread_once(&handlers_once, install_handlers);
	for (int i = 0; i < LIVE_MAX; i++) {
		char *expected = NULL;
		if (atomic_compare_exchange_strong(&live_tmp[i], &expected, path))
			return i;
	}
	return -1;
}

static void live_remove(int slot)
{
	if (slot >= 0)
		atomic_store(&live_tmp[slot], NULL);
}

/* "<dir>/.<base>.kogei-tmp.<pid>.<6 characters>" for path (caller frees). */
static char *tmp_name(const char *path)
{
	static _Atomic uint64_t counter;
	static const char chars[] = "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789";
	const char *slash = strrchr(path, '/');
	size_t dirlen = slash ? (size_t)(slash - path) + 1 : 0;
	size_t n = strlen(path) + sizeof(TMP_TAG) + 32;
	char *s = malloc(n);
	if (!s)
		return NULL;
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	uint64_t x = (uint64_t)ts.tv_nsec ^ ((uint64_t)ts.tv_sec << 30) ^
	             ((uint64_t)getpid() << 16) ^ (atomic_fetch_add(&counter, 1) * 0x9E3779B97F4A7C15ULL);
	char suffix[7];
	for (int i = 0; i < 6; i++) {
		x ^= x >> 33;
		x *= 0xff51afd7ed558ccdULL;
		x ^= x >> 29;
		suffix[i] = chars[x % (sizeof(chars) - 1)];
	}
	suffix[6] = '\0';
	snprintf(s, n, "%.*s.%s" TMP_TAG "%ld.%s", (int)dirlen, path, path + dirlen,
	         (long)getpid(), suffix);
	return s;
}

/* The pid in a name of tmp_name's pattern, or 0 when name is not one. */
static long tmp_name_pid(const char *name)
{
	if (name[0] != '.')
		return 0;
	const char *tag = NULL;
	for (const char *p = strstr(name, TMP_TAG); p; p = strstr(p + 1, TMP_TAG))
		tag = p;
	if (!tag)
		return 0;
	char *end;
	long pid = strtol(tag + strlen(TMP_TAG), &end, 10);
	return pid > 0 && end[0] == '.' && strlen(end + 1) == 6 ? pid : 0;
}

/* Remove the temporaries of dead processes in dir (a scan of its entries, at every
 * open: output directories hold few files). */
void kg_atomicfile_sweep(const char *dir)
{
	DIR *d = opendir(dir);
	if (!d)
		return;
	for (struct dirent *e; (e = readdir(d));) {
		long pid = tmp_name_pid(e->d_name);
		struct stat fs;
		if (pid && pid != (long)getpid() && kill((pid_t)pid, 0) != 0 && errno == ESRCH &&
		    fstatat(dirfd(d), e->d_name, &fs, AT_SYMLINK_NOFOLLOW) == 0 && S_ISREG(fs.st_mode))
			unlinkat(dirfd(d), e->d_name, 0);
	}
	closedir(d);
}

char *kg_path_dir(const char *path)
{
	const char *slash = strrchr(path, '/');
	if (!slash)
		return strdup(".");
	if (slash == path)
		return strdup("/");
	return strndup(path, (size_t)(slash - path));
}

/* Try unique hidden names of kogei's pattern beside t->path until attempt(t, name)
 * succeeds (returns >= 0, taken as the result; the name stays in t->tmp_path) or fails
 * otherwise than with EEXIST. -1 with errno on failure. */
static int with_unique_name(kg_atomicfile *t, int (*attempt)(kg_atomicfile *t, const char *name))
{
	for (int tries = 0; tries < 100; tries++) {
		char *name = tmp_name(t->path);
		if (!name) {
			errno = ENOMEM;
			return -1;
		}
		t->slot = live_add(name);
		int r = attempt(t, name);
		if (r >= 0) {
			t->tmp_path = name;
			return r;
		}
		int e = errno;
		live_remove(t->slot);
		t->slot = -1;
		free(name);
		if (e != EEXIST) {
			errno = e;
			return -1;
		}
	}
	errno = EEXIST;
	return -1;
}

static int create_exclusive(kg_atomicfile *t, const char *name)
{
	(void)t;
	return open(name, O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
}

int kg_atomicfile_open(kg_atomicfile *t, const char *path, kg_err *err)
{
	return kg_atomicfile_open_flags(t, path, 0, err);
}

int kg_atomicfile_open_flags(kg_atomicfile *t, const char *path, unsigned flags, kg_err *err)
{
	kg_check_arg(t && path, err);
	*t = (kg_atomicfile){.fd = -1, .slot = -1};
	if (!*path)
		return kg_fail(err, KG_EINVAL, "no output file given");
	int ret = kg_inputs_check_output(path, err);
	if (ret)
		return ret;
	char *dir = kg_path_dir(path);
	t->path = strdup(path);
	if (!dir || !t->path) {
		free(dir);
		kg_atomicfile_abort(t);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	}
	if (!(flags & KG_ATOMICFILE_NO_SWEEP))
		kg_atomicfile_sweep(dir);
	const char *mode = getenv("KOGEI_TMPFILE");
	int fd = -1;
	if (!mode || strcmp(mode, "named") != 0) {
		fd = open(dir, O_TMPFILE | O_RDWR | O_CLOEXEC, 0644);
		/* no O_TMPFILE here: an old kernel (EISDIR) or file system (EOPNOTSUPP) */
		if (fd < 0 && errno != EOPNOTSUPP && errno != EISDIR && errno != EINVAL &&
		    errno != ENOSYS) {
			int e = errno;
			free(dir);
			kg_atomicfile_abort(t);
			return kg_fail_write(err, e, path, "cannot create");
		}
	}
	free(dir);
	if (fd < 0 && (fd = with_unique_name(t, create_exclusive)) < 0) {
		int e = errno;
		kg_atomicfile_abort(t);
		return kg_fail_write(err, e, path, "cannot create");
	}
	t->fd = fd;
	fchmod(fd, 0644); /* as a new file of the user's, whatever the umask */
	return 0;
}

/* Give the anonymous file fd the name `name` (EEXIST if it is taken). */
static int link_anonymous(int fd, const char *name)
{
	if (linkat(fd, "", AT_FDCWD, name, AT_EMPTY_PATH) == 0)
		return 0;
	if (errno != ENOENT && errno != EPERM)
		return -1;
	char proc[64]; /* AT_EMPTY_PATH needs CAP_DAC_READ_SEARCH; /proc does not */
	snprintf(proc, sizeof(proc), "/proc/self/fd/%d", fd);
	return linkat(AT_FDCWD, proc, AT_FDCWD, name, AT_SYMLINK_FOLLOW);
}

/* Give the anonymous file t->fd the hidden name `name` (0, or -1 with errno). */
static int name_anonymous(kg_atomicfile *t, const char *name)
{
	return link_anonymous(t->fd, name);
}

int kg_atomicfile_commit(kg_atomicfile *t, kg_err *err)
{
	kg_check_arg(t && t->path, err);
	int ret = 0;
	if (t->fd < 0)
		ret = kg_fail(err, KG_EINVAL, "%s: output file not open", t->path);
	if (ret == 0 && !t->tmp_path && with_unique_name(t, name_anonymous) != 0)
		ret = kg_fail(err, KG_EIO, "%s: cannot link the finished file: %s", t->path,
		              strerror(errno));
	if (t->fd >= 0 && close(t->fd) != 0 && ret == 0)
		ret = kg_fail_write(err, errno, t->path, "write failed");
	t->fd = -1;
	if (ret == 0)
		ret = kg_inputs_check_output(t->path, err);
	if (ret == 0 && rename(t->tmp_path, t->path) != 0)
		ret = kg_fail(err, KG_EIO, "%s: cannot rename into place: %s", t->path,
		              strerror(errno));
	if (ret == 0) {
		live_remove(t->slot);
		t->slot = -1;
		free(t->tmp_path);
		t->tmp_path = NULL;
	}
	kg_atomicfile_abort(t);
	return ret;
}

void kg_atomicfile_abort(kg_atomicfile *t)
{
	if (!t)
		return;
	if (t->fd >= 0)
		close(t->fd);
	t->fd = -1;
	if (t->tmp_path)
		unlink(t->tmp_path);
	live_remove(t->slot);
	t->slot = -1;
	free(t->tmp_path);
	free(t->path);
	t->tmp_path = NULL;
	t->path = NULL;
}

/* ---- kg_outfile -------------------------------------------------------------------- */

int kg_outfile_open(kg_outfile *o, const char *path, int allow_stdout, kg_err *err)
{
	memset(o, 0, sizeof(*o));
	o->tmp.fd = o->tmp.slot = -1;
	if (!path || !*path)
		return kg_fail(err, KG_EINVAL, "no output file given");
	if (strcmp(path, "-") == 0) {
		if (!allow_stdout)
			return kg_fail(err, KG_EINVAL,
			               "output '-': this output is binary and cannot go to standard output");
		o->fp = stdout;
		o->path = strdup(path);
		return o->path ? 0 : KG_ENOMEM;
	}
	int ret = kg_atomicfile_open(&o->tmp, path, err);
	if (ret)
		return ret;
	o->path = strdup(path);
	if (!o->path) {
		kg_outfile_abort(o);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	}
	o->fp = fdopen(o->tmp.fd, "w+b");
	if (!o->fp) {
		int e = errno;
		kg_outfile_abort(o);
		return kg_fail(err, KG_EIO, "%s: cannot open: %s", path, strerror(e));
	}
	return 0;
}

int kg_outfile_commit(kg_outfile *o, kg_err *err)
{
	int ret = 0;
	if (!o->fp)
		return kg_fail(err, KG_EINVAL, "output file not open");
	if (o->fp == stdout) {
		if (fflush(stdout) != 0)
			ret = kg_fail(err, KG_EIO, "standard output: write failed: %s", strerror(errno));
		o->fp = NULL;
		kg_outfile_abort(o);
		return ret;
	}
	if (fflush(o->fp) != 0 || ferror(o->fp) || fsync(fileno(o->fp)) != 0)
		ret = kg_fail_write(err, errno, o->path, "write failed");
	/* the stream gives up its descriptor; kg_atomicfile_commit closes it */
	o->tmp.fd = dup(fileno(o->fp));
	if (o->tmp.fd < 0 && ret == 0)
		ret = kg_fail_write(err, errno, o->path, "write failed");
	fclose(o->fp);
	o->fp = NULL;
	if (ret == 0)
		ret = kg_atomicfile_commit(&o->tmp, err);
	kg_outfile_abort(o);
	return ret;
}

void kg_outfile_abort(kg_outfile *o)
{
	if (o->fp && o->fp != stdout) {
		fclose(o->fp);
		o->tmp.fd = -1; /* closed with the stream */
	}
	o->fp = NULL;
	kg_atomicfile_abort(&o->tmp);
	free(o->path);
	o->path = NULL;
}

/* b (cap + 1 bytes) at twice the capacity, or NULL (b freed) without memory. */
static char *grow_buffer(char *b, size_t *cap)
{
	*cap *= 2;
	char *nb = realloc(b, *cap + 1);
	if (!nb)
		free(b);
	return nb;
}

int kg_read_file(const char *path, char **buf, size_t *len, kg_err *err)
{
	FILE *fp = fopen(path, "rb");
	if (!fp)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s",
		               path, strerror(errno));
	kg_inputs_add(path, fileno(fp));
	/* a regular file's size is known: one buffer of that size (plus one byte, so that
	 * a file that grew is still read to its end), huge pages asked for over a large
	 * one, whose first-touch page faults otherwise cost more than the read */
	struct stat st;
	size_t cap = 1 << 16, n = 0;
	if (fstat(fileno(fp), &st) == 0 && S_ISREG(st.st_mode) && st.st_size >= 0 &&
	    (uint64_t)st.st_size < (uint64_t)SIZE_MAX / 2)
		cap = (size_t)st.st_size + 1;
	char *b = malloc(cap + 1);
	if (b)
		kg_advise_huge_pages(b, cap + 1);
	while (b) {
		size_t got = fread(b + n, 1, cap - n, fp);
		n += got;
		if (n < cap)
			break;
		b = grow_buffer(b, &cap);
	}
	int bad = ferror(fp);
	fclose(fp);
	if (!b)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory reading file", path);
	if (bad) {
		free(b);
		return kg_fail(err, KG_EIO, "%s: read error", path);
	}
	b[n] = '\0';
	*buf = b;
	if (len)
		*len = n;
	return 0;
}

int kg_write_all(int fd, const void *buf, size_t n)
{
	const char *p = buf;
	while (n) {
		ssize_t w = write(fd, p, n);
		if (w < 0 && errno == EINTR)
			continue;
		if (w <= 0)
			return -1;
		p += w;
		n -= (size_t)w;
	}
	return 0;
}

int kg_mkdir_p(const char *path, kg_err *err)
{
	char *p = strdup(path);
	if (!p)
		return KG_ENOMEM;
	for (char *s = p + 1;; s++) {
		if (*s == '/' || *s == '\0') {
			char c = *s;
			*s = '\0';
			if (mkdir(p, 0755) != 0 && errno != EEXIST) {
				int e = errno;
				int r = kg_fail(err, KG_EIO, "%s: cannot create directory: %s", p, strerror(e));
				free(p);
				return r;
			}
			*s = c;
			if (c == '\0')
				break;
		}
	}
	free(p);
	return 0;
}

int kg_fail_write(kg_err *err, int errnum, const char *path, const char *what)
{
	if (errnum == ENOSPC || errnum == EDQUOT)
		return kg_fail(err, KG_ENOSPC,
		               "%s: %s: %s (ENOSPC): the disk is full; free space or write elsewhere",
		               path, what, strerror(errnum));
	return kg_fail(err, KG_EIO, "%s: %s: %s", path, what, strerror(errnum));
}

int kg_name_is_safe(const char *s, size_t max_len)
{
	size_t n = s ? strlen(s) : 0;
	if (!n || n >= max_len || s[0] == '.')
		return 0;
	for (size_t i = 0; i < n; i++)
		if (!((s[i] >= 'a' && s[i] <= 'z') || (s[i] >= 'A' && s[i] <= 'Z') ||
		      (s[i] >= '0' && s[i] <= '9') || s[i] == '.' || s[i] == '_' || s[i] == '-'))
			return 0;
	return 1;
}

int kg_relpath_is_safe(const char *rel, size_t max_len)
{
	if (!rel || !*rel)
		return 0;
	char part[256];
	for (const char *p = rel;;) {
		const char *slash = strchr(p, '/');
		size_t n = slash ? (size_t)(slash - p) : strlen(p);
		if (n >= sizeof(part) || n >= max_len)
			return 0;
		memcpy(part, p, n);
		part[n] = 0;
		if (!kg_name_is_safe(part, max_len))
			return 0;
		if (!slash)
			return 1;
		p = slash + 1;
	}
}

char *kg_path_join(const char *dir, const char *name)
{
	size_t n = strlen(dir) + strlen(name) + 2;
	char *s = malloc(n);
	if (s)
		snprintf(s, n, "%s%s%s", dir, (*dir && dir[strlen(dir) - 1] != '/') ? "/" : "", name);
	return s;
}

const char *kg_path_below(const char *path, const char *dir)
{
	if (!path || !dir || !*dir)
		return path;
	size_t n = strlen(dir);
	while (n > 1 && dir[n - 1] == '/')
		n--;
	if (strncmp(path, dir, n) || path[n] != '/')
		return path;
	path += n;
	while (*path == '/')
		path++;
	return path;
}

char *kg_data_path(const char *name)
{
	const char *dirs[3] = {getenv("KOGEI_DATA_DIR"), KG_DATA_DIR, KG_SOURCE_ROOT "/fixtures"};
	for (int i = 0; i < 3; i++) {
		if (!dirs[i] || !*dirs[i])
			continue;
		char *p = kg_path_join(dirs[i], name);
		struct stat st;
		if (p && stat(p, &st) == 0)
			return p;
		free(p);
	}
	return kg_path_join(KG_SOURCE_ROOT "/fixtures", name);
}

int kg_data_resolve(const char *arg, const char *what, const kg_data_name *table, int n,
                    char **path, kg_err *err)
{
	kg_check_arg(arg && what && path && (table || n == 0), err);
	*path = NULL;
	struct stat st;
	if (stat(arg, &st) == 0 || strchr(arg, '/')) {
		*path = strdup(arg);
		return *path ? 0 : kg_fail(err, KG_ENOMEM, "%s: out of memory", arg);
	}
	size_t len = strlen(arg);
	if (len > 5 && !strcmp(arg + len - 5, ".json"))
		len -= 5;
	for (int i = 0; i < n; i++)
		if (strlen(table[i].name) == len && !strncmp(table[i].name, arg, len)) {
			*path = kg_data_path(table[i].file);
			return *path ? 0 : kg_fail(err, KG_ENOMEM, "%s: out of memory", arg);
		}
	char names[512] = "";
	for (int i = 0, at = 0; i < n && at < (int)sizeof(names); i++)
		at += snprintf(names + at, sizeof(names) - (size_t)at, "%s%s", i ? ", " : "",
		               table[i].name);
	return kg_fail(err, KG_ENOENT, "%s: no such file, and no bundled %s of that name "
	               "(expected a file or one of: %s)", arg, what, names);
}

int kg_cpu_count(int max)
{
	cpu_set_t set;
	long n = 0;
	if (sched_getaffinity(0, sizeof(set), &set) == 0)
		n = CPU_COUNT(&set);
	if (n < 1)
		n = sysconf(_SC_NPROCESSORS_ONLN);
	if (n < 1)
		n = 1;
	return max > 0 && n > max ? max : (int)n;
}

/* ---- paths below a root, no symbolic link on the way ------------------------------ */

/* The error for a component that is a symbolic link (or not a folder where one must
 * be): names root/rel up to that component. */
static int below_fail(kg_err *err, const char *root, const char *rel, size_t upto, int errnum,
                      int is_link)
{
	char shown[4096];
	snprintf(shown, sizeof(shown), "%s%s%.*s", root,
	         (*root && root[strlen(root) - 1] != '/') ? "/" : "", (int)upto, rel);
	if (is_link)
		return kg_fail(err, KG_EINVAL,
		               "%s: is a symbolic link; kogei writes and reads only real files and "
		               "folders inside %s (remove the link)",
		               shown, root);
	if (errnum == ENOTDIR)
		return kg_fail(err, KG_EINVAL, "%s: expected a folder", shown);
	return kg_fail(err, errnum == ENOENT ? KG_ENOENT : KG_EIO, "%s: %s", shown,
	               strerror(errnum));
}

/* Walk rel below root: *dirfd is left open on the folder that holds the last component,
 * *last points at that component. Every folder on the way is opened with O_NOFOLLOW;
 * with create, missing folders are made. */
static int walk_below(const char *root, const char *rel, int create, int *dirfd,
                      const char **last, kg_err *err)
{
	*dirfd = -1;
	if (!rel || !*rel || rel[0] == '/')
		return kg_fail(err, KG_EINVAL, "%s: '%s': expected a relative path inside it", root,
		               rel ? rel : "");
	int fd = open(root, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (fd < 0)
		return below_fail(err, root, "", 0, errno, 0);
	const char *p = rel;
	for (const char *slash; (slash = strchr(p, '/'));) {
		size_t n = (size_t)(slash - p);
		char part[256];
		if (!n || n >= sizeof(part) || (n == 1 && p[0] == '.') ||
		    (n == 2 && p[0] == '.' && p[1] == '.')) {
			close(fd);
			return kg_fail(err, KG_EINVAL, "%s: '%s': expected a path inside it (no '..', "
			               "'.' or empty component)", root, rel);
		}
		memcpy(part, p, n);
		part[n] = 0;
		if (create && mkdirat(fd, part, 0755) != 0 && errno != EEXIST) {
			int e = errno;
			close(fd);
			return below_fail(err, root, rel, (size_t)(slash - rel), e, 0);
		}
		int next = openat(fd, part, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
		if (next < 0) {
			int e = errno;
			struct stat st;
			int link = (e == ELOOP || e == ENOTDIR) &&
			           fstatat(fd, part, &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISLNK(st.st_mode);
			close(fd);
			return below_fail(err, root, rel, (size_t)(slash - rel), e, link);
		}
		close(fd);
		fd = next;
		p = slash + 1;
	}
	if (!*p || !strcmp(p, ".") || !strcmp(p, "..")) {
		close(fd);
		return kg_fail(err, KG_EINVAL, "%s: '%s': expected a path inside it (no '..', '.' "
		               "or empty component)", root, rel);
	}
	*dirfd = fd;
	*last = p;
	return 0;
}

int kg_open_below(const char *root, const char *rel, int flags, int mode, kg_err *err)
{
	kg_check_arg(root, err);
	int dfd;
	const char *last;
	int ret = walk_below(root, rel, (flags & O_CREAT) != 0, &dfd, &last, err);
	if (ret)
		return ret;
	int fd = openat(dfd, last, flags | O_NOFOLLOW | O_CLOEXEC, mode);
	if (fd < 0) {
		int e = errno;
		struct stat st;
		int link = fstatat(dfd, last, &st, AT_SYMLINK_NOFOLLOW) == 0 && S_ISLNK(st.st_mode);
		close(dfd);
		return below_fail(err, root, rel, strlen(rel), e, link);
	}
	close(dfd);
	return fd;
}

int kg_stat_below(const char *root, const char *rel, struct stat *st, kg_err *err)
{
	kg_check_arg(root && st, err);
	int dfd;
	const char *last;
	int ret = walk_below(root, rel, 0, &dfd, &last, err);
	if (ret)
		return ret;
	if (fstatat(dfd, last, st, AT_SYMLINK_NOFOLLOW) != 0) {
		int e = errno;
		close(dfd);
		return below_fail(err, root, rel, strlen(rel), e, 0);
	}
	close(dfd);
	if (S_ISLNK(st->st_mode))
		return below_fail(err, root, rel, strlen(rel), ELOOP, 1);
	return 0;
}

int kg_check_below(const char *root, const char *rel, kg_err *err)
{
	struct stat st;
	kg_err e = {{0}};
	int ret = kg_stat_below(root, rel, &st, &e);
	if (ret == KG_ENOENT)
		return 0;
	if (ret && err)
		*err = e;
	return ret;
}

int kg_mkdir_below(const char *root, const char *rel, kg_err *err)
{
	kg_check_arg(root && rel, err);
	size_t n = strlen(rel);
	char *with_slash = malloc(n + 3);
	if (!with_slash)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", root);
	/* walk "rel/x" so that every component of rel is a folder made or opened */
	snprintf(with_slash, n + 3, "%s/x", rel);
	int dfd;
	const char *last;
	int ret = walk_below(root, with_slash, 1, &dfd, &last, err);
	free(with_slash);
	if (!ret)
		close(dfd);
	return ret;
}

int kg_read_below(const char *root, const char *rel, char **buf, size_t *len, kg_err *err)
{
	kg_check_arg(root && buf, err);
	*buf = NULL;
	int fd = kg_open_below(root, rel, O_RDONLY, 0, err);
	if (fd < 0)
		return fd;
	char *path = kg_path_join(root, rel);
	struct stat st;
	int ret = 0;
	if (!path)
		ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", root);
	else if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode))
		ret = kg_fail(err, KG_EINVAL, "%s: expected a regular file", path);
	if (ret) {
		close(fd);
		free(path);
		return ret;
	}
	kg_inputs_add(path, fd);
	size_t cap = (size_t)st.st_size + 1, n = 0;
	char *b = malloc(cap + 1);
	while (b) {
		ssize_t got = read(fd, b + n, cap - n);
		if (got < 0 && errno == EINTR)
			continue;
		if (got < 0) {
			ret = kg_fail(err, KG_EIO, "%s: read error: %s", path, strerror(errno));
			break;
		}
		if (got == 0)
			break;
		n += (size_t)got;
		if (n == cap) {
			b = grow_buffer(b, &cap);
		}
	}
	close(fd);
	if (!b && !ret)
		ret = kg_fail(err, KG_ENOMEM, "%s: out of memory reading file", path);
	free(path);
	if (ret) {
		free(b);
		return ret;
	}
	b[n] = '\0';
	*buf = b;
	if (len)
		*len = n;
	return 0;
}
