/* Which stems each level of detail keeps. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_internal.h"

/* Level 1 drops stems thinner than this share of the trunk radius; it
 * doubles per further level. Stems shorter than 3 % of the tree's height
 * went too, until stop 48: with their children, so a scanned sapling's
 * traced twigs, chains of short stems, left its coarse levels bare (the
 * rTwig cloud's LOD1 / LOD2 / LOD3 silhouettes 0.873 / 0.685 / 0.457 against
 * LOD0, 0.933 / 0.766 / 0.532 without); the reach ranking below drops the
 * short stems that matter little. The grown library's levels are the same
 * without it. */
#define DROP_RADIUS 0.03f
/* A level restored from a cliff aims at this share of the previous level. */
#define FLOOR_SHARE 0.3

size_t sy_lod_bark_triangles(const sy_stems *st, const sy_lod_params *lp)
{
    size_t total = 0;
    for (size_t i = 0; i < st->n; i++) {
        size_t nv, ni;
        sy_tube_counts(st, i, lp, &nv, &ni);
        total += ni / 3;
    }
    return total;
}

typedef struct {
    float importance;
    int depth;
    int32_t index;
} ranked;

/* Most important first; ties put parents (smaller depth) first so a prefix
 * of the ranking is always closed under "parent of". */
static int cmp_ranked(const void *a, const void *b)
{
    const ranked *x = a, *y = b;
    if (x->importance != y->importance) return x->importance > y->importance ? -1 : 1;
    if (x->depth != y->depth) return x->depth < y->depth ? -1 : 1;
    return (x->index > y->index) - (x->index < y->index);
}

/* Stems thinner than this (twice the default min_radius) rank lower in
 * proportion: drawn at min_radius with their own ring spacing, they were
 * most of the LOD0 slivers (the aspen's 0.11 % of its bark became 0.24 %
 * when they ranked by reach alone). */
#define THIN_STEM 0.003f

/* The stems by importance, most important first: how far the stem's
 * subtree reaches from its base (st->reach), the geometric error of
 * dropping it, as its leaves then move onto the nearest kept ancestor
 * (THIN_STEM scales the thinnest down); never above the parent's, so
 * dropping in reverse rank order removes children before parents. Before, a volume proxy r^2 L ranked the long
 * thin stems round a crown's top and a willow's hanging whips last: the
 * budget dropped them and their leaves moved metres down onto the limbs
 * (the London plane's leaves topped out 3.6 m under its tree, the weeping
 * willow's 4.6 m). NULL when out of memory. */
static ranked *rank_stems(const sy_stems *st)
{
    ranked *rk = malloc((st->n ? st->n : 1) * sizeof *rk);
    float *imp = malloc((st->n ? st->n : 1) * sizeof *imp);
    if (!rk || !imp) {
        free(rk), free(imp);
        return NULL;
    }
    for (size_t o = 0; o < st->n; o++) {
        int32_t i = st->by_depth[o];
        const sy_stem *s = &st->s[i];
        float v = st->reach ? st->reach[i] * (s->r_base < THIN_STEM ? s->r_base / THIN_STEM : 1)
                            : s->r_base * s->r_base * s->length;
        imp[i] = s->parent >= 0 && imp[s->parent] < v ? imp[s->parent] : v;
        rk[o] = (ranked){imp[i], s->depth, i};
    }
    free(imp);
    qsort(rk, st->n, sizeof *rk, cmp_ranked);
    return rk;
}

int sy_lod_fit_budget(const sy_stems *st, sy_lod_params *lp, size_t *count_io, size_t budget)
{
    size_t count = *count_io;
    ranked *rk = rank_stems(st);
    if (!rk) return 0;
    for (size_t o = st->n; o-- > 0 && count > budget;) {
        int32_t i = rk[o].index;
        if (!lp->keep[i] || st->s[i].parent < 0) continue;
        size_t nv, ni;
        sy_tube_counts(st, (size_t)i, lp, &nv, &ni);
        lp->keep[i] = 0;
        count -= ni / 3;
    }
    free(rk);
    *count_io = count;
    return 1;
}

int sy_lod_restore(const sy_stems *st, const uint8_t *prev_keep, sy_lod_params *lp, size_t *count_io, size_t target)
{
    size_t count = *count_io;
    ranked *rk = rank_stems(st);
    if (!rk) return 0;
    /* Ranked parents-first, so a stem's parent has had its turn before it. */
    for (size_t o = 0; o < st->n && count < target; o++) {
        int32_t i = rk[o].index;
        const sy_stem *s = &st->s[i];
        if (lp->keep[i] || !prev_keep[i] || (s->parent >= 0 && !lp->keep[s->parent])) continue;
        lp->keep[i] = 1;
        size_t nv, ni;
        sy_tube_counts(st, (size_t)i, lp, &nv, &ni);
        if (count + ni / 3 > target) {
            lp->keep[i] = 0;
            continue;
        }
        count += ni / 3;
    }
    free(rk);
    *count_io = count;
    return 1;
}

int sy_lod_select(const sy_stems *st, const uint8_t *prev_keep, size_t prev_tris, size_t lent, sy_lod_params *lp,
                  size_t *tris)
{
    float grow = ldexpf(1.0f, lp->level - 1);
    float r_min = DROP_RADIUS * grow * st->trunk_radius;
    for (size_t o = 0; o < st->n; o++) {
        int32_t i = st->by_depth[o];
        const sy_stem *s = &st->s[i];
        int big = s->parent < 0 || s->r_base >= r_min;
        lp->keep[i] = prev_keep[i] && big && (s->parent < 0 || lp->keep[s->parent]);
    }
    /* SY_LOD_SHARE of the previous level's bark, less what it lends the
     * cards: the level's drawn triangles stay within half of the previous
     * level's. */
    size_t count = sy_lod_bark_triangles(st, lp), budget = (size_t)(SY_LOD_SHARE * (double)prev_tris);
    budget = budget > lent ? budget - lent : 0;
    if (count > budget && !sy_lod_fit_budget(st, lp, &count, budget)) return 0;
    /* No cliffs: when the thresholds dropped so much that the level has under
     * a quarter of the previous one's triangles, the most important dropped
     * stems come back (parents before children) up to FLOOR_SHARE of it. */
    size_t floor = (size_t)(FLOOR_SHARE * (double)prev_tris);
    if (count < prev_tris / 4 && count <= budget) {
        if (!sy_lod_restore(st, prev_keep, lp, &count, floor < budget ? floor : budget)) return 0;
        /* A small tree's stems may each cost more than the gap to the floor
         * (the airborne palm's LOD3 kept 24 of 198 triangles: every frond
         * was over the 35 that fit); then one may take the budget. */
        if (count < prev_tris / 4 && !sy_lod_restore(st, prev_keep, lp, &count, budget)) return 0;
    }
    *tris = count;
    return count <= budget;
}
