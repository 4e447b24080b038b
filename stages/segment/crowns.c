/* Crowns from stems: the above-ground points are voxelised, voxels within
 * graph_reach of each other are joined by edges as long as the distance
 * between their centroids, and one multi-source Dijkstra from the stems'
 * lower trunk voxels gives every voxel to the stem whose path reaches it
 * first. A branch reaches its own trunk along the wood, so its path is the
 * shorter one even where the crown touches a neighbour's: the comparative
 * shortest-path rule of Tao et al. 2015 (ISPRS J. 110:66-76). Edge costs
 * grow faster than their length (gap_penalty) so a path prefers many short
 * steps through dense wood and foliage to a jump across a gap. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "segment_internal.h"
#include "stages/core/voxel.h"

/* The column over a stem that belongs to it (metres, at least). */
#define COLUMN_RADIUS 0.5
/* Climbing the column costs this much per metre more than a path seen in
 * the points, so a path the scan shows wins where both reach. */
#define COLUMN_COST 3.0


/* The voxel graph: edges implicit between voxels up to R cells apart along
 * each axis, cost len * (len / voxel)^gap_penalty. */
typedef struct {
    const sy_voxel_entry *pts;
    const uint32_t *start;
    const double *cen;
    double *dist;
    int32_t *vlab;
    const uint8_t *fixed; /* NULL, or voxels whose label is final */
    const seg_map *map;
    seg_heap *heap;
    double voxel, gap_penalty;
    /* neighbour iteration */
    uint32_t at, ix, iy, iz;
    int R, dx, dy, dz;
} graph;

static void neighbours_begin(graph *g, uint32_t vi, int R)
{
    uint64_t key = g->pts[g->start[vi]].key;
    g->at = vi;
    g->ix = (uint32_t)(key >> 42), g->iy = (uint32_t)(key >> 21) & 0x1fffff, g->iz = (uint32_t)key & 0x1fffff;
    g->R = R;
    g->dx = -R, g->dy = -R, g->dz = -R - 1;
}

/* The next existing neighbour and the cost of the edge to it; 0 at the end. */
static int neighbours_next(graph *g, uint32_t *nb, double *cost)
{
    for (;;) {
        if (++g->dz > g->R) {
            g->dz = -g->R;
            if (++g->dy > g->R) {
                g->dy = -g->R;
                if (++g->dx > g->R) return 0;
            }
        }
        if (!g->dx && !g->dy && !g->dz) continue;
        uint32_t n = seg_map_get(g->map, seg_key3(g->ix + (uint32_t)g->dx, g->iy + (uint32_t)g->dy, g->iz + (uint32_t)g->dz));
        if (n == UINT32_MAX) continue;
        const double *a = g->cen + 3 * (size_t)g->at, *b = g->cen + 3 * (size_t)n;
        double ex = b[0] - a[0], ey = b[1] - a[1], ez = b[2] - a[2];
        double len = sqrt(ex * ex + ey * ey + ez * ez), gp = g->gap_penalty, v = g->voxel;
        *cost = gp == 1 ? len * len / v : gp == 0 ? len : len * pow(len / v, gp);
        *nb = n;
        return 1;
    }
}

/* Dijkstra from what the heap holds, over edges up to R cells, never
 * relabelling a fixed voxel. */
static sy_code grow(graph *g, int R, sy_error *err)
{
    double d;
    uint32_t vi;
    while (seg_heap_pop(g->heap, &d, &vi)) {
        if (d > g->dist[vi]) continue;
        neighbours_begin(g, vi, R);
        uint32_t nb;
        double cost;
        while (neighbours_next(g, &nb, &cost)) {
            if (g->fixed && g->fixed[nb]) continue;
            double nd = d + cost;
            if (nd < g->dist[nb]) {
                g->dist[nb] = nd;
                g->vlab[nb] = g->vlab[vi];
                sy_code rc = seg_heap_push(g->heap, nd, nb, err);
                if (rc) return rc;
            }
        }
    }
    return SY_OK;
}

