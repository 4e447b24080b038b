/* Clusters: the low-confidence cut of the skeleton and the hull of each
 * cluster (alpha shape -> coarse closed mesh), with the mesh checks that make
 * every hull closed, outward and holding its points. */
#include "clusters.h"
#include "stages/core/parallel.h"
#include "stages/core/progress.h"

#include <math.h>
#include <meshoptimizer.h>
#include <stdlib.h>
#include <string.h>

#include "alpha_shape_cgal.h"
#include "stages/core/geometry.h"
#include "stages/core/voxel.h"

void sy_clusters_free(sy_clusters *c)
{
    if (!c) return;
    for (size_t i = 0; i < c->n; i++) {
        free(c->items[i].points);
        free(c->items[i].verts);
        free(c->items[i].tris);
        free(c->items[i].occupancy);
        sy_cluster_twigs_free(&c->items[i]);
    }
    free(c->items);
    memset(c, 0, sizeof *c);
}

/* ---- Low-confidence rule and the cut ---- */

/* Distance of p from the segment a-b, or with ray != 0 from the ray that
 * starts at a and runs through b. */
static double line_dist(const float a[3], const float b[3], const float p[3], int ray)
{
    double ab[3], ap[3], t = 0, L = 0;
    for (int k = 0; k < 3; k++) {
        ab[k] = (double)b[k] - a[k];
        ap[k] = (double)p[k] - a[k];
        t += ab[k] * ap[k];
        L += ab[k] * ab[k];
    }
    t = L > 0 ? fmax(0, t / L) : 0;
    if (!ray) t = fmin(1, t);
    double d2 = 0;
    for (int k = 0; k < 3; k++) {
        double d = ap[k] - t * ab[k];
        d2 += d * d;
    }
    return sqrt(d2);
}

int sy_edge_low_confidence(const float parent[3], const float child[3], int around, const float *next, size_t n_next,
                           const float *xyz, const uint32_t *points, size_t n_points, double diameter, double fs)
{
    if (n_points == 0) return 0;
    double sum = 0;
    for (size_t i = 0; i < n_points; i++) {
        const float *P = xyz + 3 * (size_t)points[i];
        double d = line_dist(parent, child, P, around && n_next == 0);
        for (size_t c = 0; around && c < n_next; c++) d = fmin(d, line_dist(child, next + 3 * c, P, 0));
        sum += d;
    }
    return sum / (double)n_points > fs * diameter;
}

