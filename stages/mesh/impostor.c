/* Impostor: two crossed cards along the trunk axis, textured with
 * orthographic renders of LOD0 made by a small z-buffered CPU rasteriser:
 * an albedo atlas (bark and leaf colours, the leaf texture's alpha when there
 * is one) and a normal map of the same surfaces in the cards' tangent space,
 * so the engine lights the cards as it lights LOD0. Each atlas is S x S: the
 * view along +Z on the left half, the view along +X on the right half;
 * alpha is coverage. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <stb_image.h>

#include "mesh_internal.h"
#include "stages/core/parallel.h"
#include "stages/core/png.h"
#include "stages/core/texture.h"

/* Share of the tree's extent added around it so the silhouette never touches
 * the card border (mip-mapping would smear it). */
#define MARGIN 0.03f

typedef struct {
    unsigned char *rgba; /* atlas */
    unsigned char *nrm;  /* its tangent-space normal map (RGB), or NULL */
    unsigned char *part; /* per texel: 1 + the shade_src id drawn there, 0 nothing (the coverage); or NULL */
    float *depth;
    int W, H;      /* atlas size */
    int x0, w;     /* this view's tile: columns [x0, x0 + w) */
    float right[3], toward[3]; /* image +x direction and direction to the viewer */
    float u_lo, u_hi, y_lo, y_hi; /* world extent of the tile along right and +Y */
} view;

typedef struct {
    unsigned char *px; /* RGBA texels or NULL */
    int w, h;
    float color[4];
    float emissive[3];
    int id;          /* this source's index among the level's parts (< 255) */
    int double_sided;
    float cutoff;
    int masked;
    int exact;     /* cover only the pixels whose centre the triangle holds */
    int fill_only; /* write only pixels nothing else covers */
} shade_src;

static void to_pixel(const view *v, const float p[3], float out[3])
{
    out[0] = (float)v->x0 + (sy_dot3(p, v->right) - v->u_lo) / (v->u_hi - v->u_lo) * (float)v->w;
    out[1] = (v->y_hi - p[1]) / (v->y_hi - v->y_lo) * (float)v->H;
    out[2] = sy_dot3(p, v->toward);
}

/* Rasterises one triangle's albedo (the material's colour times its
 * texture; uv, 6 floats, looks up the texture's alpha and colour when there
 * is one) and, with v->nrm, its normals (9 floats: the corners' vertex
 * normals, NULL: the face's) in the card's tangent space. No light is baked:
 * the engine lights the card through the normal map as it lights LOD0's
 * surfaces, so the far level keeps LOD0's brightness under any light (the
 * baked Lambert, lit again on the card, drew the aspen's impostor 40 %
 * darker than its LOD0 in three.js). */
