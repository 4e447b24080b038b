/* Wood/leaf separation measured on a labelled scan (the isWood attribute of
 * `sylva scan`, used here only, never at runtime): the skeleton stage's
 * prefix (preprocess as `sylva run`, graph, Dijkstra from the base), then the
 * accuracy of sy_classify_wood and of the candidate rules it was chosen from
 * (subtree size, its one-ring maximum, 1-/2-ring PCA surface variation and
 * linearity). Usage: bench_woodleaf SCAN.las [beta] */
#define _DEFAULT_SOURCE
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "stages/core/parallel.h"
#include "stages/ingest/ingest.h"
#include "stages/preprocess/preprocess.h"
#include "stages/skeleton/skeleton_internal.h"

typedef struct { double d; uint32_t i; } di;
static int cmp_di(const void *a, const void *b)
{
    double x = ((const di *)a)->d, y = ((const di *)b)->d;
    return x > y ? -1 : x < y;
}

static void score(const char *name, const uint8_t *pred, const double *truth, size_t n)
{
    size_t tp = 0, fp = 0, fn = 0, tn = 0;
    for (size_t i = 0; i < n; i++) {
        int t = truth[i] > 0.5;
        if (pred[i] && t) tp++; else if (pred[i]) fp++; else if (t) fn++; else tn++;
    }
    printf("%-28s acc %.3f wood_recall %.3f wood_prec %.3f leaf_recall %.3f pred_wood %.3f\n", name,
           (double)(tp + tn) / n, (double)tp / (tp + fn + 1e-9), (double)tp / (tp + fp + 1e-9),
           (double)tn / (tn + fp + 1e-9), (double)(tp + fp) / n);
}

/* Eigenvalues of a symmetric 3x3 matrix, descending (trigonometric method). */
static void eig3(const double a[6], double ev[3]) /* xx yy zz xy xz yz */
{
    double p1 = a[3] * a[3] + a[4] * a[4] + a[5] * a[5];
    double q = (a[0] + a[1] + a[2]) / 3;
    double p2 = (a[0] - q) * (a[0] - q) + (a[1] - q) * (a[1] - q) + (a[2] - q) * (a[2] - q) + 2 * p1;
    double p = sqrt(p2 / 6);
    if (p < 1e-30) { ev[0] = ev[1] = ev[2] = q; return; }
    double b00 = (a[0] - q) / p, b11 = (a[1] - q) / p, b22 = (a[2] - q) / p, b01 = a[3] / p, b02 = a[4] / p,
           b12 = a[5] / p;
    double r = (b00 * (b11 * b22 - b12 * b12) - b01 * (b01 * b22 - b12 * b02) + b02 * (b01 * b12 - b11 * b02)) / 2;
    double phi = r <= -1 ? M_PI / 3 : r >= 1 ? 0 : acos(r) / 3;
    ev[0] = q + 2 * p * cos(phi);
    ev[2] = q + 2 * p * cos(phi + 2 * M_PI / 3);
    ev[1] = 3 * q - ev[0] - ev[2];
}

/* Covariance eigenvalues of the 1-ring (ring 1) or 2-ring neighbourhood. */
static void features(const float *xyz, const sy_graph *g, size_t i, int ring, uint32_t *buf, uint32_t *seen,
                     uint32_t stamp, double ev[3])
{
    size_t m = 0;
    buf[m++] = (uint32_t)i;
    seen[i] = stamp;
    for (size_t h = 0, end = 1; ring-- > 0; end = m)
        for (; h < end; h++) {
            uint32_t u = buf[h];
            for (size_t e = g->start[u]; e < g->start[u + 1] && m < 4000; e++) {
                uint32_t v = g->adj[e];
                if (seen[v] == stamp) continue;
                seen[v] = stamp;
                buf[m++] = v;
            }
        }
    double c[3] = {0}, a[6] = {0};
    for (size_t t = 0; t < m; t++) for (int k = 0; k < 3; k++) c[k] += xyz[3 * (size_t)buf[t] + k] / (double)m;
    for (size_t t = 0; t < m; t++) {
        const float *q = xyz + 3 * (size_t)buf[t];
        double d[3] = {q[0] - c[0], q[1] - c[1], q[2] - c[2]};
        a[0] += d[0] * d[0]; a[1] += d[1] * d[1]; a[2] += d[2] * d[2];
        a[3] += d[0] * d[1]; a[4] += d[0] * d[2]; a[5] += d[1] * d[2];
    }
    eig3(a, ev);
}

