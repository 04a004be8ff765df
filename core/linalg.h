/* placeholder: being written */
#ifndef KG_LINALG_H
#define KG_LINALG_H
#endif
