/* Leaf cards: one card mesh in the leaf's local frame (stem at the origin,
 * +Y towards the tip, +Z the normal) instanced once per leaf. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_internal.h"

#define SY_PI 3.14159265358979323846f
#define OUTLINE_STEPS 5
/* Outline points of the round shapes 4..9 (docs/mesh.md "Leaves"): enough
 * that the polygons keep within 2.5 % of their curves' areas, few enough that
 * a leaf stays a few dozen triangles. */
#define DISC_POINTS 24
#define CORDATE_POINTS 24
#define PALMATE_LOBES 5
#define PALMATE_POINTS (8 * PALMATE_LOBES) /* lobe tips and sinuses are both samples */
#define PALMATE_DEPTH 0.5f                 /* sinus radius = (1 - depth) x lobe radius */
#define MAX_OUTLINE 64

/* Half-width of the outline at y in [0,1] as a fraction of aspect/2, for the
 * shaped cards; 0 at the stem and at the tip. */
static float outline_width(int shape, float y)
{
    switch (shape) {
    case 1: /* elliptic */
        return sqrtf(fmaxf(0, 1 - (2 * y - 1) * (2 * y - 1)));
    case 2: /* ovate: widest at about a third, pointed tip */
        return sinf(SY_PI * powf(y, 0.7f));
    case 3: /* lanceolate: narrow, long taper. sinf(pi) rounds to a tiny
             * negative number, and a negative base to the power 1.5 is NaN,
             * so the tip is clamped to the 0 it is meant to be. */
        return powf(fmaxf(0, sinf(SY_PI * y)), 1.5f);
    default:
        return 1;
    }
}

static void put(sy_mesh *m, size_t i, float x, float y, float aspect)
{
    m->position[3 * i] = x;
    m->position[3 * i + 1] = y;
    m->position[3 * i + 2] = 0;
    m->normal[3 * i + 2] = 1;
    m->tangent[4 * i] = 1;
    m->tangent[4 * i + 3] = 1; /* cross(+Z, +X) = +Y = direction of +v */
    m->uv[2 * i] = x / aspect + 0.5f;
    m->uv[2 * i + 1] = y;
}

/* The outline of shapes 4..9, counter-clockwise seen from +Z and starting at
 * the stem, inside the card's box |x| <= aspect/2, 0 <= y <= 1. Returns the
 * point count; *centred says whether the fan needs an interior centre
 * (cx, cy) or the outline is convex and fans from its first point. */
