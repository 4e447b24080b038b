/* Lobes of bounded size (Livny et al. 2011's "texture lobes"; Pirk 2013
 * Fig. 3.11: one cluster for a whole crown over-synthesises, about twenty
 * look right) and the occupancy grid synthesis reads instead of the points. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "clusters.h"

static double box_extent(const float b[6])
{
    double e = 0;
    for (int k = 0; k < 3; k++)
        if (b[3 + k] - b[k] > e) e = b[3 + k] - b[k];
    return e;
}

static void box_add_box(float b[6], const float o[6])
{
    for (int k = 0; k < 3; k++) {
        if (o[k] < b[k]) b[k] = o[k];
        if (o[3 + k] > b[3 + k]) b[3 + k] = o[3 + k];
    }
}

static void box_add_point(float b[6], const float *p)
{
    for (int k = 0; k < 3; k++) {
        if (p[k] < b[k]) b[k] = p[k];
        if (p[k] > b[3 + k]) b[3 + k] = p[k];
    }
}

typedef struct {
    int32_t node;
    int32_t cell[3];
    uint32_t point;
} chunk_point;

static int cmp_cell(const chunk_point *x, const chunk_point *y)
{
    for (int k = 2; k >= 0; k--)
        if (x->cell[k] != y->cell[k]) return x->cell[k] < y->cell[k] ? -1 : 1;
    return 0;
}

static int cmp_chunk(const void *a, const void *b)
{
    const chunk_point *x = a, *y = b;
    int c = cmp_cell(x, y);
    if (c) return c;
    if (x->node != y->node) return x->node < y->node ? -1 : 1;
    return x->point < y->point ? -1 : x->point > y->point;
}

sy_code sy_clusters_split_lobes(const sy_skeleton *full, const float *xyz, double max_extent, int min_points,
                                int32_t *cluster_of, int32_t *seed_of, int32_t *point_lobe, size_t *n_clusters,
                                sy_error *err)
{
    size_t n = full->n, n_pts = full->support_start ? full->support_start[n] : 0;
    for (size_t i = 0; i < n_pts; i++) point_lobe[full->support[i]] = -1;
    if (n == 0 || !(max_extent > 0)) return SY_OK;
    int32_t *first = malloc(n * sizeof *first), *next = malloc(n * sizeof *next), *order = malloc(n * sizeof *order);
    int32_t *stack = malloc(n * sizeof *stack), *cand = malloc(n * sizeof *cand), *lobe = malloc(n * sizeof *lobe);
    float *box = malloc(6 * n * sizeof *box);
    size_t *pts = calloc(n, sizeof *pts);
    if (!first || !next || !order || !stack || !cand || !lobe || !box || !pts) {
        free(first), free(next), free(order), free(stack), free(cand), free(lobe), free(box), free(pts);
        return sy_fail(err, SY_EINTERNAL, "lobes: out of memory");
    }
    sy_skeleton_children(full, first, next);
    size_t no = sy_skeleton_breadth_first(full, first, next, order);
    /* Subtree boxes of the points (and nodes), leaves first. */
    for (size_t h = no; h-- > 0;) {
        int32_t v = order[h];
        float *b = box + 6 * v;
        for (int k = 0; k < 3; k++) b[k] = b[3 + k] = full->pos[3 * v + k];
        for (uint32_t s = full->support_start[v]; s < full->support_start[v + 1]; s++)
            box_add_point(b, xyz + 3 * (size_t)full->support[s]);
        pts[v] += full->support_start[v + 1] - full->support_start[v];
        for (int32_t c = first[v]; c >= 0; c = next[c]) {
            box_add_box(b, box + 6 * c);
            pts[v] += pts[c];
        }
    }
    /* Top-down: a low-confidence subtree within the bound is a lobe candidate;
     * a larger one keeps its top node on the skeleton and is split below. */
    size_t nc = 0, sp = 0, promoted_pts = 0;
    for (size_t h = 0; h < no; h++) {
        int32_t v = order[h], p = full->parent[v];
        if (cluster_of[v] >= 0 && p >= 0 && cluster_of[p] < 0) stack[sp++] = v;
    }
    while (sp) {
        int32_t v = stack[--sp];
        if (box_extent(box + 6 * v) <= max_extent || first[v] < 0) {
            cand[nc++] = v;
            continue;
        }
        cluster_of[v] = -1;
        lobe[v] = -3; /* kept on the skeleton, its points chunked below */
        promoted_pts += full->support_start[v + 1] - full->support_start[v];
        for (int32_t c = first[v]; c >= 0; c = next[c]) stack[sp++] = c;
    }
    /* Candidates in breadth-first order, so lobes come out by seed. */
    for (size_t i = 0; i < n; i++) lobe[i] = lobe[i] == -3 ? -3 : -1;
    for (size_t i = 0; i < nc; i++) lobe[cand[i]] = -2;
    size_t nl = 0;
    float cur[6] = {0, 0, 0, 0, 0, 0};
    int32_t cur_seed = -1, cur_id = -1;
    size_t *lobe_pts = calloc(n + promoted_pts + 1, sizeof *lobe_pts);
    if (!lobe_pts) {
        free(first), free(next), free(order), free(stack), free(cand), free(lobe), free(box), free(pts);
        return sy_fail(err, SY_EINTERNAL, "lobes: out of memory");
    }
    for (size_t h = 0; h < no; h++) {
        int32_t v = order[h];
        if (lobe[v] != -2) continue;
        int32_t s = full->parent[v];
        float u[6];
        memcpy(u, cur, sizeof u);
        if (s == cur_seed) box_add_box(u, box + 6 * v);
        if (s != cur_seed || box_extent(u) > max_extent) {
            cur_seed = s;
            cur_id = (int32_t)nl++;
            seed_of[cur_id] = s;
            memcpy(cur, box + 6 * v, sizeof cur);
        } else {
            memcpy(cur, u, sizeof cur);
        }
        lobe[v] = cur_id;
        lobe_pts[cur_id] += pts[v];
    }
    /* The kept top nodes' own points: one lobe per (node, grid cell). */
    chunk_point *cp = malloc((promoted_pts + 1) * sizeof *cp);
    if (!cp) {
        free(first), free(next), free(order), free(stack), free(cand), free(lobe), free(box), free(pts), free(lobe_pts);
        return sy_fail(err, SY_EINTERNAL, "lobes: out of memory");
    }
    /* The grid divides the box of these points evenly (no sliver cells at
     * its edges): as many cells a side as the bound fits, rounded. */
    size_t ncp = 0;
    float pb[6] = {INFINITY, INFINITY, INFINITY, -INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < n; v++)
        if (lobe[v] == -3)
            for (uint32_t s = full->support_start[v]; s < full->support_start[v + 1]; s++)
                box_add_point(pb, xyz + 3 * (size_t)full->support[s]);
    double cell[3];
    for (int k = 0; k < 3; k++) {
        double e = pb[3 + k] - pb[k], m = floor(e / max_extent + 0.5);
        cell[k] = e > 0 ? e / (m < 1 ? 1 : m) * (1 + 1e-9) : 1;
    }
    for (size_t v = 0; v < n; v++) {
        if (lobe[v] != -3) continue;
        for (uint32_t s = full->support_start[v]; s < full->support_start[v + 1]; s++) {
            const float *p = xyz + 3 * (size_t)full->support[s];
            chunk_point *c = &cp[ncp++];
            c->node = (int32_t)v;
            c->point = full->support[s];
            for (int k = 0; k < 3; k++) c->cell[k] = (int32_t)floor((p[k] - pb[k]) / cell[k]);
        }
    }
    /* One lobe per grid cell, seeded at the kept node holding most of its points. */
    qsort(cp, ncp, sizeof *cp, cmp_chunk);
    for (size_t i = 0; i < ncp;) {
        size_t j = i;
        while (j < ncp && cmp_cell(&cp[j], &cp[i]) == 0) j++;
        int32_t best = cp[i].node;
        size_t best_n = 0;
        for (size_t a = i; a < j;) {
            size_t b = a;
            while (b < j && cp[b].node == cp[a].node) b++;
            if (b - a > best_n) best_n = b - a, best = cp[a].node;
            a = b;
        }
        seed_of[nl] = best;
        for (size_t a = i; a < j; a++) point_lobe[cp[a].point] = (int32_t)nl;
        lobe_pts[nl] = j - i;
        nl++;
        i = j;
    }
    free(cp);
    /* Every node below a candidate joins its lobe (parents come first). */
    for (size_t h = 0; h < no; h++) {
        int32_t v = order[h], p = full->parent[v];
        if (cluster_of[v] < 0) {
            lobe[v] = -1;
            continue;
        }
        if (lobe[v] < 0 && p >= 0) lobe[v] = lobe[p];
    }
    /* Small lobes stay on the skeleton; ids stay dense. */
    int32_t *remap = malloc((nl + 1) * sizeof *remap);
    if (!remap) {
        free(first), free(next), free(order), free(stack), free(cand), free(lobe), free(box), free(pts), free(lobe_pts);
        return sy_fail(err, SY_EINTERNAL, "lobes: out of memory");
    }
    size_t kept = 0;
    for (size_t l = 0; l < nl; l++) {
        remap[l] = lobe_pts[l] >= (size_t)min_points ? (int32_t)kept : -1;
        if (remap[l] >= 0) seed_of[kept++] = seed_of[l];
    }
    for (size_t i = 0; i < n; i++) cluster_of[i] = lobe[i] >= 0 ? remap[lobe[i]] : -1;
    for (size_t i = 0; i < n_pts; i++) {
        uint32_t q = full->support[i];
        if (point_lobe[q] >= 0) point_lobe[q] = remap[point_lobe[q]];
    }
    *n_clusters = kept;
    free(first), free(next), free(order), free(stack), free(cand), free(lobe), free(box), free(pts), free(lobe_pts);
    free(remap);
    return SY_OK;
}

