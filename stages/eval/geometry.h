/* Exact distances (point-segment, point-triangle, point-truncated-cone
 * surface) shared by the metrics, which index their primitives with the
 * core BVH (stages/core/bvh.h). */
#ifndef SYLVA_EVAL_GEOMETRY_H
#define SYLVA_EVAL_GEOMETRY_H

#include "stages/core/bvh.h"

#ifdef __cplusplus
extern "C" {
#endif

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

#ifdef __cplusplus
}
#endif

#endif