static size_t outline_extra(int shape, float aspect, float *pts, int *centred, float *cx, float *cy)
{
    float h = 0.5f * aspect;
    size_t n = 0;
    *centred = 1;
    switch (shape) {
    case 4: { /* disc: round for any aspect, as wide and as long as the card allows */
        float r = 0.5f * fminf(aspect, 1);
        for (int k = 0; k < DISC_POINTS; k++) {
            float a = -0.5f * SY_PI + 2 * SY_PI * (float)k / DISC_POINTS;
            /* The stem and the top exactly on the axis (cosf(pi/2) is not 0). */
            pts[2 * n] = k == 0 || k == DISC_POINTS / 2 ? 0 : r * cosf(a);
            pts[2 * n++ + 1] = r + r * sinf(a);
        }
        *cx = 0, *cy = r;
        break;
    }
    case 5: { /* square: side min(aspect, 1), from the stem */
        float s = fminf(aspect, 1);
        const float q[4][2] = {{-0.5f * s, 0}, {0.5f * s, 0}, {0.5f * s, s}, {-0.5f * s, s}};
        for (int k = 0; k < 4; k++) pts[2 * n] = q[k][0], pts[2 * n++ + 1] = q[k][1];
        *centred = 0;
        break;
    }
    case 6: /* obovate: shape 2 upside down, widest at about two thirds */
        for (int i = 0; i <= OUTLINE_STEPS; i++) {
            float y = (float)i / OUTLINE_STEPS;
            pts[2 * n] = i == 0 || i == OUTLINE_STEPS ? 0 : h * outline_width(2, 1 - y);
            pts[2 * n++ + 1] = y;
        }
        for (int i = OUTLINE_STEPS - 1; i >= 1; i--) {
            float y = (float)i / OUTLINE_STEPS;
            pts[2 * n] = -h * outline_width(2, 1 - y);
            pts[2 * n++ + 1] = y;
        }
        *cx = 0, *cy = 0.55f;
        break;
    case 7: /* deltoid: a triangle, its base across the stem, apex at the tip */
        pts[0] = -h, pts[1] = 0, pts[2] = h, pts[3] = 0, pts[4] = 0, pts[5] = 1;
        n = 3;
        *centred = 0;
        break;
    case 8: { /* cordate: a cardioid, its cusp the notch the petiole enters */
        /* r = a (1 + cos t) at angle t from +Y: tip 2a above the cusp, basal
         * lobes a/4 below it, half-width a 3 sqrt(3)/4; a = 4/9 makes it span
         * y in [0, 1] with the cusp at 1/9, and x is stretched to the card. */
        const float a = 4.0f / 9, sx = h / (a * 0.75f * sqrtf(3));
        for (int k = 0; k < CORDATE_POINTS; k++) {
            float t = SY_PI - 2 * SY_PI * (float)k / CORDATE_POINTS, r = a * (1 + cosf(t));
            pts[2 * n] = sx * r * sinf(t);
            pts[2 * n++ + 1] = fminf(1, fmaxf(0, a / 4 + r * cosf(t)));
        }
        pts[0] = 0; /* the cusp exactly on the axis (sinf(pi) is not 0) */
        *cx = 0, *cy = a / 4 + a;
        break;
    }
    case 9: { /* palmate: five lobes round a centre, the stem in the basal sinus */
        float ymin = 0, ymax = 0, xmax = 0;
        for (int k = 0; k < PALMATE_POINTS; k++) {
            float f = 1.5f * SY_PI + 2 * SY_PI * (float)k / PALMATE_POINTS;
            float rho = 1 - 0.5f * PALMATE_DEPTH * (1 - cosf(PALMATE_LOBES * (f - 0.5f * SY_PI)));
            float x = rho * cosf(f), y = rho * sinf(f);
            if (k == 0) x = 0; /* the stem and the tip exactly on the axis */
            if (k == PALMATE_POINTS / 2) x = 0;
            pts[2 * n] = x;
            pts[2 * n++ + 1] = y;
            ymin = k == 0 || y < ymin ? y : ymin;
            ymax = k == 0 || y > ymax ? y : ymax;
            xmax = fmaxf(xmax, fabsf(x));
        }
        /* Fitted to the card's box: the tip at y = 1, the lowest lobe at 0. */
        for (size_t k = 0; k < n; k++) {
            pts[2 * k] *= h / xmax;
            pts[2 * k + 1] = fminf(1, fmaxf(0, (pts[2 * k + 1] - ymin) / (ymax - ymin)));
        }
        *cx = 0, *cy = -ymin / (ymax - ymin);
        break;
    }
    default:
        break;
    }
    return n;
}

/* The card's arrays for nv vertices and nt triangles; frees it all on failure. */
static int card_alloc(sy_mesh *out, size_t nv, size_t nt, sy_error *err)
{
    out->n_vertices = nv;
    out->n_indices = 3 * nt;
    out->position = sy_calloc(nv, 3 * sizeof(float), err, "leaf card");
    out->normal = sy_calloc(nv, 3 * sizeof(float), err, "leaf card");
    out->tangent = sy_calloc(nv, 4 * sizeof(float), err, "leaf card");
    out->uv = sy_calloc(nv, 2 * sizeof(float), err, "leaf card");
    out->indices = sy_calloc(3 * nt, sizeof(uint32_t), err, "leaf card");
    if (out->position && out->normal && out->tangent && out->uv && out->indices) return 0;
    sy_mesh_free(out);
    return -1;
}

