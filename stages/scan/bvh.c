/* Bounding volume hierarchy: binned SAH build over primitive centroids,
 * iterative near-first traversal with a float slab test and double-precision
 * primitive tests. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "scan.h"

#define BINS 16
#define LEAF_MAX 4
#define SAH_DEPTH 40 /* deeper than this, split at the median so depth stays bounded */
#define STACK 128
#define T_MIN 1e-6

typedef struct {
    float lo[3], hi[3];
} box;

typedef struct {
    box *bounds;
    float *centroid; /* 3 per primitive */
    uint32_t *idx;
    sy_scan_bvh_node *nodes;
    size_t n_nodes;
} builder;

static void box_empty(box *b)
{
    for (int k = 0; k < 3; k++) {
        b->lo[k] = FLT_MAX;
        b->hi[k] = -FLT_MAX;
    }
}

static void box_grow(box *b, const box *o)
{
    for (int k = 0; k < 3; k++) {
        if (o->lo[k] < b->lo[k]) b->lo[k] = o->lo[k];
        if (o->hi[k] > b->hi[k]) b->hi[k] = o->hi[k];
    }
}

static float box_area(const box *b)
{
    float d[3];
    for (int k = 0; k < 3; k++) d[k] = b->hi[k] > b->lo[k] ? b->hi[k] - b->lo[k] : 0;
    return 2 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0]);
}

/* Best SAH split of [begin, end) along the widest centroid axis; returns the
 * split position in *mid or 0 when a leaf is cheaper. */