int main(int argc, char **argv)
{
    sy_set_threads(1);
    sy_error err = {0};
    sy_cloud c;
    if (argc < 2 || sy_read_cloud(argv[1], &c, &err)) { fprintf(stderr, "%s\n", err.msg); return 1; }
    sy_preprocess_options po;
    po = sy_preprocess_options_default();
    po.remove_ground = 1;
    po.normals = 0;
    sy_preprocess_result pr;
    if (sy_preprocess(&c, &po, &pr, &err)) { fprintf(stderr, "%s\n", err.msg); return 1; }
    const double *truth = sy_cloud_attr(&c, "isWood");
    if (!truth) { fprintf(stderr, "no isWood\n"); return 1; }
    size_t n = c.n;
    const float *xyz = c.xyz;
    double s = sy_estimate_spacing(xyz, n), w = fmax(4 * s, 0.02);
    double zlo = INFINITY, zhi = -INFINITY;
    for (size_t i = 0; i < n; i++) { zlo = fmin(zlo, xyz[3 * i + 2]); zhi = fmax(zhi, xyz[3 * i + 2]); }
    double slab = fmax(w, 0.01 * (zhi - zlo)), z0;
    uint32_t root = sy_find_root(xyz, n, slab, &z0);
    sy_graph g;
    if (sy_graph_build(xyz, n, 12, 2 * s, root, &g, &err)) return 1;
    double *dist = calloc(n, 8), *path = calloc(n, 8);
    int32_t *spt = calloc(n, 4), *src = calloc(n, 4), *mark = calloc(n, 4);
    size_t ns = sy_base_sources(xyz, n, &g, root, z0 + slab, src, mark);
    double beta = argc > 2 ? atof(argv[2]) : 1;
    sy_graph_dijkstra(&g, (const uint32_t *)src, ns, beta, dist, spt, path, &err);
    di *ord = malloc(n * sizeof *ord);
    for (size_t i = 0; i < n; i++) { ord[i].d = dist[i]; ord[i].i = (uint32_t)i; }
    qsort(ord, n, sizeof *ord, cmp_di);
    double *cnt = calloc(n, 8), *nmax = calloc(n, 8);
    for (size_t t = 0; t < n; t++) {
        uint32_t i = ord[t].i;
        cnt[i] += 1;
        if (spt[i] >= 0) cnt[spt[i]] += cnt[i];
    }
    size_t wt = 0;
    for (size_t i = 0; i < n; i++) wt += truth[i] > 0.5;
    printf("%zu points, spacing %.4f, truth wood %.3f\n", n, s, (double)wt / n);
    uint8_t *pred = calloc(n, 1);
    for (size_t i = 0; i < n; i++) {
        nmax[i] = cnt[i];
        for (size_t e = g.start[i]; e < g.start[i + 1]; e++) nmax[i] = fmax(nmax[i], cnt[g.adj[e]]);
    }
    double T[] = {2, 5, 10, 30, 100, 300, 1000};
    char name[64];
    for (int k = 0; k < 7; k++) {
        for (size_t i = 0; i < n; i++) pred[i] = cnt[i] >= T[k];
        snprintf(name, sizeof name, "cnt >= %g", T[k]);
        score(name, pred, truth, n);
        for (size_t i = 0; i < n; i++) pred[i] = nmax[i] >= T[k];
        snprintf(name, sizeof name, "nbr max cnt >= %g", T[k]);
        score(name, pred, truth, n);
    }
    uint32_t *buf = malloc(4001 * 4), *seen = calloc(n, 4);
    double *sv1 = calloc(n, 8), *sv2 = calloc(n, 8), *lin2 = calloc(n, 8);
    for (size_t i = 0; i < n; i++) {
        double ev[3];
        features(xyz, &g, i, 1, buf, seen, (uint32_t)(2 * i + 1), ev);
        sv1[i] = ev[2] / (ev[0] + ev[1] + ev[2] + 1e-30);
        features(xyz, &g, i, 2, buf, seen, (uint32_t)(2 * i + 2), ev);
        sv2[i] = ev[2] / (ev[0] + ev[1] + ev[2] + 1e-30);
        lin2[i] = (ev[0] - ev[1]) / (ev[0] + 1e-30);
    }
    size_t nw;
    uint32_t *order = malloc(n * sizeof *order);
    for (double share = 0.001; share < 0.03; share *= 2.5) {
        sy_classify_wood(&g, spt, dist, share, pred, order, &nw, &err);
        snprintf(name, sizeof name, "sy_classify_wood %.4f", share);
        score(name, pred, truth, n);
    }
    double S[] = {0.005, 0.01, 0.02, 0.04, 0.08};
    for (int k = 0; k < 5; k++) {
        for (size_t i = 0; i < n; i++) pred[i] = sv1[i] < S[k];
        snprintf(name, sizeof name, "sv1 < %g", S[k]);
        score(name, pred, truth, n);
        for (size_t i = 0; i < n; i++) pred[i] = sv2[i] < S[k];
        snprintf(name, sizeof name, "sv2 < %g", S[k]);
        score(name, pred, truth, n);
    }
    double L[] = {0.5, 0.7, 0.8, 0.9};
    for (int k = 0; k < 4; k++) {
        for (size_t i = 0; i < n; i++) pred[i] = lin2[i] > L[k];
        snprintf(name, sizeof name, "lin2 > %g", L[k]);
        score(name, pred, truth, n);
    }
    return 0;
}
