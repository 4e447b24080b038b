/* The one growth routine for hand-grown arrays (as sds and Redis keep one):
 * capacity doubles from a minimum, the byte count is checked for overflow
 * and a failure leaves the array as it was. */
#ifndef SYLVA_ARRAY_H
#define SYLVA_ARRAY_H

#include <stddef.h>

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Makes room for at least need elements of elem bytes in the array whose
 * pointer is at items_ptr (a T **, passed as void *) and whose capacity is
 * *cap: doubles *cap (starting at min_cap) until it holds need, then
 * reallocates. Nothing happens when need <= *cap. On overflow or out of
 * memory: SY_EINTERNAL, err (may be NULL) says "<what>: out of memory for
 * N elements", *items_ptr and *cap unchanged. */
sy_code sy_array_reserve(void *items_ptr, size_t *cap, size_t need, size_t elem, size_t min_cap, sy_error *err,
                         const char *what);

#ifdef __cplusplus
}
#endif

#endif
