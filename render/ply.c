/* The PLY loader and writer (see kg_mesh.h and docs/ply.md).
 *
 * The whole file is mapped (or handed over in memory) and parsed in one pass: the
 * header into a table of elements and properties, each property given a role (x, nx,
 * red, vertex_indices, material, ...) or skipped; then the data, element by element.
 * Binary values are read with memcpy and a byte swap when the file's byte order is not
 * the host's; ASCII numbers with the hand-written parsers below (strtod only for
 * numbers the exact fast path cannot take). ASCII data is one element per line, as in
 * Turk's reference reader.
 *
 * A forged header cannot make us allocate: every element's instance count times the
 * smallest size one instance can have (binary: its scalar and list-count bytes; ASCII:
 * two characters per value that must be present) is checked against the bytes that
 * follow the header before anything is allocated. */
#include <fcntl.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "kg_mesh.h"

enum ply_type { PT_NONE, PT_I8, PT_U8, PT_I16, PT_U16, PT_I32, PT_U32, PT_F32, PT_F64 };

static const struct {
	const char *name;
	enum ply_type type;
} ply_type_names[] = {
	{ "char", PT_I8 },    { "int8", PT_I8 },     { "uchar", PT_U8 },    { "uint8", PT_U8 },
	{ "short", PT_I16 },  { "int16", PT_I16 },   { "ushort", PT_U16 },  { "uint16", PT_U16 },
	{ "int", PT_I32 },    { "int32", PT_I32 },   { "uint", PT_U32 },    { "uint32", PT_U32 },
	{ "float", PT_F32 },  { "float32", PT_F32 }, { "double", PT_F64 }, { "float64", PT_F64 },
};

static const unsigned ply_type_size[] = { 0, 1, 1, 2, 2, 4, 4, 4, 8 };
static const char *const ply_type_label[] = { "?",   "char", "uchar", "short", "ushort",
	                                          "int", "uint", "float", "double" };
/* Range of the integer types (and the full scale a colour of that type is divided by). */
static const double ply_type_min[] = { 0, -128, 0, -32768, 0, -2147483648.0, 0, 0, 0 };
static const double ply_type_max[] = { 0, 127, 255, 32767, 65535, 2147483647.0, 4294967295.0,
	                                   1, 1 };

static int ply_type_is_int(enum ply_type t)
{
	return t >= PT_I8 && t <= PT_U32;
}

enum ply_format { PF_ASCII, PF_BINARY_LE, PF_BINARY_BE };

enum ply_role {
	ROLE_SKIP,
	ROLE_X, ROLE_Y, ROLE_Z,
	ROLE_NX, ROLE_NY, ROLE_NZ,
	ROLE_RED, ROLE_GREEN, ROLE_BLUE,
	ROLE_VMAT,
	ROLE_INDICES,
	ROLE_FMAT,
};

typedef struct ply_prop {
	const char *name;
	int name_len;
	enum ply_type type;       /* the scalar's type, or a list's item type */
	enum ply_type count_type; /* PT_NONE for a scalar */
	enum ply_role role;
	size_t line;              /* header line of the declaration */
} ply_prop;

enum ply_kind { EK_OTHER, EK_VERTEX, EK_FACE };

typedef struct ply_elem {
	const char *name;
	int name_len;
	uint64_t count;
	enum ply_kind kind;
	ply_prop *props;
	int nprops, cap;
	size_t line;
} ply_elem;

typedef struct ply_reader {
	const uint8_t *data, *p, *end;
	const char *name; /* for messages */
	enum ply_format format;
	int swap; /* the file's byte order is not the host's */
	size_t line; /* ASCII: the line p is on (1-based) */
	ply_elem *elems;
	int nelems, cap;
	kg_mesh *m;
	size_t tri_cap;
	kg_err *err;
} ply_reader;

/* Outcomes of reading one value; the caller turns them into a message that names the
 * element and the property. */
enum { V_OK, V_EOL, V_EOF, V_NOTNUM, V_NOTINT, V_RANGE };

#define PLY_MAX_COUNT 4294967295ull /* indices are 32-bit */

/* ---- messages ---------------------------------------------------------------- */

/* A short, printable quotation of file bytes for a message. */
static const char *quote(char *buf, size_t size, const void *s, size_t len)
{
	const unsigned char *c = s;
	size_t o = 0;
	for (size_t i = 0; i < len && o + 5 < size; i++) {
		if (i == 32) {
			o += (size_t)snprintf(buf + o, size - o, "...");
			break;
		}
		if (c[i] >= 0x20 && c[i] < 0x7f)
			buf[o++] = (char)c[i];
		else
			o += (size_t)snprintf(buf + o, size - o, "\\x%02x", c[i]);
	}
	buf[o < size ? o : size - 1] = '\0';
	return buf;
}

/* "line 12" in ASCII data or the header, "byte 4096" in binary data. */
static const char *where(const ply_reader *r, char *buf, size_t size, const uint8_t *at)
{
	if (r->format == PF_ASCII)
		snprintf(buf, size, "line %zu", r->line);
	else
		snprintf(buf, size, "byte %zu", (size_t)(at - r->data));
	return buf;
}

/* ---- header ------------------------------------------------------------------ */

#define MAX_WORDS 8

typedef struct hline {
	const char *w[MAX_WORDS];
	int len[MAX_WORDS];
	int n;
	int more; /* more words than MAX_WORDS */
} hline;

static int word_is(const hline *h, int i, const char *s)
{
	return i < h->n && (size_t)h->len[i] == strlen(s) && memcmp(h->w[i], s, (size_t)h->len[i]) == 0;
}

static void split_words(const char *s, size_t n, hline *h)
{
	h->n = 0;
	h->more = 0;
	size_t i = 0;
	while (i < n) {
		while (i < n && (s[i] == ' ' || s[i] == '\t' || s[i] == '\r'))
			i++;
		if (i == n)
			break;
		size_t b = i;
		while (i < n && s[i] != ' ' && s[i] != '\t' && s[i] != '\r')
			i++;
		if (h->n == MAX_WORDS) {
			h->more = 1;
			break;
		}
		h->w[h->n] = s + b;
		h->len[h->n] = (int)(i - b > 4096 ? 4096 : i - b);
		h->n++;
	}
}

static enum ply_type type_from_word(const hline *h, int i)
{
	for (size_t k = 0; k < sizeof(ply_type_names) / sizeof(ply_type_names[0]); k++)
		if (word_is(h, i, ply_type_names[k].name))
			return ply_type_names[k].type;
	return PT_NONE;
}

static int bad_type(ply_reader *r, const hline *h, int i, const char *what)
{
	char q[160];
	return kg_fail(r->err, KG_EINVAL,
	               "%s: line %zu: %s: unknown type '%s' (expected char, uchar, short, ushort, "
	               "int, uint, float, double or int8, uint8, int16, uint16, int32, uint32, "
	               "float32, float64)",
	               r->name, r->line, what, quote(q, sizeof(q), h->w[i], (size_t)h->len[i]));
}

static int parse_count(const char *s, int len, uint64_t *out)
{
	uint64_t v = 0;
	if (len == 0 || len > 20)
		return -1;
	for (int i = 0; i < len; i++) {
		if (s[i] < '0' || s[i] > '9')
			return -1;
		unsigned d = (unsigned)(s[i] - '0');
		if (v > (UINT64_MAX - d) / 10)
			return -1;
		v = v * 10 + d;
	}
	*out = v;
	return 0;
}

