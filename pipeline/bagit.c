/* BagIt 1.0 (RFC 8493) for kogei deposit: checksums of files (copied on the way),
 * the walk of a folder in a stable order, manifest paths, and the check of a bag
 * (kg_bag_verify). deposit.c writes bags with these. */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#include <openssl/evp.h>

#include "pipeline_private.h"

#define WALK_DEPTH_MAX 64

/* ---- checksums ------------------------------------------------------------------------ */

static void to_hex(const unsigned char *md, unsigned len, char *hex)
{
	static const char digits[] = "0123456789abcdef";
	for (unsigned i = 0; i < len; i++) {
		hex[2 * i] = digits[md[i] >> 4];
		hex[2 * i + 1] = digits[md[i] & 15];
	}
	hex[2 * len] = 0;
}

int bag_digest_text(const char *alg, const char *text, size_t len, char *hex)
{
	const EVP_MD *md = EVP_get_digestbyname(alg);
	unsigned char out[EVP_MAX_MD_SIZE];
	unsigned n = 0;
	if (!md || !EVP_Digest(text, len, out, &n, md, NULL))
		return -1;
	to_hex(out, n, hex);
	return 0;
}

/* Read src to its end through ctx, writing what is read to out (when >= 0). */
static int digest_fd(EVP_MD_CTX *ctx, int in, int out, const bag_copy *c, unsigned long long *size,
                     kg_err *err)
{
	for (;;) {
		if (c->stop && *c->stop)
			return kg_fail(err, -EINTR, "interrupted");
		ssize_t n = read(in, c->buf, c->bufsize);
		if (n < 0 && errno == EINTR)
			continue;
		if (n < 0)
			return kg_fail(err, KG_EIO, "%s: cannot read: %s", c->src, strerror(errno));
		if (n == 0)
			return 0;
		if (!EVP_DigestUpdate(ctx, c->buf, (size_t)n))
			return kg_fail(err, KG_ENOMEM, "%s: cannot compute its %s", c->src, c->alg);
		if (out >= 0 && kg_write_all(out, c->buf, (size_t)n))
			return kg_fail_write(err, errno, c->dst, "write failed");
		*size += (unsigned long long)n;
	}
}

int bag_digest_file(const bag_copy *c, char *hex, unsigned long long *size, kg_err *err)
{
	*size = 0;
	const EVP_MD *md = EVP_get_digestbyname(c->alg);
	if (!md)
		return kg_fail(err, KG_EINVAL, "%s: no such checksum algorithm", c->alg);
	int in = open(c->src, O_RDONLY | O_CLOEXEC);
	if (in < 0)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s", c->src,
		               strerror(errno));
	int out = -1;
	if (c->dst && (out = open(c->dst, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644)) < 0) {
		int e = errno;
		close(in);
		return kg_fail_write(err, e, c->dst, "cannot create");
	}
	EVP_MD_CTX *ctx = EVP_MD_CTX_new();
	int ret = ctx && EVP_DigestInit_ex(ctx, md, NULL)
	              ? 0
	              : kg_fail(err, KG_ENOMEM, "%s: cannot compute its %s", c->src, c->alg);
	if (!ret)
		ret = digest_fd(ctx, in, out, c, size, err);
	unsigned char mdv[EVP_MAX_MD_SIZE];
	unsigned n = 0;
	if (!ret && !EVP_DigestFinal_ex(ctx, mdv, &n))
		ret = kg_fail(err, KG_ENOMEM, "%s: cannot compute its %s", c->src, c->alg);
	if (!ret && out >= 0 && fsync(out) != 0)
		ret = kg_fail_write(err, errno, c->dst, "cannot flush to disk");
	if (out >= 0 && close(out) != 0 && !ret)
		ret = kg_fail_write(err, errno, c->dst, "write failed");
	close(in);
	EVP_MD_CTX_free(ctx);
	if (!ret)
		to_hex(mdv, n, hex);
	return ret;
}

/* ---- the walk ----------------------------------------------------------------------- */

static int by_name(const struct dirent **a, const struct dirent **b)
{
	return strcmp((*a)->d_name, (*b)->d_name);
}

