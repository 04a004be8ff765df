#include <errno.h>
#include <pthread.h>
#include <sched.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fsutil.h"
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

int kg_outfile_open(kg_outfile *o, const char *path, int allow_stdout, kg_err *err)
{
	memset(o, 0, sizeof(*o));
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
	int ret = kg_inputs_check_output(path, err);
	if (ret)
		return ret;
	o->path = strdup(path);
	size_t n = strlen(path) + 32;
	o->tmp_path = malloc(n);
	if (!o->path || !o->tmp_path) {
		kg_outfile_abort(o);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", path);
	}
	snprintf(o->tmp_path, n, "%s.tmp.XXXXXX", path);
	int fd = mkstemp(o->tmp_path);
	if (fd < 0) {
		int e = errno;
		free(o->tmp_path);
		o->tmp_path = NULL;
		kg_outfile_abort(o);
		return kg_fail_write(err, e, path, "cannot create");
	}
	fchmod(fd, 0644);
	o->fp = fdopen(fd, "wb");
	if (!o->fp) {
		close(fd);
		kg_outfile_abort(o);
		return kg_fail(err, KG_EIO, "%s: cannot open: %s", path, strerror(errno));
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
	if (fclose(o->fp) != 0 && ret == 0)
		ret = kg_fail_write(err, errno, o->path, "write failed");
	o->fp = NULL;
	if (ret == 0)
		ret = kg_inputs_check_output(o->path, err);
	if (ret == 0 && rename(o->tmp_path, o->path) != 0)
		ret = kg_fail(err, KG_EIO, "%s: cannot rename into place: %s", o->path,
		              strerror(errno));
	if (ret == 0) {
		free(o->tmp_path);
		o->tmp_path = NULL;
	}
	kg_outfile_abort(o);
	return ret;
}

void kg_outfile_abort(kg_outfile *o)
{
	if (o->fp && o->fp != stdout)
		fclose(o->fp);
	o->fp = NULL;
	if (o->tmp_path)
		unlink(o->tmp_path);
	free(o->tmp_path);
	free(o->path);
	o->tmp_path = NULL;
	o->path = NULL;
}

int kg_read_file(const char *path, char **buf, size_t *len, kg_err *err)
{
	FILE *fp = fopen(path, "rb");
	if (!fp)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s",
		               path, strerror(errno));
	kg_inputs_add(path, fileno(fp));
	size_t cap = 1 << 16, n = 0;
	char *b = malloc(cap + 1);
	while (b) {
		size_t got = fread(b + n, 1, cap - n, fp);
		n += got;
		if (n < cap)
			break;
		cap *= 2;
		char *nb = realloc(b, cap + 1);
		if (!nb) {
			free(b);
			b = NULL;
		} else
			b = nb;
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
