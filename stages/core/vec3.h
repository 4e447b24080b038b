/* 3-vectors of doubles as plain arrays: the handful of operations every
 * geometric stage needs, header-only so they inline. Results may alias
 * inputs. */
#ifndef SYLVA_VEC3_H
#define SYLVA_VEC3_H

#include <math.h>

#ifdef __cplusplus
extern "C" {
#endif

static inline double sy_v3_dot(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static inline void sy_v3_sub(double r[3], const double a[3], const double b[3])
{
    r[0] = a[0] - b[0];
    r[1] = a[1] - b[1];
    r[2] = a[2] - b[2];
}

/* r = a x b (r must not alias a or b). */
static inline void sy_v3_cross(double r[3], const double a[3], const double b[3])
{
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}

static inline double sy_v3_len(const double v[3]) { return sqrt(sy_v3_dot(v, v)); }

static inline double sy_v3_dist(const double a[3], const double b[3])
{
    double d[3];
    sy_v3_sub(d, a, b);
    return sy_v3_len(d);
}

/* Squared distance of two float points, in double (a kd-tree's or a point
 * list's own coordinates). */
static inline double sy_v3f_dist2(const float a[3], const float b[3])
{
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return dx * dx + dy * dy + dz * dz;
}

/* Scales v to unit length; a zero vector stays zero. Returns the old length. */
static inline double sy_v3_normalize(double v[3])
{
    double l = sy_v3_len(v);
    if (l > 0)
        for (int i = 0; i < 3; i++) v[i] /= l;
    return l;
}

/* A unit basis e1, e2 across unit direction d (any vector not parallel to
 * d, crossed with it twice): a twig's radial directions. */
static inline void sy_v3_basis_across(const double d[3], double e1[3], double e2[3])
{
    const double helper[3] = {fabs(d[2]) < 0.9 ? 0 : 1, 0, fabs(d[2]) < 0.9 ? 1 : 0};
    sy_v3_cross(e1, d, helper);
    sy_v3_normalize(e1);
    sy_v3_cross(e2, d, e1);
}

/* A leaf card's frame for its unit axis Y: its normal Z faces the sky as
 * far as Y allows (where Y stands within about 0.06 degrees of vertical,
 * fallback made orthogonal to Y instead), X = Y x Z. */
static inline void sy_v3_card_frame(const double Y[3], const double fallback[3], double X[3], double Z[3])
{
    const double up[3] = {0, 0, 1};
    double dot = Y[2];
    for (int k = 0; k < 3; k++) Z[k] = up[k] - dot * Y[k];
    if (sy_v3_len(Z) < 1e-3) {
        dot = sy_v3_dot(fallback, Y);
        for (int k = 0; k < 3; k++) Z[k] = fallback[k] - dot * Y[k];
    }
    sy_v3_normalize(Z);
    sy_v3_cross(X, Y, Z);
}

#ifdef __cplusplus
}
#endif

#endif
