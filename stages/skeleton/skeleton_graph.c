/* Neighbour graph over the points (kNN joined with a radius graph, bridged to
 * one component) and the Dijkstra shortest-path tree over it.
 *
 * Spatial queries use a uniform grid hashed by cell: with the cell edge equal
 * to the join radius (about two point spacings) a query almost always ends
 * after the 27 cells around the point, which is faster than a kd-tree for the
 * near-uniform spacing of voxel-thinned scans and keeps the code in C. */
#include "stages/skeleton/skeleton.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/array.h"
#include "stages/core/grid.h"
#include "stages/core/kdtree.h"
#include "stages/core/parallel.h"
#include "stages/core/sort.h"
#include "stages/core/vec3.h"

/* Visits the cells whose Chebyshev ring distance from c is exactly r. */
#define FOR_RING(g, c, r, cell, BODY)                                                                  \
    for (int32_t dz_ = -(r); dz_ <= (r); dz_++)                                                        \
        for (int32_t dy_ = -(r); dy_ <= (r); dy_++)                                                    \
            for (int32_t dx_ = -(r); dx_ <= (r); dx_++) {                                              \
                if (abs(dx_) != (r) && abs(dy_) != (r) && abs(dz_) != (r)) continue;                   \
                long cell = sy_grid_find(g, (c)[0] + dx_, (c)[1] + dy_, (c)[2] + dz_);                 \
                if (cell < 0) continue;                                                                \
                BODY                                                                                   \
            }

/* ---- k nearest within a few rings ---- */

typedef struct {
    float d2;
    uint32_t j;
} cand;

/* Inserts (d2, j) into the sorted list of at most cap entries. */
static void cand_insert(cand *list, int *len, int cap, float d2, uint32_t j)
{
    if (*len == cap && d2 >= list[cap - 1].d2) return;
    int i = *len < cap ? (*len)++ : cap - 1;
    while (i > 0 && (list[i - 1].d2 > d2 || (list[i - 1].d2 == d2 && list[i - 1].j > j))) {
        list[i] = list[i - 1];
        i--;
    }
    list[i].d2 = d2;
    list[i].j = j;
}

/* Up to cap nearest other points of q, searching rings until the need-th
 * nearest is certain and every point within one cell edge has been seen, or
 * max_ring is reached. */
static int knn_query(const sy_grid *g, const float *xyz, uint32_t q, int need, int cap, int max_ring, cand *list)
{
    int len = 0;
    int32_t c[3];
    sy_grid_cell_of(g, xyz + 3 * (size_t)q, c);
    for (int r = 0; r <= max_ring; r++) {
        FOR_RING(g, c, r, cell, {
            for (size_t t = g->cell_start[cell]; t < g->cell_start[cell + 1]; t++) {
                uint32_t j = g->order[t];
                if (j != q) cand_insert(list, &len, cap, (float)sy_v3f_dist2(xyz + 3 * (size_t)q, xyz + 3 * (size_t)j), j);
            }
        })
        double reach = r * g->h;
        if (r >= 1 && len >= need && list[need - 1].d2 <= reach * reach) break;
    }
    return len;
}

double sy_estimate_spacing(const float *xyz, size_t n)
{
    if (n < 2) return 0;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], xyz[3 * i + a]);
            hi[a] = fmax(hi[a], xyz[3 * i + a]);
        }
    double vol = 1;
    for (int a = 0; a < 3; a++) vol *= fmax(hi[a] - lo[a], 1e-3);
    sy_grid g;
    sy_error err;
    if (sy_grid_build(&g, xyz, n, cbrt(vol / (double)n), &err)) return 0;
    size_t samples = n < 2000 ? n : 2000;
    double *d = malloc(samples * sizeof *d);
    size_t m = 0;
    for (size_t s = 0; d && s < samples; s++) {
        uint32_t q = (uint32_t)(s * (n / samples));
        cand best = {0, 0};
        if (knn_query(&g, xyz, q, 1, 1, 8, &best) == 1 && best.d2 > 0) d[m++] = sqrt(best.d2);
    }
    double med = 0;
    if (m) {
        /* Insertion-free median: partial selection is overkill for 2000 values. */
        for (size_t i = 1; i < m; i++) {
            double v = d[i];
            size_t j = i;
            while (j > 0 && d[j - 1] > v) {
                d[j] = d[j - 1];
                j--;
            }
            d[j] = v;
        }
        med = d[m / 2];
    }
    free(d);
    sy_grid_free(&g);
    return med;
}

