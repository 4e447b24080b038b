/* A bounding volume hierarchy over axis-aligned boxes, shared by the scanner
 * (closest ray hits) and the evaluation (nearest primitives, inside tests).
 * The caller owns the primitives and answers exact per-primitive questions
 * through callbacks; the BVH only prunes. Build: binned SAH, deterministic
 * (the same boxes give the same tree on any thread count). Nodes hold float
 * boxes relative to a double origin, widened so that no rounding ever cuts a
 * primitive off its box: large (georeferenced) coordinates keep full
 * precision and the node stays 32 bytes. */
#ifndef SYLVA_BVH_H
#define SYLVA_BVH_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double lo[3], hi[3];
} sy_box;

void sy_box_empty(sy_box *b);
void sy_box_add_point(sy_box *b, const double p[3]);

typedef struct {
    float lo[3], hi[3]; /* relative to sy_bvh.origin */
    uint32_t start;     /* leaf: first slot in order; inner: index of the right child (left is next) */
    uint32_t count;     /* primitives in a leaf, 0 for inner nodes */
} sy_bvh_node;

typedef struct {
    sy_bvh_node *nodes; /* depth first, the root at 0 */
    size_t n_nodes;
    uint32_t *order; /* leaf slot -> caller's primitive index */
    size_t n_prims;
    double origin[3];
} sy_bvh;

/* Builds over n boxes (16 SAH bins, leaves of 1 to 16, median splits below
 * depth 40 so the depth stays bounded). */
sy_code sy_bvh_build(sy_bvh *b, const sy_box *boxes, size_t n, sy_error *err);
void sy_bvh_free(sy_bvh *b);
/* Rearranges the caller's n_prims items (item_size bytes each) into leaf
 * order, so each leaf's primitives lie together in memory; from then on the
 * queries report positions in the rearranged array. */
sy_code sy_bvh_reorder(sy_bvh *b, void *items, size_t item_size, sy_error *err);
/* The box of everything (empty when there is nothing). */
void sy_bvh_bounds(const sy_bvh *b, sy_box *box);

/* ---------------------------------------------------------------- rays */

/* 1 when the ray o + t d crosses primitive prim at some t < tmax (the lower
 * limit is the callback's choice), setting *t. */
typedef int (*sy_bvh_ray_fn)(const void *ctx, uint32_t prim, const double o[3], const double d[3], double tmax,
                             double *t);

typedef struct {
    double t;
    uint32_t prim;
} sy_hit;

/* Closest hit below tmax: iterative, near child first, skipping every box
 * beyond the best hit so far. Returns 1 and fills *hit, else 0. Of hits at
 * the very same t the first one tested wins. */
int sy_bvh_closest(const sy_bvh *b, const double o[3], const double d[3], double tmax, sy_bvh_ray_fn fn,
                   const void *ctx, sy_hit *hit);
/* The same by testing every primitive in index order, for tests. */
int sy_bvh_closest_brute(const sy_bvh *b, const double o[3], const double d[3], double tmax, sy_bvh_ray_fn fn,
                         const void *ctx, sy_hit *hit);
/* Number of primitives the ray crosses (fn called with tmax = INFINITY):
 * odd for a point inside a closed surface. */
size_t sy_bvh_ray_count(const sy_bvh *b, const double o[3], const double d[3], sy_bvh_ray_fn fn, const void *ctx);

/* Moller-Trumbore: 1 when the line o + t d crosses triangle abc, setting *t
 * (of either sign). closed_edges = 1 counts the edges in, so neighbouring
 * triangles leave no crack for a closest-hit search; 0 makes u and u + v
 * half-open, so that parity counting sees a shared edge no more than once
 * for most orientations. Inline: airborne scans are mostly ground-triangle
 * tests, and an out-of-line call costs them ~4%. */
static inline int sy_ray_triangle(const double o[3], const double d[3], const double a[3], const double b[3],
                                  const double c[3], int closed_edges, double *t)
{
    double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double pv[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
    double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
    /* Rays in the plane and degenerate triangles: no crossing. */
    if (fabs(det) < 1e-14) return 0;
    double inv = 1.0 / det;
    double tv[3] = {o[0] - a[0], o[1] - a[1], o[2] - a[2]};
    double u = (tv[0] * pv[0] + tv[1] * pv[1] + tv[2] * pv[2]) * inv;
    if (u < 0 || u > 1 || (!closed_edges && u == 1)) return 0;
    double qv[3] = {tv[1] * e1[2] - tv[2] * e1[1], tv[2] * e1[0] - tv[0] * e1[2], tv[0] * e1[1] - tv[1] * e1[0]};
    double v = (d[0] * qv[0] + d[1] * qv[1] + d[2] * qv[2]) * inv;
    if (v < 0 || u + v > 1 || (!closed_edges && u + v == 1)) return 0;
    *t = (e2[0] * qv[0] + e2[1] * qv[1] + e2[2] * qv[2]) * inv;
    return 1;
}

/* --------------------------------------------------------------- points */

/* Distance from q to primitive prim (>= the distance to its box). */
typedef double (*sy_bvh_distance_fn)(const void *ctx, uint32_t prim, const double q[3]);

/* Nearest primitive within max_dist (INFINITY for no limit): returns its
 * index and sets *dist, or returns UINT32_MAX (*dist = INFINITY). hint, a
 * primitive likely to be near (the previous query's answer), or UINT32_MAX,
 * only speeds the search up: ties go to the lower index, so the answer does
 * not depend on it. */
uint32_t sy_bvh_nearest(const sy_bvh *b, const double q[3], double max_dist, sy_bvh_distance_fn fn, const void *ctx,
                        uint32_t hint, double *dist);
/* 1 when some primitive lies within r of q (stops at the first found). */
int sy_bvh_any_within(const sy_bvh *b, const double q[3], double r, sy_bvh_distance_fn fn, const void *ctx);

#ifdef __cplusplus
}
#endif

#endif
