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

int sy_stem_radial(const sy_stem *s, const sy_lod_params *lp)
{
    int p = s->radial >> lp->level, lo = s->has_children ? PARENT_MIN_RADIAL : 3;
    return p < lo ? lo : p;
}

/* Twigs end in a cone: their hemisphere would cost a ring for a tip a few
 * millimetres across. */
int sy_stem_cap_rings(const sy_stem *s, const sy_lod_params *lp)
{
    return s->has_children || s->parent < 0 ? lp->cap_rings : 0;
}

size_t sy_stem_rings(const sy_stem *s, const sy_lod_params *lp, int32_t *idx)
{
    size_t n = 0, last = s->n_samp - 1, stride = (size_t)lp->stride;
    for (size_t i = 0; i < last; i += stride) idx[n++] = (int32_t)i;
    idx[n++] = (int32_t)last;
    return n;
}

/* A free base (the trunk, or a child that cannot reach its parent's
 * surface) is closed by a disc so no open end is visible. */
static int has_base_cap(const sy_stem *s) { return !s->junction; }

void sy_tube_counts(const sy_stems *st, size_t stem, const sy_lod_params *lp, size_t *nv, size_t *ni)
{
    const sy_stem *s = &st->s[stem];
    *nv = *ni = 0;
    if (!s->has_geometry || !lp->keep[stem]) return;
    size_t P = (size_t)sy_stem_radial(s, lp);
    size_t rings = (s->n_samp - 1 + (size_t)lp->stride - 1) / (size_t)lp->stride + 1;
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

/* Moves q along unit d onto the polygonal tube of stem p as drawn at this
 * level (P-gon cross-sections through the rings pidx, lobed on a grown
 * trunk), iterating the local frame so a curved parent is followed. Falls
 * back to the radial projection when the line misses the tube. Returns the
 * signed distance along d. */
static float project_to_parent(const sy_stem *p, const int32_t *pidx, size_t np, int P, const float q[3],
                               const float d[3], float s_est, float limit, float out[3])
{
    float lam = 0;
    for (int iter = 0; iter < 4; iter++) {
        float c[3], T[3], N[3], B[3], R;
        sy_stem_frame_at(p, pidx, np, s_est, c, T, N, &R);
        sy_cross3(T, N, B);
        float w[3] = {q[0] - c[0], q[1] - c[1], q[2] - c[2]};
        float w2[2] = {sy_dot3(w, N), sy_dot3(w, B)}, d2[2] = {sy_dot3(d, N), sy_dot3(d, B)}, best = 0;
        if (section_exit(p, P, R, w2, d2, &best) && fabsf(best) <= limit) {
            lam = best;
            for (int k = 0; k < 3; k++) out[k] = q[k] + lam * d[k];
        } else {
            /* The line misses the tube: take its closest approach to the
             * parent's axis, then scale that point's cross-section offset
             * onto the polygon, so the vertex still moves mostly along d. */
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
            l0 = l0 > limit ? limit : l0 < -limit ? -limit : l0;
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
                arc += project_to_parent(par, pidx, npr, Pp, pos, T, s->attach_s, limit, out);
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
 * the ring with half a quad to spare) and fills the hole between the
 * rectangle's boundary and the child's ring with a strip of triangles, so
 * parent, junction and child are one closed, consistently oriented surface.
 * The strip is zipped by angle about the child's axis, in the manner of
 * contour stitching (Fuchs, Kedem & Uselton 1977, reduced to the greedy
 * angular merge). A junction that cannot be welded (its ring wraps most of
 * the parent, runs off the parent's end, or overlaps a neighbour's hole)
 * stays as it was: an open ring on the parent's surface. */

typedef struct {
    int32_t stem;
    float r_base;
} weld_job;

static int cmp_weld(const void *x, const void *y)
{
    const weld_job *a = x, *b = y;
    if (a->r_base != b->r_base) return a->r_base > b->r_base ? -1 : 1;
    return (a->stem > b->stem) - (a->stem < b->stem);
}

#define WELD_MAX_LOOP 1024

/* The hole child c's ring needs in its parent's grid at this level. */
typedef struct {
    int32_t stem;
    long q0, q1; /* quad rows */
    int c0, c1;  /* quad columns, unwrapped about jc */
    int jc;
    int ok;      /* the rectangle lies in the parent's tube and leaves it a band */
} weld_rect;

/* Where point x (glTF frame) sits on parent p's grid at this level: arc
 * length s along the parent, fractional ring row (-1 beyond the tube's
 * rings) and fractional column in [0, P), plus the radius there. */
static void grid_coords(const sy_stem *p, const int32_t *pidx, size_t np, int P, const float xy[3], float s_hint,
                        float *s_out, float *row, float *col, float *R_out)
{
    float x[3] = {xy[0], -xy[2], xy[1]}, c[3], T[3], N[3], R, s_est = s_hint;
    for (int it = 0; it < 4; it++) {
        sy_stem_frame_at(p, pidx, np, s_est, c, T, N, &R);
        float w[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]}, ds = sy_dot3(w, T);
        s_est += ds;
        if (fabsf(ds) < 1e-6f) break;
    }
    sy_stem_frame_at(p, pidx, np, s_est, c, T, N, &R);
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

/* Unwraps column c about the reference column ref into (ref - P/2, ref + P/2]. */
static float unwrap_col(float c, float ref, int P)
{
    while (c - ref > 0.5f * (float)P) c -= (float)P;
    while (c - ref <= -0.5f * (float)P) c += (float)P;
    return c;
}

#define WELD_MAX_RING 256

/* The quads the ring covers: rows floor(min) .. floor(max) of its vertices'
 * fractional rows, columns likewise about the ring's mean column. */
static void weld_footprint(const sy_stems *st, size_t c, const sy_lod_params *lp, const sy_mesh *m,
                           const size_t *vo, int32_t *pidx, weld_rect *w)
{
    const sy_stem *s = &st->s[c], *ps = &st->s[s->parent];
    int P = sy_stem_radial(ps, lp), Pc = sy_stem_radial(s, lp);
    size_t np = sy_stem_rings(ps, lp, pidx);
    const float *ring = m->position + 3 * vo[c];
    float rows[WELD_MAX_RING], cols[WELD_MAX_RING], sx, R;
    int inside = 1;
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
        rmin = fminf(rmin, rows[v]), rmax = fmaxf(rmax, rows[v]);
        cmin = fminf(cmin, u), cmax = fmaxf(cmax, u);
    }
    w->stem = (int32_t)c;
    w->jc = 0;
    w->q0 = inside ? (long)floorf(rmin) : 0;
    w->q1 = inside ? (long)floorf(rmax) : 0;
    w->c0 = (int)floorf(cmin), w->c1 = (int)floorf(cmax);
    if (w->q1 > (long)np - 2) w->q1 = (long)np - 2;
    w->ok = inside && Pc <= WELD_MAX_RING && w->c1 - w->c0 + 1 <= P - 1 &&
            2 * ((size_t)(w->q1 - w->q0 + 1) + (size_t)(w->c1 - w->c0 + 1)) <= WELD_MAX_LOOP;
}

/* First triangle of parent quad (r, j) (unwrapped column j about jc). */
static size_t quad_tri(const size_t *io, size_t p, int P, long r, int j, int jc)
{
    return io[p] / 3 + 2 * ((size_t)r * (size_t)P + (size_t)(((j + jc) % P + P) % P));
}

/* Angle of (u, s) about (u0, s0) in [0, 2 pi). */
static float param_angle(float u, float sv, float u0, float s0)
{
    float a = atan2f(sv - s0, u - u0);
    return a < 0 ? a + 2 * SY_PI : a;
}

/* Unwraps n angles from index start on; 0 unless they climb once around. */
static int climb_once(const float *ang, size_t n, size_t start, float *un)
{
    un[0] = ang[start];
    for (size_t i = 1; i <= n; i++) {
        float d = ang[(start + i) % n] - ang[(start + i - 1) % n];
        while (d > SY_PI) d -= 2 * SY_PI;
        while (d <= -SY_PI) d += 2 * SY_PI;
        if (d < 0) return 0;
        un[i] = un[i - 1] + d;
    }
    return fabsf(un[n] - un[0] - 2 * SY_PI) < 0.1f;
}

/* Welds child w->stem into its parent: marks the parent's quads in cut (per
 * triangle) and writes the strip to extra (3 indices per triangle).
 * Returns the strip's triangles, 0 when either loop does not turn once
 * about the ring's centre in the parent's (around, along) parameter plane
 * (then nothing is cut). */
static size_t weld_one(const sy_stems *st, const weld_rect *w, const sy_lod_params *lp, const sy_mesh *m,
                       const size_t *vo, const size_t *io, uint8_t *cut, uint32_t *extra, int32_t *pidx)
{
    const sy_stem *s = &st->s[w->stem];
    size_t p = (size_t)s->parent;
    const sy_stem *ps = &st->s[p];
    int P = sy_stem_radial(ps, lp), Pc = sy_stem_radial(s, lp);
    size_t row = (size_t)P + 1, np = sy_stem_rings(ps, lp, pidx);
    /* The hole's boundary, oriented like the removed quads (counter-clockwise
     * seen from outside): along row q0, up column c1 + 1, back along row
     * q1 + 1, down column c0. (u, s): around in metres, along. */
    uint32_t loop[WELD_MAX_LOOP];
    float lu[WELD_MAX_LOOP], ls[WELD_MAX_LOOP];
    size_t n = 0;
    float c0[3], T0[3], N0[3], R;
    sy_stem_frame_at(ps, pidx, np, s->attach_s, c0, T0, N0, &R);
    float arc = 2 * SY_PI * R / (float)P;
#define PUSH(r, j)                                                                                        \
    do {                                                                                                  \
        loop[n] = (uint32_t)(vo[p] + (size_t)(r) * row + (size_t)((((j) + w->jc) % P + P) % P));          \
        lu[n] = (float)(j) * arc, ls[n] = ps->ss[pidx[r]], n++;                                           \
    } while (0)
    for (int j = w->c0; j < w->c1 + 1; j++) PUSH(w->q0, j);
    for (long r = w->q0; r < w->q1 + 1; r++) PUSH(r, w->c1 + 1);
    for (int j = w->c1 + 1; j > w->c0; j--) PUSH(w->q1 + 1, j);
    for (long r = w->q1 + 1; r > w->q0; r--) PUSH(r, w->c0);
#undef PUSH
    /* The ring in the same plane, columns unwrapped next to the hole's. */
    float iu[WELD_MAX_RING], is[WELD_MAX_RING], u0 = 0, s0 = 0, ref = 0.5f * (float)(w->c0 + w->c1 + 1);
    const float *ring = m->position + 3 * vo[w->stem];
    for (int k = 0; k < Pc; k++) {
        float rw, cl, sx, Rx;
        grid_coords(ps, pidx, np, P, ring + 3 * k, s->attach_s, &sx, &rw, &cl, &Rx);
        iu[k] = unwrap_col(cl, ref, P) * arc, is[k] = sx;
        u0 += iu[k] / (float)Pc, s0 += is[k] / (float)Pc;
    }
    float ao[WELD_MAX_LOOP], uo[WELD_MAX_LOOP + 1], ai[WELD_MAX_RING], ui[WELD_MAX_RING + 1];
    size_t so = 0, si = 0;
    for (size_t i = 0; i < n; i++) {
        ao[i] = param_angle(lu[i], ls[i], u0, s0);
        if (ao[i] < ao[so]) so = i;
    }
    for (int k = 0; k < Pc; k++) {
        ai[k] = param_angle(iu[k], is[k], u0, s0);
        if (ai[k] < ai[si]) si = (size_t)k;
    }
    if (!climb_once(ao, n, so, uo) || !climb_once(ai, (size_t)Pc, si, ui)) return 0;
    /* Zip: state (outer i, inner k); advance whichever comes next by angle.
     * Outer edges keep the removed quads' direction, ring edges run against
     * the child tube's, so the strip is oriented with both. The ring's
     * vertex Pc is its seam copy of vertex 0. */
    uint32_t r0 = (uint32_t)vo[w->stem];
    size_t i = 0, k = 0, t = 0;
    while (i < n || k < (size_t)Pc) {
        float next_outer = i < n ? uo[i + 1] : INFINITY, next_inner = k < (size_t)Pc ? ui[k + 1] : INFINITY;
        uint32_t o = loop[(so + i) % n];
        size_t kk = (si + k) % (size_t)Pc, k1 = si + k + 1 == (size_t)Pc ? (size_t)Pc : (si + k + 1) % (size_t)Pc;
        if (next_outer <= next_inner) {
            extra[t++] = o, extra[t++] = loop[(so + i + 1) % n], extra[t++] = r0 + (uint32_t)kk;
            i++;
        } else {
            extra[t++] = o, extra[t++] = r0 + (uint32_t)k1, extra[t++] = r0 + (uint32_t)kk;
            k++;
        }
    }
    /* No folds: every strip triangle faces the way the parent's surface does
     * at its outer corner (the first of its three). */
    for (size_t f = 0; f < t; f += 3) {
        const float *a = m->position + 3 * extra[f], *b = m->position + 3 * extra[f + 1];
        const float *c = m->position + 3 * extra[f + 2];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]}, g[3];
        sy_cross3(e1, e2, g);
        if (!(sy_dot3(g, m->normal + 3 * extra[f]) > 0)) return 0;
    }
    for (long r = w->q0; r <= w->q1; r++)
        for (int j = w->c0; j <= w->c1; j++) {
            size_t q = quad_tri(io, p, P, r, j, w->jc);
            cut[q] = cut[q + 1] = 1;
        }
    return t / 3;
}