/* ---- Graph construction ---- */

typedef struct {
    const sy_grid *g, *tier;
    int last_tier;
    const float *xyz;
    int k, cap;
    double r2;
    uint32_t *nbr; /* cap per point */
    uint8_t *cnt;
    uint8_t *pending; /* not settled by the fine grid: the coarse pass takes it */
} knn_job;

/* Appends the grid slots of cell nb's points to *near (*nn used, room for
 * *cap, doubled as needed); 0 when out of memory, the list as it was. */
static int gather_cell(const sy_grid *g, long nb, uint32_t **near, size_t *nn, size_t *cap)
{
    size_t s = g->cell_start[nb], e = g->cell_start[nb + 1];
    if (sy_array_reserve(near, cap, *nn + (e - s), sizeof **near, *cap, NULL, "neighbours")) return 0;
    for (size_t t = s; t < e; t++) (*near)[(*nn)++] = (uint32_t)t;
    return 1;
}

/* Queries run cell by cell: the 27 cells around a cell are looked up once
 * and their points serve every point of the cell, which settles most queries
 * (all points within one cell edge are then known); the rest (sparse parts,
 * e.g. foliage) search the 27 cells of a grid four times coarser. */
static void knn_chunk(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    knn_job *J = ctx;
    const sy_grid *g = J->g;
    cand list[64];
    size_t cap_near = 1024;
    uint32_t *near = malloc(cap_near * sizeof *near);
    for (size_t cell = begin; cell < end; cell++) {
        const int32_t *c = g->cell_coord + 3 * cell;
        size_t nn = 0;
        int ok = near != NULL;
        FOR_RING(g, c, 1, nb, {
            if (ok) ok = gather_cell(g, nb, &near, &nn, &cap_near);
        })
        size_t own_start = g->cell_start[cell], own_end = g->cell_start[cell + 1];
        for (size_t t = own_start; t < own_end; t++) {
            uint32_t q = g->order[t];
            const float *pq = g->pts + 3 * t;
            int len = 0;
            if (ok) {
                /* Only points within one cell edge can settle the query here,
                 * so farther candidates are never sorted in. */
                float h2 = (float)(g->h * g->h);
                for (size_t u = own_start; u < own_end; u++) {
                    float d2 = (float)sy_v3f_dist2(pq, g->pts + 3 * u);
                    if (u != t && d2 <= h2) cand_insert(list, &len, J->cap, d2, g->order[u]);
                }
                for (size_t u = 0; u < nn; u++) {
                    float d2 = (float)sy_v3f_dist2(pq, g->pts + 3 * (size_t)near[u]);
                    if (d2 <= h2) cand_insert(list, &len, J->cap, d2, g->order[near[u]]);
                }
            }
            if (!ok || len < J->k || list[J->k - 1].d2 > g->h * g->h) {
                J->pending[q] = 1;
                continue;
            }
            int m = 0;
            for (int i = 0; i < len; i++)
                if (i < J->k || list[i].d2 <= J->r2) J->nbr[(size_t)q * J->cap + m++] = list[i].j;
            J->cnt[q] = (uint8_t)m;
        }
    }
    free(near);
}

/* The same over a coarser grid (J->tier), for the points earlier passes
 * left pending; the last tier takes whatever its 27 cells hold. */
