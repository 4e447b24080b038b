/* Stems -> triangles: rings of P+1 vertices (seam duplicated for UVs), a
 * hemisphere or cone at the tip, a flat disc at a free base, and at a
 * junction a base ring pushed along the child's axis onto the parent's
 * polygonal surface. Vertices are written in glTF's Y-up frame. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_internal.h"

#define SY_PI 3.14159265358979323846f

/* A triangular parent's faces lie at half its radius from the axis, too
 * close for a child's base ring to land on; six sides keep them at 87%. */
#define PARENT_MIN_RADIAL 6
/* A lean parent (a traced twig with twigs of its own) keeps four sides, its
 * faces at 71 %: on three, a strip triangle joining two corners of a row
 * stands in the ring's plane across the prism (a fin, which the weld
 * refuses), and rTwig's sapling capped 105 of its 601 junctions. Five or
 * six sides cost the willows half their twigs under the LOD0 budget
 * (docs/mesh.md, "Stop 39"). */
#define LEAN_PARENT_MIN_RADIAL 4

int sy_stem_radial(const sy_stem *s, const sy_lod_params *lp)
{
    int p = s->radial >> lp->level, lo = !s->has_children ? 3 : sy_stem_lean(s) ? LEAN_PARENT_MIN_RADIAL : PARENT_MIN_RADIAL;
    if (s->lean == 2) p = 3;
    return p < lo ? lo : p;
}

/* Twigs end in a cone: their hemisphere would cost a ring for a tip a few
 * millimetres across. */
int sy_stem_cap_rings(const sy_stem *s, const sy_lod_params *lp)
{
    return (s->has_children || s->parent < 0) && !sy_stem_lean(s) ? lp->cap_rings : 0;
}

/* A coarser level skips LOD0 rings, but never so many that the tube turns
 * more than this between two of its rings: LOD0 spaces rings by curvature
 * (10 degrees a step), so a plain every-stride-th pick turned 40 degrees a
 * segment at LOD2 and 80 at LOD3, the square "staple" bends of a curved
 * branch. */
#define LOD_MAX_TURN_COS 0.9063078f /* cos 25 degrees */

/* Nor may a skipped LOD0 ring's centre lie farther than this many of its
 * radii from the chord that replaces it. A gently bowed limb turns under
 * LOD_MAX_TURN over a metre: a palm's 1.2 cm rachis was cut by 1.1 m chords
 * 5 cm inside its curve at LOD3, and the mesh check's sails at LOD1-3 of
 * the samples and real scans were 1,856 (82 with the bound), at the same
 * silhouettes (docs/mesh.md, "Levels of detail"). */
#define LOD_MAX_BOW 2.0f

/* Whether the chord from ring a to ring b passes a ring between them
 * farther than LOD_MAX_BOW of that ring's radius. */
static int bows(const sy_stem *s, size_t a, size_t b)
{
    const float *p = s->sp + 3 * a, *q = s->sp + 3 * b;
    float d[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]}, dd = sy_dot3(d, d);
    for (size_t k = a + 1; k < b; k++) {
        const float *c = s->sp + 3 * k;
        float w[3] = {c[0] - p[0], c[1] - p[1], c[2] - p[2]};
        float t = dd > 0 ? sy_dot3(w, d) / dd : 0;
        t = t < 0 ? 0 : t > 1 ? 1 : t;
        float e[3] = {w[0] - t * d[0], w[1] - t * d[1], w[2] - t * d[2]}, lim = LOD_MAX_BOW * s->sr[k];
        if (sy_dot3(e, e) > lim * lim) return 1;
    }
    return 0;
}

/* The rings of s at this level (idx may be NULL to count them): from each
 * ring, the farthest of the next stride LOD0 rings reached with the
 * tangent never turning more than LOD_MAX_TURN from it (an S-bend between
 * two parallel tangents counts) and no ring skipped bowing off the chord,
 * the next ring at least. */
static size_t ring_walk(const sy_stem *s, const sy_lod_params *lp, int32_t *idx)
{
    size_t n = 0, last = s->n_samp - 1, stride = (size_t)lp->stride, i = 0;
    if (idx) idx[n] = 0;
    n++;
    while (i < last) {
        size_t end = i + stride < last ? i + stride : last, j = i + 1;
        while (j < end && sy_dot3(s->st + 3 * i, s->st + 3 * (j + 1)) >= LOD_MAX_TURN_COS && !bows(s, i, j + 1)) j++;
        if (idx) idx[n] = (int32_t)j;
        n++;
        i = j;
    }
    return n;
}

size_t sy_stem_rings(const sy_stem *s, const sy_lod_params *lp, int32_t *idx) { return ring_walk(s, lp, idx); }

/* A free base (the trunk, or a child that cannot reach its parent's
 * surface) is closed by a disc so no open end is visible. */
static int has_base_cap(const sy_stem *s) { return !s->junction; }

void sy_tube_counts(const sy_stems *st, size_t stem, const sy_lod_params *lp, size_t *nv, size_t *ni)
{
    const sy_stem *s = &st->s[stem];
    *nv = *ni = 0;
    if (!s->has_geometry || !lp->keep[stem]) return;
    size_t P = (size_t)sy_stem_radial(s, lp);
    size_t rings = ring_walk(s, lp, NULL);
    size_t cap = (size_t)sy_stem_cap_rings(s, lp);
    size_t tris = (rings - 1 + cap) * P * 2 + P;
    *nv = (rings + cap) * (P + 1) + P;
    if (has_base_cap(s)) {
        *nv += P + 2;
        tris += P;
    }
    *ni = 3 * tris;
}

/* Weber-Penn lobes (digest 1.8): the cross-section radius factor
 * f = 1 + d sin(L theta) of stem s drawn with P ring vertices, and df/dtheta.
 * A ring shows L lobes only when P >= 2L + 1 (Nyquist); a coarser ring would
 * alias them into fewer, mirrored ones, so it keeps the circle of the same
 * area, sqrt(1 + d^2 / 2) (the mean of f^2 over a turn). */
static float lobe(const sy_stem *s, int P, float theta, float *dfdt)
{
    *dfdt = 0;
    if (s->lobes <= 0 || s->lobe_depth <= 0) return 1;
    float d = s->lobe_depth, L = (float)s->lobes;
    if (P < 2 * s->lobes + 1) return sqrtf(1 + 0.5f * d * d);
    *dfdt = d * L * cosf(L * theta);
    return 1 + d * sinf(L * theta);
}

/* Vertex j of stem p's P-gon cross-section of radius R as drawn (lobed on a
 * grown trunk), in the ring's (N, B) coordinates. */
static void section_vertex(const sy_stem *p, int P, float R, int j, float v[2])
{
    float th = 2 * SY_PI * (float)(j % P) / (float)P, df, f = R * lobe(p, P, th, &df);
    v[0] = f * cosf(th);
    v[1] = f * sinf(th);
}

static float cross2(const float a[2], const float b[2]) { return a[0] * b[1] - a[1] * b[0]; }

/* Where the line w + lam d leaves the section for the last time: the largest
 * lam at which it crosses an edge outwards (edges run counter-clockwise, so
 * outwards is cross(d, e) > 0). A lobed section need not be convex; the last
 * exit keeps the whole child outside it. Returns 0 when the line misses. */
static int section_exit(const sy_stem *p, int P, float R, const float w[2], const float d[2], float *lam)
{
    int found = 0;
    float a[2], b[2];
    section_vertex(p, P, R, 0, a);
    for (int j = 0; j < P; j++, a[0] = b[0], a[1] = b[1]) {
        section_vertex(p, P, R, j + 1, b);
        float e[2] = {b[0] - a[0], b[1] - a[1]}, aw[2] = {a[0] - w[0], a[1] - w[1]}, den = cross2(d, e);
        if (!(den > 1e-12f)) continue;
        float mu = cross2(aw, d) / den, l = cross2(aw, e) / den;
        if (mu < -1e-5f || mu > 1 + 1e-5f) continue;
        if (!found || l > *lam) *lam = l;
        found = 1;
    }
    return found;
}

/* Distance from the centre to the section's boundary along unit u (the
 * section is star-shaped about its centre, so there is one crossing). */
static float section_reach(const sy_stem *p, int P, float R, const float u[2])
{
    float a[2], b[2], best = 0;
    section_vertex(p, P, R, 0, a);
    for (int j = 0; j < P; j++, a[0] = b[0], a[1] = b[1]) {
        section_vertex(p, P, R, j + 1, b);
        float e[2] = {b[0] - a[0], b[1] - a[1]}, den = cross2(u, e);
        if (!(den > 1e-12f)) continue;
        float t = cross2(a, e) / den, mu = cross2(a, u) / den;
        if (mu >= -1e-5f && mu <= 1 + 1e-5f && t > best) best = t;
    }
    return best;
}

/* How far along the way to its tube's next ring a base-ring vertex may be
 * pushed onto its parent (sy_tube_emit). */
#define RING_AHEAD 0.9f

/* Moves q along unit d onto the polygonal tube of stem p as drawn at this
 * level (P-gon cross-sections through the rings pidx, lobed on a grown
 * trunk), iterating the local frame so a curved parent is followed. Takes
 * the line's crossing only within [-limit, ahead] along d; otherwise falls
 * back to the radial projection, whose snap onto the polygon may carry the
 * vertex a little farther along d. Returns the signed distance along d. */
static float project_to_parent(const sy_stem *p, const int32_t *pidx, size_t np, int P, const float q[3],
                               const float d[3], float s_est, float limit, float ahead, float out[3])
{
    float lam = 0;
    for (int iter = 0; iter < 4; iter++) {
        float c[3], T[3], N[3], B[3], R;
        sy_stem_frame_at(p, pidx, np, s_est, c, T, N, &R);
        sy_cross3(T, N, B);
        float w[3] = {q[0] - c[0], q[1] - c[1], q[2] - c[2]};
        float w2[2] = {sy_dot3(w, N), sy_dot3(w, B)}, d2[2] = {sy_dot3(d, N), sy_dot3(d, B)}, best = 0;
        if (section_exit(p, P, R, w2, d2, &best) && best >= -limit && best <= ahead) {
            lam = best;
            for (int k = 0; k < 3; k++) out[k] = q[k] + lam * d[k];
        } else {
            /* The line misses the tube (or crosses it out of range): take
             * its closest approach to the parent's axis, within range, then
             * scale that point's cross-section offset onto the polygon, so
             * the vertex still moves mostly along d. */
            float Rc = 0, v[2];
            for (int j = 0; j < P; j++) {
                section_vertex(p, P, R, j, v);
                Rc = fmaxf(Rc, hypotf(v[0], v[1]));
            }
            float dd = d2[0] * d2[0] + d2[1] * d2[1], bb = w2[0] * d2[0] + w2[1] * d2[1];
            float disc = bb * bb - dd * (w2[0] * w2[0] + w2[1] * w2[1] - Rc * Rc);
            float l0 = dd > 1e-12f ? -bb / dd : 0;
            /* Prefer where the line leaves the circumscribed circle: the snap
             * onto the polygon is then at most its sagitta. */
            if (dd > 1e-12f && disc >= 0) l0 = (-bb + sqrtf(disc)) / dd;
            l0 = l0 > ahead ? ahead : l0 < -limit ? -limit : l0;
            for (int k = 0; k < 3; k++) w[k] += l0 * d[k];
            w2[0] += l0 * d2[0], w2[1] += l0 * d2[1];
            float len = hypotf(w2[0], w2[1]), f = 0;
            if (len > 1e-9f) {
                float u[2] = {w2[0] / len, w2[1] / len};
                f = section_reach(p, P, R, u) / len;
            }
            float wt = sy_dot3(w, T);
            if (f == 0) section_vertex(p, P, R, 0, w2), f = 1;
            for (int k = 0; k < 3; k++) out[k] = c[k] + wt * T[k] + f * (w2[0] * N[k] + w2[1] * B[k]);
            float mv[3] = {out[0] - q[0], out[1] - q[1], out[2] - q[2]};
            lam = sy_dot3(mv, d);
        }
        float h[3] = {out[0] - c[0], out[1] - c[1], out[2] - c[2]};
        float ds = sy_dot3(h, T);
        s_est += ds;
        if (fabsf(ds) < 1e-5f) break;
    }
    return lam;
}

typedef struct {
    sy_mesh *m;
    size_t v;
    const sy_stem *s;
} writer;

static void put_vertex(writer *wr, const float pos[3], const float nrm[3], const float tan[3], float u, float v,
                       float x)
{
    sy_mesh *m = wr->m;
    size_t i = wr->v++;
    sy_to_yup(pos, m->position + 3 * i);
    sy_to_yup(nrm, m->normal + 3 * i);
    sy_to_yup(tan, m->tangent + 4 * i);
    m->tangent[4 * i + 3] = 1.0f;
    m->uv[2 * i] = u;
    m->uv[2 * i + 1] = v;
    m->wind_branch[i] = (uint16_t)wr->s->wind_index;
    memcpy(m->wind_w + 4 * i, wr->s->wind_w, 4 * sizeof(float));
    if (wr->s->wind_slot >= 0) m->wind_w[4 * i + wr->s->wind_slot] = x < 0 ? 0 : x > 1 ? 1 : x;
}