sy_code sy_clusters_cut(const sy_skeleton *s, const float *xyz, const float *measured, int around, double fs, int min_points,
                        int32_t *cluster_of, int32_t *seed_of, size_t *n_clusters, sy_error *err)
{
    size_t n = s->n;
    *n_clusters = 0;
    if (!s->support_start) return sy_fail(err, SY_EINTERNAL, "clusters: skeleton has no support");
    for (size_t i = 1; i < n; i++)
        if (s->parent[i] < 0 || s->parent[i] >= (int32_t)i)
            return sy_fail(err, SY_EINTERNAL, "clusters: skeleton is not in breadth-first order");
    /* group[i]: the seed node whose low-confidence group i belongs to, or -1. */
    int32_t *group = sy_calloc(n ? n : 1, sizeof *group, err, "clusters");
    size_t *pts = sy_calloc(n ? n : 1, sizeof *pts, err, "clusters");
    int32_t *first_child = sy_calloc(n ? n : 1, sizeof *first_child, err, "clusters");
    int32_t *next_sibling = sy_calloc(n ? n : 1, sizeof *next_sibling, err, "clusters");
    float *next = sy_calloc(n ? n : 1, 3 * sizeof *next, err, "clusters"); /* a node's children's positions */
    if (!group || !pts || !first_child || !next_sibling || !next) {
        free(group);
        free(pts);
        free(first_child);
        free(next_sibling);
        free(next);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < n; i++) group[i] = -1;
    sy_skeleton_children(s, first_child, next_sibling);
    for (size_t i = 1; i < n; i++) {
        int32_t p = s->parent[i];
        if (group[p] >= 0) {
            group[i] = group[p];
            continue;
        }
        /* A ring of returns around the axis is a branch the scan resolved. */
        if (measured && measured[i] > 0) continue;
        const uint32_t *sp = s->support + s->support_start[i];
        size_t cnt = s->support_start[i + 1] - s->support_start[i];
        size_t nk = 0;
        for (int32_t c = first_child[i]; c >= 0; c = next_sibling[c], nk++)
            memcpy(next + 3 * nk, s->pos + 3 * (size_t)c, 3 * sizeof *next);
        if (sy_edge_low_confidence(s->pos + 3 * (size_t)p, s->pos + 3 * i, around, next, nk, xyz, sp, cnt,
                                   2.0 * s->radius[i], fs))
            group[i] = p;
    }
    for (size_t i = 0; i < n; i++)
        if (group[i] >= 0) pts[group[i]] += s->support_start[i + 1] - s->support_start[i];
    /* Groups too small for a hull stay on the skeleton, subtrees and all. */
    for (size_t i = 0; i < n; i++)
        if (group[i] >= 0 && pts[group[i]] < (size_t)min_points) group[i] = -1;
    /* Number the clusters by their seed's position in the skeleton. */
    int32_t *index = (int32_t *)pts; /* reuse: seed -> cluster index */
    for (size_t i = 0; i < n; i++) index[i] = -1;
    for (size_t i = 0; i < n; i++) {
        cluster_of[i] = -1;
        if (group[i] < 0) continue;
        int32_t seed = group[i];
        if (index[seed] < 0) {
            index[seed] = (int32_t)*n_clusters;
            seed_of[(*n_clusters)++] = seed;
        }
        cluster_of[i] = index[seed];
    }
    /* index[] was filled in node order, but seeds must be numbered in seed
     * order: renumber so cluster c's seed is the c-th smallest seed. */
    size_t m = *n_clusters;
    for (size_t a = 1; a < m; a++)
        for (size_t b = a; b > 0 && seed_of[b - 1] > seed_of[b]; b--) {
            int32_t t = seed_of[b - 1];
            seed_of[b - 1] = seed_of[b];
            seed_of[b] = t;
        }
    for (size_t c = 0; c < m; c++) index[seed_of[c]] = (int32_t)c;
    for (size_t i = 0; i < n; i++)
        if (group[i] >= 0) cluster_of[i] = index[group[i]];
    free(group);
    free(pts);
    free(first_child);
    free(next_sibling);
    free(next);
    return SY_OK;
}

/* ---- Mesh checks ---- */

typedef struct {
    uint64_t key; /* (min << 32) | max */
    int dir;      /* +1 when traversed min -> max */
} half;

static int cmp_half(const void *a, const void *b)
{
    const half *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return x->dir - y->dir;
}

sy_code sy_mesh_bad_edges(const uint32_t *tris, size_t n_tris, size_t n_verts, size_t *bad_out, sy_error *err)
{
    *bad_out = 1;
    if (n_tris == 0) return SY_OK;
    half *h = sy_calloc(3 * n_tris, sizeof *h, err, "mesh check: half-edges");
    if (!h) return SY_EINTERNAL;
    size_t bad = 0;
    for (size_t t = 0; t < n_tris; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t a = tris[3 * t + k], b = tris[3 * t + (k + 1) % 3];
            if (a >= n_verts || b >= n_verts || a == b) bad++;
            h[3 * t + k].key = a < b ? ((uint64_t)a << 32) | b : ((uint64_t)b << 32) | a;
            h[3 * t + k].dir = a < b ? 1 : -1;
        }
    qsort(h, 3 * n_tris, sizeof *h, cmp_half);
    for (size_t i = 0; i < 3 * n_tris;) {
        size_t j = i;
        while (j < 3 * n_tris && h[j].key == h[i].key) j++;
        /* Exactly one traversal each way. */
        if (j - i != 2 || h[i].dir == h[i + 1].dir) bad++;
        i = j;
    }
    free(h);
    *bad_out = bad;
    return SY_OK;
}

double sy_mesh_signed_volume(const float *v, const uint32_t *tris, size_t n_tris)
{
    double vol = 0;
    for (size_t t = 0; t < n_tris; t++) {
        const float *a = v + 3 * (size_t)tris[3 * t], *b = v + 3 * (size_t)tris[3 * t + 1],
                    *c = v + 3 * (size_t)tris[3 * t + 2];
        vol += (double)a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]) -
               (double)a[1] * ((double)b[0] * c[2] - (double)b[2] * c[0]) +
               (double)a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
    }
    return vol / 6.0;
}

/* Squared distance from p to triangle abc (the closest point of
 * stages/core/geometry.h, squared here to compare with tol^2). */
static double point_tri_dist2(const double p[3], const double a[3], const double b[3], const double c[3])
{
    double q[3];
    sy_point_triangle_distance(p, a, b, c, q);
    double d = 0;
    for (int k = 0; k < 3; k++) d += (p[k] - q[k]) * (p[k] - q[k]);
    return d;
}

