/* Evaluation speed: 100k points vs a 100k-triangle mesh (point->mesh
 * distances, then the full surface metrics with model->points sampling),
 * the same points vs a 100k-edge skeleton as cones, and skeleton metrics of
 * a 100k-edge skeleton against a shifted copy. Each on 1 thread and on all
 * cores. Usage: bench_eval [points_thousands] (default 100). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "stages/core/parallel.h"
#include "stages/eval/eval.h"

#define PI 3.14159265358979323846

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static double cpu(void)
{
    struct timespec t;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static unsigned long long rng;
static double unit(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 7;
    rng ^= rng << 17;
    return (double)(rng >> 11) * (1.0 / 9007199254740992.0);
}

/* 500 random tubes of 20 rings x 10 sides: 200 triangles each. */
static double *tube_mesh(size_t *n_tri, double *axes)
{
    size_t tubes = 500, per = 200, k = 0;
    double *tri = malloc(tubes * per * 9 * sizeof *tri);
    for (size_t t = 0; t < tubes; t++) {
        double a[3] = {10 * unit(), 10 * unit(), 10 * unit()}, d[3] = {unit() - 0.5, unit() - 0.5, unit() - 0.5};
        double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int c = 0; c < 3; c++) d[c] /= l;
        double h[3] = {fabs(d[0]) < 0.9, fabs(d[0]) >= 0.9, 0};
        double e1[3] = {d[1] * h[2] - d[2] * h[1], d[2] * h[0] - d[0] * h[2], d[0] * h[1] - d[1] * h[0]};
        l = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
        for (int c = 0; c < 3; c++) e1[c] /= l;
        double e2[3] = {d[1] * e1[2] - d[2] * e1[1], d[2] * e1[0] - d[0] * e1[2], d[0] * e1[1] - d[1] * e1[0]};
        memcpy(axes + 9 * t, a, sizeof a);
        memcpy(axes + 9 * t + 3, e1, sizeof e1);
        memcpy(axes + 9 * t + 6, d, sizeof d);
        double r = 0.05 + 0.1 * unit(), len = 2.0;
        for (int i = 0; i < 10; i++)
            for (int j = 0; j < 10; j++) {
                double v[4][3];
                for (int q = 0; q < 4; q++) {
                    double z = len * (i + (q >> 1)) / 10.0, ang = 2 * PI * (j + (q & 1)) / 10.0;
                    for (int c = 0; c < 3; c++) v[q][c] = a[c] + z * d[c] + r * cos(ang) * e1[c] + r * sin(ang) * e2[c];
                }
                const int idx[2][3] = {{0, 1, 3}, {0, 3, 2}};
                for (int f = 0; f < 2; f++, k++)
                    for (int q = 0; q < 3; q++) memcpy(tri + 9 * k + 3 * q, v[idx[f][q]], 3 * sizeof(double));
            }
        axes[9 * t + 3] = r; /* reuse: radius */
        (void)e2;
    }
    *n_tri = k;
    return tri;
}

/* 1000 stems of 100 edges, each from a random earlier node. */
static void random_forest(sy_forest *f, double shift)
{
    sy_error err = {0};
    sy_eval_tree t;
    rng = 0x2545F4914F6CDD1Dull; /* the same forest every time */
    memset(&t, 0, sizeof t);
    t.tree_id = 1;
    t.dbh = t.height = t.crown_width = NAN;
    float p0[3] = {(float)shift, 0, 0};
    sy_skeleton_add(&t.skel, p0, 0.3f, -1, 0, 0, &err);
    for (int s = 0; s < 1000; s++) {
        int32_t from = s ? (int32_t)(unit() * (double)t.skel.n) : 0;
        double d[3] = {unit() - 0.5, unit() - 0.5, unit()};
        float p[3];
        memcpy(p, t.skel.pos + 3 * from, sizeof p);
        int order = s ? t.skel.order[from] + 1 : 0;
        for (int i = 0; i < 100; i++) {
            for (int c = 0; c < 3; c++) {
                d[c] += 0.3 * (unit() - 0.5);
                p[c] += (float)(0.05 * d[c]);
            }
            from = sy_skeleton_add(&t.skel, p, (float)(0.1 / (1 + order) + 0.005), from, order, s, &err);
        }
    }
    t.position[0] = shift;
    memset(f, 0, sizeof *f);
    sy_forest_add(f, &t, &err);
}

