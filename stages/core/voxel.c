#include "voxel.h"

#include <math.h>
#include <stdlib.h>

uint64_t sy_voxel_key(const float p[3], const float lo[3], double size)
{
    uint64_t key = 0;
    for (int k = 0; k < 3; k++) {
        double c = floor((p[k] - lo[k]) / size);
        if (!(c >= 0)) c = 0;
        if (c > SY_VOXEL_AXIS_CELLS - 1) c = SY_VOXEL_AXIS_CELLS - 1;
        key = key << SY_VOXEL_BITS | (uint64_t)c;
    }
    return key;
}

static int cmp_entry(const void *a, const void *b)
{
    const sy_voxel_entry *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return (x->index > y->index) - (x->index < y->index);
}

void sy_voxel_sort(const float *xyz, size_t n, const float lo[3], double size, sy_voxel_entry *e)
{
    for (size_t i = 0; i < n; i++) {
        e[i].key = sy_voxel_key(xyz + 3 * i, lo, size);
        e[i].index = i;
    }
    qsort(e, n, sizeof *e, cmp_entry);
}
