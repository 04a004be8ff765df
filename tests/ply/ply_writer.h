/* A PLY writer for the tests, independent of render/ply.c: it builds files in memory
 * byte by byte in any of the three encodings, with any scalar type for the positions
 * and any count/item types for the face lists, polygons of any size, and optional
 * extra properties and elements the loader must skip. */
#ifndef PLY_WRITER_H
#define PLY_WRITER_H

#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct tw_buf {
	char *p;
	size_t len, cap;
} tw_buf;

static void tw_put(tw_buf *b, const void *src, size_t n)
{
	if (b->len + n + 1 > b->cap) {
		size_t cap = (b->len + n + 1) * 2;
		char *p = realloc(b->p, cap);
		if (!p) {
			fprintf(stderr, "out of memory\n");
			exit(1);
		}
		b->p = p;
		b->cap = cap;
	}
	memcpy(b->p + b->len, src, n);
	b->len += n;
	b->p[b->len] = '\0';
}

static void tw_printf(tw_buf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void tw_printf(tw_buf *b, const char *fmt, ...)
{
	char tmp[512];
	va_list ap;
	va_start(ap, fmt);
	int n = vsnprintf(tmp, sizeof(tmp), fmt, ap);
	va_end(ap);
	tw_put(b, tmp, (size_t)n);
}

enum tw_encoding { TW_ASCII, TW_LE, TW_BE };

/* A polygon soup: what the writer writes and what a loaded mesh is compared with. */
typedef struct tw_mesh {
	size_t nverts, nfaces;
	const double *pos;        /* nverts x 3 */
	const double *normal;     /* nverts x 3 or NULL */
	const unsigned char *rgb; /* nverts x 3 (written as uchar) or NULL */
	const int *vert_material; /* or NULL */
	const unsigned *face_len; /* nfaces */
	const unsigned *face_idx; /* concatenated indices */
	const int *face_material; /* or NULL */
} tw_mesh;

typedef struct tw_opts {
	enum tw_encoding enc;
	const char *pos_type;   /* any PLY type name, e.g. "float", "int16" */
	const char *count_type; /* list count type */
	const char *index_type; /* list item type */
	int extras;             /* extra properties and elements to be skipped */
	int crlf;               /* header lines end in \r\n */
} tw_opts;

/* The byte size and kind of a PLY type name: 'i' signed, 'u' unsigned, 'f' float. */
static int tw_type(const char *name, char *kind)
{
	static const struct {
		const char *n;
		int size;
		char kind;
	} t[] = {
		{ "char", 1, 'i' },    { "int8", 1, 'i' },    { "uchar", 1, 'u' },   { "uint8", 1, 'u' },
		{ "short", 2, 'i' },   { "int16", 2, 'i' },   { "ushort", 2, 'u' },  { "uint16", 2, 'u' },
		{ "int", 4, 'i' },     { "int32", 4, 'i' },   { "uint", 4, 'u' },    { "uint32", 4, 'u' },
		{ "float", 4, 'f' },   { "float32", 4, 'f' }, { "double", 8, 'f' }, { "float64", 8, 'f' },
	};
	for (size_t i = 0; i < sizeof(t) / sizeof(t[0]); i++)
		if (strcmp(t[i].n, name) == 0) {
			*kind = t[i].kind;
			return t[i].size;
		}
	fprintf(stderr, "tw_type: %s?\n", name);
	exit(1);
}

/* One value of the named type, in the file's encoding. */
static void tw_value(tw_buf *b, const tw_opts *o, const char *type, double v)
{
	char kind;
	int size = tw_type(type, &kind);
	if (o->enc == TW_ASCII) {
		if (kind == 'f')
			tw_printf(b, " %.17g", v);
		else
			tw_printf(b, " %lld", (long long)v);
		return;
	}
	unsigned char bytes[8];
	uint64_t u = 0;
	if (kind == 'f' && size == 4) {
		float f = (float)v;
		uint32_t w;
		memcpy(&w, &f, 4);
		u = w;
	} else if (kind == 'f') {
		memcpy(&u, &v, 8);
	} else if (kind == 'i') {
		u = (uint64_t)(int64_t)v;
	} else {
		u = (uint64_t)v;
	}
	for (int k = 0; k < size; k++) { /* least significant byte first */
		bytes[k] = (unsigned char)(u & 0xff);
		u >>= 8;
	}
	if (o->enc == TW_BE)
		for (int k = 0; k < size / 2; k++) {
			unsigned char c = bytes[k];
			bytes[k] = bytes[size - 1 - k];
			bytes[size - 1 - k] = c;
		}
	tw_put(b, bytes, (size_t)size);
}

/* Ends an element instance: an ASCII line holds one (each value starts with a blank). */
static void tw_line_end(tw_buf *b, const tw_opts *o)
{
	if (o->enc == TW_ASCII)
		tw_put(b, "\n", 1);
}

static void tw_write(tw_buf *b, const tw_mesh *m, const tw_opts *o)
{
	const char *nl = o->crlf ? "\r\n" : "\n";
	b->len = 0;
	tw_printf(b, "ply%sformat %s 1.0%s", nl,
	          o->enc == TW_ASCII ? "ascii" : o->enc == TW_LE ? "binary_little_endian"
	                                                       : "binary_big_endian", nl);
	tw_printf(b, "comment written by tests/ply/ply_writer.h%sobj_info a test mesh%s", nl, nl);
	if (o->extras)
		tw_printf(b, "element camera 2%sproperty float view_px%sproperty list uchar int "
		          "tags%sproperty double view_py%s", nl, nl, nl, nl);
	tw_printf(b, "element vertex %zu%s", m->nverts, nl);
	if (o->extras)
		tw_printf(b, "property list uchar float uv%sproperty short confidence%s", nl, nl);
	tw_printf(b, "property %s x%sproperty %s y%sproperty %s z%s", o->pos_type, nl, o->pos_type,
	          nl, o->pos_type, nl);
	if (m->normal)
		tw_printf(b, "property float nx%sproperty float ny%sproperty float nz%s", nl, nl, nl);
	if (m->rgb)
		tw_printf(b, "property uchar red%sproperty uchar green%sproperty uchar blue%s", nl, nl,
		          nl);
	if (m->vert_material)
		tw_printf(b, "property int material%s", nl);
	if (o->extras)
		tw_printf(b, "property uchar alpha%s", nl);
	if (o->extras)
		tw_printf(b, "element edge 3%sproperty int vertex1%sproperty int vertex2%s", nl, nl, nl);
	tw_printf(b, "element face %zu%s", m->nfaces, nl);
	if (o->extras)
		tw_printf(b, "property uchar flags%s", nl);
	tw_printf(b, "property list %s %s vertex_indices%s", o->count_type, o->index_type, nl);
	if (m->face_material)
		tw_printf(b, "property int material_index%s", nl);
	if (o->extras)
		tw_printf(b, "property list ushort double texcoord%s", nl);
	tw_printf(b, "end_header\n");

	for (int c = 0; o->extras && c < 2; c++) {
		tw_value(b, o, "float", 0.25 * c);
		tw_value(b, o, "uchar", 2);
		tw_value(b, o, "int", -7);
		tw_value(b, o, "int", 9);
		tw_value(b, o, "double", 1e-300);
		tw_line_end(b, o);
	}
	for (size_t i = 0; i < m->nverts; i++) {
		if (o->extras) {
			tw_value(b, o, "uchar", (double)(i % 3));
			for (size_t k = 0; k < i % 3; k++)
				tw_value(b, o, "float", 0.5 * (double)k);
			tw_value(b, o, "short", -(double)i);
		}
		for (int k = 0; k < 3; k++)
			tw_value(b, o, o->pos_type, m->pos[i * 3 + (size_t)k]);
		for (int k = 0; m->normal && k < 3; k++)
			tw_value(b, o, "float", m->normal[i * 3 + (size_t)k]);
		for (int k = 0; m->rgb && k < 3; k++)
			tw_value(b, o, "uchar", m->rgb[i * 3 + (size_t)k]);
		if (m->vert_material)
			tw_value(b, o, "int", m->vert_material[i]);
		if (o->extras)
			tw_value(b, o, "uchar", 255);
		tw_line_end(b, o);
	}
	for (int e = 0; o->extras && e < 3; e++) {
		tw_value(b, o, "int", e);
		tw_value(b, o, "int", e + 1);
		tw_line_end(b, o);
	}
	size_t at = 0;
	for (size_t f = 0; f < m->nfaces; f++) {
		if (o->extras)
			tw_value(b, o, "uchar", 1);
		tw_value(b, o, o->count_type, m->face_len[f]);
		for (unsigned k = 0; k < m->face_len[f]; k++)
			tw_value(b, o, o->index_type, m->face_idx[at + k]);
		at += m->face_len[f];
		if (m->face_material)
			tw_value(b, o, "int", m->face_material[f]);
		if (o->extras) {
			tw_value(b, o, "ushort", 2);
			tw_value(b, o, "double", 0.125);
			tw_value(b, o, "double", -3.5);
		}
		tw_line_end(b, o);
	}
}

#endif
