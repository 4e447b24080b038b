#include "qsm_internal.h"
#include "stages/core/json.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------ topology */

void sy_skel_topo_free(sy_skel_topo *t)
{
    free(t->first);
    free(t->child);
    free(t->bfs);
    memset(t, 0, sizeof *t);
}

sy_code sy_skel_topo_build(const sy_skeleton *s, sy_skel_topo *t, sy_error *err)
{
    memset(t, 0, sizeof *t);
    size_t n = s->n;
    t->first = sy_calloc(n + 1, sizeof(int32_t), err, "skeleton topology");
    t->child = sy_calloc(n ? n : 1, sizeof(int32_t), err, "skeleton topology");
    t->bfs = sy_calloc(n ? n : 1, sizeof(int32_t), err, "skeleton topology");
    if (!t->first || !t->child || !t->bfs) {
        sy_skel_topo_free(t);
        return SY_EINTERNAL;
    }
    t->root = -1;
    for (size_t i = 0; i < n; i++) {
        if (s->parent[i] < 0) t->root = (int32_t)i;
        else t->first[s->parent[i] + 1]++;
    }
    for (size_t i = 0; i < n; i++) t->first[i + 1] += t->first[i];
    /* Fill children in index order: bfs doubles as a per-node cursor here. */
    for (size_t i = 0; i < n; i++) t->bfs[i] = t->first[i];
    for (size_t i = 0; i < n; i++)
        if (s->parent[i] >= 0) t->child[t->bfs[s->parent[i]]++] = (int32_t)i;
    size_t head = 0, tail = 0;
    if (n) t->bfs[tail++] = t->root;
    while (head < tail) {
        int32_t v = t->bfs[head++];
        for (int32_t k = t->first[v]; k < t->first[v + 1]; k++) t->bfs[tail++] = t->child[k];
    }
    if (tail != n) {
        sy_skel_topo_free(t);
        return sy_fail(err, SY_EINPUT, "skeleton: %zu nodes unreachable from the root", n - tail);
    }
    return SY_OK;
}

double sy_skel_edge_length(const sy_skeleton *s, int32_t i)
{
    int32_t p = s->parent[i];
    if (p < 0) return 0;
    double d2 = 0;
    for (int k = 0; k < 3; k++) {
        double d = (double)s->pos[3 * i + k] - (double)s->pos[3 * p + k];
        d2 += d * d;
    }
    return sqrt(d2);
}

sy_code sy_skeleton_growth_length(const sy_skeleton *s, double *growth, sy_error *err)
{
    sy_skel_topo t;
    sy_code rc = sy_skel_topo_build(s, &t, err);
    if (rc) return rc;
    for (size_t i = 0; i < s->n; i++) growth[i] = sy_skel_edge_length(s, (int32_t)i);
    for (size_t k = s->n; k-- > 1;) {
        int32_t v = t.bfs[k];
        growth[s->parent[v]] += growth[v];
    }
    sy_skel_topo_free(&t);
    return SY_OK;
}

sy_code sy_skeleton_reverse_order(const sy_skeleton *s, int32_t *rbo, sy_error *err)
{
    sy_skel_topo t;
    sy_code rc = sy_skel_topo_build(s, &t, err);
    if (rc) return rc;
    for (size_t k = s->n; k-- > 0;) {
        int32_t v = t.bfs[k];
        int32_t nc = t.first[v + 1] - t.first[v], best = 0;
        for (int32_t j = t.first[v]; j < t.first[v + 1]; j++)
            if (rbo[t.child[j]] > best) best = rbo[t.child[j]];
        rbo[v] = nc == 0 ? 1 : nc == 1 ? best : best + 1;
    }
    sy_skel_topo_free(&t);
    return SY_OK;
}

