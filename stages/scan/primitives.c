/* Exact ray intersections with the scene's surfaces. Positions are stored as
 * float (scenes span tens of metres) but every intersection is solved in
 * double, so a hit lies on the float-defined surface to well under a micron. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "scan.h"
#include "stages/core/vec3.h"
#include "stages/core/array.h"
#include "stages/core/rng.h"

sy_code sy_prims_push(sy_prims *list, const sy_prim *p, sy_error *err)
{
    sy_code rc = sy_array_reserve(&list->p, &list->cap, list->n + 1, sizeof *list->p, 1024, err, "scene primitives");
    if (rc) return rc;
    list->p[list->n++] = *p;
    return SY_OK;
}

void sy_prims_free(sy_prims *list)
{
    free(list->p);
    memset(list, 0, sizeof *list);
}

static sy_prim blank(int kind)
{
    sy_prim p;
    memset(&p, 0, sizeof p);
    p.kind = (uint8_t)kind;
    p.species_id = -1;
    p.branch_id = -1;
    return p;
}

sy_prim sy_prim_cone(const float a[3], float ra, const float b[3], float rb)
{
    sy_prim p = blank(SY_PRIM_CONE);
    memcpy(p.v, a, 3 * sizeof(float));
    memcpy(p.v + 3, b, 3 * sizeof(float));
    p.v[6] = ra;
    p.v[7] = rb;
    p.material = SY_MAT_WOOD;
    return p;
}

sy_prim sy_prim_quad(const float base[3], const float x_axis[3], const float y_axis[3], float length, float width,
                     int elliptic)
{
    sy_prim p = blank(SY_PRIM_QUAD);
    double n[3] = {(double)x_axis[1] * y_axis[2] - (double)x_axis[2] * y_axis[1],
                   (double)x_axis[2] * y_axis[0] - (double)x_axis[0] * y_axis[2],
                   (double)x_axis[0] * y_axis[1] - (double)x_axis[1] * y_axis[0]};
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (int k = 0; k < 3; k++) {
        p.v[k] = base[k];
        p.v[3 + k] = x_axis[k] * width * 0.5f;
        p.v[6 + k] = y_axis[k] * length;
        p.v[9 + k] = (float)(len > 0 ? n[k] / len : (k == 2));
    }
    p.material = SY_MAT_LEAF;
    p.elliptic = (uint8_t)(elliptic != 0);
    return p;
}

void sy_prim_quad_gaps(sy_prim *quad, double fill)
{
    double open = fill > 0 && fill < 1 ? 1 - fill : 0;
    quad->gaps = (uint8_t)lround(fmin(open * 256, 255));
}

sy_prim sy_prim_tri(const float a[3], const float b[3], const float c[3])
{
    sy_prim p = blank(SY_PRIM_TRI);
    memcpy(p.v, a, 3 * sizeof(float));
    memcpy(p.v + 3, b, 3 * sizeof(float));
    memcpy(p.v + 6, c, 3 * sizeof(float));
    p.material = SY_MAT_GROUND;
    return p;
}

#define dot3 sy_v3_dot

static void load3(const float *f, double d[3])
{
    d[0] = f[0];
    d[1] = f[1];
    d[2] = f[2];
}

/* Cone axis frame: unit axis w, length h, radius slope k = (rb - ra) / h. */
static int cone_frame(const sy_prim *p, double a[3], double w[3], double *h, double *k)
{
    double b[3];
    load3(p->v, a);
    load3(p->v + 3, b);
    for (int i = 0; i < 3; i++) w[i] = b[i] - a[i];
    *h = sqrt(dot3(w, w));
    if (!(*h > 0)) return 0;
    for (int i = 0; i < 3; i++) w[i] /= *h;
    *k = ((double)p->v[7] - p->v[6]) / *h;
    return 1;
}

/* Points x on the cone satisfy |q|^2 - (q.w)^2 = (ra + k q.w)^2 with q = x - a
 * and 0 <= q.w <= h; substituting x = o + t d gives a quadratic in t. */