sy_code seg_grow_crowns(const seg_frame *f, const sy_segment_options *o, const seg_stem *stems, size_t n_stems,
                        int32_t *label, sy_error *err)
{
    const double v = o->voxel;
    size_t m = 0;
    for (size_t i = 0; i < f->n; i++) {
        label[i] = f->ground[i] ? 0 : -1;
        m += !f->ground[i];
    }
    if (m == 0 || n_stems == 0) return SY_OK;
    for (int k = 0; k < 3; k++)
        if ((f->hi[k] - f->lo[k]) / v >= (double)(1u << 21) - 80)
            return sy_fail(err, SY_EINPUT, "segment: the plot spans %.0f m, too much for %.3g m voxels",
                           f->hi[k] - f->lo[k], v);
    sy_voxel_entry *pts = sy_calloc(m, sizeof *pts, err, "crown voxels");
    if (!pts) return SY_EINTERNAL;
    m = 0;
    for (size_t i = 0; i < f->n; i++) {
        if (f->ground[i]) continue;
        uint32_t ix = (uint32_t)((f->xyz[3 * i] - f->lo[0]) / v), iy = (uint32_t)((f->xyz[3 * i + 1] - f->lo[1]) / v),
                 iz = (uint32_t)((f->xyz[3 * i + 2] - f->lo[2]) / v);
        pts[m].key = seg_key3(ix + 32, iy + 32, iz + 32); /* +32: neighbours of cell 0 need no sign */
        pts[m++].index = i;
    }
    sy_voxel_entries_sort(pts, m); /* by cell, then point */
    size_t nv = 0;
    for (size_t i = 0; i < m; i++) nv += i == 0 || pts[i].key != pts[i - 1].key;
    uint32_t *start = sy_calloc(nv + 1, sizeof *start, err, "crown voxels");
    double *cen = sy_calloc(3 * nv, sizeof *cen, err, "crown voxels");
    double *vhag = sy_calloc(nv, sizeof *vhag, err, "crown voxels");
    double *dist = sy_calloc(nv, sizeof *dist, err, "crown voxels");
    int32_t *vlab = sy_calloc(nv, sizeof *vlab, err, "crown voxels");
    seg_map map = {0};
    seg_heap heap = {0};
    sy_code rc = start && cen && vhag && dist && vlab ? seg_map_init(&map, nv, err) : SY_EINTERNAL;
    if (rc == SY_OK) {
        size_t c = 0;
        for (size_t i = 0; i < m; i++) {
            if (i == 0 || pts[i].key != pts[i - 1].key) {
                start[c] = (uint32_t)i;
                seg_map_put(&map, pts[i].key, (uint32_t)c);
                c++;
            }
            size_t vi = c - 1, p = pts[i].index;
            for (int k = 0; k < 3; k++) cen[3 * vi + k] += f->xyz[3 * p + k];
            vhag[vi] += f->hag[p];
        }
        start[nv] = (uint32_t)m;
        for (size_t i = 0; i < nv; i++) {
            double cnt = start[i + 1] - start[i];
            for (int k = 0; k < 3; k++) cen[3 * i + k] /= cnt;
            vhag[i] /= cnt;
            dist[i] = INFINITY;
            vlab[i] = -1;
        }
        /* Sources: the lower trunk of each stem, from the ground to the top
         * of the breast-height band, within a little of its circle. */
        double top = o->breast_height + 0.5 * o->slice;
        for (size_t i = 0; i < nv && rc == SY_OK; i++) {
            if (vhag[i] > top) continue;
            int best = -1;
            double bd = INFINITY;
            for (size_t s = 0; s < n_stems; s++) {
                double dx = cen[3 * i] - stems[s].x, dy = cen[3 * i + 1] - stems[s].y, d = sqrt(dx * dx + dy * dy);
                if (d <= stems[s].r + v && d - stems[s].r < bd) bd = d - stems[s].r, best = (int)s;
            }
            if (best < 0) continue;
            vlab[i] = best + 1;
            dist[i] = 0;
            rc = seg_heap_push(&heap, 0, (uint32_t)i, err);
        }
        /* And the column over it, at the cost of climbing there along the
         * trunk: a trunk is upright, so what stands right above a stem is
         * that tree, even where the scan lost the trunk half way up behind
         * a neighbour's foliage and the crown would otherwise be reached
         * from the side only. */
        for (size_t i = 0; i < nv && rc == SY_OK; i++) {
            if (vlab[i] > 0 || vhag[i] <= top) continue;
            int best = -1;
            double bd = INFINITY;
            for (size_t s = 0; s < n_stems; s++) {
                double dx = cen[3 * i] - stems[s].x, dy = cen[3 * i + 1] - stems[s].y, d = sqrt(dx * dx + dy * dy);
                if (d <= fmax(2 * stems[s].r, COLUMN_RADIUS) && d < bd) bd = d, best = (int)s;
            }
            if (best < 0) continue;
            vlab[i] = best + 1;
            dist[i] = COLUMN_COST * (vhag[i] - top + bd);
            rc = seg_heap_push(&heap, dist[i], (uint32_t)i, err);
        }
    }
    graph g = {.pts = pts, .start = start, .cen = cen, .dist = dist, .vlab = vlab, .map = &map, .heap = &heap, .voxel = v, .gap_penalty = o->gap_penalty};
    if (rc == SY_OK) rc = grow(&g, o->graph_reach, err);
    /* What no path reaches stays unassigned: giving a crown the scan saw
     * apart from every stem to the stem nearest across hands the top of a
     * leaning tree to its neighbour (measured: worse than leaving it). */
    if (rc == SY_OK)
        for (size_t i = 0; i < nv; i++)
            for (uint32_t j = start[i]; j < start[i + 1]; j++) label[pts[j].index] = vlab[i];
    free(pts), free(start), free(cen), free(vhag), free(dist), free(vlab);
    seg_map_free(&map);
    seg_heap_free(&heap);
    return rc;
}