static int add_element(ply_reader *r, const hline *h)
{
	char q[160];
	if (h->n != 3 || h->more)
		return kg_fail(r->err, KG_EINVAL,
		               "%s: line %zu: expected 'element NAME COUNT'", r->name, r->line);
	uint64_t count;
	if (parse_count(h->w[2], h->len[2], &count) != 0)
		return kg_fail(r->err, KG_EINVAL,
		               "%s: line %zu: element %.*s: expected a count (a whole number >= 0), "
		               "found '%s'", r->name, r->line, h->len[1], h->w[1],
		               quote(q, sizeof(q), h->w[2], (size_t)h->len[2]));
	if (count > PLY_MAX_COUNT)
		return kg_fail(r->err, KG_EINVAL,
		               "%s: line %zu: element %.*s: count %llu is larger than %llu",
		               r->name, r->line, h->len[1], h->w[1], (unsigned long long)count,
		               PLY_MAX_COUNT);
	for (int i = 0; i < r->nelems; i++)
		if (r->elems[i].name_len == h->len[1] &&
		    memcmp(r->elems[i].name, h->w[1], (size_t)h->len[1]) == 0)
			return kg_fail(r->err, KG_EINVAL,
			               "%s: line %zu: element %.*s is declared twice (first on line %zu)",
			               r->name, r->line, h->len[1], h->w[1], r->elems[i].line);
	if (r->nelems == r->cap) {
		int cap = r->cap ? 2 * r->cap : 4;
		ply_elem *e = realloc(r->elems, (size_t)cap * sizeof(*e));
		if (!e)
			return kg_fail(r->err, KG_ENOMEM, "%s: out of memory", r->name);
		r->elems = e;
		r->cap = cap;
	}
	ply_elem *e = &r->elems[r->nelems++];
	memset(e, 0, sizeof(*e));
	e->name = h->w[1];
	e->name_len = h->len[1];
	e->count = count;
	e->line = r->line;
	e->kind = word_is(h, 1, "vertex") ? EK_VERTEX : word_is(h, 1, "face") ? EK_FACE : EK_OTHER;
	return 0;
}

static int add_property(ply_reader *r, const hline *h)
{
	if (r->nelems == 0)
		return kg_fail(r->err, KG_EINVAL,
		               "%s: line %zu: a property before any element (expected 'element NAME "
		               "COUNT' first)", r->name, r->line);
	ply_elem *e = &r->elems[r->nelems - 1];
	ply_prop p = { 0 };
	p.line = r->line;
	if (word_is(h, 1, "list")) {
		if (h->n != 5 || h->more)
			return kg_fail(r->err, KG_EINVAL,
			               "%s: line %zu: element %.*s: expected 'property list COUNT_TYPE "
			               "ITEM_TYPE NAME'", r->name, r->line, e->name_len, e->name);
		p.count_type = type_from_word(h, 2);
		if (p.count_type == PT_NONE)
			return bad_type(r, h, 2, "list count");
		if (!ply_type_is_int(p.count_type))
			return kg_fail(r->err, KG_EINVAL,
			               "%s: line %zu: property %.*s: list count type %s is not an "
			               "integer type", r->name, r->line, h->len[4], h->w[4],
			               ply_type_label[p.count_type]);
		p.type = type_from_word(h, 3);
		if (p.type == PT_NONE)
			return bad_type(r, h, 3, "list item");
		p.name = h->w[4];
		p.name_len = h->len[4];
	} else {
		if (h->n != 3 || h->more)
			return kg_fail(r->err, KG_EINVAL,
			               "%s: line %zu: element %.*s: expected 'property TYPE NAME' or "
			               "'property list COUNT_TYPE ITEM_TYPE NAME'", r->name, r->line,
			               e->name_len, e->name);
		p.type = type_from_word(h, 1);
		if (p.type == PT_NONE)
			return bad_type(r, h, 1, "property");
		p.name = h->w[2];
		p.name_len = h->len[2];
	}
	for (int i = 0; i < e->nprops; i++)
		if (e->props[i].name_len == p.name_len &&
		    memcmp(e->props[i].name, p.name, (size_t)p.name_len) == 0)
			return kg_fail(r->err, KG_EINVAL,
			               "%s: line %zu: element %.*s: property %.*s is declared twice",
			               r->name, r->line, e->name_len, e->name, p.name_len, p.name);
	if (e->nprops == e->cap) {
		int cap = e->cap ? 2 * e->cap : 8;
		ply_prop *np = realloc(e->props, (size_t)cap * sizeof(*np));
		if (!np)
			return kg_fail(r->err, KG_ENOMEM, "%s: out of memory", r->name);
		e->props = np;
		e->cap = cap;
	}
	e->props[e->nprops++] = p;
	return 0;
}

/* Reads the header up to and including the end_header line; r->p is left at the
 * first data byte. */
static int parse_header(ply_reader *r)
{
	char q[160];
	int have_format = 0;
	r->line = 0;
	while (r->p < r->end) {
		const uint8_t *nl = memchr(r->p, '\n', (size_t)(r->end - r->p));
		const char *s = (const char *)r->p;
		size_t n = (size_t)((nl ? nl : r->end) - r->p);
		r->p = nl ? nl + 1 : r->end;
		r->line++;
		if (r->line == 1) {
			if (n && s[n - 1] == '\r')
				n--;
			if (n != 3 || memcmp(s, "ply", 3) != 0)
				return kg_fail(r->err, KG_EINVAL,
				               "%s: line 1: expected 'ply' (the magic of a PLY file), found "
				               "'%s'", r->name, quote(q, sizeof(q), s, n));
			continue;
		}
		hline h;
		split_words(s, n, &h);
		if (h.n == 0 || word_is(&h, 0, "comment") || word_is(&h, 0, "obj_info"))
			continue;
		int ret = 0;
		if (word_is(&h, 0, "format")) {
			if (have_format)
				return kg_fail(r->err, KG_EINVAL, "%s: line %zu: a second format line",
				               r->name, r->line);
			if (r->nelems)
				return kg_fail(r->err, KG_EINVAL,
				               "%s: line %zu: format comes after the first element (expected "
				               "it on line 2)", r->name, r->line);
			if (h.n != 3 || h.more)
				return kg_fail(r->err, KG_EINVAL,
				               "%s: line %zu: expected 'format ascii|binary_little_endian|"
				               "binary_big_endian 1.0'", r->name, r->line);
			if (word_is(&h, 1, "ascii"))
				r->format = PF_ASCII;
			else if (word_is(&h, 1, "binary_little_endian"))
				r->format = PF_BINARY_LE;
			else if (word_is(&h, 1, "binary_big_endian"))
				r->format = PF_BINARY_BE;
			else
				return kg_fail(r->err, KG_EINVAL,
				               "%s: line %zu: unknown format '%s' (expected ascii, "
				               "binary_little_endian or binary_big_endian)", r->name, r->line,
				               quote(q, sizeof(q), h.w[1], (size_t)h.len[1]));
			if (!(word_is(&h, 2, "1.0") || word_is(&h, 2, "1")))
				return kg_fail(r->err, KG_EINVAL,
				               "%s: line %zu: format version '%s' (expected 1.0)", r->name,
				               r->line, quote(q, sizeof(q), h.w[2], (size_t)h.len[2]));
			have_format = 1;
		} else if (word_is(&h, 0, "element")) {
			if (!have_format)
				return kg_fail(r->err, KG_EINVAL,
				               "%s: line %zu: element before the format line (expected "
				               "'format ...' on line 2)", r->name, r->line);
			ret = add_element(r, &h);
		} else if (word_is(&h, 0, "property")) {
			ret = add_property(r, &h);
		} else if (word_is(&h, 0, "end_header")) {
			if (!have_format)
				return kg_fail(r->err, KG_EINVAL, "%s: line %zu: no format line in the header",
				               r->name, r->line);
			return 0;
		} else if (r->nelems) {
			/* Before the first element a stray line is taken as a comment: Blender
			 * 2.4x wrote "Created by Blender..." there without the keyword. */
			return kg_fail(r->err, KG_EINVAL,
			               "%s: line %zu: expected comment, obj_info, element, property or "
			               "end_header, found '%s'", r->name, r->line,
			               quote(q, sizeof(q), h.w[0], (size_t)h.len[0]));
		}
		if (ret)
			return ret;
	}
	if (r->line == 0)
		return kg_fail(r->err, KG_EINVAL,
		               "%s: the file is empty (expected 'ply' on line 1)", r->name);
	return kg_fail(r->err, KG_EINVAL,
	               "%s: the header has no end_header line (the file ends on line %zu)",
	               r->name, r->line);
}

