/* Chart layouts: patch and tag geometry in millimetres, read from "kogei-chart/1"
 * JSON or from ArgyllCMS .cht recognition templates, and the checks that make a
 * layout printable and detectable. */
#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#include "kg_calib.h"

/* The tag families a layout may name, with the geometry of apriltag's family tables
 * (width_at_border, total_width, ncodes); chart_print.c checks them against the
 * library when it is present. */
typedef struct tag_family_info {
	const char *name;
	int border_width, total_width, ncodes;
} tag_family_info;

static const tag_family_info tag_families[] = {
	{"tag36h11", 8, 10, 587},
	{"tagStandard41h12", 5, 9, 2115},
};

static const tag_family_info *find_family(const char *name)
{
	for (size_t i = 0; i < sizeof(tag_families) / sizeof(tag_families[0]); i++)
		if (strcmp(tag_families[i].name, name) == 0)
			return &tag_families[i];
	return NULL;
}

void kg_chart_layout_free(kg_chart_layout **l)
{
	if (!l || !*l)
		return;
	free((*l)->tags);
	free((*l)->patches);
	free(*l);
	*l = NULL;
}

/* Ids equal up to zeros padding their trailing number: "A1" and "A01" (Argyll writes
 * both styles: ColorChecker.cie "A01", ColorCheckerPassport.cie "A1"). */
static int same_padded_id(const char *a, const char *b)
{
	size_t na = strcspn(a, "0123456789"), nb = strcspn(b, "0123456789");
	if (na != nb || na == 0 || strncmp(a, b, na) != 0 || !a[na] || !b[nb])
		return 0;
	a += na, b += nb;
	while (*a == '0' && a[1])
		a++;
	while (*b == '0' && b[1])
		b++;
	return strcmp(a, b) == 0 && strspn(a, "0123456789") == strlen(a);
}

int kg_chart_layout_find_patch(const kg_chart_layout *l, const char *id)
{
	if (!l || !id)
		return -1;
	for (int i = 0; i < l->npatches; i++)
		if (strcmp(l->patches[i].id, id) == 0)
			return i;
	for (int i = 0; i < l->npatches; i++)
		if (l->patches[i].alias[0] && strcmp(l->patches[i].alias, id) == 0)
			return i;
	for (int i = 0; i < l->npatches; i++)
		if (same_padded_id(l->patches[i].id, id))
			return i;
	return -1;
}

int kg_chart_layout_find_tag(const kg_chart_layout *l, int id)
{
	if (!l)
		return -1;
	for (int i = 0; i < l->ntags; i++)
		if (l->tags[i].id == id)
			return i;
	return -1;
}

void kg_chart_patch_sample_corners(const kg_chart_layout *l, int i, double corners[4][2])
{
	const kg_chart_patch *p = &l->patches[i];
	double hw = 0.5 * p->size_mm[0] * l->sample_fraction;
	double hh = 0.5 * p->size_mm[1] * l->sample_fraction;
	double cx = p->center_mm[0], cy = p->center_mm[1];
	corners[0][0] = cx - hw, corners[0][1] = cy - hh;
	corners[1][0] = cx + hw, corners[1][1] = cy - hh;
	corners[2][0] = cx + hw, corners[2][1] = cy + hh;
	corners[3][0] = cx - hw, corners[3][1] = cy + hh;
}

void kg_chart_tag_footprint(const kg_chart_layout *l, int i, double rect[4])
{
	const tag_family_info *f = find_family(l->family);
	const kg_chart_tag *t = &l->tags[i];
	double side = f ? t->size_mm * f->total_width / f->border_width : t->size_mm;
	rect[0] = t->center_mm[0] - 0.5 * side;
	rect[1] = t->center_mm[1] - 0.5 * side;
	rect[2] = side;
	rect[3] = side;
}

/* The detected square's corners in apriltag_detection_t.p order for an upright tag
 * (y down): (-1,+1), (+1,+1), (+1,-1), (-1,-1) in tag coordinates. */
static void tag_set_corners(kg_chart_tag *t)
{
	static const double sx[4] = {-1, 1, 1, -1}, sy[4] = {1, 1, -1, -1};
	for (int k = 0; k < 4; k++) {
		t->corners_mm[k][0] = t->center_mm[0] + 0.5 * t->size_mm * sx[k];
		t->corners_mm[k][1] = t->center_mm[1] + 0.5 * t->size_mm * sy[k];
	}
}

/* ---- checks ---------------------------------------------------------------------- */

/* Rectangles x, y, w, h overlap with positive area (touching edges do not count). */
static int rects_overlap(const double a[4], const double b[4])
{
	const double eps = 1e-9 * (1 + fabs(a[2]) + fabs(b[2]));
	return a[0] < b[0] + b[2] - eps && b[0] < a[0] + a[2] - eps &&
	       a[1] < b[1] + b[3] - eps && b[1] < a[1] + a[3] - eps;
}