static void raster(view *v, const float a[3], const float b[3], const float c[3], const float *uv,
                   const float *normals, const shade_src *src)
{
    float pa[3], pb[3], pc[3];
    to_pixel(v, a, pa), to_pixel(v, b, pb), to_pixel(v, c, pc);
    float area = (pb[0] - pa[0]) * (pc[1] - pa[1]) - (pb[1] - pa[1]) * (pc[0] - pa[0]);
    if (fabsf(area) < 1e-12f) return;
    float lox = fminf(pa[0], fminf(pb[0], pc[0])), hix = fmaxf(pa[0], fmaxf(pb[0], pc[0]));
    float loy = fminf(pa[1], fminf(pb[1], pc[1])), hiy = fmaxf(pa[1], fmaxf(pb[1], pc[1]));
    int xmin = (int)fmaxf((float)v->x0, floorf(lox) - 1), xmax = (int)fminf((float)(v->x0 + v->w - 1), ceilf(hix) + 1);
    int ymin = (int)fmaxf(0, floorf(loy) - 1), ymax = (int)fminf((float)(v->H - 1), ceilf(hiy) + 1);
    /* The weights are stepped along a row from xstep: where a row starts
     * changes their rounding, so rows always start there. */
    int xstep = xmin;
    if (src->exact) {
        /* Only pixels whose centre the triangle holds: a twig's triangle
         * under a pixel wide mostly holds none (a hair of slack for the
         * weights' rounding). */
        xmin = (int)fmaxf((float)xmin, ceilf(lox - 0.5f - 1e-3f)), xmax = (int)fminf((float)xmax, floorf(hix - 0.5f + 1e-3f));
        ymin = (int)fmaxf((float)ymin, ceilf(loy - 0.5f - 1e-3f)), ymax = (int)fminf((float)ymax, floorf(hiy - 0.5f + 1e-3f));
        if (xmin > xmax || ymin > ymax) return;
    }
    float face[3] = {0, 0, 0};
    int back = 0;
    if (src->double_sided || (v->nrm && !normals)) {
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        sy_cross3(e1, e2, face);
        sy_normalize3(face);
        back = src->double_sided && sy_dot3(face, v->toward) < 0;
    }
    /* Conservative coverage: a pixel counts when the triangle touches its
     * square (each edge pushed out by half a pixel in the L1 sense), so
     * twigs thinner than a pixel still show in the silhouette. */
    float aa = fabsf(area), widen = src->exact ? 0.0f : 0.5f;
    float t0 = widen * (fabsf(pb[1] - pc[1]) + fabsf(pc[0] - pb[0])) / aa;
    float t1 = widen * (fabsf(pc[1] - pa[1]) + fabsf(pa[0] - pc[0])) / aa;
    float t2 = widen * (fabsf(pa[1] - pb[1]) + fabsf(pb[0] - pa[0])) / aa;
    /* The barycentric weights are affine in the pixel: w(x, y) = c + gx x +
     * gy y, stepped along a row instead of evaluated with two divisions a
     * pixel (most pixels of a twig's bounding box lie outside it). */
    float inv = 1.0f / area;
    float g0x = (pb[1] - pc[1]) * inv, g0y = (pc[0] - pb[0]) * inv;
    float g1x = (pc[1] - pa[1]) * inv, g1y = (pa[0] - pc[0]) * inv;
    float c0 = (pb[0] * pc[1] - pb[1] * pc[0]) * inv, c1 = (pc[0] * pa[1] - pc[1] * pa[0]) * inv;
    for (int y = ymin; y <= ymax; y++) {
        float py = (float)y + 0.5f, x0 = (float)xstep + 0.5f;
        float r0 = c0 + g0x * x0 + g0y * py, r1 = c1 + g1x * x0 + g1y * py;
        for (int x = xstep; x < xmin; x++) r0 += g0x, r1 += g1x;
        for (int x = xmin; x <= xmax; x++, r0 += g0x, r1 += g1x) {
            float w0 = r0, w1 = r1, w2 = 1 - w0 - w1;
            if (w0 < -t0 || w1 < -t1 || w2 < -t2) continue;
            /* Outside the triangle proper: interpolate at its nearest part. */
            if (w0 < 0 || w1 < 0 || w2 < 0) {
                w0 = fmaxf(w0, 0), w1 = fmaxf(w1, 0), w2 = fmaxf(w2, 0);
                float ws = w0 + w1 + w2;
                w0 /= ws, w1 /= ws, w2 /= ws;
            }
            float z = w0 * pa[2] + w1 * pb[2] + w2 * pc[2];
            size_t i = (size_t)y * (size_t)v->W + (size_t)x;
            if (z <= v->depth[i] || (src->fill_only && v->rgba[4 * i + 3])) continue;
            float col[4] = {src->color[0], src->color[1], src->color[2], 1};
            if (src->px) {
                float tu = w0 * uv[0] + w1 * uv[2] + w2 * uv[4], tv = w0 * uv[1] + w1 * uv[3] + w2 * uv[5];
                int tx = (int)(tu * (float)src->w), ty = (int)(tv * (float)src->h);
                tx = tx < 0 ? 0 : tx >= src->w ? src->w - 1 : tx;
                ty = ty < 0 ? 0 : ty >= src->h ? src->h - 1 : ty;
                const unsigned char *t = src->px + 4 * ((size_t)ty * (size_t)src->w + (size_t)tx);
                for (int k = 0; k < 3; k++) col[k] *= (float)t[k] / 255.0f;
                col[3] = (float)t[3] / 255.0f * src->color[3];
            }
            if (src->masked && col[3] < src->cutoff) continue;
            v->depth[i] = z;
            for (int k = 0; k < 3; k++) {
                float c = col[k];
                v->rgba[4 * i + k] = (unsigned char)(255.0f * (c < 0 ? 0 : c > 1 ? 1 : c) + 0.5f);
            }
            v->rgba[4 * i + 3] = 255;
            if (v->part) v->part[i] = (unsigned char)(src->id + 1);
            if (v->nrm) {
                float n[3];
                for (int k = 0; k < 3; k++)
                    n[k] = normals ? w0 * normals[k] + w1 * normals[3 + k] + w2 * normals[6 + k] : face[k];
                sy_normalize3(n);
                float t = sy_dot3(n, v->toward);
                if (back) {
                    /* A double-sided triangle seen from behind shows its
                     * back: the engine turns its normals round (by the
                     * triangle's facing, not per pixel). */
                    for (int k = 0; k < 3; k++) n[k] = -n[k];
                } else if (t < 0) {
                    /* A smooth normal near an outline leaning away from
                     * the viewer: no more than edge-on. */
                    for (int k = 0; k < 3; k++) n[k] -= t * v->toward[k];
                    sy_normalize3(n);
                }
                /* Tangent space of the card (glTF: bitangent = cross(normal,
                 * tangent) w = +Y, up the image as the normal-map convention
                 * has it): +u the image's right, green up, blue the viewer. */
                float ts[3] = {sy_dot3(n, v->right), n[1], sy_dot3(n, v->toward)};
                for (int k = 0; k < 3; k++)
                    v->nrm[3 * i + k] = (unsigned char)(127.5f * (1.0f + (ts[k] < -1 ? -1 : ts[k] > 1 ? 1 : ts[k])) + 0.5f);
            }
        }
    }
}

