/* placeholder: being written */
#ifndef KG_IMAGE_H
#define KG_IMAGE_H
#endif