static int rect_inside(const double in[4], const double out[4])
{
	const double eps = 1e-9 * (1 + fabs(out[2]) + fabs(out[3]));
	return in[0] >= out[0] - eps && in[1] >= out[1] - eps &&
	       in[0] + in[2] <= out[0] + out[2] + eps && in[1] + in[3] <= out[1] + out[3] + eps;
}

static void patch_rect(const kg_chart_patch *p, double r[4])
{
	r[0] = p->center_mm[0] - 0.5 * p->size_mm[0];
	r[1] = p->center_mm[1] - 0.5 * p->size_mm[1];
	r[2] = p->size_mm[0];
	r[3] = p->size_mm[1];
}

static int all_finite(const double *v, int n)
{
	for (int i = 0; i < n; i++)
		if (!isfinite(v[i]))
			return 0;
	return 1;
}

int kg_chart_layout_check(const kg_chart_layout *l, kg_err *err)
{
	kg_check_arg(l, err);
	const char *nm = l->name[0] ? l->name : "layout";
	const char *unit = l->template_units ? "template units" : "mm";
	double frame[4] = {0, 0, l->width_mm, l->height_mm};
	if (!all_finite(frame, 4) || !(l->width_mm > 0) || !(l->height_mm > 0))
		return kg_fail(err, KG_EINVAL, "%s: frame size %g x %g: expected positive sizes",
		               nm, l->width_mm, l->height_mm);
	const double *area = l->chart_area_mm;
	if (!all_finite(area, 4) || !(area[2] > 0) || !(area[3] > 0))
		return kg_fail(err, KG_EINVAL, "%s: chart area: expected x, y and a positive w, h",
		               nm);
	if (!rect_inside(area, frame))
		return kg_fail(err, KG_EINVAL,
		               "%s: chart area (%g, %g, %g x %g %s) is not inside the %g x %g frame",
		               nm, area[0], area[1], area[2], area[3], unit, l->width_mm,
		               l->height_mm);
	if (!(l->sample_fraction > 0 && l->sample_fraction <= 1))
		return kg_fail(err, KG_EINVAL, "%s: sample_fraction %g: expected 0 < f <= 1", nm,
		               l->sample_fraction);
	if (l->npatches < 1)
		return kg_fail(err, KG_EINVAL, "%s: no patches", nm);
	for (int i = 0; i < l->npatches; i++) {
		const kg_chart_patch *p = &l->patches[i];
		double r[4];
		patch_rect(p, r);
		if (!p->id[0])
			return kg_fail(err, KG_EINVAL, "%s: patch %d has an empty id", nm, i + 1);
		if (!all_finite(r, 4) || !(p->size_mm[0] > 0) || !(p->size_mm[1] > 0))
			return kg_fail(err, KG_EINVAL,
			               "%s: patch %s: expected a finite centre and a positive size", nm,
			               p->id);
		if (!rect_inside(r, area))
			return kg_fail(err, KG_EINVAL,
			               "%s: patch %s (%g..%g, %g..%g %s) lies outside the chart area",
			               nm, p->id, r[0], r[0] + r[2], r[1], r[1] + r[3], unit);
		for (int j = 0; j < i; j++) {
			const kg_chart_patch *q = &l->patches[j];
			if (strcmp(p->id, q->id) == 0 || (p->alias[0] && strcmp(p->alias, q->alias) == 0))
				return kg_fail(err, KG_EINVAL, "%s: patch id %s appears twice", nm,
				               strcmp(p->id, q->id) == 0 ? p->id : p->alias);
			/* Boxes may overlap by up to 1 % of the smaller side: ArgyllCMS's own
			 * it8Wolf.cht steps its grey scale 0.2 % less than its box width. */
			double s[4], t = 0.01 * fmin(fmin(r[2], r[3]), fmin(q->size_mm[0], q->size_mm[1]));
			patch_rect(q, s);
			double shrunk[4] = {r[0] + t, r[1] + t, r[2] - 2 * t, r[3] - 2 * t};
			if (rects_overlap(shrunk, s))
				return kg_fail(err, KG_EINVAL, "%s: patches %s and %s overlap", nm, q->id,
				               p->id);
		}
	}
	if (l->ntags == 0)
		return 0;
	const tag_family_info *f = find_family(l->family);
	if (!f)
		return kg_fail(err, KG_EINVAL,
		               "%s: tag family \"%s\": expected tag36h11 or tagStandard41h12", nm,
		               l->family);
	for (int i = 0; i < l->ntags; i++) {
		const kg_chart_tag *t = &l->tags[i];
		double r[4];
		kg_chart_tag_footprint(l, i, r);
		if (t->id < 0 || t->id >= f->ncodes)
			return kg_fail(err, KG_EINVAL, "%s: tag id %d: expected 0..%d for %s", nm, t->id,
			               f->ncodes - 1, f->name);
		if (!all_finite(r, 4) || !(t->size_mm > 0))
			return kg_fail(err, KG_EINVAL,
			               "%s: tag %d: expected a finite centre and a positive size", nm,
			               t->id);
		if (!rect_inside(r, frame))
			return kg_fail(err, KG_EINVAL, "%s: tag %d (printed %g x %g at %g, %g) is not "
			               "inside the %g x %g frame", nm, t->id, r[2], r[3], r[0], r[1],
			               l->width_mm, l->height_mm);
		if (rects_overlap(r, area))
			return kg_fail(err, KG_EINVAL,
			               "%s: tag %d overlaps the chart area: the chart would cover it",
			               nm, t->id);
		for (int j = 0; j < i; j++) {
			double s[4];
			kg_chart_tag_footprint(l, j, s);
			if (l->tags[j].id == t->id)
				return kg_fail(err, KG_EINVAL, "%s: tag id %d appears twice", nm, t->id);
			if (rects_overlap(r, s))
				return kg_fail(err, KG_EINVAL, "%s: tags %d and %d overlap", nm,
				               l->tags[j].id, t->id);
		}
	}
	return 0;
}

