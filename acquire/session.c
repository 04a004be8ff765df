/* Session directories and their manifest (kg_acquire.h, docs/acquire.md). */
#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include <openssl/evp.h>

#include "acquire_private.h"
#include "kg_config.h"

#define LOCK_NAME ".lock"

struct kg_session {
	char *dir;
	char *manifest_path;
	json_t *root;
	int lock_fd;
	char foreign[512]; /* entries kogei did not write, of a session that has a manifest */
};

void kg_utc_now(char buf[32])
{
	struct timespec ts;
	clock_gettime(CLOCK_REALTIME, &ts);
	struct tm tm;
	gmtime_r(&ts.tv_sec, &tm);
	char date[24];
	strftime(date, sizeof(date), "%Y-%m-%dT%H:%M:%S", &tm);
	snprintf(buf, 32, "%.19s.%03dZ", date, (int)(ts.tv_nsec / 1000000L) % 1000);
}

int kg_sync_dir(const char *path, kg_err *err)
{
	int fd = open(path, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
	if (fd < 0 || fsync(fd) != 0) {
		int e = errno;
		if (fd >= 0)
			close(fd);
		return kg_fail(err, KG_EIO, "%s: cannot sync the directory: %s", path, strerror(e));
	}
	close(fd);
	return 0;
}

int kg_capture_name_ok(const char *s) { return kg_name_is_safe(s, KG_CAPTURE_NAME_MAX); }

int kg_file_sha256(const char *path, char hex[65], kg_err *err)
{
	kg_check_arg(path && hex, err);
	hex[0] = 0;
	FILE *fp = fopen(path, "rb");
	if (!fp)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s", path,
		               strerror(errno));
	EVP_MD_CTX *ctx = EVP_MD_CTX_new();
	int ok = ctx && EVP_DigestInit_ex(ctx, EVP_sha256(), NULL);
	unsigned char buf[1 << 16];
	size_t n;
	while (ok && (n = fread(buf, 1, sizeof(buf), fp)) > 0)
		ok = EVP_DigestUpdate(ctx, buf, n);
	ok = ok && !ferror(fp);
	unsigned char md[EVP_MAX_MD_SIZE];
	unsigned int len = 0;
	ok = ok && EVP_DigestFinal_ex(ctx, md, &len) && len == 32;
	EVP_MD_CTX_free(ctx);
	fclose(fp);
	if (!ok)
		return kg_fail(err, KG_EIO, "%s: cannot read or hash (sha256)", path);
	for (unsigned i = 0; i < len; i++)
		snprintf(hex + 2 * i, 3, "%02x", md[i]);
	return 0;
}

char *kg_session_path(const kg_session *s, const char *rel)
{
	return kg_path_join(s->dir, rel);
}

const char *kg_session_dir(const kg_session *s) { return s->dir; }

const json_t *kg_session_manifest(const kg_session *s) { return s->root; }

const json_t *kg_session_find(const kg_session *s, const char *name)
{
	json_t *caps = json_object_get(s->root, "captures"), *c;
	size_t i;
	json_array_foreach(caps, i, c)
	{
		const char *n = json_string_value(json_object_get(c, "name"));
		if (n && !strcmp(n, name))
			return c;
	}
	return NULL;
}

/* ---- open ------------------------------------------------------------------------ */

/* What a session directory may hold: its own files, the temporaries of the manifest,
 * and dot files. */
static int session_entry(const char *name)
{
	return name[0] == '.' || !strcmp(name, "frames") || !strcmp(name, "captures") ||
	       !strcmp(name, "spectra") || !strncmp(name, KG_SESSION_MANIFEST, 12);
}

/* Check the directory's entries; remove temporaries of the manifest a killed writer left
 * (the lock is held, so nobody is writing one). A folder with a manifest is a session:
 * entries kogei did not write (the spectra measured into it, notes) are kept and listed
 * in s->foreign. A folder without one that holds anything else is not a session. */
