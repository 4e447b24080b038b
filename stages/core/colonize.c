/* Space colonisation's shared loop (colonize.h). */
#include "stages/core/colonize.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void sy_colony_free(sy_colony *c)
{
    free(c->pos), free(c->parent), free(c->first), free(c->next);
    memset(c, 0, sizeof *c);
}

sy_code sy_colony_grow(sy_colony *c, const float *seed, size_t n_seed, const float *att, size_t n_att,
                       const sy_colony_options *o, sy_error *err)
{
    memset(c, 0, sizeof *c);
    size_t cap = o->max_nodes < n_seed ? n_seed : o->max_nodes;
    c->pos = malloc((cap ? cap : 1) * 3 * sizeof *c->pos);
    c->parent = malloc((cap ? cap : 1) * sizeof *c->parent);
    c->first = malloc((cap ? cap : 1) * sizeof *c->first);
    c->next = malloc((cap ? cap : 1) * sizeof *c->next);
    double *pull = calloc((cap ? cap : 1) * 4, sizeof *pull);
    int32_t *near = malloc((n_att ? n_att : 1) * sizeof *near);
    double *near_d2 = malloc((n_att ? n_att : 1) * sizeof *near_d2);
    if (!c->pos || !c->parent || !c->first || !c->next || !pull || !near || !near_d2) {
        free(pull), free(near), free(near_d2), sy_colony_free(c);
        return sy_fail(err, SY_EINTERNAL, "colonisation: out of memory");
    }
    c->cap = cap;
    memcpy(c->pos, seed, n_seed * 3 * sizeof *c->pos);
    for (size_t v = 0; v < cap; v++) c->parent[v] = c->first[v] = c->next[v] = -1;
    c->n = n_seed;
    for (size_t a = 0; a < n_att; a++) near[a] = -1, near_d2[a] = INFINITY;
    size_t checked = 0, alive = n_att;
    double kill2 = o->kill * o->kill;
    for (int round = 0; alive && c->n < cap && (o->max_rounds <= 0 || round < o->max_rounds); round++) {
        /* Each live point's nearest node: only the nodes added since the
         * last round can have come closer. */
        for (size_t a = 0; a < n_att; a++) {
            if (near[a] == -2) continue;
            const float *p = att + 3 * a;
            for (size_t v = checked; v < c->n; v++) {
                double dx = c->pos[3 * v] - p[0], dy = c->pos[3 * v + 1] - p[1], dz = c->pos[3 * v + 2] - p[2];
                double d2 = dx * dx + dy * dy + dz * dz;
                if (d2 < near_d2[a]) near_d2[a] = d2, near[a] = (int32_t)v;
            }
            if (near_d2[a] <= kill2) {
                near[a] = -2; /* reached */
                alive--;
            }
        }
        checked = c->n;
        memset(pull, 0, c->n * 4 * sizeof *pull);
        for (size_t a = 0; a < n_att; a++) {
            if (near[a] < 0) continue;
            const float *p = att + 3 * a, *q = c->pos + 3 * (size_t)near[a];
            double d = sqrt(near_d2[a]), *u = pull + 4 * (size_t)near[a];
            for (int k = 0; k < 3; k++) u[k] += (p[k] - q[k]) / d;
            u[3] += 1;
        }
        size_t grown = 0, n0 = c->n;
        for (size_t v = 0; v < n0 && c->n < cap; v++) {
            double *u = pull + 4 * v;
            if (u[3] == 0) continue;
            double len = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
            if (len < o->min_pull * u[3]) continue;
            double dir[3] = {u[0] / len, u[1] / len, u[2] / len};
            if (o->steer && !o->steer(o->ctx, c, v, dir)) continue;
            int same = 0;
            for (int32_t ch = c->first[v]; ch >= 0 && !same; ch = c->next[ch]) {
                double cd[3], cl = 0, dot = 0;
                for (int k = 0; k < 3; k++) {
                    cd[k] = c->pos[3 * (size_t)ch + k] - c->pos[3 * v + k];
                    cl += cd[k] * cd[k];
                }
                cl = sqrt(cl);
                for (int k = 0; k < 3; k++) dot += cd[k] * dir[k];
                same = cl > 0 && dot >= o->same_cos * cl;
            }
            if (same) continue;
            size_t m = c->n++;
            for (int k = 0; k < 3; k++) c->pos[3 * m + k] = (float)(c->pos[3 * v + k] + o->step * dir[k]);
            c->parent[m] = (int32_t)v, c->next[m] = c->first[v], c->first[v] = (int32_t)m;
            grown++;
        }
        if (!grown) break;
    }
    free(pull), free(near), free(near_d2);
    return SY_OK;
}