/* ---- JSON ------------------------------------------------------------------------ */

static int copy_string(const char *file, const json_t *root, const char *key, char *dst,
                       size_t size, int required, kg_err *err)
{
	const char *s = NULL;
	if (!required && !kg_json_find(root, key)) {
		dst[0] = '\0';
		return 0;
	}
	int ret = kg_json_get_string(file, root, key, &s, err);
	if (ret)
		return ret;
	if (strlen(s) >= size)
		return kg_fail(err, KG_EINVAL, "%s: %s: \"%s\" is longer than %zu characters", file,
		               key, s, size - 1);
	snprintf(dst, size, "%s", s);
	return 0;
}

static int parse_json(const char *path, const json_t *root, kg_chart_layout *l, kg_err *err)
{
	const char *fmt = NULL;
	int ret = kg_json_get_string(path, root, "format", &fmt, err);
	if (ret)
		return ret;
	if (strcmp(fmt, KG_CHART_FORMAT) != 0)
		return kg_fail(err, KG_EINVAL, "%s: format \"%s\": expected \"%s\"", path, fmt,
		               KG_CHART_FORMAT);
	double frame[2];
	if ((ret = copy_string(path, root, "name", l->name, sizeof(l->name), 1, err)) ||
	    (ret = kg_json_get_numbers(path, root, "frame_mm", 2, frame, err)) ||
	    (ret = kg_json_get_numbers(path, root, "chart_area_mm", 4, l->chart_area_mm, err)) ||
	    (ret = kg_json_get_number(path, root, "sample_fraction", &l->sample_fraction, err)))
		return ret;
	l->width_mm = frame[0];
	l->height_mm = frame[1];

	json_t *patches = NULL;
	if ((ret = kg_json_get(path, root, "patches", &patches, err)))
		return ret;
	if (!json_is_array(patches) || json_array_size(patches) == 0)
		return kg_fail(err, KG_EINVAL, "%s: patches: expected a non-empty array", path);
	l->npatches = (int)json_array_size(patches);
	if (!(l->patches = calloc((size_t)l->npatches, sizeof(*l->patches))))
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; i < l->npatches; i++) {
		kg_chart_patch *p = &l->patches[i];
		char key[64];
#define PKEY(k) (snprintf(key, sizeof(key), "patches[%d].%s", i, (k)), key)
		if ((ret = copy_string(path, root, PKEY("id"), p->id, sizeof(p->id), 1, err)) ||
		    (ret = copy_string(path, root, PKEY("alias"), p->alias, sizeof(p->alias), 0,
		                       err)) ||
		    (ret = copy_string(path, root, PKEY("name"), p->name, sizeof(p->name), 0, err)) ||
		    (ret = kg_json_get_numbers(path, root, PKEY("center_mm"), 2, p->center_mm, err)) ||
		    (ret = kg_json_get_numbers(path, root, PKEY("size_mm"), 2, p->size_mm, err)))
			return ret;
#undef PKEY
	}

	json_t *tags = kg_json_find(root, "tags");
	if (!tags)
		return 0;
	if (!json_is_array(tags))
		return kg_fail(err, KG_EINVAL, "%s: tags: expected an array", path);
	if ((ret = copy_string(path, root, "tag_family", l->family, sizeof(l->family), 1, err)))
		return ret;
	l->ntags = (int)json_array_size(tags);
	if (l->ntags && !(l->tags = calloc((size_t)l->ntags, sizeof(*l->tags))))
		return kg_fail(err, KG_ENOMEM, "out of memory");
	for (int i = 0; i < l->ntags; i++) {
		kg_chart_tag *t = &l->tags[i];
		char key[64];
		long id;
#define TKEY(k) (snprintf(key, sizeof(key), "tags[%d].%s", i, (k)), key)
		if ((ret = kg_json_get_int(path, root, TKEY("id"), 0, 1 << 20, &id, err)) ||
		    (ret = kg_json_get_numbers(path, root, TKEY("center_mm"), 2, t->center_mm, err)) ||
		    (ret = kg_json_get_number(path, root, TKEY("size_mm"), &t->size_mm, err)))
			return ret;
#undef TKEY
		t->id = (int)id;
		tag_set_corners(t);
	}
	return 0;
}

