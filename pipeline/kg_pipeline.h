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
 *                                 confidence.png, scene.json (kogei-scene/1), render.png,
 *                                 master.tif, master_linear.tif, highlights.png
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
 * object is in process.json); objects recorded later are the only ones processed.
 *
 * OUTDIR (process_outdir.c, docs/formats.md): new, empty or this session's earlier
 * output, not inside the session; nothing there that process did not write is
 * replaced, and no input may lie inside what a run replaces (refused, KG_EINVAL,
 * before anything is written). A run is staged in OUTDIR/.kogei-run.PID and put in
 * place through a journal when complete, process.json and report.html last; the next
 * run removes or completes what a killed run left. */
#ifndef KG_PIPELINE_H
#define KG_PIPELINE_H

#include <stdio.h>

#include "kg_acquire.h"
#include "kg_calib.h"
#include "kg_devices.h"
#include "kg_core.h"

#define KG_PROCESS_FORMAT "kogei-process/1"
/* Default for kg_process_options.max_residual: calib/'s (docs/calib-camera.md). */
#define KG_PROCESS_MAX_RESIDUAL KG_CALIB_MAX_RESIDUAL

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
	const char *verify;        /* a second chart capture graded through the calibration */
	const char *mesh;          /* PLY for the scenes, or NULL: a plane */
	const char *mask;          /* object mask image (0 = background), or NULL */
	const char *outdir;
	int min_tags;              /* 0: 2 tags with the tagless fallback; N: N, no fallback */
	double max_residual;       /* relative M2 residual refused above */
	double angle_deg;          /* eq11: incidence assumed for the library's spectra (30) */
	const char *method;        /* labels: "camera" (camera-space matching, the default)
	                            * or "eq11" (the paper's eq. 11 on the pca weights) */
	double angles[3];          /* camera: incidence angles searched, from, to, step
	                            * (0, 70, 5) */
	double intensity[2];       /* camera: intensities searched (0.3, 1.0) */
	int force;                 /* accept a 3-patch chart and another camera */
	int assume_same_exposure;  /* take an exposure time or gain that is not recorded as
	                            * the chart capture's (what is recorded still counts) */
	const char *const *skip;   /* captures left out of the run by name (nskip) */
	int nskip;
	int render;                /* render each scene.json to render.png (when Embree) */
	const char *cube;          /* per object cube: "f32" (the default), "f16", "weights"
	                            * (the K PCA weights and their basis) or "none" */
	const char *master_space;  /* each object's master.tif: "ecirgb-v2" (NULL: the
	                            * default), "adobe-rgb", "prophoto" or "none" */
	const char *master_illuminant; /* its illuminant, NAME|FILE (NULL: D50) */
	const char *icc_version;   /* "2" (NULL: the default) or "4": the ICC version of
	                            * the master's profile and camera.icc */
	/* the IIIF access copy and manifest (access.c, manifest.c; kg_process_access_table) */
	const char *access_compression; /* access.tif's tiles: "jpeg" (NULL) or "deflate" */
	const char *access_quality;     /* their JPEG quality, "1".."100" (NULL: 90) */
	const char *iiif_base;     /* the IIIF Image API base OUTDIR is served under, or NULL:
	                            * manifest ids relative */
	const char *iiif_image_api; /* "3" (NULL) or "2": that server's IIIF Image API */
	const char *files_base;    /* the URL of OUTDIR's files, or NULL: relative */
	int threads;               /* 0: all */
	FILE *progress;            /* progress lines, or NULL */
	const char *command;       /* how it was invoked, for process.json (may be NULL) */
	const json_t *meta;        /* --meta object record (kg_meta_*), merged over the
	                            * captures' into process.json "meta"; NULL: none */
	int accept_rerecorded;     /* an OUTDIR holding the results of an earlier recording
	                            * of a session at the same path counts as this
	                            * session's (the demo records its sessions anew) */
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

/* The warnings of a process.json (pj may be NULL: 0): each is recorded once, in its
 * scope's list, the session's ("warnings") or an object's ("objects[].warnings", kept
 * with an unchanged object); the count is of both, the number the command line, the
 * report and the console say. */
