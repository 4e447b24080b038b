/* How much of a simulated tree's thick-branch length the scan can show at all:
 * the ceiling that leaf occlusion puts on the skeleton's recall_r2cm.
 *
 * `sylva eval` counts a truth sample (1 cm along an edge whose stem has a base
 * radius >= 2 cm) as found when the model's axis passes within
 * max(2 r, 5 cm) of it. A reconstruction placed from the points can only be
 * put there on evidence, so this program asks, per such sample, whether any
 * wood return (the scanner's isWood label) lies within that tolerance, and
 * whether any return at all (wood or leaf) does. The first share bounds what
 * a method that follows wood can reach, up to bridging short gaps along a
 * straight limb; the second is the share where the scan holds anything.
 *
 * Usage: bench_visibility SCAN.las TRUTH.json   (from `sylva scan ... --truth`) */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/eval/eval.h"
#include "stages/ingest/ingest.h"

#define CELL 0.05 /* grid cell edge in metres: the smallest tolerance */

/* Points hashed into a uniform grid (counting sort by cell key). */
typedef struct {
    double lo[3];
    int dim[3];
    size_t *start; /* cells + 1 */
    float *pts;    /* 3 per point, cell-sorted, world - lo */
} grid;

static size_t cell_of(const grid *g, const double p[3], int c[3])
{
    for (int k = 0; k < 3; k++) {
        c[k] = (int)floor((p[k] - g->lo[k]) / CELL);
        if (c[k] < 0) c[k] = 0;
        if (c[k] >= g->dim[k]) c[k] = g->dim[k] - 1;
    }
    return ((size_t)c[2] * (size_t)g->dim[1] + (size_t)c[1]) * (size_t)g->dim[0] + (size_t)c[0];
}

/* Grid over the wood returns of c (wood NULL: over every point). */
static int grid_build(grid *g, const sy_cloud *c, const double *wood)
{
    double hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int k = 0; k < 3; k++) g->lo[k] = INFINITY;
    for (size_t i = 0; i < c->n; i++)
        for (int k = 0; k < 3; k++) {
            double v = c->origin[k] + c->xyz[3 * i + k];
            g->lo[k] = fmin(g->lo[k], v);
            hi[k] = fmax(hi[k], v);
        }
    size_t cells = 1;
    for (int k = 0; k < 3; k++) {
        g->dim[k] = (int)((hi[k] - g->lo[k]) / CELL) + 1;
        cells *= (size_t)g->dim[k];
    }
    if (cells > (size_t)1 << 28) return -1;
    g->start = calloc(cells + 1, sizeof *g->start);
    g->pts = malloc(3 * (c->n ? c->n : 1) * sizeof *g->pts);
    size_t *key = malloc((c->n ? c->n : 1) * sizeof *key);
    if (!g->start || !g->pts || !key) return -1;
    int cc[3];
    for (size_t i = 0; i < c->n; i++) {
        double p[3] = {c->origin[0] + c->xyz[3 * i], c->origin[1] + c->xyz[3 * i + 1], c->origin[2] + c->xyz[3 * i + 2]};
        key[i] = cell_of(g, p, cc);
        if (!(wood && wood[i] < 0.5)) g->start[key[i] + 1]++;
    }
    for (size_t k = 0; k < cells; k++) g->start[k + 1] += g->start[k];
    size_t *fill = malloc((cells + 1) * sizeof *fill);
    if (!fill) return -1;
    memcpy(fill, g->start, (cells + 1) * sizeof *fill);
    for (size_t i = 0; i < c->n; i++) {
        if (wood && wood[i] < 0.5) continue;
        size_t at = fill[key[i]]++;
        for (int k = 0; k < 3; k++) g->pts[3 * at + k] = (float)(c->origin[k] + c->xyz[3 * i + k] - g->lo[k]);
    }
    free(fill);
    free(key);
    return 0;
}

