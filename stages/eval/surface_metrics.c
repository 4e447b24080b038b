/* Model vs input points, no truth needed: exact point -> model distances
 * (triangles, truncated cones of skeleton edges; 0 inside closed hulls), and
 * model -> points over samples of the model surface. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "eval.h"
#include "geometry.h"
#include "stages/core/parallel.h"
#include "stages/core/rng.h"
#include "stages/core/array.h"
#include "stages/core/sort.h"

#define PI 3.14159265358979323846

/* Every primitive of a model: triangles first, then cones. */
typedef struct {
    size_t n_tri, n_cone;
    double *tri;        /* 9 n_tri */
    double *cone;       /* 8 per cone: a[3], b[3], ra, rb */
    sy_bvh bvh;
    /* closed hulls: their own index for inside tests */
    size_t n_closed;
    sy_bvh *closed_bvh;
    sy_box *closed_box;
    const double **closed_tri;
} prims;

static void prims_free(prims *P)
{
    free(P->tri);
    free(P->cone);
    sy_bvh_free(&P->bvh);
    for (size_t i = 0; i < P->n_closed; i++) sy_bvh_free(&P->closed_bvh[i]);
    free(P->closed_bvh);
    free(P->closed_box);
    free(P->closed_tri);
    memset(P, 0, sizeof *P);
}

static double prim_distance(const void *ctx, uint32_t i, const double q[3])
{
    const prims *P = ctx;
    if (i < P->n_tri) {
        const double *t = P->tri + 9 * (size_t)i;
        return sy_point_triangle_distance(q, t, t + 3, t + 6, NULL);
    }
    const double *c = P->cone + 8 * ((size_t)i - P->n_tri);
    return sy_point_cone_distance(q, c, c[6], c + 3, c[7]);
}

/* Crossings at s > 0 with half-open edges: callers vote over several rays. */
static int tri_ray(const void *ctx, uint32_t i, const double o[3], const double d[3], double tmax, double *t)
{
    const double *v = (const double *)ctx + 9 * (size_t)i;
    return sy_ray_triangle(o, d, v, v + 3, v + 6, 0, t) && *t > 0 && *t < tmax;
}

static void tri_box(const double *t, sy_box *b)
{
    for (int c = 0; c < 3; c++) {
        b->lo[c] = fmin(t[c], fmin(t[3 + c], t[6 + c]));
        b->hi[c] = fmax(t[c], fmax(t[3 + c], t[6 + c]));
    }
}

static sy_code build_closed(prims *P, const sy_eval_model *m, sy_error *err)
{
    for (size_t i = 0; i < m->n_meshes; i++) P->n_closed += m->meshes[i].closed && m->meshes[i].n;
    if (!P->n_closed) return SY_OK;
    P->closed_bvh = sy_calloc(P->n_closed, sizeof *P->closed_bvh, err, "hulls");
    P->closed_box = sy_calloc(P->n_closed, sizeof *P->closed_box, err, "hulls");
    P->closed_tri = sy_calloc(P->n_closed, sizeof *P->closed_tri, err, "hulls");
    if (!P->closed_bvh || !P->closed_box || !P->closed_tri) return SY_EINTERNAL;
    size_t k = 0;
    for (size_t i = 0; i < m->n_meshes; i++) {
        const sy_tri_mesh *me = &m->meshes[i];
        if (!me->closed || !me->n) continue;
        sy_box *boxes = sy_calloc(me->n, sizeof *boxes, err, "hulls");
        if (!boxes) return SY_EINTERNAL;
        for (size_t t = 0; t < me->n; t++) tri_box(me->tri + 9 * t, &boxes[t]);
        sy_code rc = sy_bvh_build(&P->closed_bvh[k], boxes, me->n, err);
        free(boxes);
        if (rc) return rc;
        sy_bvh_bounds(&P->closed_bvh[k], &P->closed_box[k]);
        P->closed_tri[k] = me->tri;
        k++;
    }
    return SY_OK;
}