static int check_entries(kg_session *s, kg_err *err)
{
	DIR *d = opendir(s->dir);
	if (!d)
		return kg_fail(err, KG_EIO, "%s: cannot read the directory: %s", s->dir,
		               strerror(errno));
	struct stat st;
	int has_manifest = lstat(s->manifest_path, &st) == 0 && S_ISREG(st.st_mode);
	int ret = 0, nforeign = 0;
	size_t at = 0;
	for (struct dirent *e; !ret && (e = readdir(d));) {
		if (!session_entry(e->d_name) && !has_manifest) {
			ret = kg_fail(err, KG_EINVAL,
			              "%s: not a kogei session: it has no session.json and holds '%s'; "
			              "give --out a new or empty directory or an existing session",
			              s->dir, e->d_name);
		} else if (!session_entry(e->d_name)) {
			if (nforeign++ < 8 && at < sizeof(s->foreign))
				at += (size_t)snprintf(s->foreign + at, sizeof(s->foreign) - at, "%s%s",
				                       at ? ", " : "", e->d_name);
		} else if (!strncmp(e->d_name, KG_SESSION_MANIFEST ".tmp.", 17)) {
			char *p = kg_session_path(s, e->d_name);
			if (p)
				unlink(p);
			free(p);
		}
	}
	closedir(d);
	if (nforeign > 8 && at < sizeof(s->foreign))
		snprintf(s->foreign + at, sizeof(s->foreign) - at, " and %d more", nforeign - 8);
	return ret;
}

const char *kg_session_foreign(const kg_session *s)
{
	return s ? s->foreign : "";
}

/* No symbolic link where kogei writes or reads: the manifest, frames/, captures/,
 * spectra/, frames/index.jsonl and every entry of frames/ and captures/ (a linked folder
 * would have frames and outputs written outside the session, a linked index appended
 * through the link). */
static int check_links(const kg_session *s, kg_err *err)
{
	static const char *const top[] = {KG_SESSION_MANIFEST, "frames", "captures", "spectra",
	                                  "frames/index.jsonl", "frames/camera.json"};
	int ret = 0;
	for (size_t i = 0; !ret && i < sizeof(top) / sizeof(top[0]); i++)
		ret = kg_check_below(s->dir, top[i], err);
	for (int k = 0; !ret && k < 2; k++) {
		const char *sub = k ? "captures" : "frames";
		int fd = kg_open_below(s->dir, sub, O_RDONLY | O_DIRECTORY, 0, NULL);
		DIR *d = fd >= 0 ? fdopendir(fd) : NULL;
		if (!d) {
			if (fd >= 0)
				close(fd);
			continue; /* not there (yet) */
		}
		for (struct dirent *e; !ret && (e = readdir(d));) {
			if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
				continue;
			struct stat st;
			if (fstatat(dirfd(d), e->d_name, &st, AT_SYMLINK_NOFOLLOW) == 0 &&
			    S_ISLNK(st.st_mode)) {
				char rel[512];
				snprintf(rel, sizeof(rel), "%s/%s", sub, e->d_name);
				ret = kg_check_below(s->dir, rel, err);
			}
		}
		closedir(d);
	}
	return ret;
}

static int load_manifest(kg_session *s, kg_err *err)
{
	const char *f = s->manifest_path;
	int ret = kg_json_load(f, &s->root, err);
	if (ret)
		return ret;
	kg_inputs_forget(f); /* the session's own, rewritten after every capture */
	return kg_session_manifest_validate(f, s->root, err);
}

/* A random (version 4) UUID, the session's identity wherever it is moved or copied. */
static int new_session_id(char out[37])
{
	unsigned char b[16];
	if (getrandom(b, sizeof(b), 0) != (ssize_t)sizeof(b))
		return -1;
	b[6] = (unsigned char)((b[6] & 0x0F) | 0x40);
	b[8] = (unsigned char)((b[8] & 0x3F) | 0x80);
	snprintf(out, 37, "%02x%02x%02x%02x-%02x%02x-%02x%02x-%02x%02x-%02x%02x%02x%02x%02x%02x",
	         b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7], b[8], b[9], b[10], b[11], b[12],
	         b[13], b[14], b[15]);
	return 0;
}

static json_t *new_manifest(void)
{
	char now[32], id[37];
	kg_utc_now(now);
	if (new_session_id(id))
		return NULL;
	return json_pack("{s:s, s:s, s:{s:s, s:s}, s:s, s:{s:[]}, s:[]}", "format",
	                 KG_SESSION_FORMAT, "id", id, "station", "software", "kogei", "version",
	                 KG_VERSION, "created", now, "devices", "cameras", "captures");
}