/* Inside test by the generalised winding number (sum of signed solid angles,
 * van Oosterom & Strackee), which is exact for closed meshes and robust to
 * rays grazing edges. */
static int inside_mesh(const float *v, const uint32_t *tris, size_t n_tris, const double p[3])
{
    double total = 0;
    for (size_t t = 0; t < n_tris; t++) {
        double a[3], b[3], c[3];
        for (int k = 0; k < 3; k++) {
            a[k] = v[3 * (size_t)tris[3 * t] + k] - p[k];
            b[k] = v[3 * (size_t)tris[3 * t + 1] + k] - p[k];
            c[k] = v[3 * (size_t)tris[3 * t + 2] + k] - p[k];
        }
        double la = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
        double lb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
        double lc = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        double det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                     a[2] * (b[0] * c[1] - b[1] * c[0]);
        double den = la * lb * lc + (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) * lc +
                     (b[0] * c[0] + b[1] * c[1] + b[2] * c[2]) * la + (c[0] * a[0] + c[1] * a[1] + c[2] * a[2]) * lb;
        total += 2 * atan2(det, den);
    }
    return total > 2 * 3.14159265358979323846; /* winding number > 1/2 */
}

static int near_mesh(const float *v, const uint32_t *tris, size_t n_tris, const double p[3], double tol)
{
    double t2 = tol * tol;
    for (size_t t = 0; t < n_tris; t++) {
        double a[3], b[3], c[3];
        for (int k = 0; k < 3; k++) {
            a[k] = v[3 * (size_t)tris[3 * t] + k];
            b[k] = v[3 * (size_t)tris[3 * t + 1] + k];
            c[k] = v[3 * (size_t)tris[3 * t + 2] + k];
        }
        if (point_tri_dist2(p, a, b, c) <= t2) return 1;
    }
    return 0;
}

/* Containment over every stride-th point (stride 1 checks all). */
static double containment_strided(const float *verts, const uint32_t *tris, size_t n_tris, const float *xyz,
                                  const uint32_t *points, size_t n_points, double tol, size_t stride)
{
    if (n_points == 0) return 1;
    size_t in = 0, tested = 0;
    for (size_t i = 0; i < n_points; i += stride) {
        const float *q = xyz + 3 * (size_t)points[i];
        double p[3] = {q[0], q[1], q[2]};
        tested++;
        if (inside_mesh(verts, tris, n_tris, p) || near_mesh(verts, tris, n_tris, p, tol)) in++;
    }
    return (double)in / (double)tested;
}

double sy_mesh_containment(const float *verts, const uint32_t *tris, size_t n_tris, const float *xyz,
                           const uint32_t *points, size_t n_points, double tol)
{
    return containment_strided(verts, tris, n_tris, xyz, points, n_points, tol, 1);
}

/* ---- Hulls ---- */

/* How many points the hull builder hands to CGAL, and how many it checks
 * containment against: enough for a coarse hull, cheap on million-point trees. */
#define HULL_MAX_POINTS 3000
#define CHECK_MAX_POINTS 1500

typedef struct {
    uint64_t key;
    float d2;
    uint32_t idx;
} vox;

static int cmp_vox(const void *a, const void *b)
{
    const vox *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    if (x->d2 != y->d2) return x->d2 > y->d2 ? -1 : 1; /* farthest first */
    return x->idx < y->idx ? -1 : x->idx > y->idx;
}

/* Thins the points to at most about max per voxel grid, keeping in each
 * voxel the point farthest from the centroid so the outline survives. Writes
 * positions to out (3 floats each) and returns the count. */
