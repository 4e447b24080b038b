#include "skeleton.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "cloud.h"

sy_code sy_skeleton_init(sy_skeleton *s, size_t n, sy_error *err)
{
    memset(s, 0, sizeof *s);
    if (n == 0) return SY_OK;
    s->pos = sy_calloc(n, 3 * sizeof(float), err, "skeleton");
    s->radius = sy_calloc(n, sizeof(float), err, "skeleton");
    s->parent = sy_calloc(n, sizeof(int32_t), err, "skeleton");
    s->order = sy_calloc(n, 1, err, "skeleton");
    s->branch = sy_calloc(n, sizeof(int32_t), err, "skeleton");
    if (!s->pos || !s->radius || !s->parent || !s->order || !s->branch) {
        sy_skeleton_free(s);
        return SY_EINTERNAL;
    }
    s->n = n;
    return SY_OK;
}

void sy_skeleton_free(sy_skeleton *s)
{
    free(s->pos);
    free(s->radius);
    free(s->parent);
    free(s->order);
    free(s->branch);
    free(s->support_start);
    free(s->support);
    memset(s, 0, sizeof *s);
}

/* Grows every per-node array to hold cap nodes. */
static int grow(sy_skeleton *s, size_t cap)
{
    void *p;
    if (!(p = realloc(s->pos, cap * 3 * sizeof(float)))) return 0;
    s->pos = p;
    if (!(p = realloc(s->radius, cap * sizeof(float)))) return 0;
    s->radius = p;
    if (!(p = realloc(s->parent, cap * sizeof(int32_t)))) return 0;
    s->parent = p;
    if (!(p = realloc(s->order, cap))) return 0;
    s->order = p;
    if (!(p = realloc(s->branch, cap * sizeof(int32_t)))) return 0;
    s->branch = p;
    return 1;
}

int32_t sy_skeleton_add(sy_skeleton *s, const float pos[3], float radius, int32_t parent, int order,
                        int32_t branch, sy_error *err)
{
    /* Capacity doubles at powers of two, so n itself tells when to grow. */
    size_t n = s->n;
    if (n >= INT32_MAX) {
        sy_fail(err, SY_EINTERNAL, "skeleton: too many nodes");
        return -1;
    }
    if ((n & (n - 1)) == 0 && !grow(s, n ? 2 * n : 1)) {
        sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
        return -1;
    }
    memcpy(s->pos + 3 * n, pos, 3 * sizeof(float));
    s->radius[n] = radius;
    s->parent[n] = parent;
    s->order[n] = (uint8_t)(order < 0 ? 0 : order > 255 ? 255 : order);
    s->branch[n] = branch;
    s->n = n + 1;
    return (int32_t)n;
}

sy_code sy_skeleton_validate(const sy_skeleton *s, sy_error *err)
{
    size_t roots = 0;
    if (s->lobes < 0 || !(s->lobe_depth >= 0 && s->lobe_depth < 1))
        return sy_fail(err, SY_EINPUT, "skeleton: %d trunk lobes of depth %g (want lobes >= 0, depth in [0, 1))",
                       s->lobes, (double)s->lobe_depth);
    for (size_t i = 0; i < s->n; i++) {
        if (s->parent[i] < -1 || s->parent[i] >= (int32_t)s->n || s->parent[i] == (int32_t)i)
            return sy_fail(err, SY_EINPUT, "skeleton: node %zu has invalid parent %d", i, s->parent[i]);
        if (s->parent[i] == -1) roots++;
        for (int k = 0; k < 3; k++)
            if (!isfinite(s->pos[3 * i + k])) return sy_fail(err, SY_EINPUT, "skeleton: node %zu position is not finite", i);
        if (!(s->radius[i] > 0) || !isfinite(s->radius[i]))
            return sy_fail(err, SY_EINPUT, "skeleton: node %zu radius %g is not positive", i, s->radius[i]);
        if (s->radius[i] > SY_SKELETON_MAX_RADIUS)
            return sy_fail(err, SY_EINPUT, "skeleton: node %zu radius %g m exceeds %g m (a corrupt value?)", i,
                           s->radius[i], SY_SKELETON_MAX_RADIUS);
    }
    if (s->n && roots != 1) return sy_fail(err, SY_EINPUT, "skeleton: %zu roots, expected exactly one", roots);
    for (int k = 0; k < 3; k++)
        if (!(fabs(s->origin[k]) <= SY_WORLD_MAX))
            return sy_fail(err, SY_EINPUT, "skeleton: origin %g on axis %c lies beyond %g m", s->origin[k], 'x' + k,
                           SY_WORLD_MAX);
    size_t root = 0;
    while (root < s->n && s->parent[root] != -1) root++;
    for (size_t i = 0; i < s->n; i++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) {
            double d = (double)s->pos[3 * i + k] - s->pos[3 * root + k];
            d2 += d * d;
        }
        if (!(d2 <= SY_SKELETON_MAX_SPAN * SY_SKELETON_MAX_SPAN))
            return sy_fail(err, SY_EINPUT, "skeleton: node %zu lies %.3g m from the root (a tree spans at most %g m)", i,
                           sqrt(d2), SY_SKELETON_MAX_SPAN);
    }
    /* Cycle check: walking up from any node must reach the root within n steps. */
    uint8_t *state = calloc(s->n ? s->n : 1, 1); /* 0 unknown, 1 on path, 2 reaches root */
    if (!state) return sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
    for (size_t i = 0; i < s->n; i++) {
        int32_t v = (int32_t)i;
        while (v >= 0 && state[v] == 0) {
            state[v] = 1;
            v = s->parent[v];
        }
        if (v >= 0 && state[v] == 1) {
            free(state);
            return sy_fail(err, SY_EINPUT, "skeleton: parent links form a cycle through node %d", v);
        }
        for (v = (int32_t)i; v >= 0 && state[v] == 1; v = s->parent[v]) state[v] = 2;
    }
    free(state);
    return SY_OK;
}

