/* Inside estimate/: what the apply_*.c files (images to files) share among themselves
 * and with labels_cam*.c (camera-space label maps): the input feed, progress, the files
 * of a call, the refusal stage, the margin statistics, LABELS.json and the label map's
 * colours and preview. Not included from outside estimate/. */
#ifndef KG_APPLY_PRIVATE_H
#define KG_APPLY_PRIVATE_H

#include <jansson.h>
#include <stdio.h>

#include "est_private.h"
#include "kg_core.h"

typedef struct feed {
	const kg_row_source *src, *var, *mask;
	const char *what, *var_name;
	double pre[9];
	int has_pre;
	float clip;     /* on the image's values */
	float clip3[3]; /* per channel: clip, or the saturation found below it */
	float job_clip; /* what the framework tests kin against */
} feed;

typedef struct planes {
	const float *kin, *raw, *var, *mask;
} planes;

typedef struct progress {
	FILE *fp;
	const char *what;
	int height, width;
	double start, last;
} progress;

typedef struct written {
	char *paths[16];
	int n;
} written;

typedef struct staging {
	float *v;
	size_t cap;
} staging;

#define HIST_BINS 65536
#define MAX_TARGETS 3 /* the median's one or two ranks, the 5th percentile's */

typedef struct class_stats {
	uint64_t count;
	double margin_sum;
	double rgb_sum[3]; /* what the kernel saw, for the mean spectrum */
	uint32_t *hi;      /* HIST_BINS counts of the keys' high halves, once it has pixels */
	int ntargets;
	uint64_t rank[MAX_TARGETS];  /* 0-based ranks wanted */
	uint32_t bucket[MAX_TARGETS];
	uint64_t below[MAX_TARGETS]; /* keys in lower buckets */
	uint32_t *lo[MAX_TARGETS];   /* the bucket's low halves (pass 2) */
	float value[MAX_TARGETS];
} class_stats;

planes ap_feed_planes(const feed *f, const void *in, size_t n);
int ap_feed_init(feed *f, const kg_row_source *src, const kg_apply_options *opt, const char *what, kg_err *err);
int ap_feed_fill(void *user, int y0, int rows, void *in, kg_err *err);
void ap_feed_job(feed *f, kg_est_job *job);
int ap_check_estimable(const kg_est_stats *st, const feed *f, const char *what, kg_err *err);
double ap_now_seconds(void);
void ap_progress_init(progress *p, const kg_apply_options *opt, const char *what, int width, int height);
void ap_progress_rows(progress *p, int rows_done);
void ap_written_add(written *w, const char *path);
void ap_written_add_envi(written *w, const char *path);
void ap_written_clear(written *w, int remove);
int ap_finish_all(kg_envi_writer **ws, const char *const *paths, int n, written *done, kg_err *err);
float *ap_staging_get(staging *s, size_t n, kg_err *err);
int ap_put_bytes(kg_envi_writer *w, staging *s, const kg_est_block *b, const uint8_t *src, kg_err *err);
/* The size, type, interleave and description of an ENVI file; the rest 0. */
kg_envi_meta ap_envi_meta(int width, int height, int bands, enum kg_envi_type type,
                          enum kg_envi_interleave interleave, const char *description);
/* A float32 BIP cube of `bands` bands (its writer). */
int ap_open_floats(const char *path, int width, int height, int bands, const char *description, const char *const *band_names, kg_envi_writer **w, kg_err *err);
/* A uint8 ENVI Classification map of classes (unclassified, the classes, unknown,
 * background) with their names and colours. */
int ap_open_label_map(const char *path, int width, int height, const kg_est_material_set *classes, const char *description, kg_envi_writer **w, kg_err *err);
int ap_open_mask(const char *out_hdr, int width, int height, char **mask_path, kg_envi_writer **w, kg_err *err);
void ap_class_colour(int j, unsigned char rgb[3]);
int ap_label_unknown(const kg_est_material_set *set);
int ap_label_background(const kg_est_material_set *set);

const char *ap_label_name(const kg_est_material_set *set, int label);
void ap_label_colour(const kg_est_material_set *set, int label, unsigned char rgb[3]);
uint32_t ap_order_key(float v);
float ap_key_value(uint32_t k);
void ap_stats_targets(class_stats *c);
/* Free n classes' statistics and the array. */
void ap_class_stats_free(class_stats *cs, int n);
/* Pass 2 of the margins' order statistics (cs: nclasses entries, label j + 1): the
 * margins are band 0 of conf_hdr's `bands` bands. */
int ap_margin_pass(class_stats *cs, int nclasses, const char *labels_hdr, const char *conf_hdr, int bands, int width, int height, kg_err *err);
/* Counts, mean spectra (from the mean RGB through k; NaN without k) and margin
 * statistics per class, after ap_margin_pass. count: per label. */
int ap_summarise(const kg_est_kernel *k, const kg_est_material_set *set, const uint64_t *count, const class_stats *cstats, size_t npix, kg_classify_result *res, kg_err *err);
/* The classify options against the image: frames, noise values, bounds, and the
 * variance's and mask's sizes and channels. */