/* Shapes 4..9: a fan over outline_extra's polygon. */
static sy_code extra_card(int shape, float aspect, sy_mesh *out, sy_error *err)
{
    float pts[2 * MAX_OUTLINE], cx = 0, cy = 0;
    int centred;
    size_t n = outline_extra(shape, aspect, pts, &centred, &cx, &cy);
    size_t nv = n + (centred ? 1 : 0), nt = centred ? n : n - 2;
    if (card_alloc(out, nv, nt, err)) return SY_EINTERNAL;
    size_t k = 0;
    if (centred) put(out, k++, cx, cy, aspect);
    for (size_t i = 0; i < n; i++) put(out, k++, pts[2 * i], pts[2 * i + 1], aspect);
    /* x / aspect + 1/2 can round a hair past [0, 1] at the card's edge. */
    for (size_t i = 0; i < nv; i++) out->uv[2 * i] = fminf(1, fmaxf(0, out->uv[2 * i]));
    for (size_t t = 0; t < nt; t++) {
        uint32_t *ix = out->indices + 3 * t;
        if (centred) {
            ix[0] = 0, ix[1] = (uint32_t)(1 + t), ix[2] = (uint32_t)(1 + (t + 1) % n);
        } else {
            ix[0] = 0, ix[1] = (uint32_t)(t + 1), ix[2] = (uint32_t)(t + 2);
        }
    }
    return SY_OK;
}

sy_code sy_leaf_card(int shape, float aspect, int material, sy_mesh *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    snprintf(out->name, sizeof out->name, "leaf_card");
    out->material = material;
    if (shape >= 4 && shape <= 9) return extra_card(shape, aspect, out, err);
    int shaped = shape >= 1 && shape <= 3;
    size_t nv = shaped ? 1 + 2 * OUTLINE_STEPS : 4, nt = shaped ? 2 * OUTLINE_STEPS : 2;
    if (card_alloc(out, nv, nt, err)) return SY_EINTERNAL;
    float h = 0.5f * aspect;
    if (!shaped) {
        put(out, 0, -h, 0, aspect);
        put(out, 1, h, 0, aspect);
        put(out, 2, h, 1, aspect);
        put(out, 3, -h, 1, aspect);
        uint32_t ix[6] = {0, 1, 2, 0, 2, 3};
        memcpy(out->indices, ix, sizeof ix);
        return SY_OK;
    }
    /* Fan from an interior centre over the outline, counter-clockwise seen
     * from +Z: stem (y=0), up the right side, tip (y=1), down the left. */
    put(out, 0, 0, 0.45f, aspect);
    size_t k = 1;
    for (int i = 0; i <= OUTLINE_STEPS; i++) {
        float y = (float)i / OUTLINE_STEPS;
        put(out, k++, h * outline_width(shape, y) * (i == 0 || i == OUTLINE_STEPS ? 0 : 1), y, aspect);
    }
    for (int i = OUTLINE_STEPS - 1; i >= 1; i--) {
        float y = (float)i / OUTLINE_STEPS;
        put(out, k++, -h * outline_width(shape, y), y, aspect);
    }
    for (size_t t = 0; t < nt; t++) {
        out->indices[3 * t] = 0;
        out->indices[3 * t + 1] = (uint32_t)(1 + t);
        out->indices[3 * t + 2] = (uint32_t)(1 + (t + 1) % (nv - 1));
    }
    return SY_OK;
}


/* (x, y, z, w) quaternion product a * b. */
static void quat_mul(const float a[4], const float b[4], float out[4])
{
    out[0] = a[3] * b[0] + a[0] * b[3] + a[1] * b[2] - a[2] * b[1];
    out[1] = a[3] * b[1] - a[0] * b[2] + a[1] * b[3] + a[2] * b[0];
    out[2] = a[3] * b[2] + a[0] * b[1] - a[1] * b[0] + a[2] * b[3];
    out[3] = a[3] * b[3] - a[0] * b[0] - a[1] * b[1] - a[2] * b[2];
}

/* The ring centre of stem s nearest p and its radius: a leaf of a dropped
 * twig comes toward it until it hangs within reach of drawn bark. */
static void nearest_centre(const sy_stem *s, const float p[3], float out[3], float *radius)
{
    float best = INFINITY;
    for (size_t k = 0; k < s->n_samp; k++) {
        const float *c = s->sp + 3 * k;
        float d[3] = {p[0] - c[0], p[1] - c[1], p[2] - c[2]}, dd = sy_dot3(d, d);
        if (dd < best) best = dd, memcpy(out, c, 3 * sizeof(float)), *radius = s->sr[k];
    }
}
/* A moved leaf's petiole stands at most this many leaf lengths plus half
 * the ring radius from the ring centre: within a leaf length of the drawn
 * bark even on a three-sided tube, whose faces stand half a radius in. */
#define LEAF_REACH 0.75f

