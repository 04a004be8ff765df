/* placeholder: being written */
#ifndef KG_COLORIMETRY_H
#define KG_COLORIMETRY_H
#endif
