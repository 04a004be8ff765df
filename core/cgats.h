/* placeholder: being written */
#ifndef KG_CGATS_H
#define KG_CGATS_H
#endif
