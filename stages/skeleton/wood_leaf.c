/* Wood/leaf separation by shortest-path "path frequency" (Vicari et al. 2019,
 * GBS-style), computed on the Dijkstra tree the skeleton already builds.
 *
 * Every point's shortest path to the base runs along the shortest-path tree,
 * so the number of points whose path passes through a point is the size of
 * its subtree. Limbs carry the paths of everything beyond them (large
 * subtrees); a leaf carries only the few points behind it. A point is wood
 * when its subtree holds at least min_share of all points (these "highways"
 * form an ancestor-closed tree from the base), or when it is a graph
 * neighbour of such a point: highways are one point wide, the one-ring
 * around them gives the level sets a connected ring of limb points to split.
 *
 * Measured on simulated TLS scans (docs/skeleton.md): local PCA features
 * (surface variation, linearity) of the 1- and 2-ring neighbourhoods did not
 * separate wood from leaves at all at the scan spacing there (wood precision
 * below the 9-12 % base rate), so they are not used. */
#include <stdlib.h>

#include "skeleton_internal.h"

typedef struct {
    double d;
    uint32_t i;
} keyed;

static int cmp_keyed(const void *a, const void *b)
{
    double x = ((const keyed *)a)->d, y = ((const keyed *)b)->d;
    if (x != y) return x < y ? -1 : 1;
    uint32_t p = ((const keyed *)a)->i, q = ((const keyed *)b)->i;
    return p < q ? -1 : p > q;
}

sy_code sy_classify_wood(const sy_graph *g, const int32_t *spt, const double *dist, double min_share, uint8_t *wood,
                         uint32_t *order, size_t *n_wood, sy_error *err)
{
    size_t n = g->n;
    keyed *k = sy_calloc(n ? n : 1, sizeof *k, err, "wood/leaf");
    uint32_t *cnt = sy_calloc(n ? n : 1, sizeof *cnt, err, "wood/leaf");
    if (!k || !cnt) {
        free(k);
        free(cnt);
        return SY_EINTERNAL;
    }
    /* Parents are closer to the base than their children, so ascending
     * distance is a topological order of the shortest-path tree. Unreached
     * points (infinite distance) come last and stay roots of their own. */
    for (size_t i = 0; i < n; i++) {
        k[i].d = dist[i];
        k[i].i = (uint32_t)i;
    }
    qsort(k, n, sizeof *k, cmp_keyed);
    for (size_t t = 0; t < n; t++) order[t] = k[t].i;
    free(k);
    for (size_t t = n; t-- > 0;) {
        uint32_t i = order[t];
        cnt[i] += 1;
        if (spt[i] >= 0) cnt[spt[i]] += cnt[i];
    }
    double limit = min_share * (double)n;
    if (limit < 2) limit = 2;
    for (size_t i = 0; i < n; i++) wood[i] = cnt[i] >= limit || spt[i] < 0;
    /* One ring around the highways (and the sources). */
    for (size_t i = 0; i < n; i++) {
        if (wood[i] != 1) continue;
        for (size_t e = g->start[i]; e < g->start[i + 1]; e++)
            if (!wood[g->adj[e]]) wood[g->adj[e]] = 2;
    }
    size_t w = 0;
    for (size_t i = 0; i < n; i++) {
        wood[i] = wood[i] != 0;
        w += wood[i];
    }
    *n_wood = w;
    free(cnt);
    return SY_OK;
}