static void knn_coarse_chunk(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    knn_job *J = ctx;
    const sy_grid *g = J->tier;
    cand list[64];
    size_t cap_near = 4096, nn;
    uint32_t *near = malloc(cap_near * sizeof *near);

    for (size_t cell = begin; cell < end; cell++) {
        size_t own_start = g->cell_start[cell], own_end = g->cell_start[cell + 1], waiting = 0;
        for (size_t t = own_start; t < own_end; t++) waiting += J->pending[g->order[t]];
        if (!waiting) continue;
        const int32_t *c = g->cell_coord + 3 * cell;
        int ok = near != NULL;
        nn = 0;
        for (int r = 0; r <= 1; r++) {
            FOR_RING(g, c, r, nb, {
                if (ok) ok = gather_cell(g, nb, &near, &nn, &cap_near);
            })
        }
        for (size_t t = own_start; t < own_end; t++) {
            uint32_t q = g->order[t];
            if (!J->pending[q]) continue;
            int len = 0;
            if (ok) {
                for (size_t u = 0; u < nn; u++)
                    if (near[u] != t)
                        cand_insert(list, &len, J->cap, (float)sy_v3f_dist2(g->pts + 3 * t, g->pts + 3 * (size_t)near[u]),
                                    g->order[near[u]]);
            } else {
                len = knn_query(g, J->xyz, q, J->k, J->cap, 1, list);
            }
            if (!J->last_tier && (len < J->k || list[J->k - 1].d2 > g->h * g->h)) continue;
            J->pending[q] = 0;
            int m = 0;
            for (int i = 0; i < len; i++)
                if (i < J->k || list[i].d2 <= J->r2) J->nbr[(size_t)q * J->cap + m++] = list[i].j;
            J->cnt[q] = (uint8_t)m;
        }
    }
    free(near);
}

static uint32_t uf_find(uint32_t *up, uint32_t a)
{
    while (up[a] != a) {
        up[a] = up[up[a]];
        a = up[a];
    }
    return a;
}

static void uf_union(uint32_t *up, uint32_t a, uint32_t b)
{
    a = uf_find(up, a);
    b = uf_find(up, b);
    if (a != b) {
        if (a < b) up[b] = a;
        else up[a] = b;
    }
}

typedef struct {
    uint32_t a, b;
} edge;

/* One round of the bridging: the components to join and what each found. */
typedef struct {
    const sy_kdtree *kd;
    const float *xyz;
    const uint32_t *members, *roots;
    const size_t *first;
    edge *found;
    uint8_t *ok;
} bridge_round;

/* For each listed component, its (approximately) shortest edge to any other:
 * the nearest foreign point from a sample of 8 of its points, refined by two
 * alternating nearest-point steps. Components are independent: any split of
 * them over threads gives the same edges. */
static void bridge_chunk(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    bridge_round *R = ctx;
    for (size_t c = begin; c < end; c++) {
        uint32_t root = R->roots[c];
        size_t cnt = R->first[root + 1] - R->first[root];
        const uint32_t *mem = R->members + R->first[root];
        double best = INFINITY;
        uint32_t bj = 0, bi = mem[0];
        size_t samples = cnt < 8 ? cnt : 8;
        for (size_t s = 0; s < samples; s++) {
            uint32_t q = mem[s * cnt / samples];
            double before = best;
            sy_kdtree_nearest_foreign(R->kd, R->xyz + 3 * (size_t)q, root, &best, &bj);
            if (best < before) bi = q;
        }
        for (int step = 0; step < 2 && isfinite(best); step++) {
            /* Closest member to the found target, then its nearest foreign point. */
            double md = INFINITY;
            uint32_t mi = bi;
            for (size_t t = 0; t < cnt; t++) {
                double d2 = sy_v3f_dist2(R->xyz + 3 * (size_t)mem[t], R->xyz + 3 * (size_t)bj);
                if (d2 < md) {
                    md = d2;
                    mi = mem[t];
                }
            }
            double before = best;
            sy_kdtree_nearest_foreign(R->kd, R->xyz + 3 * (size_t)mi, root, &best, &bj);
            if (best < before) bi = mi;
        }
        R->ok[c] = isfinite(best);
        R->found[c] = (edge){bi, bj};
    }
}