void sy_tube_emit(const sy_stems *st, size_t stem, const sy_lod_params *lp, sy_mesh *m, size_t v0, size_t i0,
                  int32_t *idx)
{
    const sy_stem *s = &st->s[stem];
    int P = sy_stem_radial(s, lp);
    size_t nr = sy_stem_rings(s, lp, idx);
    const sy_stem *par = s->junction ? &st->s[s->parent] : NULL;
    int32_t *pidx = idx + s->n_samp;
    size_t npr = par ? sy_stem_rings(par, lp, pidx) : 0;
    int Pp = par ? sy_stem_radial(par, lp) : 0;
    float vscale = 1.0f / (2 * SY_PI * s->r_base), xscale = s->length > 0 ? 1.0f / s->length : 0;
    writer wr = {m, v0, s};
    uint32_t *ix = m->indices + i0;
    float cs[65], sn[65];
    float *cw = P + 1 <= 65 ? cs : malloc((size_t)(P + 1) * sizeof(float));
    float *sw = P + 1 <= 65 ? sn : malloc((size_t)(P + 1) * sizeof(float));
    for (int j = 0; j <= P; j++) {
        float th = 2 * SY_PI * (float)(j % P) / (float)P;
        cw[j] = cosf(th);
        sw[j] = sinf(th);
    }
    /* Tube rings. */
    float first_pos[3] = {0, 0, 0}, first_arc = 0;
    for (size_t r = 0; r < nr; r++) {
        size_t k = (size_t)idx[r];
        const float *c = s->sp + 3 * k, *T = s->st + 3 * k, *N = s->sn + 3 * k;
        float B[3], rad = s->sr[k], slope = s->sdr[k];
        sy_cross3(T, N, B);
        for (int j = 0; j <= P; j++) {
            float radial[3], pos[3], nrm[3], tan[3], arc = s->ss[k];
            /* p = c + r f(theta) e_r: dp/dtheta ~ f' e_r + f e_theta and the
             * normal ~ e_r - (f'/f) e_theta - r' f T (r' = dr/ds). */
            float df, f = lobe(s, P, 2 * SY_PI * (float)(j % P) / (float)P, &df);
            for (int q = 0; q < 3; q++) {
                float et = -sw[j] * N[q] + cw[j] * B[q];
                radial[q] = cw[j] * N[q] + sw[j] * B[q];
                pos[q] = c[q] + rad * f * radial[q];
                nrm[q] = radial[q] - (df / f) * et - slope * f * T[q];
                tan[q] = df * radial[q] + f * et;
            }
            sy_normalize3(nrm);
            if (df != 0) sy_normalize3(tan);
            if (r == 0 && par && j < P) {
                /* Far enough to cross the parent at any angle, never so far
                 * that a child running along its parent drags its base ring
                 * metres down the stem (a sail). */
                float limit = 2 * (s->r_base + st->s[s->parent].r_base), out[3];
                /* Nor past RING_AHEAD of the way to the next ring: a vertex
                 * pushed that far folds the first row back over itself (96
                 * over the grown library, seeds 1 and 2, now 12; the trim keeps the
                 * next ring clear of the push the parent's straight cylinder
                 * predicts, and the drawn parent can take it farther). */
                float ahead = nr > 1 ? RING_AHEAD * (s->ss[idx[1]] - s->ss[idx[0]]) : limit;
                if (ahead > limit) ahead = limit;
                arc += project_to_parent(par, pidx, npr, Pp, pos, T, s->attach_s, limit, ahead, out);
                memcpy(pos, out, sizeof pos);
            }
            if (j == 0) memcpy(first_pos, pos, sizeof pos), first_arc = arc;
            if (j == P) memcpy(pos, first_pos, sizeof pos), arc = first_arc; /* bit-identical seam */
            put_vertex(&wr, pos, nrm, tan, (float)j / (float)P, arc * vscale, arc * xscale);
        }
    }
    /* Tip: cap_rings rings on a hemisphere (flattened to at most half the
     * stem length), then one apex copy per column so each keeps its u. */
    size_t kl = s->n_samp - 1;
    const float *c = s->sp + 3 * kl, *T = s->st + 3 * kl, *N = s->sn + 3 * kl;
    float B[3], rad = s->sr[kl], h = fminf(rad, 0.5f * s->length);
    sy_cross3(T, N, B);
    float arc = s->ss[kl], prev_r = rad, prev_h = 0;
    int cap_rings = sy_stem_cap_rings(s, lp);
    for (int cr = 1; cr <= cap_rings; cr++) {
        float ph = 0.5f * SY_PI * (float)cr / (float)(cap_rings + 1), rr = rad * cosf(ph), hh = h * sinf(ph);
        arc += hypotf(prev_r - rr, hh - prev_h);
        prev_r = rr, prev_h = hh;
        for (int j = 0; j <= P; j++) {
            float pos[3], nrm[3], tan[3], df, f = lobe(s, P, 2 * SY_PI * (float)(j % P) / (float)P, &df);
            for (int q = 0; q < 3; q++) {
                float radial = cw[j] * N[q] + sw[j] * B[q];
                pos[q] = c[q] + hh * T[q] + rr * f * radial;
                nrm[q] = cosf(ph) * radial / rad + sinf(ph) * T[q] / h;
                tan[q] = -sw[j] * N[q] + cw[j] * B[q];
            }
            sy_normalize3(nrm);
            put_vertex(&wr, pos, nrm, tan, (float)j / (float)P, arc * vscale, 1.0f);
        }
    }
    arc += hypotf(prev_r, h - prev_h);
    float apex[3] = {c[0] + h * T[0], c[1] + h * T[1], c[2] + h * T[2]};
    for (int j = 0; j < P; j++) {
        float th = 2 * SY_PI * ((float)j + 0.5f) / (float)P, tan[3];
        for (int q = 0; q < 3; q++) tan[q] = -sinf(th) * N[q] + cosf(th) * B[q];
        put_vertex(&wr, apex, T, tan, ((float)j + 0.5f) / (float)P, arc * vscale, 1.0f);
    }
    /* Quad strips between consecutive rings (tube rings then cap rings),
     * wound counter-clockwise seen from outside: (u, u+1, v+1). */
    size_t total_rings = nr + (size_t)cap_rings, row = (size_t)P + 1;
    for (size_t r = 0; r + 1 < total_rings; r++) {
        uint32_t a0 = (uint32_t)(v0 + r * row), b0 = (uint32_t)(a0 + row);
        for (uint32_t j = 0; j < (uint32_t)P; j++) {
            *ix++ = a0 + j, *ix++ = a0 + j + 1, *ix++ = b0 + j;
            *ix++ = a0 + j + 1, *ix++ = b0 + j + 1, *ix++ = b0 + j;
        }
    }
    uint32_t last = (uint32_t)(v0 + (total_rings - 1) * row), ap = (uint32_t)(v0 + total_rings * row);
    for (uint32_t j = 0; j < (uint32_t)P; j++) *ix++ = last + j, *ix++ = last + j + 1, *ix++ = ap + j;
    if (has_base_cap(s)) {
        /* Disc facing -T; positions copied from ring 0 so the rim welds. */
        const float *c0 = s->sp, *T0 = s->st, *N0 = s->sn;
        float nb[3] = {-T0[0], -T0[1], -T0[2]}, tan[3] = {N0[0], N0[1], N0[2]};
        uint32_t centre = (uint32_t)wr.v;
        put_vertex(&wr, c0, nb, tan, 0.5f, 0.5f, 0.0f);
        for (int j = 0; j <= P; j++) {
            /* Undo the Y-up conversion of ring 0 exactly (only negations). */
            const float *y = m->position + 3 * (v0 + (size_t)j);
            float pos[3] = {y[0], -y[2], y[1]};
            put_vertex(&wr, pos, nb, tan, 0.5f + 0.5f * cw[j], 0.5f - 0.5f * sw[j], 0.0f);
        }
        for (uint32_t j = 0; j < (uint32_t)P; j++) *ix++ = centre, *ix++ = centre + 2 + j, *ix++ = centre + 1 + j;
    }
    if (cw != cs) free(cw);
    if (sw != sn) free(sw);
}

/* ---- welding junctions into their parents ----
 * A child's base ring lies on its parent's drawn surface. Welding cuts the
 * parent quads under it (a rectangle of the parent's ring grid that holds
 * the ring; children whose rectangles overlap share one, grown to hold them
 * all) and fills the hole between the rectangle's boundary and the rings
 * with a strip of triangles: a polygon with holes in the parent's (around,
 * along) parameter plane, ear-clipped and flipped towards Delaunay. Parent,
 * junctions and children are one closed, consistently oriented surface. A
 * group that cannot be welded (a ring that wraps most of the parent, runs
 * off its end, crosses another ring, or a strip that would fold) keeps its
 * parent's quads and closes each ring with a cap inside the parent, so the
 * bark has no open edge either way. */

typedef sy_stem_by_radius weld_job; /* a child to weld into its parent */

#define WELD_MAX_LOOP 1024
#define WELD_MAX_GROUP 64 /* children in one hole */
#define WELD_MAX_BAND_ROWS 64 /* rows of a band whose seam may step between rows */
#define WELD_MAX_BAND_COLS 64 /* ... and the parent's columns there */

/* The hole child c's ring needs in its parent's grid at this level. */
typedef struct {
    int32_t stem;
    long q0, q1; /* quad rows */
    int c0, c1;  /* quad columns, unwrapped about jc */
    int ok;      /* the rectangle lies in the parent's tube and leaves it a band */
} weld_rect;

/* Where point x (glTF frame) sits on parent p's grid at this level: arc
 * length s along the parent, fractional ring row (-1 beyond the tube's
 * rings) and fractional column in [0, P), plus the radius there. */
static void grid_coords(const sy_stem *p, const int32_t *pidx, size_t np, int P, const float xy[3], float s_hint,
                        float *s_out, float *row, float *col, float *R_out)
{
    float x[3] = {xy[0], -xy[2], xy[1]}, c[3], T[3], N[3], R;
    float s_est = sy_stem_closest_on_axis(p, pidx, np, x, s_hint, 4, c, T, N, &R);
    float B[3], w[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]};
    sy_cross3(T, N, B);
    float th = atan2f(sy_dot3(w, B), sy_dot3(w, N));
    if (th < 0) th += 2 * SY_PI;
    *col = th * (float)P / (2 * SY_PI);
    if (*col >= (float)P) *col -= (float)P;
    *row = -1;
    for (size_t r = 0; r + 1 < np; r++) {
        float a = p->ss[pidx[r]], b = p->ss[pidx[r + 1]];
        if (s_est >= a && s_est <= b) {
            *row = (float)r + (b > a ? (s_est - a) / (b - a) : 0);
            break;
        }
    }
    *s_out = s_est;
    *R_out = R;
}

/* Arc length of the parent's grid vertex at position xy (glTF frame) in
 * ring r: the ring's own, but a junction's first ring was pushed along its
 * tangent onto its own parent, each vertex by its own distance, so its
 * vertices sit that far along the stem (the quads above them are drawn from
 * there; measured at the ring's own arc length, a hole's corners there were
 * centimetres off the drawn quads in the plane). */
static float grid_vertex_s(const sy_stem *p, const int32_t *pidx, long r, const float xy[3])
{
    size_t k = (size_t)pidx[r];
    if (r != 0 || !p->junction) return p->ss[k];
    float x[3] = {xy[0], -xy[2], xy[1]}, w[3];
    for (int c = 0; c < 3; c++) w[c] = x[c] - p->sp[3 * k + c];
    return p->ss[k] + sy_dot3(w, p->st + 3 * k);
}

/* Unwraps column c about the reference column ref into (ref - P/2, ref + P/2]. */
static float unwrap_col(float c, float ref, int P)
{
    while (c - ref > 0.5f * (float)P) c -= (float)P;
    while (c - ref <= -0.5f * (float)P) c += (float)P;
    return c;
}

#define WELD_MAX_RING 256
/* A ring vertex a hair inside its rectangle's side leaves a sliver between
 * it and the side, which in space faces any way (a fold). A junction that
 * fails to weld tries once more with its rectangle a column wider on a side
 * its ring comes this near (in columns). Widening every rectangle instead
 * put the aspen over its LOD0 budget and drew sails across long rows. */
#define WELD_SIDE_MARGIN 0.2f

/* The quads the ring covers: rows floor(min) .. floor(max) of its vertices'
 * fractional rows, columns likewise about the ring's mean column. */
static void weld_footprint(const sy_stems *st, size_t c, const sy_lod_params *lp, const sy_mesh *m,
                           const size_t *vo, int32_t *pidx, float margin, weld_rect *w)
{
    const sy_stem *s = &st->s[c], *ps = &st->s[s->parent];
    int P = sy_stem_radial(ps, lp), Pc = sy_stem_radial(s, lp);
    size_t np = sy_stem_rings(ps, lp, pidx);
    const float *ring = m->position + 3 * vo[c];
    float rows[WELD_MAX_RING], cols[WELD_MAX_RING], sx, R;
    int inside = Pc <= WELD_MAX_RING;
    if (Pc > WELD_MAX_RING) Pc = WELD_MAX_RING;
    for (int v = 0; v < Pc; v++) {
        grid_coords(ps, pidx, np, P, ring + 3 * v, s->attach_s, &sx, &rows[v], &cols[v], &R);
        if (rows[v] < 0) inside = 0;
    }
    /* Mean column on the circle. */
    float cx = 0, cy = 0;
    for (int v = 0; v < Pc; v++) {
        float a = 2 * SY_PI * cols[v] / (float)P;
        cx += cosf(a), cy += sinf(a);
    }
    float ref = atan2f(cy, cx);
    if (ref < 0) ref += 2 * SY_PI;
    ref *= (float)P / (2 * SY_PI);
    float rmin = INFINITY, rmax = -INFINITY, cmin = INFINITY, cmax = -INFINITY;
    for (int v = 0; v < Pc; v++) {
        float u = unwrap_col(cols[v], ref, P);
        if (rows[v] >= 0) rmin = fminf(rmin, rows[v]), rmax = fmaxf(rmax, rows[v]);
        cmin = fminf(cmin, u), cmax = fmaxf(cmax, u);
    }
    w->stem = (int32_t)c;
    /* A ring partly off the tube still blocks the quads it stands on. */
    w->q0 = rmin <= rmax ? (long)floorf(rmin) : -1;
    w->q1 = rmin <= rmax ? (long)floorf(rmax) : -2;
    w->c0 = (int)floorf(cmin), w->c1 = (int)floorf(cmax);
    /* margin: a ring vertex nearer than this (in columns) to the
     * rectangle's side makes it take the next column too, while it still
     * leaves a band. */
    if (cmin - floorf(cmin) < margin && w->c1 - w->c0 + 2 <= P - 1) w->c0--;
    if (ceilf(cmax) - cmax < margin && w->c1 - w->c0 + 2 <= P - 1) w->c1++;
    if (w->q1 > (long)np - 2) w->q1 = (long)np - 2;
    w->ok = inside && w->c1 - w->c0 + 1 <= P - 1;
}