int32_t sy_skeleton_branch_count(const sy_skeleton *s)
{
    int32_t m = -1;
    for (size_t i = 0; i < s->n; i++)
        if (s->branch[i] > m) m = s->branch[i];
    return m + 1;
}

double sy_skeleton_radius_at_height(const sy_skeleton *s, const int32_t *path, size_t n, double z, double span[2])
{
    for (size_t i = 1; i < n; i++) {
        double za = s->pos[3 * (size_t)path[i - 1] + 2], zc = s->pos[3 * (size_t)path[i] + 2];
        if ((za <= z && zc >= z) || (za >= z && zc <= z)) {
            double t = zc != za ? (z - za) / (zc - za) : 0;
            if (span) span[0] = za < zc ? za : zc, span[1] = za < zc ? zc : za;
            return s->radius[path[i - 1]] + t * (s->radius[path[i]] - s->radius[path[i - 1]]);
        }
    }
    return NAN;
}

double sy_skeleton_height(const sy_skeleton *s)
{
    if (s->n == 0) return 0;
    size_t root = 0;
    float top = s->pos[2];
    for (size_t i = 0; i < s->n; i++) {
        if (s->parent[i] < 0) root = i;
        if (s->pos[3 * i + 2] > top) top = s->pos[3 * i + 2];
    }
    return (double)top - s->pos[3 * root + 2];
}

double sy_skeleton_length(const sy_skeleton *s)
{
    double total = 0;
    for (size_t i = 0; i < s->n; i++) {
        int32_t p = s->parent[i];
        if (p < 0) continue;
        double d2 = 0;
        for (int k = 0; k < 3; k++) {
            double d = s->pos[3 * i + k] - s->pos[3 * p + k];
            d2 += d * d;
        }
        total += sqrt(d2);
    }
    return total;
}

void sy_leaves_free(sy_leaves *l)
{
    free(l->pos);
    free(l->rot);
    free(l->scale);
    free(l->node);
    memset(l, 0, sizeof *l);
}

sy_code sy_leaves_add(sy_leaves *l, const float pos[3], const float rot[4], float scale, int32_t node,
                      sy_error *err)
{
    size_t n = l->n;
    if ((n & (n - 1)) == 0) {
        size_t cap = n ? 2 * n : 1;
        void *a = realloc(l->pos, cap * 3 * sizeof(float));
        if (a) l->pos = a;
        void *b = realloc(l->rot, cap * 4 * sizeof(float));
        if (b) l->rot = b;
        void *c = realloc(l->scale, cap * sizeof(float));
        if (c) l->scale = c;
        void *d = realloc(l->node, cap * sizeof(int32_t));
        if (d) l->node = d;
        if (!a || !b || !c || !d) return sy_fail(err, SY_EINTERNAL, "leaves: out of memory");
    }
    memcpy(l->pos + 3 * n, pos, 3 * sizeof(float));
    memcpy(l->rot + 4 * n, rot, 4 * sizeof(float));
    l->scale[n] = scale;
    l->node[n] = node;
    l->n = n + 1;
    return SY_OK;
}

void sy_skeleton_children(const sy_skeleton *s, int32_t *first_child, int32_t *next_sibling)
{
    for (size_t i = 0; i < s->n; i++) first_child[i] = next_sibling[i] = -1;
    for (size_t i = s->n; i-- > 0;) {
        int32_t p = s->parent[i];
        if (p < 0) continue;
        next_sibling[i] = first_child[p];
        first_child[p] = (int32_t)i;
    }
}

size_t sy_skeleton_breadth_first(const sy_skeleton *s, const int32_t *first_child, const int32_t *next_sibling,
                                 int32_t *order)
{
    size_t m = 0;
    for (size_t i = 0; i < s->n; i++)
        if (s->parent[i] < 0) order[m++] = (int32_t)i;
    for (size_t h = 0; h < m; h++)
        for (int32_t c = first_child[order[h]]; c >= 0; c = next_sibling[c]) order[m++] = c;
    return m;
}

void sy_skeleton_branch_next(const sy_skeleton *s, int32_t *next)
{
    for (size_t i = 0; i < s->n; i++) next[i] = -1;
    for (size_t i = 0; i < s->n; i++) {
        int32_t p = s->parent[i];
        if (p >= 0 && s->branch[p] == s->branch[i] && next[p] < 0) next[p] = (int32_t)i;
    }
}

