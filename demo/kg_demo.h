/* demo/: `kogei demo` (docs/demo.md, docs/architecture.md). Built on pipeline/;
 * nothing below it includes this header. */
#ifndef KG_DEMO_H
#define KG_DEMO_H

#include "kg_core.h"

/* `kogei demo`: the bundled session (fixtures/demo/session) replayed into a lab and a
 * site session under dir, the chart measured with the simulated spectrophotometer,
 * then kg_process_run on both, and the demo's comparisons with the simulation's truth
 * (summary.md, figures, renders of Fig. 13). Progress on standard output. */
int kg_demo_run(const char *dir, kg_err *err);

#endif
