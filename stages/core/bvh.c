/* Binned SAH build, float slab tests against widened node boxes, and the
 * four traversals (closest hit, ray crossings, nearest, any within). */
#include "bvh.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BINS 16
#define LEAF_MIN_SPLIT 4  /* at most this many primitives always make a leaf */
#define LEAF_MAX 16       /* SAH may keep up to this many in a leaf */
#define SAH_DEPTH 40      /* deeper than this, split at the median so depth stays bounded */
#define STACK 128         /* > SAH_DEPTH + log2(UINT32_MAX) + 1 */

void sy_box_empty(sy_box *b)
{
    for (int k = 0; k < 3; k++) {
        b->lo[k] = INFINITY;
        b->hi[k] = -INFINITY;
    }
}

void sy_box_add_point(sy_box *b, const double p[3])
{
    for (int k = 0; k < 3; k++) {
        if (p[k] < b->lo[k]) b->lo[k] = p[k];
        if (p[k] > b->hi[k]) b->hi[k] = p[k];
    }
}

static void box_grow(sy_box *b, const sy_box *o)
{
    for (int k = 0; k < 3; k++) {
        if (o->lo[k] < b->lo[k]) b->lo[k] = o->lo[k];
        if (o->hi[k] > b->hi[k]) b->hi[k] = o->hi[k];
    }
}

/* ---------------------------------------------------------------- build */

/* The build runs on float boxes relative to the origin, as the nodes store
 * them: half the memory traffic of doubles. */
typedef struct {
    float lo[3], hi[3];
} fbox;

static void fbox_empty(fbox *b)
{
    for (int k = 0; k < 3; k++) {
        b->lo[k] = FLT_MAX;
        b->hi[k] = -FLT_MAX;
    }
}

static void fbox_grow(fbox *b, const fbox *o)
{
    for (int k = 0; k < 3; k++) {
        if (o->lo[k] < b->lo[k]) b->lo[k] = o->lo[k];
        if (o->hi[k] > b->hi[k]) b->hi[k] = o->hi[k];
    }
}

static float fbox_area(const fbox *b)
{
    float d[3];
    for (int k = 0; k < 3; k++) d[k] = b->hi[k] > b->lo[k] ? b->hi[k] - b->lo[k] : 0;
    return 2 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0]);
}

/* The float box relative to origin that contains x: rounded outwards, then
 * widened by pad so that float slab tests of rays starting within the scene
 * never cut a primitive off. */
static void to_fbox(const sy_box *x, const double origin[3], double pad, fbox *f)
{
    for (int k = 0; k < 3; k++) {
        double lo = x->lo[k] - origin[k] - pad, hi = x->hi[k] - origin[k] + pad;
        f->lo[k] = (float)lo;
        f->hi[k] = (float)hi;
        if ((double)f->lo[k] > lo) f->lo[k] = nextafterf(f->lo[k], -INFINITY);
        if ((double)f->hi[k] < hi) f->hi[k] = nextafterf(f->hi[k], INFINITY);
    }
}

typedef struct {
    fbox *boxes;
    float *centroid; /* 3 per primitive */
    uint32_t *idx;
    sy_bvh_node *nodes;
    size_t n_nodes;
} builder;

/* scale in double: BINS over a tiny float extent can overflow float. */
static int bin_of(const builder *b, uint32_t p, int axis, float lo, double scale)
{
    /* Clamped before the cast: a flat extent makes scale infinite and 0 * inf
     * NaN, and converting NaN or a value past int is undefined. */
    double v = (double)(b->centroid[3 * p + axis] - lo) * scale;
    return v >= BINS ? BINS - 1 : v >= 0 ? (int)v : 0;
}

/* Best SAH split of [begin, end) along axis; returns the split position in
 * *mid, or 0 when a leaf is cheaper or no bin boundary separates anything. */
