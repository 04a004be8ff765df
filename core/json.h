/* placeholder: being written */
#ifndef KG_JSON_H
#define KG_JSON_H
#endif
