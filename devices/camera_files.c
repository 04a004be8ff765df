/* files:DIR or files:DIR/PATTERN — photographs already taken, one frame per file.
 *
 * Camera raw files (DNG, CR2, CR3, NEF, ARW, IIQ, ...: core/raw.h, LibRaw) and TIFF or
 * PNG images are served in name order, each decoded once when popped. Raw files give
 * a Bayer mosaic with black subtracted and scaled by the white level (bayer16, 16
 * bits: round(65535 v), v clamped to 0..1); TIFF and PNG give their samples scaled to
 * 16 bits (mono16, bayer16 with their CFA tags, or rgb16). The files' own metadata is
 * the camera: make, model, body serial and lens (raw files) are its identity, exposure
 * time, ISO, aperture and focal length its features (read-only: setting one to the
 * value the files have succeeds, any other value is refused).
 *
 * At open every file's header is read and the set is refused when the files are not
 * frames of one capture: different cameras, sizes, mosaics, kinds, exposure times, ISO
 * speeds or apertures; the message names two files and the difference. */
#include "kg_config.h"

#include <ctype.h>
#include <dirent.h>
#include <errno.h>
#include <fnmatch.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "camera_driver.h"
#include "image.h"
#include "raw.h"

typedef struct files_entry {
	char *path;
	int raw;
	kg_raw_meta meta; /* raw files; NAN / "" for TIFF and PNG */
	int width, height, channels;
	char cfa[5];
} files_entry;

typedef struct files_cam {
	char *spec; /* the target as given */
	files_entry *files;
	int nfiles;
	int next;     /* the next file to serve */
	int streaming;
	kg_frame_format fmt;
	uint16_t *buf; /* the frame handed out */
	int held;
	char note[256];
} files_cam;

static void files_close(void *state)
{
	files_cam *s = state;
	if (!s)
		return;
	for (int i = 0; i < s->nfiles; i++)
		free(s->files[i].path);
	free(s->files);
	free(s->buf);
	free(s->spec);
	free(s);
}

static int has_ext(const char *name, const char *const *exts, size_t n)
{
	const char *dot = strrchr(name, '.');
	if (!dot)
		return 0;
	for (size_t i = 0; i < n; i++)
		if (!strcasecmp(dot + 1, exts[i]))
			return 1;
	return 0;
}

static int cmp_entry(const void *a, const void *b)
{
	return strcmp(((const files_entry *)a)->path, ((const files_entry *)b)->path);
}

/* The files named by the target: a directory (its images), or DIR/PATTERN (fnmatch
 * on the names in DIR), in name order. */
static int list_files(files_cam *s, const char *target, kg_err *err)
{
	struct stat st;
	char *dir = NULL;
	const char *pattern = NULL;
	if (!target[0])
		return kg_fail(err, KG_EINVAL, "expected files:DIR or files:DIR/PATTERN");
	if (stat(target, &st) == 0 && S_ISDIR(st.st_mode)) {
		dir = strdup(target);
	} else {
		const char *slash = strrchr(target, '/');
		dir = slash ? strndup(target, (size_t)(slash - target) + (slash == target)) : strdup(".");
		pattern = slash ? slash + 1 : target;
	}
	if (!dir)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	DIR *d = opendir(dir);
	if (!d) {
		int e = errno;
		int ret = kg_fail(err, e == ENOENT ? KG_ENODEV : KG_EIO, "%s: cannot list: %s", dir,
		                  strerror(e));
		free(dir);
		return ret;
	}
	static const char *const images[] = {"tif", "tiff", "png"};
	int cap = 0, ret = 0;
	struct dirent *de;
	while (!ret && (de = readdir(d))) {
		const char *name = de->d_name;
		if (name[0] == '.')
			continue;
		if (pattern ? fnmatch(pattern, name, 0) != 0
		            : !(has_ext(name, images, 3) || kg_raw_is_raw(name)))
			continue;
		char *path = NULL;
		if (asprintf(&path, "%s%s%s", dir, dir[strlen(dir) - 1] == '/' ? "" : "/", name) < 0) {
			ret = kg_fail(err, KG_ENOMEM, "out of memory");
			break;
		}
		if (stat(path, &st) != 0 || !S_ISREG(st.st_mode)) {
			free(path);
			continue;
		}
		if (s->nfiles == cap) {
			cap = cap ? 2 * cap : 16;
			files_entry *f = realloc(s->files, (size_t)cap * sizeof(*f));
			if (!f) {
				free(path);
				ret = kg_fail(err, KG_ENOMEM, "out of memory");
				break;
			}
			s->files = f;
		}
		memset(&s->files[s->nfiles], 0, sizeof(s->files[0]));
		s->files[s->nfiles++].path = path;
	}
	closedir(d);
	if (!ret && s->nfiles == 0)
		ret = kg_fail(err, KG_ENODEV, "%s: no %s in %s", target,
		              pattern ? "file matches the pattern" : "raw, TIFF or PNG file", dir);
	free(dir);
	if (!ret)
		qsort(s->files, (size_t)s->nfiles, sizeof(s->files[0]), cmp_entry);
	return ret;
}