/* ---- ArgyllCMS .cht --------------------------------------------------------------- */

/* A .cht file as lines of whitespace-separated tokens. */
typedef struct cht_reader {
	const char *path;
	char *buf;
	char *next;      /* start of the next line */
	int lineno;
	char *tok[16];
	int ntok;
} cht_reader;

/* Read the next line that holds tokens; 0 at the end of the file. Lines with more
 * than 16 tokens keep their first 16 and set ntok to 17 so callers refuse them. */
static int cht_next_line(cht_reader *r)
{
	while (r->next && *r->next) {
		char *line = r->next;
		char *nl = strpbrk(line, "\r\n");
		if (nl) {
			int crlf = nl[0] == '\r' && nl[1] == '\n';
			*nl = '\0';
			r->next = nl + 1 + crlf;
		} else {
			r->next = NULL;
		}
		r->lineno++;
		r->ntok = 0;
		char *save = NULL;
		for (char *s = strtok_r(line, " \t", &save); s; s = strtok_r(NULL, " \t", &save)) {
			if (r->ntok == 16) {
				r->ntok = 17;
				break;
			}
			r->tok[r->ntok++] = s;
		}
		if (r->ntok > 0)
			return 1;
	}
	return 0;
}

static int cht_number(cht_reader *r, int i, const char *what, double *out, kg_err *err)
{
	char *end;
	errno = 0;
	double v = strtod(r->tok[i], &end);
	if (end == r->tok[i] || *end || errno == ERANGE || !isfinite(v))
		return kg_fail(err, KG_EINVAL, "%s:%d: %s: \"%s\" is not a number", r->path,
		               r->lineno, what, r->tok[i]);
	*out = v;
	return 0;
}

static int cht_count(cht_reader *r, const char *keyword, long max, long *out, kg_err *err)
{
	char *end;
	if (r->ntok != 2)
		return kg_fail(err, KG_EINVAL, "%s:%d: %s: expected one count after the keyword",
		               r->path, r->lineno, keyword);
	long n = strtol(r->tok[1], &end, 10);
	if (end == r->tok[1] || *end || n < 0 || n > max)
		return kg_fail(err, KG_EINVAL, "%s:%d: %s: count \"%s\": expected 0..%ld", r->path,
		               r->lineno, keyword, r->tok[1], max);
	*out = n;
	return 0;
}

/* Argyll's labels step like an odometer: digits 0-9 and letters A-Z (a-z) carry into
 * the character on their left; a carry out of the first character prepends "1" or
 * "A" ("9" -> "10", "Z" -> "AA"). 0 when the label cannot grow (too long). */
static int label_increment(char *s, size_t size)
{
	size_t n = strlen(s);
	for (size_t k = n; k-- > 0;) {
		char c = s[k];
		if (c == '9')
			s[k] = '0';
		else if (c == 'Z')
			s[k] = 'A';
		else if (c == 'z')
			s[k] = 'a';
		else if (isalnum((unsigned char)c)) {
			s[k] = (char)(c + 1);
			return 1;
		} else {
			return 0; /* a symbol cannot be stepped */
		}
	}
	if (n + 2 > size)
		return 0;
	memmove(s + 1, s, n + 1);
	s[0] = isdigit((unsigned char)s[1]) ? '1' : (s[1] >= 'a' ? 'a' : 'A');
	return 1;
}

#define CHT_MAX_LABELS 4096

