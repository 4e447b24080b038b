/* Limbs for a crown whose inside the scan never saw: space colonisation
 * (Runions, Lane & Prusinkiewicz 2007, "Modeling trees with a space
 * colonization algorithm"). A dense leaf-on crown shows a terrestrial
 * scanner its outer foliage and hardly a limb; the shortest paths through it
 * then run along the shell, and hung from a rebuilt stem they are spokes
 * (docs/skeleton.md). The foliage returns themselves are the evidence of
 * where limbs must go, and the attraction points of the colonisation: each
 * pulls its nearest node, a node with pull grows one step along the mean
 * direction, and a point a node comes within the kill distance of is
 * reached. Branches so grown fork where the foliage divides and end in it,
 * which is what the clusters stage and cluster texturing hang leaves from.
 * The influence radius is unbounded (the open variant of the paper): a shell
 * crown has no points between the stem and its foliage to lead growth out. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "skeleton_internal.h"
#include "stages/core/voxel.h"

/* A node whose pulls nearly cancel (points on all sides of it, the stem in
 * a ring of foliage) does not grow that step: the mean of unit vectors must
 * be at least this long. */
#define COLONIZE_MIN_PULL 0.05
/* A node grows no child within this cosine of an existing child's
 * direction: two attraction points balanced about a branch would otherwise
 * stack nodes on one spot (the paper's duplicate-node check). */
#define COLONIZE_SAME_DIR 0.98

sy_code sy_colonize(const float *seed, size_t n_seed, const float *pts, size_t n_pts, double step, double kill,
                    size_t max_nodes, float **pos_out, int32_t **parent_out, size_t *n_out, sy_error *err)
{
    *pos_out = NULL;
    *parent_out = NULL;
    *n_out = 0;
    if (max_nodes < n_seed) max_nodes = n_seed;
    sy_code rc = SY_OK;
    /* Attraction points: one per voxel of edge step, its points' centroid. */
    float lo[3] = {INFINITY, INFINITY, INFINITY};
    for (size_t i = 0; i < n_pts; i++)
        for (int k = 0; k < 3; k++) lo[k] = fminf(lo[k], pts[3 * i + k]);
    sy_voxel_entry *e = malloc((n_pts ? n_pts : 1) * sizeof *e);
    float *att = malloc((n_pts ? n_pts : 1) * 3 * sizeof *att);
    float *pos = malloc(max_nodes * 3 * sizeof *pos);
    int32_t *parent = malloc(max_nodes * sizeof *parent), *first = malloc(max_nodes * sizeof *first);
    int32_t *next = malloc(max_nodes * sizeof *next);
    double *pull = calloc(max_nodes * 4, sizeof *pull);
    size_t n_att = 0;
    int32_t *near = NULL;
    double *near_d2 = NULL;
    if (!e || !att || !pos || !parent || !first || !next || !pull) goto oom;
    if (n_pts) sy_voxel_sort(pts, n_pts, lo, step, e);
    for (size_t a = 0; a < n_pts;) {
        size_t b = a;
        double c[3] = {0, 0, 0};
        for (; b < n_pts && e[b].key == e[a].key; b++)
            for (int k = 0; k < 3; k++) c[k] += pts[3 * e[b].index + k];
        for (int k = 0; k < 3; k++) att[3 * n_att + k] = (float)(c[k] / (double)(b - a));
        n_att++;
        a = b;
    }
    free(e);
    e = NULL;
    near = malloc((n_att ? n_att : 1) * sizeof *near);
    near_d2 = malloc((n_att ? n_att : 1) * sizeof *near_d2);
    if (!near || !near_d2) goto oom;
    memcpy(pos, seed, n_seed * 3 * sizeof *pos);
    for (size_t v = 0; v < max_nodes; v++) parent[v] = first[v] = next[v] = -1;
    size_t n = n_seed, checked = 0, alive = n_att;
    for (size_t a = 0; a < n_att; a++) {
        near[a] = -1;
        near_d2[a] = INFINITY;
    }
    double kill2 = kill * kill;
    while (alive && n < max_nodes) {
        /* Each live point's nearest node: only the nodes added since the last
         * round can have come closer. */
        for (size_t a = 0; a < n_att; a++) {
            if (near[a] == -2) continue;
            const float *p = att + 3 * a;
            for (size_t v = checked; v < n; v++) {
                double dx = pos[3 * v] - p[0], dy = pos[3 * v + 1] - p[1], dz = pos[3 * v + 2] - p[2];
                double d2 = dx * dx + dy * dy + dz * dz;
                if (d2 < near_d2[a]) {
                    near_d2[a] = d2;
                    near[a] = (int32_t)v;
                }
            }
            if (near_d2[a] <= kill2) {
                near[a] = -2; /* reached */
                alive--;
            }
        }
        checked = n;
        memset(pull, 0, n * 4 * sizeof *pull);
        for (size_t a = 0; a < n_att; a++) {
            if (near[a] < 0) continue;
            const float *p = att + 3 * a, *q = pos + 3 * (size_t)near[a];
            double d = sqrt(near_d2[a]);
            double *u = pull + 4 * (size_t)near[a];
            for (int k = 0; k < 3; k++) u[k] += (p[k] - q[k]) / d;
            u[3] += 1;
        }
        size_t grown = 0, n0 = n;
        for (size_t v = 0; v < n0 && n < max_nodes; v++) {
            double *u = pull + 4 * v;
            if (u[3] == 0) continue;
            double len = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
            if (len < COLONIZE_MIN_PULL * u[3]) continue;
            double dir[3] = {u[0] / len, u[1] / len, u[2] / len};
            int same = 0;
            for (int32_t c = first[v]; c >= 0 && !same; c = next[c]) {
                double cd[3], cl = 0, dot = 0;
                for (int k = 0; k < 3; k++) {
                    cd[k] = pos[3 * (size_t)c + k] - pos[3 * v + k];
                    cl += cd[k] * cd[k];
                }
                cl = sqrt(cl);
                for (int k = 0; k < 3; k++) dot += cd[k] * dir[k];
                same = cl > 0 && dot >= COLONIZE_SAME_DIR * cl;
            }
            if (same) continue;
            for (int k = 0; k < 3; k++) pos[3 * n + k] = (float)(pos[3 * v + k] + step * dir[k]);
            parent[n] = (int32_t)v;
            next[n] = first[v];
            first[v] = (int32_t)n;
            n++;
            grown++;
        }
        if (!grown) break;
    }
    *pos_out = pos;
    *parent_out = parent;
    *n_out = n;
    pos = NULL;
    parent = NULL;
    goto done;
oom:
    rc = sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
done:
    free(e);
    free(att);
    free(pos);
    free(parent);
    free(first);
    free(next);
    free(pull);
    free(near);
    free(near_d2);
    return rc;
}