int kg_process_warning_count(const json_t *pj);

/* For a program that runs kg_process_run as its one job (kogei process): SIGINT,
 * SIGTERM and SIGHUP (those not ignored) are blocked in the calling thread and taken
 * by a thread of their own, which prints what OUTDIR keeps, removes the run's staging
 * folder and ends the process by the signal (exit status 128 + the signal). Call it
 * before any other thread starts. -1 if the thread cannot be started. */
int kg_process_watch_signals(void);

/* Readers of a processed OUTDIR (report, console, deposit, collection). A run puts its
 * results in place by several renames (a journal folder .kogei-commit.PID, then each
 * object folder, then the files, process.json last); a run killed among them leaves
 * the journal, and OUTDIR half old and half new until it is completed.
 * kg_outdir_settle makes OUTDIR whole before it is read: when it holds a journal and
 * no run is live (the OUTDIR lock is free) it takes the lock and completes every
 * journal and clears every leftover of a dead run, saying so on progress as
 * "<who>: ..."; when a run is live and putting its results in place, it waits up to
 * wait_ms for it to finish.
 * With lock_fd, the caller gets the lock and keeps it (it will write into OUTDIR:
 * kg_outdir_unlock when done), and a live run is waited for whatever it is doing;
 * without it, a live run that is still computing is no obstacle (its results are
 * invisible until they are complete). KG_EBUSY naming OUTDIR when the wait ends
 * first; KG_ENOENT when OUTDIR does not exist. */
int kg_outdir_settle(const char *outdir, const char *who, FILE *progress, int wait_ms,
                     int *lock_fd, kg_err *err);
void kg_outdir_unlock(int *lock_fd);
/* 1 while OUTDIR holds a journal (a run is putting results in place, or died doing
 * so): a reader that opened a file meanwhile may hold a half-made view. */
int kg_outdir_in_commit(const char *outdir);

/* ==== Options of an operation (options.c) ===========================================
 * An operation that several front ends start (kogei deposit from the command line, the
 * console's POST /api/deposit; later kogei collection) declares its options once, as a
 * table: each option's name, its value's name, its type, where it goes in the
 * operation's options struct and its help. The command line is parsed through the
 * table (kg_opt_parse_argv), --help is printed from it (kg_opt_print_help) and a JSON
 * request fills the same struct (kg_opt_from_json), so no front end spells the options
 * out again. Checking the values is the operation's (one function both front ends
 * call), not the table's. */

typedef enum kg_opt_type {
	KG_OPT_FLAG,   /* an int set to 1 (JSON: true or false) */
	KG_OPT_STRING, /* a const char * (JSON: a string, borrowed from the request) */
} kg_opt_type;

enum {
	KG_OPT_CLI_ONLY = 1u << 0, /* not taken from JSON: a path on the operator's machine,
	                            * the console's own choice */
};

typedef struct kg_opt_spec {
	const char *name;  /* "contact-name": --contact-name, JSON key "contact_name" */
	char letter;       /* the short form (-o), or 0 */
	const char *value; /* the value's name in the help ("NAME"); NULL for a flag */
	kg_opt_type type;
	size_t offset;     /* of its field in the options struct */
	unsigned flags;    /* KG_OPT_* */
	const char *help;  /* one paragraph, wrapped when printed */
} kg_opt_spec;

typedef struct kg_opt_table {
	const char *synopsis;    /* the usage lines ("kogei deposit RESULTS -o BAG ...") */
	const char *description; /* what the operation does, printed before the options */
	const char *positional;  /* the name of its one positional argument, or NULL */
	size_t positional_offset; /* of the const char * it goes to */
	const kg_opt_spec *specs;
	int nspecs;
} kg_opt_table;

/* argv[1..argc-1] into opts: --name VALUE, --name=VALUE, -l VALUE, -lVALUE, flags, the
 * positional argument, "--" before a positional that starts with '-'. A later string
 * option replaces an earlier one. KG_EINVAL with a message for the usage error (an
 * unknown option, a missing value, a value given to a flag, an unexpected argument). */