/* 1 when a grid point lies within tol of p. */
static int any_within(const grid *g, const double p[3], double tol)
{
    int lo[3], hi[3];
    for (int k = 0; k < 3; k++) {
        lo[k] = (int)floor((p[k] - tol - g->lo[k]) / CELL);
        hi[k] = (int)floor((p[k] + tol - g->lo[k]) / CELL);
        if (lo[k] < 0) lo[k] = 0;
        if (hi[k] >= g->dim[k]) hi[k] = g->dim[k] - 1;
        if (lo[k] > hi[k]) return 0;
    }
    double q[3] = {p[0] - g->lo[0], p[1] - g->lo[1], p[2] - g->lo[2]}, t2 = tol * tol;
    for (int z = lo[2]; z <= hi[2]; z++)
        for (int y = lo[1]; y <= hi[1]; y++)
            for (int x = lo[0]; x <= hi[0]; x++) {
                size_t cell = ((size_t)z * (size_t)g->dim[1] + (size_t)y) * (size_t)g->dim[0] + (size_t)x;
                for (size_t i = g->start[cell]; i < g->start[cell + 1]; i++) {
                    double dx = g->pts[3 * i] - q[0], dy = g->pts[3 * i + 1] - q[1], dz = g->pts[3 * i + 2] - q[2];
                    if (dx * dx + dy * dy + dz * dz <= t2) return 1;
                }
            }
    return 0;
}

/* Base radius of every branch id: the radius at its first node (a node whose
 * parent is on another branch, or the root). */
static float *branch_base_radius(const sy_skeleton *s)
{
    int32_t nb = sy_skeleton_branch_count(s);
    float *base = calloc((size_t)(nb > 0 ? nb : 1), sizeof *base);
    if (!base) return NULL;
    for (size_t i = 0; i < s->n; i++) {
        int32_t p = s->parent[i], b = s->branch[i];
        if (b >= 0 && b < nb && (p < 0 || s->branch[p] != b)) base[b] = s->radius[i];
    }
    return base;
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: bench_visibility SCAN.las TRUTH.json\n");
        return 1;
    }
    sy_error err = {0};
    sy_cloud c;
    sy_forest f;
    if (sy_read_cloud(argv[1], &c, &err) || sy_forest_read(argv[2], &f, &err)) {
        fprintf(stderr, "%s\n", err.msg);
        return 2;
    }
    const double *wood = sy_cloud_attr(&c, "isWood");
    if (!wood) {
        fprintf(stderr, "%s: no isWood attribute (a `sylva scan` LAS holds one)\n", argv[1]);
        return 2;
    }
    grid gw = {0}, ga = {0};
    if (grid_build(&gw, &c, wood) || grid_build(&ga, &c, NULL)) {
        fprintf(stderr, "out of memory\n");
        return 3;
    }
    const double step = 0.01;
    double len = 0, seen_wood = 0, seen_any = 0;
    for (size_t t = 0; t < f.n_trees; t++) {
        const sy_skeleton *s = &f.trees[t].skel;
        float *base = branch_base_radius(s);
        if (!base) return 3;
        for (size_t i = 0; i < s->n; i++) {
            int32_t p = s->parent[i];
            if (p < 0 || base[s->branch[i]] < 0.02f) continue;
            double a[3], b[3];
            for (int k = 0; k < 3; k++) {
                a[k] = s->origin[k] + s->pos[3 * (size_t)p + k];
                b[k] = s->origin[k] + s->pos[3 * i + k];
            }
            double L = sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]));
            int m = (int)ceil(L / step);
            for (int j = 0; j < m; j++) {
                double u = (j + 0.5) / m, q[3];
                for (int k = 0; k < 3; k++) q[k] = a[k] + u * (b[k] - a[k]);
                double r = s->radius[p] + u * (s->radius[i] - s->radius[p]);
                double tol = fmax(2 * r, 0.05), w = L / m;
                len += w;
                if (any_within(&gw, q, tol)) seen_wood += w;
                if (any_within(&ga, q, tol)) seen_any += w;
            }
        }
        free(base);
    }
    size_t n_wood = 0;
    for (size_t i = 0; i < c.n; i++) n_wood += wood[i] >= 0.5;
    printf("%s: %zu points (%.1f%% wood); thick-stem length %.1f m; within tolerance of a wood return %.3f, "
           "of any return %.3f\n",
           argv[1], c.n, 100.0 * (double)n_wood / (double)(c.n ? c.n : 1), len, len > 0 ? seen_wood / len : NAN,
           len > 0 ? seen_any / len : NAN);
    free(gw.start);
    free(gw.pts);
    free(ga.start);
    free(ga.pts);
    sy_forest_free(&f);
    sy_cloud_free(&c);
    return 0;
}