int kg_session_open(const char *dir, kg_session **out, kg_err *err)
{
	kg_check_arg(dir && *dir && out, err);
	*out = NULL;
	kg_session *s = calloc(1, sizeof(*s));
	if (!s)
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", dir);
	s->lock_fd = -1;
	s->dir = strdup(dir);
	s->manifest_path = kg_path_join(dir, KG_SESSION_MANIFEST);
	char *lock = kg_path_join(dir, LOCK_NAME);
	int ret = s->dir && s->manifest_path && lock ? 0
	                                             : kg_fail(err, KG_ENOMEM, "%s: out of memory",
	                                                       dir);
	struct stat st;
	if (!ret && stat(dir, &st) == 0 && !S_ISDIR(st.st_mode))
		ret = kg_fail(err, KG_EINVAL, "%s: exists and is not a directory", dir);
	if (!ret)
		ret = kg_mkdir_p(dir, err);
	if (!ret) {
		s->lock_fd = open(lock, O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0644);
		if (s->lock_fd < 0 && errno == ELOOP)
			ret = kg_fail(err, KG_EINVAL, "%s: is a symbolic link; kogei writes and reads "
			              "only real files and folders inside %s (remove the link)", lock, dir);
		else if (s->lock_fd < 0)
			ret = kg_fail(err, KG_EIO, "%s: cannot create: %s", lock, strerror(errno));
		else if (flock(s->lock_fd, LOCK_EX | LOCK_NB) != 0)
			ret = kg_fail(err, errno == EWOULDBLOCK ? KG_EINVAL : KG_EIO,
			              "%s: the session is in use by another kogei (lock %s held)", dir,
			              lock);
	}
	if (!ret)
		ret = check_entries(s, err);
	if (!ret)
		ret = check_links(s, err);
	if (!ret) {
		if (stat(s->manifest_path, &st) == 0) {
			ret = load_manifest(s, err);
			/* a session recorded before sessions had ids gets one with its next capture */
			char id[37];
			if (!ret && !json_object_get(s->root, "id") &&
			    (new_session_id(id) || json_object_set_new(s->root, "id", json_string(id))))
				ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", dir);
		}
		else if (!(s->root = new_manifest()))
			ret = kg_fail(err, KG_ENOMEM, "%s: out of memory", dir);
		else /* frames of a first capture that never finished */
			ret = kg_camera_recording_validate(dir, err);
	}
	free(lock);
	if (ret) {
		kg_session_free(&s);
		return ret;
	}
	*out = s;
	return 0;
}

void kg_session_free(kg_session **ps)
{
	if (!ps || !*ps)
		return;
	kg_session *s = *ps;
	if (s->lock_fd >= 0)
		close(s->lock_fd); /* releases the flock */
	json_decref(s->root);
	free(s->dir);
	free(s->manifest_path);
	free(s);
	*ps = NULL;
}

/* ---- names ----------------------------------------------------------------------- */

/* 1 when rel (e.g. "frames/chart-0001") exists in the session. */
static int exists(const kg_session *s, const char *sub, const char *name)
{
	char rel[KG_CAPTURE_NAME_MAX + 16];
	snprintf(rel, sizeof(rel), "%s/%s", sub, name);
	char *p = kg_session_path(s, rel);
	struct stat st;
	int r = p && lstat(p, &st) == 0;
	free(p);
	return r;
}

int kg_session_check_name(const kg_session *s, const char *name, kg_err *err)
{
	if (!kg_capture_name_ok(name))
		return kg_fail(err, KG_EINVAL,
		               "capture name '%s': expected 1 to %d letters, digits, '.', '_' or '-', "
		               "not starting with '.'",
		               name, KG_CAPTURE_NAME_MAX - 1);
	if (kg_session_find(s, name))
		return kg_fail(err, KG_EINVAL, "%s: capture '%s' is already in the session; choose "
		                               "another --name",
		               s->manifest_path, name);
	for (int k = 0; k < 2; k++)
		if (exists(s, k ? "captures" : "frames", name))
			return kg_fail(err, KG_EINVAL,
			               "%s/%s/%s: an interrupted capture left files under this name; "
			               "choose another --name (or remove that folder)",
			               s->dir, k ? "captures" : "frames", name);
	return 0;
}

int kg_session_next_name(const kg_session *s, const char *kind, char name[KG_CAPTURE_NAME_MAX],
                         kg_err *err)
{
	for (int n = 1; n <= 9999; n++) {
		snprintf(name, KG_CAPTURE_NAME_MAX, "%s-%04d", kind, n);
		if (!kg_session_find(s, name) && !exists(s, "frames", name) &&
		    !exists(s, "captures", name))
			return 0;
	}
	return kg_fail(err, KG_EINVAL, "%s: no free capture name %s-0001..9999", s->dir, kind);
}

/* ---- append ---------------------------------------------------------------------- */