int main(int argc, char **argv)
{
    size_t n = (size_t)(argc > 1 ? atof(argv[1]) : 100) * 1000;
    rng = 88172645463325252ull;
    double axes[500 * 9];
    size_t n_tri;
    double *tri = tube_mesh(&n_tri, axes);
    double *pts = malloc(3 * n * sizeof *pts);
    for (size_t i = 0; i < n; i++) { /* near a tube's surface, 2 cm noise */
        const double *ax = axes + 9 * (size_t)(unit() * 500);
        double z = 2 * unit(), ang = 2 * PI * unit(), r = ax[3] + 0.02 * (unit() - 0.5);
        const double *d = ax + 6;
        double h[3] = {fabs(d[0]) < 0.9, fabs(d[0]) >= 0.9, 0};
        double e1[3] = {d[1] * h[2] - d[2] * h[1], d[2] * h[0] - d[0] * h[2], d[0] * h[1] - d[1] * h[0]};
        double l = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
        for (int c = 0; c < 3; c++) e1[c] /= l;
        double e2[3] = {d[1] * e1[2] - d[2] * e1[1], d[2] * e1[0] - d[0] * e1[2], d[0] * e1[1] - d[1] * e1[0]};
        for (int c = 0; c < 3; c++) pts[3 * i + c] = ax[c] + z * d[c] + r * cos(ang) * e1[c] + r * sin(ang) * e2[c];
    }
    sy_error err = {0};
    sy_eval_model mesh = {0};
    sy_eval_model_add_mesh(&mesh, tri, n_tri, 0, &err);
    sy_forest skel, shifted;
    random_forest(&skel, 0);
    random_forest(&shifted, 0.03);
    sy_eval_model cones = {0, NULL, skel};
    double *dist = malloc(n * sizeof *dist);
    printf("%zu points, %zu triangles, %zu skeleton nodes\n", n, n_tri, skel.trees[0].skel.n);
    int threads[2] = {1, 0};
    for (int ti = 0; ti < 2; ti++) {
        sy_set_threads(threads[ti]);
        printf("threads %d:\n", sy_threads());
        double t0 = now(), c0 = cpu();
        sy_model_distances(&mesh, pts, n, dist, &err);
        double t1 = now(), c1 = cpu();
        printf("  point->mesh distances (BVH build + queries)   wall %.3f s cpu %.3f s  coverage(2cm) %.3f\n", t1 - t0,
               c1 - c0, sy_coverage(dist, n, 0.02));
        sy_surface_metrics s;
        sy_surface_metrics_compute(&mesh, pts, n, 0.02, 0.01, &s, &err);
        double t2 = now(), c2 = cpu();
        printf("  full surface metrics (%zu model samples)  wall %.3f s cpu %.3f s  mean %.4f p95 %.4f H %.3f/%.3f\n",
               s.n_model_samples, t2 - t1, c2 - c1, s.mean_distance, s.p95_distance, s.hausdorff,
               s.hausdorff_model_to_points);
        sy_model_distances(&cones, pts, n, dist, &err);
        double t3 = now(), c3 = cpu();
        printf("  point->skeleton cone distances                wall %.3f s cpu %.3f s\n", t3 - t2, c3 - c2);
        sy_skeleton_metrics m;
        sy_skeleton_metrics_compute(&skel, &shifted, NULL, &m, &err);
        double t4 = now(), c4 = cpu();
        printf("  skeleton metrics, 100k edges vs 3 cm shift    wall %.3f s cpu %.3f s  recall %.3f precision %.3f "
               "(%.0f m of edges)\n", t4 - t3, c4 - c3, m.recall, m.precision, m.truth_length);
    }
    free(dist);
    free(pts);
    free(tri);
    sy_eval_model_free(&mesh);
    sy_forest_free(&skel);
    sy_forest_free(&shifted);
    return 0;
}
