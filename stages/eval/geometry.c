#include "geometry.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void sub3(double r[3], const double a[3], const double b[3])
{
    r[0] = a[0] - b[0];
    r[1] = a[1] - b[1];
    r[2] = a[2] - b[2];
}
static void cross3(double r[3], const double a[3], const double b[3])
{
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}
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

/* Moller-Trumbore; edge hits count for one side only through the strict and
 * non-strict comparisons, and callers vote over several rays. */
int sy_ray_hits_triangle(const double o[3], const double d[3], const double a[3], const double b[3], const double c[3])
{
    double e1[3], e2[3], pv[3], tv[3], qv[3];
    sub3(e1, b, a);
    sub3(e2, c, a);
    cross3(pv, d, e2);
    double det = dot3(e1, pv);
    if (fabs(det) < 1e-300) return 0;
    double inv = 1.0 / det;
    sub3(tv, o, a);
    double u = dot3(tv, pv) * inv;
    if (u < 0 || u >= 1) return 0;
    cross3(qv, tv, e1);
    double v = dot3(d, qv) * inv;
    if (v < 0 || u + v >= 1) return 0;
    return dot3(e2, qv) * inv > 0;
}

/* ---- BVH ---- */

typedef struct {
    const sy_box *boxes;
    double *centroid; /* 3 per primitive */
    sy_bvh *b;
} builder;

static void box_empty(sy_box *x)
{
    for (int k = 0; k < 3; k++) x->lo[k] = INFINITY, x->hi[k] = -INFINITY;
}
static void box_grow(sy_box *x, const sy_box *y)
{
    for (int k = 0; k < 3; k++) {
        if (y->lo[k] < x->lo[k]) x->lo[k] = y->lo[k];
        if (y->hi[k] > x->hi[k]) x->hi[k] = y->hi[k];
    }
}

/* Partial sort of prims[lo..hi) so the element at mid is in place by axis:
 * a three-way quickselect, which always shrinks because the run equal to the
 * pivot is never empty. */
static void select_median(builder *B, uint32_t *prims, size_t lo, size_t hi, size_t mid, int axis)
{
    const double *c = B->centroid;
    while (hi - lo > 1) {
        double pivot = c[3 * prims[lo + (hi - lo) / 2] + axis];
        size_t lt = lo, i = lo, gt = hi; /* [lo,lt) < pivot, [lt,i) == pivot, [gt,hi) > pivot */
        while (i < gt) {
            double v = c[3 * prims[i] + axis];
            uint32_t t = prims[i];
            if (v < pivot) {
                prims[i++] = prims[lt];
                prims[lt++] = t;
            } else if (v > pivot) {
                prims[i] = prims[--gt];
                prims[gt] = t;
            } else {
                i++;
            }
        }
        if (mid < lt) hi = lt;
        else if (mid >= gt) lo = gt;
        else return;
    }
}

#define LEAF_SIZE 4

static void build_node(builder *B, uint32_t node, size_t first, size_t count)
{
    sy_bvh *b = B->b;
    sy_bvh_node *nd = &b->nodes[node];
    box_empty(&nd->box);
    sy_box cb;
    box_empty(&cb);
    for (size_t i = first; i < first + count; i++) {
        uint32_t p = b->prims[i];
        box_grow(&nd->box, &B->boxes[p]);
        sy_box c = {{B->centroid[3 * p], B->centroid[3 * p + 1], B->centroid[3 * p + 2]},
                    {B->centroid[3 * p], B->centroid[3 * p + 1], B->centroid[3 * p + 2]}};
        box_grow(&cb, &c);
    }
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if (cb.hi[k] - cb.lo[k] > cb.hi[axis] - cb.lo[axis]) axis = k;
    if (count <= LEAF_SIZE) {
        nd->first = (uint32_t)first;
        nd->count = (uint32_t)count;
        return;
    }
    size_t half = count / 2;
    select_median(B, b->prims, first, first + count, first + half, axis);
    uint32_t left = (uint32_t)b->n_nodes;
    b->n_nodes += 2;
    nd->first = left;
    nd->count = 0;
    build_node(B, left, first, half);
    build_node(B, left + 1, first + half, count - half);
}

sy_code sy_bvh_build(sy_bvh *b, const sy_box *boxes, size_t n, sy_error *err)
{
    memset(b, 0, sizeof *b);
    if (n >= UINT32_MAX / 2) return sy_fail(err, SY_EINTERNAL, "spatial index: %zu primitives is too many", n);
    b->nodes = sy_calloc(n ? 2 * n : 1, sizeof *b->nodes, err, "spatial index");
    b->prims = sy_calloc(n ? n : 1, sizeof *b->prims, err, "spatial index");
    double *centroid = sy_calloc(n ? 3 * n : 1, sizeof *centroid, err, "spatial index");
    if (!b->nodes || !b->prims || !centroid) {
        free(centroid);
        sy_bvh_free(b);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < n; i++) {
        b->prims[i] = (uint32_t)i;
        for (int k = 0; k < 3; k++) centroid[3 * i + k] = 0.5 * (boxes[i].lo[k] + boxes[i].hi[k]);
    }
    b->n_prims = n;
    builder B = {boxes, centroid, b};
    b->n_nodes = 1;
    if (n) build_node(&B, 0, 0, n);
    else box_empty(&b->nodes[0].box);
    free(centroid);
    return SY_OK;
}

