/* Limb fairing: the level sets put one node per bin at the centroid of what
 * the scanner saw of a limb, and in a leafy crown that is as much foliage as
 * wood. The chains then wander at the scale of the crown's leaf clumps, and
 * a 5 cm limb drawn along them loops and kinks (AdTree's tree33: loops of
 * 0.4-0.6 m on limbs 4-8 cm thick). A limb is stiff in proportion to its
 * thickness, so each chain node is smoothed over a length proportional to
 * its radius: Laplacian passes (Taubin 1995, "A signal processing approach
 * to fair surface design": repeated [1/4 1/2 1/4] passes are a Gaussian of
 * variance passes / 2 in node steps), as many at a node as make the
 * Gaussian's width there sigma_factor x its radius. Twigs of a few
 * millimetres get a pass or two; tips and the root stay where they are,
 * so the tree keeps its extent. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "skeleton.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* One branch's chain, from its first node c0 (whose parent, the fork, is
 * faired already and stays put) to its tip, which stays put too: pass
 * counts as in sy_skeleton_fair_limbs, Jacobi passes over the chain's
 * positions and its radii (not c0's where its parent is the thicker limb
 * it leaves). chain, passes, pos and rad are scratch of the chain's length. */
static void fair_chain(sy_skeleton *s, const int32_t *cont, int32_t c0, double sigma_factor, int32_t *chain,
                       int *passes, float *pos, float *rad)
{
    const int max_passes = 400;
    size_t m = 0;
    for (int32_t v = c0; v >= 0; v = cont[v]) chain[m++] = v;
    int most = 0;
    for (size_t k = 0; k + 1 < m; k++) {
        size_t i = (size_t)chain[k];
        double step = 0.5 * (sy_skeleton_edge_length(s, i) + sy_skeleton_edge_length(s, (size_t)chain[k + 1]));
        double w = sigma_factor * s->radius[i] / step, q = ceil(2 * w * w); /* the width in node steps */
        passes[k] = step > 0 && q >= 0 ? (q > max_passes ? max_passes : (int)q) : 0; /* NaN: none */
        if (passes[k] > most) most = passes[k];
    }
    for (int pass = 0; pass < most; pass++) {
        for (size_t k = 0; k + 1 < m; k++) {
            if (passes[k] <= pass) continue;
            size_t i = (size_t)chain[k], p = (size_t)s->parent[i], c = (size_t)chain[k + 1];
            for (int q = 0; q < 3; q++)
                pos[3 * k + q] = 0.5f * s->pos[3 * i + q] + 0.25f * (s->pos[3 * p + q] + s->pos[3 * c + q]);
            rad[k] = s->branch[p] == s->branch[i] ? 0.5f * s->radius[i] + 0.25f * (s->radius[p] + s->radius[c])
                                                  : s->radius[i];
        }
        for (size_t k = 0; k + 1 < m; k++) {
            if (passes[k] <= pass) continue;
            memcpy(s->pos + 3 * (size_t)chain[k], pos + 3 * k, 3 * sizeof *pos);
            s->radius[chain[k]] = rad[k];
        }
    }
}

/* The root's chain (root, cont[root], ...) into chain; its length. */
static size_t root_chain(const int32_t *cont, int32_t root, int32_t *chain)
{
    size_t len = 0;
    for (int32_t v = root; v >= 0; v = cont[v]) chain[len++] = v;
    return len;
}