/* Joins every component to the anchor's by shortest gap edges, Boruvka style:
 * each round every component but the anchor's finds its (approximately)
 * shortest edge to any other component. The nearest foreign point comes from
 * a kd-tree whose nodes know when all their points are of one component, so
 * a query skips its own component's subtrees and never walks empty space
 * (the cell rings of a grid grow with the gap: 58% of a 3 M-point run went
 * there). Rounds at most halve the count: O(n log n) in all. */
static sy_code bridge_components(const float *xyz, size_t n, uint32_t *up, uint32_t anchor, edge **bridges,
                                 size_t *n_bridges, sy_error *err)
{
    *bridges = NULL;
    *n_bridges = 0;
    size_t cap = 0;
    uint32_t *members = sy_calloc(n, sizeof *members, err, "graph");
    uint32_t *label = sy_calloc(n, sizeof *label, err, "graph");
    uint32_t *roots = sy_calloc(n, sizeof *roots, err, "graph");
    size_t *first = sy_calloc(n + 1, sizeof *first, err, "graph");
    edge *found = sy_calloc(n, sizeof *found, err, "graph");
    uint8_t *ok = sy_calloc(n, 1, err, "graph");
    sy_kdtree kd = {0};
    sy_code rc = SY_OK;
    if (!members || !label || !roots || !first || !found || !ok) {
        rc = SY_EINTERNAL;
        goto done;
    }
    int built = 0;
    for (;;) {
        /* Group points by component root (counting sort keeps index order). */
        memset(first, 0, (n + 1) * sizeof *first);
        for (size_t i = 0; i < n; i++) {
            label[i] = uf_find(up, (uint32_t)i);
            first[label[i] + 1]++;
        }
        size_t comps = 0;
        for (size_t i = 0; i < n; i++) {
            if (first[i + 1]) comps++;
            first[i + 1] += first[i];
        }
        if (comps <= 1) break;
        if (!built) {
            if ((rc = sy_kdtree_build(&kd, xyz, n, err))) goto done;
            built = 1;
        }
        sy_kdtree_relabel(&kd, label);
        size_t *fill = malloc(n * sizeof *fill);
        if (!fill) {
            rc = sy_fail(err, SY_EINTERNAL, "graph: out of memory");
            goto done;
        }
        memcpy(fill, first, n * sizeof *fill);
        for (size_t i = 0; i < n; i++) members[fill[label[i]]++] = (uint32_t)i;
        free(fill);
        uint32_t main_comp = label[anchor];
        size_t n_roots = 0;
        for (size_t root = 0; root < n; root++)
            if (first[root + 1] > first[root] && root != main_comp) roots[n_roots++] = (uint32_t)root;
        bridge_round R = {&kd, xyz, members, roots, first, found, ok};
        sy_parallel_for(n_roots, 16, bridge_chunk, &R);
        size_t round_start = *n_bridges;
        for (size_t c = 0; c < n_roots; c++) {
            if (!ok[c]) continue;
            if (*n_bridges == cap) {
                cap = cap ? 2 * cap : 64;
                edge *e = realloc(*bridges, cap * sizeof *e);
                if (!e) {
                    rc = sy_fail(err, SY_EINTERNAL, "graph: out of memory");
                    goto done;
                }
                *bridges = e;
            }
            (*bridges)[(*n_bridges)++] = found[c];
        }
        if (*n_bridges == round_start) break; /* nothing left to join (cannot happen with >1 component) */
        for (size_t e = round_start; e < *n_bridges; e++) uf_union(up, (*bridges)[e].a, (*bridges)[e].b);
    }
done:
    sy_kdtree_free(&kd);
    free(members);
    free(label);
    free(roots);
    free(first);
    free(found);
    free(ok);
    return rc;
}