/* Colour source for a material: its base colour times its texture (leaf:
 * looked up per pixel; bark: averaged, since bark texels are far below an
 * impostor pixel). */
static void material_source(const sy_asset *a, int mi, int per_pixel, shade_src *s)
{
    memset(s, 0, sizeof *s);
    for (int k = 0; k < 4; k++) s->color[k] = 1;
    if (mi < 0 || (size_t)mi >= a->n_materials) return;
    const sy_material *m = &a->materials[mi];
    memcpy(s->color, m->base_color, sizeof s->color);
    memcpy(s->emissive, m->emissive, sizeof s->emissive);
    s->double_sided = m->double_sided;
    s->masked = m->alpha_mode == SY_ALPHA_MASK;
    s->cutoff = m->alpha_cutoff;
    int img = m->base_color_image;
    if (img < 0 || (size_t)img >= a->n_images || a->images[img].size > INT32_MAX) return;
    int w, h, comp;
    unsigned char *px = stbi_load_from_memory(a->images[img].png, (int)a->images[img].size, &w, &h, &comp, 4);
    if (!px) return; /* an undecodable texture falls back to the plain colour */
    if (per_pixel) {
        s->px = px, s->w = w, s->h = h;
        return;
    }
    double sum[3] = {0, 0, 0}, cnt = 0;
    for (size_t i = 0; i < (size_t)w * (size_t)h; i++) {
        if (px[4 * i + 3] < 128) continue;
        for (int k = 0; k < 3; k++) sum[k] += px[4 * i + k] / 255.0;
        cnt++;
    }
    if (cnt > 0)
        for (int k = 0; k < 3; k++) s->color[k] *= (float)(sum[k] / cnt);
    stbi_image_free(px);
}

static void rotate(const float q[4], const float v[3], float out[3])
{
    /* v + 2 w (u x v) + 2 u x (u x v), u = q.xyz */
    float u[3] = {q[0], q[1], q[2]}, t[3], t2[3];
    sy_cross3(u, v, t);
    for (int k = 0; k < 3; k++) t[k] *= 2;
    sy_cross3(u, t, t2);
    for (int k = 0; k < 3; k++) out[k] = v[k] + q[3] * t[k] + t2[k];
}