/* ---- roles and sizes --------------------------------------------------------- */

static int name_is(const ply_prop *p, const char *s)
{
	return (size_t)p->name_len == strlen(s) && memcmp(p->name, s, (size_t)p->name_len) == 0;
}

static enum ply_role vertex_role(const ply_prop *p)
{
	static const struct {
		const char *name;
		enum ply_role role;
	} names[] = {
		{ "x", ROLE_X },          { "y", ROLE_Y },
		{ "z", ROLE_Z },          { "nx", ROLE_NX },
		{ "ny", ROLE_NY },        { "nz", ROLE_NZ },
		{ "red", ROLE_RED },      { "green", ROLE_GREEN },
		{ "blue", ROLE_BLUE },    { "diffuse_red", ROLE_RED },
		{ "diffuse_green", ROLE_GREEN }, { "diffuse_blue", ROLE_BLUE },
		{ "material", ROLE_VMAT }, { "material_index", ROLE_VMAT },
	};
	for (size_t i = 0; i < sizeof(names) / sizeof(names[0]); i++)
		if (name_is(p, names[i].name))
			return names[i].role;
	return ROLE_SKIP;
}

/* Gives every property of the vertex and face elements its role; a group (normal,
 * colour) is used only when all three of its properties are present. */
static int assign_roles(ply_reader *r, ply_elem **vertex, ply_elem **face)
{
	*vertex = *face = NULL;
	for (int i = 0; i < r->nelems; i++) {
		ply_elem *e = &r->elems[i];
		if (e->kind == EK_VERTEX)
			*vertex = e;
		else if (e->kind == EK_FACE)
			*face = e;
	}
	ply_elem *v = *vertex, *f = *face;
	if (!v)
		return kg_fail(r->err, KG_EINVAL, "%s: the header declares no 'element vertex'",
		               r->name);
	unsigned seen = 0;
	for (int i = 0; i < v->nprops; i++) {
		ply_prop *p = &v->props[i];
		p->role = vertex_role(p);
		if (p->role != ROLE_SKIP && p->count_type != PT_NONE)
			return kg_fail(r->err, KG_EINVAL,
			               "%s: line %zu: element vertex: property %.*s is a list (expected "
			               "a scalar)", r->name, p->line, p->name_len, p->name);
		if (p->role == ROLE_VMAT && !ply_type_is_int(p->type))
			return kg_fail(r->err, KG_EINVAL,
			               "%s: line %zu: element vertex: property %.*s is %s (expected an "
			               "integer type)", r->name, p->line, p->name_len, p->name,
			               ply_type_label[p->type]);
		if (p->role != ROLE_SKIP) {
			if (seen & (1u << p->role))
				p->role = ROLE_SKIP; /* red and diffuse_red: the first wins */
			seen |= 1u << p->role;
		}
	}
	for (enum ply_role k = ROLE_X; k <= ROLE_Z; k++)
		if (!(seen & (1u << k)))
			return kg_fail(r->err, KG_EINVAL,
			               "%s: line %zu: element vertex has no property %s (expected x, y "
			               "and z)", r->name, v->line, k == ROLE_X ? "x" : k == ROLE_Y ? "y" : "z");
	unsigned normals = (1u << ROLE_NX) | (1u << ROLE_NY) | (1u << ROLE_NZ);
	unsigned colours = (1u << ROLE_RED) | (1u << ROLE_GREEN) | (1u << ROLE_BLUE);
	for (int i = 0; i < v->nprops; i++) {
		ply_prop *p = &v->props[i];
		if ((p->role >= ROLE_NX && p->role <= ROLE_NZ && (seen & normals) != normals) ||
		    (p->role >= ROLE_RED && p->role <= ROLE_BLUE && (seen & colours) != colours))
			p->role = ROLE_SKIP;
	}
	if (!f)
		return 0;
	int have_indices = 0, have_mat = 0;
	for (int i = 0; i < f->nprops; i++) {
		ply_prop *p = &f->props[i];
		p->role = ROLE_SKIP;
		if (name_is(p, "vertex_indices") || name_is(p, "vertex_index")) {
			if (p->count_type == PT_NONE)
				return kg_fail(r->err, KG_EINVAL,
				               "%s: line %zu: element face: property %.*s is a scalar "
				               "(expected a list)", r->name, p->line, p->name_len, p->name);
			if (!have_indices)
				p->role = ROLE_INDICES;
			have_indices = 1;
		} else if (name_is(p, "material") || name_is(p, "material_index")) {
			if (p->count_type != PT_NONE || !ply_type_is_int(p->type))
				return kg_fail(r->err, KG_EINVAL,
				               "%s: line %zu: element face: property %.*s must be an integer "
				               "scalar", r->name, p->line, p->name_len, p->name);
			if (!have_mat)
				p->role = ROLE_FMAT;
			have_mat = 1;
		}
	}
	if (!have_indices && f->count > 0)
		return kg_fail(r->err, KG_EINVAL,
		               "%s: line %zu: element face has no list property vertex_indices",
		               r->name, f->line);
	return 0;
}

/* The fewest bytes one instance of e can take in the data. */
static uint64_t min_instance_bytes(const ply_reader *r, const ply_elem *e)
{
	uint64_t n = 0;
	for (int i = 0; i < e->nprops; i++) {
		const ply_prop *p = &e->props[i];
		if (r->format != PF_ASCII)
			n += ply_type_size[p->count_type != PT_NONE ? p->count_type : p->type];
		else if (p->count_type == PT_NONE || i == 0)
			n += 2; /* a digit and a separator; a trailing list may be absent */
	}
	return n;
}

static int check_sizes(ply_reader *r)
{
	/* The last ASCII line may lack its newline. */
	uint64_t avail = (uint64_t)(r->end - r->p) + (r->format == PF_ASCII), need = 0;
	for (int i = 0; i < r->nelems; i++) {
		const ply_elem *e = &r->elems[i];
		uint64_t one = min_instance_bytes(r, e);
		if (one && e->count > (avail - need) / one)
			return kg_fail(r->err, KG_EINVAL,
			               "%s: line %zu: element %.*s: %llu instances need at least %llu "
			               "bytes each, but only %llu bytes of data follow the header "
			               "(truncated file or wrong count)", r->name, e->line, e->name_len,
			               e->name, (unsigned long long)e->count, (unsigned long long)one,
			               (unsigned long long)avail);
		need += one * e->count;
	}
	return 0;
}

