/* Edge flips that remove the few near-degenerate triangles the tubes and
 * junction strips leave (three nearly collinear corners where a strip meets
 * a ring edge, a needle at a thin twig's junction): under 0.005 mm^2 they
 * cannot be seen, but they break tangent frames and count as defects in a
 * close look (issue 19). A flip keeps the bark closed and consistently
 * oriented, and it moves no vertex, so normals, UVs and wind stay as built;
 * it only reconnects the four corners of the two triangles beside an edge. */
#include <math.h>
#include <string.h>

#include "mesh_internal.h"
#include "stages/core/vec3.h"

static const float *corner(const sy_mesh *m, size_t t, int c) { return m->position + 3 * m->indices[3 * t + c]; }

/* (b - a) x (c - a) in double: twice the area, along the face's normal. */
static void tri_cross(const float *a, const float *b, const float *c, double n[3])
{
    double e1[3], e2[3];
    for (int k = 0; k < 3; k++) e1[k] = (double)b[k] - a[k], e2[k] = (double)c[k] - a[k];
    sy_v3_cross(n, e1, e2);
}

double sy_tri_area(const float *a, const float *b, const float *c)
{
    double n[3];
    tri_cross(a, b, c, n);
    return 0.5 * sy_v3_len(n);
}

static double tri_area(const sy_mesh *m, size_t t) { return sy_tri_area(corner(m, t, 0), corner(m, t, 1), corner(m, t, 2)); }

static int same_pos(const sy_mesh *m, uint32_t i, uint32_t j)
{
    return i == j || memcmp(m->position + 3 * (size_t)i, m->position + 3 * (size_t)j, 3 * sizeof(float)) == 0;
}

static int near(const float *x, const float *y, int n, float tol)
{
    for (int k = 0; k < n; k++)
        if (!(fabsf(x[k] - y[k]) <= tol)) return 0;
    return 1;
}

/* Two copies that differ in nothing a renderer would show (a junction
 * strip's copies of its parent's ring vertices, their v a rounding apart):
 * an edge between them is no seam. */
static int same_vertex(const sy_mesh *m, uint32_t i, uint32_t j)
{
    size_t a = i, b = j;
    return i == j ||
           (same_pos(m, i, j) && (!m->normal || near(m->normal + 3 * a, m->normal + 3 * b, 3, 1e-5f)) &&
            (!m->uv || near(m->uv + 2 * a, m->uv + 2 * b, 2, 1e-5f)) &&
            (!m->tangent || near(m->tangent + 4 * a, m->tangent + 4 * b, 4, 1e-4f)) &&
            (!m->wind_w || near(m->wind_w + 4 * a, m->wind_w + 4 * b, 4, 1e-5f)) &&
            (!m->wind_branch || m->wind_branch[a] == m->wind_branch[b]));
}

/* Twice the signed area of triangle (i, j, k) on the texture. */
static double uv_area(const sy_mesh *m, uint32_t i, uint32_t j, uint32_t k)
{
    const float *a = m->uv + 2 * (size_t)i, *b = m->uv + 2 * (size_t)j, *c = m->uv + 2 * (size_t)k;
    return ((double)b[0] - a[0]) * ((double)c[1] - a[1]) - ((double)b[1] - a[1]) * ((double)c[0] - a[0]);
}

/* Whether some triangle has an edge between the positions of i and j. */
static int has_edge(const sy_mesh *m, uint32_t i, uint32_t j)
{
    for (size_t t = 0; t < m->n_indices / 3; t++)
        for (int c = 0; c < 3; c++) {
            uint32_t u = m->indices[3 * t + c], w = m->indices[3 * t + (c + 1) % 3];
            if ((same_pos(m, u, i) && same_pos(m, w, j)) || (same_pos(m, u, j) && same_pos(m, w, i))) return 1;
        }
    return 0;
}

