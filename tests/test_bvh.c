/* The core BVH against brute force: nearest, any-within and ray crossings
 * over spheres (exact answers known per primitive), far from the origin as
 * georeferenced data are, plus duplicate points, an empty index, reordering
 * and ray-triangle edge conventions. Closest hits are checked in test_scan. */
#include "testutil.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/bvh.h"

/* UTM-like offset: float coordinates alone would be 0.5 m coarse here. */
static const double OFFSET[3] = {512345.0, 4123456.0, 250.0};

typedef struct {
    double c[3], r;
} sphere;

static double frand(double lo, double hi) { return lo + (hi - lo) * rand() / (double)RAND_MAX; }

static double sphere_distance(const void *ctx, uint32_t i, const double q[3])
{
    const sphere *s = (const sphere *)ctx + i;
    double d = sqrt((q[0] - s->c[0]) * (q[0] - s->c[0]) + (q[1] - s->c[1]) * (q[1] - s->c[1]) +
                    (q[2] - s->c[2]) * (q[2] - s->c[2])) -
               s->r;
    return d > 0 ? d : 0;
}

/* First crossing of the sphere's surface at 0 < t < tmax. */
static int sphere_ray(const void *ctx, uint32_t i, const double o[3], const double d[3], double tmax, double *t)
{
    const sphere *s = (const sphere *)ctx + i;
    double oc[3] = {o[0] - s->c[0], o[1] - s->c[1], o[2] - s->c[2]};
    double b = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
    double c = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - s->r * s->r;
    double disc = b * b - c;
    if (disc < 0) return 0;
    double sq = sqrt(disc);
    double t0 = -b - sq, t1 = -b + sq;
    double hit = t0 > 0 ? t0 : t1;
    if (!(hit > 0 && hit < tmax)) return 0;
    *t = hit;
    return 1;
}

static sphere *random_spheres(size_t n)
{
    sphere *s = malloc(n * sizeof *s);
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++) s[i].c[k] = OFFSET[k] + frand(-40, 40);
        s[i].r = frand(0.001, 0.6);
    }
    return s;
}

/* n random spheres (seeded) and their index. */
static sphere *indexed_spheres(size_t n, unsigned seed, sy_bvh *bvh)
{
    srand(seed);
    sphere *s = random_spheres(n);
    sy_box *b = malloc(n * sizeof *b);
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            b[i].lo[k] = s[i].c[k] - s[i].r;
            b[i].hi[k] = s[i].c[k] + s[i].r;
        }
    sy_error err = {0};
    assert_int_equal(sy_bvh_build(bvh, b, n, &err), SY_OK);
    free(b);
    return s;
}

static void nearest_and_within_match_brute_force(void **state)
{
    (void)state;
    size_t n = 3000;
    sy_bvh bvh;
    sphere *s = indexed_spheres(n, 3, &bvh);
    uint32_t prev = UINT32_MAX;
    for (int q = 0; q < 2000; q++) {
        double p[3];
        for (int k = 0; k < 3; k++) p[k] = OFFSET[k] + frand(-45, 45);
        uint32_t want = UINT32_MAX;
        double want_d = INFINITY;
        for (uint32_t i = 0; i < n; i++) {
            double d = sphere_distance(s, i, p);
            if (d < want_d) want_d = d, want = i;
        }
        double d;
        /* The hint is the previous answer: a wrong one must not matter. */
        uint32_t got = sy_bvh_nearest(&bvh, p, INFINITY, sphere_distance, s, prev, &d);
        assert_int_equal(got, want);
        assert_true(d == want_d);
        prev = got;
        /* Limited search: found exactly when the nearest lies within. */
        double limit = frand(0, 2);
        got = sy_bvh_nearest(&bvh, p, limit, sphere_distance, s, UINT32_MAX, &d);
        assert_int_equal(got, want_d <= limit ? want : UINT32_MAX);
        assert_int_equal(sy_bvh_any_within(&bvh, p, limit, sphere_distance, s), want_d <= limit);
    }
    sy_bvh_free(&bvh);
    free(s);
}

static void rays_match_brute_force(void **state)
{
    (void)state;
    size_t n = 2000;
    sy_bvh bvh;
    sphere *s = indexed_spheres(n, 7, &bvh);
    int n_hit = 0;
    for (int r = 0; r < 1500; r++) {
        double o[3], d[3];
        for (int k = 0; k < 3; k++) o[k] = OFFSET[k] + frand(-50, 50);
        if (r % 2) {
            const sphere *aim = &s[rand() % n];
            for (int k = 0; k < 3; k++) d[k] = aim->c[k] - o[k];
        } else {
            for (int k = 0; k < 3; k++) d[k] = frand(-1, 1);
        }
        if (r % 5 == 0) d[r % 3] = 0; /* axis-parallel components */
        double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int k = 0; k < 3; k++) d[k] /= l;
        size_t want = 0;
        for (uint32_t i = 0; i < n; i++) {
            double t;
            want += (size_t)sphere_ray(s, i, o, d, INFINITY, &t);
        }
        assert_int_equal(sy_bvh_ray_count(&bvh, o, d, sphere_ray, s), want);
        sy_hit a = {0, 0}, b = {0, 0};
        int ha = sy_bvh_closest(&bvh, o, d, 200, sphere_ray, s, &a);
        int hb = sy_bvh_closest_brute(&bvh, o, d, 200, sphere_ray, s, &b);
        assert_int_equal(ha, hb);
        if (ha) {
            n_hit++;
            assert_true(a.t == b.t);
            assert_int_equal(a.prim, b.prim);
        }
    }
    assert_true(n_hit > 500);
    sy_bvh_free(&bvh);
    free(s);
}