static int sah_split(builder *b, uint32_t begin, uint32_t end, const fbox *cb, int axis, float parent_area,
                     uint32_t *mid)
{
    fbox bin_box[BINS];
    uint32_t bin_n[BINS] = {0};
    for (int i = 0; i < BINS; i++) fbox_empty(&bin_box[i]);
    double scale = BINS / ((double)cb->hi[axis] - cb->lo[axis]);
    for (uint32_t i = begin; i < end; i++) {
        uint32_t p = b->idx[i];
        int bin = bin_of(b, p, axis, cb->lo[axis], scale);
        bin_n[bin]++;
        fbox_grow(&bin_box[bin], &b->boxes[p]);
    }
    float right_area[BINS];
    uint32_t right_n[BINS];
    fbox acc;
    fbox_empty(&acc);
    uint32_t cnt = 0;
    for (int i = BINS - 1; i > 0; i--) {
        fbox_grow(&acc, &bin_box[i]);
        cnt += bin_n[i];
        right_area[i] = fbox_area(&acc);
        right_n[i] = cnt;
    }
    fbox_empty(&acc);
    cnt = 0;
    float best = FLT_MAX;
    int best_bin = -1;
    for (int i = 0; i < BINS - 1; i++) {
        fbox_grow(&acc, &bin_box[i]);
        cnt += bin_n[i];
        if (cnt == 0 || right_n[i + 1] == 0) continue;
        float cost = fbox_area(&acc) * cnt + right_area[i + 1] * right_n[i + 1];
        if (cost < best) {
            best = cost;
            best_bin = i;
        }
    }
    /* A traversal step costs about one primitive test. */
    float leaf_cost = parent_area * (float)(end - begin);
    if (best_bin < 0 || (end - begin <= LEAF_MAX && best + parent_area >= leaf_cost)) return 0;
    uint32_t i = begin, j = end;
    while (i < j) {
        uint32_t p = b->idx[i];
        if (bin_of(b, p, axis, cb->lo[axis], scale) <= best_bin) {
            i++;
        } else {
            b->idx[i] = b->idx[--j];
            b->idx[j] = p;
        }
    }
    if (i == begin || i == end) return 0;
    *mid = i;
    return 1;
}

/* Partial sort of idx[lo..hi) so the element at mid is in place by axis: a
 * three-way quickselect, which always shrinks because the run equal to the
 * pivot is never empty, and needs no global state, unlike qsort. */
static void select_median(builder *b, uint32_t lo, uint32_t hi, uint32_t mid, int axis)
{
    const float *c = b->centroid;
    uint32_t *idx = b->idx;
    while (hi - lo > 1) {
        float pivot = c[3 * idx[lo + (hi - lo) / 2] + axis];
        uint32_t lt = lo, i = lo, gt = hi; /* [lo,lt) < pivot, [lt,i) == pivot, [gt,hi) > pivot */
        while (i < gt) {
            float v = c[3 * idx[i] + axis];
            uint32_t t = idx[i];
            if (v < pivot) {
                idx[i++] = idx[lt];
                idx[lt++] = t;
            } else if (v > pivot) {
                idx[i] = idx[--gt];
                idx[gt] = t;
            } else {
                i++;
            }
        }
        if (mid < lt) hi = lt;
        else if (mid >= gt) lo = gt;
        else return;
    }
}

static void build_node(builder *b, size_t node, uint32_t begin, uint32_t end, int depth)
{
    fbox bb, cb;
    fbox_empty(&bb);
    fbox_empty(&cb);
    for (uint32_t i = begin; i < end; i++) {
        uint32_t p = b->idx[i];
        fbox_grow(&bb, &b->boxes[p]);
        const float *c = b->centroid + 3 * p;
        fbox cp = {{c[0], c[1], c[2]}, {c[0], c[1], c[2]}};
        fbox_grow(&cb, &cp);
    }
    sy_bvh_node *nd = &b->nodes[node];
    memcpy(nd->lo, bb.lo, sizeof bb.lo);
    memcpy(nd->hi, bb.hi, sizeof bb.hi);
    nd->start = begin;
    nd->count = end - begin;
    if (end - begin <= LEAF_MIN_SPLIT) return;
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if (cb.hi[k] - cb.lo[k] > cb.hi[axis] - cb.lo[axis]) axis = k;
    uint32_t mid;
    if (!(cb.hi[axis] > cb.lo[axis])) {
        /* Identical centroids (duplicate points): halves in any order keep
         * the leaves small. */
        if (end - begin <= LEAF_MAX) return;
        mid = begin + (end - begin) / 2;
    } else if (depth >= SAH_DEPTH || !sah_split(b, begin, end, &cb, axis, fbox_area(&bb), &mid)) {
        if (depth < SAH_DEPTH && end - begin <= LEAF_MAX) return;
        mid = begin + (end - begin) / 2;
        select_median(b, begin, end, mid, axis);
    }
    size_t left = b->n_nodes++;
    build_node(b, left, begin, mid, depth + 1);
    size_t right = b->n_nodes++;
    b->nodes[node].start = (uint32_t)right;
    b->nodes[node].count = 0;
    build_node(b, right, mid, end, depth + 1);
}