/* First triangle of parent quad (r, j) (unwrapped column j about jc). */
static size_t quad_tri(const size_t *io, size_t p, int P, long r, int j, int jc)
{
    return io[p] / 3 + 2 * ((size_t)r * (size_t)P + (size_t)(((j + jc) % P + P) % P));
}

/* ---- a polygon with holes in the parent's (around, along) plane ----
 * The hole cut for a group of junctions is a rectangle of parent quads;
 * the rings of the group's children are holes in it. Each ring is bridged
 * to the outer boundary (nearest vertex that sees it, holes taken from the
 * largest "around" coordinate down, as in Eberly's "Triangulation by Ear
 * Clipping"), then the single polygon is ear-clipped (Meisters 1975). */

typedef struct {
    float u, s;  /* parameter plane, metres */
    uint32_t id; /* mesh vertex */
    int loop;    /* 0: the parent's boundary, k + 1: ring k */
} weld_pt;

static float orient2(const weld_pt *a, const weld_pt *b, const weld_pt *c)
{
    return (b->u - a->u) * (c->s - a->s) - (b->s - a->s) * (c->u - a->u);
}

static int same_pt(const weld_pt *a, const weld_pt *b) { return a->id == b->id || (a->u == b->u && a->s == b->s); }

/* Proper crossing of segments ab and cd (shared end points do not count). */
static int segments_cross(const weld_pt *a, const weld_pt *b, const weld_pt *c, const weld_pt *d)
{
    if (same_pt(a, c) || same_pt(a, d) || same_pt(b, c) || same_pt(b, d)) return 0;
    float d1 = orient2(a, b, c), d2 = orient2(a, b, d), d3 = orient2(c, d, a), d4 = orient2(c, d, b);
    return ((d1 > 0) != (d2 > 0)) && ((d3 > 0) != (d4 > 0)) && d1 != 0 && d2 != 0 && d3 != 0 && d4 != 0;
}

typedef struct {
    weld_pt *v; /* the polygon being built, counter-clockwise */
    size_t n, cap;
} weld_poly;

/* Splices hole h (clockwise, nh points) into poly through the nearest
 * polygon vertex whose bridge crosses no edge of the polygon or of the
 * holes still to come (rest, their sizes in nrest). */
static int bridge_hole(weld_poly *poly, const weld_pt *h, size_t nh, const weld_pt *const *rest, const size_t *nrest,
                       size_t n_rest)
{
    if (poly->n + nh + 2 > poly->cap) return 0;
    size_t m = 0;
    for (size_t i = 1; i < nh; i++)
        if (h[i].u > h[m].u) m = i;
    long best = -1;
    float best_d = INFINITY;
    for (size_t i = 0; i < poly->n; i++) {
        const weld_pt *q = &poly->v[i];
        float d = (q->u - h[m].u) * (q->u - h[m].u) + (q->s - h[m].s) * (q->s - h[m].s);
        if (!(d < best_d)) continue;
        /* The bridge must leave q into the polygon's inside (q may be a
         * copy left by an earlier bridge). */
        const weld_pt *pv = &poly->v[(i + poly->n - 1) % poly->n], *nv = &poly->v[(i + 1) % poly->n];
        int inside = orient2(pv, q, nv) >= 0 ? orient2(pv, q, &h[m]) > 0 && orient2(q, nv, &h[m]) > 0
                                              : orient2(pv, q, &h[m]) > 0 || orient2(q, nv, &h[m]) > 0;
        if (!inside) continue;
        int clear = 1;
        for (size_t e = 0; e < poly->n && clear; e++)
            clear = !segments_cross(&h[m], q, &poly->v[e], &poly->v[(e + 1) % poly->n]);
        for (size_t e = 0; e < nh && clear; e++) clear = !segments_cross(&h[m], q, &h[e], &h[(e + 1) % nh]);
        for (size_t r = 0; r < n_rest && clear; r++)
            for (size_t e = 0; e < nrest[r] && clear; e++)
                clear = !segments_cross(&h[m], q, &rest[r][e], &rest[r][(e + 1) % nrest[r]]);
        if (clear) best = (long)i, best_d = d;
    }
    if (best < 0) return 0;
    /* ... q, h[m], h[m+1], ..., h[m-1], h[m], q, ... */
    size_t at = (size_t)best + 1;
    memmove(poly->v + at + nh + 2, poly->v + at, (poly->n - at) * sizeof *poly->v);
    for (size_t i = 0; i <= nh; i++) poly->v[at + i] = h[(m + i) % nh];
    poly->v[at + nh + 1] = poly->v[best];
    poly->n += nh + 2;
    return 1;
}

static int inside_tri(const weld_pt *p, const weld_pt *a, const weld_pt *b, const weld_pt *c)
{
    if (same_pt(p, a) || same_pt(p, b) || same_pt(p, c)) return 0;
    return orient2(a, b, p) >= 0 && orient2(b, c, p) >= 0 && orient2(c, a, p) >= 0;
}

/* Ear-clips the simple counter-clockwise polygon (its bridges doubled) into
 * tri (3 ids each); returns the triangle count or 0 when it gets stuck. */
static size_t ear_clip(weld_poly *poly, uint32_t *tri)
{
    size_t n = poly->n, t = 0;
    weld_pt *v = poly->v;
    while (n > 3) {
        int clipped = 0;
        for (size_t i = 0; i < n && !clipped; i++) {
            const weld_pt *a = &v[(i + n - 1) % n], *b = &v[i], *c = &v[(i + 1) % n];
            float area = orient2(a, b, c);
            float scale = fmaxf(fabsf(b->u - a->u) + fabsf(b->s - a->s), fabsf(c->u - b->u) + fabsf(c->s - b->s));
            if (!(area > 1e-6f * scale * scale)) continue;
            int empty = 1;
            for (size_t k = 0; k < n && empty; k++)
                if (k != i && k != (i + n - 1) % n && k != (i + 1) % n) empty = !inside_tri(&v[k], a, b, c);
            if (!empty) continue;
            tri[3 * t] = a->id, tri[3 * t + 1] = b->id, tri[3 * t + 2] = c->id, t++;
            memmove(v + i, v + i + 1, (n - i - 1) * sizeof *v);
            n--;
            clipped = 1;
        }
        if (!clipped) return 0;
    }
    /* The last triangle too, or none: dropping it left three open edges. */
    if (!(orient2(&v[0], &v[1], &v[2]) > 0)) return 0;
    tri[3 * t] = v[0].id, tri[3 * t + 1] = v[1].id, tri[3 * t + 2] = v[2].id, t++;
    return t;
}


typedef struct {
    uint32_t a, b;
} id_pair;

static int cmp_id_pair(const void *x, const void *y)
{
    const id_pair *p = x, *q = y;
    if (p->a != q->a) return p->a < q->a ? -1 : 1;
    return (p->b > q->b) - (p->b < q->b);
}

/* Sorts pairs by (a, b). A junction strip's sets are small: insertion
 * sort there (qsort's calls through a pointer cost 3 % of a decode); equal
 * pairs are identical, so any sort gives the same array. */
static void id_pairs_sort(id_pair *s, size_t n)
{
    if (n > 48) {
        qsort(s, n, sizeof *s, cmp_id_pair);
        return;
    }
    for (size_t i = 1; i < n; i++) {
        id_pair x = s[i];
        size_t j = i;
        while (j > 0 && (s[j - 1].a > x.a || (s[j - 1].a == x.a && s[j - 1].b > x.b))) {
            s[j] = s[j - 1];
            j--;
        }
        s[j] = x;
    }
}

/* The first of the sorted pairs s[0..n) not below key. */
static size_t pair_lower_bound(const id_pair *s, size_t n, id_pair key)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (cmp_id_pair(&s[mid], &key) < 0) lo = mid + 1;
        else hi = mid;
    }
    return lo;
}

/* How many of the sorted pairs s[0..n) equal key. */
static size_t pair_count(const id_pair *s, size_t n, id_pair key)
{
    size_t lo = pair_lower_bound(s, n, key), c = 0;
    while (lo + c < n && !cmp_id_pair(&s[lo + c], &key)) c++;
    return c;
}

/* The plane position of vertex id: its first copy in pts[0..n), found
 * through by_id, the pairs (id, index) sorted. */
static const weld_pt *weld_find(const weld_pt *pts, const id_pair *by_id, size_t n, uint32_t id)
{
    size_t lo = pair_lower_bound(by_id, n, (id_pair){id, 0});
    return lo < n && by_id[lo].a == id ? &pts[by_id[lo].b] : NULL;
}

/* Should edge ab of the counter-clockwise triangles (a, b, c) and (b, a, d)
 * flip to cd? When d lies inside the circle through a, b, c and the quad
 * a d b c is convex, so (a, d, c) and (d, b, c) are counter-clockwise. */
static int flips_to_delaunay(const weld_pt *pa, const weld_pt *pb, const weld_pt *pc, const weld_pt *pd)
{
    double ax = pa->u - pd->u, ay = pa->s - pd->s, bx = pb->u - pd->u, by = pb->s - pd->s;
    double cx = pc->u - pd->u, cy = pc->s - pd->s;
    double det = (ax * ax + ay * ay) * (bx * cy - cx * by) - (bx * bx + by * by) * (ax * cy - cx * ay) +
                 (cx * cx + cy * cy) * (ax * by - bx * ay);
    double scale = ax * ax + ay * ay + bx * bx + by * by + cx * cx + cy * cy;
    if (!(det > 1e-9 * scale * scale)) return 0;
    return orient2(pa, pd, pc) > 0 && orient2(pd, pb, pc) > 0;
}

/* The strip's directed edges, hashed: entry k holds a triangle corner
 * (3 f + e, the edge from corner e to corner e + 1). A flip rewrites two
 * triangles and appends their six corners again; stale entries, whose
 * corner no longer holds the edge they were filed under, are skipped. A
 * strip of t triangles then finds an edge's twin in constant time, where
 * scanning the strip made each pass O(t^2) (the 1M black oak's stem with a
 * hundred limbs: most of its meshing time). */
typedef struct {
    uint32_t *head, *next, *corner; /* bucket heads and chains hold entry index + 1; 0 ends */
    size_t mask, n, cap;
} edge_index;

static size_t edge_bucket(const edge_index *ix, uint32_t a, uint32_t b)
{
    return (size_t)(((uint64_t)a * 0x9E3779B97F4A7C15ull ^ (uint64_t)b * 0xC2B2AE3D27D4EB4Full) >> 20) & ix->mask;
}

static int edge_file(edge_index *ix, const uint32_t *tri, uint32_t corner)
{
    if (ix->n == ix->cap) {
        size_t cap = 2 * ix->cap;
        uint32_t *nx = realloc(ix->next, cap * sizeof *nx), *co = nx ? realloc(ix->corner, cap * sizeof *co) : NULL;
        if (nx) ix->next = nx;
        if (!co) return 0;
        ix->corner = co, ix->cap = cap;
    }
    uint32_t f = corner / 3, e = corner % 3;
    size_t b = edge_bucket(ix, tri[3 * f + e], tri[3 * f + (e + 1) % 3]);
    ix->corner[ix->n] = corner, ix->next[ix->n] = ix->head[b], ix->head[b] = (uint32_t)++ix->n;
    return 1;
}

/* The lowest triangle above `after` holding directed edge ab (SIZE_MAX: none). */
static size_t edge_face(const edge_index *ix, const uint32_t *tri, uint32_t a, uint32_t b, size_t after)
{
    size_t best = SIZE_MAX;
    for (uint32_t k = ix->head[edge_bucket(ix, a, b)]; k; k = ix->next[k - 1]) {
        uint32_t f = ix->corner[k - 1] / 3, e = ix->corner[k - 1] % 3;
        if (tri[3 * f + e] == a && tri[3 * f + (e + 1) % 3] == b && (after == SIZE_MAX || f > after) && f < best)
            best = f;
    }
    return best;
}

static void edge_index_free(edge_index *ix) { free(ix->head), free(ix->next), free(ix->corner); }

/* Lawson's flips towards the Delaunay triangulation of the ear-clipped
 * strip in the parameter plane (edges of the outer loop and of the rings
 * occur once and never flip): ear clipping leaves fans of long, thin
 * triangles that fold over a curved or lobed parent. pts[0..n) are the
 * plane positions by vertex id. Returns 0 when out of memory (the strip is
 * then partly flipped, still a valid triangulation). */
