/* Private to pipeline/collection*.c: OUT's layout, the plan and the entries' states
 * (kg_pipeline.h, "A collection"). */
#ifndef KG_COLLECTION_PRIVATE_H
#define KG_COLLECTION_PRIVATE_H

#include <jansson.h>
#include <stdio.h>

#include "kg_pipeline.h"

#define COLL_PLAN_FORMAT "kogei-collection-plan/1"
#define COLL_ENTRY_FORMAT "kogei-collection-entry/1"
#define COLL_FORMAT "kogei-collection/1"
#define COLL_NAME_MAX 128 /* an entry's name: a folder name of at most 127 bytes */

typedef enum coll_status { COLL_PENDING, COLL_DONE, COLL_FAILED } coll_status;

/* OUT/.collection/<rel> (rel may be NULL: the folder), newly allocated. */
char *coll_path(const char *out, const char *rel);
/* OUT/.collection/entries/NAME.json, logs/NAME.log, thumbs/NAME. */
char *coll_state_path(const char *out, const char *name);
char *coll_log_path(const char *out, const char *name);
char *coll_thumb_dir(const char *out, const char *name);

/* The plan of the last run (OUT/.collection/plan.json). KG_EINVAL naming the file when
 * there is none ("not a collection") or it is malformed. */
int coll_plan_load(const char *out, json_t **plan, kg_err *err);
/* Read and check the list into a plan (every bad row a line on problems). */
int coll_plan_make(const kg_collection_options *o, const char *out_abs, json_t **plan,
                   kg_err *err);

/* The status of a plan's entry from its state file: *state (new reference, or NULL) is
 * the state read when it records the entry's current key. */
coll_status coll_entry_status(const char *out, const json_t *entry, json_t **state);
/* Counts over the plan. */
void coll_count(const char *out, const json_t *plan, kg_collection_counts *c);

/* Now as "YYYY-MM-DDTHH:MM:SSZ". */
void coll_now(char buf[32]);
/* A JSON string of s (UTF-8 checked), NULL on failure with err set. */
json_t *coll_text(const char *what, const char *s, kg_err *err);

/* OUT/collection-manifest.json from the record (collection_iiif.c): a IIIF Collection
 * of the done entries' object manifests, ids under the plan's files_base or relative. */
int coll_iiif_write(const char *out, const json_t *plan, const json_t *record, kg_err *err);
/* base + "/" + name (base's trailing '/' dropped) into *url: 0, or -1 out of memory. */
int coll_url_join(const char *base, const char *name, char **url);

/* index.html (collection_html.c). */
int coll_html_write(const char *out, const json_t *record, kg_err *err);
/* Thumbnails of a done entry's objects (best effort). */
void coll_thumbs_make(const char *out, const char *name);

/* Engines (collection_local.c, collection_slurm.c): run the entries at indices
 * run[0..nrun-1] of the plan. */
int coll_run_local(const kg_collection_options *o, const char *out, const json_t *plan,
                   const int *run, int nrun, kg_collection_counts *c, int *signal_out,
                   kg_err *err);
int coll_run_slurm(const kg_collection_options *o, const char *out, const json_t *plan,
                   const int *run, int nrun, kg_collection_counts *c, int *signal_out,
                   kg_err *err);
/* Slurm: a job recorded in OUT/.slurm/job.json that squeue still lists: 1 (its id in
 * job), 0 none, -1 squeue failed. */
int coll_slurm_active(const char *out, char job[64], int *tasks);

/* The kogei executable: self, else /proc/self/exe resolved (newly allocated). */
char *coll_self(const char *self);

/* Signals caught while a run waits: SIGINT, SIGTERM, SIGHUP (not when ignored). */
void coll_catch_signals(void);
int coll_signal(void);

/* The progress line: done, failed, remaining and the estimated time left. */
void coll_progress(FILE *fp, const kg_collection_counts *c, int remaining, double elapsed,
                   int ran_done, int jobs, const char *what);

#endif