static sy_code prims_build(const sy_eval_model *m, prims *P, sy_error *err)
{
    memset(P, 0, sizeof *P);
    for (size_t i = 0; i < m->n_meshes; i++) P->n_tri += m->meshes[i].n;
    for (size_t t = 0; t < m->skeletons.n_trees; t++) {
        const sy_skeleton *s = &m->skeletons.trees[t].skel;
        for (size_t i = 0; i < s->n; i++) P->n_cone += s->parent[i] >= 0;
    }
    size_t n = P->n_tri + P->n_cone;
    if (n >= UINT32_MAX / 2) return sy_fail(err, SY_EINPUT, "model: %zu primitives is too many", n);
    P->tri = sy_calloc(P->n_tri ? 9 * P->n_tri : 1, sizeof(double), err, "model triangles");
    P->cone = sy_calloc(P->n_cone ? 8 * P->n_cone : 1, sizeof(double), err, "model cones");
    sy_box *boxes = sy_calloc(n ? n : 1, sizeof *boxes, err, "model");
    if (!P->tri || !P->cone || !boxes) {
        free(boxes);
        prims_free(P);
        return SY_EINTERNAL;
    }
    size_t k = 0;
    for (size_t i = 0; i < m->n_meshes; i++) {
        memcpy(P->tri + 9 * k, m->meshes[i].tri, 9 * m->meshes[i].n * sizeof(double));
        for (size_t t = 0; t < m->meshes[i].n; t++, k++) tri_box(P->tri + 9 * k, &boxes[k]);
    }
    size_t c = 0;
    for (size_t t = 0; t < m->skeletons.n_trees; t++) {
        const sy_skeleton *s = &m->skeletons.trees[t].skel;
        for (size_t i = 0; i < s->n; i++) {
            int32_t p = s->parent[i];
            if (p < 0) continue;
            double *cn = P->cone + 8 * c;
            for (int a = 0; a < 3; a++) {
                cn[a] = s->origin[a] + s->pos[3 * p + a];
                cn[3 + a] = s->origin[a] + s->pos[3 * i + a];
            }
            cn[6] = s->radius[p];
            cn[7] = s->radius[i];
            double r = fmax(cn[6], cn[7]);
            for (int a = 0; a < 3; a++) {
                boxes[k + c].lo[a] = fmin(cn[a], cn[3 + a]) - r;
                boxes[k + c].hi[a] = fmax(cn[a], cn[3 + a]) + r;
            }
            c++;
        }
    }
    sy_code rc = sy_bvh_build(&P->bvh, boxes, n, err);
    free(boxes);
    if (!rc) rc = build_closed(P, m, err);
    if (rc) prims_free(P);
    return rc;
}

/* Ray parity, voted over three fixed directions chosen off any axis so that
 * grazing an edge or vertex of a mesh on the grid is unlikely for all three. */
static int inside_closed(const prims *P, const double q[3])
{
    static const double dirs[3][3] = {{0.5773, 0.5774, 0.5775},
                                      {-0.2672612, 0.8017837, -0.5345225},
                                      {0.8728716, -0.2182179, -0.4364358}};
    for (size_t h = 0; h < P->n_closed; h++) {
        const sy_box *b = &P->closed_box[h];
        if (q[0] < b->lo[0] || q[0] > b->hi[0] || q[1] < b->lo[1] || q[1] > b->hi[1] || q[2] < b->lo[2] ||
            q[2] > b->hi[2])
            continue;
        int votes = 0;
        for (int r = 0; r < 3; r++) votes += sy_bvh_ray_count(&P->closed_bvh[h], q, dirs[r], tri_ray, P->closed_tri[h]) & 1;
        if (votes >= 2) return 1;
    }
    return 0;
}

typedef struct {
    const prims *P;
    const double *pts;
    double *dist;
} dist_job;