static int delaunay_flips(uint32_t *tri, size_t t, const weld_pt *pts, size_t n)
{
    edge_index ix = {0};
    size_t buckets = 16;
    while (buckets < 6 * t) buckets *= 2;
    ix.mask = buckets - 1, ix.cap = 3 * t + 64;
    ix.head = calloc(buckets, sizeof *ix.head), ix.next = malloc(ix.cap * sizeof *ix.next);
    ix.corner = malloc(ix.cap * sizeof *ix.corner);
    id_pair *by_id = malloc((n + 1) * sizeof *by_id);
    int ok = ix.head && ix.next && ix.corner && by_id;
    for (size_t i = 0; ok && i < n; i++) by_id[i] = (id_pair){pts[i].id, (uint32_t)i};
    if (ok) id_pairs_sort(by_id, n);
    for (size_t k = 0; ok && k < 3 * t; k++) ok = edge_file(&ix, tri, (uint32_t)k);
    /* clean[f]: no edge of f flips as things stand. Each pass flips the
     * first flippable edge from the first triangle on, so a pass may skip
     * the clean ones; a flip of (a, b) into (c, d) can only change what
     * triangles touching a, b, c or d can do (their neighbours across the
     * two triangles' edges, and the flips that would recreate (a, b)), so
     * those become unclean. The flips, and so the strip, are the same as
     * rescanning every triangle each pass (quadratic in a band's strip). */
    uint8_t *clean = calloc(t + 1, 1);
    ok = ok && clean;
    for (size_t pass = 0, flipped = 1; ok && flipped && pass < 4 * t + 8; pass++) {
        flipped = 0;
        for (size_t f = 0; f < t && ok; clean[f] = !flipped, f++) {
            if (clean[f]) continue;
            for (int e = 0; e < 3; e++) {
                uint32_t a = tri[3 * f + e], b = tri[3 * f + (e + 1) % 3], c = tri[3 * f + (e + 2) % 3];
                size_t g = edge_face(&ix, tri, b, a, f);
                if (g == SIZE_MAX) continue;
                int k = 0;
                while (tri[3 * g + k] != b || tri[3 * g + (k + 1) % 3] != a) k++;
                uint32_t d = tri[3 * g + (k + 2) % 3];
                const weld_pt *pa = weld_find(pts, by_id, n, a), *pb = weld_find(pts, by_id, n, b),
                              *pc = weld_find(pts, by_id, n, c), *pd = weld_find(pts, by_id, n, d);
                /* Only edges between two loops (the parent's and a ring, or
                 * two rings): a chord between two vertices of one loop could
                 * repeat an edge of the tube or of the neighbouring quads
                 * that the strip cannot see. */
                if (!pa || !pb || !pc || !pd || d == c || pc->loop == pd->loop) continue;
                if (!flips_to_delaunay(pa, pb, pc, pd)) continue;
                /* Never duplicate an edge (c, d) the strip already has. */
                if (edge_face(&ix, tri, c, d, SIZE_MAX) != SIZE_MAX || edge_face(&ix, tri, d, c, SIZE_MAX) != SIZE_MAX)
                    continue;
                tri[3 * f] = a, tri[3 * f + 1] = d, tri[3 * f + 2] = c;
                tri[3 * g] = d, tri[3 * g + 1] = b, tri[3 * g + 2] = c;
                for (int q = 0; q < 3 && ok; q++)
                    ok = edge_file(&ix, tri, (uint32_t)(3 * f) + (uint32_t)q) &&
                         edge_file(&ix, tri, (uint32_t)(3 * g) + (uint32_t)q);
                for (size_t h = 0; h < 3 * t; h++)
                    if (tri[h] == a || tri[h] == b || tri[h] == c || tri[h] == d) clean[h / 3] = 0;
                flipped = 1;
                goto next_pass; /* one flip a pass, from the first triangle again */
            }
        }
    next_pass:;
    }
    edge_index_free(&ix);
    free(by_id), free(clean);
    return ok;
}

/* ---- Steiner points on the parent's ridges ----
 * Ear clipping and the flips triangulate the hole with the polygon's own
 * vertices: the parent's grid corners round the rectangle and the rings.
 * Where a ring is nearly as wide as its parent (a fork-like junction, or a
 * six-sided parent at a coarse level) a triangle can then join points half
 * the parent's girth apart and cut through the parent: the fold the check
 * below refuses, and a capped junction. Points on the parent's ridges (its
 * drawn columns) inside the hole, about one column apart, keep every
 * triangle within about one face of the parent. They are inserted one at a
 * time into the triangulation and the edges round each are legalised by
 * Lawson flips (the incremental Delaunay insertion of Guibas & Stolfi
 * 1985; Ruppert 1995 refines with Steiner points the same way). */

#define WELD_MAX_STEINER 192
/* Steiner vertices' ids: above every mesh vertex id. */
#define WELD_STEINER_ID0 (UINT32_MAX - 2u * WELD_MAX_STEINER)

typedef struct {
    size_t n;
    float pos[3 * WELD_MAX_STEINER]; /* glTF frame */
    float ww[4 * WELD_MAX_STEINER];
    uint16_t wb[WELD_MAX_STEINER];
} weld_steiner;

/* A band's second copy of its seam column (see weld_group) is labelled
 * with this bit: the same mesh vertex at the other end of the band, so the
 * plane's predicates tell the two apart. Steiner ids lie above both. */
#define WELD_SEAM_BIT 0x80000000u

/* The mesh vertex behind a label that is not a Steiner point. */
static uint32_t seam_vertex(uint32_t id) { return id & ~WELD_SEAM_BIT; }

/* Position of strip vertex id: a mesh vertex or a Steiner point. */
static const float *strip_pos(const sy_mesh *m, const weld_steiner *sp, uint32_t id)
{
    if (sp && id >= WELD_STEINER_ID0) return sp->pos + 3 * (size_t)(id - WELD_STEINER_ID0);
    return m->position + 3 * (size_t)seam_vertex(id);
}

/* Is (u, s) inside ring h (nh points) by the crossing rule? */
static int inside_ring(const weld_pt *h, size_t nh, float u, float s)
{
    int in = 0;
    for (size_t i = 0, j = nh - 1; i < nh; j = i++)
        if ((h[i].s > s) != (h[j].s > s) && u < h[j].u + (h[i].u - h[j].u) * (s - h[j].s) / (h[i].s - h[j].s)) in = !in;
    return in;
}

/* Squared distance from (u, s) to segment ab of the plane. */
static float seg_dist2(const weld_pt *a, const weld_pt *b, float u, float s)
{
    float du = b->u - a->u, ds = b->s - a->s, l2 = du * du + ds * ds;
    float t = l2 > 0 ? ((u - a->u) * du + (s - a->s) * ds) / l2 : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    float x = a->u + t * du - u, y = a->s + t * ds - s;
    return x * x + y * y;
}

/* The triangle holding the directed edge (b, a), or -1 (a boundary edge). */
static long edge_twin(const uint32_t *loc, size_t t, uint32_t a, uint32_t b)
{
    for (size_t g = 0; g < t; g++)
        for (int k = 0; k < 3; k++)
            if (loc[3 * g + k] == b && loc[3 * g + (k + 1) % 3] == a) return (long)g;
    return -1;
}

/* Lawson's legalisation of edge (a, b) of triangle f = (a, b, p), p the
 * point just inserted: flips it when the twin's far vertex lies inside the
 * circle through a, b, p, then legalises the two edges that face p anew.
 * loc holds plane indices into pts. */
static void legalise(uint32_t *loc, size_t t, const weld_pt *pts, size_t f, int depth)
{
    if (depth > 64) return;
    uint32_t a = loc[3 * f], b = loc[3 * f + 1], p = loc[3 * f + 2];
    long g = edge_twin(loc, t, a, b);
    if (g < 0) return;
    int k = 0;
    while (!(loc[3 * g + k] == b && loc[3 * g + (k + 1) % 3] == a)) k++;
    uint32_t d = loc[3 * g + (k + 2) % 3];
    const weld_pt *pa = &pts[a], *pb = &pts[b], *pp = &pts[p], *pd = &pts[d];
    if (!flips_to_delaunay(pa, pb, pp, pd)) return;
    /* (a, b, p) + (b, a, d) -> (a, d, p) + (d, b, p). */
    loc[3 * f] = a, loc[3 * f + 1] = d, loc[3 * f + 2] = p;
    loc[3 * g] = d, loc[3 * g + 1] = b, loc[3 * g + 2] = p;
    legalise(loc, t, pts, f, depth + 1);
    legalise(loc, t, pts, (size_t)g, depth + 1);
}

/* Puts triangle f's vertex v last (its edges keep their direction). */
static void rotate_last(uint32_t *loc, size_t f, uint32_t v)
{
    while (loc[3 * f + 2] != v) {
        uint32_t x = loc[3 * f];
        loc[3 * f] = loc[3 * f + 1], loc[3 * f + 1] = loc[3 * f + 2], loc[3 * f + 2] = x;
    }
}

/* Inserts plane point q (index iq into pts) into the triangulation loc (t
 * triangles, room for cap): the triangle holding it is split in three, or
 * the two on an edge it lies on in four; then the edges round it are
 * legalised. Returns the new count (t when q lies on no triangle, on a
 * vertex or on the hole's boundary). */
static size_t insert_point(uint32_t *loc, size_t t, size_t cap, const weld_pt *pts, uint32_t iq)
{
    const weld_pt *q = &pts[iq];
    if (t + 2 > cap) return t;
    for (size_t f = 0; f < t; f++) {
        uint32_t v[3] = {loc[3 * f], loc[3 * f + 1], loc[3 * f + 2]};
        float o[3], sc = 0;
        for (int e = 0; e < 3; e++) {
            const weld_pt *a = &pts[v[e]], *b = &pts[v[(e + 1) % 3]];
            o[e] = orient2(a, b, q);
            sc = fmaxf(sc, fabsf(b->u - a->u) + fabsf(b->s - a->s));
        }
        float eps = 1e-6f * sc * sc;
        if (o[0] < -eps || o[1] < -eps || o[2] < -eps) continue;
        int on = -1, n_on = 0;
        for (int e = 0; e < 3; e++)
            if (o[e] <= eps) on = e, n_on++;
        if (n_on > 1) return t; /* on a vertex */
        if (on < 0) {
            loc[3 * f + 2] = iq;
            uint32_t *x = loc + 3 * t;
            x[0] = v[1], x[1] = v[2], x[2] = iq, x[3] = v[2], x[4] = v[0], x[5] = iq;
            size_t n = t + 2;
            legalise(loc, n, pts, f, 0);
            for (size_t h = t; h < n; h++) rotate_last(loc, h, iq), legalise(loc, n, pts, h, 0);
            return n;
        }
        uint32_t a = v[on], b = v[(on + 1) % 3], c = v[(on + 2) % 3];
        long g = edge_twin(loc, t, a, b);
        if (g < 0) return t; /* on the hole's boundary */
        int k = 0;
        while (loc[3 * g + k] == a || loc[3 * g + k] == b) k++;
        uint32_t d = loc[3 * g + k];
        loc[3 * f] = a, loc[3 * f + 1] = iq, loc[3 * f + 2] = c;
        loc[3 * (size_t)g] = b, loc[3 * (size_t)g + 1] = iq, loc[3 * (size_t)g + 2] = d;
        uint32_t *x = loc + 3 * t;
        x[0] = iq, x[1] = b, x[2] = c, x[3] = iq, x[4] = a, x[5] = d;
        size_t n = t + 2, tris[4] = {f, (size_t)g, t, t + 1};
        for (int h = 0; h < 4; h++) rotate_last(loc, tris[h], iq), legalise(loc, n, pts, tris[h], 0);
        return n;
    }
    return t;
}

/* Refines the strip (t triangles of vertex ids in extra, room for
 * extra_cap ids) of the hole [q0, q1] x [c0, c1] with Steiner points on the
 * parent's interior ridges, about one column apart along the parent, none
 * inside a ring or closer than half a column to one. pts[0..n_poly) is the
 * hole's polygon (its bridges doubled); the points are appended after it
 * (room for pts_cap) with their positions in sp. Returns the new triangle
 * count; *n_all is the points' count then. */
