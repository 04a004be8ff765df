/* CGATS.17 text files (ArgyllCMS .ti1/.ti2/.ti3/.cie/.sp, colord .sp/.cmf, X-Rite
 * exports) and the patch sets built from them.
 *
 * A file holds one or more tables. Each table starts with a file-type identifier line
 * ("CGATS.17", "CTI3", "SPECT", ...), has keywords with values, a list of field names
 * (BEGIN_DATA_FORMAT ... END_DATA_FORMAT) and data sets (BEGIN_DATA ... END_DATA), one
 * set per line. Cells are kept as text; kg_cgats_number() converts one with an error
 * that names the file, the line, the field and what was expected. Every name, keyword
 * value and cell is UTF-8: a file in Windows-1252 (Latin-1) is converted, one in
 * neither encoding refused, as text.h describes. */
#ifndef KG_CGATS_H
#define KG_CGATS_H

#include <stddef.h>

#include "error.h"
#include "spectrum.h"

/* Longest line the reader accepts; longer lines are refused with the line number. */
#define KG_CGATS_MAX_LINE (1 << 20)

typedef struct kg_cgats_kw {
	char *name;
	char *value; /* without its quotes */
	int line;    /* source line, 0 when built in memory */
} kg_cgats_kw;

typedef struct kg_cgats_table {
	const char *path; /* the owning kg_cgats' path, for messages */
	char *type;       /* file-type identifier, e.g. "CGATS.17", "CTI3", "SPECT" */
	int line;         /* line of the identifier, 0 when built in memory */
	int nkeywords;
	kg_cgats_kw *keywords; /* in file order; NUMBER_OF_FIELDS/SETS and KEYWORD
	                             * declarations are structure, not stored here */
	int nfields;
	char **fields;
	int nsets;
	char **cells;   /* nsets x nfields, row-major, text without quotes */
	int *set_lines; /* source line of each set, 0 when built in memory */
	int cap_sets;   /* allocated rows (private) */
} kg_cgats_table;

typedef struct kg_cgats {
	char *path; /* file name used in messages ("<memory>" or a caller's name) */
	int ntables;
	kg_cgats_table **tables;
} kg_cgats;

/* --- reading --- */

/* Read and parse a file. */
int kg_cgats_read(const char *path, kg_cgats **out, kg_err *err);
/* Parse a buffer (need not be NUL-terminated; NUL bytes are an error). `name` is used
 * in messages and as the path; NULL means "<memory>". */
int kg_cgats_parse(const char *buf, size_t len, const char *name, kg_cgats **out,
                   kg_err *err);
void kg_cgats_free(kg_cgats **cg);

/* --- access --- */

/* Index of a field by exact name, or -1. */
int kg_cgats_field(const kg_cgats_table *t, const char *name);
/* Value of the first keyword with this name, or NULL. */
const char *kg_cgats_keyword(const kg_cgats_table *t, const char *name);
/* Keyword as a finite number. KG_ENOENT if absent, KG_EINVAL if not a number. */
int kg_cgats_keyword_number(const kg_cgats_table *t, const char *name, double *out,
                            kg_err *err);
/* Text of a cell (never NULL for valid indices). */
const char *kg_cgats_cell(const kg_cgats_table *t, int set, int field);
/* A cell as a finite number; the message names file, line, field and the text found.
 * NaN and infinity are refused. */
int kg_cgats_number(const kg_cgats_table *t, int set, int field, double *out,
                    kg_err *err);
/* Parse text as a finite decimal number (the rule kg_cgats_number uses). 0 or
 * KG_EINVAL, no message. */
int kg_cgats_parse_number(const char *text, double *out);
/* The spectral fields of a table: indices of the spectral fields (in field order) and
 * their wavelengths in nm. A spectral field is named SPEC_<nm>, or as X-Rite writes
 * SPECTRAL_NM<nm>, SPECTRAL_NM_<nm> or nm<nm>, each prefix in any case; numbers from
 * 10000 up are picometres, as colord writes them (SPEC_300000). Refused (KG_EINVAL,
 * naming the file and the field): a name with one of these prefixes whose rest is not
 * a plain number (SPEC_abc, SPEC_Inf, nmInf, nm-x, nm400x, "nm 400", SPEC_, nm), a
 * wavelength outside 100..5000 nm (nm-5, SPEC_5), a wavelength given twice (also in
 * two forms: SPEC_400 and nm400), fields out of order, and SPECTRAL_START_NM /
 * SPECTRAL_END_NM / SPECTRAL_BANDS that disagree with the fields (by more than 1 nm,
 * or in the count); when all three are given the exact keyword grid is used (Argyll
 * rounds 3.33 nm steps in the names). *n = 0 and NULL arrays when there are none.
 * Caller frees both arrays. */