sy_code sy_bvh_build(sy_bvh *bvh, const sy_box *boxes, size_t n, sy_error *err)
{
    memset(bvh, 0, sizeof *bvh);
    if (n > UINT32_MAX / 2) return sy_fail(err, SY_EINPUT, "spatial index: %zu primitives exceed its limit", n);
    builder b = {0};
    b.boxes = sy_calloc(n ? n : 1, sizeof(fbox), err, "BVH bounds");
    b.centroid = sy_calloc(n ? 3 * n : 1, sizeof(float), err, "BVH centroids");
    b.idx = sy_calloc(n ? n : 1, sizeof(uint32_t), err, "BVH index");
    b.nodes = sy_calloc(n ? 2 * n : 1, sizeof(sy_bvh_node), err, "BVH nodes");
    if (!b.boxes || !b.centroid || !b.idx || !b.nodes) {
        free(b.boxes);
        free(b.centroid);
        free(b.idx);
        free(b.nodes);
        return SY_EINTERNAL;
    }
    sy_box all;
    sy_box_empty(&all);
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++)
            if (!isfinite(boxes[i].lo[k]) || !isfinite(boxes[i].hi[k])) {
                free(b.boxes);
                free(b.centroid);
                free(b.idx);
                free(b.nodes);
                return sy_fail(err, SY_EINPUT, "spatial index: primitive %zu has a non-finite bound", i);
            }
        box_grow(&all, &boxes[i]);
    }
    double reach = 0;
    for (int k = 0; k < 3 && n; k++) {
        bvh->origin[k] = 0.5 * (all.lo[k] + all.hi[k]);
        reach = fmax(reach, all.hi[k] - bvh->origin[k]);
    }
    /* A few float ulps at the scene's scale: covers rounding of box corners
     * and of ray origins within it. */
    double pad = 4 * FLT_EPSILON * (1 + reach);
    for (size_t i = 0; i < n; i++) {
        to_fbox(&boxes[i], bvh->origin, pad, &b.boxes[i]);
        for (int k = 0; k < 3; k++) b.centroid[3 * i + k] = 0.5f * (b.boxes[i].lo[k] + b.boxes[i].hi[k]);
        b.idx[i] = (uint32_t)i;
    }
    if (n) {
        b.n_nodes = 1;
        build_node(&b, 0, 0, (uint32_t)n, 0);
    }
    free(b.boxes);
    free(b.centroid);
    bvh->nodes = b.nodes;
    bvh->n_nodes = b.n_nodes;
    bvh->order = b.idx;
    bvh->n_prims = n;
    return SY_OK;
}

void sy_bvh_free(sy_bvh *b)
{
    free(b->nodes);
    free(b->order);
    memset(b, 0, sizeof *b);
}

sy_code sy_bvh_reorder(sy_bvh *b, void *items, size_t item_size, sy_error *err)
{
    unsigned char *copy = sy_calloc(b->n_prims ? b->n_prims : 1, item_size, err, "BVH reorder");
    if (!copy) return SY_EINTERNAL;
    memcpy(copy, items, b->n_prims * item_size);
    for (size_t i = 0; i < b->n_prims; i++) {
        memcpy((unsigned char *)items + i * item_size, copy + (size_t)b->order[i] * item_size, item_size);
        b->order[i] = (uint32_t)i;
    }
    free(copy);
    return SY_OK;
}