static void instance_point(const sy_instances *in, size_t i, const float v[3], float out[3])
{
    const float *s = in->scale + 3 * i, *t = in->translation + 3 * i;
    float sv[3] = {v[0] * s[0], v[1] * s[1], v[2] * s[2]};
    rotate(in->rotation + 4 * i, sv, out);
    for (int k = 0; k < 3; k++) out[k] += t[k];
}

/* A normal of the instanced mesh in the world: rotated, and scaled by the
 * inverse of the instance's scale (a squashed card tilts its normal). */
static void instance_normal(const sy_instances *in, size_t i, const float n[3], float out[3])
{
    const float *s = in->scale + 3 * i;
    float sn[3];
    for (int k = 0; k < 3; k++) sn[k] = s[k] != 0 ? n[k] / s[k] : n[k];
    rotate(in->rotation + 4 * i, sn, out);
    sy_normalize3(out);
}

static void grow_box(float lo[3], float hi[3], const float p[3])
{
    for (int k = 0; k < 3; k++) lo[k] = fminf(lo[k], p[k]), hi[k] = fmaxf(hi[k], p[k]);
}

/* Draws everything of lod into view v. */
static void render_view(const sy_asset *a, const sy_lod *lod, view *v, const shade_src *src_mesh, int meshes_only)
{
    for (int k = 0; k < lod->n_meshes; k++) {
        const sy_mesh *m = &a->meshes[lod->meshes[k]];
        for (size_t t = 0; t + 2 < m->n_indices; t += 3) {
            const uint32_t *ix = m->indices + t;
            float uv[6] = {0, 0, 0, 0, 0, 0}, nv[9];
            for (int c = 0; c < 3 && m->normal; c++) memcpy(nv + 3 * c, m->normal + 3 * ix[c], 3 * sizeof *nv);
            raster(v, m->position + 3 * ix[0], m->position + 3 * ix[1], m->position + 3 * ix[2], uv,
                   m->normal ? nv : NULL, &src_mesh[k]);
        }
    }
    for (int k = 0; k < lod->n_instances && !meshes_only; k++) {
        const sy_instances *in = &lod->instances[k];
        const sy_mesh *m = &a->meshes[in->mesh];
        const shade_src *src = &src_mesh[SY_LOD_MAX_PARTS + k];
        for (size_t i = 0; i < in->n; i++) {
            for (size_t t = 0; t + 2 < m->n_indices; t += 3) {
                float p[3][3], uv[6] = {0, 0, 0, 0, 0, 0}, nv[9];
                for (int c = 0; c < 3; c++) {
                    uint32_t vi = m->indices[t + (size_t)c];
                    instance_point(in, i, m->position + 3 * vi, p[c]);
                    if (m->uv) uv[2 * c] = m->uv[2 * vi], uv[2 * c + 1] = m->uv[2 * vi + 1];
                    if (m->normal && v->nrm) instance_normal(in, i, m->normal + 3 * vi, nv + 3 * c);
                }
                raster(v, p[0], p[1], p[2], uv, m->normal && v->nrm ? nv : NULL, src);
            }
        }
    }
}

typedef struct {
    const sy_asset *a;
    const sy_lod *lod;
    view *views[2];
    const shade_src *src, *fill; /* fill: the bark again, after everything, where nothing is drawn */
} view_job;

static void render_chunk(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    view_job *j = ctx;
    for (size_t k = begin; k < end; k++) {
        render_view(j->a, j->lod, j->views[k], j->src, 0);
        if (j->fill) render_view(j->a, j->lod, j->views[k], j->fill, 1);
    }
}

/* Rows of the cards: they bend with the trunk between them. */
#define CARD_ROWS 8

/* Two cards of CARD_ROWS strips: one facing +Z (atlas u in [0, 0.5]), one
 * facing +X (u in [0.5, 1], image right = -Z), rows at heights lo[1] ..
 * hi[1]. Row r of the first lies at depth z = zc + off[r][1], of the second
 * at x = xc + off[r][0], so the two cross on the trunk's axis (trunk_path). */
