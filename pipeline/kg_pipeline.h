/* pipeline/: the session job (docs/process.md, docs/architecture.md).
 *
 * A session recorded by `kogei acquire` (captures of kind dark, flat, chart, object)
 * goes in; the site calibration, per-object reflectance cubes, label maps, render
 * scenes and the operator's report come out:
 *
 *   OUTDIR/camera.json            the site calibration (kogei-camera/1)
 *   OUTDIR/reference.json         lab sessions (--spectra without --reference) only
 *   OUTDIR/chart_overlay.png      what chart detection found
 *   OUTDIR/process.json           inputs with sha256, versions, parameters, per-object
 *                                 statistics, warnings (kogei-process/1)
 *   OUTDIR/report.html            the operator's report (self-contained)
 *   OUTDIR/<capture>/             per object capture: cube.hdr (+ _mask), labels.hdr
 *                                 (+ .json, .png, _confidence, _mask), photo.png,
 *                                 confidence.png, scene.json (kogei-scene/1), render.png
 *
 * Steps: the chart capture's image, dark- and flat-corrected where acquire did not
 * already; the chart found and sampled (calib/); flagged patches left out of M2; M2
 * fitted and checked (calib/); then every object capture: the camera checked against
 * the chart's, its values normalised by exposure time x gain to the chart capture's,
 * estimated (estimate/), classified and written with a scene that renders as it is.
 *
 * Refusals: no chart, too few usable patches, an M2 residual above max_residual, a
 * 3-patch chart (uncheckable) without force, an object from another camera without
 * force, unknown exposure settings without assume_same_exposure, an output that is an
 * input. A refusal returns KG_EINVAL with a message naming the capture or file and the
 * cause; nothing is written under a final name.
 *
 * Re-running skips objects whose inputs and parameters are unchanged (the key of each
 * object is in process.json); objects recorded later are the only ones processed. */
#ifndef KG_PIPELINE_H
#define KG_PIPELINE_H

#include <stdio.h>

#include "kg_core.h"

#define KG_PROCESS_FORMAT "kogei-process/1"
/* Default for kg_process_options.max_residual (see docs/process.md). */
#define KG_PROCESS_MAX_RESIDUAL 0.05

typedef struct kg_process_options {
	const char *session;       /* the session directory */
	const char *reference;     /* kogei-reference/1, or NULL for a lab session */
	const char *spectra;       /* the chart's measured spectra (CGATS): fits the
	                            * reference when reference is NULL; else used for the
	                            * colour accuracy of the report */
	const char *materials;     /* library path or bundled name (NULL: "default") */
	const char *const *only;   /* materials declared for the scene, or NULL: all */
	int nonly;
	const char *layout;        /* chart layout path or name; NULL: the chart capture's */
	const char *chart;         /* chart capture name; NULL: the latest chart capture */
	const char *mesh;          /* PLY for the scenes, or NULL: a plane */
	const char *mask;          /* object mask image (0 = background), or NULL */
	const char *outdir;
	int min_tags;              /* 0: 2 tags with the tagless fallback; N: N, no fallback */
	double max_residual;       /* relative M2 residual refused above */
	double angle_deg;          /* incidence assumed for the library's spectra (30) */
	int force;                 /* accept a 3-patch chart and another camera */
	int assume_same_exposure;  /* accept captures whose exposure is unknown */
	int render;                /* render each scene.json to render.png (when Embree) */
	int threads;               /* 0: all */
	FILE *progress;            /* progress lines, or NULL */
	const char *command;       /* how it was invoked, for process.json (may be NULL) */
} kg_process_options;

void kg_process_options_default(kg_process_options *o);

/* What one run did. */
typedef struct kg_process_summary {
	int objects;        /* object captures in the session */
	int processed;      /* of them, processed in this run */
	int skipped;        /* unchanged since the last run */
	int warnings;
	double residual;    /* of M2 */
	double seconds;
} kg_process_summary;

int kg_process_run(const kg_process_options *o, kg_process_summary *summary, kg_err *err);

/* ==== Report ====================================================================== */

/* Write OUTDIR/report.html from OUTDIR/process.json and the files it names. */
int kg_report_write(const char *outdir, kg_err *err);

/* ==== The demo ===================================================================== */

/* `kogei demo`: the bundled session (fixtures/demo/session) replayed into a lab and a
 * site session under dir, the chart measured with the simulated spectrophotometer,
 * then kg_process_run on both, and the demo's comparisons with the simulation's truth
 * (summary.md, figures, renders of Fig. 13). Progress on standard output. */
int kg_demo_run(const char *dir, kg_err *err);

#endif