size_t sy_cluster_occupancy_bytes(const sy_cluster *c)
{
    size_t n = (size_t)c->occ_dims[0] * c->occ_dims[1] * c->occ_dims[2];
    return c->occupancy ? (n + 7) / 8 : 0;
}

/* The occupancy of c from n points of xyz: those listed in idx, or (idx
 * NULL) the first n; each marks every cell its cube of half-side reach
 * touches. */
static sy_code occupancy_of(sy_cluster *c, const float *xyz, const uint32_t *idx, size_t n, double reach, int cells,
                            int from_above, const sy_crown_roof *roof, sy_error *err)
{
    free(c->occupancy);
    c->occupancy = NULL;
    memset(c->occ_dims, 0, sizeof c->occ_dims);
    if (!c->n_verts || cells < 1) return SY_OK;
    if (cells > 8) cells = 8;
    float b[6];
    for (int k = 0; k < 3; k++) b[k] = b[3 + k] = c->verts[k];
    for (size_t i = 1; i < c->n_verts; i++) box_add_point(b, c->verts + 3 * i);
    double cell = box_extent(b) / cells;
    if (!(cell > 0)) return SY_OK;
    for (int k = 0; k < 3; k++) {
        double d = ceil((b[3 + k] - b[k]) / cell - 1e-6);
        c->occ_dims[k] = (uint8_t)(d < 1 ? 1 : d > 8 ? 8 : d);
    }
    size_t nb = ((size_t)c->occ_dims[0] * c->occ_dims[1] * c->occ_dims[2] + 7) / 8;
    c->occupancy = sy_calloc(nb, 1, err, "occupancy");
    if (!c->occupancy) return SY_EINTERNAL;
    for (size_t i = 0; i < n; i++) {
        const float *p = xyz + 3 * (idx ? (size_t)idx[i] : i);
        /* Seen from below, the cells between a return at the crown's top
         * and the roof over it are hidden by the crown under them. */
        double up = sy_crown_roof_lift(roof, p);
        int lo[3], hi[3];
        for (int k = 0; k < 3; k++) {
            double e = b[3 + k] - b[k] > 0 ? b[3 + k] - b[k] : 1;
            for (int side = 0; side < 2; side++) {
                double v = side ? (k == 2 && !isnan(up) ? up : p[k]) + reach : p[k] - reach;
                double t = (v - b[k]) / e * c->occ_dims[k];
                int q = t < 0 ? 0 : t >= c->occ_dims[k] ? c->occ_dims[k] - 1 : (int)t;
                if (side) hi[k] = q;
                else lo[k] = q;
            }
        }
        /* Seen from above, the cells under a return are hidden by it. An
         * airborne scan's returns lie on the crown's top (the simulated
         * airborne aspen's occupied 12 % of its lobes' cells), and synthesis
         * put leaves only there: a lid on an empty crown. */
        for (int z = from_above ? 0 : lo[2]; z <= hi[2]; z++)
            for (int y = lo[1]; y <= hi[1]; y++)
                for (int x = lo[0]; x <= hi[0]; x++) {
                    size_t bit = (size_t)x + c->occ_dims[0] * ((size_t)y + c->occ_dims[1] * (size_t)z);
                    c->occupancy[bit >> 3] |= (uint8_t)(1u << (bit & 7));
                }
    }
    return SY_OK;
}

sy_code sy_cluster_occupancy(sy_cluster *c, const float *xyz, int cells, int from_above, const sy_crown_roof *roof,
                             sy_error *err)
{
    return occupancy_of(c, xyz, c->points, c->n_points, 0, cells, from_above, roof, err);
}

sy_code sy_cluster_occupancy_of_twigs(sy_cluster *c, sy_error *err)
{
    /* A node stands for the returns of its voxel, which lie within a voxel
     * of it along each axis: it marks every cell they may fall in. From the
     * nodes' own cells alone the simulated palm's leaf area against its true
     * tree fell from 0.83 (its points' bits) to 0.55; this way 0.76 (half a
     * voxel: 0.75). */
    return occupancy_of(c, c->twig_pos, NULL, c->n_twigs, c->twig_voxel, 8, 0, NULL, err);
}