static int hit_cone(const sy_prim *p, const double o[3], const double d[3], double tmin, double tmax, double *t)
{
    double a[3], w[3], h, k;
    if (!cone_frame(p, a, w, &h, &k)) return 0;
    double oa[3] = {o[0] - a[0], o[1] - a[1], o[2] - a[2]};
    double ra = p->v[6];
    double dw = dot3(d, w), t0 = dot3(oa, w), od = dot3(oa, d);
    double r0 = ra + k * t0;
    double A = dot3(d, d) - dw * dw - k * k * dw * dw;
    double B = 2.0 * (od - t0 * dw - r0 * k * dw);
    double C = dot3(oa, oa) - t0 * t0 - r0 * r0;
    double roots[2];
    int n = 0;
    if (fabs(A) < 1e-12) {
        if (fabs(B) < 1e-300) return 0;
        roots[n++] = -C / B;
    } else {
        double disc = B * B - 4 * A * C;
        if (disc < 0) return 0;
        double sq = sqrt(disc);
        /* The numerically stable pair of roots. */
        double q = -0.5 * (B + (B >= 0 ? sq : -sq));
        double x0 = q / A, x1 = q != 0 ? C / q : x0;
        roots[n++] = x0 < x1 ? x0 : x1;
        roots[n++] = x0 < x1 ? x1 : x0;
    }
    for (int i = 0; i < n; i++) {
        double s = roots[i];
        if (!(s > tmin && s < tmax)) continue;
        double along = t0 + s * dw;
        if (along < 0 || along > h) continue;
        if (ra + k * along < 0) continue; /* the mirrored nappe of the double cone */
        *t = s;
        return 1;
    }
    return 0;
}

/* Whether the card's cell at (x, y) (card coordinates of hit_quad) is a gap
 * between needles: a hash of the cell and of the card's base, so neighbouring
 * cards' patterns are independent and every ray sees the same pattern. */
static int card_cell_open(const sy_prim *p, double x, double y, double uu, double vv)
{
    int64_t cx = (int64_t)floor((x + 1) * sqrt(uu) / SY_CARD_GAP_CELL);
    int64_t cy = (int64_t)floor(y * sqrt(vv) / SY_CARD_GAP_CELL);
    uint32_t b[3];
    memcpy(b, p->v, sizeof b);
    uint64_t card = sy_mix64(((uint64_t)b[0] << 32 | b[1]) ^ sy_mix64(b[2]));
    uint64_t h = sy_mix64(card ^ ((uint64_t)cx << 32) ^ (uint64_t)(uint32_t)cy);
    return (h >> 56) < p->gaps;
}

static int hit_quad(const sy_prim *p, const double o[3], const double d[3], double tmin, double tmax, double *t)
{
    double base[3], u[3], v[3], n[3];
    load3(p->v, base);
    load3(p->v + 3, u);
    load3(p->v + 6, v);
    load3(p->v + 9, n);
    double den = dot3(n, d);
    if (fabs(den) < 1e-12) return 0;
    double bo[3] = {base[0] - o[0], base[1] - o[1], base[2] - o[2]};
    double s = dot3(n, bo) / den;
    if (!(s > tmin && s < tmax)) return 0;
    double r[3] = {o[0] + s * d[0] - base[0], o[1] + s * d[1] - base[1], o[2] + s * d[2] - base[2]};
    double uu = dot3(u, u), vv = dot3(v, v);
    if (!(uu > 0 && vv > 0)) return 0;
    double x = dot3(r, u) / uu, y = dot3(r, v) / vv;
    if (p->elliptic) {
        double yc = 2 * y - 1;
        if (x * x + yc * yc > 1) return 0;
    } else if (x < -1 || x > 1 || y < 0 || y > 1) {
        return 0;
    }
    if (p->gaps && card_cell_open(p, x, y, uu, vv)) return 0;
    *t = s;
    return 1;
}

static int hit_tri(const sy_prim *p, const double o[3], const double d[3], double tmin, double tmax, double *t)
{
    double a[3], b[3], c[3], s;
    load3(p->v, a);
    load3(p->v + 3, b);
    load3(p->v + 6, c);
    if (!sy_ray_triangle(o, d, a, b, c, 1, &s) || !(s > tmin && s < tmax)) return 0;
    *t = s;
    return 1;
}

int sy_prim_intersect(const sy_prim *p, const double o[3], const double d[3], double tmin, double tmax, double *t)
{
    switch (p->kind) {
    case SY_PRIM_CONE: return hit_cone(p, o, d, tmin, tmax, t);
    case SY_PRIM_QUAD: return hit_quad(p, o, d, tmin, tmax, t);
    case SY_PRIM_TRI: return hit_tri(p, o, d, tmin, tmax, t);
    }
    return 0;
}