/* ---- values ------------------------------------------------------------------ */

static uint16_t bswap16(uint16_t v)
{
	return (uint16_t)((v >> 8) | (v << 8));
}

static uint32_t bswap32(uint32_t v)
{
	return __builtin_bswap32(v);
}

static uint64_t bswap64(uint64_t v)
{
	return __builtin_bswap64(v);
}

static inline double bin_value(const uint8_t *p, enum ply_type t, int swap)
{
	switch (t) {
	case PT_I8:
		return (int8_t)p[0];
	case PT_U8:
		return p[0];
	case PT_I16:
	case PT_U16: {
		uint16_t u;
		memcpy(&u, p, 2);
		if (swap)
			u = bswap16(u);
		return t == PT_I16 ? (double)(int16_t)u : (double)u;
	}
	case PT_I32:
	case PT_U32:
	case PT_F32: {
		uint32_t u;
		memcpy(&u, p, 4);
		if (swap)
			u = bswap32(u);
		if (t == PT_I32)
			return (int32_t)u;
		if (t == PT_U32)
			return u;
		float f;
		memcpy(&f, &u, 4);
		return f;
	}
	case PT_F64: {
		uint64_t u;
		memcpy(&u, p, 8);
		if (swap)
			u = bswap64(u);
		double d;
		memcpy(&d, &u, 8);
		return d;
	}
	default:
		return 0;
	}
}

static const double pow10_exact[] = { 1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
	                                  1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
	                                  1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22 };

static int ci_equal(const char *s, size_t n, const char *word)
{
	if (strlen(word) != n)
		return 0;
	for (size_t i = 0; i < n; i++) {
		char c = s[i];
		if (c >= 'A' && c <= 'Z')
			c = (char)(c - 'A' + 'a');
		if (c != word[i])
			return 0;
	}
	return 1;
}

static inline int is_blank(uint8_t c)
{
	return c == ' ' || c == '\t' || c == '\r';
}

static inline int ends_token(const char *p, const char *e)
{
	return p == e || is_blank((uint8_t)*p) || *p == '\n';
}

/* A decimal number at s, correctly rounded: exact (Clinger's fast path) when the
 * digits fit in 53 bits and the power of ten is exact, else strtod. Returns the end
 * of the number, or NULL when s does not start with one. */
static const char *scan_real(const char *s, const char *e, double *out)
{
	const char *p = s;
	int neg = 0;
	if (p < e && (*p == '+' || *p == '-'))
		neg = *p++ == '-';
	uint64_t mant = 0;
	int ndig = 0, exp10 = 0, digits = 0, inexact = 0;
	for (; p < e && *p >= '0' && *p <= '9'; p++, digits++) {
		if (ndig < 19) {
			mant = mant * 10 + (uint64_t)(*p - '0');
			ndig += mant != 0;
		} else {
			exp10++;
			inexact |= *p != '0';
		}
	}
	if (p < e && *p == '.') {
		for (p++; p < e && *p >= '0' && *p <= '9'; p++, digits++) {
			if (ndig < 19) {
				mant = mant * 10 + (uint64_t)(*p - '0');
				ndig += mant != 0;
				exp10--;
			} else
				inexact |= *p != '0';
		}
	}
	if (!digits)
		return NULL;
	if (p < e && (*p == 'e' || *p == 'E')) {
		p++;
		int eneg = 0, x = 0, edig = 0;
		if (p < e && (*p == '+' || *p == '-'))
			eneg = *p++ == '-';
		for (; p < e && *p >= '0' && *p <= '9'; p++, edig++)
			if (x < 100000)
				x = x * 10 + (*p - '0');
		if (!edig)
			return NULL;
		exp10 += eneg ? -x : x;
	}
	if (mant == 0) {
		*out = neg ? -0.0 : 0.0;
		return p;
	}
	if (!inexact && mant <= (1ull << 53) && exp10 >= -22 && exp10 <= 22) {
		double v = (double)mant;
		v = exp10 < 0 ? v / pow10_exact[-exp10] : v * pow10_exact[exp10];
		*out = neg ? -v : v;
		return p;
	}
	char buf[400];
	size_t n = (size_t)(p - s);
	if (n >= sizeof(buf))
		return NULL;
	memcpy(buf, s, n);
	buf[n] = '\0';
	*out = strtod(buf, NULL);
	return p;
}

/* A whole number of at most 12 significant digits at s; the end, or NULL. */
static const char *scan_integer(const char *s, const char *e, double *out)
{
	const char *p = s;
	int neg = 0;
	if (p < e && (*p == '+' || *p == '-'))
		neg = *p++ == '-';
	const char *digits = p;
	while (p < e && *p == '0')
		p++;
	const char *significant = p;
	int64_t v = 0;
	for (; p < e && *p >= '0' && *p <= '9' && p - significant < 12; p++)
		v = v * 10 + (*p - '0');
	if (p == digits)
		return NULL;
	*out = (double)(neg ? -v : v);
	return p;
}

/* A whole token as a real number: a decimal number, or nan / inf / infinity (any
 * case), returned as such so the caller can say the value is not finite. */
static int parse_real(const char *s, size_t n, double *out)
{
	const char *e = s + n, *p = scan_real(s, e, out);
	if (p)
		return p == e ? 0 : -1;
	const char *w = s + (n && (*s == '+' || *s == '-'));
	size_t wn = (size_t)(e - w);
	if (ci_equal(w, wn, "nan")) {
		*out = NAN;
		return 0;
	}
	if (ci_equal(w, wn, "inf") || ci_equal(w, wn, "infinity")) {
		*out = n && *s == '-' ? -INFINITY : INFINITY;
		return 0;
	}
	return -1;
}

/* The next value of type t on the current ASCII line. */
static int ascii_value(ply_reader *r, enum ply_type t, double *v, const uint8_t **at)
{
	const uint8_t *p = r->p, *e = r->end;
	while (p < e && is_blank(*p))
		p++;
	*at = p;
	if (p == e || *p == '\n') {
		r->p = p;
		return V_EOL;
	}
	const char *b = (const char *)p, *end = (const char *)e;
	int is_int = ply_type_is_int(t);
	const char *q = is_int ? scan_integer(b, end, v) : scan_real(b, end, v);
	if (q && ends_token(q, end)) {
		r->p = (const uint8_t *)q;
		return !is_int || (*v >= ply_type_min[t] && *v <= ply_type_max[t]) ? V_OK : V_RANGE;
	}
	/* Not a plain number: nan, inf, a real for an integer type, or garbage. */
	while (p < e && !is_blank(*p) && *p != '\n')
		p++;
	r->p = p;
	size_t n = (size_t)((const char *)p - b);
	double d;
	if (parse_real(b, n, is_int ? &d : v) != 0)
		return V_NOTNUM;
	if (!is_int)
		return V_OK;
	size_t sign = *b == '+' || *b == '-', digits = sign;
	while (digits < n && b[digits] >= '0' && b[digits] <= '9')
		digits++;
	return digits == n ? V_RANGE : V_NOTINT; /* too many digits, or a real */
}

static inline int next_value(ply_reader *r, enum ply_type t, double *v, const uint8_t **at)
{
	if (r->format == PF_ASCII)
		return ascii_value(r, t, v, at);
	*at = r->p;
	unsigned size = ply_type_size[t];
	if ((size_t)(r->end - r->p) < size)
		return V_EOF;
	*v = bin_value(r->p, t, r->swap);
	r->p += size;
	return V_OK;
}

