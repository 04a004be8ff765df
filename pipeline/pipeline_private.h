/* Private to pipeline/: the session job's state, shared by its files. */
#ifndef KG_PIPELINE_PRIVATE_H
#define KG_PIPELINE_PRIVATE_H

#include <signal.h>

#include "kg_acquire.h"
#include "kg_calib.h"
#include "kg_pipeline.h"

/* One capture of the session's manifest, as the job reads it. */
typedef struct proc_capture {
	const json_t *j;          /* the manifest entry (borrowed) */
	const char *name;
	kg_capture_kind kind;
	const json_t *camera;     /* its devices.cameras entry, or NULL */
	double exposure_us;       /* NAN when not recorded */
	double gain_linear;       /* 10^(dB / 20), or ISO / 100 for a photographic camera
	                             without a gain; NAN when not recorded or in another unit */
	double aperture;          /* f-number; NAN when not recorded */
	double gain;              /* as recorded, in gain_unit; NAN when not recorded */
	const char *gain_unit;
	long frames;
	const char *pixfmt, *cfa;
	long bits, width, height;
	const char *dark, *flat;  /* corrections acquire applied (NULL: none) */
} proc_capture;

/* The image of a capture, ready to estimate: RGB (demosaiced where needed), corrected
 * for dark and flat, with the per-channel variance of the mean when recorded. */
typedef struct proc_image {
	kg_image *rgb;
	kg_image *variance;       /* of the mean (frame variance / frames), or NULL */
	char dark[KG_CAPTURE_NAME_MAX], flat[KG_CAPTURE_NAME_MAX]; /* applied, "" none */
	int dark_by_process, flat_by_process; /* 1: applied here, not by acquire */
} proc_image;

typedef struct proc {
	const kg_process_options *o;
	kg_err *err;
	char *manifest_path;
	json_t *manifest;
	char manifest_sha[65];
	proc_capture *caps;
	int ncaps;
	json_t *inputs;           /* [{role, path, sha256}] */
	json_t *warnings;         /* every warning of every step */
	json_t *skipped;          /* [{capture, kind}] left out by --skip */
	const proc_capture *chart;
	kg_chart_layout *layout;
	char *layout_path;
	kg_reference *ref;
	kg_camera_calib *cam;
	json_t *calibration;      /* process.json "calibration" */
	json_t *calib_key;        /* what the calibration depended on */
	double chart_H[9];        /* chart mm -> chart capture px */
	int chart_width, chart_height;
	char *library_path;
	kg_material_library *lib; /* the materials (--materials) */
	kg_est_material_set *set; /* those declared (--only) */
	json_t *previous;         /* the last run's process.json, or NULL */
	/* OUTDIR (process_outdir.c) */
	char *stage;              /* where this run writes: OUTDIR/.kogei-run.PID */
	const char *object_mask;  /* the object being processed: its mask (--mask, or the
	                             difference from its background capture), or NULL */
	int lock_fd;              /* OUTDIR, locked for the run; -1 */
	char **created;           /* folders created for OUTDIR, parents first */
	int ncreated;
	char *session_abs;        /* the session's absolute path */
	int committed;            /* the results are in place */
} proc;

/* A warning: kept for process.json and the report, and printed on progress. */
void proc_warn(proc *p, json_t *list, const char *fmt, ...) KG_PRINTF(3, 4);
/* What an object's labels do not know (process_object.c; its process.json entry with
 * unknown_fraction, background_fraction, unclassified_fraction and regions.table): a
 * new array of warning strings, maybe empty; NULL when out of memory. */
json_t *proc_label_warnings(const char *capture, const json_t *object);
/* A progress line ("kogei process: ..."). */
void proc_progress(proc *p, const char *fmt, ...) KG_PRINTF(2, 3);

/* Record a file read: its sha256 against the manifest's (when expected is not NULL),
 * into the inputs list under role. */
int proc_input(proc *p, const char *role, const char *path, const char *expected);

