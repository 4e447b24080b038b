/* Hermite curves and rotation-minimising frames for the branch tubes. */
#include <math.h>

#include "mesh_internal.h"

void sy_hermite(const float p0[3], const float m0[3], const float p1[3], const float m1[3], float t, float pos[3],
                float der[3])
{
    float t2 = t * t, t3 = t2 * t;
    float h0 = 2 * t3 - 3 * t2 + 1, h1 = t3 - 2 * t2 + t, h2 = -2 * t3 + 3 * t2, h3 = t3 - t2;
    float d0 = 6 * t2 - 6 * t, d1 = 3 * t2 - 4 * t + 1, d2 = -6 * t2 + 6 * t, d3 = 3 * t2 - 2 * t;
    for (int k = 0; k < 3; k++) {
        pos[k] = h0 * p0[k] + h1 * m0[k] + h2 * p1[k] + h3 * m1[k];
        der[k] = d0 * p0[k] + d1 * m0[k] + d2 * p1[k] + d3 * m1[k];
    }
}

/* Removes from r its component along unit t and renormalises; falls back to
 * any unit vector orthogonal to t when r is (nearly) parallel to t. */
static void orthonormalize_against(float r[3], const float t[3])
{
    float d = sy_dot3(r, t);
    for (int k = 0; k < 3; k++) r[k] -= d * t[k];
    if (sy_normalize3(r) > 1e-6f) return;
    float axis[3] = {0, 0, 0};
    axis[fabsf(t[0]) < 0.6f ? 0 : fabsf(t[1]) < 0.6f ? 1 : 2] = 1;
    sy_cross3(t, axis, r);
    sy_normalize3(r);
}

void sy_rmf(size_t n, const float *x, const float *t, const float r0[3], float *r)
{
    if (n == 0) return;
    for (int k = 0; k < 3; k++) r[k] = r0[k];
    orthonormalize_against(r, t);
    for (size_t i = 0; i + 1 < n; i++) {
        const float *xi = x + 3 * i, *xj = x + 3 * i + 3, *ti = t + 3 * i, *tj = t + 3 * i + 3;
        const float *ri = r + 3 * i;
        float *rj = r + 3 * i + 3;
        float v1[3] = {xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]};
        float c1 = sy_dot3(v1, v1);
        float rl[3], tl[3];
        if (c1 < 1e-20f) {
            /* Coincident points: no reflection plane, and a single reflection
             * would mirror the frame. Projecting onto the new normal plane is
             * the minimal rotation to first order. */
            for (int k = 0; k < 3; k++) rj[k] = ri[k];
            orthonormalize_against(rj, tj);
            continue;
        } else {
            float a = 2 * sy_dot3(v1, ri) / c1, b = 2 * sy_dot3(v1, ti) / c1;
            for (int k = 0; k < 3; k++) {
                rl[k] = ri[k] - a * v1[k];
                tl[k] = ti[k] - b * v1[k];
            }
        }
        float v2[3] = {tj[0] - tl[0], tj[1] - tl[1], tj[2] - tl[2]};
        float c2 = sy_dot3(v2, v2);
        if (c2 < 1e-20f) {
            for (int k = 0; k < 3; k++) rj[k] = rl[k];
        } else {
            float a = 2 * sy_dot3(v2, rl) / c2;
            for (int k = 0; k < 3; k++) rj[k] = rl[k] - a * v2[k];
        }
        /* Float round-off accumulates over thousands of rings; re-projecting
         * keeps each frame exactly orthonormal without adding twist. */
        orthonormalize_against(rj, tj);
    }
}
