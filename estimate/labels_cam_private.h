/* Inside estimate/: what the labels_cam*.c files (camera-space label maps,
 * kg_classify_camera_rows) share: the run, the per-pixel noise, the regions, the sink,
 * the survey, and the stages each file holds. Not included from outside estimate/. */
#ifndef KG_LABELS_CAM_PRIVATE_H
#define KG_LABELS_CAM_PRIVATE_H

#include <math.h>

#include "apply_private.h"

#define MAX_PROVISIONAL (1 << 20) /* runs of the union-find; above, no regions */
#define MAX_USER_REGIONS 65536
#define RESOLVE_POSTERIOR 0.99
#define TABLE_MIN_PIXELS 100 /* regions listed in LABELS.json */
/* The neutral-diffuse alternative takes a pixel a material also fits only when its d2
 * is less by this (a likelihood ratio of e^0.5 = 1.65 in its favour). A material that
 * fits about as well keeps the pixel: black lacquer at grazing incidence is mostly its
 * neutral surface reflection. Measured (docs/estimate.md): a margin of 0 gives 994 of
 * the 2303 urushi dome pixels of apply-classify-camera to background, 1 gives 11, 2
 * gives 4; of a 20 % grey card's pixels under the noise model (no variance image)
 * 99.4 %, 98.5 %, 95.2 % read background, 67 % at 4, 11 % at 6.63. */
#define NEUTRAL_MARGIN 1.0

typedef struct noise {
	double M2[9], R[9];
	double P[6][3]; /* M2[a][ch] M2[b][ch] for the covariance's 6 entries (a, b) */
	double inv_frames, floor2, rel2;
} noise;

typedef struct cam_run {
	const kg_cs_model *model;
	noise nz;
	feed in;
	size_t base;  /* floats per pixel the feed writes */
	int nm, nc;   /* materials, classes */
	int group[KG_EST_MAX_MATERIALS];   /* material -> class index */
	double threshold;                  /* unknown above; +Inf: no test */
	double model_tr[KG_EST_MAX_MATERIALS]; /* the materials' model relative variances */
	int dof;                           /* of a pixel's d2 */
	/* composition: the pure metals' readings (silver, copper, gold) at the model's
	 * angles, and which materials are made of them */
	const kg_cs_model *metals; /* NULL: no composition */
	uint8_t comp_ok[KG_EST_MAX_MATERIALS];
	double gold_range;         /* of the declared Ag-Cu-Au materials' gold fractions */
	float background_level;
	uint8_t unknown, background;
	int neutral;      /* the neutral-diffuse alternative is on */
	uint8_t metal[KG_EST_MAX_MATERIALS]; /* the material is a metal or an alloy */
	double white[3];  /* its reading: F times a flat reflectance of 1 */
} cam_run;

/* The extra planes after the feed's, per block of n pixels. */
typedef struct cam_planes {
	float *x, *cov, *post, *angle, *scale, *best, *fshare, *comp, *flat, *d2;
} cam_planes;

typedef struct run_seg {
	int x0, x1; /* inclusive */
	uint32_t id;
	uint8_t label;
} run_seg;

/* What the rule for regions too small for the noise did. */
typedef struct small_stats {
	int done;                  /* the rule was applied (connected components) */
	uint64_t regions, pixels;  /* merged into their surroundings (unknown included) */
	uint64_t unknown_regions, unknown_pixels; /* of those, made unknown */
	uint64_t one_pixel, one_pixel_kept;       /* regions of one pixel; of them kept */
} small_stats;

typedef struct regions {
	int on, overflow, user;
	double user_scale; /* a user map's values to region numbers */
	const char *user_name; /* its file, for messages */
	int dof;           /* of a pixel's d2 */
	int nm;
	/* union-find over provisional ids (connected components) or user ids */
	uint32_t *parent;
	uint8_t *label;
	uint64_t *count;
	double *d2;        /* nm per id */
	double *f_sum;     /* l^2 / tr(C) of the pixels, summed */
	double cal_tr;     /* the calibration residual's relative covariance: its trace */
	const double *model_tr; /* per material, its model's relative covariance's trace */
	double *comp;      /* 6 per id: sum of c / sd^2 and of 1 / sd^2 for Ag, Cu, Au */
	uint32_t n, cap;
	run_seg *prev, *cur;
	int nprev, ncur, width;
	/* after the run */
	uint32_t *final;   /* id -> region number (1-based), 0 none */
	uint32_t nfinal;
	double *q999;      /* 1001: chi-square's 99.9 % point by degrees of freedom; 0: not
	                      yet computed */
	/* regions too small for the noise (lc_write_region_map): the materials'
	 * separabilities (nm x nm) and each one's from the neutral-diffuse alternative */
	const double *sep, *flat_sep;
	double *min_px;       /* [nfinal + 1]: the pixels it needed against its surroundings
	                         (a region never too small: against its nearest alternative) */
	const char **merged;  /* [nfinal + 1]: the label it took from its surroundings (or
	                         "unknown"), NULL: kept */
	small_stats small;
} regions;