static int value_error(ply_reader *r, int code, const ply_elem *e, uint64_t i,
                       const ply_prop *p, const char *part, enum ply_type t, const uint8_t *at)
{
	char loc[64], q[160];
	const char *tok = (const char *)at;
	size_t n = 0;
	if (r->format == PF_ASCII)
		while (at + n < r->end && !is_blank(at[n]) && at[n] != '\n')
			n++;
	const char *what;
	switch (code) {
	case V_EOL:
		what = "the line ends";
		break;
	case V_EOF:
		what = "the file ends (truncated)";
		break;
	case V_NOTINT:
		what = "found a non-integer";
		break;
	case V_RANGE:
		what = "found a value out of the type's range";
		break;
	default:
		what = "found something that is not a number";
		break;
	}
	return kg_fail(r->err, KG_EINVAL,
	               "%s: %s: element %.*s %llu of %llu: property %.*s%s: expected %s %s, %s%s%s%s",
	               r->name, where(r, loc, sizeof(loc), at), e->name_len, e->name,
	               (unsigned long long)i, (unsigned long long)e->count, p->name_len, p->name,
	               part, ply_type_is_int(t) ? "an integer of type" : "a number of type",
	               ply_type_label[t], what, n ? " '" : "", n ? quote(q, sizeof(q), tok, n) : "",
	               n ? "'" : "");
}

/* ---- data -------------------------------------------------------------------- */

static int grow_tris(ply_reader *r, size_t need)
{
	kg_mesh *m = r->m;
	if (need <= r->tri_cap)
		return 0;
	size_t cap = r->tri_cap ? r->tri_cap : 64;
	while (cap < need)
		cap *= 2;
	uint32_t *t = realloc(m->tri, cap * 3 * sizeof(*t));
	if (!t)
		return kg_fail(r->err, KG_ENOMEM, "%s: out of memory for %zu triangles", r->name, cap);
	m->tri = t;
	kg_advise_huge_pages(t, cap * 3 * sizeof(*t));
	if (m->tri_material) {
		int32_t *tm = realloc(m->tri_material, cap * sizeof(*tm));
		if (!tm)
			return kg_fail(r->err, KG_ENOMEM, "%s: out of memory for %zu triangles", r->name,
			               cap);
		m->tri_material = tm;
	}
	r->tri_cap = cap;
	return 0;
}

/* Colours out of 0..1 (floats, signed types) are clamped. */
static inline float clamp01(float f)
{
	return f < 0 ? 0 : f > 1 ? 1 : f;
}

/* One vertex attribute; non-finite floats and non-integer ids are refused. */
static int store_vertex(ply_reader *r, const ply_elem *e, uint64_t i, const ply_prop *p,
                        double v, const uint8_t *at)
{
	kg_mesh *m = r->m;
	float f;
	float *dst;
	switch (p->role) {
	case ROLE_X:
	case ROLE_Y:
	case ROLE_Z:
		dst = &m->pos[i * 3 + (size_t)(p->role - ROLE_X)];
		f = (float)v;
		break;
	case ROLE_NX:
	case ROLE_NY:
	case ROLE_NZ:
		dst = &m->normal[i * 3 + (size_t)(p->role - ROLE_NX)];
		f = (float)v;
		break;
	case ROLE_RED:
	case ROLE_GREEN:
	case ROLE_BLUE:
		dst = &m->color[i * 3 + (size_t)(p->role - ROLE_RED)];
		f = (float)(v / ply_type_max[p->type]);
		break;
	case ROLE_VMAT: /* an integer type (assign_roles) */
		if (v < INT32_MIN || v > INT32_MAX) {
			char loc[64];
			return kg_fail(r->err, KG_EINVAL,
			               "%s: %s: element vertex %llu: property %.*s: %.0f does not fit a "
			               "32-bit material id", r->name, where(r, loc, sizeof(loc), at),
			               (unsigned long long)i, p->name_len, p->name, v);
		}
		m->vert_material[i] = (int32_t)v;
		return 0;
	default:
		return 0;
	}
	if (isfinite(f) && p->role >= ROLE_RED && p->role <= ROLE_BLUE)
		f = clamp01(f);
	if (!isfinite(f)) {
		char loc[64];
		return kg_fail(r->err, KG_EINVAL,
		               "%s: %s: element %.*s %llu: property %.*s is %s (expected a finite "
		               "number)", r->name, where(r, loc, sizeof(loc), at), e->name_len, e->name,
		               (unsigned long long)i, p->name_len, p->name,
		               isnan(v) ? "NaN" : isinf(v) ? "infinite" : "too large for a float");
	}
	*dst = f;
	return 0;
}

/* End of one ASCII element: only blanks may remain on its line. */
static int ascii_end_of_line(ply_reader *r, const ply_elem *e, uint64_t i)
{
	const uint8_t *p = r->p;
	while (p < r->end && is_blank(*p))
		p++;
	if (p < r->end && *p != '\n') {
		char q[160];
		const uint8_t *b = p;
		while (p < r->end && *p != '\n')
			p++;
		return kg_fail(r->err, KG_EINVAL,
		               "%s: line %zu: element %.*s %llu of %llu: expected the end of the line "
		               "after its %d %s, found '%s' (the header declares fewer values)",
		               r->name, r->line, e->name_len, e->name, (unsigned long long)i,
		               (unsigned long long)e->count, e->nprops,
		               e->nprops == 1 ? "property" : "properties",
		               quote(q, sizeof(q), b, (size_t)(p - b)));
	}
	if (p < r->end) {
		p++;
		r->line++;
	}
	r->p = p;
	return 0;
}

/* Skips blank lines before an ASCII element; fails at the end of the file. */
static int ascii_start_line(ply_reader *r, const ply_elem *e, uint64_t i)
{
	const uint8_t *p = r->p;
	for (;;) {
		while (p < r->end && is_blank(*p))
			p++;
		if (p == r->end) {
			r->p = p;
			return kg_fail(r->err, KG_EINVAL,
			               "%s: line %zu: element %.*s %llu of %llu: the file ends (expected "
			               "%llu more lines)", r->name, r->line, e->name_len, e->name,
			               (unsigned long long)i, (unsigned long long)e->count,
			               (unsigned long long)(e->count - i));
		}
		if (*p != '\n')
			break;
		p++;
		r->line++;
	}
	r->p = p;
	return 0;
}

