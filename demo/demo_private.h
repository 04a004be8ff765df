/* Private to `kogei demo` (demo/demo.c runs the sessions, demo_report.c judges
 * it): what the session produced and what the report needs to describe it. */
#ifndef KG_DEMO_PRIVATE_H
#define KG_DEMO_PRIVATE_H

#include "kg_pipeline.h"
#include "kg_calib.h"
#include "kg_render.h"
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
#define DEMO_ANGLE_DEG 30.0 /* eq. 11's assumed incidence (kogei process --method eq11) */
#define DEMO_OBJECT_WIDTH 800 /* the object's photograph: the site camera's sensor */
#define DEMO_OBJECT_HEIGHT 600
/* The object: a tsuba with inlays, one library material per region (face id), in a
 * grey studio under CIE A (fixtures/demo/tsuba_scene.json, studio.png), rendered
 * noise-free through the site camera and photographed by the sim: camera when the
 * session was recorded. Its truth, from the same render (fixtures/demo/README.md):
 * the material per pixel (8-bit PNG, the value the render's truth class: 0
 * background, 1 + i the library's entry i) and the incidence angle (16-bit PNG, the
 * value round(10 x degrees), 65535 on the background). */
#define DEMO_OBJECT_SCENE "demo/tsuba_scene.json"
#define DEMO_TRUTH_LABELS "demo/object_truth_labels.png"
#define DEMO_TRUTH_ANGLE "demo/object_truth_angle.png"
#define DEMO_TRUTH_ANGLE_SCALE 10.0 /* PNG value per degree */
#define DEMO_TRUTH_ANGLE_NONE 65535
#define DEMO_MAX_REGIONS 64         /* face ids of the scene */
#define DEMO_REGION_MIN_PIXELS 100  /* regions of the label map judged */
/* The re-render from the estimated labels and the one from the truth (step 7): the
 * object's scene under D65, half the photograph's size. */
#define DEMO_RERENDER_WIDTH 400
#define DEMO_RERENDER_HEIGHT 300
#define DEMO_RERENDER_SPP 8
/* The chart: the 15 samples in a printed AprilTag frame (fixtures/demo/README.md),
 * photographed, found by its tags and sampled (kg_chart_detect). */
#define DEMO_CHART_LAYOUT "demo/cie-tcs-frame.json"
/* The photographs themselves (sizes, field of view, pose, blur, vignetting, paper
 * and ink) are fixed when the session is recorded: fixtures/demo/make_session.sh;
 * the poses below are the ones it uses, for the report. */
#define DEMO_REFERENCE_TILT 20.0     /* deg; the lab: a modest tilt, a sharp lens */
#define DEMO_REFERENCE_TILT_AXIS 30.0
#define DEMO_REFERENCE_ROTATE 0.0
#define DEMO_REFERENCE_BLUR 0.8      /* Gaussian sigma, px */
#define DEMO_REFERENCE_VIGNETTING 0.1 /* light lost at the image corners */
#define DEMO_SITE_TILT 30.0          /* the site: handheld, steeper and turned */
#define DEMO_SITE_TILT_AXIS 120.0
#define DEMO_SITE_ROTATE 10.0
#define DEMO_SITE_BLUR 1.2
#define DEMO_SITE_VIGNETTING 0.2
/* The chart's spectra S, measured patch by patch with the simulated spectrophotometer
 * (devices/, as `kogei measure` drives it): it reads DEMO_CHART's spectra through a
 * lamp, a 2048-pixel detector and its noise, dark and white references first. */
#define DEMO_SPECTRO "sim:" DEMO_CHART
#define DEMO_SPECTRO_INTEGRATION_US 100000u /* 100 ms, `kogei measure`'s default */
#define DEMO_SPECTRO_SCANS 5                /* averaged per reading */
#define DEMO_CHART_SPECTRA "chart_spectra.cgats"
#define DEMO_MAX_PATCHES 64
#define DEMO_SEED_REFERENCE 1
#define DEMO_SEED_SITE 2
#define DEMO_SEED_OBJECT 3

/* The demo's photographs as a recorded session (fixtures/demo/session, recorded by
 * fixtures/demo/make_session.sh): replayed through the replay: camera with acquire/
 * into DIR/lab-session and DIR/site-session (demo_session.c), one capture each, which
 * kg_process_run then processes. photos keep the demosaiced RGB means (or without
 * OpenCV the raw Bayer means with their CFA attached) for the truth comparison. */
#define DEMO_SESSION "demo/session"
#define DEMO_CAPTURE_REFERENCE "reference-chart"
#define DEMO_CAPTURE_SITE "site-chart"
#define DEMO_CAPTURE_OBJECT "object"
typedef struct demo_photos {
	kg_image *reference_chart, *site_chart, *object;
} demo_photos;

/* One photograph of the chart: how it was taken and what detection found. */
typedef struct demo_chart_shot {
	const char *role;        /* "reference", "site" */
	const char *camera;      /* fixture name (DEMO_*_CAMERA) */
	const char *illuminant, *noise;
	double tilt_deg, tilt_axis_deg, rotate_deg, blur_px, vignetting;
	uint64_t seed;
	/* detection */
	int ntags_used;
	char tags_used[64];      /* "0,1,2,3" */
	double rms_px;           /* homography reprojection RMS */
	int npatches, nsampled;  /* of the layout; in the patch file */
	int nflagged;            /* patches with a warning */
	int nwarnings;
	double worst_sd;         /* largest per-channel pixel spread of a patch */
	char worst_id[32];
	char worst_channel;      /* 'R', 'G' or 'B' */
	double max_error;        /* largest |detected - rendered truth|, % of full scale */
	double detect_ms, tag_ms;
	int decimate;
} demo_chart_shot;

