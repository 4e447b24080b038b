#include "stages/core/array.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

sy_code sy_array_reserve(void *items_ptr, size_t *cap, size_t need, size_t elem, size_t min_cap, sy_error *err,
                         const char *what)
{
    if (need <= *cap) return SY_OK;
    size_t want = *cap ? *cap : (min_cap ? min_cap : 1);
    while (want < need) {
        if (want > SIZE_MAX / 2) {
            want = need;
            break;
        }
        want *= 2;
    }
    if (elem && want > SIZE_MAX / elem)
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory for %zu elements", what, need);
    void *old;
    memcpy(&old, items_ptr, sizeof old);
    size_t bytes = want * elem;
    void *grown = realloc(old, bytes ? bytes : 1);
    if (!grown) return sy_fail(err, SY_EINTERNAL, "%s: out of memory for %zu elements", what, want);
    memcpy(items_ptr, &grown, sizeof grown);
    *cap = want;
    return SY_OK;
}