/* A list's items; vertex indices are fan-triangulated as they come. */
static int read_list(ply_reader *r, const ply_elem *e, uint64_t i, const ply_prop *p,
                     int first_prop)
{
	char loc[64];
	double v;
	const uint8_t *at;
	int c = next_value(r, p->count_type, &v, &at);
	if (c == V_EOL && !first_prop)
		return 0; /* a trailing list left out of an ASCII line reads as empty */
	if (c != V_OK)
		return value_error(r, c, e, i, p, " (list count)", p->count_type, at);
	if (v < 0)
		return kg_fail(r->err, KG_EINVAL,
		               "%s: %s: element %.*s %llu: property %.*s: list count %.0f is negative",
		               r->name, where(r, loc, sizeof(loc), at), e->name_len, e->name,
		               (unsigned long long)i, p->name_len, p->name, v);
	uint64_t n = (uint64_t)v;
	uint64_t least = r->format == PF_ASCII ? 2 : ply_type_size[p->type];
	if (n > (uint64_t)(r->end - r->p) / least + 1)
		return kg_fail(r->err, KG_EINVAL,
		               "%s: %s: element %.*s %llu: property %.*s: list count %llu is more than "
		               "the rest of the file can hold (truncated file or wrong count)", r->name, where(r, loc, sizeof(loc), at),
		               e->name_len, e->name, (unsigned long long)i, p->name_len, p->name,
		               (unsigned long long)n);
	if (p->role != ROLE_INDICES) {
		if (r->format != PF_ASCII) {
			if (n * ply_type_size[p->type] > (uint64_t)(r->end - r->p))
				return value_error(r, V_EOF, e, i, p, " (list item)", p->type, r->p);
			r->p += n * ply_type_size[p->type];
			return 0;
		}
		for (uint64_t k = 0; k < n; k++)
			if ((c = next_value(r, p->type, &v, &at)) != V_OK)
				return value_error(r, c, e, i, p, " (list item)", p->type, at);
		return 0;
	}
	kg_mesh *m = r->m;
	uint32_t first = 0, prev = 0;
	if (n >= 3) {
		int ret = grow_tris(r, m->ntris + (size_t)n - 2);
		if (ret)
			return ret;
	}
	for (uint64_t k = 0; k < n; k++) {
		if ((c = next_value(r, p->type, &v, &at)) != V_OK)
			return value_error(r, c, e, i, p, " (vertex index)", p->type, at);
		if (!(v >= 0 && v < (double)m->nverts && v == floor(v)))
			return kg_fail(r->err, KG_EINVAL,
			               "%s: %s: element %.*s %llu: property %.*s: vertex index %.17g is out "
			               "of range (expected a whole number from 0 to %zu)", r->name,
			               where(r, loc, sizeof(loc), at), e->name_len, e->name,
			               (unsigned long long)i, p->name_len, p->name, v,
			               m->nverts ? m->nverts - 1 : 0);
		uint32_t idx = (uint32_t)v;
		if (k == 0)
			first = idx;
		else if (k >= 2) {
			uint32_t *t = &m->tri[m->ntris * 3];
			t[0] = first;
			t[1] = prev;
			t[2] = idx;
			m->ntris++;
		}
		prev = idx;
	}
	if (n < 3)
		m->degenerate++;
	return 0;
}

/* ---- binary fast paths ---------------------------------------------------------
 * The common layouts, read without the per-value bookkeeping of the general reader:
 * they stop at the first instance they cannot take (a value to refuse, a list other
 * than the indices, the end of the data) and return how many they did; the general
 * reader carries on from there and reports any error with its full message. */

/* A vertex element of scalars only: every record has the same size and layout. */
static uint64_t bin_vertices(ply_reader *r, const ply_elem *e)
{
	struct {
		unsigned offset;
		enum ply_type type;
		enum ply_role role;
	} slot[16];
	int ns = 0, all_float = 1;
	size_t size = 0;
	for (int k = 0; k < e->nprops; k++) {
		const ply_prop *p = &e->props[k];
		if (p->count_type != PT_NONE || ns == 16)
			return 0;
		if (p->role != ROLE_SKIP) {
			slot[ns].offset = (unsigned)size;
			slot[ns].type = p->type;
			slot[ns].role = p->role;
			all_float &= p->type == PT_F32 && p->role <= ROLE_NZ;
			ns++;
		}
		size += ply_type_size[p->type];
	}
	kg_mesh *m = r->m;
	uint64_t n = e->count, room = (uint64_t)(r->end - r->p) / size, i;
	n = n < room ? n : room;
	const int swap = r->swap;
	if (all_float) { /* positions and normals as float32: move the bits */
		float *dst[16];
		for (int k = 0; k < ns; k++)
			dst[k] = slot[k].role <= ROLE_Z ? m->pos + (slot[k].role - ROLE_X)
			                                : m->normal + (slot[k].role - ROLE_NX);
		for (i = 0; i < n; i++) {
			const uint8_t *rec = r->p + i * size;
			for (int k = 0; k < ns; k++) {
				uint32_t u;
				memcpy(&u, rec + slot[k].offset, 4);
				if (swap)
					u = bswap32(u);
				if ((u & 0x7f800000u) == 0x7f800000u) /* NaN or Inf */
					goto stop;
				memcpy(&dst[k][i * 3], &u, 4);
			}
		}
		goto stop;
	}
	for (i = 0; i < n; i++) {
		const uint8_t *rec = r->p + i * size;
		for (int k = 0; k < ns; k++) {
			double v = bin_value(rec + slot[k].offset, slot[k].type, swap);
			float f;
			switch (slot[k].role) {
			case ROLE_X:
			case ROLE_Y:
			case ROLE_Z:
				f = (float)v;
				if (!isfinite(f))
					goto stop;
				m->pos[i * 3 + (size_t)(slot[k].role - ROLE_X)] = f;
				break;
			case ROLE_NX:
			case ROLE_NY:
			case ROLE_NZ:
				f = (float)v;
				if (!isfinite(f))
					goto stop;
				m->normal[i * 3 + (size_t)(slot[k].role - ROLE_NX)] = f;
				break;
			case ROLE_RED:
			case ROLE_GREEN:
			case ROLE_BLUE:
				f = (float)(v / ply_type_max[slot[k].type]);
				if (!isfinite(f))
					goto stop;
				m->color[i * 3 + (size_t)(slot[k].role - ROLE_RED)] = clamp01(f);
				break;
			case ROLE_VMAT:
				if (v < INT32_MIN || v > INT32_MAX)
					goto stop;
				m->vert_material[i] = (int32_t)v;
				break;
			default:
				break;
			}
		}
	}
stop:
	r->p += i * size;
	return i;
}

/* Triangles as most files write them: a face element holding only the index list,
 * with a one-byte count of 3 and 32-bit indices, 13 bytes a face. Returns the faces
 * done, stopping before the first that is not such a triangle or is out of range. */
static uint64_t bin_triangle_run(ply_reader *r, const ply_elem *e, uint64_t i,
                                 const uint8_t **pp)
{
	const ply_prop *p = &e->props[0];
	kg_mesh *m = r->m;
	const uint8_t *at = *pp;
	uint64_t room = (uint64_t)(r->end - at) / 13, n = e->count - i;
	n = n < room ? n : room;
	if (m->ntris + n > r->tri_cap && grow_tris(r, m->ntris + (size_t)n) != 0)
		return 0;
	/* int indices: a negative one reads as >= 2^31 and fails the same test. */
	uint32_t cap = p->type == PT_I32 ? 0x80000000u : UINT32_MAX;
	uint32_t limit = m->nverts < cap ? (uint32_t)m->nverts : cap;
	uint32_t *t = &m->tri[m->ntris * 3];
	uint64_t k;
	for (k = 0; k < n; k++, at += 13, t += 3) {
		uint32_t v[3];
		if (at[0] != 3)
			break;
		memcpy(v, at + 1, 12);
		if (r->swap) {
			v[0] = bswap32(v[0]);
			v[1] = bswap32(v[1]);
			v[2] = bswap32(v[2]);
		}
		if (v[0] >= limit || v[1] >= limit || v[2] >= limit)
			break;
		t[0] = v[0];
		t[1] = v[1];
		t[2] = v[2];
	}
	m->ntris += (size_t)k;
	m->npolygons += (size_t)k;
	*pp = at;
	return k;
}