/* The header of one file: size, mosaic and (raw files) the shooting metadata. */
static int read_header(files_entry *f, kg_err *err)
{
	kg_raw_meta *m = &f->meta;
	f->raw = kg_raw_is_raw(f->path);
	if (f->raw) {
		int ret = kg_raw_read_meta(f->path, m, err);
		if (ret)
			return ret;
		f->width = m->width;
		f->height = m->height;
		f->channels = 1;
		memcpy(f->cfa, m->cfa, sizeof(f->cfa));
		return 0;
	}
	memset(m, 0, sizeof(*m));
	m->exposure_s = m->iso = m->aperture = m->focal_length_mm = NAN;
	kg_image_rows *r = NULL;
	int ret = kg_image_rows_open(f->path, &r, err);
	if (ret)
		return ret;
	const kg_image *h = kg_image_rows_header(r);
	f->width = h->width;
	f->height = h->height;
	f->channels = h->channels;
	if (h->cfa && h->cfa_rows == 2 && h->cfa_cols == 2)
		memcpy(f->cfa, h->cfa, 4);
	else if (h->cfa)
		ret = kg_fail(err, KG_ENOTSUP, "%s: a %dx%d CFA: expected a 2x2 Bayer pattern", f->path,
		              h->cfa_rows, h->cfa_cols);
	kg_image_rows_free(&r);
	return ret;
}

static int same_number(double a, double b)
{
	return (isnan(a) && isnan(b)) || fabs(a - b) <= 1e-6 * fmax(fabs(a), fabs(b));
}

/* Refuse files that are not frames of one capture. */
static int check_consistent(const files_cam *s, kg_err *err)
{
	const files_entry *a = &s->files[0];
	for (int i = 1; i < s->nfiles; i++) {
		const files_entry *b = &s->files[i];
		const char *what = NULL;
		char va[96] = "", vb[96] = "";
		if (a->raw != b->raw) {
			what = "kind";
			snprintf(va, sizeof(va), "%s", a->raw ? "camera raw" : "TIFF/PNG");
			snprintf(vb, sizeof(vb), "%s", b->raw ? "camera raw" : "TIFF/PNG");
		} else if (strcmp(a->meta.make, b->meta.make) || strcmp(a->meta.model, b->meta.model) ||
		           strcmp(a->meta.serial, b->meta.serial)) {
			what = "camera";
			snprintf(va, sizeof(va), "%.30s %.30s serial %.20s", a->meta.make, a->meta.model,
			         a->meta.serial[0] ? a->meta.serial : "unknown");
			snprintf(vb, sizeof(vb), "%.30s %.30s serial %.20s", b->meta.make, b->meta.model,
			         b->meta.serial[0] ? b->meta.serial : "unknown");
		} else if (a->width != b->width || a->height != b->height ||
		           a->channels != b->channels || strcmp(a->cfa, b->cfa)) {
			what = "image size or mosaic";
			snprintf(va, sizeof(va), "%dx%d %d channel(s) %s", a->width, a->height,
			         a->channels, a->cfa);
			snprintf(vb, sizeof(vb), "%dx%d %d channel(s) %s", b->width, b->height,
			         b->channels, b->cfa);
		} else if (!same_number(a->meta.exposure_s, b->meta.exposure_s)) {
			what = "exposure time";
			snprintf(va, sizeof(va), "%g s", a->meta.exposure_s);
			snprintf(vb, sizeof(vb), "%g s", b->meta.exposure_s);
		} else if (!same_number(a->meta.iso, b->meta.iso)) {
			what = "ISO speed";
			snprintf(va, sizeof(va), "ISO %g", a->meta.iso);
			snprintf(vb, sizeof(vb), "ISO %g", b->meta.iso);
		} else if (!same_number(a->meta.aperture, b->meta.aperture)) {
			what = "aperture";
			snprintf(va, sizeof(va), "f/%g", a->meta.aperture);
			snprintf(vb, sizeof(vb), "f/%g", b->meta.aperture);
		}
		if (what)
			return kg_fail(err, KG_EINVAL,
			               "%s (%s) and %s (%s) differ in %s: the frames of one capture must "
			               "come from one camera at one exposure; give each its own capture "
			               "(a pattern per camera and exposure)",
			               a->path, va, b->path, vb, what);
	}
	return 0;
}

