/* Leaf cards along the finest branches of a skeleton (leaf_placement.h). */
#include "leaf_placement.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stages/qsm/qsm.h"
#include "stages/core/rng.h"
#include "stages/core/vec3.h"

/* Beyond this the asset is no longer a game asset; the caller lowers the density. */
#define MAX_PLACED_LEAVES 2000000
#define PI 3.14159265358979323846

sy_leaf_placement sy_leaf_placement_from_species(const sy_species_params *sp, uint64_t seed)
{
    sy_leaf_placement p;
    memset(&p, 0, sizeof p);
    double quality = sp->leaf_quality > 0 ? sp->leaf_quality : 1;
    double length = sp->scale;
    int last = sp->levels - 1 < SY_WP_LEVELS - 1 ? sp->levels - 1 : SY_WP_LEVELS - 1;
    for (int l = 0; l <= last; l++)
        if (sp->level[l].length > 0) length *= sp->level[l].length;
    p.per_metre = length > 1e-3 ? fabs(sp->leaves) * quality / length : 0;
    p.size = (float)(sp->leaf_scale / sqrt(quality));
    p.max_reverse_order = 2;
    p.seed = seed;
    return p;
}

void sy_leaf_placement_fit_tree(sy_leaf_placement *p, const sy_species_params *sp, double tree_height)
{
    double k = sy_species_leaf_fit(sp, tree_height, 1); /* a QSM's height is its own */
    p->size = (float)(p->size * k);
    p->per_metre /= k * k;
}

static double unit(uint64_t *state) { return sy_unit53(sy_splitmix64(state)); }

/* Unit quaternion (x, y, z, w) of the rotation whose matrix columns are x, y, z. */
static void quat_from_columns(const double x[3], const double y[3], const double z[3], float q[4])
{
    double m00 = x[0], m10 = x[1], m20 = x[2], m01 = y[0], m11 = y[1], m21 = y[2], m02 = z[0], m12 = z[1],
           m22 = z[2], r[4];
    double tr = m00 + m11 + m22;
    if (tr > 0) {
        double s = sqrt(tr + 1) * 2;
        r[0] = (m21 - m12) / s, r[1] = (m02 - m20) / s, r[2] = (m10 - m01) / s, r[3] = 0.25 * s;
    } else if (m00 > m11 && m00 > m22) {
        double s = sqrt(1 + m00 - m11 - m22) * 2;
        r[0] = 0.25 * s, r[1] = (m01 + m10) / s, r[2] = (m02 + m20) / s, r[3] = (m21 - m12) / s;
    } else if (m11 > m22) {
        double s = sqrt(1 + m11 - m00 - m22) * 2;
        r[0] = (m01 + m10) / s, r[1] = 0.25 * s, r[2] = (m12 + m21) / s, r[3] = (m02 - m20) / s;
    } else {
        double s = sqrt(1 + m22 - m00 - m11) * 2;
        r[0] = (m02 + m20) / s, r[1] = (m12 + m21) / s, r[2] = 0.25 * s, r[3] = (m10 - m01) / s;
    }
    double n = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
    for (int k = 0; k < 4; k++) q[k] = (float)(r[k] / n);
}

/* One leaf at parameter t of edge a -> b (radii ra, rb; unit direction d). */
static sy_code leaf_on_edge(const double a[3], const double b[3], float ra, float rb, const double d[3],
                            double t, uint64_t *rng, float size, int32_t node, sy_leaves *out, sy_error *err)
{
    double e1[3], e2[3];
    sy_v3_basis_across(d, e1, e2);
    double phi = 2 * PI * unit(rng), lean = (30 + 30 * unit(rng)) * PI / 180;
    double radial[3], yaxis[3], zaxis[3], xaxis[3];
    for (int k = 0; k < 3; k++) {
        radial[k] = cos(phi) * e1[k] + sin(phi) * e2[k];
        yaxis[k] = cos(lean) * radial[k] + sin(lean) * d[k];
    }
    sy_v3_normalize(yaxis);
    /* The blade faces the sky as far as its axis allows. */
    sy_v3_card_frame(yaxis, radial, xaxis, zaxis);
    double r = ra + t * (rb - ra);
    float pos[3], q[4];
    for (int k = 0; k < 3; k++) pos[k] = (float)(a[k] + t * (b[k] - a[k]) + r * radial[k]);
    quat_from_columns(xaxis, yaxis, zaxis, q);
    return sy_leaves_add(out, pos, q, size, node, err);
}

sy_code sy_place_leaves(const sy_skeleton *s, const sy_leaf_placement *p, sy_leaves *leaves, double *twig_length,
                        sy_error *err)
{
    memset(leaves, 0, sizeof *leaves);
    if (twig_length) *twig_length = 0;
    if (!(p->per_metre >= 0) || !(p->size > 0) || !isfinite(p->per_metre) || !isfinite(p->size))
        return sy_fail(err, SY_EUSAGE, "leaves: density must be >= 0 and size > 0");
    int32_t *rbo = sy_calloc(s->n ? s->n : 1, sizeof *rbo, err, "leaf placement");
    if (!rbo) return SY_EINTERNAL;
    sy_code rc = sy_skeleton_reverse_order(s, rbo, err);
    double twigs = 0, carry = 0;
    uint64_t rng = p->seed ^ 0x6C656166ull; /* "leaf": apart from other users of the seed */
    for (size_t i = 0; i < s->n && !rc; i++) {
        int32_t par = s->parent[i];
        if (par < 0 || rbo[i] > p->max_reverse_order) continue;
        double a[3], b[3], d[3];
        for (int k = 0; k < 3; k++) {
            a[k] = s->pos[3 * par + k];
            b[k] = s->pos[3 * i + k];
            d[k] = b[k] - a[k];
        }
        double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (!(len > 1e-9)) continue;
        for (int k = 0; k < 3; k++) d[k] /= len;
        twigs += len;
        carry += p->per_metre * len;
        /* Compared as a double first: a long twig times the density may pass
         * any int (the cast would be undefined). */
        if ((double)leaves->n + floor(carry) > MAX_PLACED_LEAVES) {
            rc = sy_fail(err, SY_EINPUT,
                         "leaves: %.4g leaves per metre of twig make more than %d leaves (%.4g m of twigs so far); "
                         "lower the leaf density",
                         p->per_metre, MAX_PLACED_LEAVES, twigs);
            break;
        }
        int count = (int)floor(carry);
        carry -= count;
        for (int j = 0; j < count && !rc; j++) {
            double t = ((double)j + unit(&rng)) / count; /* stratified along the edge */
            rc = leaf_on_edge(a, b, s->radius[par], s->radius[i], d, t, &rng, p->size, (int32_t)i, leaves, err);
        }
    }
    free(rbo);
    if (rc) sy_leaves_free(leaves);
    else if (twig_length) *twig_length = twigs;
    return rc;
}