static sy_code card_mesh(const float lo[3], const float hi[3], float xc, float zc, const float off[CARD_ROWS + 1][2],
                         int material, sy_mesh *m, sy_error *err)
{
    memset(m, 0, sizeof *m);
    snprintf(m->name, sizeof m->name, "impostor");
    m->material = material;
    const size_t nv = 4 * (CARD_ROWS + 1), ni = 12 * CARD_ROWS;
    m->n_vertices = nv;
    m->n_indices = ni;
    m->position = sy_calloc(nv, 3 * sizeof(float), err, "impostor");
    m->normal = sy_calloc(nv, 3 * sizeof(float), err, "impostor");
    m->tangent = sy_calloc(nv, 4 * sizeof(float), err, "impostor");
    m->uv = sy_calloc(nv, 2 * sizeof(float), err, "impostor");
    m->indices = sy_calloc(ni, sizeof(uint32_t), err, "impostor");
    if (!m->position || !m->normal || !m->tangent || !m->uv || !m->indices) {
        sy_mesh_free(m);
        return SY_EINTERNAL;
    }
    const float dy = (hi[1] - lo[1]) / CARD_ROWS;
    for (int side = 0; side < 2; side++)
        for (int r = 0; r <= CARD_ROWS; r++) {
            /* The card's slope across this row (central where it can), for its normal. */
            int r0 = r > 0 ? r - 1 : r, r1 = r < CARD_ROWS ? r + 1 : r;
            float slope = dy > 0 ? (off[r1][side ? 0 : 1] - off[r0][side ? 0 : 1]) / ((float)(r1 - r0) * dy) : 0;
            float y = r == CARD_ROWS ? hi[1] : lo[1] + (float)r * dy, v = 1 - (float)r / CARD_ROWS;
            for (int e = 0; e < 2; e++) {
                size_t i = (size_t)(2 * (CARD_ROWS + 1) * side + 2 * r + e);
                float *p = m->position + 3 * i, *n = m->normal + 3 * i, *t = m->tangent + 4 * i, *uv = m->uv + 2 * i;
                float nl = 1 / sqrtf(1 + slope * slope);
                p[1] = y;
                if (side) {
                    p[0] = xc + off[r][0], p[2] = e ? lo[2] : hi[2];
                    n[0] = nl, n[1] = -slope * nl;
                    t[2] = -1;
                } else {
                    p[0] = e ? hi[0] : lo[0], p[2] = zc + off[r][1];
                    n[2] = nl, n[1] = -slope * nl;
                    t[0] = 1;
                }
                /* +u is +X on the first card and -Z on the second; cross(normal,
                 * tangent) is up the image on both: w = +1, the bitangent the
                 * normal map's green (glTF's convention, so an engine that
                 * derives its own tangents reads the map the same way). */
                t[3] = 1;
                uv[0] = 0.5f * (float)side + 0.5f * (float)e, uv[1] = v;
            }
        }
    uint32_t *ix = m->indices;
    for (uint32_t side = 0; side < 2; side++)
        for (uint32_t r = 0; r < CARD_ROWS; r++) {
            uint32_t a = 2 * (CARD_ROWS + 1) * side + 2 * r; /* a, a + 1 this row; a + 2, a + 3 the next */
            const uint32_t q[6] = {a, a + 1, a + 3, a, a + 3, a + 2};
            memcpy(ix, q, sizeof q);
            ix += 6;
        }
    return SY_OK;
}

/* The box around a level's meshes and every instance of its instanced
 * meshes (empty: lo > hi). */
static void lod_bounds(const sy_asset *a, const sy_lod *l, float lo[3], float hi[3])
{
    for (int k = 0; k < 3; k++) lo[k] = INFINITY, hi[k] = -INFINITY;
    for (int k = 0; k < l->n_meshes; k++) {
        const sy_mesh *m = &a->meshes[l->meshes[k]];
        for (size_t i = 0; i < m->n_vertices; i++) grow_box(lo, hi, m->position + 3 * i);
    }
    for (int k = 0; k < l->n_instances; k++) {
        const sy_instances *in = &l->instances[k];
        const sy_mesh *m = &a->meshes[in->mesh];
        for (size_t i = 0; i < in->n; i++)
            for (size_t j = 0; j < m->n_vertices; j++) {
                float p[3];
                instance_point(in, i, m->position + 3 * j, p);
                grow_box(lo, hi, p);
            }
    }
}