int kg_opt_parse_argv(const kg_opt_table *t, int argc, char **argv, void *opts, kg_err *err);
/* The members of a JSON object into opts (keys with '_' where the option has '-'): a
 * flag takes true or false, a string option a string. An unknown key, a KG_OPT_CLI_ONLY
 * one or a value of the wrong type is KG_EINVAL naming the key and what was expected.
 * Strings are borrowed from obj. */
int kg_opt_from_json(const kg_opt_table *t, const json_t *obj, void *opts, kg_err *err);
/* "usage: SYNOPSIS", the description and every option with its help. */
void kg_opt_print_help(FILE *fp, const kg_opt_table *t);
/* One option of a table set from its value (a flag from NULL): for a front end that
 * parses its command line itself and takes some options from a table. */
void kg_opt_set(const kg_opt_spec *s, void *opts, const char *value);
/* The table's options with their help, as kg_opt_print_help prints them. */
void kg_opt_print_options(FILE *fp, const kg_opt_table *t);

/* The options of the access copy and the manifests (access.c), declared once for the
 * command line (kogei process) and JSON requests (the console's process job): fields
 * of kg_process_options. kg_process_access_check checks their values (kg_process_run
 * calls it too). */
extern const kg_opt_table kg_process_access_table;
int kg_process_access_check(const kg_process_options *o, kg_err *err);
/* 1 when kogei was built with libvips, which makes the access copy. */
int kg_access_available(void);


/* ==== A BagIt deposit (deposit.c, docs/deposit.md) ===================================
 * kogei deposit RESULTS -o BAG: a BagIt 1.0 bag (RFC 8493) of one processed OUTDIR,
 * for a repository to ingest:
 *
 *   BAG/bagit.txt               BagIt-Version 1.0, Tag-File-Character-Encoding UTF-8
 *   BAG/data/                   every file of RESULTS, or with with_session
 *                               data/results/ (RESULTS) and data/session/ (the session
 *                               process.json names)
 *   BAG/manifest-sha512.txt     the sha512 of every payload file
 *   BAG/bag-info.txt            Source-Organization ... Contact-Email (options, config),
 *                               External-Identifier (each accession of process.json),
 *                               Internal-Sender-Identifier (the session's id),
 *                               Bagging-Date, Payload-Oxum, Bag-Software-Agent
 *   BAG/tagmanifest-sha512.txt  the sha512 of the three tag files above
 *
 * RESULTS is settled and locked while it is read (kg_outdir_settle). Payload files are
 * hard links to RESULTS' (and the session's) files where the file system allows it,
 * else (or with copy) copies. The bag is staged in BAG's parent as
 * .BASE.kogei-tmp.PID, flushed to disk and renamed to BAG in one step; an existing BAG
 * is replaced (in one exchange) only when it is a bag and force is set. A failure, or
 * a signal caught by kg_deposit_catch_signals, removes the staging folder: nothing is
 * left; after SIGKILL the next deposit beside BAG removes it. */

typedef struct kg_deposit_options {
	const char *results;      /* RESULTS: an OUTDIR of kogei process */
	const char *bag;          /* -o BAG */
	const char *verify;       /* --verify BAG: check a bag instead */
	int with_session;         /* the session's files too (data/session/) */
	const char *session;      /* the session's folder when it is no longer where
	                           * process.json says (implies with_session) */
	int copy;                 /* copy every payload file, never hard-link */
	int force;                /* replace an existing bag at BAG */
	const char *config;       /* bag-info.txt values, "Label: value" lines */
	/* bag-info.txt values given by the operator (over the config's) */
	const char *source_organization;
	const char *organization_address;
	const char *contact_name;
	const char *contact_phone;
	const char *contact_email;
	const char *external_description;
	int show_progress;        /* --progress: progress lines even off a terminal */
	FILE *progress;           /* where progress lines go, or NULL */
} kg_deposit_options;

extern const kg_opt_table kg_deposit_table;