/* A face element of scalars and the one index list. */
static uint64_t bin_faces(ply_reader *r, const ply_elem *e)
{
	for (int k = 0; k < e->nprops; k++)
		if (e->props[k].count_type != PT_NONE && e->props[k].role != ROLE_INDICES)
			return 0;
	kg_mesh *m = r->m;
	const int swap = r->swap;
	const double nverts = (double)m->nverts;
	const uint8_t *p = r->p;
	const ply_prop *p0 = &e->props[0];
	const int triangles = e->nprops == 1 && ply_type_size[p0->count_type] == 1 &&
	                      (p0->type == PT_I32 || p0->type == PT_U32);
	uint64_t i = 0;
	for (;;) {
		if (triangles)
			i += bin_triangle_run(r, e, i, &p);
		if (i == e->count)
			break;
		const uint8_t *face = p;
		size_t first_tri = m->ntris, first_degenerate = m->degenerate;
		int32_t material = 0;
		for (int k = 0; k < e->nprops; k++) {
			const ply_prop *pp = &e->props[k];
			if (pp->count_type == PT_NONE) {
				unsigned size = ply_type_size[pp->type];
				if ((size_t)(r->end - p) < size)
					goto stop;
				if (pp->role == ROLE_FMAT) {
					double v = bin_value(p, pp->type, swap);
					if (v < INT32_MIN || v > INT32_MAX)
						goto stop;
					material = (int32_t)v;
				}
				p += size;
				continue;
			}
			unsigned csize = ply_type_size[pp->count_type], isize = ply_type_size[pp->type];
			if ((size_t)(r->end - p) < csize)
				goto stop;
			double c = bin_value(p, pp->count_type, swap);
			p += csize;
			if (c < 0 || c * isize > (double)(r->end - p))
				goto stop;
			size_t n = (size_t)c;
			if (n >= 3 && m->ntris + n - 2 > r->tri_cap && grow_tris(r, m->ntris + n - 2) != 0)
				goto stop;
			uint32_t v0 = 0, prev = 0;
			for (size_t j = 0; j < n; j++, p += isize) {
				double v = bin_value(p, pp->type, swap);
				if (!(v >= 0 && v < nverts && v == (double)(uint32_t)v))
					goto stop;
				uint32_t idx = (uint32_t)v;
				if (j == 0)
					v0 = idx;
				else if (j >= 2) {
					uint32_t *t = &m->tri[m->ntris++ * 3];
					t[0] = v0;
					t[1] = prev;
					t[2] = idx;
				}
				prev = idx;
			}
			m->degenerate += n < 3;
		}
		m->npolygons++;
		if (m->tri_material)
			for (size_t t = first_tri; t < m->ntris; t++)
				m->tri_material[t] = material;
		i++;
		continue;
	stop:
		/* Undo the face for the general reader to read again and report. */
		p = face;
		m->ntris = first_tri;
		m->degenerate = first_degenerate;
		break;
	}
	r->p = p;
	return i;
}

static int read_element(ply_reader *r, const ply_elem *e)
{
	kg_mesh *m = r->m;
	if (e->nprops == 0)
		return 0;
	if (e->kind == EK_OTHER && r->format != PF_ASCII) {
		int fixed = 1;
		for (int k = 0; k < e->nprops; k++)
			fixed &= e->props[k].count_type == PT_NONE;
		uint64_t size = e->count * min_instance_bytes(r, e); /* < file size: check_sizes */
		if (fixed && size > (uint64_t)(r->end - r->p)) {
			char loc[64];
			return kg_fail(r->err, KG_EINVAL,
			               "%s: %s: element %.*s: %llu instances of %llu bytes: the file ends "
			               "(truncated)", r->name, where(r, loc, sizeof(loc), r->p),
			               e->name_len, e->name, (unsigned long long)e->count,
			               (unsigned long long)min_instance_bytes(r, e));
		}
		if (fixed) {
			r->p += size;
			return 0;
		}
	}
	uint64_t i = 0;
	if (r->format != PF_ASCII && e->kind == EK_VERTEX)
		i = bin_vertices(r, e);
	else if (r->format != PF_ASCII && e->kind == EK_FACE)
		i = bin_faces(r, e);
	for (; i < e->count; i++) {
		int ret;
		if (r->format == PF_ASCII && (ret = ascii_start_line(r, e, i)) != 0)
			return ret;
		size_t face_first_tri = m->ntris;
		int32_t face_material = 0;
		for (int k = 0; k < e->nprops; k++) {
			const ply_prop *p = &e->props[k];
			if (p->count_type != PT_NONE) {
				if ((ret = read_list(r, e, i, p, k == 0)) != 0)
					return ret;
				continue;
			}
			double v;
			const uint8_t *at;
			int c = next_value(r, p->type, &v, &at);
			if (c != V_OK)
				return value_error(r, c, e, i, p, "", p->type, at);
			if (e->kind == EK_VERTEX) {
				if ((ret = store_vertex(r, e, i, p, v, at)) != 0)
					return ret;
			} else if (p->role == ROLE_FMAT) {
				if (v < INT32_MIN || v > INT32_MAX) {
					char loc[64];
					return kg_fail(r->err, KG_EINVAL,
					               "%s: %s: element face %llu: property %.*s: %.0f does not "
					               "fit a 32-bit material id", r->name,
					               where(r, loc, sizeof(loc), at), (unsigned long long)i,
					               p->name_len, p->name, v);
				}
				face_material = (int32_t)v;
			}
		}
		if (e->kind == EK_FACE) {
			m->npolygons++;
			if (m->tri_material)
				for (size_t t = face_first_tri; t < m->ntris; t++)
					m->tri_material[t] = face_material;
		}
		if (r->format == PF_ASCII && (ret = ascii_end_of_line(r, e, i)) != 0)
			return ret;
	}
	return 0;
}

/* Only blanks (a final newline, padding) may follow the last element. */
static int check_trailer(ply_reader *r)
{
	const uint8_t *p = r->p;
	while (p < r->end && (is_blank(*p) || *p == '\n'))
		p++;
	if (p == r->end)
		return 0;
	char loc[64], q[160];
	return kg_fail(r->err, KG_EINVAL,
	               "%s: %s: %zu bytes after the last element, starting '%s' (expected the end "
	               "of the file; the header declares fewer data than the file has)", r->name,
	               where(r, loc, sizeof(loc), r->p), (size_t)(r->end - r->p),
	               quote(q, sizeof(q), p, (size_t)(r->end - p)));
}

static int allocate(ply_reader *r, const ply_elem *v, const ply_elem *f)
{
	kg_mesh *m = calloc(1, sizeof(*m));
	if (!m)
		return kg_fail(r->err, KG_ENOMEM, "%s: out of memory", r->name);
	r->m = m;
	m->nverts = (size_t)v->count;
	size_t nv = m->nverts ? m->nverts : 1;
	unsigned roles = 0;
	for (int i = 0; i < v->nprops; i++)
		roles |= 1u << v->props[i].role;
	m->pos = malloc(nv * 3 * sizeof(float));
	if (roles & (1u << ROLE_NX))
		m->normal = malloc(nv * 3 * sizeof(float));
	if (roles & (1u << ROLE_RED))
		m->color = malloc(nv * 3 * sizeof(float));
	if (roles & (1u << ROLE_VMAT))
		m->vert_material = malloc(nv * sizeof(int32_t));
	int fmat = 0;
	if (f)
		for (int i = 0; i < f->nprops; i++)
			fmat |= f->props[i].role == ROLE_FMAT;
	if (fmat)
		m->tri_material = malloc(sizeof(int32_t));
	/* the parse writes every value once: page faults were most of its time */
	kg_advise_huge_pages(m->pos, nv * 3 * sizeof(float));
	kg_advise_huge_pages(m->normal, nv * 3 * sizeof(float));
	kg_advise_huge_pages(m->color, nv * 3 * sizeof(float));
	if (!m->pos || ((roles & (1u << ROLE_NX)) && !m->normal) ||
	    ((roles & (1u << ROLE_RED)) && !m->color) ||
	    ((roles & (1u << ROLE_VMAT)) && !m->vert_material) || (fmat && !m->tri_material))
		return kg_fail(r->err, KG_ENOMEM, "%s: out of memory for %zu vertices", r->name,
		               m->nverts);
	r->tri_cap = 0;
	return f ? grow_tris(r, (size_t)(f->count ? f->count : 1)) : grow_tris(r, 1);
}

