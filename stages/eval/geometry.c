#include "geometry.h"
#include "stages/core/vec3.h"

#include <math.h>
#include <string.h>

#define dot3 sy_v3_dot
#define sub3 sy_v3_sub
static double dist3(const double a[3], const double b[3])
{
    double d[3];
    sub3(d, a, b);
    return sqrt(dot3(d, d));
}

double sy_point_segment_distance(const double p[3], const double a[3], const double b[3], double *t)
{
    double ab[3], ap[3];
    sub3(ab, b, a);
    sub3(ap, p, a);
    double len2 = dot3(ab, ab), s = len2 > 0 ? dot3(ap, ab) / len2 : 0;
    s = s < 0 ? 0 : s > 1 ? 1 : s;
    if (t) *t = s;
    double c[3] = {a[0] + s * ab[0], a[1] + s * ab[1], a[2] + s * ab[2]};
    return dist3(p, c);
}

/* Ericson, Real-Time Collision Detection 5.1.5: the closest point by Voronoi
 * region of the triangle, exact for degenerate triangles too. */
double sy_point_triangle_distance(const double p[3], const double a[3], const double b[3], const double c[3],
                                  double closest[3])
{
    double ab[3], ac[3], ap[3], bp[3], cp[3], q[3];
    sub3(ab, b, a);
    sub3(ac, c, a);
    sub3(ap, p, a);
    double d1 = dot3(ab, ap), d2 = dot3(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        memcpy(q, a, sizeof q);
        goto done;
    }
    sub3(bp, p, b);
    double d3 = dot3(ab, bp), d4 = dot3(ac, bp);
    if (d3 >= 0 && d4 <= d3) {
        memcpy(q, b, sizeof q);
        goto done;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        double v = d1 / (d1 - d3);
        for (int k = 0; k < 3; k++) q[k] = a[k] + v * ab[k];
        goto done;
    }
    sub3(cp, p, c);
    double d5 = dot3(ab, cp), d6 = dot3(ac, cp);
    if (d6 >= 0 && d5 <= d6) {
        memcpy(q, c, sizeof q);
        goto done;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        double w = d2 / (d2 - d6);
        for (int k = 0; k < 3; k++) q[k] = a[k] + w * ac[k];
        goto done;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int k = 0; k < 3; k++) q[k] = b[k] + w * (c[k] - b[k]);
        goto done;
    }
    {
        double denom = va + vb + vc;
        if (!(fabs(denom) > 0)) { /* zero-area triangle: nearest of its edges */
            double best = sy_point_segment_distance(p, a, b, NULL), t;
            const double *e[3][2] = {{a, b}, {b, c}, {a, c}};
            int bi = 0;
            for (int i = 1; i < 3; i++) {
                double d = sy_point_segment_distance(p, e[i][0], e[i][1], NULL);
                if (d < best) best = d, bi = i;
            }
            sy_point_segment_distance(p, e[bi][0], e[bi][1], &t);
            for (int k = 0; k < 3; k++) q[k] = e[bi][0][k] + t * (e[bi][1][k] - e[bi][0][k]);
            goto done;
        }
        double v = vb / denom, w = vc / denom;
        for (int k = 0; k < 3; k++) q[k] = a[k] + ab[k] * v + ac[k] * w;
    }
done:
    if (closest) memcpy(closest, q, sizeof q);
    return dist3(p, q);
}

/* 2D distance from (x, y) to the segment (x0, y0)-(x1, y1). */
static double seg2(double x, double y, double x0, double y0, double x1, double y1)
{
    double dx = x1 - x0, dy = y1 - y0, l2 = dx * dx + dy * dy;
    double t = l2 > 0 ? ((x - x0) * dx + (y - y0) * dy) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double ex = x - (x0 + t * dx), ey = y - (y0 + t * dy);
    return sqrt(ex * ex + ey * ey);
}

/* The cone is a surface of revolution, so the nearest surface point lies in
 * p's meridian half-plane: there the surface is three segments in (axial t,
 * radial rho) coordinates, the lateral profile and the two end-disc radii. */
double sy_point_cone_distance(const double p[3], const double a[3], double ra, const double b[3], double rb)
{
    double ab[3], ap[3];
    sub3(ab, b, a);
    sub3(ap, p, a);
    double len = sqrt(dot3(ab, ab));
    if (!(len > 0)) { /* degenerate axis: a disc of the larger radius */
        double r = ra > rb ? ra : rb, h = 0, rho2 = dot3(ap, ap);
        double rho = sqrt(rho2);
        return seg2(h, rho, 0, 0, 0, r);
    }
    double t = dot3(ap, ab) / len;
    double rho2 = dot3(ap, ap) - t * t;
    double rho = rho2 > 0 ? sqrt(rho2) : 0;
    double d = seg2(t, rho, 0, ra, len, rb);
    double d0 = seg2(t, rho, 0, 0, 0, ra), d1 = seg2(t, rho, len, 0, len, rb);
    if (d0 < d) d = d0;
    if (d1 < d) d = d1;
    return d;
}