void sy_bvh_bounds(const sy_bvh *b, sy_box *box)
{
    sy_box_empty(box);
    if (!b->n_prims) return;
    for (int k = 0; k < 3; k++) {
        box->lo[k] = b->origin[k] + b->nodes[0].lo[k];
        box->hi[k] = b->origin[k] + b->nodes[0].hi[k];
    }
}

/* ----------------------------------------------------------------- rays */

typedef struct {
    float o[3], inv[3];
} fray;

static void make_fray(const sy_bvh *b, fray *r, const double o[3], const double d[3])
{
    for (int k = 0; k < 3; k++) {
        r->o[k] = (float)(o[k] - b->origin[k]);
        /* A zero component gets a huge finite inverse: no inf * 0 NaNs. */
        double dk = fabs(d[k]) < 1e-30 ? (d[k] < 0 ? -1e-30 : 1e-30) : d[k];
        r->inv[k] = (float)(1.0 / dk);
    }
}

/* Entry distance into the node box, or INFINITY if missed before tmax. */
static inline float slab(const sy_bvh_node *nd, const fray *r, float tmax)
{
    float t0 = 0, t1 = tmax;
    for (int k = 0; k < 3; k++) {
        float a = (nd->lo[k] - r->o[k]) * r->inv[k];
        float b = (nd->hi[k] - r->o[k]) * r->inv[k];
        if (a > b) {
            float s = a;
            a = b;
            b = s;
        }
        if (a > t0) t0 = a;
        if (b < t1) t1 = b;
    }
    /* The relative slack covers float rounding of the direction's inverse. */
    return t0 <= t1 * 1.00001f + 1e-5f ? t0 : INFINITY;
}

/* The float bound on box entry for a hit at t. */
static inline float box_limit(double t) { return (float)t * 1.0001f + 1e-4f; }

int sy_bvh_closest(const sy_bvh *b, const double o[3], const double d[3], double tmax, sy_bvh_ray_fn fn,
                   const void *ctx, sy_hit *hit)
{
    if (!b->n_prims) return 0;
    fray r;
    make_fray(b, &r, o, d);
    double best = tmax;
    int found = 0;
    uint32_t stack[STACK];
    int sp = 0;
    if (slab(&b->nodes[0], &r, box_limit(best)) == INFINITY) return 0;
    uint32_t node = 0;
    for (;;) {
        const sy_bvh_node *nd = &b->nodes[node];
        if (nd->count) {
            for (uint32_t i = nd->start; i < nd->start + nd->count; i++) {
                double t;
                if (fn(ctx, b->order[i], o, d, best, &t)) {
                    best = t;
                    hit->t = t;
                    hit->prim = b->order[i];
                    found = 1;
                }
            }
        } else {
            uint32_t l = node + 1, rr = nd->start;
            float lim = box_limit(best);
            float tl = slab(&b->nodes[l], &r, lim), tr = slab(&b->nodes[rr], &r, lim);
            if (tl != INFINITY || tr != INFINITY) {
                uint32_t first = l, second = rr;
                float tsecond = tr;
                if (tr < tl) {
                    first = rr;
                    second = l;
                    tsecond = tl;
                }
                if (tsecond != INFINITY && sp < STACK) stack[sp++] = second;
                node = first;
                continue;
            }
        }
        /* Pop, skipping nodes now farther than the best hit. */
        int next = 0;
        while (sp > 0) {
            uint32_t c = stack[--sp];
            if (slab(&b->nodes[c], &r, box_limit(best)) != INFINITY) {
                node = c;
                next = 1;
                break;
            }
        }
        if (!next) break;
    }
    return found;
}

int sy_bvh_closest_brute(const sy_bvh *b, const double o[3], const double d[3], double tmax, sy_bvh_ray_fn fn,
                         const void *ctx, sy_hit *hit)
{
    double best = tmax;
    int found = 0;
    for (size_t i = 0; i < b->n_prims; i++) {
        double t;
        if (fn(ctx, (uint32_t)i, o, d, best, &t)) {
            best = t;
            hit->t = t;
            hit->prim = (uint32_t)i;
            found = 1;
        }
    }
    return found;
}