static size_t weld_refine(uint32_t *extra, size_t t, size_t extra_cap, weld_pt *pts, size_t n_poly, size_t pts_cap,
                          size_t *n_all, const weld_pt *const *hp, const size_t *hn, size_t ng, const sy_stem *ps,
                          const int32_t *pidx, const sy_mesh *m, size_t vbase, int P, long q0, long q1, int c0, int c1,
                          const int *seam, float arc, weld_steiner *sp, size_t np)
{
    *n_all = n_poly;
    sp->n = 0;
    if (m->n_vertices >= WELD_STEINER_ID0) return t;
    /* The plane's distinct points: the polygon's (a bridge repeats two). */
    weld_pt *up = malloc((n_poly + WELD_MAX_STEINER) * sizeof *up);
    uint32_t *loc = malloc((3 * t + 6 * WELD_MAX_STEINER) * sizeof *loc);
    if (!up || !loc) {
        free(up), free(loc);
        return 0;
    }
    size_t nu = 0;
    for (size_t i = 0; i < n_poly; i++) {
        size_t k = 0;
        while (k < nu && up[k].id != pts[i].id) k++;
        if (k == nu) up[nu++] = pts[i];
    }
    for (size_t f = 0; f < 3 * t; f++) {
        size_t k = 0;
        while (k < nu && up[k].id != extra[f]) k++;
        if (k == nu) {
            free(up), free(loc);
            return 0;
        }
        loc[f] = (uint32_t)k;
    }
    size_t row = (size_t)P + 1, nt = t, cap = t + 2 * WELD_MAX_STEINER;
    if (3 * cap > extra_cap) cap = extra_cap / 3;
    /* Only the band of the parent the rings stand on (and a column beyond)
     * needs them: away from the rings the hole's triangles join the
     * parent's own corners, one column apart. */
    float s_lo = INFINITY, s_hi = -INFINITY, ring_lo[WELD_MAX_GROUP], ring_hi[WELD_MAX_GROUP];
    for (size_t g = 0; g < ng; g++) {
        ring_lo[g] = INFINITY, ring_hi[g] = -INFINITY;
        for (size_t e = 0; e < hn[g]; e++) ring_lo[g] = fminf(ring_lo[g], hp[g][e].s), ring_hi[g] = fmaxf(ring_hi[g], hp[g][e].s);
        s_lo = fminf(s_lo, ring_lo[g]), s_hi = fmaxf(s_hi, ring_hi[g]);
    }
    float s_min = ps->ss[pidx[q0]], s_max = ps->ss[pidx[q1 + 1]];
    s_lo = fmaxf(s_lo - arc, s_min), s_hi = fminf(s_hi + arc, s_max);
    /* About a column apart; wider when that would be more points than the
     * room (the count falls as the spacing grows). A pass counts them, the
     * last places them. */
    float spacing = arc, keep = 0.5f * arc;
    for (int pass = 0, placing = 0;; pass++) {
        size_t n = 0;
        int k = (int)ceilf((s_hi - s_lo) / spacing);
        for (int j0 = c0 + 1; j0 <= c1; j0++) {
            for (int i = 0; i <= k; i++) {
                float s = s_lo + (s_hi - s_lo) * (float)i / (float)(k > 0 ? k : 1);
                /* On a band whose seam steps, the ridge's place in this row's
                 * span, and clear of the row lines the seam moves along. */
                long r = q0;
                while (r < q1 && ps->ss[pidx[r + 1]] <= s) r++;
                int j = j0, on_step = 0;
                if (seam) {
                    int rel = ((j0 - seam[r - q0]) % P + P) % P;
                    if (rel == 0) continue;
                    j = seam[r - q0] + rel;
                    for (long e = q0 + 1; e <= q1 && !on_step; e++)
                        on_step = seam[e - q0] != seam[e - 1 - q0] && fabsf(s - ps->ss[pidx[e]]) < keep;
                    if (on_step) continue;
                }
                int jj = ((j % P) + P) % P;
                float u = (float)j * arc;
                /* Within a column of a ring's rows (a band holds rings
                 * metres apart along a long thin parent), clear of the
                 * hole's top and bottom rows and of every ring. */
                int clear = s - s_min >= keep && s_max - s >= keep, near = 0;
                for (size_t g = 0; g < ng && !near; g++) near = s >= ring_lo[g] - arc && s <= ring_hi[g] + arc;
                clear = clear && near;
                for (size_t g = 0; g < ng && clear; g++) {
                    clear = !inside_ring(hp[g], hn[g], u, s);
                    for (size_t e = 0; e < hn[g] && clear; e++)
                        clear = seg_dist2(&hp[g][e], &hp[g][(e + 1) % hn[g]], u, s) >= keep * keep;
                }
                if (!clear) continue;
                if (placing && n < WELD_MAX_STEINER) {
                    /* On the parent's section at s, as the rings' plane
                     * positions are measured (grid_coords), not on the drawn
                     * quad's edge: a parent's first ring is moved onto its
                     * own parent, so its first quads leave the sections. */
                    float sa = ps->ss[pidx[r]], sb = ps->ss[pidx[r + 1]], f = sb > sa ? (s - sa) / (sb - sa) : 0;
                    size_t va = vbase + (size_t)r * row + (size_t)jj, vb = va + row;
                    float c3[3], T[3], N[3], B[3], R, v2[2], x[3];
                    sy_stem_frame_at(ps, pidx, np, s, c3, T, N, &R);
                    sy_cross3(T, N, B);
                    section_vertex(ps, P, R, jj, v2);
                    for (int c = 0; c < 3; c++) x[c] = c3[c] + v2[0] * N[c] + v2[1] * B[c];
                    sy_to_yup(x, sp->pos + 3 * n);
                    for (int c = 0; c < 4; c++)
                        sp->ww[4 * n + c] = m->wind_w[4 * va + c] + f * (m->wind_w[4 * vb + c] - m->wind_w[4 * va + c]);
                    sp->wb[n] = m->wind_branch[va];
                    up[nu] = (weld_pt){u, s, WELD_STEINER_ID0 + (uint32_t)n, -1 - (int)n};
                    nt = insert_point(loc, nt, cap, up, (uint32_t)nu);
                    nu++;
                }
                n++;
            }
        }
        if (placing) {
            sp->n = n < WELD_MAX_STEINER ? n : WELD_MAX_STEINER;
            break;
        }
        /* Counted: place them at this spacing, or widen it (twice at most). */
        if (n > WELD_MAX_STEINER && pass < 2) spacing *= 1.25f * (float)n / (float)WELD_MAX_STEINER;
        else placing = 1;
    }
    /* Back to vertex ids; the points join pts after the polygon. */
    int ok = n_poly + sp->n <= pts_cap;
    for (size_t f = 0; ok && f < 3 * nt; f++) extra[f] = up[loc[f]].id;
    for (size_t k = 0; ok && k < sp->n; k++) pts[n_poly + k] = up[nu - sp->n + k];
    free(up), free(loc);
    if (!ok) return 0;
    *n_all = n_poly + sp->n;
    return nt;
}

/* A strip corner (3 f + e) and where it lies. */
typedef struct {
    float p[3];
    uint32_t corner;
} corner_at;

static int cmp_place(const corner_at *a, const corner_at *b)
{
    for (int k = 0; k < 3; k++)
        if (a->p[k] != b->p[k]) return a->p[k] < b->p[k] ? -1 : 1;
    return 0;
}

static int cmp_corner_at(const void *x, const void *y)
{
    const corner_at *a = x, *b = y;
    int c = cmp_place(a, b);
    return c ? c : (a->corner > b->corner) - (a->corner < b->corner);
}

/* A strip fills its polygon exactly once: every directed edge occurs once,
 * and each is either on the polygon's boundary (pts, in order, its bridges
 * included) or matched by its reverse. Vertices compare by position (the
 * seams' copies are distinct vertices at one place): the corners are
 * numbered by place (sorted by position) and the edges sorted, O(t log t)
 * where comparing every edge with every other was O(t^2) per strip. Out of
 * memory: not valid (the caller keeps the ear-clipped strip, or caps the
 * junction). */
static int strip_valid(const uint32_t *tri, size_t t, const weld_pt *pts, size_t n, const sy_mesh *m,
                       const weld_steiner *sp)
{
    size_t nc = 3 * t;
    corner_at *at = malloc((nc + 1) * sizeof *at);
    uint32_t *place = malloc((nc + 1) * sizeof *place);
    id_pair *edge = malloc((nc + 1) * sizeof *edge), *sorted = malloc((nc + 1) * sizeof *sorted);
    id_pair *boundary = malloc((n + 1) * sizeof *boundary);
    int ok = at && place && edge && sorted && boundary;
    if (ok) {
        for (size_t k = 0; k < nc; k++) {
            memcpy(at[k].p, strip_pos(m, sp, tri[k]), sizeof at[k].p);
            at[k].corner = (uint32_t)k;
        }
        if (nc > 48) qsort(at, nc, sizeof *at, cmp_corner_at);
        else /* a strip's few corners: insertion, as id_pairs_sort */
            for (size_t i = 1; i < nc; i++) {
                corner_at x = at[i];
                size_t j = i;
                while (j > 0 && cmp_corner_at(&at[j - 1], &x) > 0) {
                    at[j] = at[j - 1];
                    j--;
                }
                at[j] = x;
            }
        for (size_t i = 0, c = 0; i < nc; i++) {
            if (i && cmp_place(&at[i], &at[i - 1])) c++;
            place[at[i].corner] = (uint32_t)c;
        }
        for (size_t f = 0; f < nc; f++) {
            size_t next = f - f % 3 + (f % 3 + 1) % 3;
            edge[f] = (id_pair){place[f], place[next]};
            ok &= edge[f].a != edge[f].b; /* a degenerate edge */
        }
        memcpy(sorted, edge, nc * sizeof *edge);
        id_pairs_sort(sorted, nc);
        for (size_t i = 0; i < n; i++) boundary[i] = (id_pair){pts[i].id, pts[(i + 1) % n].id};
        id_pairs_sort(boundary, n);
        for (size_t f = 0; f < nc && ok; f++) {
            size_t next = f - f % 3 + (f % 3 + 1) % 3;
            size_t twice = pair_count(sorted, nc, edge[f]) - 1;
            size_t reverse = pair_count(sorted, nc, (id_pair){edge[f].b, edge[f].a});
            int on_boundary = pair_count(boundary, n, (id_pair){tri[f], tri[next]}) > 0;
            ok = !(twice || reverse > 1 || !(reverse || on_boundary));
        }
    }
    free(at), free(place), free(edge), free(sorted), free(boundary);
    return ok;
}
/* Outward radial of parent p (glTF frame) at the point xy near its
 * surface: xy minus its closest point on the axis (rings pidx). */
static void parent_radial(const sy_stem *p, const int32_t *pidx, size_t np, const float xy[3], float s_hint,
                          float out[3])
{
    float x[3] = {xy[0], -xy[2], xy[1]}, c[3], T[3], N[3], R;
    sy_stem_closest_on_axis(p, pidx, np, x, s_hint, 6, c, T, N, &R);
    float w[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]}, d = sy_dot3(w, T);
    for (int k = 0; k < 3; k++) w[k] -= d * T[k];
    sy_to_yup(w, out);
}

/* The strip's own vertices: a copy of each boundary and ring vertex it
 * uses, textured in the parent's (around, along) coordinates unwrapped
 * about the hole (u past 1 or below 0 repeats), so the bark runs on across
 * the junction. Sharing the parent's and the child's vertices gave the
 * strip u = 0 next to u = (P-1)/P where a hole crossed the parent's seam
 * (the whole texture squeezed into one quad: the visible seam) and the
 * child's own u and v around its ring (a smeared patch). Positions are
 * the same, so the bark stays one closed surface; ring copies take the
 * parent's normal and tangent there. */
typedef struct {
    size_t n, cap;
    uint32_t base; /* index of the first copy in the mesh */
    float *pos, *nrm, *tan, *uv, *ww;
    uint16_t *wb;
} strip_verts;

/* Resizes the six arrays a bark vertex lives in (position 3, normal 3,
 * tangent 4, uv 2, wind weights 4 floats, wind branch) to n vertices, the
 * strip buffer's or the mesh's. Every array that could be resized is kept,
 * so after a failure (0) each is still valid for its old size. */
static int resize_vertices(float **pos, float **nrm, float **tan, float **uv, float **ww, uint16_t **wb, size_t n)
{
    float *a = realloc(*pos, 3 * n * sizeof *a);
    if (a) *pos = a;
    float *b = realloc(*nrm, 3 * n * sizeof *b);
    if (b) *nrm = b;
    float *c = realloc(*tan, 4 * n * sizeof *c);
    if (c) *tan = c;
    float *d = realloc(*uv, 2 * n * sizeof *d);
    if (d) *uv = d;
    float *e = realloc(*ww, 4 * n * sizeof *e);
    if (e) *ww = e;
    uint16_t *f = realloc(*wb, n * sizeof *f);
    if (f) *wb = f;
    return a && b && c && d && e && f;
}

static int strip_verts_grow(strip_verts *vb, size_t need)
{
    if (vb->n + need <= vb->cap) return 1;
    size_t nc = vb->cap ? 2 * vb->cap : 4096;
    while (nc < vb->n + need) nc *= 2;
    if (!resize_vertices(&vb->pos, &vb->nrm, &vb->tan, &vb->uv, &vb->ww, &vb->wb, nc)) return 0;
    vb->cap = nc;
    return 1;
}

static void strip_verts_free(strip_verts *vb)
{
    free(vb->pos), free(vb->nrm), free(vb->tan), free(vb->uv), free(vb->ww), free(vb->wb);
}

static int strip_copies(const sy_stems *st, const int32_t *g, size_t ng, const sy_lod_params *lp, const sy_mesh *m,
                        const size_t *vo, const sy_stem *ps, const int32_t *pidx, size_t np, float arc,
                        int P, const weld_pt *pts, size_t n_pts, const weld_steiner *sp, uint32_t *tri, size_t t,
                        strip_verts *vb)
{
    uint32_t *made = malloc((n_pts + 1) * sizeof *made);
    if (!made || !strip_verts_grow(vb, n_pts)) {
        free(made);
        return 0;
    }
    for (size_t i = 0; i < n_pts; i++) made[i] = UINT32_MAX;
    float vscale = 1.0f / (2 * SY_PI * ps->r_base);
    for (size_t f = 0; f < 3 * t; f++) {
        uint32_t id = tri[f];
        /* A ring's seam copy stands for its vertex 0. */
        for (size_t k = 0; k < ng; k++) {
            uint32_t r0 = (uint32_t)vo[g[k]];
            if (id == r0 + (uint32_t)sy_stem_radial(&st->s[g[k]], lp)) id = r0;
        }
        size_t i = 0;
        while (i < n_pts && pts[i].id != id) i++;
        if (i == n_pts) {
            free(made);
            return 0;
        }
        if (made[i] == UINT32_MAX) {
            size_t w = vb->n++;
            const weld_pt *q = &pts[i];
            memcpy(vb->pos + 3 * w, strip_pos(m, sp, id), 3 * sizeof(float));
            if (id >= WELD_STEINER_ID0) {
                memcpy(vb->ww + 4 * w, sp->ww + 4 * (size_t)(id - WELD_STEINER_ID0), 4 * sizeof(float));
                vb->wb[w] = sp->wb[id - WELD_STEINER_ID0];
            } else {
                memcpy(vb->ww + 4 * w, m->wind_w + 4 * (size_t)seam_vertex(id), 4 * sizeof(float));
                vb->wb[w] = m->wind_branch[seam_vertex(id)];
            }
            vb->uv[2 * w] = q->u / arc / (float)P, vb->uv[2 * w + 1] = q->s * vscale;
            if (q->loop == 0) {
                memcpy(vb->nrm + 3 * w, m->normal + 3 * (size_t)seam_vertex(id), 3 * sizeof(float));
                memcpy(vb->tan + 4 * w, m->tangent + 4 * (size_t)seam_vertex(id), 4 * sizeof(float));
            } else {
                const float *y = strip_pos(m, sp, id);
                float x[3] = {y[0], -y[2], y[1]}, c[3], T[3], N[3], R, s = q->s;
                sy_stem_frame_at(ps, pidx, np, s, c, T, N, &R);
                float r[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]}, d = sy_dot3(r, T), e[3];
                for (int k = 0; k < 3; k++) r[k] -= d * T[k];
                sy_normalize3(r);
                sy_cross3(T, r, e);
                sy_normalize3(e);
                sy_to_yup(r, vb->nrm + 3 * w);
                sy_to_yup(e, vb->tan + 4 * w);
                vb->tan[4 * w + 3] = 1.0f;
            }
            made[i] = vb->base + (uint32_t)w;
        }
        tri[f] = made[i];
    }
    free(made);
    return 1;
}



