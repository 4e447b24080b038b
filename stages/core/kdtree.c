/* Static 3-d kd-tree with per-node labels (kdtree.h). */
#include "stages/core/kdtree.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define LEAF 8

/* Strict total order on points along axis a: coordinate, then index, so the
 * split is the same whatever order the points arrive in. */
static int before(const float *xyz, int a, uint32_t i, uint32_t j)
{
    float x = xyz[3 * (size_t)i + a], y = xyz[3 * (size_t)j + a];
    return x < y || (x == y && i < j);
}

/* Reorders v[0..n) so v[k] is the k-th in the order above, smaller ones before
 * it (Hoare's selection with a median-of-three pivot). */
static void select_kth(const float *xyz, int a, uint32_t *v, size_t n, size_t k)
{
    size_t lo = 0, hi = n - 1;
    while (hi > lo) {
        size_t mid = lo + (hi - lo) / 2;
        if (before(xyz, a, v[mid], v[lo])) { uint32_t t = v[mid]; v[mid] = v[lo]; v[lo] = t; }
        if (before(xyz, a, v[hi], v[lo])) { uint32_t t = v[hi]; v[hi] = v[lo]; v[lo] = t; }
        if (before(xyz, a, v[hi], v[mid])) { uint32_t t = v[hi]; v[hi] = v[mid]; v[mid] = t; }
        uint32_t pivot = v[mid];
        size_t i = lo, j = hi;
        for (;;) {
            while (before(xyz, a, v[i], pivot)) i++;
            while (before(xyz, a, pivot, v[j])) j--;
            if (i >= j) break;
            uint32_t t = v[i];
            v[i] = v[j];
            v[j] = t;
            i++;
            j--;
        }
        /* v[lo..j] <= pivot <= v[j+1..hi] */
        if (k <= j) hi = j;
        else lo = j + 1;
    }
}

static int32_t build(sy_kdtree *t, uint32_t begin, uint32_t end)
{
    int32_t id = (int32_t)t->n_nodes++;
    sy_kd_node *nd = &t->node[id];
    for (int a = 0; a < 3; a++) {
        nd->lo[a] = INFINITY;
        nd->hi[a] = -INFINITY;
    }
    for (uint32_t s = begin; s < end; s++)
        for (int a = 0; a < 3; a++) {
            float v = t->xyz[3 * (size_t)t->order[s] + a];
            if (v < nd->lo[a]) nd->lo[a] = v;
            if (v > nd->hi[a]) nd->hi[a] = v;
        }
    nd->begin = begin;
    nd->end = end;
    nd->left = nd->right = -1;
    nd->label = SY_KD_MIXED;
    if (end - begin <= LEAF) return id;
    int axis = 0;
    for (int a = 1; a < 3; a++)
        if (nd->hi[a] - nd->lo[a] > nd->hi[axis] - nd->lo[axis]) axis = a;
    uint32_t mid = begin + (end - begin) / 2;
    select_kth(t->xyz, axis, t->order + begin, end - begin, mid - begin);
    int32_t l = build(t, begin, mid);
    int32_t r = build(t, mid, end);
    t->node[id].left = l;
    t->node[id].right = r;
    return id;
}

sy_code sy_kdtree_build(sy_kdtree *t, const float *xyz, size_t n, sy_error *err)
{
    memset(t, 0, sizeof *t);
    if (n >= UINT32_MAX) return sy_fail(err, SY_EINPUT, "kd-tree: %zu points are too many", n);
    t->xyz = xyz;
    t->n = n;
    t->order = sy_calloc(n ? n : 1, sizeof *t->order, err, "kd-tree");
    /* A node per leaf of at least LEAF/2 points, doubled for the inner ones. */
    size_t cap = 2 * (n / (LEAF / 2) + 1) + 1;
    t->node = sy_calloc(cap, sizeof *t->node, err, "kd-tree");
    if (!t->order || !t->node) {
        sy_kdtree_free(t);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < n; i++) t->order[i] = (uint32_t)i;
    if (n) build(t, 0, (uint32_t)n);
    return SY_OK;
}

void sy_kdtree_free(sy_kdtree *t)
{
    free(t->order);
    free(t->node);
    memset(t, 0, sizeof *t);
}

void sy_kdtree_relabel(sy_kdtree *t, const uint32_t *label)
{
    t->label = label;
    /* Children have higher ids than their parent: one backward sweep. */
    for (size_t k = t->n_nodes; k-- > 0;) {
        sy_kd_node *nd = &t->node[k];
        if (nd->left < 0) {
            uint32_t l = label[t->order[nd->begin]];
            for (uint32_t s = nd->begin + 1; s < nd->end && l != SY_KD_MIXED; s++)
                if (label[t->order[s]] != l) l = SY_KD_MIXED;
            nd->label = l;
        } else {
            uint32_t a = t->node[nd->left].label, b = t->node[nd->right].label;
            nd->label = a == b ? a : SY_KD_MIXED;
        }
    }
}

static double box_d2(const sy_kd_node *nd, const float q[3])
{
    double d2 = 0;
    for (int a = 0; a < 3; a++) {
        double d = q[a] < nd->lo[a] ? nd->lo[a] - q[a] : q[a] > nd->hi[a] ? q[a] - nd->hi[a] : 0;
        d2 += d * d;
    }
    return d2;
}

void sy_kdtree_nearest_foreign(const sy_kdtree *t, const float q[3], uint32_t own, double *best_d2,
                               uint32_t *best_j)
{
    if (!t->n_nodes) return;
    int32_t stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top) {
        const sy_kd_node *nd = &t->node[stack[--top]];
        if (nd->label == own || box_d2(nd, q) > *best_d2) continue;
        if (nd->left < 0) {
            for (uint32_t s = nd->begin; s < nd->end; s++) {
                uint32_t j = t->order[s];
                if (t->label[j] == own) continue;
                const float *p = t->xyz + 3 * (size_t)j;
                double dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
                double d2 = dx * dx + dy * dy + dz * dz;
                if (d2 < *best_d2 || (d2 == *best_d2 && j < *best_j)) {
                    *best_d2 = d2;
                    *best_j = j;
                }
            }
            continue;
        }
        /* Nearer child last on the stack: visited first. */
        const sy_kd_node *l = &t->node[nd->left], *r = &t->node[nd->right];
        double dl = box_d2(l, q), dr = box_d2(r, q);
        /* Median splits keep the depth under 32 for any n < 2^32: the stack never fills. */
        if (dl <= dr) {
            stack[top++] = nd->right;
            stack[top++] = nd->left;
        } else {
            stack[top++] = nd->left;
            stack[top++] = nd->right;
        }
    }
}