/* The chart measured with the spectrophotometer, against the spectra it measured. */
typedef struct demo_spectro_run {
	char model[32], serial[32];
	uint32_t integration_us;
	int scans, boxcar;
	int npatches;
	int nwarnings;
	double rmse[DEMO_MAX_PATCHES];     /* per patch, measured vs DEMO_CHART, 61 bands */
	double max_diff[DEMO_MAX_PATCHES]; /* per patch, largest |measured - file| */
	double rmse_mean, rmse_max, diff_max;
	int rmse_max_at, diff_max_at;      /* patch index */
	double diff_max_nm;
	double ms;                         /* the whole run: dark, white, patches */
} demo_spectro_run;

typedef struct demo_ctx {
	const char *dir;
	kg_err err;
	int nwritten;

	char *library_path;     /* the default material library */
	char *reference_camera; /* fixture paths */
	char *site_camera;
	char *layout_path;      /* the chart's frame (DEMO_CHART_LAYOUT) */
	char layout_name[64];
	char layout_family[32];
	double sample_fraction; /* of each patch side, sampled */
	int npatches;           /* of the chart */
	char patch_ids[DEMO_MAX_PATCHES][32];   /* the layout's, in order */
	char patch_names[DEMO_MAX_PATCHES][48];
	demo_spectro_run spectro; /* step 1: the chart's spectra measured */
	demo_chart_shot shots[2]; /* reference, site */

	kg_reference *ref;      /* as fitted and saved */
	kg_camera_calib *cam;   /* as read back from camera.json */
	double cond_m2;         /* of the 3 x 3 M2 */
	double angles[3];       /* the incidence angles camera-space matching searched */
	/* The object's truth (step 4): the render's truth maps as the fixtures hold them
	 * (classes: 0 background, 1 + i library entry i; angles in degrees, NaN on the
	 * background), the library, and the scene's regions: face id and material (its
	 * library index) of each, in the order of the scene file. */
	kg_render_truth *truth;
	kg_material_library *lib;
	int nregions;
	int region_id[DEMO_MAX_REGIONS];
	int region_material[DEMO_MAX_REGIONS];
	kg_est_stats est_stats; /* of the cube */
	kg_classify_result classes;
	demo_photos photos;     /* the session's captures, replayed */
} demo_ctx;

/* DIR/name (caller frees). */
char *demo_path(demo_ctx *d, const char *name);

/* Replay the bundled session into DIR/session (see demo_photos above). */
int demo_session_replay(demo_ctx *d, demo_photos *out);
void demo_photos_free(demo_photos *p);

/* A progress line for a file just written. */
void demo_wrote(demo_ctx *d, const char *path, const char *what);

/* The object (the tsuba of render/kg_mesh.h) rendered in each material of the paper's
 * Fig. 13 (the five shibuichi, gold, copper, urushi) into render/<material>.png and
 * the labelled contact sheet render_fig13.png, with the scene (render_scene.json) and
 * its environment (render_sky.tif); skipped with a message without Embree
 * (demo_render.c). */
int demo_render(demo_ctx *d);

/* The true reflectance of each library material at every angle the truth holds
 * (0-90 deg in steps of 1 / DEMO_TRUTH_ANGLE_SCALE; kg_material_reflectance), only for
 * the materials the truth shows: (*table)[(material * steps + step) * 61 + band],
 * caller frees. */
int demo_truth_table(demo_ctx *d, float **table);

/* The name of a region of the object's scene: "plate", "rim", "relief",
 * "seppa-dai" for the tsuba's face ids 0-3, "inlay N" for the domes (ids 4 on). */
void demo_region_name(int face_id, char *buf, size_t size);

/* The re-render (step 7): the object's scene under D65, once with each region's true
 * material, once with the material given (library index per region, d->region_*
 * order); both in CIE XYZ relative to the white, their difference in CIEDE2000 per
 * pixel over the object (the truth render's object pixels). Writes
 * rerender/truth.json, estimate.json (kogei render --scene ... gives them again),
 * the studio they name, truth.png, estimate.png and de00.tif (NaN off the object).
 * Without Embree: available = 0, nothing written. */
typedef struct demo_rerender_result {
	int available;
	int width, height;
	kg_image *truth, *estimate; /* XYZ, Y = 1 the white */
	float *de00;                /* per pixel, NaN off the object */
	long pixels;                /* object pixels */
	double de00_mean, de00_p90, de00_max;
	double seconds;
} demo_rerender_result;
int demo_rerender(demo_ctx *d, const int *estimate_material, demo_rerender_result *out);
void demo_rerender_result_clear(demo_rerender_result *r);

/* Read the cube, the label map and its regions back, compare them with the object's
 * truth, re-render the object from the estimated labels, and write
 * spectra_by_material.png, confusion.png, object_d65.png, truth_vs_estimate.png and
 * summary.md, then print the summary. */
int demo_report(demo_ctx *d);

#endif