/* The labels from first to last inclusive; "_" alone is one empty label. */
static int label_range(cht_reader *r, const char *first, const char *last, char (**out)[16],
                       int *n, kg_err *err)
{
	if (strcmp(first, "_") == 0 || strcmp(last, "_") == 0) {
		if (strcmp(first, last) != 0)
			return kg_fail(err, KG_EINVAL, "%s:%d: label range %s..%s: \"_\" must be used "
			               "for both ends", r->path, r->lineno, first, last);
		if (!(*out = calloc(1, sizeof(**out))))
			return kg_fail(err, KG_ENOMEM, "out of memory");
		*n = 1;
		return 0;
	}
	if (strlen(first) >= 16 || strlen(last) >= 16)
		return kg_fail(err, KG_EINVAL, "%s:%d: label %s or %s is longer than 15 characters",
		               r->path, r->lineno, first, last);
	char (*labels)[16] = calloc(CHT_MAX_LABELS, sizeof(*labels));
	if (!labels)
		return kg_fail(err, KG_ENOMEM, "out of memory");
	char cur[16];
	snprintf(cur, sizeof(cur), "%s", first);
	int k = 0;
	for (;;) {
		if (k == CHT_MAX_LABELS || strlen(cur) > strlen(last)) {
			free(labels);
			return kg_fail(err, KG_EINVAL, "%s:%d: label range %s..%s: stepping from %s "
			               "never reaches %s", r->path, r->lineno, first, last, first, last);
		}
		memcpy(labels[k++], cur, sizeof(cur));
		if (strcmp(cur, last) == 0)
			break;
		if (!label_increment(cur, sizeof(cur))) {
			free(labels);
			return kg_fail(err, KG_EINVAL, "%s:%d: label %s cannot be stepped towards %s",
			               r->path, r->lineno, cur, last);
		}
	}
	*out = labels;
	*n = k;
	return 0;
}

typedef struct cht_state {
	kg_chart_patch *patches;
	int npatches, cap;
	double fid[4][2];
	int have_fid;
	long nboxes_declared;
	long nboxes_seen;   /* patches and diagnostic boxes */
	double shrink;
	int have_boxes, have_shrink;
} cht_state;

static int cht_add_patch(cht_state *st, const char *id, double x, double y, double w,
                         double h)
{
	if (st->npatches == st->cap) {
		int cap = st->cap ? 2 * st->cap : 64;
		kg_chart_patch *p = realloc(st->patches, (size_t)cap * sizeof(*p));
		if (!p)
			return KG_ENOMEM;
		st->patches = p;
		st->cap = cap;
	}
	kg_chart_patch *p = &st->patches[st->npatches++];
	memset(p, 0, sizeof(*p));
	snprintf(p->id, sizeof(p->id), "%s", id);
	p->center_mm[0] = x + 0.5 * w;
	p->center_mm[1] = y + 0.5 * h;
	p->size_mm[0] = w;
	p->size_mm[1] = h;
	return 0;
}

/* One BOXES line: F (fiducials), D (diagnostic boxes, counted only), X or Y (sample
 * boxes; X names a box x label first, Y y label first):
 *   X xfirst xlast yfirst ylast w h xorigin yorigin xstep ystep */
static int cht_box_line(cht_reader *r, cht_state *st, kg_err *err)
{
	const char *kind = r->tok[0];
	int ret;
	if (strcmp(kind, "F") == 0) {
		if (r->ntok != 11)
			return kg_fail(err, KG_EINVAL, "%s:%d: F line: expected \"F _ _\" and 8 numbers "
			               "(four corners), found %d fields", r->path, r->lineno, r->ntok);
		for (int k = 0; k < 8; k++)
			if ((ret = cht_number(r, 3 + k, "fiducial corner", &st->fid[k / 2][k % 2], err)))
				return ret;
		st->have_fid = 1;
		return 0;
	}
	if (strcmp(kind, "D") && strcmp(kind, "X") && strcmp(kind, "Y"))
		return kg_fail(err, KG_EINVAL, "%s:%d: box line \"%s\": expected F, D, X or Y",
		               r->path, r->lineno, kind);
	if (r->ntok != 11)
		return kg_fail(err, KG_EINVAL, "%s:%d: %s line: expected 4 labels and 6 numbers (w h "
		               "xorigin yorigin xstep ystep), found %d fields", r->path, r->lineno,
		               kind, r->ntok);
	double v[6];
	static const char *const what[6] = {"width", "height", "x origin", "y origin", "x step",
	                                    "y step"};
	for (int k = 0; k < 6; k++)
		if ((ret = cht_number(r, 5 + k, what[k], &v[k], err)))
			return ret;
	if (!(v[0] > 0) || !(v[1] > 0))
		return kg_fail(err, KG_EINVAL, "%s:%d: box size %g x %g: expected positive sizes",
		               r->path, r->lineno, v[0], v[1]);
	char (*xl)[16] = NULL, (*yl)[16] = NULL;
	int nx = 0, ny = 0;
	if ((ret = label_range(r, r->tok[1], r->tok[2], &xl, &nx, err)) ||
	    (ret = label_range(r, r->tok[3], r->tok[4], &yl, &ny, err))) {
		free(xl);
		return ret;
	}
	st->nboxes_seen += (long)nx * ny;
	if (kind[0] != 'D') {
		for (int iy = 0; iy < ny && !ret; iy++)
			for (int ix = 0; ix < nx && !ret; ix++) {
				/* two labels of at most 15 characters (label_range): every id fits
				 * a patch's, checked here at compile time */
				char id[2 * sizeof(*xl) - 1];
				_Static_assert(sizeof(id) <= sizeof(st->patches[0].id),
				               "a patch id holds two box labels");
				if (kind[0] == 'X')
					snprintf(id, sizeof(id), "%s%s", xl[ix], yl[iy]);
				else
					snprintf(id, sizeof(id), "%s%s", yl[iy], xl[ix]);
				if (cht_add_patch(st, id, v[2] + ix * v[4], v[3] + iy * v[5], v[0], v[1]))
					ret = kg_fail(err, KG_ENOMEM, "out of memory");
			}
	}
	free(xl);
	free(yl);
	return ret;
}