static int walk_dir(const char *dir, const char *rel, int depth, bag_visit visit, void *user,
                    kg_err *err);

static int walk_entry(const char *dir, const char *rel, const char *name, int depth,
                      bag_visit visit, void *user, kg_err *err)
{
	char *path = kg_path_join(dir, name), *sub = kg_path_join(rel, name);
	struct stat st;
	int ret = path && sub ? 0 : kg_fail(err, KG_ENOMEM, "out of memory");
	if (!ret && lstat(path, &st) != 0)
		ret = kg_fail(err, KG_EIO, "%s: cannot stat: %s", path, strerror(errno));
	int r = ret ? ret : visit(user, path, sub, &st);
	if (r < 0)
		ret = r;
	else if (r == 0 && S_ISDIR(st.st_mode))
		ret = walk_dir(path, sub, depth + 1, visit, user, err);
	free(path);
	free(sub);
	return ret;
}

static int walk_dir(const char *dir, const char *rel, int depth, bag_visit visit, void *user,
                    kg_err *err)
{
	if (depth > WALK_DEPTH_MAX)
		return kg_fail(err, KG_EINVAL, "%s: folders nested deeper than %d", dir, WALK_DEPTH_MAX);
	struct dirent **list = NULL;
	int n = scandir(dir, &list, NULL, by_name);
	if (n < 0)
		return kg_fail(err, KG_EIO, "%s: cannot read the folder: %s", dir, strerror(errno));
	int ret = 0;
	for (int i = 0; i < n; i++) {
		const char *name = list[i]->d_name;
		if (!ret && strcmp(name, ".") && strcmp(name, ".."))
			ret = walk_entry(dir, rel, name, depth, visit, user, err);
		free(list[i]);
	}
	free(list);
	return ret;
}

int bag_walk(const char *dir, const char *rel, bag_visit visit, void *user, kg_err *err)
{
	return walk_dir(dir, rel, 0, visit, user, err);
}

/* ---- manifest paths ------------------------------------------------------------------ */

void bag_put_path(FILE *f, const char *rel)
{
	for (const char *c = rel; *c; c++) {
		if (*c == '%')
			fputs("%25", f);
		else if (*c == '\n')
			fputs("%0A", f);
		else if (*c == '\r')
			fputs("%0D", f);
		else
			fputc(*c, f);
	}
}

/* The path of a manifest line, decoded in place (%0A, %0D and %25, the only encodings
 * RFC 8493 has); 0, or -1 when it could leave the bag (absolute, an empty, "." or ".."
 * component). */
static int decode_path(char *p)
{
	char *w = p;
	for (const char *r = p; *r; r++) {
		if (r[0] == '%' && (!strncasecmp(r, "%0A", 3) || !strncasecmp(r, "%0D", 3) ||
		                    !strncmp(r, "%25", 3))) {
			*w++ = r[2] == '5' ? '%' : (r[2] == 'A' || r[2] == 'a') ? '\n' : '\r';
			r += 2;
		} else {
			*w++ = *r;
		}
	}
	*w = 0;
	for (const char *c = p;;) {
		size_t len = strcspn(c, "/");
		if (!len || (len == 1 && c[0] == '.') || (len == 2 && c[0] == '.' && c[1] == '.'))
			return -1;
		if (!c[len])
			return 0;
		c += len + 1;
	}
}

/* ---- kg_bag_verify -------------------------------------------------------------------- */

typedef struct verify {
	char *bag;                 /* as given, without a trailing '/' */
	FILE *problems, *progress;
	kg_err *err;
	char **payload;            /* "data/..." of every payload file, sorted */
	int n, cap;
	unsigned char *seen;       /* per payload file, by the manifest being read */
	int missing, extra, changed, other;
	unsigned long long bytes;
	unsigned char buf[1 << 16];
} verify;