static size_t thin_points(const float *xyz, const uint32_t *pts, size_t n, size_t max, float *out)
{
    if (n <= max) {
        for (size_t i = 0; i < n; i++) memcpy(out + 3 * i, xyz + 3 * (size_t)pts[i], 3 * sizeof(float));
        return n;
    }
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY}, c[3] = {0, 0, 0};
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            double v = xyz[3 * (size_t)pts[i] + k];
            lo[k] = fmin(lo[k], v);
            hi[k] = fmax(hi[k], v);
            c[k] += v / (double)n;
        }
    vox *v = malloc(n * sizeof *v);
    if (!v) {
        /* Out of memory: an even stride keeps the hull usable. */
        size_t m = 0;
        for (size_t i = 0; i < n && m < max; i += (n + max - 1) / max, m++)
            memcpy(out + 3 * m, xyz + 3 * (size_t)pts[i], 3 * sizeof(float));
        return m;
    }
    double ext = fmax(fmax(hi[0] - lo[0], hi[1] - lo[1]), fmax(hi[2] - lo[2], 1e-6));
    /* Start at a voxel giving roughly max surface cells, grow until it fits. */
    double h = ext / sqrt((double)max);
    size_t m = n;
    for (int tries = 0; tries < 30 && m > max; tries++, h *= 1.25) {
        for (size_t i = 0; i < n; i++) {
            const float *p = xyz + 3 * (size_t)pts[i];
            double pd[3] = {p[0], p[1], p[2]};
            float d2 = 0;
            for (int k = 0; k < 3; k++) d2 += (float)((p[k] - c[k]) * (p[k] - c[k]));
            v[i].key = sy_voxel_key_d(pd, lo, h);
            v[i].d2 = d2;
            v[i].idx = pts[i];
        }
        qsort(v, n, sizeof *v, cmp_vox);
        m = 0;
        for (size_t i = 0; i < n; i++)
            if (i == 0 || v[i].key != v[i - 1].key) m++;
    }
    size_t w = 0;
    for (size_t i = 0; i < n && w < max; i++)
        if (i == 0 || v[i].key != v[i - 1].key) memcpy(out + 3 * w++, xyz + 3 * (size_t)v[i].idx, 3 * sizeof(float));
    free(v);
    return w;
}

/* Drops unreferenced vertices and renumbers in first-use order. */
static int compact_mesh(float **verts, size_t *nv, uint32_t *tris, size_t nt)
{
    uint32_t *map = malloc((*nv ? *nv : 1) * sizeof *map);
    float *nvts = malloc((*nv ? *nv : 1) * 3 * sizeof *nvts);
    if (!map || !nvts) {
        free(map);
        free(nvts);
        return -1;
    }
    for (size_t i = 0; i < *nv; i++) map[i] = UINT32_MAX;
    size_t m = 0;
    for (size_t i = 0; i < 3 * nt; i++) {
        uint32_t v = tris[i];
        if (map[v] == UINT32_MAX) {
            map[v] = (uint32_t)m;
            memcpy(nvts + 3 * m, *verts + 3 * (size_t)v, 3 * sizeof(float));
            m++;
        }
        tris[i] = map[v];
    }
    free(map);
    free(*verts);
    *verts = nvts;
    *nv = m;
    return 0;
}

/* Out of memory counts as not closed: the caller tries the next hull. */
static int closed_outward(const float *verts, size_t nv, const uint32_t *tris, size_t nt)
{
    size_t bad;
    sy_error err;
    return nt >= 4 && sy_mesh_bad_edges(tris, nt, nv, &bad, &err) == SY_OK && bad == 0 &&
           sy_mesh_signed_volume(verts, tris, nt) > 0;
}

static int holds_points(const float *verts, const uint32_t *tris, size_t nt, const float *xyz, const uint32_t *pts,
                        size_t np, double tol)
{
    size_t stride = np > CHECK_MAX_POINTS ? (np + CHECK_MAX_POINTS - 1) / CHECK_MAX_POINTS : 1;
    return containment_strided(verts, tris, nt, xyz, pts, np, tol, stride) >= 0.95;
}

/* A coarse hull keeps a subset of the alpha shape's vertices, so it sits
 * inside the shape and cuts off the outermost points. Push every vertex out
 * along its normal, doubling the offset from 0 until the hull holds 95% of
 * the points; gives up beyond a tenth of the hull's size. On success verts
 * holds the moved positions. */