/* Thousands of copies of one point still make small leaves. */
static void duplicate_points_split(void **state)
{
    (void)state;
    size_t n = 5000;
    sy_box *boxes = malloc(n * sizeof *boxes);
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) boxes[i].lo[k] = boxes[i].hi[k] = OFFSET[k] + (i % 2 ? 1.0 : 0.0);
    sy_bvh bvh;
    sy_error err = {0};
    assert_int_equal(sy_bvh_build(&bvh, boxes, n, &err), SY_OK);
    size_t in_leaves = 0;
    for (size_t i = 0; i < bvh.n_nodes; i++) {
        assert_true(bvh.nodes[i].count <= 16);
        in_leaves += bvh.nodes[i].count;
    }
    assert_int_equal(in_leaves, n);
    sy_bvh_free(&bvh);
    free(boxes);
}

static void empty_index(void **state)
{
    (void)state;
    sy_bvh bvh;
    sy_error err = {0};
    assert_int_equal(sy_bvh_build(&bvh, NULL, 0, &err), SY_OK);
    double q[3] = {0, 0, 0}, d[3] = {0, 0, 1}, dist;
    sy_hit h;
    assert_int_equal(sy_bvh_nearest(&bvh, q, INFINITY, sphere_distance, NULL, UINT32_MAX, &dist), UINT32_MAX);
    assert_true(isinf(dist));
    assert_int_equal(sy_bvh_any_within(&bvh, q, 1, sphere_distance, NULL), 0);
    assert_int_equal(sy_bvh_ray_count(&bvh, q, d, sphere_ray, NULL), 0);
    assert_int_equal(sy_bvh_closest(&bvh, q, d, 1, sphere_ray, NULL, &h), 0);
    sy_box all;
    sy_bvh_bounds(&bvh, &all);
    assert_true(all.lo[0] > all.hi[0]);
    sy_bvh_free(&bvh);
}

/* After reordering, answers name positions in the rearranged array. */
static void reorder_keeps_answers(void **state)
{
    (void)state;
    size_t n = 500;
    sy_bvh bvh;
    sphere *s = indexed_spheres(n, 9, &bvh);
    sy_error err = {0};
    double q[3] = {OFFSET[0] + 3, OFFSET[1] - 2, OFFSET[2] + 1}, d0, d1;
    uint32_t before = sy_bvh_nearest(&bvh, q, INFINITY, sphere_distance, s, UINT32_MAX, &d0);
    sphere want = s[before];
    assert_int_equal(sy_bvh_reorder(&bvh, s, sizeof *s, &err), SY_OK);
    uint32_t after = sy_bvh_nearest(&bvh, q, INFINITY, sphere_distance, s, UINT32_MAX, &d1);
    assert_true(d0 == d1);
    assert_memory_equal(&s[after], &want, sizeof want);
    sy_box all;
    sy_bvh_bounds(&bvh, &all);
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) assert_true(all.lo[k] <= s[i].c[k] - s[i].r && all.hi[k] >= s[i].c[k] + s[i].r);
    sy_bvh_free(&bvh);
    free(s);
}

static void ray_triangle_edges(void **state)
{
    (void)state;
    double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0}, down[3] = {0, 0, -1}, t;
    double inside[3] = {0.25, 0.25, 2}, outside[3] = {0.75, 0.75, 2}, on_bc[3] = {0.5, 0.5, 2};
    assert_int_equal(sy_ray_triangle(inside, down, a, b, c, 0, &t), 1);
    assert_true(fabs(t - 2) < 1e-15);
    assert_int_equal(sy_ray_triangle(outside, down, a, b, c, 1, &t), 0);
    /* The edge bc (u + v = 1) is in for closest hits, out for parity. */
    assert_int_equal(sy_ray_triangle(on_bc, down, a, b, c, 1, &t), 1);
    assert_int_equal(sy_ray_triangle(on_bc, down, a, b, c, 0, &t), 0);
    /* Behind the origin: the line still crosses, at negative t. */
    double below[3] = {0.25, 0.25, -3};
    assert_int_equal(sy_ray_triangle(below, down, a, b, c, 0, &t), 1);
    assert_true(fabs(t + 3) < 1e-15);
    /* In the plane of the triangle: no crossing. */
    double along[3] = {1, 0, 0}, in_plane[3] = {-1, 0.2, 0};
    assert_int_equal(sy_ray_triangle(in_plane, along, a, b, c, 1, &t), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(nearest_and_within_match_brute_force),
        cmocka_unit_test(rays_match_brute_force),
        cmocka_unit_test(duplicate_points_split),
        cmocka_unit_test(empty_index),
        cmocka_unit_test(reorder_keeps_answers),
        cmocka_unit_test(ray_triangle_edges),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