void sy_skeleton_continuations(const sy_skeleton *s, int32_t *cont)
{
    size_t n = s->n;
    sy_skeleton_branch_next(s, cont);
    for (size_t i = 0; i < n; i++) {
        int32_t p = s->parent[i], g = p >= 0 ? s->parent[p] : -1;
        if (p < 0 || g < 0) continue;
        if (cont[p] >= 0 && s->branch[cont[p]] == s->branch[p]) continue; /* goes on in its own id */
        float a[3], b[3];
        for (int k = 0; k < 3; k++) {
            a[k] = s->pos[3 * (size_t)p + k] - s->pos[3 * (size_t)g + k];
            b[k] = s->pos[3 * i + k] - s->pos[3 * (size_t)p + k];
        }
        float ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2], aa = a[0] * a[0] + a[1] * a[1] + a[2] * a[2],
              bb = b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
        if (!(aa > 0 && bb > 0) || ab < 0.5f * sqrtf(aa * bb)) continue; /* turns by more than 60 degrees */
        if (cont[p] < 0 || s->radius[i] > s->radius[cont[p]]) cont[p] = (int32_t)i;
    }
}

double sy_skeleton_edge_length(const sy_skeleton *s, size_t i)
{
    int32_t p = s->parent[i];
    if (p < 0) return 0;
    double d2 = 0;
    for (int a = 0; a < 3; a++) {
        double d = s->pos[3 * i + a] - s->pos[3 * (size_t)p + a];
        d2 += d * d;
    }
    return sqrt(d2);
}

void sy_skeleton_subtree_lengths(const sy_skeleton *s, double *l)
{
    for (size_t i = 0; i < s->n; i++) l[i] = sy_skeleton_edge_length(s, i);
    for (size_t i = s->n; i-- > 1;)
        if (s->parent[i] >= 0) l[s->parent[i]] += l[i];
}

void sy_skeleton_assign_branches(sy_skeleton *s, const double *l)
{
    size_t n = s->n;
    int32_t *cont = malloc((n ? n : 1) * sizeof *cont);
    if (!cont) return; /* leaves the previous ids: only cosmetic information is lost */
    for (size_t i = 0; i < n; i++) cont[i] = -1;
    for (size_t i = 1; i < n; i++) {
        int32_t p = s->parent[i];
        if (p >= 0 && (cont[p] < 0 || l[i] > l[cont[p]])) cont[p] = (int32_t)i;
    }
    int32_t next = 0;
    for (size_t i = 0; i < n; i++) {
        int32_t p = s->parent[i];
        if (p < 0) {
            s->branch[i] = next++;
            s->order[i] = 0;
        } else if (cont[p] == (int32_t)i) {
            s->branch[i] = s->branch[p];
            s->order[i] = s->order[p];
        } else {
            s->branch[i] = next++;
            s->order[i] = (uint8_t)(s->order[p] < 255 ? s->order[p] + 1 : 255);
        }
    }
    free(cont);
}

sy_code sy_skeleton_prepend_root(sy_skeleton *s, float z, sy_error *err)
{
    if (s->n == 0) return sy_fail(err, SY_EINTERNAL, "skeleton: no root to extend");
    sy_skeleton t;
    sy_code rc = sy_skeleton_init(&t, s->n + 1, err);
    if (rc) return rc;
    if (s->support_start) {
        t.support_start = sy_calloc(s->n + 2, sizeof *t.support_start, err, "skeleton");
        if (!t.support_start) {
            sy_skeleton_free(&t);
            return SY_EINTERNAL;
        }
        for (size_t i = 0; i <= s->n; i++) t.support_start[i + 1] = s->support_start[i];
    }
    memcpy(t.origin, s->origin, sizeof t.origin);
    t.pos[0] = s->pos[0];
    t.pos[1] = s->pos[1];
    t.pos[2] = z;
    t.parent[0] = -1;
    t.radius[0] = s->radius[0];
    t.order[0] = s->order[0];
    t.branch[0] = s->branch[0];
    memcpy(t.pos + 3, s->pos, 3 * s->n * sizeof *s->pos);
    memcpy(t.radius + 1, s->radius, s->n * sizeof *s->radius);
    memcpy(t.order + 1, s->order, s->n * sizeof *s->order);
    memcpy(t.branch + 1, s->branch, s->n * sizeof *s->branch);
    for (size_t i = 0; i < s->n; i++) t.parent[i + 1] = s->parent[i] + 1; /* the old root's -1 becomes 0 */
    t.lobes = s->lobes;
    t.lobe_depth = s->lobe_depth;
    t.support = s->support;
    s->support = NULL;
    sy_skeleton_free(s);
    *s = t;
    return SY_OK;
}

void sy_full_skeleton_free(sy_full_skeleton *f)
{
    if (!f) return;
    sy_skeleton_free(&f->full);
    free(f->point_node);
    free(f->wood);
    free(f->measured);
    memset(f, 0, sizeof *f);
}
