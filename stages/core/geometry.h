/* Exact point-to-primitive distances (Ericson 2005, "Real-Time Collision
 * Detection", 5.1.2 and 5.1.5), in doubles. */
#ifndef SYLVA_CORE_GEOMETRY_H
#define SYLVA_CORE_GEOMETRY_H

#ifdef __cplusplus
extern "C" {
#endif

/* Distance from p to segment ab; *t (if not NULL) the parameter in [0,1] of
 * the closest point a + t (b - a). */
double sy_point_segment_distance(const double p[3], const double a[3], const double b[3], double *t);

/* Distance from p to triangle abc (closest point in closest if not NULL). */
double sy_point_triangle_distance(const double p[3], const double a[3], const double b[3], const double c[3],
                                  double closest[3]);

#ifdef __cplusplus
}
#endif

#endif