/* A region's decision (see the top of the file). */
typedef struct region_decision {
	int unknown;     /* no declared material explains the region */
	int cls;         /* class index */
	int material;    /* the material it resolves to, or -1 (the compound class) */
	double posterior;
	double d2_mean;  /* the decided label's pooled distance per pixel */
} region_decision;

typedef struct cam_sink {
	kg_envi_writer *labels, *conf, *mask, *comp;
	staging stage;
	progress prog;
	const cam_run *run;
	const kg_row_source *region_map;
	float *region_row;
	int nclasses;
	uint64_t count[KG_EST_MAX_MATERIALS + 3];
	class_stats *cs;
	uint8_t *preview;
	int pw, ph, next_py, height;
	float *conf4;   /* a block's 4 bands, BIP */
	size_t conf4_cap;
	regions reg;
} cam_sink;

typedef struct survey_result {
	uint64_t pixels;
	/* per channel, the variance of a site reading rho: a + b rho + c rho^2 (fitted to the
	 * variance image by least squares, c = 0; or the noise model: floor^2, 0, rel^2) */
	double va[3], vb[3], vc[3];
	double cov[9];   /* mean covariance */
	double level;    /* mean intensity, in the model's units */
	double rms;      /* mean rms reading */
	double calib_share;
} survey_result;

/* One call of kg_classify_camera_rows: its inputs, what its stages make, its files. */
typedef struct cam_call {
	const kg_est_kernel *k;
	const kg_est_material_set *set;
	const kg_classify_camera *cam;
	const kg_row_source *src;
	const kg_apply_options *opt;
	const kg_classify_options *copt;
	const kg_classify_info *info;
	const char *out_hdr;
	double merge_d;              /* the merge distance in force */
	cam_run run;
	kg_cs_model *model, *metals; /* metals: NULL without composition */
	survey_result sv;
	double *sep;                 /* nm x nm separabilities at the survey's noise */
	double *flat_sep;            /* nm: each material's from the neutral alternative */
	kg_est_material_set classes; /* the label map's classes */
	cam_sink sink;
	classify_call files;
	char *reg_path, *csv_path;   /* the region map and table */
	char *mat_path;              /* the material map (regions' decisions) */
} cam_call;

/* Stages of the call before the run (labels_cam_setup.c). */
int lc_check_inputs(const cam_call *c, kg_err *err);
/* The feed and the noise of c->run, the materials' kinds and the white's reading. */
int lc_run_init(cam_call *c, kg_err *err);
/* The materials' model and, with the three pure metals, theirs and the gold range. */
int lc_models_new(cam_call *c, kg_err *err);
/* Materials closer than the merge distance (c->sep) joined into the classes. */
int lc_classes_new(cam_call *c, kg_err *err);
void lc_classes_free(kg_est_material_set *classes);

static inline double exp_or_zero(double arg) { return arg <= -750.0 ? 0.0 : exp(arg); }

/* nz->P from nz->M2 */
void lc_noise_products(noise *nz);

/* x = M2 rho and its covariance (6 values) in double. */
void lc_pixel_noise(const noise *nz, const float *rho, const float *var, double x[3],
                    double c[6]);

size_t lc_extra_floats(int nm);
cam_planes lc_cam_planes_of(const cam_run *r, void *in, size_t n);
void lc_cam_compute(void *user, void *inbuf, size_t n, uint8_t *labels, float *conf,
                    uint8_t *mask, uint64_t *nonfinite, uint64_t *clipped);

void lc_regions_free(regions *g);
int lc_regions_grow(regions *g, uint32_t need, kg_err *err);
uint32_t lc_find_root(uint32_t *parent, uint32_t a);
uint32_t lc_new_id(regions *g, uint8_t label);
/* The runs of one row of labels (classes 1..nc only), each given a provisional id when
 * assign is set (pass 1) or in the same order again (pass 2). */