static void problem(verify *v, int *count, const char *fmt, ...) KG_PRINTF(3, 4);
static void problem(verify *v, int *count, const char *fmt, ...)
{
	char line[4400];
	va_list ap;
	va_start(ap, fmt);
	vsnprintf(line, sizeof(line), fmt, ap);
	va_end(ap);
	if (v->problems) {
		char shown[4 * sizeof(line) + 16];
		fprintf(v->problems, "kogei deposit: %s\n",
		        kg_text_visible(line, SIZE_MAX, shown, sizeof(shown)));
	}
	(*count)++;
}

static int add_payload(void *user, const char *path, const char *rel, const struct stat *st)
{
	verify *v = user;
	if (S_ISDIR(st->st_mode))
		return 0;
	if (!S_ISREG(st->st_mode)) {
		problem(v, &v->other, "%s: not a regular file (a bag's payload is files and folders)",
		        path);
		return 1;
	}
	if (v->n == v->cap) {
		int cap = v->cap ? 2 * v->cap : 64;
		char **p = realloc(v->payload, (size_t)cap * sizeof(*p));
		if (!p)
			return kg_fail(v->err, KG_ENOMEM, "out of memory");
		v->payload = p;
		v->cap = cap;
	}
	if (!(v->payload[v->n] = strdup(rel)))
		return kg_fail(v->err, KG_ENOMEM, "out of memory");
	v->n++;
	v->bytes += (unsigned long long)st->st_size;
	return 0;
}

