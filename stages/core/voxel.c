#include "voxel.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Appends the cell of offset d (in cells) to key. */
static uint64_t push_cell(uint64_t key, double d)
{
    double c = floor(d);
    if (!(c >= 0)) c = 0;
    if (c > SY_VOXEL_AXIS_CELLS - 1) c = SY_VOXEL_AXIS_CELLS - 1;
    return key << SY_VOXEL_BITS | (uint64_t)c;
}

uint64_t sy_voxel_key(const float p[3], const float lo[3], double size)
{
    uint64_t key = 0;
    for (int k = 0; k < 3; k++) key = push_cell(key, (p[k] - lo[k]) / size);
    return key;
}

uint64_t sy_voxel_key_d(const double p[3], const double lo[3], double size)
{
    uint64_t key = 0;
    for (int k = 0; k < 3; k++) key = push_cell(key, (p[k] - lo[k]) / size);
    return key;
}

static int cmp_entry(const void *a, const void *b)
{
    const sy_voxel_entry *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return (x->index > y->index) - (x->index < y->index);
}

/* Stable LSD radix sort by key, 8 bits a pass, skipping the bytes that do not
 * vary (most of the 63 key bits on one tree); the entries enter in index
 * order, so equal keys stay in index order: the same order as sorting by
 * (key, index). 0 when the scratch buffer cannot be had. */
static int radix_sort(sy_voxel_entry *a, size_t n)
{
    sy_voxel_entry *tmp = malloc(n * sizeof *tmp);
    if (!tmp) return 0;
    sy_voxel_entry *src = a, *dst = tmp;
    for (int shift = 0; shift < 64; shift += 8) {
        size_t count[257] = {0};
        for (size_t i = 0; i < n; i++) count[((src[i].key >> shift) & 0xff) + 1]++;
        int single = 0;
        for (int b = 1; b <= 256; b++) single |= count[b] == n;
        if (single) continue;
        for (int b = 0; b < 256; b++) count[b + 1] += count[b];
        for (size_t i = 0; i < n; i++) dst[count[(src[i].key >> shift) & 0xff]++] = src[i];
        sy_voxel_entry *t = src;
        src = dst;
        dst = t;
    }
    if (src != a) memcpy(a, src, n * sizeof *a);
    free(tmp);
    return 1;
}

void sy_voxel_sort(const float *xyz, size_t n, const float lo[3], double size, sy_voxel_entry *e)
{
    for (size_t i = 0; i < n; i++) {
        e[i].key = sy_voxel_key(xyz + 3 * i, lo, size);
        e[i].index = i;
    }
    sy_voxel_entries_sort(e, n);
}

void sy_voxel_entries_sort(sy_voxel_entry *e, size_t n)
{
    /* Radix for the large sorts (a 100k-point tree: ~10x faster than qsort). */
    if (n < 256 || !radix_sort(e, n)) qsort(e, n, sizeof *e, cmp_entry);
}
