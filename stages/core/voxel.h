/* Voxel keys: a point's cell in a grid of cubes of edge size from a low
 * corner, packed 21 bits per axis into one 64-bit key (2^21 cells a side),
 * and points sorted by it so that each voxel's points lie together. What the
 * voxel filter (preprocess) and the classifier's multi-scale subsampling
 * share: sorted keys are sparse, never a dense array over the extent. */
#ifndef SYLVA_CORE_VOXEL_H
#define SYLVA_CORE_VOXEL_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SY_VOXEL_BITS 21
#define SY_VOXEL_AXIS_CELLS (1u << SY_VOXEL_BITS)

typedef struct {
    uint64_t key;
    size_t index; /* of the point */
} sy_voxel_entry;

/* Key of p: per axis floor((p - lo) / size), clamped to [0, 2^21 - 1]; the
 * difference p - lo is taken in float. */
uint64_t sy_voxel_key(const float p[3], const float lo[3], double size);
/* The same key with the difference taken in double, for a corner held in
 * double (the clusters' hull thinning). */
uint64_t sy_voxel_key_d(const double p[3], const double lo[3], double size);
/* e[i] = {key of point i of xyz, i} for the n points, sorted by key and
 * then index: the points of one voxel end up adjacent, ascending. */
void sy_voxel_sort(const float *xyz, size_t n, const float lo[3], double size, sy_voxel_entry *e);
/* Sorts n entries of any 64-bit keys by key and then index (a radix sort for
 * large sets, qsort when small or when its scratch memory cannot be had).
 * The radix sort is stable, so the entries must enter in index order (as
 * every caller fills them) for equal keys to come out by index. */
void sy_voxel_entries_sort(sy_voxel_entry *e, size_t n);

#ifdef __cplusplus
}
#endif

#endif
