/* placeholder: being written */
#ifndef KG_OPTICS_H
#define KG_OPTICS_H
#include "kg_core.h"
#endif
