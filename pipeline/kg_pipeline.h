/* The session job: a recorded session in, and out of it the calibration, the
 * reflectance cubes, the label maps, the render scenes and the operator's report,
 * all in one output folder (OUTDIR). The job's record of what it did is
 * OUTDIR/process.json ("format": "kogei-process/1", docs/formats.md); everything
 * the report shows is read back from that record and the files it names.
 *
 * Functions return 0 or a negative KG_E* code and fill the optional kg_err with a
 * message naming the file, the key and what was expected. */
#ifndef KG_PIPELINE_H
#define KG_PIPELINE_H

#include "kg_core.h"

/* ---- Report ----------------------------------------------------------------------
 *
 * OUTDIR/report.html: one self-contained HTML file (inline CSS, every image a
 * data: URI of a PNG, no script, no font and no reference outside the file) that a
 * conservator can read, print and archive. Sections, each <section id=...>:
 * summary, calibration, color-accuracy, objects, provenance, warnings
 * (docs/report.md). Text from process.json is HTML-escaped; an optional piece that is
 * absent (a null key, a missing image file) is stated in the page, never dropped. */

/* Read OUTDIR/process.json and the files it names and write OUTDIR/report.html
 * atomically. A missing or mistyped required key is KG_EINVAL naming
 * OUTDIR/process.json and the key path (e.g. "calibration.cond_M2"). */
int kg_report_write(const char *outdir, kg_err *err);

/* Colour accuracy: the summary of per-patch colour differences (CIEDE2000) and its
 * grades. The report recomputes only these aggregates from the per-patch values of
 * process.json. */
typedef struct kg_de_summary {
	int n;       /* values summarised (the finite ones) */
	double mean;
	/* 90th percentile by the nearest-rank convention: the ceil(0.9 n)-th smallest
	 * value (1-based), always one of the values; no interpolation. */
	double p90;
	double max;
} kg_de_summary;

/* Summarise the finite values of v[0..n-1]; NaN marks a patch without a value and
 * is skipped. No finite value, or a negative or infinite one, is KG_EINVAL. */
int kg_de_summarise(const double *v, int n, kg_de_summary *out, kg_err *err);

/* FADGI 4-star (Technical Guidelines for Digitizing Cultural Heritage Materials),
 * colour accuracy in CIEDE2000: mean < 2 and 90th percentile < 4 (strict). */
#define KG_FADGI4_MEAN_BELOW 2.0
#define KG_FADGI4_P90_BELOW 4.0
/* ISO 19264-1:2021 level A, colour accuracy in CIEDE2000: mean <= 4 and
 * maximum <= 10 (inclusive). */
#define KG_ISO19264_A_MEAN_AT_MOST 4.0
#define KG_ISO19264_A_MAX_AT_MOST 10.0

/* 1 when the summary passes, 0 when it fails (also for n == 0). */
int kg_grade_fadgi4(const kg_de_summary *s);
int kg_grade_iso19264_a(const kg_de_summary *s);

#endif