void kg_deposit_options_default(kg_deposit_options *o);
/* The options' combination and every bag-info value (one line of text: no line break
 * or other control character, well-formed UTF-8) before anything is read: KG_EINVAL
 * naming the option. */
int kg_deposit_check(const kg_deposit_options *o, kg_err *err);

typedef struct kg_deposit_summary {
	int files;              /* payload files */
	unsigned long long bytes; /* their octets */
	int linked, copied;     /* how each came into the bag */
	int identifiers;        /* External-Identifier lines */
} kg_deposit_summary;

/* Write the bag. KG_EINVAL for bad input (RESULTS not a kogei-process/1 output, a
 * config line, BAG a folder that is not a bag, BAG without force, BAG and RESULTS
 * inside each other), KG_EBUSY while a run holds RESULTS, KG_EIO or KG_ENOSPC for a
 * failed write, -EINTR when a caught signal stopped it; nothing left at BAG then. */
int kg_deposit_run(const kg_deposit_options *o, kg_deposit_summary *sum, kg_err *err);

/* For a program that runs one deposit (kogei deposit): SIGINT, SIGTERM and SIGHUP stop
 * kg_deposit_run at its next block of data (-EINTR, the staging folder removed).
 * kg_deposit_signal is the signal that did it, or 0. */
void kg_deposit_catch_signals(void);
int kg_deposit_signal(void);

/* Re-check a bag: bagit.txt, every file of every payload manifest (manifest-ALG.txt,
 * any digest OpenSSL knows) present with its checksum and every payload file in every
 * manifest, the tag manifests' files and checksums, bag-info.txt's Payload-Oxum. Each
 * problem is a line on problems ("BAG/data/x: changed: ..."), all of them; then
 * KG_EINVAL with the counts ("BAG: invalid: 1 missing, ..."). 0 and *sum for a valid
 * bag. */
int kg_bag_verify(const char *bag, FILE *problems, FILE *progress, kg_deposit_summary *sum,
                  kg_err *err);

/* ==== A collection (collection*.c, docs/collection.md) ===============================
 * kogei collection run LIST.csv -o OUT: every session of a list, each by `kogei
 * process` into OUT/<name>/, on this machine (N worker processes) or as one Slurm job
 * array, resumable; then the collection's record:
 *
 *   OUT/<name>/                  what kogei process writes for that session
 *   OUT/collection.json          the record (kogei-collection/1): engine, per entry its
 *                                session, status, reason, job, time and objects
 *   OUT/index.html               the whole collection as one sortable table
 *   OUT/collection-manifest.json a IIIF Presentation 3 Collection of the objects'
 *                                manifests (collection_iiif.c)
 *   OUT/.collection/plan.json    the list as checked by the last run (absolute paths,
 *                                each entry's process arguments and key)
 *   OUT/.collection/entries/NAME.json  one entry's last result (done or failed), written
 *                                atomically by the task that ran it
 *   OUT/.collection/logs/NAME.log      that run's output (kogei process's stderr)
 *   OUT/.collection/thumbs/NAME/CAPTURE.png  thumbnails for index.html
 *   OUT/.slurm/                  the sbatch script, job.json (the job ids) and logs/
 *
 * An entry is done when its state says done and records the key the list gives it now
 * (the process arguments and the sha256 of session.json, the reference, the spectra and
 * a materials file); else failed (its state says failed with that key) or pending. A
 * run runs the failed and pending entries only. */

typedef struct kg_collection_options {
	const char *list;         /* LIST.csv */
	const char *out;          /* -o OUT */
	const char *engine;       /* "local" (NULL: local) or "slurm" */
	const char *jobs;         /* --jobs N: workers, or the array's throttle (NULL: cores) */
	const char *partition;    /* slurm: --partition */
	const char *sbatch_args;  /* slurm: more sbatch options, split at blanks */
	int no_wait;              /* slurm: submit and return */
	int show_progress;        /* --progress: the progress line off a terminal too */
	const char *iiif_base;    /* kogei process --iiif-base of each entry: URL/<name> */
	const char *iiif_image_api; /* kogei process --iiif-image-api of each entry */
	const char *files_base;   /* OUT's files' URL: each entry's --files-base URL/<name>,
	                           * the ids of OUT/collection-manifest.json */
	/* set by kg_collection_check */
	int njobs;
	FILE *progress;           /* the progress line, or NULL */
	FILE *problems;           /* bad rows of the list, one a line (NULL: stderr) */
	const char *self;         /* the kogei executable (NULL: /proc/self/exe) */
} kg_collection_options;

