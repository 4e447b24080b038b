/* A seeded recursive tree generator for the mesh tests and benchmark: stems
 * of a few slightly bent segments, children leaving interior nodes at 30-70
 * degrees, leaves on the last level. Header-only so the bench can share it. */
#ifndef SYLVA_TREE_GEN_H
#define SYLVA_TREE_GEN_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "stages/core/skeleton.h"

typedef struct {
    uint64_t state;
    int max_depth;
    int children;        /* per stem at depth 0; halves per level, at least 2 */
    int leaves_per_node; /* on the deepest stems */
    int32_t next_branch;
} tree_gen;

static double tg_rand(tree_gen *g)
{
    uint64_t z = (g->state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return (double)((z ^ (z >> 31)) >> 11) / 9007199254740992.0;
}

static void tg_perp(const float d[3], float out[3])
{
    float a[3] = {fabsf(d[0]) < 0.7f ? 1.0f : 0.0f, fabsf(d[0]) < 0.7f ? 0.0f : 1.0f, 0};
    out[0] = d[1] * a[2] - d[2] * a[1];
    out[1] = d[2] * a[0] - d[0] * a[2];
    out[2] = d[0] * a[1] - d[1] * a[0];
    float l = sqrtf(out[0] * out[0] + out[1] * out[1] + out[2] * out[2]);
    for (int k = 0; k < 3; k++) out[k] /= l;
}

/* Grows one stem from node `attach` (or the root when -1) at base along dir. */
static int tg_stem(tree_gen *g, sy_skeleton *s, sy_leaves *lv, int32_t attach, const float base[3],
                   const float dir[3], float length, float radius, int depth)
{
    sy_error err;
    int32_t id = g->next_branch++;
    int nodes = 6;
    float p[3], d[3];
    memcpy(p, base, sizeof p);
    memcpy(d, dir, sizeof d);
    int32_t chain[8];
    int32_t prev = attach;
    for (int i = 0; i < nodes; i++) {
        float t = (float)i / (float)(nodes - 1);
        if (attach >= 0 || i > 0) {
            float step = length / (float)(nodes - (attach >= 0 ? 0 : 1));
            for (int k = 0; k < 3; k++) d[k] += 0.25f * (float)(tg_rand(g) - 0.5);
            if (depth > 0) d[2] += 0.05f; /* a slight upward bend */
            float l = sqrtf(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
            for (int k = 0; k < 3; k++) p[k] += step * d[k] / l;
        }
        float r = radius * (1.0f - 0.8f * t);
        prev = sy_skeleton_add(s, p, r, prev, depth, id, &err);
        if (prev < 0) return -1;
        chain[i] = prev;
    }
    if (depth >= g->max_depth) {
        for (int i = 2; i < nodes; i++)
            for (int k = 0; k < g->leaves_per_node; k++) {
                float lp[3], q[4];
                const float *np = s->pos + 3 * chain[i];
                for (int c = 0; c < 3; c++) lp[c] = np[c] + 0.05f * (float)(tg_rand(g) - 0.5);
                for (int c = 0; c < 4; c++) q[c] = (float)(tg_rand(g) - 0.5);
                if (sy_leaves_add(lv, lp, q, 0.06f + 0.04f * (float)tg_rand(g), chain[i], &err) != SY_OK) return -1;
            }
        return 0;
    }
    int n_child = g->children >> depth;
    if (n_child < 2) n_child = 2;
    for (int c = 0; c < n_child; c++) {
        int at = 1 + (int)(tg_rand(g) * (nodes - 2)); /* interior nodes only */
        if (at > nodes - 2) at = nodes - 2;
        int32_t node = chain[at];
        int32_t nxt = chain[at + 1];
        float axis[3], side[3], cd[3];
        for (int k = 0; k < 3; k++) axis[k] = s->pos[3 * nxt + k] - s->pos[3 * node + k];
        float l = sqrtf(axis[0] * axis[0] + axis[1] * axis[1] + axis[2] * axis[2]);
        for (int k = 0; k < 3; k++) axis[k] /= l;
        tg_perp(axis, side);
        float other[3] = {axis[1] * side[2] - axis[2] * side[1], axis[2] * side[0] - axis[0] * side[2],
                          axis[0] * side[1] - axis[1] * side[0]};
        double az = 2 * 3.14159265 * tg_rand(g), el = (30 + 40 * tg_rand(g)) * 3.14159265 / 180;
        for (int k = 0; k < 3; k++)
            cd[k] = (float)(cos(el) * axis[k] + sin(el) * (cos(az) * side[k] + sin(az) * other[k]));
        float rp = s->radius[node];
        if (tg_stem(g, s, lv, node, s->pos + 3 * node, cd, length * (0.35f + 0.2f * (float)tg_rand(g)),
                    rp * (0.45f + 0.2f * (float)tg_rand(g)), depth + 1) < 0)
            return -1;
    }
    return 0;
}

/* A whole tree: trunk of height h at the origin along +Z. */
static int tg_tree(uint64_t seed, int max_depth, int children, int leaves_per_node, float h, sy_skeleton *s,
                   sy_leaves *lv)
{
    tree_gen g = {seed, max_depth, children, leaves_per_node, 0};
    memset(s, 0, sizeof *s);
    memset(lv, 0, sizeof *lv);
    const float base[3] = {0, 0, 0}, up[3] = {0, 0, 1};
    return tg_stem(&g, s, lv, -1, base, up, h, 0.025f * h, 0);
}

#endif