static const char *const cht_sections[] = {"BOXES", "BOX_SHRINK", "REF_ROTATION", "XLIST",
                                           "YLIST", "EXPECTED"};

static int cht_is_section(const char *s)
{
	for (size_t i = 0; i < sizeof(cht_sections) / sizeof(cht_sections[0]); i++)
		if (strcmp(s, cht_sections[i]) == 0)
			return 1;
	return 0;
}

/* A data line of XLIST/YLIST (numbers only) or EXPECTED (an id, then numbers). */
static int cht_data_line(cht_reader *r, int has_id)
{
	if (r->ntok < 2 || r->ntok > 16 || cht_is_section(r->tok[0]))
		return 0;
	for (int i = has_id ? 1 : 0; i < r->ntok; i++) {
		char *end;
		double v = strtod(r->tok[i], &end);
		if (end == r->tok[i] || *end || !isfinite(v))
			return 0;
	}
	return 1;
}

/* The n data lines of XLIST, YLIST or EXPECTED, then any further lines of the same
 * shape: ArgyllCMS's own templates do not always count them exactly (ISO12641_2_1.cht
 * lists one more YLIST edge than it declares, it8Wolf.cht 24 more EXPECTED values).
 * Leaves the reader on the next section's line; *have is 0 at the end of the file. */
static int cht_data_lines(cht_reader *r, const char *keyword, long n, int has_id, int *have,
                          kg_err *err)
{
	int start = r->lineno;
	for (long k = 0; k < n; k++) {
		if (!cht_next_line(r))
			return kg_fail(err, KG_EINVAL, "%s:%d: %s declares %ld lines, the file ends "
			               "after %ld", r->path, start, keyword, n, k);
		if (!cht_data_line(r, has_id))
			return kg_fail(err, KG_EINVAL, "%s:%d: %s line %ld of %ld: expected %s",
			               r->path, r->lineno, keyword, k + 1, n,
			               has_id ? "an id and numbers" : "numbers");
	}
	while ((*have = cht_next_line(r)) && cht_data_line(r, has_id))
		;
	return 0;
}

static int cht_parse(cht_reader *r, cht_state *st, kg_err *err)
{
	int ret = 0, have = cht_next_line(r);
	while (have) {
		const char *kw = r->tok[0];
		long n = 0; /* cht_count sets it on success only; GCC cannot see kg_fail is nonzero */
		if (strcmp(kw, "BOXES") == 0) {
			if (st->have_boxes)
				return kg_fail(err, KG_EINVAL, "%s:%d: a second BOXES section", r->path,
				               r->lineno);
			if ((ret = cht_count(r, "BOXES", 1000000, &st->nboxes_declared, err)))
				return ret;
			st->have_boxes = 1;
			while ((have = cht_next_line(r)) && !cht_is_section(r->tok[0]))
				if ((ret = cht_box_line(r, st, err)))
					return ret;
			continue;
		} else if (strcmp(kw, "BOX_SHRINK") == 0) {
			if (r->ntok != 2)
				return kg_fail(err, KG_EINVAL, "%s:%d: BOX_SHRINK: expected one number",
				               r->path, r->lineno);
			if ((ret = cht_number(r, 1, "BOX_SHRINK", &st->shrink, err)))
				return ret;
			if (st->shrink < 0)
				return kg_fail(err, KG_EINVAL, "%s:%d: BOX_SHRINK %g: expected >= 0",
				               r->path, r->lineno, st->shrink);
			st->have_shrink = 1;
		} else if (strcmp(kw, "REF_ROTATION") == 0) {
			double rot;
			if (r->ntok != 2)
				return kg_fail(err, KG_EINVAL, "%s:%d: REF_ROTATION: expected one number",
				               r->path, r->lineno);
			if ((ret = cht_number(r, 1, "REF_ROTATION", &rot, err)))
				return ret;
		} else if (strcmp(kw, "XLIST") == 0 || strcmp(kw, "YLIST") == 0) {
			const char *name = kw[0] == 'X' ? "XLIST" : "YLIST";
			if ((ret = cht_count(r, name, 100000, &n, err)) ||
			    (ret = cht_data_lines(r, name, n, 0, &have, err)))
				return ret;
			continue;
		} else if (strcmp(kw, "EXPECTED") == 0) {
			/* EXPECTED <space> <count>, then "id v1 v2 v3" lines */
			if (r->ntok != 3)
				return kg_fail(err, KG_EINVAL, "%s:%d: EXPECTED: expected a colour space "
				               "and a count", r->path, r->lineno);
			r->tok[1] = r->tok[2];
			r->ntok = 2;
			if ((ret = cht_count(r, "EXPECTED", 1000000, &n, err)) ||
			    (ret = cht_data_lines(r, "EXPECTED", n, 1, &have, err)))
				return ret;
			continue;
		} else {
			return kg_fail(err, KG_EINVAL, "%s:%d: \"%s\": expected BOXES, BOX_SHRINK, "
			               "REF_ROTATION, XLIST, YLIST or EXPECTED", r->path, r->lineno, kw);
		}
		have = cht_next_line(r);
	}
	if (!st->have_boxes)
		return kg_fail(err, KG_EINVAL, "%s: no BOXES section: not an ArgyllCMS chart "
		               "recognition template", r->path);
	if (st->npatches == 0)
		return kg_fail(err, KG_EINVAL, "%s: BOXES has no X or Y sample boxes", r->path);
	if (st->nboxes_seen != st->nboxes_declared)
		return kg_fail(err, KG_EINVAL, "%s: BOXES declares %ld boxes, its lines give %ld "
		               "(sample and diagnostic boxes)", r->path, st->nboxes_declared,
		               st->nboxes_seen);
	return 0;
}

