/* Per-branch wind data (Habel 2009 ch. 4, docs/wind.md): the tapered-beam
 * polynomial, natural frequency and stiffness of every stem, and the per-vertex
 * hierarchy vector w each stem's vertices carry. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_internal.h"

#define WIND_LEVELS 4
#define SY_PI_D 3.14159265358979323846
/* Below this |alpha - 1| the closed form (4.7) cancels catastrophically; the
 * uniform cantilever is the limit it tends to. */
#define UNIFORM_BAND 0.01

double sy_beam_deflection(double alpha, double x)
{
    if (fabs(alpha - 1) < UNIFORM_BAND) return x * x * (6 - 4 * x + x * x) / (6 * SY_PI_D);
    double a = alpha, t = x * (a - 1), q = 1 + t;
    double num = t * (6 + t * (2 * t * (3 + (a - 3) * a) + 3 * (4 + (a - 2) * a))) - 6 * q * q * log1p(t);
    return num / (3 * SY_PI_D * q * q * pow(a - 1, 4));
}

void sy_beam_fit(double alpha, float *c2, float *c4)
{
    double s4 = 0, s6 = 0, s8 = 0, b2 = 0, b4 = 0;
    for (int i = 0; i <= 100; i++) {
        double x = i / 100.0, x2 = x * x, x4 = x2 * x2, u = sy_beam_deflection(alpha, x);
        s4 += x4, s6 += x4 * x2, s8 += x4 * x4, b2 += x2 * u, b4 += x4 * u;
    }
    double det = s4 * s8 - s6 * s6;
    *c2 = (float)((b2 * s8 - b4 * s6) / det);
    *c4 = (float)((s4 * b4 - s6 * b2) / det);
}

/* Bending stiffness of a cantilever, k ~ E r^4 / L^3, spans many decades
 * between trunk and twig, so it is normalised on a log scale. */
static double raw_stiffness(const sy_stem *s)
{
    double L = s->length > 0.01f ? s->length : 0.01, r = s->r_base;
    return log(r * r * r * r / (L * L * L));
}

sy_code sy_wind_build(sy_stems *st, sy_asset *asset, sy_error *err)
{
    /* The table holds the stems of levels 0-3 only: deeper stems ride
     * rigidly on their level-3 ancestor, so no vertex names them. A
     * synthesised crown has tens of thousands of such twigs (a 300k-point
     * black oak: 81,323 stems), which would overflow the 16-bit index for
     * nothing. slot[i]: stem i's table entry, or -1. */
    int32_t *slot = sy_calloc(st->n ? st->n : 1, sizeof *slot, err, "mesh wind");
    if (!slot) return SY_EINTERNAL;
    size_t n_table = 0;
    for (size_t i = 0; i < st->n; i++) slot[i] = st->s[i].depth < WIND_LEVELS ? (int32_t)n_table++ : -1;
    if (n_table > 65535) {
        free(slot);
        return sy_fail(err, SY_EINPUT, "mesh: %zu branches of levels 0-3 exceed the 16-bit wind branch index",
                       n_table);
    }
    sy_wind_branch *w = sy_calloc(n_table ? n_table : 1, sizeof *w, err, "mesh wind");
    if (!w) {
        free(slot);
        return SY_EINTERNAL;
    }
    /* Stiffness is relative to the whole tree, its rigid twigs included. */
    double kmin = INFINITY, kmax = -INFINITY;
    for (size_t i = 0; i < st->n; i++) {
        double k = raw_stiffness(&st->s[i]);
        kmin = fmin(kmin, k), kmax = fmax(kmax, k);
    }
    for (size_t i = 0; i < st->n; i++) {
        sy_stem *s = &st->s[i];
        sy_wind_branch *b = slot[i] >= 0 ? &w[slot[i]] : NULL;
        if (b) {
            /* Ancestors have lower levels: their entries exist. */
            int32_t tp = sy_stem_tree_parent(s);
            b->parent = tp >= 0 ? slot[tp] : -1;
            b->level = s->depth < WIND_LEVELS - 1 ? s->depth : WIND_LEVELS - 1;
            const float *base = s->pts, *tip = s->pts + 3 * (s->n_pts - 1);
            float axis[3] = {tip[0] - base[0], tip[1] - base[1], tip[2] - base[2]};
            if (sy_normalize3(axis) == 0) axis[0] = 0, axis[1] = 0, axis[2] = 1;
            sy_to_yup(base, b->anchor);
            sy_to_yup(axis, b->axis);
            b->length = s->length;
            double alpha = s->r_base > 0 ? s->r_tip / s->r_base : 1;
            /* A tip thicker than its base is reconstruction noise; (4.7) needs
             * alpha > 0. */
            alpha = alpha < 0.02 ? 0.02 : alpha > 1 ? 1 : alpha;
            sy_beam_fit(alpha, &b->c2, &b->c4);
            b->frequency = (float)(2.55 * pow(s->length > 0.01f ? s->length : 0.01, -0.59));
            b->stiffness = kmax > kmin ? (float)((raw_stiffness(s) - kmin) / (kmax - kmin)) : 1.0f;
        }
        /* w: for each ancestor level l, where the path to this stem leaves
         * it. Stems deeper than level 3 ride rigidly on their level-3
         * ancestor at the point where their sub-hierarchy attaches. */
        int32_t path[WIND_LEVELS + 1];
        int depth = s->depth;
        int32_t v = (int32_t)i;
        while (st->s[v].depth > WIND_LEVELS) v = sy_stem_tree_parent(&st->s[v]);
        for (int32_t u = v; u >= 0; u = sy_stem_tree_parent(&st->s[u])) path[st->s[u].depth] = u;
        memset(s->wind_w, 0, sizeof s->wind_w);
        int top = depth < WIND_LEVELS ? depth : WIND_LEVELS;
        for (int l = 0; l < top; l++) {
            const sy_stem *anc = &st->s[path[l]];
            float x = anc->length > 0 ? sy_stem_tree_attach_s(&st->s[path[l + 1]]) / anc->length : 0;
            /* Kept above 0: a shader that stops at the first zero (as in the
             * thesis) must still reach the deeper levels. */
            s->wind_w[l] = x < 1e-6f ? 1e-6f : x > 1 ? 1 : x;
        }
        if (depth < WIND_LEVELS) {
            s->wind_index = slot[i];
            s->wind_slot = depth;
        } else {
            s->wind_index = slot[path[WIND_LEVELS - 1]];
            s->wind_slot = -1;
        }
    }
    free(slot);
    free(asset->wind);
    asset->wind = w;
    asset->n_wind = n_table;
    return SY_OK;
}