static void dist_chunk(void *arg, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    dist_job *J = arg;
    uint32_t prev = UINT32_MAX; /* scans are spatially coherent in file order */
    for (size_t i = begin; i < end; i++) {
        const double *q = J->pts + 3 * i;
        double d;
        prev = sy_bvh_nearest(&J->P->bvh, q, INFINITY, prim_distance, J->P, prev, &d);
        if (d > 0 && J->P->n_closed && inside_closed(J->P, q)) d = 0;
        J->dist[i] = d;
    }
}

/* The model's primitives, which must hold something to measure against. */
static sy_code prims_to_measure(const sy_eval_model *m, prims *P, sy_error *err)
{
    sy_code rc = prims_build(m, P, err);
    if (rc) return rc;
    if (P->n_tri + P->n_cone == 0) {
        prims_free(P);
        return sy_fail(err, SY_EINPUT, "model: no triangles or skeleton edges to measure against");
    }
    return SY_OK;
}

sy_code sy_model_distances(const sy_eval_model *m, const double *pts, size_t n, double *dist, sy_error *err)
{
    prims P;
    sy_code rc = prims_to_measure(m, &P, err);
    if (rc) return rc;
    dist_job J = {&P, pts, dist};
    sy_parallel_for(n, 1024, dist_chunk, &J);
    prims_free(&P);
    return SY_OK;
}

double sy_coverage(const double *dist, size_t n, double eps)
{
    if (!n) return NAN;
    size_t k = 0;
    for (size_t i = 0; i < n; i++) k += dist[i] <= eps;
    return (double)k / (double)n;
}

double *sy_cloud_world_points(const sy_cloud *c, sy_error *err)
{
    double *p = sy_calloc(c->n ? 3 * c->n : 1, sizeof *p, err, "points");
    if (!p) return NULL;
    for (size_t i = 0; i < c->n; i++)
        for (int k = 0; k < 3; k++) p[3 * i + k] = c->origin[k] + c->xyz[3 * i + k];
    return p;
}

/* ---- model surface samples ---- */

typedef struct {
    size_t n, cap;
    double *p;
} sample_buf;

static int put_sample(sample_buf *s, double x, double y, double z)
{
    if (sy_array_reserve(&s->p, &s->cap, s->n + 1, 3 * sizeof *s->p, 4096, NULL, "samples")) return 0;
    s->p[3 * s->n] = x;
    s->p[3 * s->n + 1] = y;
    s->p[3 * s->n + 2] = z;
    s->n++;
    return 1;
}

/* Deterministic uniform numbers in [0,1): splitmix64. */
static double next_unit(uint64_t *state) { return sy_unit53(sy_splitmix64(state)); }

static double tri_area(const double *t)
{
    double u[3], v[3];
    for (int c = 0; c < 3; c++) u[c] = t[3 + c] - t[c], v[c] = t[6 + c] - t[c];
    double x = u[1] * v[2] - u[2] * v[1], y = u[2] * v[0] - u[0] * v[2], z = u[0] * v[1] - u[1] * v[0];
    return 0.5 * sqrt(x * x + y * y + z * z);
}

/* Vertices plus area / spacing^2 uniform samples per triangle; rings of
 * samples every spacing along and around each cone. */