sy_code sy_skel_derive_structure(sy_skeleton *s, sy_error *err)
{
    double *growth = sy_calloc(s->n ? s->n : 1, sizeof(double), err, "skeleton structure");
    if (!growth) return SY_EINTERNAL;
    sy_skel_topo t;
    sy_code rc = sy_skeleton_growth_length(s, growth, err);
    if (!rc) rc = sy_skel_topo_build(s, &t, err);
    if (rc) {
        free(growth);
        return rc;
    }
    int32_t next_branch = 1;
    if (s->n) {
        s->order[t.root] = 0;
        s->branch[t.root] = 0;
    }
    for (size_t k = 0; k < s->n; k++) {
        int32_t v = t.bfs[k], main = -1;
        for (int32_t j = t.first[v]; j < t.first[v + 1]; j++)
            if (main < 0 || growth[t.child[j]] > growth[main]) main = t.child[j];
        for (int32_t j = t.first[v]; j < t.first[v + 1]; j++) {
            int32_t c = t.child[j];
            if (c == main) {
                s->order[c] = s->order[v];
                s->branch[c] = s->branch[v];
            } else {
                s->order[c] = (uint8_t)(s->order[v] < 255 ? s->order[v] + 1 : 255);
                s->branch[c] = next_branch++;
            }
        }
    }
    sy_skel_topo_free(&t);
    free(growth);
    return SY_OK;
}

/* ------------------------------------------------------------ numbers */

void sy_fmt_float(char *buf, size_t size, float v) { sy_format_float(buf, size, v); }

void sy_fmt_coord(char *buf, size_t size, double w, double o)
{
    float want = (float)(w - o);
    for (int prec = 6; prec <= 17; prec++) {
        snprintf(buf, size, "%.*g", prec, w);
        if ((float)(strtod(buf, NULL) - o) == want) return;
    }
}

int sy_qsm_parse_number(const char *b, const char *e, double *out)
{
    char tmp[72];
    size_t len = (size_t)(e - b);
    if (len == 0 || len >= sizeof tmp) return 0;
    memcpy(tmp, b, len);
    tmp[len] = '\0';
    char *stop;
    *out = strtod(tmp, &stop);
    return stop == tmp + len;
}

void sy_origin_floor(const double world[3], double origin[3])
{
    for (int k = 0; k < 3; k++) origin[k] = isfinite(world[k]) ? floor(world[k]) : 0;
}

/* ------------------------------------------------------------ assembly */

static double dist3(const double a[3], const double b[3])
{
    double d2 = 0;
    for (int k = 0; k < 3; k++) d2 += (a[k] - b[k]) * (a[k] - b[k]);
    return sqrt(d2);
}

typedef struct {
    long long id;
    size_t idx;
} id_slot;

static int cmp_slot(const void *a, const void *b)
{
    const id_slot *x = a, *y = b;
    if (x->id != y->id) return x->id < y->id ? -1 : 1;
    return x->idx < y->idx ? -1 : x->idx > y->idx;
}

static long find_id(const id_slot *slots, size_t n, long long id)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (slots[mid].id < id) lo = mid + 1;
        else hi = mid;
    }
    return lo < n && slots[lo].id == id ? (long)slots[lo].idx : -1;
}

/* Parent cylinder index per cylinder (-1 for roots); rejects duplicate IDs,
 * unknown parents and cycles with the offending line. */