void sy_bvh_free(sy_bvh *b)
{
    free(b->nodes);
    free(b->prims);
    memset(b, 0, sizeof *b);
}

/* Squared distance from q to the box (0 inside). */
static double box_distance2(const sy_box *x, const double q[3])
{
    double d2 = 0;
    for (int k = 0; k < 3; k++) {
        double e = q[k] < x->lo[k] ? x->lo[k] - q[k] : q[k] > x->hi[k] ? q[k] - x->hi[k] : 0;
        d2 += e * e;
    }
    return d2;
}

/* Median splits keep the depth near log2(n / LEAF_SIZE), far below this. */
#define STACK_MAX 128

typedef struct {
    uint32_t node;
    double d2;
} stack_entry;

uint32_t sy_bvh_nearest(const sy_bvh *b, const double q[3], double max_dist, sy_prim_distance fn, const void *ctx,
                        uint32_t hint, double *dist)
{
    uint32_t best = UINT32_MAX;
    double best_d = max_dist;
    *dist = INFINITY;
    if (!b->n_prims) return best;
    if (hint < b->n_prims) {
        double d = fn(ctx, hint, q);
        if (d <= best_d) best_d = d, best = hint;
    }
    double best_d2 = best_d * best_d;
    stack_entry stack[STACK_MAX];
    int top = 0;
    stack[top].node = 0;
    stack[top++].d2 = box_distance2(&b->nodes[0].box, q);
    while (top > 0) {
        top--;
        if (stack[top].d2 > best_d2) continue;
        const sy_bvh_node *nd = &b->nodes[stack[top].node];
        if (nd->count) {
            for (uint32_t i = nd->first; i < nd->first + nd->count; i++) {
                uint32_t p = b->prims[i];
                if (p == hint) continue;
                double d = fn(ctx, p, q);
                /* Ties go to the lower index, so answers do not depend on the hint. */
                if (d < best_d || (d == best_d && (best == UINT32_MAX || p < best))) {
                    best_d = d;
                    best_d2 = d * d;
                    best = p;
                }
            }
            continue;
        }
        uint32_t l = nd->first, r = nd->first + 1;
        double dl = box_distance2(&b->nodes[l].box, q), dr = box_distance2(&b->nodes[r].box, q);
        if (top + 2 > STACK_MAX) continue; /* unreachable for median-split trees */
        /* Push the farther child first so the nearer one is searched first. */
        if (dl < dr) {
            if (dr <= best_d2) stack[top].node = r, stack[top++].d2 = dr;
            if (dl <= best_d2) stack[top].node = l, stack[top++].d2 = dl;
        } else {
            if (dl <= best_d2) stack[top].node = l, stack[top++].d2 = dl;
            if (dr <= best_d2) stack[top].node = r, stack[top++].d2 = dr;
        }
    }
    if (best != UINT32_MAX) *dist = best_d;
    return best;
}

int sy_bvh_any_within(const sy_bvh *b, const double q[3], double r, sy_prim_distance fn, const void *ctx)
{
    if (!b->n_prims) return 0;
    double r2 = r * r;
    uint32_t stack[STACK_MAX];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const sy_bvh_node *nd = &b->nodes[stack[--top]];
        if (box_distance2(&nd->box, q) > r2) continue;
        if (nd->count) {
            for (uint32_t i = nd->first; i < nd->first + nd->count; i++)
                if (fn(ctx, b->prims[i], q) <= r) return 1;
            continue;
        }
        if (top + 2 > STACK_MAX) continue;
        stack[top++] = nd->first + 1;
        stack[top++] = nd->first;
    }
    return 0;
}

static int ray_hits_box(const sy_box *x, const double o[3], const double d[3])
{
    double t0 = 0, t1 = INFINITY;
    for (int k = 0; k < 3; k++) {
        if (d[k] == 0) {
            if (o[k] < x->lo[k] || o[k] > x->hi[k]) return 0;
            continue;
        }
        double inv = 1.0 / d[k], a = (x->lo[k] - o[k]) * inv, c = (x->hi[k] - o[k]) * inv;
        if (a > c) {
            double t = a;
            a = c;
            c = t;
        }
        if (a > t0) t0 = a;
        if (c < t1) t1 = c;
        if (t0 > t1) return 0;
    }
    return 1;
}

size_t sy_bvh_ray_count(const sy_bvh *b, const double o[3], const double d[3], sy_prim_ray fn, const void *ctx)
{
    size_t hits = 0;
    if (!b->n_prims) return 0;
    uint32_t stack[STACK_MAX];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const sy_bvh_node *nd = &b->nodes[stack[--top]];
        if (!ray_hits_box(&nd->box, o, d)) continue;
        if (nd->count) {
            for (uint32_t i = nd->first; i < nd->first + nd->count; i++) hits += (size_t)fn(ctx, b->prims[i], o, d);
            continue;
        }
        if (top + 2 > STACK_MAX) continue;
        stack[top++] = nd->first;
        stack[top++] = nd->first + 1;
    }
    return hits;
}