extern const kg_opt_table kg_collection_table;

void kg_collection_options_default(kg_collection_options *o);
/* The options' values and combination (engine, jobs, slurm options with the local
 * engine): KG_EINVAL naming the option. Sets njobs. */
int kg_collection_check(kg_collection_options *o, kg_err *err);

typedef struct kg_collection_counts {
	int entries, done, failed, pending;
	int ran;                  /* entries run by this call */
	char array_job[32], finish_job[32]; /* slurm: the submitted jobs ("" none) */
} kg_collection_counts;

/* Read and check LIST (every bad row written to o->problems naming file, line and
 * column; then KG_EINVAL, nothing run), write the plan, run the failed and pending
 * entries on the engine and write the record. 0 when the run ended (entries may have
 * failed: counts); KG_EINVAL for a bad list or OUT; KG_EBUSY while another run or a
 * queued Slurm job holds OUT; KG_ENODEV when the engine fails (sbatch refused, squeue
 * unreachable), with its message; -EINTR when a signal stopped it (*signal_out). */
int kg_collection_run(const kg_collection_options *o, kg_collection_counts *c,
                      int *signal_out, kg_err *err);
/* Run entry index of OUT's plan (kogei process with its arguments, threads > 0 passed
 * as --threads) and write its state, job naming the run. *done is 1 when it is done.
 * A run stopped by a signal writes no state. */
int kg_collection_task(const char *out, int index, const char *job, int threads,
                       const char *self, int *done, kg_err *err);
/* OUT/collection.json and OUT/index.html from the plan and the entries' states. */
int kg_collection_finish(const char *out, kg_collection_counts *c, kg_err *err);
/* The counts and each failure (and, with a submitted Slurm job, how many of its tasks
 * are queued or running) on fp. */
int kg_collection_status(const char *out, FILE *fp, kg_collection_counts *c, kg_err *err);
/* The failed entries, one "NAME (LIST line N): reason" line each, on fp. */
void kg_collection_print_failures(const char *out, FILE *fp);

/* ==== Report ====================================================================== */

/* The operator's report (docs/report.md): one self-contained HTML file that a
 * conservator can read, print and archive. Sections, each <section id=...>:
 * summary, calibration, color-accuracy, objects, provenance, warnings. Text from
 * process.json is HTML-escaped; an optional piece that is absent (a null key, a
 * missing image file) is stated in the page, never dropped. */

/* Read OUTDIR/process.json and the files it names and write OUTDIR/report.html
 * atomically, under the OUTDIR lock after kg_outdir_settle (an unfinished commit
 * completed first, noted on stderr; KG_EBUSY while a run is live). A missing or mistyped required key is KG_EINVAL naming
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

/* The imaging-quality analysis of the chart capture (OUTDIR/conformance.json's
 * "characteristics", docs/report.md): seven records (oecf, white_balance,
 * illuminance_non_uniformity, noise, colour_accuracy, sfr, colour_misregistration)
 * from process.json's calibration.patches (keys dL, dab, noise_L, de00_d50,
 * de00_d50_heldout, neutral) and the flat's non-uniformity (a fraction; NaN: none). */
json_t *kg_conformance(const json_t *patches, double flat_nonuniformity);
/* Fill the sfr and colour_misregistration records of list (from kg_conformance) by the
 * slanted-edge method on the sides of the detected tags of l in r, in img (the chart
 * capture as detected, binned bin x bin). A side whose band reaches r->clip, or whose
 * blur does not fit the band its tag's cells allow, is left out ("left_out": id, why);
 * "not measured" with the reason when fewer than 3 sides remain. */
void kg_conformance_edges(json_t *list, const kg_chart_layout *l, const kg_chart_result *r,
                          const kg_image *img, int bin);