static sy_code link_cylinders(const char *path, const sy_cyl *c, size_t n, long *pidx, sy_error *err)
{
    id_slot *slots = sy_calloc(n, sizeof *slots, err, "cylinder index");
    uint8_t *state = sy_calloc(n, 1, err, "cylinder index");
    sy_code rc = SY_OK;
    if (!slots || !state) {
        rc = SY_EINTERNAL;
        goto done;
    }
    for (size_t i = 0; i < n; i++) slots[i] = (id_slot){c[i].id, i};
    qsort(slots, n, sizeof *slots, cmp_slot);
    for (size_t i = 1; i < n; i++)
        if (slots[i].id == slots[i - 1].id) {
            rc = sy_fail(err, SY_EINPUT, "%s:%zu: duplicate cylinder ID %lld", path, c[slots[i].idx].line,
                         slots[i].id);
            goto done;
        }
    for (size_t i = 0; i < n; i++) {
        pidx[i] = -1;
        if (c[i].parent_id < 0) continue;
        pidx[i] = find_id(slots, n, c[i].parent_id);
        if (pidx[i] < 0) {
            rc = sy_fail(err, SY_EINPUT, "%s:%zu: parent ID %lld not found", path, c[i].line, c[i].parent_id);
            goto done;
        }
    }
    /* Walk up from each cylinder: meeting one on the current path is a cycle. */
    for (size_t i = 0; i < n; i++) {
        long v = (long)i;
        while (v >= 0 && state[v] == 0) {
            state[v] = 1;
            v = pidx[v];
        }
        if (v >= 0 && state[v] == 1) {
            rc = sy_fail(err, SY_EINPUT, "%s:%zu: cylinder ID %lld lies on a parent cycle", path, c[v].line,
                         c[v].id);
            goto done;
        }
        for (v = (long)i; v >= 0 && state[v] == 1; v = pidx[v]) state[v] = 2;
    }
done:
    free(slots);
    free(state);
    return rc;
}

static void set_node(sy_skeleton *s, double *world, int32_t node, const double w[3], const sy_cyl *c)
{
    memcpy(world + 3 * node, w, 3 * sizeof(double));
    s->radius[node] = c->radius;
    s->order[node] = (uint8_t)(c->order < 0 ? 0 : c->order);
    s->branch[node] = c->branch < 0 ? 0 : c->branch;
}

static sy_code finish_positions(sy_skeleton *s, const double *world, const double *origin)
{
    if (origin) memcpy(s->origin, origin, sizeof s->origin);
    else sy_origin_floor(world, s->origin);
    for (size_t i = 0; i < s->n; i++)
        for (int k = 0; k < 3; k++) s->pos[3 * i + k] = (float)(world[3 * i + k] - s->origin[k]);
    return SY_OK;
}

/* Validation failures of an assembled skeleton, prefixed with the file. */
static sy_code fail_invalid(const char *path, sy_error *err)
{
    char msg[sizeof err->msg];
    snprintf(msg, sizeof msg, "%s", err ? err->msg : "invalid skeleton");
    return sy_fail(err, SY_EINPUT, "%s: %s", path, msg);
}

