/* The twigs a lobe's returns trace: the lobe's points thinned to one return
 * per voxel and joined, with the seed node, by their Euclidean minimum
 * spanning tree (Prim), rooted at the seed. Where the returns are wood (a
 * leaf-off crown, the fine twigs the level sets mix), the tree runs along
 * them: AdTree (Du et al. 2019) draws its branches through every return the
 * same way, from a spanning tree of the points. The skeleton's level sets
 * mix several twigs into one node (the cut's mean distances in these crowns
 * are 2-13 cm on limbs of 0.5-5.6 cm radius), so the main skeleton cannot
 * keep them; this keeps them at the voxel the .sylva budget allows.
 * Deterministic: voxels and ties by index, any thread count. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "clusters.h"
#include "stages/core/parallel.h"
#include "stages/core/progress.h"
#include "stages/core/vec3.h"
#include "stages/core/voxel.h"

#define VOXEL_STEP 1.25 /* the ladder of voxel sizes tried */

sy_twig_options sy_twig_options_default(void)
{
    sy_twig_options o;
    memset(&o, 0, sizeof o);
    o.voxel_min = 0.02;
    o.voxel_max = 0.4;
    o.max_nodes = 0;
    return o;
}

sy_code sy_twig_options_check(const sy_twig_options *o, sy_error *err)
{
    if (!(o->voxel_min > 0) || !isfinite(o->voxel_min))
        return sy_fail(err, SY_EUSAGE, "clusters: twig voxel_min %g must be > 0", o->voxel_min);
    if (!(o->voxel_max >= o->voxel_min) || !(o->voxel_max <= 1e4 * o->voxel_min))
        return sy_fail(err, SY_EUSAGE, "clusters: twig voxel_max %g must be within 1 and 10^4 times voxel_min %g",
                       o->voxel_max, o->voxel_min);
    return SY_OK;
}

/* The lobe's points sorted by voxel of size v from its lowest corner
 * (e[i].index: the point's place in the lobe's list; n entries). The key
 * takes the axes as z, y, x, so the voxels, and the twig nodes numbered
 * from them, come in that order (the files written since version 4). */
static void voxel_sort(const sy_cluster *c, const float *xyz, double v, sy_voxel_entry *e)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}; /* z, y, x */
    for (size_t i = 0; i < c->n_points; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], xyz[3 * (size_t)c->points[i] + 2 - k]);
    for (size_t i = 0; i < c->n_points; i++) {
        const float *f = xyz + 3 * (size_t)c->points[i];
        const double p[3] = {f[2], f[1], f[0]};
        e[i] = (sy_voxel_entry){sy_voxel_key_d(p, lo, v), i};
    }
    sy_voxel_entries_sort(e, c->n_points);
}

/* Distinct voxels of size v over the lobe. */
static size_t count_voxels(const sy_cluster *c, const float *xyz, double v, sy_voxel_entry *e)
{
    if (!c->n_points) return 0;
    voxel_sort(c, xyz, v, e);
    size_t m = 1;
    for (size_t i = 1; i < c->n_points; i++) m += e[i].key != e[i - 1].key;
    return m;
}

typedef struct {
    const sy_clusters *cl;
    const sy_skeleton *main;
    const float *xyz;
    double v;
    size_t *count; /* per lobe; SIZE_MAX: out of memory */
    uint8_t *oom;  /* per lobe */
    sy_code *rc;
    sy_error *err;
} twig_job;

static void count_chunk(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    twig_job *J = ctx;
    for (size_t c = begin; c < end; c++) {
        const sy_cluster *C = &J->cl->items[c];
        sy_voxel_entry *e = malloc((C->n_points + 1) * sizeof *e);
        J->oom[c] = !e;
        J->count[c] = e ? count_voxels(C, J->xyz, J->v, e) : SIZE_MAX;
        free(e);
    }
}

/* Lobe c's twigs at voxel v: per voxel the return nearest the mean of its
 * returns (ties: the lower index), then Prim's spanning tree from the
 * seed, its tips moved to their voxels' farthest returns, written in
 * depth-first preorder (children by index) so that a node's parent comes
 * before it. */