int sy_prim_ray_hit(const void *prims, uint32_t i, const double o[3], const double d[3], double tmax, double *t)
{
    return sy_prim_intersect((const sy_prim *)prims + i, o, d, SY_SCAN_TMIN, tmax, t);
}

static void normalize3(double v[3]) { sy_v3_normalize(v); }

void sy_prim_normal(const sy_prim *p, const double x[3], double n[3])
{
    if (p->kind == SY_PRIM_CONE) {
        double a[3], w[3], h, k;
        if (!cone_frame(p, a, w, &h, &k)) {
            n[0] = n[1] = 0;
            n[2] = 1;
            return;
        }
        double q[3] = {x[0] - a[0], x[1] - a[1], x[2] - a[2]};
        double along = dot3(q, w);
        double radial[3] = {q[0] - along * w[0], q[1] - along * w[1], q[2] - along * w[2]};
        normalize3(radial);
        /* A widening cone's surface leans outwards: its normal tilts back along -w. */
        for (int i = 0; i < 3; i++) n[i] = radial[i] - k * w[i];
    } else if (p->kind == SY_PRIM_QUAD) {
        load3(p->v + 9, n);
    } else {
        double e1[3] = {(double)p->v[3] - p->v[0], (double)p->v[4] - p->v[1], (double)p->v[5] - p->v[2]};
        double e2[3] = {(double)p->v[6] - p->v[0], (double)p->v[7] - p->v[1], (double)p->v[8] - p->v[2]};
        n[0] = e1[1] * e2[2] - e1[2] * e2[1];
        n[1] = e1[2] * e2[0] - e1[0] * e2[2];
        n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    }
    normalize3(n);
}

void sy_prim_bounds(const sy_prim *p, sy_box *box)
{
    sy_box_empty(box);
    double x[3];
    if (p->kind == SY_PRIM_CONE) {
        double a[3], b[3], w[3];
        load3(p->v, a);
        load3(p->v + 3, b);
        for (int k = 0; k < 3; k++) w[k] = b[k] - a[k];
        double h = sqrt(dot3(w, w));
        for (int end = 0; end < 2; end++) {
            const double *c = end ? b : a;
            double r = p->v[6 + end];
            for (int k = 0; k < 3; k++) {
                /* The extent of a disc of radius r normal to w along axis k. */
                double wk = h > 0 ? w[k] / h : 0;
                double e = r * sqrt(fmax(0.0, 1.0 - wk * wk));
                x[k] = c[k] - e;
            }
            sy_box_add_point(box, x);
            for (int k = 0; k < 3; k++) x[k] = 2 * c[k] - x[k];
            sy_box_add_point(box, x);
        }
    } else if (p->kind == SY_PRIM_QUAD) {
        for (int s = -1; s <= 1; s += 2)
            for (int t = 0; t <= 1; t++) {
                for (int k = 0; k < 3; k++) x[k] = (double)p->v[k] + s * (double)p->v[3 + k] + t * (double)p->v[6 + k];
                sy_box_add_point(box, x);
            }
    } else {
        for (int c = 0; c < 3; c++) {
            load3(p->v + 3 * c, x);
            sy_box_add_point(box, x);
        }
    }
    /* Rounding in the cone extents must never cut a surface off its box. */
    for (int k = 0; k < 3; k++) {
        box->lo[k] -= 1e-5 * (1.0 + fabs(box->lo[k]));
        box->hi[k] += 1e-5 * (1.0 + fabs(box->hi[k]));
    }
}

sy_code sy_prims_index(sy_prims *list, sy_bvh *bvh, sy_error *err)
{
    sy_box *boxes = sy_calloc(list->n ? list->n : 1, sizeof *boxes, err, "scene bounds");
    if (!boxes) return SY_EINTERNAL;
    for (size_t i = 0; i < list->n; i++) sy_prim_bounds(&list->p[i], &boxes[i]);
    sy_code rc = sy_bvh_build(bvh, boxes, list->n, err);
    free(boxes);
    if (!rc) rc = sy_bvh_reorder(bvh, list->p, sizeof *list->p, err);
    if (rc) sy_bvh_free(bvh);
    return rc;
}
