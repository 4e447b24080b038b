/* Exact distances (point-segment, point-triangle, point-truncated-cone
 * surface), ray-triangle crossing, and a bounding volume hierarchy answering
 * exact nearest-primitive queries at any distance, shared by the metrics. */
#ifndef SYLVA_EVAL_GEOMETRY_H
#define SYLVA_EVAL_GEOMETRY_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/status.h"

/* Distance from p to segment ab; *t (if not NULL) the parameter in [0,1] of
 * the closest point a + t (b - a). */
double sy_point_segment_distance(const double p[3], const double a[3], const double b[3], double *t);

/* Distance from p to triangle abc (closest point in closest if not NULL). */
double sy_point_triangle_distance(const double p[3], const double a[3], const double b[3], const double c[3],
                                  double closest[3]);

/* Distance from p to the surface of the truncated cone with axis a->b and
 * radii ra at a, rb at b: lateral surface and both end discs. A point inside
 * gets its (positive) distance to that surface. */
double sy_point_cone_distance(const double p[3], const double a[3], double ra, const double b[3], double rb);

/* 1 when the ray o + s d (s > 0) crosses triangle abc. */
int sy_ray_hits_triangle(const double o[3], const double d[3], const double a[3], const double b[3], const double c[3]);

typedef struct {
    double lo[3], hi[3];
} sy_box;

typedef struct {
    sy_box box;
    uint32_t first; /* leaf: first index into prims; inner: left child (right = first + 1) */
    uint32_t count; /* leaf: primitive count; inner: 0 */
} sy_bvh_node;

typedef struct {
    size_t n_nodes;
    sy_bvh_node *nodes;
    uint32_t *prims; /* primitive indices, leaves own contiguous runs */
    size_t n_prims;
} sy_bvh;

/* Builds over n boxes (median split on the longest centroid axis). */
sy_code sy_bvh_build(sy_bvh *b, const sy_box *boxes, size_t n, sy_error *err);
void sy_bvh_free(sy_bvh *b);

/* Distance from q to primitive prim (>= the distance to its box). */
typedef double (*sy_prim_distance)(const void *ctx, uint32_t prim, const double q[3]);
/* Nearest primitive within max_dist (use INFINITY for none): returns its
 * index and sets *dist, or returns UINT32_MAX (*dist = INFINITY). hint, a
 * primitive likely to be near (the previous query's answer), or UINT32_MAX,
 * only speeds the search up; the answer is exact either way. */
uint32_t sy_bvh_nearest(const sy_bvh *b, const double q[3], double max_dist, sy_prim_distance fn, const void *ctx,
                        uint32_t hint, double *dist);
/* 1 when some primitive lies within r of q (stops at the first found). */
int sy_bvh_any_within(const sy_bvh *b, const double q[3], double r, sy_prim_distance fn, const void *ctx);

/* 1 when the ray o + s d (s > 0) crosses primitive prim. */
typedef int (*sy_prim_ray)(const void *ctx, uint32_t prim, const double o[3], const double d[3]);
/* Number of primitives the ray crosses. */
size_t sy_bvh_ray_count(const sy_bvh *b, const double o[3], const double d[3], sy_prim_ray fn, const void *ctx);

#endif
