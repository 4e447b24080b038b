/* Exact point-to-primitive distances shared by the stages that test points
 * against hulls (clusters) and score models (eval). */
#include "stages/core/geometry.h"

#include <math.h>
#include <string.h>

#include "stages/core/vec3.h"

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

void sy_sym3_eigen(const double c[6], double l[3], double v[9])
{
    double a[3][3] = {{c[0], c[1], c[2]}, {c[1], c[3], c[4]}, {c[2], c[4], c[5]}};
    double e[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (int sweep = 0; sweep < 24; sweep++) {
        double off = fabs(a[0][1]) + fabs(a[0][2]) + fabs(a[1][2]);
        if (off < 1e-18) break;
        for (int p = 0; p < 2; p++)
            for (int q = p + 1; q < 3; q++) {
                if (fabs(a[p][q]) < 1e-300) continue;
                double th = (a[q][q] - a[p][p]) / (2 * a[p][q]);
                double t = (th >= 0 ? 1 : -1) / (fabs(th) + sqrt(th * th + 1));
                double cs = 1 / sqrt(t * t + 1), sn = t * cs;
                for (int k = 0; k < 3; k++) {
                    double akp = a[k][p], akq = a[k][q];
                    a[k][p] = cs * akp - sn * akq;
                    a[k][q] = sn * akp + cs * akq;
                }
                for (int k = 0; k < 3; k++) {
                    double apk = a[p][k], aqk = a[q][k];
                    a[p][k] = cs * apk - sn * aqk;
                    a[q][k] = sn * apk + cs * aqk;
                }
                for (int k = 0; k < 3; k++) {
                    double ekp = e[k][p], ekq = e[k][q];
                    e[k][p] = cs * ekp - sn * ekq;
                    e[k][q] = sn * ekp + cs * ekq;
                }
            }
    }
    int ord[3] = {0, 1, 2};
    for (int i = 0; i < 2; i++)
        for (int j = i + 1; j < 3; j++)
            if (a[ord[j]][ord[j]] > a[ord[i]][ord[i]]) {
                int t = ord[i];
                ord[i] = ord[j];
                ord[j] = t;
            }
    for (int i = 0; i < 3; i++) {
        l[i] = a[ord[i]][ord[i]] > 0 ? a[ord[i]][ord[i]] : 0;
        for (int k = 0; k < 3; k++) v[k * 3 + i] = e[k][ord[i]];
    }
}