int kg_chart_layout_load_cht(const char *path, double width_mm, kg_chart_layout **out,
                             kg_err *err)
{
	kg_check_arg(path && out, err);
	kg_check_arg(width_mm >= 0 && isfinite(width_mm), err);
	*out = NULL;
	cht_reader r = {.path = path};
	size_t len;
	int ret = kg_read_file(path, &r.buf, &len, err);
	if (ret)
		return ret;
	if (strlen(r.buf) != len) {
		free(r.buf);
		return kg_fail(err, KG_EINVAL, "%s: contains NUL bytes: not a text template", path);
	}
	r.next = r.buf;
	cht_state st = {0};
	kg_chart_layout *l = NULL;
	if ((ret = cht_parse(&r, &st, err)))
		goto error;
	if (!(l = calloc(1, sizeof(*l)))) {
		ret = kg_fail(err, KG_ENOMEM, "out of memory");
		goto error;
	}
	const char *base = strrchr(path, '/');
	base = base ? base + 1 : path;
	snprintf(l->name, sizeof(l->name), "%.*s", (int)strcspn(base, "."), base);

	/* chart area: the bounding box of the fiducials and the boxes */
	double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY, smin = INFINITY;
	for (int i = 0; i < st.npatches; i++) {
		const kg_chart_patch *p = &st.patches[i];
		x0 = fmin(x0, p->center_mm[0] - 0.5 * p->size_mm[0]);
		x1 = fmax(x1, p->center_mm[0] + 0.5 * p->size_mm[0]);
		y0 = fmin(y0, p->center_mm[1] - 0.5 * p->size_mm[1]);
		y1 = fmax(y1, p->center_mm[1] + 0.5 * p->size_mm[1]);
		smin = fmin(smin, fmin(p->size_mm[0], p->size_mm[1]));
	}
	for (int k = 0; st.have_fid && k < 4; k++) {
		x0 = fmin(x0, st.fid[k][0]), x1 = fmax(x1, st.fid[k][0]);
		y0 = fmin(y0, st.fid[k][1]), y1 = fmax(y1, st.fid[k][1]);
	}
	if (x0 < 0 || y0 < 0) {
		ret = kg_fail(err, KG_EINVAL, "%s: boxes reach negative coordinates (%g, %g): "
		              "expected a template with its origin at the top left", path, x0, y0);
		goto error;
	}
	if (2 * st.shrink >= smin) {
		ret = kg_fail(err, KG_EINVAL, "%s: BOX_SHRINK %g leaves nothing of the smallest box "
		              "(%g)", path, st.shrink, smin);
		goto error;
	}
	double scale = width_mm > 0 ? width_mm / (x1 - x0) : 1.0;
	l->template_units = width_mm > 0 ? 0 : 1;
	l->sample_fraction = 1.0 - 2.0 * st.shrink / smin;
	l->chart_area_mm[0] = x0 * scale;
	l->chart_area_mm[1] = y0 * scale;
	l->chart_area_mm[2] = (x1 - x0) * scale;
	l->chart_area_mm[3] = (y1 - y0) * scale;
	l->width_mm = x1 * scale;
	l->height_mm = y1 * scale;
	for (int i = 0; i < st.npatches; i++)
		for (int k = 0; k < 2; k++) {
			st.patches[i].center_mm[k] *= scale;
			st.patches[i].size_mm[k] *= scale;
		}
	l->patches = st.patches;
	l->npatches = st.npatches;
	st.patches = NULL;
	if ((ret = kg_chart_layout_check(l, err))) {
		kg_err_prefix(err, "%s", path);
		goto error;
	}
	free(r.buf);
	*out = l;
	return 0;
error:
	free(r.buf);
	free(st.patches);
	kg_chart_layout_free(&l);
	return ret;
}