int kg_cgats_spectral_fields(const kg_cgats_table *t, int **fields, double **wl, int *n,
                             kg_err *err);
/* The spectra of a table at the file's own wavelengths (kg_cgats_spectral_fields),
 * brought to fractions by the rule of the patch sets (see KG_PATCH_KEEP_SCALE and
 * KG_PATCH_REFLECTANCE, which `flags` may hold, and the range every value must keep):
 * *wl (n nm), *values (nsets x n, row-major) and, if scale is not NULL, the factor
 * applied. *n = 0 and NULL arrays when there are none. Caller frees both arrays. */
int kg_cgats_spectra(const kg_cgats_table *t, unsigned flags, double **wl,
                     double **values, int *n, double *scale, kg_err *err);

/* --- building and writing --- */

/* A new file with one empty table of the given type (NULL means "CGATS.17"). */
int kg_cgats_new(const char *type, kg_cgats **out, kg_err *err);
/* Append another table; *out stays valid until the kg_cgats is freed. */
int kg_cgats_add_table(kg_cgats *cg, const char *type, kg_cgats_table **out,
                       kg_err *err);
/* Set a keyword (replaces the first one of that name, else appends). The value may
 * not contain a double quote or a line break. */
int kg_cgats_set_keyword(kg_cgats_table *t, const char *name, const char *value,
                         kg_err *err);
int kg_cgats_set_keyword_number(kg_cgats_table *t, const char *name, double value,
                                kg_err *err);
/* Set the field names; only allowed while the table has no sets. */
int kg_cgats_set_fields(kg_cgats_table *t, const char *const *names, int n,
                        kg_err *err);
/* Append a set of nfields texts. */
int kg_cgats_add_row(kg_cgats_table *t, const char *const *cells, kg_err *err);
/* Append a set: `first` (if not NULL) fills field 0 and vals fill the remaining
 * fields (nvals must make up nfields). Numbers are written with %.10g; NaN/Inf are
 * refused. */
int kg_cgats_add_row_numbers(kg_cgats_table *t, const char *first, const double *vals,
                             int nvals, kg_err *err);
/* Append an empty set (all cells "") and return its index in *set. */
int kg_cgats_append_set(kg_cgats_table *t, int *set, kg_err *err);
int kg_cgats_set_cell(kg_cgats_table *t, int set, int field, const char *text,
                      kg_err *err);
int kg_cgats_set_cell_number(kg_cgats_table *t, int set, int field, double v,
                             kg_err *err);
/* Write atomically (kg_outfile); "-" writes to standard output. */
int kg_cgats_write(const kg_cgats *cg, const char *path, kg_err *err);

/* --- patch sets --- */

/* Which columns a patch set carries (kg_patchset_new, kg_patchset_write). */
enum {
	KG_PATCH_SPECTRA = 1 << 0, /* SPEC_400 .. SPEC_700 */
	KG_PATCH_RGB = 1 << 1,     /* RGB_R RGB_G RGB_B */
	KG_PATCH_XYZ = 1 << 2,     /* XYZ_X XYZ_Y XYZ_Z */
	KG_PATCH_LAB = 1 << 3,     /* LAB_L LAB_A LAB_B */
	KG_PATCH_EXTRA = 1 << 4,   /* the extra numeric columns */
};

/* Extra flag for kg_patchset_from_cgats/read and kg_cgats_spectra, combinable with
 * KG_RESAMPLE_*: take spectral values as stored. Without it, whatever the file-type
 * identifier: values are divided by SPECTRAL_NORM when the table has it; else kept
 * when MEAS_TYPE is EMISSION or AMBIENT; else read as percent when any exceeds 1.5
 * (ArgyllCMS's measured spectra, which carry no SPECTRAL_NORM), as fractions
 * otherwise (colord's CIE-TCS.sp). */
#define KG_PATCH_KEEP_SCALE (1u << 8)
/* Extra flag, as KG_PATCH_KEEP_SCALE: the spectra are reflectance (or transmittance)
 * factors, and each value, once brought to a fraction, must lie within
 * KG_REFLECTANCE_MIN..KG_REFLECTANCE_MAX: a little below 0 (noise on a black, an
 * estimate's ringing) and above 1 (fluorescence, a white brighter than the reference)
 * are measured; far beyond them the file is wrong. Whatever the flags, every spectral
 * value (once scaled) must be at most KG_SPECTRAL_MAX_ABS in magnitude: beyond any unit
 * a spectrum is written in, and small enough that sums of products over a chart stay
 * finite. Refusals name the file, the line, the field and the value. */