/* The capture's image, corrected, normalised by scale (exposure x gain relative to
 * the chart's; 1 for the chart itself), whole in memory (capture_rows.c). */
int proc_capture_image(proc *p, const proc_capture *c, double scale, proc_image *out);
/* The chart capture in memory, binned bin x bin (the smallest bin that leaves at most
 * max_pixels) where it is larger: block means, except that a channel reaching clip
 * anywhere in a block keeps its largest value (still clipped), and NaN stays NaN. No
 * variance. A mosaic kept whole where kogei has no demosaicing is not binned. */
int proc_chart_image(proc *p, const proc_capture *c, long max_pixels, float clip,
                     proc_image *out, int *bin);

/* The same read a band of rows at a time (capture_rows.c): a source is planned once
 * (files, the flat's means, a mosaic's range), then read in passes from the top, each
 * a kg_row_source of the image (variance 0) or of its variance (variance 1). A mosaic
 * is demosaiced unless kogei has no demosaicing and keep_mosaic is set (the chart:
 * detection demosaics itself); otherwise that is an error. */
typedef struct proc_image_info {
	int width, height, channels;
	int has_variance;
	char dark[KG_CAPTURE_NAME_MAX], flat[KG_CAPTURE_NAME_MAX]; /* applied, "" none */
	int dark_by_process, flat_by_process; /* 1: applied here, not by acquire */
} proc_image_info;
typedef struct proc_source proc_source;
typedef struct proc_pass proc_pass;
int proc_source_open(proc *p, const proc_capture *c, double scale, int keep_mosaic,
                     proc_source **out, proc_image_info *info);
void proc_source_free(proc_source **s);
int proc_pass_open(proc_source *s, int variance, proc_pass **out, kg_row_source *src);
void proc_pass_free(proc_pass **pp);

/* The session's latest dark for c (same camera, format, exposure and gain) and flat
 * (same camera and format), or NULL. */
const proc_capture *proc_matching_dark(const proc *p, const proc_capture *c);
/* 1 when d is a dark for c: same camera (backend, model, serial), format, exposure and
 * gain. */
int proc_dark_matches(const proc_capture *d, const proc_capture *c);
/* The capture of that name (not left out by --skip), or NULL. */
const proc_capture *proc_capture_named(const proc *p, const char *name);
const proc_capture *proc_matching_flat(const proc *p, const proc_capture *c);
void proc_image_clear(proc_image *img);

/* OUTDIR for a run (process_outdir.c): checked (not the session nor inside it; new,
 * empty or this session's earlier output; no input inside what the run replaces),
 * created, locked, cleared of dead runs' leftovers, the previous process.json loaded
 * into p->previous and the staging folder p->stage made. Every output of the run is
 * written under p->stage. */
int proc_outdir_open(proc *p);
/* root as process.json and the report staged, then everything staged put in place
 * (object folders, the files, process.json and report.html last). */
int proc_outdir_commit(proc *p, json_t *root);
/* The end of the run: the staging folder removed, and on failure the folders made for
 * OUTDIR; the lock released. */
void proc_outdir_close(proc *p, int failed);
/* path and everything below it removed (links themselves, not what they point to);
 * what cannot be removed is left. */
void proc_remove_tree(const char *path);
/* path made absolute with every symbolic link resolved, also when its last components
 * do not exist yet (those taken as written, "." and ".." lexically); NULL when it cannot
 * be resolved. Caller frees. */
char *proc_abs_path(const char *path);
/* 1 when a is dir or inside it (both absolute, as proc_abs_path makes them). */
int proc_is_under(const char *a, const char *dir);
/* The previous run's process.json entry of the object whose folder is name (its "dir",
 * or in records without one its "capture"); NULL when there is none. */
const json_t *proc_previous_object(const proc *p, const char *name);

/* Chart capture -> chart found, calibrations fitted and written (process_calib.c). */
int proc_calibrate(proc *p);