/* The id of the camera in devices.cameras (added to root when new). */
static const char *camera_id(json_t *root, const kg_camera_info *info)
{
	json_t *cams = json_object_get(json_object_get(root, "devices"), "cameras"), *c;
	size_t i;
	json_array_foreach(cams, i, c)
	{
		const char *f[] = {"backend", "uri", "vendor", "model", "serial", "transport"};
		const char *v[] = {info->backend, info->uri,    info->vendor,
		                   info->model,   info->serial, info->transport};
		int same = 1;
		for (int k = 0; k < 6 && same; k++) {
			const char *x = json_string_value(json_object_get(c, f[k]));
			same = x && !strcmp(x, v[k]);
		}
		if (same)
			return json_string_value(json_object_get(c, "id"));
	}
	char id[32];
	snprintf(id, sizeof(id), "camera-%zu", json_array_size(cams) + 1);
	json_t *c2 = json_pack("{s:s, s:s, s:s, s:s, s:s, s:s, s:s, s:i, s:i}", "id", id,
	                       "backend", info->backend, "uri", info->uri, "vendor", info->vendor,
	                       "model", info->model, "serial", info->serial, "transport",
	                       info->transport, "sensor_width", info->sensor_width,
	                       "sensor_height", info->sensor_height);
	if (!c2 || json_array_append_new(cams, c2))
		return NULL;
	return json_string_value(json_object_get(c2, "id"));
}

int kg_session_append(kg_session *s, const kg_camera_info *info, json_t *capture,
                      kg_err *err)
{
	json_t *root = json_deep_copy(s->root);
	const char *id = root ? camera_id(root, info) : NULL;
	char now[32];
	kg_utc_now(now);
	if (!id || json_object_set_new(capture, "camera", json_string(id)) ||
	    json_object_set_new(root, "updated", json_string(now)) ||
	    json_array_append(json_object_get(root, "captures"), capture)) {
		json_decref(root);
		json_decref(capture);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory", s->manifest_path);
	}
	json_decref(capture);
	int ret = kg_json_write(root, s->manifest_path, err);
	if (!ret)
		ret = kg_sync_dir(s->dir, err);
	if (ret) {
		json_decref(root);
		return ret;
	}
	json_decref(s->root);
	s->root = root;
	return 0;
}

/* ---- verify ---------------------------------------------------------------------- */

static int verify_file(const kg_session *s, const json_t *entry, const char *where, long *n,
                       kg_err *err)
{
	const char *file = json_string_value(json_object_get(entry, "file"));
	const char *sha = json_string_value(json_object_get(entry, "sha256"));
	if (!file || !sha)
		return kg_fail(err, KG_EINVAL, "%s: %s: expected \"file\" and \"sha256\"",
		               s->manifest_path, where);
	if (!kg_relpath_is_safe(file, KG_CAPTURE_NAME_MAX))
		return kg_fail(err, KG_EINVAL, "%s: %s: file '%s': expected a path inside the session",
		               s->manifest_path, where, file);
	char *p = kg_session_path(s, file);
	char got[65];
	int ret = p ? kg_file_sha256(p, got, err) : KG_ENOMEM;
	if (!ret && strcmp(got, sha))
		ret = kg_fail(err, KG_EIO, "%s: sha256 %s, but %s records %s (%s)", p, got,
		              s->manifest_path, sha, where);
	free(p);
	if (!ret && n)
		(*n)++;
	return ret;
}

int kg_session_verify(const kg_session *s, long *nfiles, kg_err *err)
{
	kg_check_arg(s, err);
	long n = 0;
	json_t *caps = json_object_get(s->root, "captures"), *c;
	size_t i;
	int ret = 0;
	json_array_foreach(caps, i, c)
	{
		const char *name = json_string_value(json_object_get(c, "name"));
		char where[160];
		json_t *e;
		size_t k;
		json_array_foreach(json_object_get(c, "frames"), k, e)
		{
			snprintf(where, sizeof(where), "capture %s, frames[%zu]", name, k);
			if ((ret = verify_file(s, e, where, &n, err)))
				return ret;
		}
		const char *key;
		json_object_foreach(json_object_get(c, "outputs"), key, e)
		{
			snprintf(where, sizeof(where), "capture %s, outputs.%s", name, key);
			if ((ret = verify_file(s, e, where, &n, err)))
				return ret;
		}
		json_t *steps = json_object_get(json_object_get(c, "exposure_helper"), "steps");
		json_array_foreach(steps, k, e)
		{
			if (!json_object_get(e, "file"))
				continue;
			snprintf(where, sizeof(where), "capture %s, exposure_helper.steps[%zu]", name, k);
			if ((ret = verify_file(s, e, where, &n, err)))
				return ret;
		}
	}
	if (nfiles)
		*nfiles = n;
	return 0;
}
