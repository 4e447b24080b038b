/* qsort comparators for plain arrays of numbers, ascending: the ones every
 * stage wrote for itself. Unordered pairs (a NaN) compare equal, as those
 * copies did, so a sort with them orders exactly as before. */
#ifndef SYLVA_CORE_SORT_H
#define SYLVA_CORE_SORT_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

int sy_cmp_double(const void *a, const void *b);
int sy_cmp_float(const void *a, const void *b);
int sy_cmp_u64(const void *a, const void *b);
int sy_cmp_u32(const void *a, const void *b);

/* The k-th smallest of v[0..n) (0-based, k < n), left at v[k] with nothing
 * larger before it and nothing smaller after it, as C++'s nth_element:
 * the sorted array's v[k] in expected O(n) instead of a whole sort (a
 * percentile of a few million samples). NaNs are not ordered. */
double sy_select_double(double *v, size_t n, size_t k);
/* The q-quantile of v[0..n) (0 <= q <= 1) interpolated between the sorted
 * array's ranks floor(q (n - 1)) and the next, as a sort would give it;
 * reorders v. NaN for n = 0. */
double sy_quantile_double(double *v, size_t n, double q);

#ifdef __cplusplus
}
#endif

#endif