/* Does the strip fold? Every triangle must face away from the parent's
 * axis (the outward radial at its centroid). Comparing with the normals of
 * its corners on the parent's boundary instead refused sound triangles
 * that span a wide hole on a six-sided parent (a corner normal is 30
 * degrees off each face), and let triangles between ring vertices alone go
 * unchecked. */
static int strip_folds(const uint32_t *tri, size_t t, const sy_mesh *m, const weld_steiner *sp, const sy_stem *ps,
                       const int32_t *pidx, size_t np, float s_mid)
{
    for (size_t f = 0; f < t; f++) {
        const uint32_t *x = tri + 3 * f;
        const float *a = strip_pos(m, sp, x[0]), *b = strip_pos(m, sp, x[1]), *c = strip_pos(m, sp, x[2]);
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]}, gn[3];
        sy_cross3(e1, e2, gn);
        float g[3] = {(a[0] + b[0] + c[0]) / 3, (a[1] + b[1] + c[1]) / 3, (a[2] + b[2] + c[2]) / 3}, ref_n[3];
        parent_radial(ps, pidx, np, g, s_mid, ref_n);
        if (!(sy_dot3(gn, ref_n) > 0)) return 1;
    }
    return 0;
}

/* Plane place of vertex id among the strip's points (the first copy: a
 * bridge repeats two points at one place). */
static const weld_pt *strip_pt(const weld_pt *pts, size_t n, uint32_t id)
{
    for (size_t i = 0; i < n; i++)
        if (pts[i].id == id) return &pts[i];
    return NULL;
}

#define UNFOLD_PASSES 8

/* Flips edges of folded strip triangles while that unfolds more triangles
 * than it folds. Near a parent's ridge the plane's thin triangles along it
 * (a ring vertex a few millimetres across the ridge from a grid corner or a
 * Steiner point) can face into the parent in space; the other diagonal of
 * the quad they form with a neighbour usually does not. A flip is taken only
 * where the quad is convex in the plane, so the strip still tiles its
 * polygon (strip_valid checks it again). Each flip lowers the count of
 * folded triangles, so the passes end. */
static void unfold_flips(uint32_t *tri, size_t t, const weld_pt *pts, size_t n, const sy_mesh *m,
                         const weld_steiner *sp, const sy_stem *ps, const int32_t *pidx, size_t np, float s_mid)
{
    for (int pass = 0, changed = 1; changed && pass < UNFOLD_PASSES; pass++) {
        changed = 0;
        for (size_t f = 0; f < t; f++) {
            if (!strip_folds(tri + 3 * f, 1, m, sp, ps, pidx, np, s_mid)) continue;
            for (int e = 0; e < 3; e++) {
                uint32_t a = tri[3 * f + e], b = tri[3 * f + (e + 1) % 3], c = tri[3 * f + (e + 2) % 3];
                long tw = edge_twin(tri, t, a, b);
                if (tw < 0) continue;
                size_t g = (size_t)tw;
                int k = 0;
                while (tri[3 * g + k] != b) k++; /* the twin runs (b, a, d) */
                uint32_t d = tri[3 * g + (k + 2) % 3];
                const weld_pt *pa = strip_pt(pts, n, a), *pb = strip_pt(pts, n, b), *pc = strip_pt(pts, n, c),
                              *pd = strip_pt(pts, n, d);
                if (!pa || !pb || !pc || !pd || !(orient2(pa, pd, pc) > 0 && orient2(pd, pb, pc) > 0)) continue;
                uint32_t nf[3] = {a, d, c}, ng[3] = {d, b, c};
                int before = 1 + strip_folds(tri + 3 * g, 1, m, sp, ps, pidx, np, s_mid);
                int after = strip_folds(nf, 1, m, sp, ps, pidx, np, s_mid) + strip_folds(ng, 1, m, sp, ps, pidx, np, s_mid);
                if (after >= before) continue;
                memcpy(tri + 3 * f, nf, sizeof nf), memcpy(tri + 3 * g, ng, sizeof ng);
                changed = 1;
                break;
            }
        }
    }
}

/* A group's strip as weld_group found it, kept until it is drawn: its
 * triangles (vertex ids), plane points and Steiner points, and the
 * parent's column arc. The greedy grouping (weld_junctions) tries every
 * group before it draws any; drawing the kept strip instead of welding the
 * group a second time halves the welds' cost, with the same bytes. */
typedef struct {
    uint32_t *tri;
    size_t t;
    weld_pt *pts;
    size_t n_pts;
    weld_steiner sp;
    float arc;
} weld_strip;

static void weld_strip_free(weld_strip *w)
{
    if (!w) return;
    free(w->tri), free(w->pts);
    free(w);
}

/* Welds the group of children g[0..ng) of one parent into the parent's
 * quads [q0, q1] x [c0, c1] (columns unwrapped about the rectangle): writes the strip to
 * extra and, with keep, a copy of it for weld_emit (NULL when out of memory). Returns the
 * strip's triangles, 0 when the rings do not fit (crossing rings, a ring that winds the wrong
 * way, a fold), the strip would hold a degenerate triangle, or, with no_needles, a needle
 * (SY_MESH_NEEDLE_ASPECT); *needled says whether a needle alone refused it. */
static size_t weld_group(const sy_stems *st, const int32_t *g, size_t ng, long q0, long q1, int c0, int c1,
                         const int *seam, const sy_lod_params *lp, const sy_mesh *m, const size_t *vo,
                         uint32_t *extra, size_t extra_cap, int32_t *pidx, weld_pt *scratch, size_t scratch_cap,
                         int no_needles, int *needled, weld_strip **keep)
{
    *needled = 0;
    size_t p = (size_t)st->s[g[0]].parent;
    const sy_stem *ps = &st->s[p];
    int P = sy_stem_radial(ps, lp);
    size_t row = (size_t)P + 1, np = sy_stem_rings(ps, lp, pidx);
    float cmid[3], T0[3], N0[3], R;
    float s_mid = 0.5f * (ps->ss[pidx[q0]] + ps->ss[pidx[q1 + 1]]);
    sy_stem_frame_at(ps, pidx, np, s_mid, cmid, T0, N0, &R);
    float arc = 2 * SY_PI * R / (float)P;
    /* A band (seam given): the hole runs once round the parent between its
     * seam, one column boundary a row (seam[r - q0], stepping along the
     * row lines between rows), and the seam one turn on; that second seam
     * is the same mesh vertices, labelled (WELD_SEAM_BIT). Parent rows the
     * rings of a whorl cover all round were capped whole before. A
     * rectangle is a band whose seam stands still, c0 to c1 + 1. */
    int band = seam != NULL, rect_seam = c0, right = band ? P : c1 - c0 + 1;
    const int *L = band ? seam : &rect_seam;
#define SEAM(r) (L[band ? (r) - q0 : 0])
    if (band && m->n_vertices >= WELD_SEAM_BIT - 2u * WELD_MAX_STEINER) return 0;
    size_t moves = 0;
    for (long r = q0; band && r < q1; r++) moves += (size_t)abs(SEAM(r + 1) - SEAM(r));
    /* Outer boundary, counter-clockwise in (around, along): along row q0,
     * up the right side, back along row q1 + 1, down the left side. */
    size_t n_out = 2 * ((size_t)(q1 - q0 + 1) + (size_t)right + moves), n_ring = 0;
    for (size_t k = 0; k < ng; k++) n_ring += (size_t)sy_stem_radial(&st->s[g[k]], lp);
    size_t need = 2 * (n_out + n_ring + 2 * ng) + n_ring;
    if (need > scratch_cap || 3 * (n_out + n_ring + 2 * ng) > extra_cap) return 0;
    weld_poly poly = {scratch, 0, n_out + n_ring + 2 * ng};
    weld_pt *holes = scratch + poly.cap;
#define PUSH(r, j, second)                                                                                  \
    do {                                                                                                    \
        uint32_t vid = (uint32_t)(vo[p] + (size_t)(r) * row + (size_t)((((j) % P) + P) % P));               \
        poly.v[poly.n].id = band && (second) ? vid | WELD_SEAM_BIT : vid;                                   \
        poly.v[poly.n].u = (float)(j) * arc;                                                                \
        poly.v[poly.n].s = grid_vertex_s(ps, pidx, r, m->position + 3 * (size_t)vid);                       \
        poly.v[poly.n++].loop = 0;                                                                          \
    } while (0)
    for (int j = SEAM(q0); j < SEAM(q0) + right; j++) PUSH(q0, j, 0);
    /* Right side, up: each row's edge, then along the next row line to
     * that row's seam. */
    for (long r = q0; r <= q1; r++) {
        int j = SEAM(r) + right;
        PUSH(r, j, 1);
        if (r == q1) break;
        for (int to = SEAM(r + 1) + right, d = to > j ? 1 : -1; j != to; j += d) PUSH(r + 1, j, 1);
    }
    for (int j = SEAM(q1) + right; j > SEAM(q1); j--) PUSH(q1 + 1, j, j == SEAM(q1) + right);
    /* Left side, down: the same path the other way. */
    for (long r = q1; r >= q0; r--) {
        int j = SEAM(r);
        PUSH(r + 1, j, 0);
        if (r == q0) break;
        for (int to = SEAM(r - 1), d = to > j ? 1 : -1; j != to; j += d) PUSH(r, j, 0);
    }
#undef PUSH
    /* Rings, clockwise (reversed): their edges then run against the child
     * tubes', so the strip is oriented with them. */
    const weld_pt *hp[WELD_MAX_GROUP];
    size_t hn[WELD_MAX_GROUP], at = 0;
    float smin = ps->ss[pidx[q0]], smax = ps->ss[pidx[q1 + 1]];
    for (size_t k = 0; k < ng; k++) {
        const sy_stem *s = &st->s[g[k]];
        int Pc = sy_stem_radial(s, lp);
        const float *ring = m->position + 3 * vo[g[k]];
        weld_pt *h = holes + at;
        double area = 0;
        for (int v = 0; v < Pc; v++) {
            float rw, cl, sx, Rx;
            grid_coords(ps, pidx, np, P, ring + 3 * v, s->attach_s, &sx, &rw, &cl, &Rx);
            weld_pt *q = &h[Pc - 1 - v];
            /* Unwrapped into its row's span (the seam may step between rows). */
            long rr = rw < (float)q0 ? q0 : rw >= (float)(q1 + 1) ? q1 : (long)rw;
            float umin = (float)SEAM(rr) * arc, umax = (float)(SEAM(rr) + right) * arc;
            q->u = unwrap_col(cl, (float)SEAM(rr) + 0.5f * (float)right, P) * arc, q->s = sx;
            /* The seam copy keeps the strip's u continuous at the seam. */
            q->id = (uint32_t)(vo[g[k]] + (size_t)v);
            q->loop = (int)k + 1;
            if (!(q->u > umin && q->u < umax && q->s > smin && q->s < smax)) return 0;
        }
        for (int v = 0; v < Pc; v++) area += orient2(&h[0], &h[v], &h[(v + 1) % Pc]);
        if (!(area < 0)) return 0;
        hp[k] = h, hn[k] = (size_t)Pc, at += (size_t)Pc;
    }
    for (size_t a = 0; a < ng; a++)
        for (size_t i = 0; i < hn[a]; i++)
            for (size_t j = i + 2; j < hn[a]; j++)
                if (segments_cross(&hp[a][i], &hp[a][(i + 1) % hn[a]], &hp[a][j], &hp[a][(j + 1) % hn[a]])) return 0;
    /* Rings must not cross each other. */
    for (size_t a = 0; a < ng; a++)
        for (size_t b = a + 1; b < ng; b++)
            for (size_t i = 0; i < hn[a]; i++)
                for (size_t j = 0; j < hn[b]; j++) {
                    if (segments_cross(&hp[a][i], &hp[a][(i + 1) % hn[a]], &hp[b][j], &hp[b][(j + 1) % hn[b]])) return 0;
                    if (hp[a][i].u == hp[b][j].u && hp[a][i].s == hp[b][j].s) return 0;
                }
    /* Bridge from the largest "around" coordinate down. */
    size_t order[WELD_MAX_GROUP];
    float key[WELD_MAX_GROUP];
    for (size_t k = 0; k < ng; k++) {
        order[k] = k, key[k] = -INFINITY;
        for (size_t i = 0; i < hn[k]; i++) key[k] = fmaxf(key[k], hp[k][i].u);
    }
    for (size_t a = 1; a < ng; a++)
        for (size_t b = a; b > 0 && key[order[b]] > key[order[b - 1]]; b--) {
            size_t tmp = order[b];
            order[b] = order[b - 1], order[b - 1] = tmp;
        }
    for (size_t k = 0; k < ng; k++) {
        const weld_pt *rest[WELD_MAX_GROUP];
        size_t nrest[WELD_MAX_GROUP];
        for (size_t r = k + 1; r < ng; r++) rest[r - k - 1] = hp[order[r]], nrest[r - k - 1] = hn[order[r]];
        if (!bridge_hole(&poly, hp[order[k]], hn[order[k]], rest, nrest, ng - k - 1)) return 0;
    }
    /* Ear clipping consumes the polygon; the flips need its points. */
    weld_pt *pts = holes + n_ring;
    size_t n_pts = poly.n;
    memcpy(pts, poly.v, n_pts * sizeof *pts);
    size_t t = ear_clip(&poly, extra);
    if (!t) return 0;
    (void)row;
    uint32_t *clipped = malloc(3 * t * sizeof *clipped);
    if (!clipped) return 0;
    memcpy(clipped, extra, 3 * t * sizeof *clipped);
    if (!delaunay_flips(extra, t, pts, n_pts) || !strip_valid(extra, t, pts, n_pts, m, NULL))
        memcpy(extra, clipped, 3 * t * sizeof *clipped);
    free(clipped);
    size_t n_all = n_pts;
    weld_steiner sp;
    sp.n = 0;
    if (strip_folds(extra, t, m, NULL, ps, pidx, np, s_mid)) {
        t = weld_refine(extra, t, extra_cap, pts, n_pts, scratch_cap - (size_t)(pts - scratch), &n_all, hp, hn, ng, ps,
                        pidx, m, vo[p], P, q0, q1, c0, c1, band ? seam : NULL, arc, &sp, np);
        if (t && strip_folds(extra, t, m, &sp, ps, pidx, np, s_mid)) unfold_flips(extra, t, pts, n_all, m, &sp, ps, pidx, np, s_mid);
        if (!t || !strip_valid(extra, t, pts, n_pts, m, &sp) || strip_folds(extra, t, m, &sp, ps, pidx, np, s_mid))
            return 0;
    }
    /* A strip triangle of three nearly collinear corners (a ring vertex on
     * a parent row line) that no edge flip can mend (sy_mesh_flip_degenerates
     * flips within the bark, not across a strip's copies) leaves the
     * junction capped: a weld may not cost a degenerate triangle. A needle
     * refuses the strip only with no_needles (the caller then tries another
     * rectangle, and takes the needle when none is free of them). */
    for (size_t f = 0; f < t; f++) {
        const float *q[3];
        for (int e = 0; e < 3; e++) q[e] = strip_pos(m, &sp, extra[3 * f + (size_t)e]);
        double area = sy_tri_area(q[0], q[1], q[2]), l2 = 0; /* l2: the longest edge, squared */
        for (int e = 0; e < 3; e++) {
            double d2 = 0;
            for (int k = 0; k < 3; k++) d2 += ((double)q[(e + 1) % 3][k] - q[e][k]) * ((double)q[(e + 1) % 3][k] - q[e][k]);
            l2 = fmax(l2, d2);
        }
        if (area < SY_BARK_MIN_AREA) return 0;
        if (no_needles && 2 * area < SY_MESH_NEEDLE_ASPECT * l2) return *needled = 1, 0;
    }
    /* A ring's last vertex pairs with its seam copy, not with vertex 0. */
    for (size_t f = 0; f < t; f++)
        for (size_t k = 0; k < ng; k++) {
            uint32_t r0 = (uint32_t)vo[g[k]], last = r0 + (uint32_t)hn[k] - 1;
            uint32_t *x = extra + 3 * f;
            if (x[0] == last || x[1] == last || x[2] == last)
                for (int c = 0; c < 3; c++)
                    if (x[c] == r0) x[c] = r0 + (uint32_t)hn[k];
        }
    if (keep) {
        weld_strip *w = calloc(1, sizeof *w);
        if (w) w->tri = malloc(3 * t * sizeof *w->tri), w->pts = malloc(n_all * sizeof *w->pts);
        if (w && w->tri && w->pts) {
            memcpy(w->tri, extra, 3 * t * sizeof *w->tri), memcpy(w->pts, pts, n_all * sizeof *w->pts);
            w->t = t, w->n_pts = n_all, w->sp = sp, w->arc = arc;
        } else {
            weld_strip_free(w), w = NULL;
        }
        *keep = w;
    }
#undef SEAM
    return t;
}