static int inflate_to_hold(float *verts, size_t nv, const uint32_t *tris, size_t nt, const float *xyz,
                           const uint32_t *pts, size_t np, double tol)
{
    float *base = malloc(nv * 3 * sizeof *base), *nrm = calloc(nv * 3, sizeof *nrm);
    int ok = 0;
    if (!base || !nrm) goto done;
    memcpy(base, verts, nv * 3 * sizeof *base);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < nv; v++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], verts[3 * v + k]);
            hi[k] = fmax(hi[k], verts[3 * v + k]);
        }
    double size = sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                       (hi[2] - lo[2]) * (hi[2] - lo[2]));
    for (size_t t = 0; t < nt; t++) {
        const float *a = verts + 3 * (size_t)tris[3 * t], *b = verts + 3 * (size_t)tris[3 * t + 1],
                    *c = verts + 3 * (size_t)tris[3 * t + 2];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; k++)
            for (int m = 0; m < 3; m++) nrm[3 * (size_t)tris[3 * t + k] + m] += n[m]; /* area weighted */
    }
    for (size_t v = 0; v < nv; v++) {
        double l = sqrt(nrm[3 * v] * nrm[3 * v] + nrm[3 * v + 1] * nrm[3 * v + 1] + nrm[3 * v + 2] * nrm[3 * v + 2]);
        for (int k = 0; k < 3; k++) nrm[3 * v + k] = l > 0 ? (float)(nrm[3 * v + k] / l) : 0;
    }
    for (double d = 0; d <= 0.1 * size; d = d > 0 ? 2 * d : tol) {
        for (size_t v = 0; v < 3 * nv; v++) verts[v] = base[v] + (float)d * nrm[v];
        if (closed_outward(verts, nv, tris, nt) && holds_points(verts, tris, nt, xyz, pts, np, tol)) {
            ok = 1;
            break;
        }
    }
    if (!ok) memcpy(verts, base, nv * 3 * sizeof *base);
done:
    free(base);
    free(nrm);
    return ok;
}

/* Accepts a closed, outward mesh as c's hull (taking ownership): simplified
 * toward target_tris (then 2x and 4x that) and inflated to hold the points;
 * failing that, unsimplified if it is at most 8x the budget (bigger ones
 * would blow the file budget; the convex hull is tried next instead). */
static int try_hull(sy_cluster *c, const float *xyz, sy_alpha_mesh *m, int target_tris, double tol, int kind)
{
    if (!closed_outward(m->verts, m->n_verts, m->tris, m->n_tris)) return 0;
    uint32_t *dst = malloc(3 * m->n_tris * sizeof *dst);
    float *vcopy = malloc(3 * m->n_verts * sizeof *vcopy);
    int ok = 0;
    for (int f = 1; dst && vcopy && f <= 4 && !ok; f *= 2) {
        size_t target = 3 * (size_t)target_tris * (size_t)f;
        if (target >= 3 * m->n_tris) break;
        size_t ni = meshopt_simplify(dst, m->tris, 3 * m->n_tris, m->verts, m->n_verts, 3 * sizeof(float), target,
                                     1.0f, 0, NULL);
        memcpy(vcopy, m->verts, 3 * m->n_verts * sizeof *vcopy);
        if (closed_outward(vcopy, m->n_verts, dst, ni / 3) &&
            inflate_to_hold(vcopy, m->n_verts, dst, ni / 3, xyz, c->points, c->n_points, tol)) {
            memcpy(m->tris, dst, ni * sizeof *dst);
            m->n_tris = ni / 3;
            memcpy(m->verts, vcopy, 3 * m->n_verts * sizeof *vcopy);
            ok = 1;
        }
    }
    free(dst);
    free(vcopy);
    if (!ok && m->n_tris <= 8 * (size_t)target_tris)
        ok = inflate_to_hold(m->verts, m->n_verts, m->tris, m->n_tris, xyz, c->points, c->n_points, tol);
    if (!ok || compact_mesh(&m->verts, &m->n_verts, m->tris, m->n_tris)) return 0;
    c->verts = m->verts;
    c->n_verts = m->n_verts;
    c->tris = m->tris;
    c->n_tris = m->n_tris;
    c->alpha = kind == SY_HULL_ALPHA ? (float)m->alpha : 0;
    c->hull = kind;
    m->verts = NULL;
    m->tris = NULL;
    return 1;
}

