/* placeholder: being written */
#ifndef KG_PLOT_H
#define KG_PLOT_H
#endif
