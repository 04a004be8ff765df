/* Inside pipeline/: the pieces of the report (report.c) kept in their own files:
 * images (report_html.c; text goes through core's kg_html_put) and figures (report_figures.c). */
#ifndef KG_REPORT_PRIVATE_H
#define KG_REPORT_PRIVATE_H

#include <stdio.h>

#include "kg_pipeline.h"

/* kg_report_write for a run of kogei process that is not yet in place: stage's
 * process.json to stage/report.html, each file it names taken from stage where the
 * run staged it, else from outdir (process_outdir.c). */
int report_write_staged(const char *outdir, const char *stage, kg_err *err);

/* A PNG held in memory as <img src="data:image/png;base64,..."> with its size from
 * the PNG header and the alt text (kg_html_put). Bytes that are not a PNG are KG_EINVAL
 * naming `what`. */
int report_put_png(FILE *fp, const unsigned char *png, size_t len, const char *alt,
                   const char *cls, const char *what, kg_err *err);

/* One panel of a figure of spectra on the 61-band grid (400-700 nm). */
typedef struct report_panel {
	const char *title;
	const double *solid;  /* KG_NBANDS values or NULL: the measured or model spectrum */
	const double *dashed; /* KG_NBANDS values or NULL: the estimate */
	const double *band;   /* KG_NBANDS values or NULL: the estimate's uncertainty, drawn
	                       * as a band of +-band around it */
	const char *note;     /* said inside the panel (e.g. what is missing), or NULL */
} report_panel;

/* Small multiples: one reflectance panel per entry, `cols` to a row, each on its own
 * scale, with a title, a legend naming the two curves and axis labels; as a PNG in
 * memory (caller frees). */
int report_figure_spectra(const report_panel *panels, int n, int cols, const char *title,
                          const char *solid_label, const char *dashed_label,
                          unsigned char **png, size_t *len, kg_err *err);

#endif