static int sah_split(builder *b, uint32_t begin, uint32_t end, const float clo[3], const float chi[3], int axis,
                     float parent_area, uint32_t *mid)
{
    box bin_box[BINS];
    uint32_t bin_n[BINS] = {0};
    for (int i = 0; i < BINS; i++) box_empty(&bin_box[i]);
    float extent = chi[axis] - clo[axis];
    float scale = BINS / extent;
    for (uint32_t i = begin; i < end; i++) {
        uint32_t p = b->idx[i];
        int bin = (int)((b->centroid[3 * p + axis] - clo[axis]) * scale);
        if (bin >= BINS) bin = BINS - 1;
        if (bin < 0) bin = 0;
        bin_n[bin]++;
        box_grow(&bin_box[bin], &b->bounds[p]);
    }
    float right_area[BINS];
    uint32_t right_n[BINS];
    box acc;
    box_empty(&acc);
    uint32_t cnt = 0;
    for (int i = BINS - 1; i > 0; i--) {
        box_grow(&acc, &bin_box[i]);
        cnt += bin_n[i];
        right_area[i] = box_area(&acc);
        right_n[i] = cnt;
    }
    box_empty(&acc);
    cnt = 0;
    float best = FLT_MAX;
    int best_bin = -1;
    for (int i = 0; i < BINS - 1; i++) {
        box_grow(&acc, &bin_box[i]);
        cnt += bin_n[i];
        if (cnt == 0 || right_n[i + 1] == 0) continue;
        float cost = box_area(&acc) * cnt + right_area[i + 1] * right_n[i + 1];
        if (cost < best) {
            best = cost;
            best_bin = i;
        }
    }
    /* Traversal step costs about one primitive test. */
    float leaf_cost = parent_area * (float)(end - begin);
    if (best_bin < 0 || (end - begin <= 16 && best + parent_area >= leaf_cost)) return 0;
    uint32_t i = begin, j = end;
    while (i < j) {
        uint32_t p = b->idx[i];
        int bin = (int)((b->centroid[3 * p + axis] - clo[axis]) * scale);
        if (bin >= BINS) bin = BINS - 1;
        if (bin <= best_bin) {
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

static int cmp_axis;
static const float *cmp_centroid;
static int by_centroid(const void *x, const void *y)
{
    float a = cmp_centroid[3 * *(const uint32_t *)x + cmp_axis], c = cmp_centroid[3 * *(const uint32_t *)y + cmp_axis];
    return a < c ? -1 : a > c;
}

static void build_node(builder *b, size_t node, uint32_t begin, uint32_t end, int depth)
{
    box bb, cb;
    box_empty(&bb);
    box_empty(&cb);
    for (uint32_t i = begin; i < end; i++) {
        uint32_t p = b->idx[i];
        box_grow(&bb, &b->bounds[p]);
        box c = {{b->centroid[3 * p], b->centroid[3 * p + 1], b->centroid[3 * p + 2]},
                 {b->centroid[3 * p], b->centroid[3 * p + 1], b->centroid[3 * p + 2]}};
        box_grow(&cb, &c);
    }
    sy_scan_bvh_node *nd = &b->nodes[node];
    memcpy(nd->lo, bb.lo, sizeof bb.lo);
    memcpy(nd->hi, bb.hi, sizeof bb.hi);
    nd->start = begin;
    nd->count = end - begin;
    if (end - begin <= LEAF_MAX) return;
    int axis = 0;
    for (int k = 1; k < 3; k++)
        if (cb.hi[k] - cb.lo[k] > cb.hi[axis] - cb.lo[axis]) axis = k;
    if (!(cb.hi[axis] > cb.lo[axis])) return; /* identical centroids: one leaf */
    uint32_t mid;
    if (depth >= SAH_DEPTH || !sah_split(b, begin, end, cb.lo, cb.hi, axis, box_area(&bb), &mid)) {
        if (depth < SAH_DEPTH && end - begin <= 16) return;
        /* qsort is fine here: the median path runs only below depth 40 or on
         * awkward clusters. */
        cmp_axis = axis;
        cmp_centroid = b->centroid;
        qsort(b->idx + begin, end - begin, sizeof(uint32_t), by_centroid);
        mid = begin + (end - begin) / 2;
    }
    size_t left = b->n_nodes++, right;
    build_node(b, left, begin, mid, depth + 1);
    right = b->n_nodes++;
    b->nodes[node].start = (uint32_t)right;
    b->nodes[node].count = 0;
    build_node(b, right, mid, end, depth + 1);
}

sy_code sy_scan_bvh_build(sy_scan_bvh *bvh, const sy_prim *prims, size_t n, sy_error *err)
{
    memset(bvh, 0, sizeof *bvh);
    if (n > UINT32_MAX / 2) return sy_fail(err, SY_EINPUT, "scene: %zu primitives exceed the BVH limit", n);
    builder b = {0};
    b.bounds = sy_calloc(n ? n : 1, sizeof(box), err, "BVH bounds");
    b.centroid = sy_calloc(n ? 3 * n : 1, sizeof(float), err, "BVH centroids");
    b.idx = sy_calloc(n ? n : 1, sizeof(uint32_t), err, "BVH index");
    b.nodes = sy_calloc(n ? 2 * n : 1, sizeof(sy_scan_bvh_node), err, "BVH nodes");
    bvh->prims = sy_calloc(n ? n : 1, sizeof(sy_prim), err, "BVH primitives");
    if (!b.bounds || !b.centroid || !b.idx || !b.nodes || !bvh->prims) {
        free(b.bounds);
        free(b.centroid);
        free(b.idx);
        free(b.nodes);
        free(bvh->prims);
        bvh->prims = NULL;
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < n; i++) {
        sy_prim_bounds(&prims[i], b.bounds[i].lo, b.bounds[i].hi);
        for (int k = 0; k < 3; k++) b.centroid[3 * i + k] = 0.5f * (b.bounds[i].lo[k] + b.bounds[i].hi[k]);
        b.idx[i] = (uint32_t)i;
    }
    if (n) {
        b.n_nodes = 1;
        build_node(&b, 0, 0, (uint32_t)n, 0);
    }
    for (size_t i = 0; i < n; i++) bvh->prims[i] = prims[b.idx[i]];
    bvh->n_prims = n;
    bvh->nodes = b.nodes;
    bvh->n_nodes = b.n_nodes;
    free(b.bounds);
    free(b.centroid);
    free(b.idx);
    return SY_OK;
}

void sy_scan_bvh_free(sy_scan_bvh *b)
{
    free(b->nodes);
    free(b->prims);
    memset(b, 0, sizeof *b);
}

typedef struct {
    float o[3], inv[3];
} fray;

static void make_fray(fray *r, const double o[3], const double d[3])
{
    for (int k = 0; k < 3; k++) {
        r->o[k] = (float)o[k];
        /* A zero component gets a huge finite inverse: no inf * 0 NaNs. */
        double dk = fabs(d[k]) < 1e-30 ? (d[k] < 0 ? -1e-30 : 1e-30) : d[k];
        r->inv[k] = (float)(1.0 / dk);
    }
}

/* Entry distance into the node box, or INFINITY if missed before tmax. */
static inline float slab(const sy_scan_bvh_node *nd, const fray *r, float tmax)
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
    /* The relative slack covers float rounding of o and inv. */
    return t0 <= t1 * 1.00001f + 1e-5f ? t0 : INFINITY;
}

int sy_scan_bvh_intersect(const sy_scan_bvh *b, const double o[3], const double d[3], double tmax, sy_hit *hit)
{
    if (!b->n_nodes) return 0;
    fray r;
    make_fray(&r, o, d);
    double best = tmax;
    int found = 0;
    uint32_t stack[STACK];
    int sp = 0;
    if (slab(&b->nodes[0], &r, (float)best * 1.0001f + 1e-4f) == INFINITY) return 0;
    uint32_t node = 0;
    for (;;) {
        const sy_scan_bvh_node *nd = &b->nodes[node];
        if (nd->count) {
            for (uint32_t i = nd->start; i < nd->start + nd->count; i++) {
                double t;
                if (sy_prim_intersect(&b->prims[i], o, d, T_MIN, best, &t)) {
                    best = t;
                    hit->t = t;
                    hit->prim = i;
                    found = 1;
                }
            }
        } else {
            uint32_t l = node + 1, rr = nd->start;
            float lim = (float)best * 1.0001f + 1e-4f;
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
            if (slab(&b->nodes[c], &r, (float)best * 1.0001f + 1e-4f) != INFINITY) {
                node = c;
                next = 1;
                break;
            }
        }
        if (!next) break;
    }
    return found;
}

int sy_scan_bvh_intersect_brute(const sy_scan_bvh *b, const double o[3], const double d[3], double tmax, sy_hit *hit)
{
    double best = tmax;
    int found = 0;
    for (size_t i = 0; i < b->n_prims; i++) {
        double t;
        if (sy_prim_intersect(&b->prims[i], o, d, T_MIN, best, &t)) {
            best = t;
            hit->t = t;
            hit->prim = (uint32_t)i;
            found = 1;
        }
    }
    return found;
}