int ap_check_options(const kg_classify_options *o, const kg_row_source *img, const kg_classify_info *info, const char *what, kg_err *err);
json_t *ap_json_num(double v);
json_t *ap_refusal_class(const kg_est_material_set *set, int label, uint64_t pixels, uint64_t total);
/* Pass 1: one pixel of a class, its margin and the RGB the kernel saw. */
int ap_class_stats_add(class_stats *c, float margin, const float *rgb, kg_err *err);
/* The preview's rows (pw x ph labels, nearest sample) that block b of labels lab
 * reaches, from *next_py on; height: the image's. */
void ap_preview_rows(uint8_t *preview, int pw, int ph, int *next_py, int height,
                     const kg_est_block *b, const uint8_t *lab);
void ap_preview_size(int width, int height, int *pw, int *ph);
int ap_write_preview(const char *path, const kg_est_material_set *set, const uint8_t *labels,
                     int pw, int ph, const kg_classify_result *res, int legend, kg_err *err);

/* The refusal stage (kg_classify_options), applied to every block after the label
 * kernel, whichever implementation produced it: per pixel, in double. */
typedef struct refusal {
	const kg_est_kernel *k;
	const kg_est_classifier *cls;
	double inv_frames, noise_rel2, noise_floor2, resid2;
	double g[KG_EST_MAX_K * 3]; /* A_w P: K x 3 */
	double threshold;           /* +Inf: no unknown test */
	float background_level;     /* 0: no low-signal test */
	uint8_t unknown, background;
} refusal;

/* The refusal stage's constants; dof and threshold also go to the result. */
int ap_refusal_init(refusal *r, const kg_est_kernel *k, const kg_est_classifier *cls,
                    const kg_est_material_set *set, const kg_apply_options *opt,
                    const kg_classify_options *o, kg_classify_result *res, kg_err *err);
/* Pixel i of a block whose input planes are pl: label and conf refused in place. */
void ap_refuse_pixel(const refusal *r, const planes *pl, size_t i, uint8_t *label, float *conf);
/* An image in memory: its CFA, if any, makes the message about channels clearer. */
int ap_check_image(const kg_image *img, const char *what, kg_err *err);
/* LABELS.json's format and inputs (method: the method's name, or NULL). */
void ap_labels_json_inputs(json_t *root, const kg_classify_info *info, const char *method);
/* LABELS.json's clip levels and the image's size and pixel count. */
void ap_labels_json_image(json_t *root, const kg_apply_options *opt, const kg_row_source *img,
                          const kg_classify_result *res);
const char *ap_distance_name(kg_est_distance d);
/* LABELS.json of an image's classification (files: labels, confidence, mask, preview). */
int ap_write_labels_json(const char *path, const kg_est_material_set *set,
                         const kg_classify_options *copt, const kg_row_source *img,
                         const kg_apply_options *opt, const kg_classify_info *info,
                         const char *const files[4], const kg_classify_result *res, kg_err *err);

/* ---- one classification call (apply_call.c) ---------------------------------------- */

/* What kg_classify_rows and kg_classify_camera_rows hold alike: the default options,
 * the writers of the label map, its confidence, its mask and one more, the side files,
 * the files in place so far and the result. */
typedef struct classify_call {
	kg_apply_options opt_default;
	kg_classify_options copt_default;
	kg_envi_writer *ws[4]; /* label map, confidence, mask, one more or NULL */
	const char *paths[4];  /* their headers */
	int nws;
	char *conf_path, *mask_path, *json_path, *png_path;
	written done;
	kg_classify_result local;
} classify_call;

/* Clear c, point a NULL *opt or *copt at the defaults, clear *res (if given). */
void ap_call_begin(classify_call *c, const char *out_hdr, const kg_apply_options **opt,
                   const kg_classify_options **copt, kg_classify_result *res);
/* The confidence's, LABELS.json's and the preview's names; the last two writable. */
int ap_call_paths(classify_call *c, const char *out_hdr, kg_err *err);
/* Open the label map of classes, the confidence cube (bands) and the mask. */
int ap_call_open(classify_call *c, const char *out_hdr, int width, int height,
                 const kg_est_material_set *classes, const char *description, int bands,
                 const char *conf_description, const char *const *band_names, kg_err *err);
/* Stream job into sink, refuse an image with nothing estimable, finish the writers. */
int ap_call_stream(classify_call *c, const kg_est_job *job, int width, int height,
                   kg_est_sink_fn sink, void *user, const feed *in, const char *out_hdr,
                   kg_err *err);
/* Pass 2 of the margins (band 0 of the confidence's bands) and the classes' summary. */
int ap_call_summary(classify_call *c, const kg_est_kernel *k,
                    const kg_est_material_set *classes, const uint64_t *count,
                    class_stats *cs, const char *out_hdr, int bands, int width, int height,
                    kg_err *err);
/* The preview PNG, with its legend or not. */
int ap_call_preview(classify_call *c, const kg_est_material_set *classes,
                    const uint8_t *preview, int pw, int ph, int legend, kg_err *err);
/* Abort what is unfinished, remove the files of a failed call (rc != 0), hand the
 * result to res on success (freed otherwise) and free the names. */
void ap_call_cleanup(classify_call *c, int rc, kg_classify_result *res);

#endif
