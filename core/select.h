/* Order statistics of float arrays by selection. */
#ifndef KG_SELECT_H
#define KG_SELECT_H

#include <stddef.h>

/* The k-th smallest of v[0..n) (0-based, k < n): v is rearranged so that v[k] holds
 * it, with no larger value before it and no smaller one after (Hoare's selection with
 * a median-of-three pivot). Returns v[k]. v must hold no NaN. */
float kg_select_kth(float *v, size_t n, size_t k);

#endif
