/* placeholder: being written */
#ifndef KG_ENVI_H
#define KG_ENVI_H
#endif
