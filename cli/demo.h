/* Private to `kogei demo` (cli/cmd_demo.c runs the session, cli/demo_report.c judges
 * it): what the session produced and what the report needs to describe it. */
#ifndef KG_CLI_DEMO_H
#define KG_CLI_DEMO_H

#include "cli.h"
#include "kg_calib.h"
#include "kg_sim.h"

/* The simulated session: fixed inputs, so every run gives the same numbers. */
#define DEMO_CHART "/usr/share/colord/ref/CIE-TCS.sp" /* package colord-data */
#define DEMO_REFERENCE_CAMERA "demo/reference_camera.csv"
#define DEMO_REFERENCE_ILLUMINANT "D65"
#define DEMO_REFERENCE_NOISE "50000:3:16" /* a lab camera: deep wells, 16 bits */
#define DEMO_SITE_CAMERA "demo/site_camera.csv"
#define DEMO_SITE_ILLUMINANT "A"
#define DEMO_SITE_NOISE "20000:5:12" /* a site camera: 12 bits */
#define DEMO_WHITE_LEVEL 0.9
#define DEMO_ANGLE_DEG 30.0 /* incidence of the object's samples (specular view) */
#define DEMO_TILE 40         /* pixels per sample side in the object image */
#define DEMO_SEED_REFERENCE 1
#define DEMO_SEED_SITE 2
#define DEMO_SEED_OBJECT 3

typedef struct demo_ctx {
	const char *dir;
	kg_err err;
	int nwritten;

	char *library_path;     /* the default material library */
	char *reference_camera; /* fixture paths */
	char *site_camera;
	int npatches;           /* of the chart */

	kg_reference *ref;      /* as fitted and saved */
	kg_camera *cam;         /* as read back from camera.json */
	double cond_m2;         /* of the 3 x 3 M2 */
	kg_sim_scene *scene;    /* the object, with its ground truth */
	kg_est_stats est_stats; /* of the cube */
	kg_classify_result classes;
} demo_ctx;

/* DIR/name (caller frees). */
char *demo_path(demo_ctx *d, const char *name);
/* A progress line for a file just written. */
void demo_wrote(demo_ctx *d, const char *path, const char *what);

/* Read the cube and the label map back, compare them with the scene's ground truth
 * and write spectra_by_material.png, confusion.png, object_d65.png and summary.md,
 * then print the summary. */
int demo_report(demo_ctx *d);

#endif