static int has_suffix(const char *s, const char *suffix)
{
	size_t n = strlen(s), m = strlen(suffix);
	return n >= m && strcasecmp(s + n - m, suffix) == 0;
}

static const kg_data_name bundled_layouts[] = {
	{"colorchecker24-frame", "charts/colorchecker24-frame.json"},
	{"colorchecker-passport-frame", "charts/colorchecker-passport-frame.json"},
	{"colorchecker-sg-frame", "charts/colorchecker-sg-frame.json"},
	{"cie-tcs-frame", "demo/cie-tcs-frame.json"},
};

int kg_chart_layout_resolve(const char *arg, char **path, kg_err *err)
{
	return kg_data_resolve(arg, "chart layout", bundled_layouts,
	                       (int)(sizeof(bundled_layouts) / sizeof(bundled_layouts[0])), path,
	                       err);
}

/* The bundled layout named name (a ".json" suffix allowed), or NULL. */
static const kg_data_name *bundled_layout(const char *name)
{
	size_t len = strlen(name);
	if (len > 5 && !strcmp(name + len - 5, ".json"))
		len -= 5;
	for (size_t i = 0; i < sizeof(bundled_layouts) / sizeof(bundled_layouts[0]); i++)
		if (strlen(bundled_layouts[i].name) == len && !strncmp(bundled_layouts[i].name, name, len))
			return &bundled_layouts[i];
	return NULL;
}

int kg_chart_layout_is_bundled(const char *name)
{
	return name && !strchr(name, '/') && bundled_layout(name) != NULL;
}

int kg_chart_layout_resolve_session(const char *session_dir, const char *manifest,
                                    const char *key, const char *value, char **path,
                                    kg_err *err)
{
	kg_check_arg(session_dir && manifest && key && value && path, err);
	*path = NULL;
	if (kg_chart_layout_is_bundled(value)) {
		*path = kg_data_path(bundled_layout(value)->file);
		return *path ? 0 : kg_fail(err, KG_ENOMEM, "%s: out of memory", manifest);
	}
	struct stat st;
	kg_err e = {{0}};
	int ret = !strncmp(value, "captures/", 9) && kg_relpath_is_safe(value, 256)
	                  ? kg_stat_below(session_dir, value, &st, &e)
	                  : KG_EINVAL;
	if (!ret && !S_ISREG(st.st_mode))
		ret = KG_EINVAL;
	if (ret) {
		char names[256] = "";
		for (size_t i = 0, at = 0;
		     i < sizeof(bundled_layouts) / sizeof(bundled_layouts[0]) && at < sizeof(names); i++)
			at += (size_t)snprintf(names + at, sizeof(names) - at, "%s%s", i ? ", " : "",
			                       bundled_layouts[i].name);
		return kg_fail(err, KG_EINVAL,
		               "%s: %s: '%s': expected a bundled chart layout (%s) or a regular file "
		               "captures/<capture>/<file> inside the session %s%s%s",
		               manifest, key, value, names, session_dir, e.msg[0] ? ": " : "", e.msg);
	}
	*path = kg_path_join(session_dir, value);
	return *path ? 0 : kg_fail(err, KG_ENOMEM, "%s: out of memory", manifest);
}

static int load_json(const char *path, kg_chart_layout **out, kg_err *err)
{
	json_t *root = NULL;
	int ret = kg_json_load(path, &root, err);
	if (ret)
		return ret;
	kg_chart_layout *l = calloc(1, sizeof(*l));
	if (!l) {
		json_decref(root);
		return kg_fail(err, KG_ENOMEM, "out of memory");
	}
	ret = parse_json(path, root, l, err);
	json_decref(root);
	if (!ret && (ret = kg_chart_layout_check(l, err)) != 0)
		kg_err_prefix(err, "%s", path);
	if (ret) {
		kg_chart_layout_free(&l);
		return ret;
	}
	*out = l;
	return 0;
}

int kg_chart_layout_load(const char *arg, kg_chart_layout **out, kg_err *err)
{
	kg_check_arg(arg && out, err);
	*out = NULL;
	char *path;
	int ret = kg_chart_layout_resolve(arg, &path, err);
	if (ret)
		return ret;
	ret = has_suffix(path, ".cht") ? kg_chart_layout_load_cht(path, 0, out, err)
	                               : load_json(path, out, err);
	free(path);
	return ret;
}
