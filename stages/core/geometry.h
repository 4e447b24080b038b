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

/* Eigen-decomposition of a symmetric 3x3 matrix given by its upper triangle
 * c = {c00, c01, c02, c11, c12, c22} (a covariance, or a scatter matrix) by
 * cyclic Jacobi rotations (Golub & Van Loan, "Matrix Computations", 8.5):
 * eigenvalues descending in l (negative round-off clamped to 0), unit
 * eigenvectors as the columns of v (v[row * 3 + col]). */
void sy_sym3_eigen(const double c[6], double l[3], double v[9]);

#ifdef __cplusplus
}
#endif

#endif