sy_code sy_graph_build(const float *xyz, size_t n, int k, double radius, uint32_t anchor, sy_graph *G,
                       sy_error *err)
{
    memset(G, 0, sizeof *G);
    if (n == 0 || anchor >= n) return sy_fail(err, SY_EINPUT, "graph: no points");
    if (k < 1 || k > 32) return sy_fail(err, SY_EUSAGE, "graph: k %d outside [1, 32]", k);
    int cap = 2 * k;
    /* Two grids: cells of one join radius, and 4x coarser ones for the
     * sparse parts (foliage, the far side of a crown) the fine one leaves. */
    sy_grid g, coarse;
    sy_code rc = sy_grid_build(&g, xyz, n, radius, err);
    if (rc) return rc;
    rc = sy_grid_build(&coarse, xyz, n, 4 * radius, err);
    if (rc) {
        sy_grid_free(&g);
        return rc;
    }
    knn_job J = {&g, NULL, 0, xyz, k, cap, radius * radius, NULL, NULL, NULL};
    J.nbr = sy_calloc(n, cap * sizeof *J.nbr, err, "graph");
    J.cnt = sy_calloc(n, 1, err, "graph");
    J.pending = sy_calloc(n, 1, err, "graph");
    uint32_t *up = sy_calloc(n, sizeof *up, err, "graph");
    edge *bridges = NULL;
    size_t n_bridges = 0;
    if (!J.nbr || !J.cnt || !J.pending || !up) {
        rc = SY_EINTERNAL;
        goto fail;
    }
    sy_parallel_for(g.n_cells, 512, knn_chunk, &J);
    J.tier = &coarse;
    J.last_tier = 1;
    sy_parallel_for(coarse.n_cells, 64, knn_coarse_chunk, &J);

    for (size_t i = 0; i < n; i++) up[i] = (uint32_t)i;
    for (size_t i = 0; i < n; i++)
        for (int t = 0; t < J.cnt[i]; t++) uf_union(up, (uint32_t)i, J.nbr[i * cap + t]);
    {
        /* Component sizes, counted at each root. */
        uint32_t *size = sy_calloc(n, sizeof *size, err, "graph");
        if (!size) {
            rc = SY_EINTERNAL;
            goto fail;
        }
        for (size_t i = 0; i < n; i++) size[uf_find(up, (uint32_t)i)]++;
        for (size_t i = 0; i < n; i++) {
            if (size[i]) G->components++;
            if (size[i] > G->largest) G->largest = size[i];
        }
        free(size);
    }
    rc = bridge_components(xyz, n, up, anchor, &bridges, &n_bridges, err);
    if (rc) goto fail;
    G->bridges = n_bridges;

    /* Symmetric CSR: every directed pick and bridge becomes two half-edges. */
    G->n = n;
    G->start = sy_calloc(n + 1, sizeof *G->start, err, "graph");
    if (!G->start) {
        rc = SY_EINTERNAL;
        goto fail;
    }
    for (size_t i = 0; i < n; i++)
        for (int t = 0; t < J.cnt[i]; t++) {
            G->start[i + 1]++;
            G->start[J.nbr[i * cap + t] + 1]++;
        }
    for (size_t e = 0; e < n_bridges; e++) {
        G->start[bridges[e].a + 1]++;
        G->start[bridges[e].b + 1]++;
    }
    for (size_t i = 0; i < n; i++) G->start[i + 1] += G->start[i];
    size_t total = G->start[n];
    G->adj = sy_calloc(total ? total : 1, sizeof *G->adj, err, "graph");
    size_t *fill = sy_calloc(n, sizeof *fill, err, "graph");
    if (!G->adj || !fill) {
        free(fill);
        rc = SY_EINTERNAL;
        goto fail;
    }
    memcpy(fill, G->start, n * sizeof *fill);
    for (size_t i = 0; i < n; i++)
        for (int t = 0; t < J.cnt[i]; t++) {
            uint32_t j = J.nbr[i * cap + t];
            G->adj[fill[i]++] = j;
            G->adj[fill[j]++] = (uint32_t)i;
        }
    for (size_t e = 0; e < n_bridges; e++) {
        G->adj[fill[bridges[e].a]++] = bridges[e].b;
        G->adj[fill[bridges[e].b]++] = bridges[e].a;
    }
    /* Sort and de-duplicate each row in place, compacting the CSR. */
    size_t w = 0;
    for (size_t i = 0; i < n; i++) {
        size_t b = G->start[i], e = G->start[i + 1];
        for (size_t x = b + 1; x < e; x++) { /* rows are short: insertion sort */
            uint32_t v = G->adj[x];
            size_t y = x;
            while (y > b && G->adj[y - 1] > v) {
                G->adj[y] = G->adj[y - 1];
                y--;
            }
            G->adj[y] = v;
        }
        G->start[i] = w;
        for (size_t t = b; t < e; t++)
            if (t == b || G->adj[t] != G->adj[t - 1]) G->adj[w++] = G->adj[t];
    }
    G->start[n] = w;
    free(fill);
    G->len = sy_calloc(w ? w : 1, sizeof *G->len, err, "graph");
    if (!G->len) {
        rc = SY_EINTERNAL;
        goto fail;
    }
    for (size_t i = 0; i < n; i++)
        for (size_t t = G->start[i]; t < G->start[i + 1]; t++)
            G->len[t] = (float)sqrt(sy_v3f_dist2(xyz + 3 * i, xyz + 3 * (size_t)G->adj[t]));
    rc = SY_OK;
fail: /* the scratch goes either way; the graph only on failure */
    free(J.nbr);
    free(J.cnt);
    free(J.pending);
    free(up);
    free(bridges);
    sy_grid_free(&g);
    sy_grid_free(&coarse);
    if (rc) sy_graph_free(G);
    return rc;
}