static int sample_model(const prims *P, double spacing, sample_buf *s)
{
    uint64_t rng = 0x5EED5EEDull;
    for (size_t t = 0; t < P->n_tri; t++) {
        const double *v = P->tri + 9 * t;
        for (int c = 0; c < 3; c++)
            if (!put_sample(s, v[3 * c], v[3 * c + 1], v[3 * c + 2])) return 0;
        double k = ceil(tri_area(v) / (spacing * spacing));
        size_t nk = k > 0 ? (size_t)fmin(k, 1e6) : 0; /* NaN: no samples inside */
        for (size_t j = 0; j < nk; j++) {
            double a = next_unit(&rng), b = next_unit(&rng);
            if (a + b > 1) a = 1 - a, b = 1 - b;
            double x[3];
            for (int c = 0; c < 3; c++) x[c] = v[c] + a * (v[3 + c] - v[c]) + b * (v[6 + c] - v[c]);
            if (!put_sample(s, x[0], x[1], x[2])) return 0;
        }
    }
    for (size_t i = 0; i < P->n_cone; i++) {
        const double *cn = P->cone + 8 * i;
        double ax[3] = {cn[3] - cn[0], cn[4] - cn[1], cn[5] - cn[2]};
        double len = sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2]);
        if (!(len > 0)) continue;
        for (int c = 0; c < 3; c++) ax[c] /= len;
        /* A unit vector perpendicular to the axis, and a third completing the frame. */
        double h[3] = {fabs(ax[0]) < 0.9 ? 1 : 0, fabs(ax[0]) < 0.9 ? 0 : 1, 0};
        double e1[3] = {ax[1] * h[2] - ax[2] * h[1], ax[2] * h[0] - ax[0] * h[2], ax[0] * h[1] - ax[1] * h[0]};
        double l1 = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
        for (int c = 0; c < 3; c++) e1[c] /= l1;
        double e2[3] = {ax[1] * e1[2] - ax[2] * e1[1], ax[2] * e1[0] - ax[0] * e1[2], ax[0] * e1[1] - ax[1] * e1[0]};
        size_t nl = (size_t)fmin(fmax(1, ceil(len / spacing)), 1e5);
        for (size_t j = 0; j <= nl; j++) {
            double u = (double)j / (double)nl, r = cn[6] + u * (cn[7] - cn[6]);
            size_t na = (size_t)fmin(fmax(3, ceil(2 * PI * r / spacing)), 1e5);
            for (size_t a = 0; a < na; a++) {
                double ang = 2 * PI * (double)a / (double)na, ca = cos(ang) * r, sa = sin(ang) * r, x[3];
                for (int c = 0; c < 3; c++) x[c] = cn[c] + u * len * ax[c] + ca * e1[c] + sa * e2[c];
                if (!put_sample(s, x[0], x[1], x[2])) return 0;
            }
        }
    }
    return 1;
}

/* Surface area of the triangles and cones. */
static double prims_area(const prims *P)
{
    double area = 0;
    for (size_t t = 0; t < P->n_tri; t++) area += tri_area(P->tri + 9 * t);
    for (size_t i = 0; i < P->n_cone; i++) {
        const double *c = P->cone + 8 * i;
        double len = sqrt((c[3] - c[0]) * (c[3] - c[0]) + (c[4] - c[1]) * (c[4] - c[1]) + (c[5] - c[2]) * (c[5] - c[2]));
        area += PI * (c[6] + c[7]) * len;
    }
    return area;
}

/* The spacing, widened so that the surface takes at most max_samples
 * samples: memory and time then follow the budget, never the model's size. */
static double budget_spacing(double area, double spacing, double max_samples)
{
    return area / (spacing * spacing) > max_samples ? sqrt(area / max_samples) : spacing;
}

double *sy_model_surface_samples(const sy_eval_model *m, double spacing, size_t *n, sy_error *err)
{
    prims P;
    *n = 0;
    if (!(spacing > 0)) spacing = 0.01;
    if (prims_build(m, &P, err)) return NULL;
    spacing = budget_spacing(prims_area(&P), spacing, 4e6);
    sample_buf s = {0};
    int ok = sample_model(&P, spacing, &s);
    prims_free(&P);
    if (!ok) {
        free(s.p);
        sy_fail(err, SY_EINTERNAL, "model samples: out of memory");
        return NULL;
    }
    *n = s.n;
    return s.p ? s.p : calloc(1, sizeof(double));
}

static double point_distance(const void *ctx, uint32_t i, const double q[3])
{
    const double *p = (const double *)ctx + 3 * (size_t)i;
    double a = q[0] - p[0], b = q[1] - p[1], c = q[2] - p[2];
    return sqrt(a * a + b * b + c * c);
}

typedef struct {
    const sy_bvh *bvh;
    const double *pts, *samples;
    double *chunk_max;
} back_job;