sy_code sy_skeleton_fair_limbs(sy_skeleton *s, double sigma_factor, double breast_z, sy_error *err)
{
    size_t n = s->n;
    if (!(sigma_factor > 0) || n < 3) return SY_OK;
    int32_t *cont = malloc(n * sizeof *cont), *order = malloc(n * sizeof *order), *chain = malloc(n * sizeof *chain);
    int32_t *first = malloc(n * sizeof *first), *next = malloc(n * sizeof *next);
    int *passes = malloc(n * sizeof *passes);
    float *pos = malloc(n * 3 * sizeof *pos), *rad = malloc(n * sizeof *rad), *before = malloc(n * 3 * sizeof *before);
    if (!cont || !order || !chain || !first || !next || !passes || !pos || !rad || !before) {
        free(cont), free(order), free(chain), free(first), free(next), free(passes), free(pos), free(rad), free(before);
        return sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
    }
    /* A node is smoothed along its own chain: its parent and its child of
     * the same branch. Branches are faired parents first, each bent first
     * by as much as its fork moved, so a side branch stays on the node it
     * leaves (left alone, forks on tree33 moved up to 0.35 m from their
     * twigs, on stretched first edges). */
    sy_skeleton_branch_next(s, cont);
    sy_skeleton_children(s, first, next);
    size_t m = sy_skeleton_breadth_first(s, first, next, order);
    memcpy(before, s->pos, n * 3 * sizeof *before);
    int32_t root = m ? order[0] : -1;
    double breast_r = root >= 0 && s->parent[root] < 0
                          ? sy_skeleton_radius_at_height(s, chain, root_chain(cont, root, chain), breast_z, NULL)
                          : NAN;
    for (size_t h = 0; h < m; h++) {
        int32_t b = order[h], f = s->parent[b];
        if (f >= 0 && s->branch[f] == s->branch[b]) continue; /* not a branch's first node */
        if (f >= 0) {
            /* The fork's displacement, in full at the branch's first node
             * and down to none over the fork's own smoothing width (sigma x
             * its radius): the first edge keeps its length and the rest
             * stays on what the scan saw. Carried whole, the crowns shifted
             * with every fork below them (rTwig's sapling lost 0.05 of
             * silhouette IoU; bent down to its tip, 0.02). */
            float d[3];
            for (int q = 0; q < 3; q++) d[q] = s->pos[3 * (size_t)f + q] - before[3 * (size_t)f + q];
            double reach = sigma_factor * s->radius[f], at = 0;
            for (int32_t v = b; v >= 0 && at < reach; v = cont[v]) {
                if (v != b) {
                    if (cont[v] < 0) break; /* the tip stays */
                    at += sy_skeleton_edge_length(s, (size_t)v);
                }
                float w = at < reach ? (float)(1 - at / reach) : 0;
                for (int q = 0; q < 3; q++) s->pos[3 * (size_t)v + q] += w * d[q];
            }
            fair_chain(s, cont, b, sigma_factor, chain, passes, pos, rad);
        } else if (cont[b] >= 0) {
            fair_chain(s, cont, cont[b], sigma_factor, chain, passes, pos, rad); /* the root stays */
        }
    }
    /* The trunk keeps its radius at breast height, the DBH its circle fit
     * measured: averaging over sigma x a trunk's radius (most of a metre)
     * would carry the taper above it down to it (the trunk drawn by its
     * rings, docs/skeleton.md: the simulated beech's 0.373 m at 1.19 m
     * became 0.365 m). The correction is in full on the two nodes breast
     * height lies between and fades out over the fairing's own width
     * beyond them: scaled whole, the butt and the top thickened with it
     * (0.30 -> 0.35 m at the root of a trunk thinned from 0.30 to 0.20 m at
     * 1.5 m). */
    double span[2];
    size_t len = isfinite(breast_r) ? root_chain(cont, root, chain) : 0;
    double faired_r = len ? sy_skeleton_radius_at_height(s, chain, len, breast_z, span) : NAN;
    if (breast_r > 0 && faired_r > 0) {
        double reach = sigma_factor * breast_r, gain = breast_r / faired_r - 1;
        for (size_t k = 0; k < len; k++) {
            double z = s->pos[3 * (size_t)chain[k] + 2], off = fmax(0, fmax(span[0] - z, z - span[1]));
            double w = 1 - off / reach;
            if (w > 0) s->radius[chain[k]] = (float)(s->radius[chain[k]] * (1 + w * gain));
        }
        /* Below breast height the trunk is no thinner than above it (the
         * fairing pulled the butt's nodes down toward the thinner trunk). */
        for (size_t k = len - 1; k-- > 0;)
            if (s->pos[3 * (size_t)chain[k] + 2] < span[0] && s->radius[chain[k]] < s->radius[chain[k + 1]])
                s->radius[chain[k]] = s->radius[chain[k + 1]];
    }
    /* Averaging keeps each chain's taper, but a side branch may now start
     * thicker than the faired node it leaves: no radius grows toward a tip
     * (parents first). */
    for (size_t h = 0; h < m; h++) {
        int32_t v = order[h], p = s->parent[v];
        if (p >= 0 && s->radius[v] > s->radius[p]) s->radius[v] = s->radius[p];
    }
    free(cont), free(order), free(chain), free(first), free(next), free(passes), free(pos), free(rad), free(before);
    return SY_OK;
}

/* Walks from node u along its chain (toward the root with up, else along
 * the continuations in cont) until len of path lies behind; the node
 * reached, or u itself when the chain ends at once. Up, it stops on the
 * fork its branch leaves (past it, it would measure the fork's angle). */
static int32_t walk_chain(const sy_skeleton *s, const int32_t *cont, int32_t u, double len, int up)
{
    for (double d = 0; d < len;) {
        int32_t v = up ? s->parent[u] : cont[u];
        if (v < 0) break;
        d += sy_skeleton_edge_length(s, (size_t)(up ? u : v));
        int fork = up && s->branch[v] != s->branch[u];
        u = v;
        if (fork) break;
    }
    return u;
}

size_t sy_skeleton_limb_kinks(const sy_skeleton *s, double min_radius, double max_turn_deg, double *worst)
{
    size_t n = s->n, kinks = 0;
    double most = 0, limit = cos(max_turn_deg * M_PI / 180);
    int32_t *cont = n ? malloc(n * sizeof *cont) : NULL;
    if (worst) *worst = 0;
    if (!cont) return 0;
    sy_skeleton_branch_next(s, cont);
    for (size_t i = 1; i < n; i++) {
        if (s->radius[i] < min_radius || cont[i] < 0) continue;
        double len = fmax(4 * s->radius[i], 0.1);
        int32_t a = walk_chain(s, cont, (int32_t)i, len, 1), b = walk_chain(s, cont, (int32_t)i, len, 0);
        double u[3], w[3];
        for (int k = 0; k < 3; k++)
            u[k] = s->pos[3 * i + k] - s->pos[3 * (size_t)a + k], w[k] = s->pos[3 * (size_t)b + k] - s->pos[3 * i + k];
        double nu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]), nw = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
        if (!(nu > 0) || !(nw > 0)) continue;
        double c = (u[0] * w[0] + u[1] * w[1] + u[2] * w[2]) / (nu * nw);
        double turn = acos(c < -1 ? -1 : c > 1 ? 1 : c) * 180 / M_PI;
        if (turn > most) most = turn;
        if (c < limit) kinks++;
    }
    free(cont);
    if (worst) *worst = most;
    return kinks;
}