size_t sy_bvh_ray_count(const sy_bvh *b, const double o[3], const double d[3], sy_bvh_ray_fn fn, const void *ctx)
{
    if (!b->n_prims) return 0;
    fray r;
    make_fray(b, &r, o, d);
    size_t hits = 0;
    uint32_t stack[STACK];
    int sp = 0;
    stack[sp++] = 0;
    while (sp > 0) {
        uint32_t node = stack[--sp];
        const sy_bvh_node *nd = &b->nodes[node];
        if (slab(nd, &r, INFINITY) == INFINITY) continue;
        if (nd->count) {
            for (uint32_t i = nd->start; i < nd->start + nd->count; i++) {
                double t;
                hits += (size_t)fn(ctx, b->order[i], o, d, INFINITY, &t);
            }
            continue;
        }
        if (sp + 2 > STACK) continue; /* unreachable: the depth is bounded */
        stack[sp++] = nd->start;
        stack[sp++] = node + 1;
    }
    return hits;
}

/* --------------------------------------------------------------- points */

/* Squared distance from q (relative to the origin) to the node box, 0 inside. */
static inline double box_distance2(const sy_bvh_node *nd, const double q[3])
{
    double d2 = 0;
    for (int k = 0; k < 3; k++) {
        double lo = nd->lo[k], hi = nd->hi[k];
        double e = q[k] < lo ? lo - q[k] : q[k] > hi ? q[k] - hi : 0;
        d2 += e * e;
    }
    return d2;
}

typedef struct {
    uint32_t node;
    double d2;
} stack_entry;

uint32_t sy_bvh_nearest(const sy_bvh *b, const double q[3], double max_dist, sy_bvh_distance_fn fn, const void *ctx,
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
    double ql[3] = {q[0] - b->origin[0], q[1] - b->origin[1], q[2] - b->origin[2]};
    double best_d2 = best_d * best_d;
    stack_entry stack[STACK];
    int sp = 0;
    stack[sp].node = 0;
    stack[sp++].d2 = box_distance2(&b->nodes[0], ql);
    while (sp > 0) {
        sp--;
        if (stack[sp].d2 > best_d2) continue;
        uint32_t node = stack[sp].node;
        const sy_bvh_node *nd = &b->nodes[node];
        if (nd->count) {
            for (uint32_t i = nd->start; i < nd->start + nd->count; i++) {
                uint32_t p = b->order[i];
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
        uint32_t l = node + 1, r = nd->start;
        double dl = box_distance2(&b->nodes[l], ql), dr = box_distance2(&b->nodes[r], ql);
        if (sp + 2 > STACK) continue; /* unreachable: the depth is bounded */
        /* Push the farther child first so the nearer one is searched first. */
        if (dl < dr) {
            if (dr <= best_d2) stack[sp].node = r, stack[sp++].d2 = dr;
            if (dl <= best_d2) stack[sp].node = l, stack[sp++].d2 = dl;
        } else {
            if (dl <= best_d2) stack[sp].node = l, stack[sp++].d2 = dl;
            if (dr <= best_d2) stack[sp].node = r, stack[sp++].d2 = dr;
        }
    }
    if (best != UINT32_MAX) *dist = best_d;
    return best;
}

int sy_bvh_any_within(const sy_bvh *b, const double q[3], double r, sy_bvh_distance_fn fn, const void *ctx)
{
    if (!b->n_prims) return 0;
    double ql[3] = {q[0] - b->origin[0], q[1] - b->origin[1], q[2] - b->origin[2]};
    double r2 = r * r;
    uint32_t stack[STACK];
    int sp = 0;
    stack[sp++] = 0;
    while (sp > 0) {
        uint32_t node = stack[--sp];
        const sy_bvh_node *nd = &b->nodes[node];
        if (box_distance2(nd, ql) > r2) continue;
        if (nd->count) {
            for (uint32_t i = nd->start; i < nd->start + nd->count; i++)
                if (fn(ctx, b->order[i], q) <= r) return 1;
            continue;
        }
        if (sp + 2 > STACK) continue;
        stack[sp++] = nd->start;
        stack[sp++] = node + 1;
    }
    return 0;
}