static int files_open(const char *target, void **state, kg_camera_info *info, kg_err *err)
{
	files_cam *s = calloc(1, sizeof(*s));
	if (!s || !(s->spec = strdup(target))) {
		free(s);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	int ret = list_files(s, target, err);
	for (int i = 0; !ret && i < s->nfiles; i++)
		ret = read_header(&s->files[i], err);
	if (!ret)
		ret = check_consistent(s, err);
	if (ret) {
		files_close(s);
		return ret;
	}
	const files_entry *f = &s->files[0];
	s->fmt.pixfmt = f->channels == 3 ? KG_PIX_RGB16 : f->cfa[0] ? KG_PIX_BAYER16 : KG_PIX_MONO16;
	if (f->channels != 1 && f->channels != 3) {
		files_close(s);
		return kg_fail(err, KG_ENOTSUP, "%s: %d channels: expected 1 or 3", f->path,
		               f->channels);
	}
	s->fmt.width = f->width;
	s->fmt.height = f->height;
	memcpy(s->fmt.cfa, f->cfa, sizeof(s->fmt.cfa));
	kg_frame_format_fill(&s->fmt);
	s->fmt.bits = 16;
	s->buf = malloc(s->fmt.size);
	if (!s->buf) {
		files_close(s);
		return kg_fail(err, KG_ENOMEM, "%s: out of memory for a %dx%d frame", f->path,
		               f->width, f->height);
	}
	snprintf(info->vendor, sizeof(info->vendor), "%s", f->meta.make);
	snprintf(info->model, sizeof(info->model), "%s", f->raw ? f->meta.model : "image files");
	snprintf(info->serial, sizeof(info->serial), "%s", f->meta.serial);
	snprintf(info->lens, sizeof(info->lens), "%s", f->meta.lens);
	snprintf(info->transport, sizeof(info->transport), "%s", f->raw ? "raw files" : "image files");
	info->sensor_width = f->width;
	info->sensor_height = f->height;
	*state = s;
	return 0;
}

/* ---- features: the files' metadata ---------------------------------------------------- */

static double feature_value(const files_cam *s, kg_feature f)
{
	const kg_raw_meta *m = &s->files[s->next < s->nfiles ? s->next : 0].meta;
	switch (f) {
	case KG_FEAT_EXPOSURE_US: return m->exposure_s * 1e6;
	case KG_FEAT_ISO: return m->iso;
	case KG_FEAT_APERTURE: return m->aperture;
	case KG_FEAT_FOCAL_LENGTH: return m->focal_length_mm;
	default: return NAN;
	}
}

static int files_feature_info(void *state, kg_feature f, kg_feature_info *o, kg_err *err)
{
	(void)err;
	static const char *const units[KG_FEAT_COUNT] = {
		[KG_FEAT_EXPOSURE_US] = "us", [KG_FEAT_ISO] = "ISO", [KG_FEAT_APERTURE] = "f",
		[KG_FEAT_FOCAL_LENGTH] = "mm"};
	double v = feature_value(state, f);
	if (!units[f] || !isfinite(v))
		return 0; /* not in the files */
	o->available = 1;
	o->writable = f != KG_FEAT_FOCAL_LENGTH;
	o->min = o->max = v;
	snprintf(o->unit, sizeof(o->unit), "%s", units[f]);
	snprintf(o->native, sizeof(o->native), "the files' %s", kg_feature_name(f));
	return 0;
}

static int files_get(void *state, kg_feature f, double *v, kg_err *err)
{
	*v = feature_value(state, f);
	if (!isfinite(*v))
		return kg_fail(err, KG_ENOTSUP, "%s: not recorded in the files", kg_feature_name(f));
	return 0;
}

static int files_set(void *state, kg_feature f, double v, kg_err *err)
{
	double have = feature_value(state, f);
	if (isfinite(have) && fabs(v - have) <= 0.005 * fabs(have))
		return 0;
	return kg_fail(err, KG_ERANGE,
	               "%s: the files were taken at %g; files: serves them as they are and "
	               "cannot set %g",
	               kg_feature_name(f), have, v);
}

/* ---- format and stream ------------------------------------------------------------------ */

static int files_get_format(void *state, kg_frame_format *out, kg_err *err)
{
	(void)err;
	*out = ((files_cam *)state)->fmt;
	return 0;
}

static int files_set_format(void *state, const kg_frame_format *want, kg_frame_format *got,
                            kg_err *err)
{
	files_cam *s = state;
	const kg_frame_format *f = &s->fmt;
	if ((want->pixfmt != KG_PIX_NONE && want->pixfmt != f->pixfmt) ||
	    (want->width && want->width != f->width) || (want->height && want->height != f->height) ||
	    want->offset_x || want->offset_y || (want->cfa[0] && strcmp(want->cfa, f->cfa)))
		return kg_fail(err, KG_ENOTSUP,
		               "format: the files are %s %dx%d%s%s; files: cannot convert or crop",
		               kg_pixfmt_name(f->pixfmt), f->width, f->height, f->cfa[0] ? " " : "",
		               f->cfa);
	*got = *f;
	return 0;
}

static int files_start(void *state, int nbuffers, kg_err *err)
{
	(void)nbuffers;
	(void)err;
	((files_cam *)state)->streaming = 1;
	return 0;
}

static int files_stop(void *state, kg_err *err)
{
	(void)err;
	((files_cam *)state)->streaming = 0;
	return 0;
}

static uint16_t to_u16(float v)
{
	if (!(v > 0))
		return 0;
	if (v >= 1)
		return 65535;
	return (uint16_t)lrintf(v * 65535.0f);
}

static int files_pop(void *state, int timeout_ms, kg_frame *frame, kg_err *err)
{
	(void)timeout_ms;
	files_cam *s = state;
	if (s->held)
		return kg_fail(err, KG_EINVAL, "the previous frame was not given back");
	if (s->next >= s->nfiles)
		return kg_fail(err, KG_EINVAL,
		               "all %d file(s) were served: ask for at most %d frames (--frames)",
		               s->nfiles, s->nfiles);
	files_entry *f = &s->files[s->next];
	kg_image *img = NULL;
	kg_raw_meta meta;
	int ret = f->raw ? kg_raw_read(f->path, &img, &meta, err) : kg_image_read(f->path, &img, err);
	if (ret)
		return ret;
	if (img->width != s->fmt.width || img->height != s->fmt.height ||
	    img->channels != f->channels) {
		ret = kg_fail(err, KG_EIO, "%s: decodes to %dx%d x%d, its header said %dx%d x%d "
		              "(the file changed?)", f->path, img->width, img->height, img->channels,
		              s->fmt.width, s->fmt.height, f->channels);
		kg_image_free(&img);
		return ret;
	}
	size_t n = (size_t)img->width * (size_t)img->height * (size_t)img->channels;
	for (size_t i = 0; i < n; i++)
		s->buf[i] = to_u16(img->data[i]);
	if (f->raw)
		snprintf(s->note, sizeof(s->note),
		         "%s by LibRaw %s: black %g/%g/%g/%g, white %g/%g/%g/%g, CFA %s",
		         meta.format, kg_raw_version() ? kg_raw_version() : "", meta.black[0],
		         meta.black[1], meta.black[2], meta.black[3], meta.white[0], meta.white[1],
		         meta.white[2], meta.white[3], meta.cfa);
	else
		snprintf(s->note, sizeof(s->note), "%d-bit %s%s%s", img->bits,
		         img->is_float ? "float " : "", "image", img->note[0] ? "; " : "");
	kg_image_free(&img);
	struct stat st;
	memset(frame, 0, sizeof(*frame));
	frame->fmt = s->fmt;
	frame->data = s->buf;
	frame->size = s->fmt.size;
	frame->sequence = (uint64_t)s->next;
	frame->timestamp = f->meta.timestamp > 0 ? (double)f->meta.timestamp
	                   : stat(f->path, &st) == 0 ? (double)st.st_mtim.tv_sec + 1e-9 * st.st_mtim.tv_nsec
	                                             : NAN;
	frame->status = KG_FRAME_OK;
	frame->exposure_us = f->meta.exposure_s * 1e6;
	frame->gain = NAN;
	frame->source = f->path;
	frame->source_note = s->note;
	s->held = 1;
	s->next++;
	return 0;
}

static int files_push(void *state, kg_frame *frame, kg_err *err)
{
	(void)frame;
	(void)err;
	((files_cam *)state)->held = 0;
	return 0;
}

static long files_frames_available(void *state)
{
	const files_cam *s = state;
	return s->nfiles - s->next;
}

const kg_camera_driver kg_camera_files_driver = {
	.scheme = "files",
	.description = "photographs already taken: camera raw files (LibRaw), TIFF and PNG, one "
	               "frame per file (files:DIR or files:DIR/PATTERN)",
	.open = files_open,
	.close = files_close,
	.feature_info = files_feature_info,
	.get = files_get,
	.set = files_set,
	.set_format = files_set_format,
	.get_format = files_get_format,
	.start = files_start,
	.stop = files_stop,
	.pop = files_pop,
	.push = files_push,
	.frames_available = files_frames_available,
};