/* Flips one edge of triangle t (a, b, c), longest first, with the triangle
 * (b, a, d) across it into (c, a, d) and (d, b, c), when both new triangles
 * face the way the pair did and the smaller of them reaches min_area.
 * Only edges whose two triangles share their corners, or copies of them
 * alike in every attribute (no UV seam along the edge), are flipped; each
 * new triangle keeps its own side's copy. Returns whether it flipped. */
static int flip_one(sy_mesh *m, size_t t, double min_area)
{
    size_t nt = m->n_indices / 3;
    uint32_t *T = m->indices + 3 * t;
    int order[3] = {0, 1, 2};
    double len[3];
    for (int c = 0; c < 3; c++) {
        const float *p = corner(m, t, c), *q = corner(m, t, (c + 1) % 3);
        double e[3] = {(double)q[0] - p[0], (double)q[1] - p[1], (double)q[2] - p[2]};
        len[c] = sy_v3_len(e);
    }
    for (int i = 1; i < 3; i++)
        for (int j = i; j > 0 && len[order[j]] > len[order[j - 1]]; j--) {
            int s = order[j];
            order[j] = order[j - 1], order[j - 1] = s;
        }
    for (int k = 0; k < 3; k++) {
        int e = order[k];
        uint32_t a = T[e], b = T[(e + 1) % 3], c = T[(e + 2) % 3];
        for (size_t u = 0; u < nt; u++) {
            if (u == t) continue;
            uint32_t *U = m->indices + 3 * u;
            int f = -1;
            for (int cc = 0; cc < 3; cc++)
                if (same_vertex(m, U[cc], b) && same_vertex(m, U[(cc + 1) % 3], a)) f = cc;
            if (f < 0) continue;
            uint32_t d = U[(f + 2) % 3];
            if (same_pos(m, c, d) || has_edge(m, c, d)) break; /* would fold or double an edge: the next edge */
            double n1[3], n2[3], o1[3], o2[3], N[3];
            const float *pa = m->position + 3 * (size_t)a, *pb = m->position + 3 * (size_t)b,
                        *pc = m->position + 3 * (size_t)c, *pd = m->position + 3 * (size_t)d;
            tri_cross(pa, pb, pc, o1);
            tri_cross(pb, pa, pd, o2);
            tri_cross(pc, pa, pd, n1);
            tri_cross(pd, pb, pc, n2);
            for (int q = 0; q < 3; q++) N[q] = o1[q] + o2[q];
            double d1 = sy_v3_dot(n1, N), d2 = sy_v3_dot(n2, N), a1 = 0.5 * sy_v3_len(n1), a2 = 0.5 * sy_v3_len(n2);
            if (d1 <= 0 || d2 <= 0 || fmin(a1, a2) < min_area) break; /* try the next edge */
            /* Nor may a new triangle map mirrored onto the texture. */
            if (m->uv && (uv_area(m, c, a, d) < 0 || uv_area(m, d, b, c) < 0)) break;
            T[0] = c, T[1] = a, T[2] = d;
            U[0] = d, U[1] = b, U[2] = c;
            return 1;
        }
    }
    return 0;
}

/* Whether triangle t may be under min_area: a float test that passes every
 * triangle well above it (all but a handful), so only those pay for the
 * double-precision area (a decode's LOD0 has 56k triangles). */
static int maybe_small(const sy_mesh *m, size_t t, float min_area)
{
    const float *a = corner(m, t, 0), *b = corner(m, t, 1), *c = corner(m, t, 2);
    float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]}, n[3];
    sy_cross3(e1, e2, n);
    return sy_dot3(n, n) < 64 * min_area * min_area; /* |n| = 2 area: under 4x min_area */
}

size_t sy_mesh_flip_degenerates(sy_mesh *m, double min_area)
{
    size_t flips = 0, nt = m->n_indices / 3;
    /* A flip can leave its neighbour degenerate in turn: a few passes. */
    for (int pass = 0; pass < 4; pass++) {
        size_t before = flips;
        for (size_t t = 0; t < nt; t++)
            if (maybe_small(m, t, (float)min_area) && tri_area(m, t) < min_area)
                flips += (size_t)flip_one(m, t, min_area);
        if (flips == before) break;
    }
    return flips;
}