sy_code sy_cylinders_to_skeleton(const char *path, const sy_cyl *c, size_t n, double tol,
                                 sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err)
{
    memset(out, 0, sizeof *out);
    if (n == 0) return sy_fail(err, SY_EINPUT, "%s: no cylinders", path);
    if (n > (size_t)INT32_MAX / 2 - 1) return sy_fail(err, SY_EINPUT, "%s: too many cylinders", path);
    long *pidx = sy_calloc(n, sizeof(long), err, "cylinders");
    int32_t *endn = sy_calloc(n, sizeof(int32_t), err, "cylinders");
    int32_t *startn = sy_calloc(n, sizeof(int32_t), err, "cylinders");
    int32_t *own = sy_calloc(n, sizeof(int32_t), err, "cylinders");
    size_t *roots = sy_calloc(n, sizeof(size_t), err, "cylinders");
    double *world = NULL;
    sy_code rc = SY_OK;
    if (!pidx || !endn || !startn || !own || !roots) {
        rc = SY_EINTERNAL;
        goto done;
    }
    if ((rc = link_cylinders(path, c, n, pidx, err))) goto done;
    size_t nr = 0;
    for (size_t i = 0; i < n; i++)
        if (pidx[i] < 0) roots[nr++] = i;
    size_t r0 = roots[0]; /* the lowest start; the first in the file on ties */
    for (size_t k = 1; k < nr; k++)
        if (c[roots[k]].start[2] < c[r0].start[2]) r0 = roots[k];

    /* Pass 1: node numbers. The main root first so it becomes node 0, then
     * every other cylinder in file order; a cylinder owns its end node and,
     * where its start meets no parent end, a start node just before it. */
    int32_t nn = 0;
    int r0_point = dist3(c[r0].start, c[r0].end) == 0;
    own[r0] = r0_point ? -1 : nn++;
    endn[r0] = nn++;
    size_t gaps = 0;
    int joined = 0;
    for (size_t i = 0; i < n; i++) {
        if (i == r0) continue;
        own[i] = -1;
        if (pidx[i] < 0) {
            if (dist3(c[i].start, r0_point ? c[r0].end : c[r0].start) > tol) {
                own[i] = nn++;
                joined = 1;
            }
        } else if (dist3(c[i].start, c[pidx[i]].end) > tol) {
            own[i] = nn++;
            gaps++;
        }
        endn[i] = nn++;
    }
    int32_t node0 = 0;
    /* Pass 2: where each cylinder starts. */
    for (size_t i = 0; i < n; i++) {
        if (own[i] >= 0) startn[i] = own[i];
        else if (i == r0) startn[i] = endn[i];
        else if (pidx[i] < 0) startn[i] = node0;
        else startn[i] = endn[pidx[i]];
    }
    if ((rc = sy_skeleton_init(out, (size_t)nn, err))) goto done;
    world = sy_calloc((size_t)nn, 3 * sizeof(double), err, "cylinders");
    if (!world) {
        rc = SY_EINTERNAL;
        goto done;
    }
    for (size_t i = 0; i < n; i++) {
        set_node(out, world, endn[i], c[i].end, &c[i]);
        out->parent[endn[i]] = i == r0 && r0_point ? -1 : startn[i];
        if (own[i] < 0) continue;
        set_node(out, world, own[i], c[i].start, &c[i]);
        if (i == r0) out->parent[own[i]] = -1;
        else if (pidx[i] < 0) out->parent[own[i]] = node0;
        else out->parent[own[i]] = startn[pidx[i]];
    }
    finish_positions(out, world, NULL);
    int derive = 0;
    for (size_t i = 0; i < n; i++)
        if (c[i].order < 0 || c[i].branch < 0) derive = 1;
    if (derive && (rc = sy_skel_derive_structure(out, err))) goto done;
    if (info) {
        info->records = n;
        info->input_roots = nr;
        info->virtual_root = joined;
        info->gap_nodes = gaps;
        info->derived_structure = derive;
    }
    if (sy_skeleton_validate(out, err)) rc = fail_invalid(path, err);
done:
    if (rc) sy_skeleton_free(out);
    free(pidx);
    free(endn);
    free(startn);
    free(own);
    free(roots);
    free(world);
    return rc;
}

/* Union-find root with path halving. */
static uint32_t uf_find(uint32_t *up, uint32_t v)
{
    while (up[v] != v) {
        up[v] = up[up[v]];
        v = up[v];
    }
    return v;
}

static void edge_where(char *buf, size_t size, const sy_graph_in *g, size_t e)
{
    if (g->edge_line) snprintf(buf, size, ":%zu", g->edge_line[e]);
    else snprintf(buf, size, ": edge %zu", e);
}

/* Checks the edges form one tree over all vertices. */
static sy_code check_tree(const char *path, const sy_graph_in *g, sy_error *err)
{
    uint32_t *up = sy_calloc(g->n, sizeof(uint32_t), err, "skeleton graph");
    if (!up) return SY_EINTERNAL;
    for (size_t i = 0; i < g->n; i++) up[i] = (uint32_t)i;
    sy_code rc = SY_OK;
    size_t parts = g->n;
    char where[48];
    for (size_t e = 0; e < g->m && !rc; e++) {
        uint32_t a = g->edges[2 * e], b = g->edges[2 * e + 1];
        edge_where(where, sizeof where, g, e);
        if (a >= g->n || b >= g->n)
            rc = sy_fail(err, SY_EINPUT, "%s%s: edge %u-%u names a vertex beyond the %zu present", path, where, a,
                         b, g->n);
        else if (a == b)
            rc = sy_fail(err, SY_EINPUT, "%s%s: edge joins vertex %u to itself", path, where, a);
        else {
            uint32_t ra = uf_find(up, a), rb = uf_find(up, b);
            if (ra == rb) rc = sy_fail(err, SY_EINPUT, "%s%s: edge %u-%u closes a cycle", path, where, a, b);
            up[ra] = rb;
            parts--;
        }
    }
    if (!rc && parts != 1)
        rc = sy_fail(err, SY_EINPUT, "%s: the skeleton falls into %zu disconnected parts", path, parts);
    free(up);
    return rc;
}

