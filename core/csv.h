/* Numeric CSV tables as used by the reference data (../shared/reference) and by
 * `kogei model`, and lists such as `kogei collection`'s: UTF-8 text (or Windows-1252,
 * converted: text.h), one header row of column names, comma-separated, one record per
 * line; a value may be quoted as RFC 4180 (and kg_csv_put) writes it, on one line
 * ("a, ""b""" reads as a, "b"); blanks around a value are removed. Blank lines and lines
 * starting with '#' are ignored. Cells are kept as text; kg_csv_number() converts one
 * with an error naming the file, the line and the column. */
#ifndef KG_CSV_H
#define KG_CSV_H

#include <stddef.h>

#include "cgats.h"
#include "error.h"
#include "spectrum.h"

typedef struct kg_csv {
	char *path; /* name used in messages */
	int ncols;
	char **names; /* header, surrounding blanks removed */
	int nrows;
	char **cells;   /* nrows x ncols, row-major */
	int *row_lines; /* source line of each row */
	int header_line; /* source line of the header row */
} kg_csv;

int kg_csv_read(const char *path, kg_csv **out, kg_err *err);
/* Parse a buffer; `name` is used in messages (NULL: "<memory>"). */
int kg_csv_parse(const char *buf, size_t len, const char *name, kg_csv **out,
                 kg_err *err);
void kg_csv_free(kg_csv **t);

/* Index of a column by exact name, or -1. */
int kg_csv_column(const kg_csv *t, const char *name);
const char *kg_csv_cell(const kg_csv *t, int row, int col);
/* A cell as a finite number (message: file, line, column, text found). */
int kg_csv_number(const kg_csv *t, int row, int col, double *out, kg_err *err);

/* "patch,name,<wavelength>,<wavelength>,..." files (charts/, reflectance/): one
 * spectrum per row, ids from the `patch` column, every column whose header is a
 * number taken as a wavelength in nm (text columns such as `name` or `natural` are
 * skipped), resampled to the grid (flags: KG_RESAMPLE_*; data not covering 400-700 nm
 * need KG_RESAMPLE_EXTRAPOLATE). Values are taken as they are (fractions), within the
 * range kg_spectral_value_expected gives for `flags` (KG_PATCH_REFLECTANCE). */
int kg_csv_read_spectra_rows(const char *path, unsigned flags, kg_patchset **out,
                             kg_err *err);

/* Wavelength-column tables (`wavelength_nm,r,g,b`, `wavelength_nm,n,k`): the
 * wavelength column (`wavelength_nm`, else the first column) into *wl and the named
 * columns into *vals (n x ncol, row-major). Wavelengths must increase strictly.
 * Caller frees *wl and *vals. */
int kg_csv_read_columns(const char *path, const char *const *names, int ncol,
                        double **wl, double **vals, int *n, kg_err *err);

/* kg_csv_read_columns, each named column resampled to the grid into out[0..ncol-1]
 * (flags: KG_RESAMPLE_*). */
int kg_csv_read_column_spectra(const char *path, const char *const *names, int ncol,
                               unsigned flags, kg_spectrum *out, kg_err *err);

#endif
