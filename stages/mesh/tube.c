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
    free(vo), free(io), free(idx);
    return SY_OK;
}