/* Refuse, before anything is written, objects from another camera (unless force) or
 * of unknown exposure (unless assume_same_exposure). */
int proc_objects_precheck(proc *p);
/* The cube of each object (--cube): its name, and its format (0 when none). */
const char *proc_cube_name(const proc *p);
int proc_cube_format(const proc *p, kg_est_format *format);
/* The master (master.c): --master-space and --master-illuminant checked before
 * anything is written; then per object OUTDIR/<object>/master.tif rendered from its
 * cube in dir, recorded in object ("master": path, space, illuminant; null with a
 * warning when it cannot be made). Its gamut clipping is counted over the lit pixels
 * (process_object.c's notion, the same as the clamp warning's), lit a bitmap of them
 * (NULL: no lit count was made, every pixel counts). */
int proc_master_check(proc *p);
int proc_master(proc *p, const proc_capture *c, const char *dir, const char *cube,
                const unsigned char *lit, const json_t *identity, json_t *object);
/* An object's identity (identity.c), written into its files and process.json:
 * {"object", "session" (the session folder's name), "session_id" (the manifest's id
 * or null), "captured" (the capture's start or null), "record" (the run's --meta,
 * the capture's "meta" over it, in display order), "colour_accuracy" ({"de00_mean",
 * "de00_p90", "de00_max", "patches", "basis", "illuminant"} of the held-out patches,
 * or null), "pixels_per_mm" (the chart's plane, or null), "pixels_per_mm_source"}.
 * NULL when out of memory. */
json_t *proc_identity(const proc *p, const proc_capture *c);
/* cube.hdr's description: first, then a line "key: value" per field of the identity
 * (text as kg_envi_put_quoted writes it). *out: caller frees. */
int proc_identity_envi(const json_t *id, const char *first, char **out, kg_err *err);
/* master.tif's XMP packet (Dublin Core, xmp: and the kogei namespace), wrapped and
 * padded; *out: caller frees. */
int proc_identity_xmp(const json_t *id, char **out, size_t *len, kg_err *err);
/* The record's description, else its title (ImageDescription, dc:description), or
 * NULL. */
const char *proc_identity_description(const json_t *id);
/* master.tif's TIFF tags from the identity and its XMP packet; datetime: the buffer
 * DateTime is written in. */
void proc_identity_tiff(const json_t *id, const char *xmp, size_t xmp_len, char datetime[20],
                        kg_tiff_identity *t);
/* OUTDIR/camera.icc (ICC input profile, matrix/shaper fitted to the chart's camera
 * values and measured spectra under D50) and camera.ti3 (ArgyllCMS colprof input),
 * recorded as calibration.camera_icc (null with a warning when not made). */
int proc_camera_icc(proc *p, const kg_patchset *measured);
/* The access copy (access.c): OUTDIR/<object>/access.tif from the master in dir, or a
 * warning saying why there is none; object's "access" (null without one). */
int proc_access(proc *p, const proc_capture *c, const char *dir, const json_t *identity,
                json_t *object);
int proc_access_quality(const proc *p);
const char *proc_access_compression(const proc *p);
/* The IIIF manifest (manifest.c): dir/manifest.json of an object with an access copy;
 * object's "manifest" (null without one). */
int proc_manifest(proc *p, const proc_capture *c, const char *dir, const json_t *identity,
                  json_t *object);
/* Every object capture (process_object.c); objects is the process.json list. */
int proc_objects(proc *p, json_t *objects, kg_process_summary *sum);

/* The kogei-scene/1 file of an object: the chart capture's pose from its homography
 * (the focal length from it where the pose allows, else fov_deg_default), a plane in
 * the chart's plane (or mesh), the label map projected from that pose (scene.c).
 * class_map maps label names that are not library materials (unknown, background)
 * to one. */
int proc_scene_write(proc *p, const char *path, const char *labels_file, int width,
                     int height, const json_t *class_map, const char *fallback, json_t *object);
