/* A static 3-d kd-tree over float points (median splits on the widest box
 * side, leaves of a few points) with per-node labels: a node whose points
 * all carry one label stores it, so a query for the nearest point of another
 * label skips whole subtrees of its own (Boruvka-style Euclidean spanning
 * forests, March, Ram and Gray 2010, "Fast Euclidean minimum spanning tree").
 * Cost does not depend on the empty space between points: build O(n log n),
 * relabel O(n), a query about O(log n) plus the boundary it must look past. */
#ifndef SYLVA_KDTREE_H
#define SYLVA_KDTREE_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    float lo[3], hi[3];
    uint32_t begin, end; /* into order */
    int32_t left, right; /* children, -1 for a leaf */
    uint32_t label;      /* the one label of all its points, SY_KD_MIXED otherwise */
} sy_kd_node;

#define SY_KD_MIXED UINT32_MAX

typedef struct {
    const float *xyz; /* not owned: 3 floats a point */
    size_t n;
    uint32_t *order; /* point indices, leaf by leaf */
    sy_kd_node *node;
    size_t n_nodes;
    const uint32_t *label; /* per point, set by sy_kdtree_relabel */
} sy_kdtree;

/* Builds the tree over xyz (kept by reference). */
sy_code sy_kdtree_build(sy_kdtree *t, const float *xyz, size_t n, sy_error *err);
void sy_kdtree_free(sy_kdtree *t);

/* Takes label (n entries, kept by reference, any value but SY_KD_MIXED) and
 * recomputes every node's label bottom-up. */
void sy_kdtree_relabel(sy_kdtree *t, const uint32_t *label);

/* The nearest point to q whose label differs from own, closer than
 * sqrt(*best_d2) (INFINITY: anywhere); ties go to the lower index. Updates
 * *best_d2 and *best_j when it finds one. Reads only: safe from many threads. */
void sy_kdtree_nearest_foreign(const sy_kdtree *t, const float q[3], uint32_t own, double *best_d2,
                               uint32_t *best_j);

#ifdef __cplusplus
}
#endif

#endif