/* Draws a kept strip of the group g[0..ng) welded into the parent's quads
 * [q0, q1] x [c0, c1]: the strip's own vertex copies (into vb, its
 * triangles into extra) and the parent's quads it replaces (cut). Returns
 * the strip's triangles, 0 when out of memory. */
static size_t weld_emit(const sy_stems *st, const int32_t *g, size_t ng, long q0, long q1, int c0, int c1,
                        const sy_lod_params *lp, const sy_mesh *m, const size_t *vo, const size_t *io, uint8_t *cut,
                        const weld_strip *w, uint32_t *extra, size_t extra_cap, int32_t *pidx, strip_verts *vb)
{
    size_t p = (size_t)st->s[g[0]].parent;
    const sy_stem *ps = &st->s[p];
    int P = sy_stem_radial(ps, lp);
    size_t np = sy_stem_rings(ps, lp, pidx);
    if (3 * w->t > extra_cap) return 0;
    memcpy(extra, w->tri, 3 * w->t * sizeof *extra);
    if (!strip_copies(st, g, ng, lp, m, vo, ps, pidx, np, w->arc, P, w->pts, w->n_pts, &w->sp, extra, w->t, vb))
        return 0;
    for (long r = q0; r <= q1; r++)
        for (int j = c0; j <= c1; j++) {
            size_t q = quad_tri(io, p, P, r, j, 0);
            cut[q] = cut[q + 1] = 1;
        }
    return w->t;
}

/* Closes a ring that could not be welded with a low cone facing into the
 * parent: the tube stays a closed surface, its end hidden in the bark. The
 * cone shares the tube's ring vertices (its seam copy too, so u runs on
 * round it) and has one apex copy per column, each with its column's u, half
 * a radius inside, behind the ring's centre. A flat fan over a ring the
 * parent's surface squashed into a line (a child leaving a thin parent at a
 * glancing angle) was a zero-area triangle; and the fan's own copies of the
 * ring (u = 0) made a seam that an edge flip could not cross, leaving a
 * zero-area triangle of the tube's first row beside it (slivers.c). Returns
 * the triangles, 0 when out of memory. */
static size_t cap_ring(const sy_stems *st, size_t c, const sy_lod_params *lp, const size_t *vo, const sy_mesh *m,
                       strip_verts *vb, uint32_t *extra)
{
    const sy_stem *s = &st->s[c];
    int Pc = sy_stem_radial(s, lp);
    if (!strip_verts_grow(vb, (size_t)Pc)) return 0;
    float centre[3] = {0, 0, 0}, back[3], in_yup[3] = {-s->st[0], -s->st[1], -s->st[2]};
    for (int k = 0; k < Pc; k++)
        for (int q = 0; q < 3; q++) centre[q] += m->position[3 * (vo[c] + (size_t)k) + q] / (float)Pc;
    sy_to_yup(in_yup, back);
    uint32_t apex0 = vb->base + (uint32_t)vb->n, ring = (uint32_t)vo[c];
    /* The apex copies sit on the texture half a row before the ring's
     * lowest v (a ring pushed onto its parent has a v per vertex), so the
     * cone maps onto it the way the tube's rows do, never mirrored. */
    float v0 = INFINITY, dv = 0;
    for (int k = 0; k <= Pc; k++) {
        size_t id = vo[c] + (size_t)k;
        v0 = fminf(v0, m->uv[2 * id + 1]);
        dv = fmaxf(dv, fabsf(m->uv[2 * (id + (size_t)Pc + 1) + 1] - m->uv[2 * id + 1]));
    }
    for (int k = 0; k < Pc; k++) {
        size_t w = vb->n++, id = vo[c] + (size_t)k;
        for (int q = 0; q < 3; q++) vb->pos[3 * w + q] = centre[q] + 0.5f * s->sr[0] * back[q];
        memcpy(vb->nrm + 3 * w, back, 3 * sizeof(float));
        memcpy(vb->tan + 4 * w, m->tangent + 4 * id, 4 * sizeof(float));
        memcpy(vb->ww + 4 * w, m->wind_w + 4 * id, 4 * sizeof(float));
        vb->wb[w] = m->wind_branch[id];
        vb->uv[2 * w] = ((float)k + 0.5f) / (float)Pc, vb->uv[2 * w + 1] = v0 - fmaxf(0.5f * dv, 1e-4f);
    }
    size_t t = 0;
    for (int k = 0; k < Pc; k++)
        extra[t++] = apex0 + (uint32_t)k, extra[t++] = ring + (uint32_t)k + 1, extra[t++] = ring + (uint32_t)k;
    return t / 3;
}

static int cols_overlap(int a0, int a1, int b0, int b1, int P, int *shift)
{
    for (int k = -2; k <= 2; k++)
        if (b0 + k * P <= a1 && b1 + k * P >= a0) {
            *shift = k * P;
            return 1;
        }
    return 0;
}

static int cmp_weld_parent(const void *x, const void *y, const sy_stems *st)
{
    const weld_job *a = x, *b = y;
    int32_t pa = st->s[a->stem].parent, pb = st->s[b->stem].parent;
    if (pa != pb) return pa < pb ? -1 : 1;
    return sy_stem_by_radius_cmp(x, y);
}

/* Appends t triangles from extra to the growing strips buffer. */
static int append_strip(uint32_t **strips, size_t *n, size_t *cap, const uint32_t *extra, size_t t)
{
    if (*n + 3 * t > *cap) {
        size_t nc = *cap ? 2 * *cap : 3 * 4096;
        while (nc < *n + 3 * t) nc *= 2;
        uint32_t *gr = realloc(*strips, nc * sizeof *gr);
        if (!gr) return 0;
        *strips = gr, *cap = nc;
    }
    if (t) memcpy(*strips + *n, extra, 3 * t * sizeof *extra);
    *n += 3 * t;
    return 1;
}

/* Is column boundary b (mod P) inside ring footprint r's columns, where its
 * ring crosses it? */
static int seam_crosses(const weld_rect *r, int b, int P)
{
    int span = r->c1 - r->c0 + 1, off = ((b - r->c0) % P + P) % P;
    return off > 0 && off < span;
}

/* A group whose rectangles wrap its parent becomes a band of whole rows.
 * Its seam is the column boundary that no ring crosses and that lies
 * farthest from every ring (ties: the lowest); the band's columns run once
 * round from there: seam[r - q0] = that column for every row. When every
 * boundary is crossed somewhere, the seam may instead step from row to row
 * (a staircase): in each row a boundary no ring of that row crosses, and
 * between two rows a move along their common row line over columns no
 * ring standing on both rows covers; the path with the fewest columns of
 * moves (ties: the lowest boundaries). seam[] holds unwrapped columns, each
 * within half a turn of the one before. 0 when there is no such path. */
static int band_seam(const weld_rect *rect, const size_t *member, size_t ng, int P, weld_rect *u, int *seam)
{
    long rows = u->q1 - u->q0 + 1;
    int best = -1, best_gap = -1;
    if (rows < 1 || rows > WELD_MAX_LOOP / 2) return 0;
    for (int b = 0; b < P; b++) {
        int gap = P;
        for (size_t k = 0; k < ng && gap >= 0; k++) {
            const weld_rect *r = &rect[member[k]];
            int span = r->c1 - r->c0 + 1, off = ((b - r->c0) % P + P) % P;
            /* Crossed: -1; else the columns between b and the ring's footprint. */
            int g = seam_crosses(r, b, P) ? -1 : off == 0 ? 0 : (off - span < P - off ? off - span : P - off);
            if (g < gap) gap = g;
        }
        if (gap > best_gap) best_gap = gap, best = b;
    }
    if (best >= 0) {
        for (long r = 0; r < rows; r++) seam[r] = best;
        u->c0 = best, u->c1 = best + P - 1;
        return 1;
    }
    if (rows < 2 || rows > WELD_MAX_BAND_ROWS || P > WELD_MAX_BAND_COLS) return 0;
    /* cost[r][b]: fewest columns of moves reaching boundary b in row r
     * (-1: unreachable); from[r][b]: the boundary before it. */
    int cost[WELD_MAX_BAND_ROWS][WELD_MAX_BAND_COLS], from[WELD_MAX_BAND_ROWS][WELD_MAX_BAND_COLS];
    for (long r = 0; r < rows; r++) {
        long row = u->q0 + r;
        for (int b = 0; b < P; b++) {
            cost[r][b] = -1, from[r][b] = -1;
            int free_b = 1;
            for (size_t k = 0; k < ng && free_b; k++) {
                const weld_rect *w = &rect[member[k]];
                free_b = row < w->q0 || row > w->q1 || !seam_crosses(w, b, P);
            }
            if (!free_b) continue;
            if (r == 0) {
                cost[r][b] = 0;
                continue;
            }
            for (int a = 0; a < P; a++) {
                if (cost[r - 1][a] < 0) continue;
                /* The shorter way round from a to b along row line `row`. */
                int d = ((b - a) % P + P) % P;
                if (2 * d > P) d -= P;
                int lo = d < 0 ? a + d : a, n = d < 0 ? -d : d, clear = 1;
                for (size_t k = 0; k < ng && clear && n > 0; k++) {
                    const weld_rect *w = &rect[member[k]];
                    if (w->q0 > row - 1 || w->q1 < row) continue; /* not on both rows */
                    for (int c = lo; c < lo + n && clear; c++) {
                        int off = ((c - w->c0) % P + P) % P;
                        clear = off > w->c1 - w->c0;
                    }
                }
                int cst = cost[r - 1][a] + n;
                if (clear && (cost[r][b] < 0 || cst < cost[r][b])) cost[r][b] = cst, from[r][b] = a;
            }
        }
    }
    int end = -1;
    for (int b = 0; b < P; b++)
        if (cost[rows - 1][b] >= 0 && (end < 0 || cost[rows - 1][b] < cost[rows - 1][end])) end = b;
    if (end < 0) return 0;
    for (long r = rows - 1, b = end; r >= 0; r--) seam[r] = (int)b, b = from[r][b];
    for (long r = 1; r < rows; r++) {
        int d = ((seam[r] - seam[r - 1]) % P + P) % P;
        if (2 * d > P) d -= P;
        seam[r] = seam[r - 1] + d;
    }
    u->c0 = seam[0], u->c1 = seam[0] + P - 1;
    return 1;
}

/* Welds every junction of the level: the children of a parent whose
 * footprints overlap (and any the grown rectangle reaches) share one hole
 * and one strip; a group that cannot be welded has its rings capped. Then
 * rewrites out's index buffer: the parents' cut quads out, strips and caps in. */