void sy_graph_free(sy_graph *g)
{
    free(g->start);
    free(g->adj);
    free(g->len);
    memset(g, 0, sizeof *g);
}

/* ---- Dijkstra with a binary heap and lazy deletion ---- */

typedef struct {
    double d;
    uint32_t v;
} heap_item;

static void heap_push(heap_item *h, size_t *len, heap_item it)
{
    size_t i = (*len)++;
    while (i > 0) {
        size_t p = (i - 1) / 2;
        if (h[p].d < it.d || (h[p].d == it.d && h[p].v <= it.v)) break;
        h[i] = h[p];
        i = p;
    }
    h[i] = it;
}

static heap_item heap_pop(heap_item *h, size_t *len)
{
    heap_item top = h[0], last = h[--(*len)];
    size_t i = 0;
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= *len) break;
        if (c + 1 < *len && (h[c + 1].d < h[c].d || (h[c + 1].d == h[c].d && h[c + 1].v < h[c].v))) c++;
        if (last.d < h[c].d || (last.d == h[c].d && last.v <= h[c].v)) break;
        h[i] = h[c];
        i = c;
    }
    h[i] = last;
    return top;
}

sy_code sy_graph_dijkstra(const sy_graph *g, const uint32_t *sources, size_t n_sources, double beta, double *dist,
                          int32_t *parent, double *path, sy_error *err)
{
    size_t n = g->n;
    for (size_t s = 0; s < n_sources; s++)
        if (sources[s] >= n) return sy_fail(err, SY_EINPUT, "dijkstra: source out of range");
    /* Each edge relaxation pushes at most once, so E + sources bounds the heap. */
    heap_item *h = sy_calloc(g->start[n] + n_sources + 1, sizeof *h, err, "dijkstra");
    uint8_t *done = sy_calloc(n, 1, err, "dijkstra");
    if (!h || !done) {
        free(h);
        free(done);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < n; i++) {
        dist[i] = INFINITY;
        parent[i] = -1;
        path[i] = INFINITY;
    }
    size_t len = 0;
    for (size_t s = 0; s < n_sources; s++) {
        dist[sources[s]] = 0;
        path[sources[s]] = 0;
        heap_push(h, &len, (heap_item){0, sources[s]});
    }
    int unit = beta == 1.0;
    while (len) {
        heap_item it = heap_pop(h, &len);
        uint32_t u = it.v;
        if (done[u]) continue;
        done[u] = 1;
        for (size_t t = g->start[u]; t < g->start[u + 1]; t++) {
            uint32_t v = g->adj[t];
            if (done[v]) continue;
            double w = unit ? g->len[t] : pow(g->len[t], beta);
            double nd = dist[u] + w;
            if (nd < dist[v]) {
                dist[v] = nd;
                parent[v] = (int32_t)u;
                path[v] = path[u] + g->len[t];
                heap_push(h, &len, (heap_item){nd, v});
            }
        }
    }
    free(h);
    free(done);
    return SY_OK;
}