static sy_code trace_lobe(sy_cluster *C, const float seed[3], const float *xyz, double v, sy_error *err)
{
    size_t n = C->n_points;
    sy_voxel_entry *e = malloc((n + 1) * sizeof *e);
    float *rep = malloc((n + 1) * 3 * sizeof *rep);
    if (!e || !rep) {
        free(e), free(rep);
        return sy_fail(err, SY_EINTERNAL, "clusters: out of memory tracing twigs");
    }
    size_t m = 0;
    size_t *lo = malloc((n + 1) * sizeof *lo); /* rep i's returns: e[lo[i]] .. e[lo[i + 1]) */
    if (!lo) {
        free(e), free(rep);
        return sy_fail(err, SY_EINTERNAL, "clusters: out of memory tracing twigs");
    }
    voxel_sort(C, xyz, v, e);
    for (size_t a = 0; a < n;) {
        lo[m] = a;
        size_t b = a;
        double mean[3] = {0, 0, 0};
        while (b < n && e[b].key == e[a].key) {
            const float *p = xyz + 3 * (size_t)C->points[e[b].index];
            for (int k = 0; k < 3; k++) mean[k] += p[k];
            b++;
        }
        const float mf[3] = {(float)(mean[0] / (double)(b - a)), (float)(mean[1] / (double)(b - a)),
                             (float)(mean[2] / (double)(b - a))};
        double best = INFINITY;
        size_t bi = 0;
        for (size_t i = a; i < b; i++) {
            size_t li = e[i].index;
            double d = sy_v3f_dist2(xyz + 3 * (size_t)C->points[li], mf);
            if (d < best || (d == best && li < bi)) best = d, bi = li;
        }
        memcpy(rep + 3 * m++, xyz + 3 * (size_t)C->points[bi], 3 * sizeof *rep);
        a = b;
    }
    lo[m] = n;
    /* Prim over the m representatives and the seed (index m). */
    double *best = malloc((m + 1) * sizeof *best);
    int32_t *from = malloc((m + 1) * sizeof *from), *first = malloc((m + 1) * sizeof *first),
            *next = malloc((m + 1) * sizeof *next), *stack = malloc((m + 1) * sizeof *stack),
            *place = malloc((m + 1) * sizeof *place);
    uint8_t *done = calloc(m + 1, 1);
    C->twig_pos = m ? malloc(m * 3 * sizeof *C->twig_pos) : NULL;
    C->twig_parent = m ? malloc(m * sizeof *C->twig_parent) : NULL;
    if (!best || !from || !first || !next || !stack || !place || !done || (m && (!C->twig_pos || !C->twig_parent))) {
        free(e), free(lo), free(rep), free(best), free(from), free(first), free(next), free(stack), free(place), free(done);
        return sy_fail(err, SY_EINTERNAL, "clusters: out of memory tracing twigs");
    }
    for (size_t i = 0; i < m; i++) best[i] = sy_v3f_dist2(rep + 3 * i, seed), from[i] = (int32_t)m;
    done[m] = 1;
    for (size_t i = 0; i <= m; i++) first[i] = -1;
    for (size_t step = 0; step < m; step++) {
        size_t j = m;
        for (size_t i = 0; i < m; i++)
            if (!done[i] && (j == m || best[i] < best[j])) j = i;
        done[j] = 1;
        for (size_t i = 0; i < m; i++) {
            if (done[i]) continue;
            double d = sy_v3f_dist2(rep + 3 * i, rep + 3 * j);
            if (d < best[i]) best[i] = d, from[i] = (int32_t)j;
        }
    }
    /* Children lists in descending index, pushed in that order so that the
     * stack pops them ascending: preorder from the seed, children by index. */
    for (size_t i = 0; i < m; i++) next[i] = first[from[i]], first[from[i]] = (int32_t)i;
    /* A tip reaches its voxel's farthest return from the node it hangs
     * from, not the return nearest the voxel's middle: the twig ends where
     * the scan saw it end, up to a voxel further out. */
    for (size_t i = 0; i < m; i++) {
        if (first[i] >= 0) continue;
        const float *f = from[i] == (int32_t)m ? seed : rep + 3 * (size_t)from[i];
        double far = -1;
        size_t fi = 0;
        for (size_t k = lo[i]; k < lo[i + 1]; k++) {
            size_t li = e[k].index;
            double d = sy_v3f_dist2(xyz + 3 * (size_t)C->points[li], f);
            if (d > far || (d == far && li < fi)) far = d, fi = li;
        }
        memcpy(rep + 3 * i, xyz + 3 * (size_t)C->points[fi], 3 * sizeof *rep);
    }
    free(e), free(lo);
    size_t top = 0, out = 0;
    for (int32_t c = first[m]; c >= 0; c = next[c]) stack[top++] = c;
    while (top) {
        int32_t j = stack[--top];
        place[j] = (int32_t)out;
        memcpy(C->twig_pos + 3 * out, rep + 3 * (size_t)j, 3 * sizeof *rep);
        C->twig_parent[out] = from[j] == (int32_t)m ? -1 : place[from[j]];
        out++;
        for (int32_t c = first[j]; c >= 0; c = next[c]) stack[top++] = c;
    }
    C->n_twigs = out;
    C->twig_voxel = out ? (float)v : 0;
    free(rep), free(best), free(from), free(first), free(next), free(stack), free(place), free(done);
    return SY_OK;
}

