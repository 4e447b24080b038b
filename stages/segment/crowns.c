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

typedef struct {
    uint64_t key;
    uint32_t point;
} keyed;

static int cmp_keyed(const void *a, const void *b)
{
    const keyed *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return (x->point > y->point) - (x->point < y->point);
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
        if ((f->hi[k] - f->lo[k]) / v >= (double)(1u << 21) - 8)
            return sy_fail(err, SY_EINPUT, "segment: the plot spans %.0f m, too much for %.3g m voxels",
                           f->hi[k] - f->lo[k], v);
    keyed *pts = sy_calloc(m, sizeof *pts, err, "crown voxels");
    if (!pts) return SY_EINTERNAL;
    m = 0;
    for (size_t i = 0; i < f->n; i++) {
        if (f->ground[i]) continue;
        uint32_t ix = (uint32_t)((f->xyz[3 * i] - f->lo[0]) / v), iy = (uint32_t)((f->xyz[3 * i + 1] - f->lo[1]) / v),
                 iz = (uint32_t)((f->xyz[3 * i + 2] - f->lo[2]) / v);
        pts[m].key = seg_key3(ix + 4, iy + 4, iz + 4); /* +4: neighbours of cell 0 need no sign */
        pts[m++].point = (uint32_t)i;
    }
    qsort(pts, m, sizeof *pts, cmp_keyed);
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
            size_t vi = c - 1, p = pts[i].point;
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
    }
    const int R = o->graph_reach;
    const double gp = o->gap_penalty;
    while (rc == SY_OK) {
        double d;
        uint32_t vi;
        if (!seg_heap_pop(&heap, &d, &vi)) break;
        if (d > dist[vi]) continue;
        uint64_t key = pts[start[vi]].key;
        uint32_t ix = (uint32_t)(key >> 42), iy = (uint32_t)(key >> 21) & 0x1fffff, iz = (uint32_t)key & 0x1fffff;
        for (int dx = -R; dx <= R && rc == SY_OK; dx++)
            for (int dy = -R; dy <= R && rc == SY_OK; dy++)
                for (int dz = -R; dz <= R; dz++) {
                    if (!dx && !dy && !dz) continue;
                    uint32_t nb = seg_map_get(&map, seg_key3(ix + dx, iy + dy, iz + dz));
                    if (nb == UINT32_MAX) continue;
                    double ex = cen[3 * nb] - cen[3 * vi], ey = cen[3 * nb + 1] - cen[3 * vi + 1],
                           ez = cen[3 * nb + 2] - cen[3 * vi + 2];
                    double len = sqrt(ex * ex + ey * ey + ez * ez);
                    double cost = gp == 1 ? len * len / v : gp == 0 ? len : len * pow(len / v, gp);
                    double nd = d + cost;
                    if (nd < dist[nb]) {
                        dist[nb] = nd;
                        vlab[nb] = vlab[vi];
                        if ((rc = seg_heap_push(&heap, nd, nb, err))) break;
                    }
                }
    }
    if (rc == SY_OK)
        for (size_t i = 0; i < nv; i++)
            for (uint32_t j = start[i]; j < start[i + 1]; j++) label[pts[j].point] = vlab[i];
    free(pts), free(start), free(cen), free(vhag), free(dist), free(vlab);
    seg_map_free(&map);
    seg_heap_free(&heap);
    return rc;
}