/* The grade of value v of characteristic id (oecf, white_balance,
 * illuminance_non_uniformity, noise, sfr: sampling efficiency in %,
 * colour_misregistration: pixels) on the published limits (pipeline/conformance.c
 * cites them): the ISO 19264-1 level (0 A, 1 B, 2 C, 3 none reached) and, in *stars,
 * the FADGI stars (4..1, 0 none); -1 where no published limit was found, id is unknown
 * or v is not finite. */
int kg_conformance_grade(const char *id, double v, int *stars);
#define KG_CONFORMANCE_CAVEAT                                                           \
	"An analysis of the chart capture against the criteria of ISO 19264-1 and FADGI "  \
	"2023, not a certification under either standard."

/* ==== The guided spectrometer measurement (measure_flow.c) =========================
 * `kogei measure` (dark, white, the patches of a chart in order with redo, white again
 * and resume from OUT.partial), shared by the terminal (cli/cmd_measure.c) and the
 * operator's console (console/): the operator is asked through a callback, messages go
 * to another. */

typedef struct kg_measure_ui {
	/* Show prompt and return the answer: 'm' (measure), 'r' (redo the last patch,
	 * when allowed holds 'r'), 'w' (white again, when allowed holds 'w') or 'q'. */
	int (*ask)(void *user, const char *allowed, const char *prompt);
	/* One line for the operator: progress, notes and "warning: ..." lines. */
	void (*say)(void *user, const char *message);
	void *user;
} kg_measure_ui;

typedef struct kg_measure_flow {
	kg_measure_session s; /* the instrument, settings, dark and white references */
	double white_max_age;
	int yes;              /* never ask: every answer is 'm' (scripts, tests) */
	int white_age_warned;
	kg_measure_ui ui;
} kg_measure_flow;

/* Above this relative change of the white's signal a warning is printed. */
#define KG_WHITE_DRIFT_LIMIT 0.02

/* The patches to measure, with where each is on the chart. */
typedef struct kg_patch_list {
	int n;
	char **ids;
	char **places;
} kg_patch_list;

/* From a chart layout, a comma-separated list of ids or the SAMPLE_IDs of a CGATS
 * file (exactly one non-NULL). */
int kg_patch_list_load(const char *chart, const char *list, const char *file,
                       kg_patch_list *l, kg_err *err);
void kg_patch_list_free(kg_patch_list *l);

/* Route m->s.warn to ui.say as "warning: ..." lines. */
void kg_measure_flow_init(kg_measure_flow *m);
/* Ask (or, with m->yes, only show the prompt and answer 'm'). */
int kg_measure_flow_ask(kg_measure_flow *m, const char *allowed, const char *fmt, ...)
	KG_PRINTF(3, 4);
/* The references and one sample; 1 when the operator stopped (q). */
int kg_measure_flow_dark(kg_measure_flow *m, kg_err *err);
int kg_measure_flow_white(kg_measure_flow *m, kg_err *err);
int kg_measure_flow_sample(kg_measure_flow *m, const char *id, kg_spectrum *out, kg_err *err);
int kg_measure_flow_write(const kg_measure_flow *m, const char *path, kg_patchset *ps,
                          kg_err *err);
/* The guided chart into out (what is measured so far in out.partial after each patch;
 * resume continues from it). 0 written, 1 stopped by the operator, else an error. */
int kg_measure_flow_chart(kg_measure_flow *m, const kg_patch_list *pl, const char *out,
                          int resume, int check_white, kg_err *err);


/* ==== The exposure helper's chart measure (chart_level.c) ===========================
 * kg_capture_options.measure of `kogei acquire --exposure auto --layout L` and the
 * console: the level of the brightest sampled patch of the chart found in the frame;
 * KG_ENOENT when there is none. user: a kg_chart_level. */
typedef struct kg_chart_level {
	const kg_chart_layout *layout;
	kg_chart_detect_options opt;
} kg_chart_level;
int kg_chart_brightest_patch(void *user, const kg_image *frame, double *level, kg_err *err);

#endif