static sy_code weld_junctions(const sy_stems *st, const sy_lod_params *lp, const size_t *vo, const size_t *io,
                              int32_t *idx, sy_mesh *out, size_t *n_junctions, size_t *n_welded, sy_error *err)
{
    size_t nj = 0, nt = out->n_indices / 3;
    for (size_t i = 0; i < st->n; i++)
        nj += st->s[i].junction && lp->keep[i] && st->s[i].has_geometry && (i + 1 == st->n || vo[i + 1] > vo[i]);
    *n_junctions = nj, *n_welded = 0;
    if (nj == 0) return SY_OK;
    size_t extra_cap = 3 * (WELD_MAX_LOOP + WELD_MAX_GROUP * (WELD_MAX_RING + 2)), scratch_cap = 3 * extra_cap;
    weld_job *jobs = malloc(nj * sizeof *jobs);
    weld_rect *rect = malloc(nj * sizeof *rect);
    weld_rect *box = malloc(nj * sizeof *box);
    int *group = malloc(nj * sizeof *group), *weld_joined = malloc(nj * sizeof *weld_joined);
    weld_strip **kept = calloc(nj, sizeof *kept); /* per group (by its last child): its strip */
    uint8_t *cut = calloc(nt + 1, 1);
    uint32_t *extra = malloc(extra_cap * sizeof *extra), *strips = NULL;
    weld_pt *scratch = malloc(scratch_cap * sizeof *scratch);
    size_t n_strips = 0, cap_strips = 0;
    strip_verts vb = {0, 0, (uint32_t)out->n_vertices, NULL, NULL, NULL, NULL, NULL, NULL};
    sy_code rc = SY_OK;
    if (!jobs || !rect || !box || !group || !weld_joined || !kept || !cut || !extra || !scratch) {
        rc = sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
        goto done;
    }
    nj = 0;
    for (size_t i = 0; i < st->n; i++) {
        const sy_stem *s = &st->s[i];
        if (s->junction && lp->keep[i] && s->has_geometry && (i + 1 == st->n || vo[i + 1] > vo[i]))
            jobs[nj++] = (weld_job){(int32_t)i, s->r_base};
    }
    /* Parents together, thicker children first (insertion sort keeps it
     * deterministic without a comparison context). */
    for (size_t a = 1; a < nj; a++)
        for (size_t b = a; b > 0 && cmp_weld_parent(&jobs[b], &jobs[b - 1], st) < 0; b--) {
            weld_job tmp = jobs[b];
            jobs[b] = jobs[b - 1], jobs[b - 1] = tmp;
        }
    for (size_t j = 0; j < nj; j++) {
        weld_footprint(st, (size_t)jobs[j].stem, lp, out, vo, idx, 0.0f, &rect[j]);
    }
    int32_t members[WELD_MAX_GROUP];
    size_t member_job[WELD_MAX_GROUP];
    int seam[WELD_MAX_LOOP / 2]; /* a band's seam column, row by row */
    for (size_t a = 0; a < nj;) {
        size_t b = a;
        int32_t parent = st->s[jobs[a].stem].parent;
        while (b < nj && st->s[jobs[b].stem].parent == parent) b++;
        int P = sy_stem_radial(&st->s[parent], lp);
        size_t np = sy_stem_rings(&st->s[parent], lp, idx);
        /* Groups, built greedily, thicker children first: a child joins
         * (or starts) a group when the rectangle grown to hold it and every
         * group its rectangle overlaps (until none overlaps) still leaves
         * the parent a band and the grown group welds; otherwise its ring
         * is capped and the groups stay as they were. Merging every
         * overlapping footprint at once instead let a whorl of twigs grow
         * one rectangle round the whole parent, and a group that folded
         * anywhere capped all its rings (a quarter of an aspen's junctions). */
        for (size_t j = a; j < b; j++) group[j] = -1;
        for (size_t j = a; j < b; j++) {
            int ok = 0;
            /* Tries: the ring's own rectangle, then one a column wider
             * (WELD_SIDE_MARGIN), first refusing needle triangles in the
             * strip, then taking them where a needle alone refused it: a
             * strip's needles beside a thin twig (the mesh check's
             * slivers) mostly have a needle-free strip one column wider,
             * and a weld with needles still beats a cap. Last, the ring's
             * rectangle a row taller at each end, whose strip has room
             * to run round the ring without folding where the ring nears
             * its rows' ends (rTwig's QSM welded 64 of its 72 LOD0
             * junctions, now 69; its cloud's run 505 of 540, now 509; the
             * grown library gains none). */
            int needled[2] = {0, 0};
            for (int attempt = 0; attempt < 5 && !ok; attempt++) {
                int wide = attempt & 1, no_needles = attempt < 2, tall = attempt == 4;
                if (!tall && !no_needles && !needled[wide]) continue;
                weld_rect u = rect[j];
                if (wide) {
                    weld_footprint(st, (size_t)jobs[j].stem, lp, out, vo, idx, WELD_SIDE_MARGIN, &u);
                    if (u.c0 == rect[j].c0 && u.c1 == rect[j].c1) continue;
                }
                if (tall) {
                    if (!u.ok || u.q0 < 1 || u.q1 + 1 > (long)np - 2) continue;
                    u.q0--, u.q1++;
                }
                ok = u.ok && u.q0 >= 0;
                if (!ok && (wide || tall)) continue;
                if (!ok) break;
                size_t ng = 0;
                member_job[ng] = j;
                members[ng++] = jobs[j].stem;
                int *joined = weld_joined;
                for (size_t q = a; q < j; q++) joined[q - a] = 0;
                for (int changed = 1; changed && ok;) {
                    changed = 0;
                    for (size_t k = a; k < j && ok; k++) {
                        int sh;
                        if (group[k] != (int)k || joined[k - a] || box[k].q1 < u.q0 || box[k].q0 > u.q1 ||
                            !cols_overlap(u.c0, u.c1, box[k].c0, box[k].c1, P, &sh))
                            continue;
                        joined[k - a] = 1, changed = 1;
                        u.q0 = box[k].q0 < u.q0 ? box[k].q0 : u.q0, u.q1 = box[k].q1 > u.q1 ? box[k].q1 : u.q1;
                        u.c0 = box[k].c0 + sh < u.c0 ? box[k].c0 + sh : u.c0;
                        u.c1 = box[k].c1 + sh > u.c1 ? box[k].c1 + sh : u.c1;
                        for (size_t q = a; q < j; q++)
                            if (group[q] == (int)k) {
                                if (ng < WELD_MAX_GROUP) members[ng] = jobs[q].stem, member_job[ng] = q;
                                ng++;
                            }
                    }
                }
                /* In the children's order, as the group is drawn below. */
                for (size_t x = 1; x < ng && x < WELD_MAX_GROUP; x++)
                    for (size_t y = x; y > 0 && member_job[y] < member_job[y - 1]; y--) {
                        size_t tj = member_job[y];
                        int32_t tm = members[y];
                        member_job[y] = member_job[y - 1], members[y] = members[y - 1];
                        member_job[y - 1] = tj, members[y - 1] = tm;
                    }
                int band = ok && ng <= WELD_MAX_GROUP && u.c1 - u.c0 + 1 > P - 1;
                if (band) ok = band_seam(rect, member_job, ng, P, &u, seam);
                ok = ok && ng <= WELD_MAX_GROUP && u.c1 - u.c0 + 1 <= P && u.q1 <= (long)np - 2 &&
                     2 * ((size_t)(u.q1 - u.q0 + 1) + (size_t)(u.c1 - u.c0 + 1)) <= WELD_MAX_LOOP;
                weld_strip *w = NULL;
                if (ok)
                    ok = weld_group(st, members, ng, u.q0, u.q1, u.c0, u.c1, band ? seam : NULL, lp, out, vo, extra,
                                    extra_cap, idx, scratch, scratch_cap, no_needles, &needled[wide], &w) > 0;
                if (ok) {
                    for (size_t k = a; k < j; k++)
                        if (group[k] == (int)k && joined[k - a]) weld_strip_free(kept[k]), kept[k] = NULL;
                    for (size_t k = a; k < j; k++)
                        if (group[k] >= 0 && joined[group[k] - (int)a]) group[k] = (int)j;
                    group[j] = (int)j;
                    box[j] = u;
                    kept[j] = w;
                }
            }
            if (!ok) {
                /* A cap on the ring (also one that stands on no quad of the tube). */
                size_t add = cap_ring(st, (size_t)jobs[j].stem, lp, vo, out, &vb, extra);
                if (!add || !append_strip(&strips, &n_strips, &cap_strips, extra, add)) {
                    rc = sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
                    goto done;
                }
            }
        }
        for (size_t j = a; j < b; j++) {
            if (group[j] != (int)j) continue;
            weld_rect u = box[j];
            size_t ng = 0;
            for (size_t k = a; k < b; k++)
                if (group[k] == (int)j) members[ng++] = jobs[k].stem;
            size_t t = kept[j] ? weld_emit(st, members, ng, u.q0, u.q1, u.c0, u.c1, lp, out, vo, io, cut, kept[j],
                                           extra, extra_cap, idx, &vb)
                               : 0;
            *n_welded += ng;
            if (!t || !append_strip(&strips, &n_strips, &cap_strips, extra, t)) {
                rc = sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
                goto done;
            }
        }
        a = b;
    }
    size_t removed = 0;
    for (size_t t = 0; t < nt; t++) removed += cut[t];
    uint32_t *ix = malloc((3 * (nt - removed) + n_strips + 1) * sizeof *ix);
    if (!ix) {
        rc = sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
        goto done;
    }
    size_t w = 0;
    for (size_t t = 0; t < nt; t++)
        if (!cut[t]) memcpy(ix + w, out->indices + 3 * t, 3 * sizeof *ix), w += 3;
    if (n_strips) memcpy(ix + w, strips, n_strips * sizeof *ix), w += n_strips; /* strips may be NULL */
    free(out->indices);
    out->indices = ix;
    out->n_indices = w;
    if (vb.n) {
        size_t nv = out->n_vertices + vb.n;
        if (nv > UINT32_MAX) {
            rc = sy_fail(err, SY_EINPUT, "mesh: %zu vertices exceed 32-bit indices", nv);
            goto done;
        }
        if (!resize_vertices(&out->position, &out->normal, &out->tangent, &out->uv, &out->wind_w, &out->wind_branch,
                             nv)) {
            rc = sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
            goto done;
        }
        size_t v0 = out->n_vertices;
        memcpy(out->position + 3 * v0, vb.pos, 3 * vb.n * sizeof *vb.pos);
        memcpy(out->normal + 3 * v0, vb.nrm, 3 * vb.n * sizeof *vb.nrm);
        memcpy(out->tangent + 4 * v0, vb.tan, 4 * vb.n * sizeof *vb.tan);
        memcpy(out->uv + 2 * v0, vb.uv, 2 * vb.n * sizeof *vb.uv);
        memcpy(out->wind_w + 4 * v0, vb.ww, 4 * vb.n * sizeof *vb.ww);
        memcpy(out->wind_branch + v0, vb.wb, vb.n * sizeof *vb.wb);
        out->n_vertices = nv;
    }
done:
    strip_verts_free(&vb);
    for (size_t j = 0; kept && j < nj; j++) weld_strip_free(kept[j]);
    free(kept);
    free(jobs), free(rect), free(box), free(group), free(weld_joined), free(cut), free(extra), free(strips), free(scratch);
    return rc;
}

sy_code sy_bark_mesh(const sy_stems *st, const sy_lod_params *lp, int material, sy_mesh *out, sy_error *err)
{
    return sy_bark_mesh_welds(st, lp, material, out, NULL, NULL, err);
}

sy_code sy_bark_mesh_welds(const sy_stems *st, const sy_lod_params *lp, int material, sy_mesh *out,
                           size_t *junctions, size_t *welded, sy_error *err)
{
    size_t nj_local, nw_local;
    if (!junctions) junctions = &nj_local;
    if (!welded) welded = &nw_local;
    *junctions = *welded = 0;
    memset(out, 0, sizeof *out);
    size_t nv = 0, ni = 0, max_samp = 1;
    size_t *vo = malloc((st->n + 1) * sizeof *vo), *io = malloc((st->n + 1) * sizeof *io);
    if (!vo || !io) {
        free(vo), free(io);
        return sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
    }
    for (size_t i = 0; i < st->n; i++) {
        size_t a, b;
        sy_tube_counts(st, i, lp, &a, &b);
        vo[i] = nv, io[i] = ni;
        nv += a, ni += b;
        if (st->s[i].n_samp > max_samp) max_samp = st->s[i].n_samp;
    }
    if (nv > UINT32_MAX) {
        free(vo), free(io);
        return sy_fail(err, SY_EINPUT, "mesh: %zu vertices exceed 32-bit indices", nv);
    }
    out->n_vertices = nv;
    out->n_indices = ni;
    out->material = material;
    out->position = sy_calloc(nv + 1, 3 * sizeof(float), err, "mesh");
    out->normal = sy_calloc(nv + 1, 3 * sizeof(float), err, "mesh");
    out->tangent = sy_calloc(nv + 1, 4 * sizeof(float), err, "mesh");
    out->uv = sy_calloc(nv + 1, 2 * sizeof(float), err, "mesh");
    out->wind_w = sy_calloc(nv + 1, 4 * sizeof(float), err, "mesh");
    out->wind_branch = sy_calloc(nv + 1, sizeof(uint16_t), err, "mesh");
    out->indices = sy_calloc(ni + 1, sizeof(uint32_t), err, "mesh");
    int32_t *idx = malloc(2 * max_samp * sizeof *idx);
    if (!out->position || !out->normal || !out->tangent || !out->uv || !out->wind_w || !out->wind_branch ||
        !out->indices || !idx) {
        free(vo), free(io), free(idx);
        sy_mesh_free(out);
        return sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
    }
    for (size_t i = 0; i < st->n; i++) {
        if ((i + 1 == st->n ? nv : vo[i + 1]) == vo[i]) continue;
        sy_tube_emit(st, i, lp, out, vo[i], io[i], idx);
    }
    sy_code rc = weld_junctions(st, lp, vo, io, idx, out, junctions, welded, err);
    free(vo), free(io), free(idx);
    if (rc == SY_OK) sy_mesh_flip_degenerates(out, SY_BARK_MIN_AREA);
    else sy_mesh_free(out);
    return rc;
}