#define KG_PATCH_REFLECTANCE (1u << 9)
#define KG_REFLECTANCE_MIN (-1.0)
#define KG_REFLECTANCE_MAX 10.0
#define KG_SPECTRAL_MAX_ABS 1e30
/* RGB_R/G/B values must be at most KG_RGB_MAX_ABS in magnitude (scales 0-1, 0-100,
 * 0-255 and 0-65535 with room for noise), XYZ and L*a*b* values at most
 * KG_SPECTRAL_MAX_ABS. */
#define KG_RGB_MAX_ABS 1e6
/* NULL when v, a spectral value once scaled, keeps the range that `flags` asks for
 * (KG_PATCH_REFLECTANCE, else KG_SPECTRAL_MAX_ABS), else what was expected ("expected
 * a reflectance between ..."), for a message that names the file and the field. */
const char *kg_spectral_value_expected(double v, unsigned flags);

typedef struct kg_patchset {
	int n;
	char **ids;            /* n ids: SAMPLE_ID, else SAMPLE_NAME, else SAMPLE_LOC,
	                        * else the 1-based row number */
	kg_spectrum *spectra;  /* n spectra on the grid, or NULL */
	double (*rgb)[3];      /* or NULL; values as in the file */
	double (*xyz)[3];      /* or NULL */
	double (*lab)[3];      /* or NULL */
	int nextra;            /* other numeric columns */
	char **extra_names;
	double *extra;         /* n x nextra, row-major */
	double spectral_scale; /* factor applied to the file's spectral values */
	char *source;          /* file it came from, or NULL */
} kg_patchset;

/* An empty patch set of n patches with the arrays named by `fields` (KG_PATCH_*)
 * zeroed and ids "1".."n". */
int kg_patchset_new(int n, unsigned fields, kg_patchset **out, kg_err *err);
int kg_patchset_set_id(kg_patchset *ps, int i, const char *id, kg_err *err);
/* Append an extra numeric column (zeroed); its index is ps->nextra - 1. */
int kg_patchset_add_extra(kg_patchset *ps, const char *name, kg_err *err);
/* Build from the first table of a file (flags: KG_RESAMPLE_*, KG_PATCH_KEEP_SCALE). */
int kg_patchset_from_cgats(const kg_cgats *cg, unsigned flags, kg_patchset **out,
                           kg_err *err);
int kg_patchset_from_table(const kg_cgats_table *t, unsigned flags, kg_patchset **out,
                           kg_err *err);
/* kg_cgats_read + kg_patchset_from_cgats. */
int kg_patchset_read(const char *path, unsigned flags, kg_patchset **out, kg_err *err);
/* A table with SAMPLE_ID and the columns named by `fields` (each must be present),
 * of type CGATS.17, or SPECT when it carries spectra: those are written as ArgyllCMS
 * writes reflectance, in percent with SPECTRAL_NORM 100, MEAS_TYPE REFLECTIVE (unless
 * `keywords` gives another) and SPECTRAL_START_NM/END_NM/BANDS, every value with a
 * decimal point, so that spec2cie reads the file unchanged. The percent values are
 * the fractions' shortest decimal digits with the point moved, so the reader gives
 * the same doubles back. `keywords` is NULL or a NULL-terminated list of name, value
 * pairs. */
int kg_patchset_to_cgats(const kg_patchset *ps, unsigned fields,
                         const char *const *keywords, kg_cgats **out, kg_err *err);
/* kg_patchset_to_cgats + kg_cgats_write ("-" = standard output). */
int kg_patchset_write(const char *path, const kg_patchset *ps, unsigned fields,
                      const char *const *keywords, kg_err *err);
/* Index of the patch with this id, or -1. */
int kg_patchset_find(const kg_patchset *ps, const char *id);
/* Match the patch ids of one chart file (a, na) with another's (b, nb): match[i] is
 * the index in b of a[i]'s patch, or -1. Ids are compared as written; when that leaves
 * patches unmatched, as the same letter and number whatever the zero padding and case
 * ("A1" = "a01" = kogei's "A01"), then, when one side is all plain numbers and the
 * other all letter + number, as patch numbers in letter-major order: n is the n-th id
 * of A1..A<N>, B1..B<N>, ... with N the largest number on the grid side (ArgyllCMS
 * chartread's "1".."24" and the .cht's or kogei's ids of the ColorChecker: 7 = B1 =
 * B01), provided every number then falls within the grid's letters (else the grid's
 * width is unknown and this rule pairs nothing). The rule matching the most ids wins (the earlier on a tie). Returns the number
 * matched (-1 out of memory); *rule (may be NULL) gets NULL for exact ids, else a
 * description of the rule used. */
int kg_patch_ids_match(char *const *a, int na, char *const *b, int nb, int *match,
                       const char **rule);
/* Index of an extra column by name, or -1. */
int kg_patchset_extra_index(const kg_patchset *ps, const char *name);
void kg_patchset_free(kg_patchset **ps);

#endif
