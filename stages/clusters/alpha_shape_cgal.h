/* The only CGAL translation unit: 3-D alpha shapes (Alpha_shape_3 over a
 * Delaunay_triangulation_3 with Fast_location, REGULARIZED mode).
 *
 * Convention: CGAL's alpha is a SQUARED radius. alpha_min is the smallest
 * alpha for which the shape is one solid component holding every point on its
 * boundary or inside (find_optimal_alpha(1)); the shape is built at
 * alpha = alpha_scale * alpha_min (so a scale of 5 grows the carving ball's
 * radius by sqrt(5) ~ 2.24). */
#ifndef SYLVA_ALPHA_SHAPE_CGAL_H
#define SYLVA_ALPHA_SHAPE_CGAL_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    float *verts;     /* 3 * n_verts, malloc'd */
    size_t n_verts;
    uint32_t *tris;   /* 3 * n_tris, malloc'd, counter-clockwise seen from outside */
    size_t n_tris;
    double alpha_min; /* squared radius */
    double alpha;     /* squared radius used */
} sy_alpha_mesh;

/* Boundary of the regularized alpha shape of pts (3n floats): the REGULAR
 * facets, oriented outward. alpha_scale <= 0 asks for the convex hull (an
 * infinite alpha). Returns SY_OK; SY_EINPUT when the points span fewer than
 * three dimensions (or no alpha holds them in one solid), SY_EINTERNAL on a
 * CGAL failure or out of memory; err says which. */
sy_code sy_alpha_shape_boundary(const float *pts, size_t n, double alpha_scale, sy_alpha_mesh *out, sy_error *err);

void sy_alpha_mesh_free(sy_alpha_mesh *m);

#ifdef __cplusplus
}
#endif

#endif
