/* qsort comparators for plain arrays of numbers, ascending: the ones every
 * stage wrote for itself. Unordered pairs (a NaN) compare equal, as those
 * copies did, so a sort with them orders exactly as before. */
#ifndef SYLVA_CORE_SORT_H
#define SYLVA_CORE_SORT_H

#ifdef __cplusplus
extern "C" {
#endif

int sy_cmp_double(const void *a, const void *b);
int sy_cmp_float(const void *a, const void *b);
int sy_cmp_u64(const void *a, const void *b);
int sy_cmp_u32(const void *a, const void *b);

#ifdef __cplusplus
}
#endif

#endif