sy_code sy_graph_to_skeleton(const char *path, const sy_graph_in *g, sy_skeleton *out,
                             sy_skeleton_read_info *info, sy_error *err)
{
    memset(out, 0, sizeof *out);
    if (g->n == 0) return sy_fail(err, SY_EINPUT, "%s: no vertices", path);
    if (g->n > (size_t)INT32_MAX) return sy_fail(err, SY_EINPUT, "%s: too many vertices", path);
    sy_code rc = check_tree(path, g, err);
    if (rc) return rc;
    size_t n = g->n, root = 0;
    if (g->root >= 0 && (size_t)g->root < n) root = (size_t)g->root;
    else
        for (size_t i = 1; i < n; i++)
            if (g->world[3 * i + 2] < g->world[3 * root + 2]) root = i;
    /* The root trades places with vertex 0 so node 0 is the root. */
#define MAPV(v) ((v) == root ? 0 : (v) == 0 ? root : (v))
    int32_t *first = sy_calloc(n + 1, sizeof(int32_t), err, "skeleton graph");
    int32_t *adj = sy_calloc(2 * g->m + 1, sizeof(int32_t), err, "skeleton graph");
    int32_t *queue = sy_calloc(n, sizeof(int32_t), err, "skeleton graph");
    double *world = sy_calloc(n, 3 * sizeof(double), err, "skeleton graph");
    if (!first || !adj || !queue || !world || (rc = sy_skeleton_init(out, n, err))) {
        rc = rc ? rc : SY_EINTERNAL;
        goto done;
    }
    for (size_t e = 0; e < g->m; e++) {
        first[MAPV(g->edges[2 * e]) + 1]++;
        first[MAPV(g->edges[2 * e + 1]) + 1]++;
    }
    for (size_t i = 0; i < n; i++) first[i + 1] += first[i];
    for (size_t i = 0; i < n; i++) queue[i] = first[i];
    for (size_t e = 0; e < g->m; e++) {
        int32_t a = (int32_t)MAPV(g->edges[2 * e]), b = (int32_t)MAPV(g->edges[2 * e + 1]);
        adj[queue[a]++] = b;
        adj[queue[b]++] = a;
    }
    for (size_t i = 0; i < n; i++) {
        size_t src = MAPV(i);
        memcpy(world + 3 * i, g->world + 3 * src, 3 * sizeof(double));
        out->radius[i] = g->radius[src];
        out->order[i] = (uint8_t)(g->order ? (g->order[src] < 0 ? 0 : g->order[src] > 255 ? 255 : g->order[src]) : 0);
        out->branch[i] = g->branch ? g->branch[src] : 0;
        out->parent[i] = -2;
    }
#undef MAPV
    size_t head = 0, tail = 0;
    queue[tail++] = 0;
    out->parent[0] = -1;
    while (head < tail) {
        int32_t v = queue[head++];
        for (int32_t k = first[v]; k < first[v + 1]; k++)
            if (out->parent[adj[k]] == -2) {
                out->parent[adj[k]] = v;
                queue[tail++] = adj[k];
            }
    }
    finish_positions(out, world, g->origin);
    int derive = !g->order || !g->branch;
    if (derive && (rc = sy_skel_derive_structure(out, err))) goto done;
    if (info) {
        info->records = n;
        info->input_roots = 1;
        info->derived_structure = derive;
    }
    if (sy_skeleton_validate(out, err)) rc = fail_invalid(path, err);
done:
    if (rc) sy_skeleton_free(out);
    free(first);
    free(adj);
    free(queue);
    free(world);
    return rc;
}