int lc_row_runs(const uint8_t *lab, int width, int nc, run_seg *out);

/* Link the current row's runs to the previous row's (ids given in order from *next). */
void lc_link_rows(regions *g, run_seg *cur, int ncur, const run_seg *prev, int nprev,
                  int assign);

/* Pass 1, one row: its runs, their unions, and each pixel's distances added to its
 * run's sums. */
int lc_regions_row(regions *g, const uint8_t *lab, const float *d2, const float *fshare,
                   const float *comp, int nc, kg_err *err);

/* User regions: ids straight from the map. */
int lc_regions_user_row(regions *g, int y, const float *ids, const uint8_t *lab,
                        const float *d2, const float *fshare, const float *comp, int nc,
                        kg_err *err);

/* Roots' sums, and region numbers in order of first appearance. */
int lc_regions_resolve(regions *g, kg_err *err);

region_decision lc_decide(const regions *g, uint32_t id, const int *group, int nc);
/* A region's composition: inverse-variance means of its pixels' fractions, their sds
 * widened by sqrt(1 + N f) (the calibration's error does not average out). out: 3
 * fractions, 3 sds, NaN without data; gold NaN where its sd is not below gold_range. */
void lc_region_composition(const regions *g, uint32_t id, double gold_range, double out[6]);

const char *lc_region_label(const region_decision *d, const kg_est_material_set *set,
                            const kg_est_material_set *classes);

/* A connected region's pixels' class beside its decision, and why they differ
 * (merged_min > 0: the region took its label from its surroundings, too small for the
 * noise, needing that many pixels):
 * "pixel_class", "differs", "why" (null when they agree). The label map shows the
 * pixels' classes; the decision is the table's. */
void lc_region_why(json_t *row, const regions *g, uint32_t id, const region_decision *d,
                   const char *label, double merged_min, const kg_est_material_set *classes);

int lc_cam_sink_fn(void *user, const kg_est_block *b, kg_err *err);
int lc_survey(const cam_run *r, const kg_classify_camera *cam, const kg_cs_model *m,
              survey_result *out, kg_err *err);

/* Every pair's separability with each reading's own noise: material i at angle k at
 * the survey's level x = level mu, its site reading M2^-1 x, that reading's variance
 * from the survey's noise model through M2, and the calibration's l^2 R. */
int lc_separability(const cam_run *r, const kg_cs_model *m, const survey_result *sv,
                    double *d, kg_err *err);

/* Each material's separability from the neutral-diffuse alternative (+Inf where it is
 * not offered), at the survey's noise. */
int lc_flat_separability(const cam_run *r, const kg_cs_model *m, const survey_result *sv,
                         double *d, kg_err *err);

/* The pixels a region of class c must hold for its pooled decision against an
 * alternative to err at most 1 % (kg_cs_pixels_for of their least separability): host
 * a class index (>= 0), or -1 the neutral-diffuse alternative (background), or -2 the
 * nearest of every alternative (a region in nothing decided), or -3 - j material j. */
double lc_small_min_pixels(const regions *g, const int *group, int c, int host);

int lc_write_json(const char *path, const kg_est_material_set *set,
                  const kg_est_material_set *classes, const int *group,
                  const kg_classify_camera *cam, const kg_classify_options *copt,
                  const kg_cs_model *m, const survey_result *sv, const double *sep,
                  double merge_d, const kg_row_source *img, const kg_apply_options *opt,
                  const kg_classify_info *info, const char *const files[7],
                  const regions *reg, const kg_classify_result *res, double threshold,
                  const cam_run *run, kg_err *err);

/* The region map of connected components: pass 1's runs found again in the written
 * labels, in the same order, so each gets its provisional id and its root's number;
 * beside it the material map (mat_hdr): each region's pixels its decided label. */
int lc_write_region_map(regions *g, const kg_est_material_set *set,
                        const kg_est_material_set *classes, const int *group,
                        const char *labels_hdr, const char *reg_hdr, const char *mat_hdr,
                        written *done, kg_err *err);

/* The table of every region (CSV). */
int lc_write_region_table(const regions *g, const kg_est_material_set *set,
                          const kg_est_material_set *classes, const int *group,
                          double gold_range, const char *csv_path, written *done,
                          kg_err *err);


#endif