float sy_card_lowest(const sy_leaves *lv, uint32_t l, float aspect, sy_card_growth g, float z)
{
    const float *q = lv->rot + 4 * l;
    float n = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    if (!(n > 0)) return z;
    float x = q[0] / n, y = q[1] / n, qz = q[2] / n, w = q[3] / n, s = lv->scale[l];
    /* Z row of the rotation matrix: the z of local +X and +Y. */
    float zx = 2 * (x * qz - w * y), zy = 2 * (y * qz + w * x);
    return z + s * (g.along * fminf(0, zy) - 0.5f * aspect * g.across * fabsf(zx));
}

sy_code sy_leaf_instances(const sy_leaves *lv, const sy_stems *st, const uint8_t *keep, float aspect,
                          const uint32_t *list, size_t n, sy_card_growth g, int mesh, sy_instances *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    out->mesh = mesh;
    if (n == 0) return SY_OK;
    out->translation = sy_calloc(n, 3 * sizeof(float), err, "leaves");
    out->rotation = sy_calloc(n, 4 * sizeof(float), err, "leaves");
    out->scale = sy_calloc(n, 3 * sizeof(float), err, "leaves");
    out->wind_branch = sy_calloc(n, sizeof(uint16_t), err, "leaves");
    out->wind_w = sy_calloc(n, 4 * sizeof(float), err, "leaves");
    if (!out->translation || !out->rotation || !out->scale || !out->wind_branch || !out->wind_w) {
        sy_instances_free(out);
        return SY_EINTERNAL;
    }
    out->n = n;
    /* The Z-up -> Y-up change of frame, -90 degrees about X. */
    const float h = 0.70710678118654752f, to_yup[4] = {-h, 0, 0, h};
    for (size_t i = 0; i < n; i++) {
        uint32_t l = list[i];
        float at[3];
        memcpy(at, lv->pos + 3 * l, sizeof at);
        if (keep) {
            int32_t k = st->node_stem[lv->node[l]];
            while (k >= 0 && !(keep[k] && st->s[k].has_geometry)) k = st->s[k].parent;
            if (k >= 0 && k != st->node_stem[lv->node[l]]) {
                float c[3], cr = 0;
                nearest_centre(&st->s[k], lv->pos + 3 * l, c, &cr);
                /* Only as far as it must: a leaf within a leaf length of the
                 * drawn bark stays, the cards depicting the twig; farther ones
                 * come in to that distance. */
                float d[3] = {at[0] - c[0], at[1] - c[1], at[2] - c[2]}, dl = sqrtf(sy_dot3(d, d));
                float reach = 0.5f * cr + LEAF_REACH * lv->scale[l] * g.along;
                if (dl > reach)
                    for (int q = 0; q < 3; q++) at[q] = c[q] + d[q] * (reach / dl);
                /* Moved near the ground, the card may not reach under it. */
                float low = sy_card_lowest(lv, l, aspect, g, at[2]);
                if (low < st->ground) at[2] += st->ground - low;
            }
        }
        sy_to_yup(at, out->translation + 3 * i);
        float q[4];
        memcpy(q, lv->rot + 4 * l, sizeof q);
        float len = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        if (!(len > 1e-12f) || !isfinite(len)) q[0] = q[1] = q[2] = 0, q[3] = len = 1;
        for (int k = 0; k < 4; k++) q[k] /= len;
        float *r = out->rotation + 4 * i;
        quat_mul(to_yup, q, r);
        len = sqrtf(r[0] * r[0] + r[1] * r[1] + r[2] * r[2] + r[3] * r[3]);
        for (int k = 0; k < 4; k++) r[k] /= len;
        float s = lv->scale[l];
        out->scale[3 * i] = s * g.across;
        out->scale[3 * i + 1] = out->scale[3 * i + 2] = s * g.along;
        const sy_stem *stem = &st->s[st->node_stem[lv->node[l]]];
        out->wind_branch[i] = (uint16_t)stem->wind_index;
        memcpy(out->wind_w + 4 * i, stem->wind_w, 4 * sizeof(float));
        if (stem->wind_slot >= 0) {
            float x = stem->length > 0 ? st->node_s[lv->node[l]] / stem->length : 0;
            out->wind_w[4 * i + stem->wind_slot] = x < 0 ? 0 : x > 1 ? 1 : x;
        }
    }
    return SY_OK;
}
