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
 * crown has no points between the stem and its foliage to lead growth out.
 * The loop is stages/core/colonize.c's; this file picks the attraction
 * points and the rules. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "skeleton_internal.h"
#include "stages/core/colonize.h"
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
    /* Attraction points: one per voxel of edge step, its points' centroid. */
    float lo[3] = {INFINITY, INFINITY, INFINITY};
    for (size_t i = 0; i < n_pts; i++)
        for (int k = 0; k < 3; k++) lo[k] = fminf(lo[k], pts[3 * i + k]);
    sy_voxel_entry *e = malloc((n_pts ? n_pts : 1) * sizeof *e);
    float *att = malloc((n_pts ? n_pts : 1) * 3 * sizeof *att);
    if (!e || !att) {
        free(e), free(att);
        return sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
    }
    size_t n_att = 0;
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
    sy_colony col;
    sy_colony_options o = {step, kill, COLONIZE_MIN_PULL, COLONIZE_SAME_DIR, max_nodes, 0, NULL, NULL};
    sy_code rc = sy_colony_grow(&col, seed, n_seed, att, n_att, &o, err);
    free(att);
    if (rc) return rc;
    *pos_out = col.pos, *parent_out = col.parent, *n_out = col.n;
    free(col.first), free(col.next);
    return SY_OK;
}