int kg_ply_load_mem(const void *data, size_t len, const char *name, kg_mesh **out,
                    kg_err *err)
{
	kg_check_arg(out != NULL, err);
	*out = NULL;
	kg_check_arg(data != NULL || len == 0, err);
	if (!name)
		name = "(memory)";
	ply_reader r = { 0 };
	r.data = r.p = data;
	r.end = r.data + len;
	r.name = name;
	r.err = err;
	ply_elem *v, *f;
	int ret = parse_header(&r);
	if (ret == 0)
		ret = assign_roles(&r, &v, &f);
	if (ret == 0) {
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
		r.swap = r.format == PF_BINARY_LE;
#else
		r.swap = r.format == PF_BINARY_BE;
#endif
		r.line++; /* ASCII data starts on the line after end_header */
		ret = check_sizes(&r);
	}
	if (ret == 0)
		ret = allocate(&r, v, f);
	for (int i = 0; ret == 0 && i < r.nelems; i++)
		ret = read_element(&r, &r.elems[i]);
	if (ret == 0)
		ret = check_trailer(&r);
	for (int i = 0; i < r.nelems; i++)
		free(r.elems[i].props);
	free(r.elems);
	if (ret != 0) {
		kg_mesh_free(&r.m);
		return ret;
	}
	*out = r.m;
	return 0;
}

int kg_ply_load(const char *path, kg_mesh **out, kg_err *err)
{
	kg_check_arg(path != NULL && out != NULL, err);
	*out = NULL;
	int fd = open(path, O_RDONLY | O_CLOEXEC);
	if (fd < 0)
		return kg_fail(err, errno == ENOENT ? KG_ENOENT : KG_EIO, "%s: cannot open: %s", path,
		               strerror(errno));
	struct stat st;
	if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
		close(fd);
		return kg_fail(err, KG_EIO, "%s: not a regular file", path);
	}
	kg_inputs_add(path, fd);
	size_t len = (size_t)st.st_size;
	if (len == 0) {
		close(fd);
		return kg_ply_load_mem("", 0, path, out, err);
	}
	/* mapped through kg_mapfile: a mesh cut short by another program while it is read
	 * is refused naming the file, not a SIGBUS */
	kg_mapfile *map = NULL;
	const void *base = NULL;
	int ret = kg_mapfile_open(fd, len, 0, path, &map, &base, err);
	close(fd);
	if (ret)
		return ret;
	madvise((void *)(uintptr_t)base, len, MADV_SEQUENTIAL);
	ret = kg_ply_load_mem(base, len, path, out, err);
	kg_err merr = {{0}};
	if (kg_mapfile_check(map, &merr)) {
		kg_mesh_free(out);
		if (err)
			*err = merr;
		ret = KG_EIO;
	}
	kg_mapfile_free(&map);
	return ret;
}

/* ---- writer ------------------------------------------------------------------ */

static void put32(uint8_t *p, uint32_t v, int big)
{
	if (big)
		v = bswap32(v);
	memcpy(p, &v, 4);
}

static void put_float(uint8_t *p, float f, int big)
{
	uint32_t u;
	memcpy(&u, &f, 4);
	put32(p, u, big);
}

int kg_ply_write_format(const kg_mesh *m, const char *path, kg_ply_format format,
                        kg_err *err)
{
	kg_check_arg(m != NULL && path != NULL, err);
	kg_check_arg(format == KG_PLY_ASCII || format == KG_PLY_BINARY_LE ||
	             format == KG_PLY_BINARY_BE, err);
	kg_outfile o;
	int ret = kg_outfile_open(&o, path, format == KG_PLY_ASCII, err);
	if (ret)
		return ret;
	FILE *fp = o.fp;
	fprintf(fp, "ply\nformat %s 1.0\ncomment written by kogei\n",
	        format == KG_PLY_ASCII       ? "ascii"
	        : format == KG_PLY_BINARY_LE ? "binary_little_endian"
	                                     : "binary_big_endian");
	fprintf(fp, "element vertex %zu\nproperty float x\nproperty float y\nproperty float z\n",
	        m->nverts);
	if (m->normal)
		fprintf(fp, "property float nx\nproperty float ny\nproperty float nz\n");
	if (m->color)
		fprintf(fp, "property float red\nproperty float green\nproperty float blue\n");
	if (m->vert_material)
		fprintf(fp, "property int material\n");
	fprintf(fp, "element face %zu\nproperty list uchar uint vertex_indices\n", m->ntris);
	if (m->tri_material)
		fprintf(fp, "property int material\n");
	fprintf(fp, "end_header\n");

	int big = format == KG_PLY_BINARY_BE;
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
	big = !big;
#endif
	uint8_t rec[64];
	for (size_t i = 0; i < m->nverts; i++) {
		float f[9];
		int nf = 0;
		for (int k = 0; k < 3; k++)
			f[nf++] = m->pos[i * 3 + (size_t)k];
		for (int k = 0; m->normal && k < 3; k++)
			f[nf++] = m->normal[i * 3 + (size_t)k];
		for (int k = 0; m->color && k < 3; k++)
			f[nf++] = m->color[i * 3 + (size_t)k];
		if (format == KG_PLY_ASCII) {
			for (int k = 0; k < nf; k++)
				fprintf(fp, k ? " %.9g" : "%.9g", (double)f[k]);
			if (m->vert_material)
				fprintf(fp, " %d", (int)m->vert_material[i]);
			fputc('\n', fp);
			continue;
		}
		size_t n = 0;
		for (int k = 0; k < nf; k++, n += 4)
			put_float(rec + n, f[k], big);
		if (m->vert_material) {
			put32(rec + n, (uint32_t)m->vert_material[i], big);
			n += 4;
		}
		fwrite(rec, 1, n, fp);
	}
	for (size_t t = 0; t < m->ntris; t++) {
		const uint32_t *v = &m->tri[t * 3];
		if (format == KG_PLY_ASCII) {
			fprintf(fp, "3 %u %u %u", (unsigned)v[0], (unsigned)v[1], (unsigned)v[2]);
			if (m->tri_material)
				fprintf(fp, " %d", (int)m->tri_material[t]);
			fputc('\n', fp);
			continue;
		}
		rec[0] = 3;
		size_t n = 1;
		for (int k = 0; k < 3; k++, n += 4)
			put32(rec + n, v[k], big);
		if (m->tri_material) {
			put32(rec + n, (uint32_t)m->tri_material[t], big);
			n += 4;
		}
		fwrite(rec, 1, n, fp);
	}
	return kg_outfile_commit(&o, err);
}

int kg_ply_write(const kg_mesh *m, const char *path, kg_err *err)
{
	return kg_ply_write_format(m, path, KG_PLY_BINARY_LE, err);
}
