/* The guided spectrometer measurement of `kogei measure` (dark, white, the patches of
 * a chart in order with redo, white again and resume from OUT.partial), shared by the
 * terminal (cli/cmd_measure.c) and the operator's console (cli/console_actions.c):
 * the operator is asked through a callback, messages go to another. */
#ifndef KG_MEASURE_FLOW_H
#define KG_MEASURE_FLOW_H

#include "kg_devices.h"

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

#endif
