/* Exact distances (point-truncated-cone surface; point-segment and
 * point-triangle come from stages/core/geometry.h) shared by the metrics, which index their primitives with the
 * core BVH (stages/core/bvh.h). */
#ifndef SYLVA_EVAL_GEOMETRY_H
#define SYLVA_EVAL_GEOMETRY_H

#include "stages/core/bvh.h"
#include "stages/core/geometry.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Distance from p to the surface of the truncated cone with axis a->b and
 * radii ra at a, rb at b: lateral surface and both end discs. A point inside
 * gets its (positive) distance to that surface. */
double sy_point_cone_distance(const double p[3], const double a[3], double ra, const double b[3], double rb);

#ifdef __cplusplus
}
#endif

#endif