/* Where trunk wind branch t runs at each card row (card_mesh), less its
 * root anchor: the least-squares line x(y), z(y) through its LOD0 bark
 * vertices within a row of the row's height (its rings' centres lie on the
 * axis; the line reads a bowed trunk at the row, not at its vertices' mean
 * height), up to its lowest child's anchor or 30 % of the way to the top,
 * whichever is higher; rows above hold the last offset (the leader's
 * meanders in the crown do not bend the cards), rows without trunk
 * vertices take the row below's, and rows below the root none. Upright
 * cards through the root showed a leaning or bowed trunk twice from
 * between them (the front card draws it at the root's depth, the side card
 * at the root's x): PyTLidar's tree_1, its trunk 0.3 m off the vertical at
 * its crown, stood on two trunks from 30 degrees. The trunk's chord (its
 * wind axis) runs on through the crown, 18 m of meandering leader on that
 * 12.7 m tree, and leaned cards along it the wrong way. */
static void trunk_path(const sy_asset *a, const sy_lod *lod0, size_t t, const float lo[3], const float hi[3],
                       float off[CARD_ROWS + 1][2])
{
    const float *root = a->wind[t].anchor, dy = (hi[1] - lo[1]) / CARD_ROWS;
    float first_child = INFINITY;
    for (size_t i = 0; i < a->n_wind; i++)
        if (a->wind[i].parent == (int32_t)t) first_child = fminf(first_child, a->wind[i].anchor[1]);
    float cap = fmaxf(isfinite(first_child) ? first_child : hi[1], root[1] + 0.3f * (hi[1] - root[1]));
    /* Per row: count, sums of y, y^2, x, xy, z, zy, with y from the row's height. */
    double S[CARD_ROWS + 1][7];
    memset(S, 0, sizeof S);
    for (int k = 0; k < lod0->n_meshes && dy > 0; k++) {
        /* The level's meshes with wind branches are its bark tubes (leaves are instances). */
        const sy_mesh *m = &a->meshes[lod0->meshes[k]];
        if (!m->wind_branch) continue;
        for (size_t v = 0; v < m->n_vertices; v++) {
            const float *p = m->position + 3 * v;
            if (m->wind_branch[v] != t || p[1] > cap) continue;
            float f = (p[1] - lo[1]) / dy;
            for (int r = (int)floorf(f); r <= (int)ceilf(f); r++) {
                if (r < 0 || r > CARD_ROWS) continue;
                double y = p[1] - (lo[1] + (float)r * dy), x = p[0] - root[0], z = p[2] - root[2];
                double *q = S[r];
                q[0]++, q[1] += y, q[2] += y * y, q[3] += x, q[4] += x * y, q[5] += z, q[6] += z * y;
            }
        }
    }
    float last[2] = {0, 0};
    for (int r = 0; r <= CARD_ROWS; r++) {
        const double *q = S[r];
        float y = lo[1] + (float)r * dy;
        if (y > root[1] && y <= cap && q[0] >= 3) {
            double den = q[0] * q[2] - q[1] * q[1];
            if (den > 1e-12 * q[0] * q[0]) { /* the lines' values at the row's height */
                last[0] = (float)((q[3] * q[2] - q[1] * q[4]) / den), last[1] = (float)((q[5] * q[2] - q[1] * q[6]) / den);
            } else
                last[0] = (float)(q[3] / q[0]), last[1] = (float)(q[5] / q[0]);
        }
        off[r][0] = last[0], off[r][1] = last[1];
    }
}