/* Welds every junction of the level whose hole overlaps no other
 * junction's (thicker children first), then rewrites out's index buffer:
 * the parents' cut quads out, the strips in. */
static sy_code weld_junctions(const sy_stems *st, const sy_lod_params *lp, const size_t *vo, const size_t *io,
                              int32_t *idx, sy_mesh *out, sy_error *err)
{
    size_t nj = 0, nt = out->n_indices / 3;
    for (size_t i = 0; i < st->n; i++)
        nj += st->s[i].junction && lp->keep[i] && st->s[i].has_geometry && (i + 1 == st->n || vo[i + 1] > vo[i]);
    if (nj == 0) return SY_OK;
    weld_job *jobs = malloc(nj * sizeof *jobs);
    weld_rect *rect = malloc(nj * sizeof *rect);
    uint8_t *cut = calloc(nt + 1, 1), *claim = calloc(nt + 1, 1);
    uint32_t *extra = malloc(3 * (WELD_MAX_LOOP + WELD_MAX_RING + 4) * sizeof *extra), *strips = NULL;
    size_t n_strips = 0, cap_strips = 0;
    sy_code rc = SY_OK;
    if (!jobs || !rect || !cut || !claim || !extra) {
        rc = sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
        goto done;
    }
    nj = 0;
    for (size_t i = 0; i < st->n; i++) {
        const sy_stem *s = &st->s[i];
        if (s->junction && lp->keep[i] && s->has_geometry && (i + 1 == st->n || vo[i + 1] > vo[i]))
            jobs[nj++] = (weld_job){(int32_t)i, s->r_base};
    }
    qsort(jobs, nj, sizeof *jobs, cmp_weld);
    /* Every footprint claims its quads; a hole is cut only where no other
     * junction's ring stands (else that ring would float over the hole). */
    for (size_t j = 0; j < nj; j++) {
        weld_footprint(st, (size_t)jobs[j].stem, lp, out, vo, idx, &rect[j]);
        const weld_rect *w = &rect[j];
        size_t p = (size_t)st->s[w->stem].parent;
        int P = sy_stem_radial(&st->s[p], lp);
        for (long r = w->q0; r <= w->q1; r++)
            for (int c = w->c0; c <= w->c1 && c - w->c0 < P; c++) {
                size_t t = quad_tri(io, p, P, r, c, w->jc);
                if (claim[t] < 255) claim[t]++;
            }
    }
    for (size_t j = 0; j < nj; j++) {
        const weld_rect *w = &rect[j];
        if (!w->ok) continue;
        size_t p = (size_t)st->s[w->stem].parent;
        int P = sy_stem_radial(&st->s[p], lp), alone = 1;
        for (long r = w->q0; r <= w->q1 && alone; r++)
            for (int c = w->c0; c <= w->c1; c++) alone &= claim[quad_tri(io, p, P, r, c, w->jc)] == 1;
        if (!alone) continue;
        size_t t = weld_one(st, w, lp, out, vo, io, cut, extra, idx);
        if (!t) continue;
        if (n_strips + 3 * t > cap_strips) {
            size_t nc = cap_strips ? 2 * cap_strips : 3 * 4096;
            while (nc < n_strips + 3 * t) nc *= 2;
            uint32_t *g = realloc(strips, nc * sizeof *g);
            if (!g) {
                rc = sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
                goto done;
            }
            strips = g, cap_strips = nc;
        }
        memcpy(strips + n_strips, extra, 3 * t * sizeof *extra);
        n_strips += 3 * t;
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
done:
    free(jobs), free(rect), free(cut), free(claim), free(extra), free(strips);
    return rc;
}

sy_code sy_bark_mesh(const sy_stems *st, const sy_lod_params *lp, int material, sy_mesh *out, sy_error *err)
{
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
    sy_code rc = weld_junctions(st, lp, vo, io, idx, out, err);
    free(vo), free(io), free(idx);
    if (rc != SY_OK) sy_mesh_free(out);
    return rc;
}