/* Principal-axis box around the points, padded by pad on every side. */
static sy_code box_hull(sy_cluster *c, const float *xyz, double pad, sy_error *err)
{
    size_t n = c->n_points;
    double mean[3] = {0, 0, 0}, C[3][3] = {{0}};
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) mean[k] += xyz[3 * (size_t)c->points[i] + k] / (double)n;
    for (size_t i = 0; i < n; i++) {
        double d[3];
        for (int k = 0; k < 3; k++) d[k] = xyz[3 * (size_t)c->points[i] + k] - mean[k];
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) C[a][b] += d[a] * d[b];
    }
    /* The principal axes: eigenvectors of the scatter matrix. */
    double cu[6] = {C[0][0], C[0][1], C[0][2], C[1][1], C[1][2], C[2][2]}, ev[3], v[9], V[3][3];
    sy_sym3_eigen(cu, ev, v);
    for (int k = 0; k < 3; k++)
        for (int a = 0; a < 3; a++) V[k][a] = v[3 * k + a];
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            double t = 0;
            for (int k = 0; k < 3; k++) t += (xyz[3 * (size_t)c->points[i] + k] - mean[k]) * V[k][a];
            lo[a] = fmin(lo[a], t - pad);
            hi[a] = fmax(hi[a], t + pad);
        }
    c->verts = sy_calloc(8, 3 * sizeof(float), err, "hull");
    c->tris = sy_calloc(12, 3 * sizeof(uint32_t), err, "hull");
    if (!c->verts || !c->tris) return SY_EINTERNAL;
    for (int i = 0; i < 8; i++) {
        double t[3] = {(i & 1) ? hi[0] : lo[0], (i & 2) ? hi[1] : lo[1], (i & 4) ? hi[2] : lo[2]};
        for (int k = 0; k < 3; k++)
            c->verts[3 * i + k] = (float)(mean[k] + V[k][0] * t[0] + V[k][1] * t[1] + V[k][2] * t[2]);
    }
    static const uint32_t cube[36] = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                                      2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};
    memcpy(c->tris, cube, sizeof cube);
    c->n_verts = 8;
    c->n_tris = 12;
    /* The eigenvector frame may be left-handed: flip to face outward. */
    if (sy_mesh_signed_volume(c->verts, c->tris, 12) < 0)
        for (int t = 0; t < 12; t++) {
            uint32_t s = c->tris[3 * t + 1];
            c->tris[3 * t + 1] = c->tris[3 * t + 2];
            c->tris[3 * t + 2] = s;
        }
    c->alpha = 0;
    c->hull = SY_HULL_BOX;
    return SY_OK;
}

/* The share of a point's horizontal offset from the stem that its copy on
 * the floor keeps: the crown's profile at the floor over its profile at
 * the point's height z, at most 1 (sy_hull_floor). */
static double floor_keep(const sy_hull_floor *f, double z)
{
    double span = f->top - f->z;
    if (!(span > 0)) return 1;
    double t = (z - f->z) / span * (SY_CROWN_SLABS - 1);
    t = t < 0 ? 0 : t > SY_CROWN_SLABS - 1 ? SY_CROWN_SLABS - 1 : t;
    int k = (int)t;
    if (k >= SY_CROWN_SLABS - 1) k = SY_CROWN_SLABS - 2;
    double at = f->profile[k] + (t - k) * (f->profile[k + 1] - f->profile[k]);
    /* The floor's own width: its two lowest slabs (a crown's lowest slab
     * holds only its few lowest limbs; read alone it drew the airborne
     * poplar and willow as cones, IoU -0.036 and -0.021). */
    double base = 0.5 * (f->profile[0] + f->profile[1]);
    return at > 0 && base < at ? base / at : 1;
}

void sy_crown_roof_free(sy_crown_roof *r)
{
    free(r->top);
    free(r->roof);
    r->top = r->roof = NULL;
}