int sy_impostor_build(sy_asset *a, const sy_lod *lod0, int size, sy_error *err)
{
    float lo[3], hi[3];
    lod_bounds(a, lod0, lo, hi);
    if (!(lo[0] <= hi[0])) {
        sy_fail(err, SY_EINPUT, "mesh: nothing to draw (no branch of two distinct points, no leaf)");
        return -1;
    }
    for (int k = 0; k < 3; k++) {
        float pad = MARGIN * fmaxf(hi[k] - lo[k], 1e-3f);
        lo[k] -= pad, hi[k] += pad;
    }
    /* The cards cross on the trunk axis: through the root stem's anchor,
     * bending with the trunk below its crown (trunk_path). */
    float xc = 0.5f * (lo[0] + hi[0]), zc = 0.5f * (lo[2] + hi[2]), off[CARD_ROWS + 1][2];
    memset(off, 0, sizeof off);
    for (size_t i = 0; i < a->n_wind; i++)
        if (a->wind[i].parent < 0) {
            xc = a->wind[i].anchor[0], zc = a->wind[i].anchor[2];
            trunk_path(a, lod0, i, lo, hi, off);
        }

    int W = size, H = size;
    unsigned char *rgba = calloc((size_t)W * (size_t)H, 4), *nrm = malloc((size_t)W * (size_t)H * 3);
    float *depth = malloc((size_t)W * (size_t)H * sizeof(float));
    unsigned char *part = calloc((size_t)W * (size_t)H, 1);
    shade_src src[2 * SY_LOD_MAX_PARTS];
    memset(src, 0, sizeof src);
    if (!rgba || !nrm || !depth || !part) {
        free(rgba), free(nrm), free(depth), free(part);
        sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
        return -1;
    }
    for (size_t i = 0; i < (size_t)W * (size_t)H; i++) {
        depth[i] = -INFINITY;
        nrm[3 * i] = nrm[3 * i + 1] = 128, nrm[3 * i + 2] = 255; /* the card's own normal */
    }
    for (int k = 0; k < lod0->n_meshes; k++) material_source(a, a->meshes[lod0->meshes[k]].material, 0, &src[k]);
    for (int k = 0; k < lod0->n_instances; k++)
        material_source(a, a->meshes[lod0->instances[k].mesh].material, 1, &src[SY_LOD_MAX_PARTS + k]);
    view front = {rgba, nrm, part, depth, W, H, 0, W / 2, {1, 0, 0}, {0, 0, 1}, lo[0], hi[0], lo[1], hi[1]};
    view side = {rgba, nrm, part, depth, W, H, W / 2, W - W / 2, {0, 0, -1}, {1, 0, 0}, -hi[2], -lo[2], lo[1], hi[1]};
    /* The two views fill disjoint halves of the atlas and its depth: one a
     * thread, the same texels either way. */
    /* Colour from the bark at the pixels it holds; twigs thinner than a
     * pixel only where nothing else is drawn. Covering every pixel a twig
     * touches (as the silhouettes do) let the limbs' colour take the crown:
     * the orange-barked pine's impostor came out red-brown. The coverage,
     * and so the silhouette, is the same either way. */
    for (int k = 0; k < 2 * SY_LOD_MAX_PARTS; k++) src[k].id = k;
    shade_src fill[2 * SY_LOD_MAX_PARTS];
    memcpy(fill, src, sizeof fill);
    for (int k = 0; k < lod0->n_meshes; k++) src[k].exact = 1, fill[k].fill_only = 1;
    view_job job = {a, lod0, {&front, &side}, src, fill};
    sy_parallel_for(2, 1, render_chunk, &job);
    for (int k = 0; k < 2 * SY_LOD_MAX_PARTS; k++) stbi_image_free(src[k].px);
    free(depth);
    /* Leaves glow faintly in engines without diffuse transmission (their
     * emissive factor times their colour, species/materials.c): the cards
     * glow by the drawn texels' mean factor, times the atlas's colour. */
    double glow_sum[3] = {0, 0, 0};
    size_t drawn = 0;
    for (size_t i = 0; i < (size_t)W * (size_t)H; i++)
        if (part[i]) {
            for (int k = 0; k < 3; k++) glow_sum[k] += src[part[i] - 1].emissive[k];
            drawn++;
        }
    /* The clear texels (part 0) take the tree's colours and normals
     * (push-pull), so filtering and mip levels at the silhouette blend
     * towards the crown, not towards black (a 4-texel dilation left the rest
     * black, and the far mip levels dark). */
    int oom = sy_texture_bleed_u8(rgba, W, H, 4, 3, part, err) || sy_texture_bleed_u8(nrm, W, H, 3, 3, part, err);
    free(part);
    if (oom) {
        free(rgba), free(nrm);
        sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
        return -1;
    }
    sy_image img, nimg;
    memset(&img, 0, sizeof img);
    memset(&nimg, 0, sizeof nimg);
    int bad = sy_png_encode(rgba, W, H, 4, 8, &img.png, &img.size);
    bad |= sy_png_encode(nrm, W, H, 3, 8, &nimg.png, &nimg.size);
    free(rgba), free(nrm);
    if (bad) {
        free(img.png), free(nimg.png);
        sy_fail(err, SY_EINTERNAL, "mesh: impostor PNG encoding failed");
        return -1;
    }
    snprintf(img.name, sizeof img.name, "impostor");
    snprintf(nimg.name, sizeof nimg.name, "impostor_normal");
    int ii = sy_asset_add_image(a, &img, err);
    if (ii < 0) {
        free(img.png), free(nimg.png);
        return -1;
    }
    int ni = sy_asset_add_image(a, &nimg, err);
    if (ni < 0) {
        free(nimg.png);
        return -1;
    }
    sy_material mat = sy_material_default("impostor");
    mat.base_color_image = ii;
    mat.normal_image = ni;
    for (int k = 0; k < 3 && drawn; k++) mat.emissive[k] = (float)(glow_sum[k] / (double)drawn);
    mat.alpha_mode = SY_ALPHA_MASK;
    mat.alpha_cutoff = 0.5f;
    mat.double_sided = 1;
    mat.roughness = 0.9f;
    int mi = sy_asset_add_material(a, &mat, err);
    if (mi < 0) return -1;
    sy_mesh m;
    if (card_mesh(lo, hi, xc, zc, off, mi, &m, err) != SY_OK) return -1;
    int idx = sy_asset_add_mesh(a, &m, err);
    if (idx < 0) sy_mesh_free(&m);
    return idx;
}

