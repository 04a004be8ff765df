/* ENVI cubes: a text header (.hdr) beside raw band data, as read by ENVI, GDAL and
 * Spectral Python. Reflectance cubes are float32 or uint16, label maps are ENVI
 * Classification files of uint8.
 *
 * File names: for "x.hdr" the data file is "x.img"; for any other name the data file
 * is that name and the header replaces its extension (or is appended) with ".hdr".
 *
 * Float blocks passed in or out of this module are in one of two layouts:
 *   KG_LAYOUT_BIP    [row][x][band]  (a pixel's bands together)
 *   KG_LAYOUT_PLANAR [band][row][x]  (one plane per band)
 * independent of the file's interleave. */
#ifndef KG_ENVI_H
#define KG_ENVI_H

#include "error.h"

/* ENVI "data type" codes. The writer supports U8, I16, F32, U16 and U32 (from float
 * values, so exact up to 2^24); the reader all. */
enum kg_envi_type {
	KG_ENVI_U8 = 1,
	KG_ENVI_I16 = 2,
	KG_ENVI_I32 = 3,
	KG_ENVI_F32 = 4,
	KG_ENVI_F64 = 5,
	KG_ENVI_U16 = 12,
	KG_ENVI_U32 = 13,
};

enum kg_envi_interleave { KG_ENVI_BSQ, KG_ENVI_BIL, KG_ENVI_BIP };
enum kg_envi_layout { KG_LAYOUT_BIP, KG_LAYOUT_PLANAR };

typedef struct kg_envi_pair {
	const char *key;   /* lower case, no '=' or braces */
	const char *value; /* verbatim; a list is "{a, b, c}" (see kg_envi_format_list) */
} kg_envi_pair;

/* What a header says. When writing, the caller owns every pointer and only samples,
 * lines, bands and data_type are required; when reading, the kg_envi owns them. */
typedef struct kg_envi_meta {
	int samples, lines, bands;
	enum kg_envi_type data_type;
	enum kg_envi_interleave interleave;
	const char *description;       /* or NULL; no braces */
	const double *wavelength;      /* bands values in nm, or NULL */
	const char *const *band_names; /* bands names, or NULL; no commas or braces */
	/* "reflectance scale factor": the file stores value * scale (integer types round
	 * and clamp), the reader divides by it. 0 means none (1). */
	double scale;
	/* Classification: classes > 0 writes "file type = ENVI Classification". */
	int classes;
	const char *const *class_names;   /* classes names (required when classes > 0) */
	const unsigned char *class_lookup; /* 3 * classes RGB values, or NULL */
	/* Any other keys, e.g. a basis matrix stored with a weights cube. */
	int n_extra;
	const kg_envi_pair *extra;
} kg_envi_meta;

/* Header and data paths for a name given on the command line (caller frees both). */
int kg_envi_paths(const char *path, char **hdr_path, char **data_path, kg_err *err);

/* Remove an output a failed run had already put in place: both files of an ENVI pair
 * when envi is set, else the file itself. */
void kg_envi_remove_output(const char *path, int envi);

/* "{v0, v1, ...}" with enough digits to read back the same doubles (caller frees). */
int kg_envi_format_list(const double *v, int n, char **out, kg_err *err);

/* ---- writing ---------------------------------------------------------------- */

typedef struct kg_envi_writer kg_envi_writer;

/* Start a cube: the data go to a temporary file of the final size (a kg_atomicfile, so an
 * interrupted or killed writer leaves nothing behind); nothing appears under the final
 * names until kg_envi_writer_finish. The header is validated here. */
int kg_envi_writer_open(const char *path, const kg_envi_meta *meta, kg_envi_writer **out,
                        kg_err *err);
/* Write lines y0 .. y1-1, all bands, from float data in the given layout (rows count
 * y1 - y0). Blocks may come in any order. Calls must not overlap in time. Float32
 * without a scale factor, given planar for BSQ or BIP for BIP, is written straight
 * from the caller's buffer; anything else is converted in chunks of about 4 MB. */
int kg_envi_writer_put(kg_envi_writer *w, int y0, int y1, enum kg_envi_layout layout,
                       const float *data, kg_err *err);
/* Check every line was written, then rename the data file into place and the header
 * last. Frees the writer whatever the outcome; on failure nothing is left behind. */
int kg_envi_writer_finish(kg_envi_writer **w, kg_err *err);
/* Remove the temporary files and free the writer. */
void kg_envi_writer_abort(kg_envi_writer **w);

/* A whole cube in one call. */
int kg_envi_write(const char *path, const kg_envi_meta *meta, enum kg_envi_layout layout,
                  const float *data, kg_err *err);

/* A uint8 ENVI Classification map of width x height labels (0 to nclasses - 1, row by
 * row) with the classes' names, class 0 black and class k in the plots' series colour
 * k - 1 (kg_series_colour). */
int kg_envi_write_label_map(const char *path, int width, int height, const float *labels,
                            int nclasses, const char *const *class_names,
                            const char *description, kg_err *err);

/* ---- reading ---------------------------------------------------------------- */

typedef struct kg_envi {
	kg_envi_meta meta;            /* wavelengths converted to nm; extra = other keys */
	const char *wavelength_units; /* as written, NULL when absent */
	char *hdr_path, *data_path;
	long long header_offset;
	int byte_order; /* 0 little-endian, 1 big-endian */
	struct kg_envi_store *store; /* private */
	int fd;                      /* private */
} kg_envi;

/* Open a cube by its header or data file name. Header parsing is liberal: keys are
 * case-insensitive, braces may span lines, ';' starts a comment line. The data file
 * must be large enough for the dimensions. */
int kg_envi_open(const char *path, kg_envi **out, kg_err *err);
void kg_envi_close(kg_envi **e);

/* Read the window x0 .. x0+w-1, y0 .. y0+h-1, all bands, converted to float (and
 * divided by the scale factor) into out (w * h * bands floats). Several threads may
 * read one cube at once. */
int kg_envi_read(const kg_envi *e, int x0, int y0, int w, int h, enum kg_envi_layout layout,
                 float *out, kg_err *err);

/* The raw value of any header key (lower case), braces removed; NULL if absent. */
const char *kg_envi_get(const kg_envi *e, const char *key);
/* A key's list of numbers (caller frees *v). */
int kg_envi_get_numbers(const kg_envi *e, const char *key, double **v, int *n, kg_err *err);

#endif