static void back_chunk(void *arg, size_t begin, size_t end, size_t chunk)
{
    back_job *J = arg;
    double mx = 0;
    uint32_t prev = UINT32_MAX;
    for (size_t i = begin; i < end; i++) {
        const double *q = J->samples + 3 * i;
        /* Only samples farther than the running maximum can raise it. */
        if (prev != UINT32_MAX && sy_bvh_any_within(J->bvh, q, mx, point_distance, J->pts)) continue;
        double d;
        prev = sy_bvh_nearest(J->bvh, q, INFINITY, point_distance, J->pts, prev, &d);
        if (d > mx) mx = d;
    }
    J->chunk_max[chunk] = mx;
}

#define BACK_CHUNK 4096

/* max over model surface samples of the distance to the nearest point. */
static sy_code model_to_points(const prims *P, const double *pts, size_t n, double spacing, double *out,
                               size_t *n_samples, sy_error *err)
{
    sample_buf s = {0};
    if (!sample_model(P, spacing, &s)) {
        free(s.p);
        return sy_fail(err, SY_EINTERNAL, "model samples: out of memory");
    }
    sy_box *boxes = sy_calloc(n ? n : 1, sizeof *boxes, err, "points");
    double *chunk_max = sy_calloc(s.n / BACK_CHUNK + 1, sizeof *chunk_max, err, "model samples");
    sy_bvh bvh;
    sy_code rc = boxes && chunk_max ? SY_OK : SY_EINTERNAL;
    if (!rc) {
        for (size_t i = 0; i < n; i++)
            for (int c = 0; c < 3; c++) boxes[i].lo[c] = boxes[i].hi[c] = pts[3 * i + c];
        rc = sy_bvh_build(&bvh, boxes, n, err);
    }
    if (!rc) {
        back_job J = {&bvh, pts, s.p, chunk_max};
        sy_parallel_for(s.n, BACK_CHUNK, back_chunk, &J);
        double mx = s.n ? 0 : NAN;
        for (size_t c = 0; c < s.n / BACK_CHUNK + 1 && s.n; c++)
            if (chunk_max[c] > mx) mx = chunk_max[c];
        *out = mx;
        *n_samples = s.n;
        sy_bvh_free(&bvh);
    }
    free(boxes);
    free(chunk_max);
    free(s.p);
    return rc;
}

sy_code sy_surface_metrics_compute(const sy_eval_model *m, const double *pts, size_t n, double coverage_eps,
                                   double spacing, sy_surface_metrics *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    if (!n) return sy_fail(err, SY_EINPUT, "points: no points to measure");
    if (!(spacing > 0)) spacing = 0.01;
    prims P;
    sy_code rc = prims_to_measure(m, &P, err);
    if (rc) return rc;
    /* Model -> points: samples need not be much denser than the points
     * themselves; four per point of mean point spacing, and never more than
     * ~20 million. */
    double area = prims_area(&P);
    spacing = budget_spacing(area, fmax(spacing, 0.5 * sqrt(area / (double)n)), 2e7);
    double *dist = sy_calloc(n, sizeof *dist, err, "distances");
    if (!dist) {
        prims_free(&P);
        return SY_EINTERNAL;
    }
    dist_job J = {&P, pts, dist};
    sy_parallel_for(n, 1024, dist_chunk, &J);
    double sum = 0, sum2 = 0, mx = 0;
    for (size_t i = 0; i < n; i++) {
        sum += dist[i];
        sum2 += dist[i] * dist[i];
        if (dist[i] > mx) mx = dist[i];
    }
    out->n_points = n;
    out->mean_distance = sum / (double)n;
    out->rms_distance = sqrt(sum2 / (double)n);
    out->hausdorff = mx;
    out->coverage_eps = coverage_eps;
    out->coverage = sy_coverage(dist, n, coverage_eps);
    /* Nearest-rank 95th percentile. */
    size_t rank = (size_t)ceil(0.95 * (double)n);
    out->p95_distance = sy_select_double(dist, n, rank ? rank - 1 : 0);
    free(dist);
    rc = model_to_points(&P, pts, n, spacing, &out->hausdorff_model_to_points, &out->n_model_samples, err);
    prims_free(&P);
    return rc;
}