void sy_mesh_lod_bounds(const sy_asset *a, size_t lod, float lo[3], float hi[3])
{
    lod_bounds(a, &a->lods[lod], lo, hi);
}

sy_code sy_mesh_silhouettes(const sy_asset *a, size_t lod, const float lo[3], const float hi[3], int size,
                            uint8_t *front, uint8_t *side, sy_error *err)
{
    if (lod >= a->n_lods || size < 1) return sy_fail(err, SY_EINTERNAL, "mesh: silhouette of a missing level %zu", lod);
    int W = 2 * size, H = size;
    unsigned char *rgba = calloc((size_t)W * (size_t)H, 4);
    float *depth = malloc((size_t)W * (size_t)H * sizeof(float));
    if (!rgba || !depth) {
        free(rgba), free(depth);
        return sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
    }
    for (size_t i = 0; i < (size_t)W * (size_t)H; i++) depth[i] = -INFINITY;
    const sy_lod *l = &a->lods[lod];
    shade_src src[2 * SY_LOD_MAX_PARTS];
    memset(src, 0, sizeof src);
    for (int k = 0; k < l->n_meshes; k++) material_source(a, a->meshes[l->meshes[k]].material, 0, &src[k]);
    for (int k = 0; k < l->n_instances; k++)
        material_source(a, a->meshes[l->instances[k].mesh].material, 1, &src[SY_LOD_MAX_PARTS + k]);
    view f = {rgba, NULL, NULL, depth, W, H, 0, size, {1, 0, 0}, {0, 0, 1}, lo[0], hi[0], lo[1], hi[1]};
    view s = {rgba, NULL, NULL, depth, W, H, size, size, {0, 0, -1}, {1, 0, 0}, -hi[2], -lo[2], lo[1], hi[1]};
    render_view(a, l, &f, src, 0);
    render_view(a, l, &s, src, 0);
    for (int k = 0; k < 2 * SY_LOD_MAX_PARTS; k++) stbi_image_free(src[k].px);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < size; x++) {
            front[(size_t)y * (size_t)size + (size_t)x] = rgba[4 * ((size_t)y * (size_t)W + (size_t)x) + 3] > 0;
            side[(size_t)y * (size_t)size + (size_t)x] = rgba[4 * ((size_t)y * (size_t)W + (size_t)(x + size)) + 3] > 0;
        }
    free(rgba), free(depth);
    return SY_OK;
}