static void trace_chunk(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    twig_job *J = ctx;
    for (size_t c = begin; c < end; c++) {
        sy_cluster *C = &((sy_clusters *)J->cl)->items[c];
        J->rc[c] = trace_lobe(C, J->main->pos + 3 * (size_t)C->seed, J->xyz, J->v, &J->err[c]);
    }
}

void sy_cluster_twigs_free(sy_cluster *c)
{
    free(c->twig_pos), free(c->twig_parent);
    c->twig_pos = NULL, c->twig_parent = NULL;
    c->n_twigs = 0;
    c->twig_voxel = 0;
}

sy_code sy_clusters_trace_twigs(sy_clusters *cl, const sy_skeleton *main, const float *xyz, const sy_twig_options *o,
                                sy_twig_report *report, sy_error *err)
{
    sy_twig_report local;
    if (!report) report = &local;
    memset(report, 0, sizeof *report);
    sy_code rc = sy_twig_options_check(o, err);
    if (rc) return rc;
    double t0 = sy_now();
    for (size_t c = 0; c < cl->n; c++) sy_cluster_twigs_free(&cl->items[c]);
    if (!cl->n || !o->max_nodes) return SY_OK;
    twig_job J = {cl,
                  main,
                  xyz,
                  0,
                  sy_calloc(cl->n, sizeof *J.count, err, "twigs"),
                  sy_calloc(cl->n, 1, err, "twigs"),
                  sy_calloc(cl->n, sizeof *J.rc, err, "twigs"),
                  sy_calloc(cl->n, sizeof *J.err, err, "twigs")};
    if (!J.count || !J.oom || !J.rc || !J.err) {
        free(J.count), free(J.oom), free(J.rc), free(J.err);
        return SY_EINTERNAL;
    }
    /* A voxel of the ladder voxel_min * 1.25^k whose voxels over all lobes
     * stay within the budget, by bisection: the counts fall as the voxel
     * grows (nearly always: a coarser grid is not nested in a finer one), so
     * it is the finest that fits or one close to it. */
    int steps = (int)floor(log(o->voxel_max / o->voxel_min) / log(VOXEL_STEP) + 1e-9);
    int lo = 0, hi = steps + 1; /* hi: none fits yet */
    while (lo < hi && !rc) {
        int k = (lo + hi) / 2;
        J.v = o->voxel_min * pow(VOXEL_STEP, k);
        sy_parallel_for(cl->n, 1, count_chunk, &J);
        size_t total = 0;
        for (size_t c = 0; c < cl->n && total <= o->max_nodes; c++) {
            if (J.oom[c]) rc = sy_fail(err, SY_EINTERNAL, "clusters: out of memory counting twig voxels");
            total = J.count[c] == SIZE_MAX || total > SIZE_MAX - J.count[c] ? SIZE_MAX : total + J.count[c];
        }
        if (total <= o->max_nodes) hi = k;
        else lo = k + 1;
    }
    if (!rc && lo <= steps) {
        J.v = o->voxel_min * pow(VOXEL_STEP, lo);
        sy_parallel_for(cl->n, 1, trace_chunk, &J);
        for (size_t c = 0; c < cl->n; c++) {
            if (!rc && J.rc[c]) {
                rc = J.rc[c];
                if (err) *err = J.err[c];
            }
            report->nodes += cl->items[c].n_twigs;
        }
        report->voxel = J.v;
    }
    free(J.count), free(J.oom), free(J.rc), free(J.err);
    if (rc)
        for (size_t c = 0; c < cl->n; c++) sy_cluster_twigs_free(&cl->items[c]);
    report->seconds = sy_now() - t0;
    return rc;
}