/* The same camera: backend, model and serial of the manifest's devices.cameras. */
/* How a capture's values were made, for process.json and the report: an object with
 * gain and gain_unit as process reads them (ISO for photographic cameras), aperture,
 * demosaic (the capture's algorithm, or the one process uses for a mosaic; null for
 * RGB and mono) and raw_decoding (how its raw files were decoded; null otherwise). */
json_t *proc_capture_making(const proc_capture *c);
int proc_same_camera(const proc_capture *a, const proc_capture *b);

/* An sRGB preview of a linear image (the 99.5th percentile at 0.9), at most max_side
 * pixels on its longer side. */
int proc_preview_png(const kg_image *rgb, const char *path, int max_side, kg_err *err);
/* The same built as an image's rows pass (rows given top to bottom, each once). */
typedef struct proc_preview proc_preview;
int proc_preview_new(int width, int height, int max_side, proc_preview **out, kg_err *err);
void proc_preview_rows(proc_preview *pv, int y0, int rows, const float *rgb);
int proc_preview_write(proc_preview *pv, const char *path, kg_err *err);
/* The q-quantile of the samples taken so far (every channel), NAN when none. */
double proc_preview_quantile(proc_preview *pv, double q);
void proc_preview_free(proc_preview **pv);

/* ---- BagIt (bagit.c) for the deposit (deposit.c) ------------------------------------ */

/* A file read to its end for its checksum, and copied on the way when dst is set. */
typedef struct bag_copy {
	const char *alg;             /* OpenSSL's digest name ("sha512") */
	const char *src;
	const char *dst;             /* a new file (O_EXCL) the data go to, fsynced; or NULL */
	unsigned char *buf;          /* bufsize bytes of working space */
	size_t bufsize;
	volatile sig_atomic_t *stop; /* when it is set: -EINTR at the next block */
} bag_copy;
/* hex: 2 * EVP_MAX_MD_SIZE + 1 characters (lower case); *size: the octets read. */
int bag_digest_file(const bag_copy *c, char *hex, unsigned long long *size, kg_err *err);
/* The same of text in memory: 0, or -1 for an unknown algorithm. */
int bag_digest_text(const char *alg, const char *text, size_t len, char *hex);
/* Every entry under dir, in byte order of the names, a folder before what it holds:
 * visit gets its path, its path relative to the walk (rel/...) and its lstat; it
 * returns 0 to go on (into a folder), 1 to go on past the entry, or an error code,
 * which ends the walk. Folders deeper than 64 are refused. */
typedef int (*bag_visit)(void *user, const char *path, const char *rel, const struct stat *st);
int bag_walk(const char *dir, const char *rel, bag_visit visit, void *user, kg_err *err);
/* rel as a manifest writes it: CR, LF and '%' percent-encoded (RFC 8493, 2.1.3). */
void bag_put_path(FILE *f, const char *rel);

/* ---- kogei deposit's bag-info.txt values (deposit_info.c) -------------------------- */

#define DEPOSIT_NGIVEN 6 /* Source-Organization ... External-Description */
typedef struct deposit_info {
	char *config_text;                  /* the config file, its values cut out in place */
	const char *values[DEPOSIT_NGIVEN]; /* the operator's labels: the option's value, else
	                                     * the config's; NULL: not given */
} deposit_info;
/* The config file's values (o->config), then the options' over them; KG_EINVAL naming
 * "FILE: line N" for a line that is not "Label: value" of a label taken. */
int deposit_info_load(deposit_info *in, const kg_deposit_options *o, kg_err *err);
/* The values given as bag-info.txt lines, in its order. */
void deposit_info_print(const deposit_info *in, FILE *f);
void deposit_info_clear(deposit_info *in);
/* NULL when value can be a bag-info.txt value (one line of UTF-8 text, not empty: no
 * line break, other control or format character), else what is wrong (a phrase). */
const char *deposit_value_problem(const char *value);

#endif
