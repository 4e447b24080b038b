#include "geometry.h"
#include "stages/core/vec3.h"

#include <math.h>
#include <string.h>

#define dot3 sy_v3_dot
#define sub3 sy_v3_sub
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