static int cmp_str(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

static int find_payload(const verify *v, const char *rel)
{
	char *const *hit = bsearch(&rel, v->payload, (size_t)v->n, sizeof(char *), cmp_str);
	return hit ? (int)(hit - v->payload) : -1;
}

/* BAG/name read whole: *path and *text (the caller frees both; *text NULL when there
 * is no such file). */
static int read_bag_file(verify *v, const char *name, char **path, char **text)
{
	struct stat st;
	size_t len;
	*text = NULL;
	if (!(*path = kg_path_join(v->bag, name)))
		return kg_fail(v->err, KG_ENOMEM, "out of memory");
	if (lstat(*path, &st) != 0 && errno == ENOENT)
		return 0;
	return kg_read_file(*path, text, &len, v->err);
}

/* Each line of a manifest: "CHECKSUM PATH" (one or more spaces or tabs between);
 * calls line(v, alg, checksum, path, lineno, manifest) for each well-formed one. */
typedef void (*manifest_line)(verify *v, const char *alg, const char *sum, const char *path,
                              const char *manifest);
static int read_manifest(verify *v, const char *name, const char *alg, manifest_line line)
{
	char *path, *text;
	int ret = read_bag_file(v, name, &path, &text);
	int lineno = 0;
	for (char *s = text, *next; !ret && s && *s; s = next) {
		next = s + strcspn(s, "\n");
		if (*next)
			*next++ = 0;
		lineno++;
		size_t n = strlen(s);
		if (n && s[n - 1] == '\r')
			s[n - 1] = 0;
		char *p = s + strcspn(s, " \t");
		int sep = (int)strspn(p, " \t");
		if (!*s)
			continue;
		if (p == s || !sep || !p[sep] || (*p = 0, decode_path(p + sep))) {
			problem(v, &v->other, "%s: line %d: expected CHECKSUM PATH, a path inside the bag",
			        path, lineno);
			continue;
		}
		line(v, alg, s, p + sep, name);
	}
	free(text);
	free(path);
	return ret;
}

/* root/rel's checksum against sum: 1 when it differs, 0 when equal, < 0 on error. */
static int differs(verify *v, const char *alg, const char *rel, const char *sum, int i)
{
	char *src = kg_path_join(v->bag, rel);
	if (!src)
		return kg_fail(v->err, KG_ENOMEM, "out of memory");
	if (v->progress && i >= 0)
		fprintf(v->progress, "kogei deposit: %s [%d/%d] %s\n", alg, i + 1, v->n, rel);
	bag_copy c = {.alg = alg, .src = src, .buf = v->buf, .bufsize = sizeof(v->buf)};
	char hex[2 * EVP_MAX_MD_SIZE + 1];
	unsigned long long size;
	int ret = bag_digest_file(&c, hex, &size, v->err);
	free(src);
	return ret ? ret : strcasecmp(hex, sum) != 0;
}

/* rel's checksum against the one manifest records: a problem when it differs, or when
 * the file cannot be read. i: its index among the payload files, -1 for a tag file. */
static void compare(verify *v, const char *alg, const char *sum, const char *rel,
                    const char *manifest, int i)
{
	int d = differs(v, alg, rel, sum, i);
	if (d > 0)
		problem(v, &v->changed, "%s/%s: changed (its %s is not the one %s records)", v->bag,
		        rel, alg, manifest);
	else if (d < 0)
		problem(v, &v->other, "%s", v->err->msg);
}

static void payload_line(verify *v, const char *alg, const char *sum, const char *rel,
                         const char *manifest)
{
	int i = find_payload(v, rel);
	if (strncmp(rel, "data/", 5)) {
		problem(v, &v->other, "%s/%s: %s lists a file outside data/", v->bag, rel, manifest);
	} else if (i < 0) {
		problem(v, &v->missing, "%s/%s: missing (listed in %s)", v->bag, rel, manifest);
	} else if (v->seen[i]) {
		problem(v, &v->other, "%s/%s: listed twice in %s", v->bag, rel, manifest);
	} else {
		v->seen[i] = 1;
		compare(v, alg, sum, rel, manifest, i);
	}
}

static void tag_line(verify *v, const char *alg, const char *sum, const char *rel,
                     const char *manifest)
{
	struct stat st;
	char *path = kg_path_join(v->bag, rel);
	if (!strncmp(rel, "data/", 5)) {
		problem(v, &v->other, "%s/%s: %s lists a payload file", v->bag, rel, manifest);
	} else if (!path || lstat(path, &st) != 0 || !S_ISREG(st.st_mode)) {
		problem(v, &v->missing, "%s/%s: missing (listed in %s)", v->bag, rel, manifest);
	} else {
		compare(v, alg, sum, rel, manifest, -1);
	}
	free(path);
}

/* bagit.txt: "BagIt-Version: M.N" and "Tag-File-Character-Encoding: UTF-8". */
static int check_bagit_txt(verify *v)
{
	char *path, *text;
	int ret = read_bag_file(v, "bagit.txt", &path, &text);
	if (!ret && !text)
		ret = kg_fail(v->err, KG_EINVAL, "%s: not a bag (no bagit.txt)", v->bag);
	unsigned major, minor;
	char enc[16], end;
	if (!ret && (sscanf(text, "BagIt-Version: %u.%u%c", &major, &minor, &end) != 3 ||
	             (end != '\n' && end != '\r')))
		ret = kg_fail(v->err, KG_EINVAL, "%s: line 1: expected \"BagIt-Version: M.N\"", path);
	const char *l2 = ret ? NULL : strchr(text, '\n');
	if (!ret && (!l2 || sscanf(l2 + 1, "Tag-File-Character-Encoding: %15[A-Za-z0-9-]", enc) != 1 ||
	             strcasecmp(enc, "UTF-8")))
		ret = kg_fail(v->err, KG_EINVAL, "%s: line 2: expected \"Tag-File-Character-Encoding: "
		              "UTF-8\" (the only encoding kogei reads)", path);
	free(text);
	free(path);
	return ret;
}

/* bag-info.txt's Payload-Oxum (when there is one) against the payload. */
static int check_oxum(verify *v)
{
	char *path, *text;
	int ret = read_bag_file(v, "bag-info.txt", &path, &text);
	for (const char *s = text; !ret && s && *s; s += strcspn(s, "\n"), s += *s == '\n') {
		unsigned long long octets, files;
		char end;
		if (strncasecmp(s, "Payload-Oxum:", 13))
			continue;
		if (sscanf(s + 13, " %llu.%llu%c", &octets, &files, &end) < 2)
			problem(v, &v->other, "%s: Payload-Oxum: expected OCTETS.FILES", path);
		else if (octets != v->bytes || files != (unsigned long long)v->n)
			problem(v, &v->other, "%s: Payload-Oxum %llu.%llu, but data/ holds %llu octets "
			        "in %d files", path, octets, files, v->bytes, v->n);
		break;
	}
	free(text);
	free(path);
	return ret;
}

/* Every manifest-ALG.txt (tag 0) or tagmanifest-ALG.txt (tag 1) of the bag. */
static int check_manifests(verify *v, int tag, int *found)
{
	const char *prefix = tag ? "tagmanifest-" : "manifest-";
	size_t pl = strlen(prefix);
	struct dirent **list = NULL;
	int n = scandir(v->bag, &list, NULL, by_name), ret = 0;
	if (n < 0)
		return kg_fail(v->err, KG_EIO, "%s: cannot read the folder: %s", v->bag, strerror(errno));
	for (int i = 0; i < n; i++) {
		const char *name = list[i]->d_name;
		size_t len = strlen(name);
		char alg[32];
		if (!ret && !strncmp(name, prefix, pl) && len > pl + 4 && len - pl - 4 < sizeof(alg) &&
		    !strcmp(name + len - 4, ".txt")) {
			snprintf(alg, sizeof(alg), "%.*s", (int)(len - pl - 4), name + pl);
			(*found)++;
			memset(v->seen, 0, (size_t)v->n);
			if (!EVP_get_digestbyname(alg)) {
				problem(v, &v->other, "%s/%s: checksum algorithm '%s' unknown", v->bag, name, alg);
			} else {
				ret = read_manifest(v, name, alg, tag ? tag_line : payload_line);
				for (int k = 0; !ret && !tag && k < v->n; k++)
					if (!v->seen[k])
						problem(v, &v->extra, "%s/%s: not in %s (added to the bag after it "
						        "was made, or its line lost)", v->bag, v->payload[k], name);
			}
		}
		free(list[i]);
	}
	free(list);
	return ret;
}

static int verify_run(verify *v, kg_deposit_summary *sum)
{
	int ret = check_bagit_txt(v);
	char *data = ret ? NULL : kg_path_join(v->bag, "data");
	struct stat st;
	if (!ret && (!data || stat(data, &st) != 0 || !S_ISDIR(st.st_mode)))
		problem(v, &v->missing, "%s: missing (the payload folder)", data ? data : "data");
	else if (!ret)
		ret = bag_walk(data, "data", add_payload, v, v->err);
	free(data);
	if (ret)
		return ret;
	qsort(v->payload, (size_t)v->n, sizeof(char *), cmp_str);
	int manifests = 0, tags = 0;
	if (!(v->seen = calloc((size_t)v->n + 1, 1)))
		return kg_fail(v->err, KG_ENOMEM, "out of memory");
	ret = check_manifests(v, 0, &manifests);
	if (!ret && !manifests)
		problem(v, &v->missing, "%s: no payload manifest (manifest-ALG.txt)", v->bag);
	if (!ret)
		ret = check_manifests(v, 1, &tags);
	if (!ret)
		ret = check_oxum(v);
	if (ret)
		return ret;
	sum->files = v->n;
	sum->bytes = v->bytes;
	if (v->missing + v->extra + v->changed + v->other)
		return kg_fail(v->err, KG_EINVAL, "%s: invalid: %d missing, %d extra, %d changed, %d "
		               "other problem(s)", v->bag, v->missing, v->extra, v->changed, v->other);
	return 0;
}

int kg_bag_verify(const char *bag, FILE *problems, FILE *progress, kg_deposit_summary *sum,
                  kg_err *err)
{
	kg_check_arg(bag && sum, err);
	memset(sum, 0, sizeof(*sum));
	verify *v = calloc(1, sizeof(*v));
	if (!v)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	size_t n = strlen(bag);
	while (n > 1 && bag[n - 1] == '/')
		n--;
	v->bag = strndup(bag, n); /* "bag/" names its files bag/data/..., not bag//data/... */
	v->problems = problems;
	v->progress = progress;
	v->err = err;
	int ret = v->bag ? verify_run(v, sum) : kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; i < v->n; i++)
		free(v->payload[i]);
	free(v->payload);
	free(v->seen);
	free(v->bag);
	free(v);
	return ret;
}