sy_code sy_crown_roof_build(const float *xyz, size_t n, int cells, double lift, sy_crown_roof *r, sy_error *err)
{
    memset(r, 0, sizeof *r);
    if (!n || cells < 1) return SY_OK;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], xyz[3 * i + k]), hi[k] = fmax(hi[k], xyz[3 * i + k]);
    double cell = fmax(hi[0] - lo[0], hi[1] - lo[1]) / cells;
    if (!(cell > 0)) return SY_OK;
    r->cell = cell, r->x0 = lo[0], r->y0 = lo[1], r->z0 = lo[2], r->height = hi[2] - lo[2];
    r->lift_min = lift * r->height;
    r->nx = (int)floor((hi[0] - lo[0]) / cell) + 1, r->ny = (int)floor((hi[1] - lo[1]) / cell) + 1;
    size_t nc = (size_t)r->nx * (size_t)r->ny;
    r->top = sy_calloc(nc, sizeof *r->top, err, "roof");
    r->roof = sy_calloc(nc, sizeof *r->roof, err, "roof");
    if (!r->top || !r->roof) {
        sy_crown_roof_free(r);
        return SY_EINTERNAL;
    }
    for (size_t c = 0; c < nc; c++) r->top[c] = NAN;
    for (size_t i = 0; i < n; i++) {
        int x = (int)((xyz[3 * i] - r->x0) / cell), y = (int)((xyz[3 * i + 1] - r->y0) / cell);
        x = x < 0 ? 0 : x >= r->nx ? r->nx - 1 : x, y = y < 0 ? 0 : y >= r->ny ? r->ny - 1 : y;
        float *t = &r->top[(size_t)y * r->nx + x];
        if (isnan(*t) || xyz[3 * i + 2] > *t) *t = xyz[3 * i + 2];
    }
    memcpy(r->roof, r->top, nc * sizeof *r->roof);
    /* Midpoint concavity along rows, columns and both diagonals, repeated
     * until it holds: each cell at least the mean of every pair of cells
     * that holds returns symmetric about it. */
    static const int dir[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
    int span = r->nx > r->ny ? r->nx : r->ny;
    for (int pass = 0, changed = 1; changed && pass < 64; pass++) {
        changed = 0;
        for (int y = 0; y < r->ny; y++)
            for (int x = 0; x < r->nx; x++) {
                float *z = &r->roof[(size_t)y * r->nx + x];
                if (isnan(*z)) continue;
                for (int d = 0; d < 4; d++)
                    for (int k = 1; k < span; k++) {
                        int ax = x - k * dir[d][0], ay = y - k * dir[d][1], bx = x + k * dir[d][0], by = y + k * dir[d][1];
                        if (ax < 0 || ax >= r->nx || ay < 0 || ay >= r->ny || bx < 0 || bx >= r->nx || by < 0 ||
                            by >= r->ny)
                            break;
                        float za = r->roof[(size_t)ay * r->nx + ax], zb = r->roof[(size_t)by * r->nx + bx];
                        if (isnan(za) || isnan(zb)) continue;
                        float m = 0.5f * (za + zb);
                        if (m > *z + 1e-4f) *z = m, changed = 1;
                    }
            }
    }
    return SY_OK;
}

double sy_crown_roof_gap(const sy_crown_roof *r)
{
    if (!r->top || !(r->height > 0)) return 0;
    double sum = 0;
    size_t n = 0;
    for (size_t q = 0; q < (size_t)r->nx * (size_t)r->ny; q++)
        if (r->roof[q] > r->z0 + 0.5 * r->height) sum += (r->roof[q] - r->top[q]) / r->height, n++;
    return n ? sum / (double)n : 0;
}

double sy_crown_roof_lift(const sy_crown_roof *r, const float p[3])
{
    if (!r || !r->top) return NAN;
    int cx = (int)floor((p[0] - r->x0) / r->cell), cy = (int)floor((p[1] - r->y0) / r->cell);
    if (cx < 0 || cy < 0 || cx >= r->nx || cy >= r->ny) return NAN;
    size_t q = (size_t)cy * r->nx + cx;
    /* Only a return at its cell's top (within a cell's side): the ones
     * under it are inside the crown, not under its roof. */
    if (!(p[2] >= r->top[q] - r->cell) || !(r->roof[q] - p[2] > r->lift_min)) return NAN;
    return r->roof[q];
}

sy_code sy_cluster_build_hull(sy_cluster *c, const float *xyz, double alpha_scale, int target_tris, double tol,
                              const float *anchor, const sy_hull_floor *base, const sy_crown_roof *roof,
                              int *lifted, sy_error *err)
{
    if (lifted) *lifted = 0;
    free(c->verts);
    free(c->tris);
    c->verts = NULL;
    c->tris = NULL;
    c->n_verts = c->n_tris = 0;
    if (target_tris < 12) target_tris = 12;
    if (c->n_points >= 4) {
        size_t cap = c->n_points < HULL_MAX_POINTS ? c->n_points : HULL_MAX_POINTS;
        float *p = sy_calloc(3 * cap + 1, 3 * sizeof(float), err, "hull");
        if (!p) return SY_EINTERNAL;
        size_t m = thin_points(xyz, c->points, c->n_points, HULL_MAX_POINTS, p);
        if (base && isfinite(base->z)) {
            size_t m0 = m;
            for (size_t i = 0; i < m0; i++)
                if (p[3 * i + 2] > base->z) {
                    double keep = floor_keep(base, p[3 * i + 2]);
                    p[3 * m] = (float)(base->axis[0] + keep * (p[3 * i] - base->axis[0]));
                    p[3 * m + 1] = (float)(base->axis[1] + keep * (p[3 * i + 1] - base->axis[1]));
                    p[3 * m + 2] = (float)base->z;
                    m++;
                }
        }
        if (roof && roof->top) {
            size_t m0 = m;
            for (size_t i = 0; i < m0; i++) {
                double up = sy_crown_roof_lift(roof, p + 3 * i);
                if (isnan(up)) continue;
                p[3 * m] = p[3 * i], p[3 * m + 1] = p[3 * i + 1], p[3 * m + 2] = (float)up;
                m++;
                if (lifted) (*lifted)++;
            }
        }
        if (anchor) memcpy(p + 3 * m++, anchor, 3 * sizeof *p);
        /* The alpha shape first, then the convex hull (infinite alpha). A
         * failure here is not the stage's: the next hull, then the box, fit. */
        double scales[2] = {alpha_scale, 0};
        for (int s = 0; s < 2; s++) {
            sy_alpha_mesh mesh;
            sy_error shape_err;
            sy_code rc = sy_alpha_shape_boundary(p, m, scales[s], &mesh, &shape_err);
            if (rc == SY_EINPUT) break; /* flat or collinear: only the box fits */
            if (rc == SY_OK) {
                int ok = try_hull(c, xyz, &mesh, target_tris, tol, s == 0 ? SY_HULL_ALPHA : SY_HULL_CONVEX);
                sy_alpha_mesh_free(&mesh);
                if (ok) {
                    free(p);
                    return SY_OK;
                }
            }
        }
        free(p);
    }
    return box_hull(c, xyz, fmax(tol, 1e-3), err);
}