/* ---- Root ---- */

/* Points a stretch of `slab` above the base holds at least (more than a stray). */
#define STRAY_RUN 8

double sy_base_height(const float *xyz, size_t n, double slab)
{
    if (n == 0) return 0;
    double *z = malloc(n * sizeof *z);
    if (!z) return NAN;
    for (size_t i = 0; i < n; i++) z[i] = xyz[3 * i + 2];
    qsort(z, n, sizeof *z, sy_cmp_double);
    double base = z[n / 200];
    for (size_t i = 0; i + STRAY_RUN < n && z[i] < base; i++)
        if (z[i + STRAY_RUN] - z[i] <= slab) {
            base = z[i];
            break;
        }
    free(z);
    return base;
}

uint32_t sy_find_root(const float *xyz, size_t n, double slab, double *z0_out)
{
    if (z0_out) *z0_out = 0;
    if (n == 0) return 0;
    /* The root's slab starts at the base (sy_base_height): from the 0.5th
     * percentile the trunk's lowest metre was not the root's on a
     * ground-removed plane tree. */
    double z0 = sy_base_height(xyz, n, slab);
    if (!isfinite(z0)) return 0;
    if (z0_out) *z0_out = z0;
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (xyz[3 * i + 2] >= z0 && xyz[3 * i + 2] <= z0 + slab) m++;
    double *xs = malloc((m ? m : 1) * sizeof *xs), *ys = malloc((m ? m : 1) * sizeof *ys);
    uint32_t best = 0;
    if (xs && ys && m) {
        size_t t = 0;
        for (size_t i = 0; i < n; i++)
            if (xyz[3 * i + 2] >= z0 && xyz[3 * i + 2] <= z0 + slab) {
                xs[t] = xyz[3 * i];
                ys[t++] = xyz[3 * i + 1];
            }
        qsort(xs, m, sizeof *xs, sy_cmp_double);
        qsort(ys, m, sizeof *ys, sy_cmp_double);
        /* The median centre resists leftover ground around the trunk. */
        double cx = xs[m / 2], cy = ys[m / 2], bd = INFINITY;
        for (size_t i = 0; i < n; i++) {
            if (xyz[3 * i + 2] < z0 || xyz[3 * i + 2] > z0 + slab) continue;
            double dx = xyz[3 * i] - cx, dy = xyz[3 * i + 1] - cy, dz = xyz[3 * i + 2] - z0;
            double d = dx * dx + dy * dy + dz * dz;
            if (d < bd) {
                bd = d;
                best = (uint32_t)i;
            }
        }
    }
    free(xs);
    free(ys);
    return best;
}
