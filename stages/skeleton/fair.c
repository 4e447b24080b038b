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
 * millimetres get one pass or none; tips and the root stay where they are,
 * so the tree keeps its extent. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "skeleton.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* cont[i]: node i's child of its own branch (the lowest index), -1 at a
 * tip. The skeleton's branch ids make each branch one chain. */
static void same_branch_children(const sy_skeleton *s, int32_t *cont)
{
    for (size_t i = 0; i < s->n; i++) cont[i] = -1;
    for (size_t i = s->n; i-- > 1;) {
        int32_t p = s->parent[i];
        if (p >= 0 && s->branch[p] == s->branch[i]) cont[p] = (int32_t)i;
    }
}

sy_code sy_skeleton_fair_limbs(sy_skeleton *s, double sigma_factor, sy_error *err)
{
    size_t n = s->n;
    if (!(sigma_factor > 0) || n < 3) return SY_OK;
    int32_t *cont = malloc(n * sizeof *cont);
    int *passes = calloc(n, sizeof *passes);
    float *next = malloc(n * 3 * sizeof *next), *next_r = malloc(n * sizeof *next_r);
    if (!cont || !passes || !next || !next_r) {
        free(cont), free(passes), free(next), free(next_r);
        return sy_fail(err, SY_EINTERNAL, "skeleton: out of memory");
    }
    /* A node is smoothed along its own chain: its parent and its child of
     * the same branch; side branches follow the node they leave from. */
    same_branch_children(s, cont);
    const int max_passes = 400;
    int most = 0;
    for (size_t i = 1; i < n; i++) {
        if (cont[i] < 0 || s->parent[i] < 0) continue;
        double step = 0.5 * (sy_skeleton_edge_length(s, i) + sy_skeleton_edge_length(s, (size_t)cont[i]));
        if (!(step > 0)) continue;
        double w = sigma_factor * s->radius[i] / step; /* the width in node steps */
        double k = ceil(2 * w * w);
        passes[i] = k > max_passes ? max_passes : (int)k;
        if (passes[i] > most) most = passes[i];
    }
    /* The radii too, within each branch: eq. 3.1 steps the radius down
     * where a limb leaves (AdTree's tree7: 0.110 -> 0.088 m in one 4 cm
     * segment of its trunk, a collar under the fork), where a stem swells
     * and narrows over about its diameter. A branch's first node keeps its
     * own radius (its parent is the thicker limb it leaves). */
    for (int pass = 0; pass < most; pass++) {
        memcpy(next, s->pos, n * 3 * sizeof *next);
        memcpy(next_r, s->radius, n * sizeof *next_r);
        for (size_t i = 1; i < n; i++) {
            if (passes[i] <= pass) continue;
            int32_t p = s->parent[i], c = cont[i];
            const float *a = s->pos + 3 * (size_t)p, *b = s->pos + 3 * (size_t)c;
            for (int q = 0; q < 3; q++) next[3 * i + q] = 0.5f * s->pos[3 * i + q] + 0.25f * (a[q] + b[q]);
            if (s->branch[p] == s->branch[i]) next_r[i] = 0.5f * s->radius[i] + 0.25f * (s->radius[p] + s->radius[c]);
        }
        memcpy(s->pos, next, n * 3 * sizeof *next);
        memcpy(s->radius, next_r, n * sizeof *next_r);
    }
    /* Averaging keeps each chain's taper, but a fork's side branch may now
     * start thicker than the node it leaves: no radius grows toward a tip. */
    for (size_t i = 1; i < n; i++)
        if (s->parent[i] >= 0 && s->radius[i] > s->radius[s->parent[i]]) s->radius[i] = s->radius[s->parent[i]];
    free(cont), free(passes), free(next), free(next_r);
    return SY_OK;
}

/* Walks from node u along its chain (toward the root with up, else along
 * the continuations in cont) until len of path lies behind; the node
 * reached, or u itself when the chain ends at once. */
static int32_t walk_chain(const sy_skeleton *s, const int32_t *cont, int32_t u, double len, int up)
{
    for (double d = 0; d < len;) {
        int32_t v = up ? s->parent[u] : cont[u];
        if (v < 0) break;
        d += sy_skeleton_edge_length(s, (size_t)(up ? u : v));
        u = v;
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
    same_branch_children(s, cont);
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