sy_hull_options sy_hull_options_default(void)
{
    sy_hull_options o;
    memset(&o, 0, sizeof o);
    o.alpha_scale = 5.0;
    o.triangles = 160;
    o.tol = 0.01;
    o.floor.z = NAN;
    return o;
}

sy_code sy_hull_options_check(const sy_hull_options *o, sy_error *err)
{
    if (!(o->alpha_scale > 0) || !isfinite(o->alpha_scale))
        return sy_fail(err, SY_EUSAGE, "clusters: alpha_scale %g must be > 0", o->alpha_scale);
    if (o->triangles < 12) return sy_fail(err, SY_EUSAGE, "clusters: triangles %d must be >= 12", o->triangles);
    if (!(o->tol >= 0) || !isfinite(o->tol)) return sy_fail(err, SY_EUSAGE, "clusters: tol %g must be >= 0", o->tol);
    return SY_OK;
}

typedef struct {
    sy_clusters *cl;
    const float *xyz;
    const sy_hull_options *o;
    sy_code *rc;
    sy_error *err;
} hull_job;

static void hull_chunk(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    hull_job *J = ctx;
    for (size_t c = begin; c < end; c++) {
        sy_cluster *C = &J->cl->items[c];
        int lifted = 0;
        J->rc[c] = sy_cluster_build_hull(C, J->xyz, J->o->alpha_scale, J->o->triangles, J->o->tol,
                                         J->o->anchors ? J->o->anchors + 3 * c : NULL, &J->o->floor, J->o->roof,
                                         &lifted, &J->err[c]);
        /* What synthesis reads on decode. */
        if (!J->rc[c])
            J->rc[c] = sy_cluster_occupancy(C, J->xyz, 8, J->o->seen_from_above, lifted ? J->o->roof : NULL,
                                            &J->err[c]);
    }
}

sy_code sy_clusters_build_hulls(sy_clusters *cl, const float *xyz, const sy_hull_options *o, sy_hull_report *report,
                                sy_error *err)
{
    sy_hull_report local;
    if (!report) report = &local;
    memset(report, 0, sizeof *report);
    sy_code rc = sy_hull_options_check(o, err);
    if (rc) return rc;
    double t = sy_now();
    /* Clusters are independent: one per task on every thread, each with its
     * own status, reported in cluster order (the first failure wins), so the
     * hulls are the same for any thread count. */
    hull_job J = {cl, xyz, o, sy_calloc(cl->n ? cl->n : 1, sizeof *J.rc, err, "hulls"),
                  sy_calloc(cl->n ? cl->n : 1, sizeof *J.err, err, "hulls")};
    if (!J.rc || !J.err) {
        free(J.rc);
        free(J.err);
        return SY_EINTERNAL;
    }
    sy_parallel_for(cl->n, 1, hull_chunk, &J);
    for (size_t c = 0; c < cl->n; c++) {
        const sy_cluster *C = &cl->items[c];
        if (!rc && J.rc[c]) {
            rc = J.rc[c];
            if (err) *err = J.err[c];
        }
        if (C->hull == SY_HULL_ALPHA) report->alpha++;
        else if (C->hull == SY_HULL_CONVEX) report->convex++;
        else report->box++;
    }
    free(J.rc);
    free(J.err);
    report->seconds = sy_now() - t;
    return rc;
}
