/* Evaluation: analytic skeleton cases, exact distances, closed hulls,
 * coverage, segmentation on MixedConifer, species scores and the PNG. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <stb_image.h>

#include "stages/eval/eval.h"
#include "stages/gltf/gltf_read.h"
#include "stages/eval/geometry.h"
#include "stages/ingest/ingest.h"

/* ---- a planar test tree (all in the x-z plane, radii < 4.5 cm) ---- */

typedef struct {
    double removed_length; /* length of the stems dropped by skip_every */
} tree_info;

/* A trunk of 5 m, 8 branches of 2 m alternating left/right, each with two
 * 0.6 m twigs. Branch b is left out (with its twigs) when skip_every > 0
 * and b % skip_every == 1. Radii scaled by rscale, everything shifted by
 * shift. */
static void planar_tree(sy_forest *f, double rscale, const double shift[3], int skip_every, tree_info *info)
{
    sy_error err = {0};
    sy_eval_tree t;
    memset(&t, 0, sizeof t);
    t.tree_id = 1;
    t.species_id = -1;
    t.crown_width = NAN;
    snprintf(t.species, sizeof t.species, "test_tree");
    for (int k = 0; k < 3; k++) t.skel.origin[k] = shift[k];
    int32_t branch_id = 0, prev = -1;
    int32_t trunk[21];
    for (int i = 0; i <= 20; i++) {
        float p[3] = {0, 0, 0.25f * (float)i};
        float r = (float)(rscale * (0.045 - 0.0015 * i));
        trunk[i] = prev = sy_skeleton_add(&t.skel, p, r, prev, 0, 0, &err);
    }
    branch_id = 1;
    if (info) info->removed_length = 0;
    for (int b = 0; b < 8; b++) {
        int at = 6 + 2 * b; /* trunk node, z = 1.5 .. 5.0 */
        double side = b % 2 ? -1 : 1;
        int skip = skip_every > 0 && b % skip_every == 1;
        double bx = 0, bz = 0.25 * at;
        int32_t parent = trunk[at], base = -1;
        int32_t my_branch = branch_id++;
        for (int j = 1; j <= 8 && !skip; j++) {
            float p[3] = {(float)(side * 0.25 * j), 0, (float)(bz + 0.02 * j)};
            float r = (float)(rscale * (0.02 - 0.0015 * j));
            parent = sy_skeleton_add(&t.skel, p, r, parent, 1, my_branch, &err);
            if (j == 4) base = parent;
        }
        if (skip && info) info->removed_length += 8 * sqrt(0.25 * 0.25 + 0.02 * 0.02);
        /* two twigs from the branch's middle, one up, one down */
        for (int tw = 0; tw < 2; tw++) {
            int32_t my_twig = branch_id++;
            int32_t q = base;
            bx = side * 1.0;
            for (int j = 1; j <= 3; j++) {
                float p[3] = {(float)(bx + side * 0.1 * j), 0, (float)(bz + 0.08 + (tw ? -0.15 : 0.15) * j)};
                float r = (float)(rscale * (0.006 - 0.001 * j));
                if (!skip) q = sy_skeleton_add(&t.skel, p, r, q, 2, my_twig, &err);
            }
            if (skip && info) info->removed_length += 3 * sqrt(0.1 * 0.1 + 0.15 * 0.15);
        }
    }
    t.dbh = sy_skeleton_dbh(&t.skel);
    t.height = sy_skeleton_height(&t.skel);
    for (int k = 0; k < 3; k++) t.position[k] = shift[k];
    memset(f, 0, sizeof *f);
    assert_int_equal(sy_forest_add(f, &t, &err), SY_OK);
}

static const double zero3[3] = {0, 0, 0};

static sy_skeleton_metrics score(const sy_forest *truth, const sy_forest *model)
{
    sy_skeleton_metrics m;
    sy_error err = {0};
    assert_int_equal(sy_skeleton_metrics_compute(truth, model, NULL, &m, &err), SY_OK);
    return m;
}

static void skeleton_vs_itself_is_perfect(void **state)
{
    (void)state;
    sy_forest t;
    planar_tree(&t, 1, zero3, 0, NULL);
    sy_skeleton_metrics m = score(&t, &t);
    assert_true(m.recall == 1 && m.precision == 1);
    assert_true(m.recall_r2cm == 1 && m.precision_r2cm == 1);
    for (int k = 0; k < 3; k++) assert_true(m.recall_order[k] == 1 && m.precision_order[k] == 1);
    assert_true(isnan(m.recall_order[3])); /* no order 3 in this tree */
    assert_true(m.radius_error_median < 1e-6);
    /* 7 trunk nodes with a branch (the 8th branch continues the trunk tip,
     * one child only) and 8 branch nodes with their two twigs. */
    assert_int_equal(m.bifurcations_truth, 7 + 8);
    assert_int_equal(m.bifurcations_matched, m.bifurcations_truth);
    assert_true(m.bifurcation_error_mean < 1e-6);
    assert_true(m.dbh_error == 0 && m.height_error == 0);
    assert_true(fabs(m.truth_length - m.model_length) < 1e-9);
    sy_forest_free(&t);
}

/* The skeleton_stages fuzz find (tests/fuzz/corpus/skeleton_stages/
 * long_edges_timeout): 20 nodes, one of them 330 m below the others, scored
 * against itself. The edge samples followed the length (1 cm steps: 6e5 a
 * direction, past the fuzz time budget under the sanitizers); they now follow
 * the size: at most max(1e5, 256 per edge) a direction. A small tree keeps
 * the 1 cm step. */
static void long_edges_take_bounded_samples(void **state)
{
    (void)state;
    static const float node[20][4] = {
        {1.64f, 1.99f, 1, -1},    {0.25f, 1.9f, 2, 0},     {-0.02f, 1.81f, 3, 0},  {-1.5f, -1.85f, 4, 1},
        {2.44f, -1.17f, 5, 2},    {2.11f, 0.46f, 6, 2},    {-2.09f, 2.03f, 7, 5},  {2.27f, 2.61f, 8, 5},
        {0.69f, -2.36f, 9, 5},    {-2.65f, 0.13f, 10, 7},  {2.72f, -0.13f, 11, 8}, {-0.11f, 0, 12, 9},
        {-1.18f, 2.94f, 13, 10},  {1.85f, 2.6f, -313.68f, 12}, {0.33f, -0.2f, 15, 12}, {-0.05f, 2.12f, 16, 13},
        {0.65f, 0.56f, 17, 13},   {0.53f, 1.18f, 18, 15},  {-1.24f, 1.6f, 19, 16}, {0.43f, 2.3f, 20, 17}};
    sy_error err = {0};
    sy_eval_tree t;
    memset(&t, 0, sizeof t);
    t.tree_id = 1;
    t.species_id = -1;
    t.crown_width = NAN;
    for (int i = 0; i < 20; i++)
        assert_true(sy_skeleton_add(&t.skel, node[i], 0.19f - 0.006f * (float)i, (int32_t)node[i][3], 0, i, &err) ==
                    i);
    t.height = sy_skeleton_height(&t.skel);
    t.dbh = sy_skeleton_dbh(&t.skel);
    sy_forest f = {0};
    assert_int_equal(sy_forest_add(&f, &t, &err), SY_OK);
    sy_skeleton_metrics m = score(&f, &f);
    assert_true(m.truth_length > 600);
    assert_true(m.n_samples <= 2 * 100000 + 2 * 19);
    assert_true(m.sample_step > 0.01 && fabs(m.sample_step * 1e5 - m.truth_length) < 1e-6 * m.truth_length);
    assert_true(m.recall == 1 && m.precision == 1); /* still itself */
    sy_forest_free(&f);
    sy_forest small;
    planar_tree(&small, 1, zero3, 0, NULL);
    m = score(&small, &small);
    assert_true(m.sample_step == 0.01);
    sy_forest_free(&small);
}

static void shifted_copies(void **state)
{
    (void)state;
    sy_forest t, s3, s20;
    planar_tree(&t, 1, zero3, 0, NULL);
    const double d3[3] = {0, 0.03, 0}, d20[3] = {0, 0.20, 0};
    planar_tree(&s3, 1, d3, 0, NULL);
    planar_tree(&s20, 1, d20, 0, NULL);
    sy_skeleton_metrics m = score(&t, &s3);
    assert_true(m.recall == 1 && m.precision == 1); /* within 5 cm */
    assert_true(fabs(m.bifurcation_error_mean - 0.03) < 1e-5);
    assert_true(fabs(m.bifurcation_error_median - 0.03) < 1e-5);
    m = score(&t, &s20);
    assert_true(m.recall == 0 && m.precision == 0); /* 20 cm > max(2 r, 5 cm) everywhere */
    assert_true(m.recall_r2cm == 0);
    assert_int_equal(m.bifurcations_matched, m.bifurcations_truth); /* 0.20 < 0.25 m match radius */
    assert_true(fabs(m.bifurcation_error_mean - 0.20) < 1e-5);
    sy_forest_free(&t);
    sy_forest_free(&s3);
    sy_forest_free(&s20);
}

static void removed_branches_lower_recall_by_their_length(void **state)
{
    (void)state;
    sy_forest t, half;
    tree_info info;
    planar_tree(&t, 1, zero3, 0, NULL);
    planar_tree(&half, 1, zero3, 2, &info); /* branches 1, 3, 5, 7 with their twigs gone */
    sy_skeleton_metrics m = score(&t, &half);
    double total = sy_skeleton_length(&t.trees[0].skel);
    double want = 1 - info.removed_length / total;
    assert_true(info.removed_length > 0.3 * total);
    assert_true(fabs(m.recall - want) < 0.01);
    assert_true(m.precision == 1);
    assert_true(m.recall_order[0] == 1);
    assert_true(m.recall_order[1] < 0.55 && m.recall_order[1] > 0.45);
    sy_forest_free(&t);
    sy_forest_free(&half);
}

static void radius_scaled_by_1_2(void **state)
{
    (void)state;
    sy_forest t, big;
    planar_tree(&t, 1, zero3, 0, NULL);
    planar_tree(&big, 1.2, zero3, 0, NULL);
    sy_skeleton_metrics m = score(&t, &big);
    assert_true(fabs(m.radius_error_median - 0.2) < 1e-4);
    for (int k = 0; k < 3; k++) assert_true(fabs(m.radius_error_order[k] - 0.2) < 1e-4);
    assert_true(m.recall == 1 && m.precision == 1);
    assert_true(fabs(m.dbh_error - 0.2 * t.trees[0].dbh) < 1e-6);
    assert_true(m.height_error < 1e-9);
    sy_forest_free(&t);
    sy_forest_free(&big);
}

static void truth_json_round_trip_and_errors(void **state)
{
    (void)state;
    const char *ok = "{\"format\":\"sylva-truth\",\"version\":1,\"trees\":[{\"tree_id\":4,\"species\":\"black_oak\","
                     "\"species_id\":2,\"position\":[500000.5,4100000.25,12],\"height\":3,\"dbh\":0.3,\"nodes\":["
                     "{\"id\":0,\"parent\":-1,\"x\":500000.5,\"y\":4100000.25,\"z\":12,\"radius\":0.15,\"order\":0,\"branch\":0},"
                     "{\"id\":1,\"parent\":0,\"x\":500000.5,\"y\":4100000.25,\"z\":15,\"radius\":0.05,\"order\":0,\"branch\":0}]}]}";
    sy_forest f;
    sy_error err = {0};
    assert_int_equal(sy_forest_parse("t.json", ok, strlen(ok), &f, &err), SY_OK);
    assert_int_equal(f.n_trees, 1);
    assert_int_equal(f.trees[0].tree_id, 4);
    assert_string_equal(f.trees[0].species, "black_oak");
    const sy_skeleton *s = &f.trees[0].skel;
    /* World positions survive the float offsets to the centimetre and better. */
    assert_true(fabs(s->origin[0] + s->pos[3] - 500000.5) < 1e-4);
    assert_true(fabs(s->origin[1] + s->pos[4] - 4100000.25) < 1e-4);
    assert_true(fabs(sy_skeleton_length(s) - 3) < 1e-5);
    sy_forest_free(&f);
    /* A skeleton file without order/branch gets them from the topology. */
    const char *sk = "{\"nodes\":[{\"parent\":-1,\"x\":0,\"y\":0,\"z\":0,\"radius\":0.1},"
                     "{\"parent\":0,\"x\":0,\"y\":0,\"z\":1,\"radius\":0.1},{\"parent\":1,\"x\":0,\"y\":0,\"z\":2,\"radius\":0.1},"
                     "{\"parent\":1,\"x\":1,\"y\":0,\"z\":1,\"radius\":0.01}]}";
    assert_int_equal(sy_forest_parse("s.json", sk, strlen(sk), &f, &err), SY_OK);
    s = &f.trees[0].skel;
    assert_int_equal(s->order[2], 0);
    assert_int_equal(s->order[3], 1);
    assert_true(s->branch[3] != s->branch[2]);
    assert_true(fabs(f.trees[0].dbh - 0.2) < 1e-6);
    assert_true(fabs(f.trees[0].height - 2) < 1e-6);
    sy_forest_free(&f);
    struct {
        const char *text, *want;
    } bad[] = {
        {"{\"format\":\"other\",\"trees\":[]}", "'format' is 'other'"},
        {"{\"version\":2,\"trees\":[]}", "version 2 is not supported"},
        {"{\"foo\":1}", "neither 'trees'"},
        {"{\"trees\":[]}", "'trees' is empty"},
        {"{\"nodes\":[]}", "'nodes' is empty"},
        {"{\"nodes\":[{\"parent\":-1,\"x\":0,\"y\":0,\"radius\":1}]}", "'z' is missing"},
        {"{\"nodes\":[{\"parent\":-1,\"x\":0,\"y\":0,\"z\":0,\"radius\":-1}]}", "'radius' must be a number > 0"},
        {"{\"nodes\":[{\"parent\":5,\"x\":0,\"y\":0,\"z\":0,\"radius\":1}]}", "'parent' must be -1 or"},
        {"{\"nodes\":[{\"parent\":1,\"x\":0,\"y\":0,\"z\":0,\"radius\":1},{\"parent\":0,\"x\":0,\"y\":0,\"z\":0,\"radius\":1}]}",
         "0 root nodes"},
        {"{\"nodes\":[{\"id\":3,\"parent\":-1,\"x\":0,\"y\":0,\"z\":0,\"radius\":1}]}", "'id' must equal"},
        {"{\"nodes\":[{\"parent\":-1,\"x\":\"0\",\"y\":0,\"z\":0,\"radius\":1}]}", "'x' must be a number"},
        {"{\"trees\":[{\"nodes\":[{\"parent\":-1,\"x\":0,\"y\":0,\"z\":0,\"radius\":1}],\"position\":[1,2]}]}", "'position' must be"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        sy_error e = {0};
        assert_int_equal(sy_forest_parse("bad.json", bad[i].text, strlen(bad[i].text), &f, &e), SY_EINPUT);
        if (!strstr(e.msg, bad[i].want)) fail_msg("case %zu: '%s' lacks '%s'", i, e.msg, bad[i].want);
        assert_non_null(strstr(e.msg, "bad.json"));
        assert_int_equal(f.n_trees, 0);
    }
}

/* ---- exact distances ---- */

static double brute_triangle(const double p[3], const double a[3], const double b[3], const double c[3])
{
    double best = INFINITY;
    const int N = 300;
    for (int i = 0; i <= N; i++)
        for (int j = 0; i + j <= N; j++) {
            double u = (double)i / N, v = (double)j / N, q[3];
            for (int k = 0; k < 3; k++) q[k] = a[k] + u * (b[k] - a[k]) + v * (c[k] - a[k]);
            double d = sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]));
            if (d < best) best = d;
        }
    return best;
}

static void point_triangle_distance_is_exact(void **state)
{
    (void)state;
    const double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0};
    const double above[3] = {0.2, 0.2, 0.7}, past_a[3] = {-1, -1, 1}, past_edge[3] = {0.5, -2, 0};
    const double past_bc[3] = {1, 1, 0};
    assert_true(fabs(sy_point_triangle_distance(above, a, b, c, NULL) - 0.7) < 1e-12);
    assert_true(fabs(sy_point_triangle_distance(past_a, a, b, c, NULL) - sqrt(3)) < 1e-12);
    assert_true(fabs(sy_point_triangle_distance(past_edge, a, b, c, NULL) - 2) < 1e-12);
    assert_true(fabs(sy_point_triangle_distance(past_bc, a, b, c, NULL) - sqrt(0.5)) < 1e-12);
    /* Against brute force over random triangles and points; the grid of
     * 1/300 steps bounds the brute-force excess by the grid spacing. */
    unsigned s = 12345;
    for (int t = 0; t < 40; t++) {
        double v[4][3];
        for (int i = 0; i < 4; i++)
            for (int k = 0; k < 3; k++) {
                s = s * 1103515245u + 12345u;
                v[i][k] = ((s >> 8) % 10000) / 5000.0 - 1;
            }
        double exact = sy_point_triangle_distance(v[3], v[0], v[1], v[2], NULL);
        double brute = brute_triangle(v[3], v[0], v[1], v[2]);
        assert_true(exact <= brute + 1e-12);
        assert_true(brute - exact < 0.01);
    }
    /* Degenerate (collinear) triangle: distance to the segment. */
    const double d0[3] = {0, 0, 0}, d1[3] = {1, 0, 0}, d2[3] = {2, 0, 0}, q[3] = {1.5, 3, 4};
    assert_true(fabs(sy_point_triangle_distance(q, d0, d1, d2, NULL) - 5) < 1e-12);
}

static void point_cone_distance_is_exact(void **state)
{
    (void)state;
    const double a[3] = {0, 0, 0}, b[3] = {0, 0, 1};
    const double out[3] = {2, 0, 0.5}, in[3] = {0.05, 0, 0.5}, cap[3] = {0, 0, 2}, rim[3] = {1.1, 0, 2};
    assert_true(fabs(sy_point_cone_distance(out, a, 0.1, b, 0.1) - 1.9) < 1e-12);
    assert_true(fabs(sy_point_cone_distance(in, a, 0.1, b, 0.1) - 0.05) < 1e-12);
    assert_true(fabs(sy_point_cone_distance(cap, a, 0.1, b, 0.1) - 1) < 1e-12);
    assert_true(fabs(sy_point_cone_distance(rim, a, 0.1, b, 0.1) - sqrt(2)) < 1e-12);
    /* A true cone (0.2 -> 0): the lateral line from (0, 0.2) to (1, 0). */
    const double p[3] = {0, 1, 1};
    double len = sqrt(1 + 0.04), want = fabs(0.2 * 1 + 1 * 1 - 0.2) / len; /* |(1)(rho) + 0.2 t - 0.2| / |n| */
    assert_true(fabs(sy_point_cone_distance(p, a, 0.2, b, 0.0) - want) < 1e-12);
}

/* Unit cube [0,1]^3 as 12 triangles. */
static void cube(double tri[12 * 9], double x0, double y0, double z0)
{
    static const int f[12][3] = {{0, 1, 3}, {0, 3, 2}, {4, 6, 7}, {4, 7, 5}, {0, 4, 5}, {0, 5, 1},
                                 {2, 3, 7}, {2, 7, 6}, {0, 2, 6}, {0, 6, 4}, {1, 5, 7}, {1, 7, 3}};
    for (int t = 0; t < 12; t++)
        for (int v = 0; v < 3; v++) {
            int i = f[t][v];
            tri[9 * t + 3 * v] = x0 + (i & 1);
            tri[9 * t + 3 * v + 1] = y0 + (i >> 1 & 1);
            tri[9 * t + 3 * v + 2] = z0 + (i >> 2 & 1);
        }
}

static void closed_cube_inside_is_zero(void **state)
{
    (void)state;
    double tri[12 * 9];
    cube(tri, 0, 0, 0);
    sy_eval_model closed = {0}, open = {0};
    sy_error err = {0};
    assert_int_equal(sy_eval_model_add_mesh(&closed, tri, 12, 1, &err), SY_OK);
    assert_int_equal(sy_eval_model_add_mesh(&open, tri, 12, 0, &err), SY_OK);
    /* Inside points, including ones level with the cube's edges and vertices. */
    const double pts[][3] = {{0.5, 0.5, 0.5}, {0.1, 0.2, 0.9}, {0.5, 0.5, 0.25}, {0.999, 0.001, 0.5},
                             {2, 0.5, 0.5}, {2, 2, 0.5}, {-1, -1, -1}, {0.5, 0.5, 1.3}};
    const double want_closed[] = {0, 0, 0, 0, 1, sqrt(2), sqrt(3), 0.3};
    const double want_open[] = {0.5, 0.1, 0.25, 0.001, 1, sqrt(2), sqrt(3), 0.3};
    double d[8];
    assert_int_equal(sy_model_distances(&closed, &pts[0][0], 8, d, &err), SY_OK);
    for (int i = 0; i < 8; i++) assert_true(fabs(d[i] - want_closed[i]) < 1e-12);
    assert_int_equal(sy_model_distances(&open, &pts[0][0], 8, d, &err), SY_OK);
    for (int i = 0; i < 8; i++) assert_true(fabs(d[i] - want_open[i]) < 1e-12);
    /* Many random inside points: all 0 under the parity vote. */
    double many[3000];
    unsigned s = 7;
    for (int i = 0; i < 3000; i++) {
        s = s * 1103515245u + 12345u;
        many[i] = 0.001 + 0.998 * ((s >> 8) % 100000) / 100000.0;
    }
    double dm[1000];
    assert_int_equal(sy_model_distances(&closed, many, 1000, dm, &err), SY_OK);
    for (int i = 0; i < 1000; i++) assert_true(dm[i] == 0);
    sy_eval_model_free(&closed);
    sy_eval_model_free(&open);
}

static void coverage_grows_with_distance(void **state)
{
    (void)state;
    double tri[12 * 9];
    cube(tri, 0, 0, 0);
    sy_eval_model m = {0};
    sy_error err = {0};
    assert_int_equal(sy_eval_model_add_mesh(&m, tri, 12, 0, &err), SY_OK);
    enum { N = 2000 };
    static double pts[3 * N], d[N];
    unsigned s = 99;
    for (int i = 0; i < 3 * N; i++) {
        s = s * 1103515245u + 12345u;
        pts[i] = -0.2 + 1.4 * ((s >> 8) % 100000) / 100000.0;
    }
    assert_int_equal(sy_model_distances(&m, pts, N, d, &err), SY_OK);
    double prev = -1;
    for (double eps = 0; eps <= 0.6; eps += 0.01) {
        double c = sy_coverage(d, N, eps);
        size_t brute = 0;
        for (int i = 0; i < N; i++) {
            const double *p = pts + 3 * i;
            double best = INFINITY;
            for (int t = 0; t < 12; t++) {
                double e = sy_point_triangle_distance(p, tri + 9 * t, tri + 9 * t + 3, tri + 9 * t + 6, NULL);
                if (e < best) best = e;
            }
            assert_true(fabs(best - d[i]) < 1e-12); /* the BVH finds the exact nearest */
            brute += best <= eps;
        }
        assert_true(c >= prev);
        assert_true(fabs(c - (double)brute / N) < 1e-12);
        prev = c;
    }
    assert_true(prev == 1.0);
    sy_surface_metrics sm;
    assert_int_equal(sy_surface_metrics_compute(&m, pts, N, 0.02, 0.01, &sm, &err), SY_OK);
    assert_true(sm.mean_distance > 0 && sm.rms_distance >= sm.mean_distance);
    assert_true(sm.p95_distance <= sm.hausdorff);
    /* The cube's surface is far from the sparse random points at places. */
    assert_true(sm.hausdorff_model_to_points > 0.05);
    sy_eval_model_free(&m);
}

static void skeleton_model_vs_its_own_surface(void **state)
{
    (void)state;
    sy_forest t;
    planar_tree(&t, 1, zero3, 0, NULL);
    sy_eval_model m = {0, NULL, t};
    sy_error err = {0};
    size_t n;
    double *pts = sy_model_surface_samples(&m, 0.01, &n, &err);
    assert_non_null(pts);
    assert_true(n > 1000);
    sy_surface_metrics s;
    assert_int_equal(sy_surface_metrics_compute(&m, pts, n, 0.02, 0.01, &s, &err), SY_OK);
    assert_true(s.mean_distance < 1e-6);
    assert_true(s.hausdorff < 1e-5);
    assert_true(s.coverage == 1);
    assert_true(s.hausdorff_model_to_points < 0.01);
    /* Points 1 cm outside a cylinder are 1 cm from it. */
    sy_forest cyl = {0};
    sy_eval_tree tr;
    memset(&tr, 0, sizeof tr);
    float p0[3] = {0, 0, 0}, p1[3] = {0, 0, 1};
    sy_skeleton_add(&tr.skel, p0, 0.1f, -1, 0, 0, &err);
    sy_skeleton_add(&tr.skel, p1, 0.1f, 0, 0, 0, &err);
    assert_int_equal(sy_forest_add(&cyl, &tr, &err), SY_OK);
    sy_eval_model cm = {0, NULL, cyl};
    double ring[3 * 36];
    for (int i = 0; i < 36; i++) {
        double ang = i * 0.17453292519943295;
        ring[3 * i] = 0.11 * cos(ang);
        ring[3 * i + 1] = 0.11 * sin(ang);
        ring[3 * i + 2] = 0.5;
    }
    assert_int_equal(sy_surface_metrics_compute(&cm, ring, 36, 0.02, 0.01, &s, &err), SY_OK);
    assert_true(fabs(s.mean_distance - 0.01) < 1e-6 && fabs(s.hausdorff - 0.01) < 1e-6);
    assert_true(s.coverage == 1);
    assert_true(s.hausdorff_model_to_points > 0.45); /* the cylinder's ends are far from the ring */
    free(pts);
    sy_forest_free(&t);
    sy_forest_free(&cyl);
}

/* ---- glTF ---- */

static void put32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (8 * i));
}

/* A GLB: one cube mesh, node translation (10, 0, 0) and two
 * EXT_mesh_gpu_instancing instances at (0,0,0) and (0,5,0) (glTF Y up). */
static void write_cube_glb(const char *path)
{
    char json[1200];
    int jl = snprintf(json, sizeof json,
                      "{\"asset\":{\"version\":\"2.0\"},\"extensionsUsed\":[\"EXT_mesh_gpu_instancing\"],\"scene\":0,"
                      "\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0,\"translation\":[10,0,0],\"extensions\":"
                      "{\"EXT_mesh_gpu_instancing\":{\"attributes\":{\"TRANSLATION\":2}}}}],"
                      "\"meshes\":[{\"primitives\":[{\"attributes\":{\"POSITION\":0},\"indices\":1}]}],"
                      "\"buffers\":[{\"byteLength\":192}],\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":96},"
                      "{\"buffer\":0,\"byteOffset\":96,\"byteLength\":72},{\"buffer\":0,\"byteOffset\":168,\"byteLength\":24}],"
                      "\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":8,\"type\":\"VEC3\",\"min\":[0,0,0],"
                      "\"max\":[1,1,1]},{\"bufferView\":1,\"componentType\":5123,\"count\":36,\"type\":\"SCALAR\"},"
                      "{\"bufferView\":2,\"componentType\":5126,\"count\":2,\"type\":\"VEC3\"}]}");
    while (jl % 4) json[jl++] = ' ';
    unsigned char bin[192];
    float pos[24];
    for (int i = 0; i < 8; i++) {
        pos[3 * i] = (float)(i & 1);
        pos[3 * i + 1] = (float)(i >> 1 & 1);
        pos[3 * i + 2] = (float)(i >> 2 & 1);
    }
    memcpy(bin, pos, 96);
    static const int f[12][3] = {{0, 1, 3}, {0, 3, 2}, {4, 6, 7}, {4, 7, 5}, {0, 4, 5}, {0, 5, 1},
                                 {2, 3, 7}, {2, 7, 6}, {0, 2, 6}, {0, 6, 4}, {1, 5, 7}, {1, 7, 3}};
    for (int t = 0; t < 12; t++)
        for (int v = 0; v < 3; v++) {
            uint16_t ix = (uint16_t)f[t][v];
            memcpy(bin + 96 + 2 * (3 * t + v), &ix, 2);
        }
    float inst[6] = {0, 0, 0, 0, 5, 0};
    memcpy(bin + 168, inst, 24);
    size_t total = 12 + 8 + (size_t)jl + 8 + sizeof bin;
    unsigned char *g = calloc(total, 1);
    assert_non_null(g);
    memcpy(g, "glTF", 4);
    put32(g + 4, 2);
    put32(g + 8, (uint32_t)total);
    put32(g + 12, (uint32_t)jl);
    memcpy(g + 16, "JSON", 4);
    memcpy(g + 20, json, (size_t)jl);
    put32(g + 20 + jl, sizeof bin);
    memcpy(g + 24 + jl, "BIN\0", 4);
    memcpy(g + 28 + jl, bin, sizeof bin);
    assert_int_equal(write_bytes(path, g, total), 0);
    free(g);
}

static void glb_instances_and_axes(void **state)
{
    (void)state;
    const char *path = tmp_path("cubes.glb");
    write_cube_glb(path);
    sy_eval_model m;
    sy_error err = {0};
    if (sy_eval_load_model(path, 1, &m, &err)) fail_msg("%s", err.msg);
    assert_int_equal(m.n_meshes, 1);
    assert_int_equal(m.meshes[0].n, 24);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < 24 * 3; i++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], m.meshes[0].tri[3 * i + k]);
            hi[k] = fmax(hi[k], m.meshes[0].tri[3 * i + k]);
        }
    /* glTF (x, y, z) -> (x, -z, y): x in [10, 11], y in [-1, 0], z in [0, 6]. */
    assert_true(lo[0] == 10 && hi[0] == 11 && lo[1] == -1 && hi[1] == 0 && lo[2] == 0 && hi[2] == 6);
    const double q[3][3] = {{10.5, -0.5, 0.5}, {10.5, -0.5, 5.5}, {10.5, -0.5, 3}};
    double d[3];
    assert_int_equal(sy_model_distances(&m, &q[0][0], 3, d, &err), SY_OK);
    assert_true(d[0] == 0 && d[1] == 0 && fabs(d[2] - 2) < 1e-12);
    sy_eval_model_free(&m);
    /* Broken files fail with one line naming the file. */
    const char *junk = tmp_path("junk.glb");
    assert_int_equal(write_bytes(junk, "glTF\2\0\0\0\50\0\0\0", 12), 0);
    assert_int_equal(sy_eval_load_model(junk, 0, &m, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "junk.glb"));
    assert_null(strchr(err.msg, '\n'));
    assert_int_equal(sy_eval_load_model(tmp_path("x.stl"), 0, &m, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "unknown model kind"));
}

/* ---- segmentation ---- */

static void mixedconifer_instances(void **state)
{
    (void)state;
    sy_cloud c;
    sy_error err = {0};
    if (sy_read_cloud(data_path("real/lidr/MixedConifer.las"), &c, &err)) fail_msg("%s", err.msg);
    const double *id = sy_cloud_attr(&c, "treeID");
    assert_non_null(id);
    sy_segmentation_metrics m;
    assert_int_equal(sy_segmentation_metrics_labels(id, id, c.n, &m, &err), SY_OK);
    assert_int_equal(m.n_truth, 205);
    assert_int_equal(m.n_matched, 205);
    assert_true(m.f1 == 1 && m.precision == 1 && m.recall == 1);
    double *pred = malloc(c.n * sizeof *pred);
    assert_non_null(pred);
    /* Tree sizes; pick one with an even count to split exactly in half, and
     * two of different sizes to merge. */
    double max_id = 0;
    for (size_t i = 0; i < c.n; i++)
        if (id[i] > max_id) max_id = id[i];
    size_t *count = calloc((size_t)max_id + 1, sizeof *count);
    for (size_t i = 0; i < c.n; i++)
        if (!isnan(id[i]) && id[i] > 0) count[(size_t)id[i]]++;
    size_t even = 0, a = 0, b = 0;
    for (size_t t = 1; t <= (size_t)max_id; t++) {
        if (!even && count[t] >= 10 && count[t] % 2 == 0) even = t;
        else if (!a && count[t] >= 10) a = t;
        else if (a && !b && count[t] >= 10 && count[t] != count[a] && t != even) b = t;
    }
    assert_true(even && a && b);
    /* Split: halves have IoU exactly 0.5, which is not > 0.5. */
    size_t seen = 0;
    for (size_t i = 0; i < c.n; i++) {
        pred[i] = id[i];
        if (id[i] == (double)even && seen++ >= count[even] / 2) pred[i] = max_id + 1;
    }
    assert_int_equal(sy_segmentation_metrics_labels(id, pred, c.n, &m, &err), SY_OK);
    assert_int_equal(m.n_pred, 206);
    assert_int_equal(m.n_matched, 204);
    assert_true(fabs(m.f1 - 2.0 * 204 / (205 + 206)) < 1e-12);
    /* Merge b into a: the larger of the two still matches the merged one. */
    for (size_t i = 0; i < c.n; i++) pred[i] = id[i] == (double)b ? (double)a : id[i];
    assert_int_equal(sy_segmentation_metrics_labels(id, pred, c.n, &m, &err), SY_OK);
    assert_int_equal(m.n_pred, 204);
    assert_int_equal(m.n_matched, 204);
    assert_true(m.precision == 1);
    assert_true(fabs(m.recall - 204.0 / 205) < 1e-12);
    /* Reordered copy: matched by nearest point instead of by index. */
    sy_cloud r;
    assert_int_equal(sy_cloud_copy(&r, &c, &err), SY_OK);
    double *rid = sy_cloud_attr(&r, "treeID");
    for (size_t i = 0; i < c.n; i++) {
        size_t j = c.n - 1 - i;
        for (int k = 0; k < 3; k++) r.xyz[3 * i + k] = c.xyz[3 * j + k];
        rid[i] = id[j];
    }
    assert_int_equal(sy_segmentation_metrics_clouds(&c, "t.las", "treeID", &r, "p.las", "treeID", 0.01, &m, &err), SY_OK);
    assert_int_equal(m.n_unmatched_points, 0);
    assert_int_equal(m.n_matched, 205);
    assert_true(m.f1 == 1);
    assert_int_equal(sy_segmentation_metrics_clouds(&c, "t.las", "nope", &r, "p.las", "treeID", 0.01, &m, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "t.las: no attribute 'nope'"));
    sy_cloud_free(&r);
    free(count);
    free(pred);
    sy_cloud_free(&c);
}

/* ---- species ---- */

static void species_scores(void **state)
{
    (void)state;
    const char *truth_csv = "id,species\n1,a\n2,a\n3,a\n4,a\n5,b\n6,b\n7,b\n8,c\n9,c\n10,c\n";
    const char *pred_csv = "# model v1\r\n\"1\",a\r\n2,a\r\n3,a\r\n4,b\r\n5,b\r\n6,b\r\n7,c\r\n8,c\r\n9,c\r\n10 , c\r\n";
    sy_label_table t, p;
    sy_error err = {0};
    assert_int_equal(sy_label_table_parse_csv("t.csv", truth_csv, strlen(truth_csv), &t, &err), SY_OK);
    assert_int_equal(sy_label_table_parse_csv("p.csv", pred_csv, strlen(pred_csv), &p, &err), SY_OK);
    assert_int_equal(t.n, 10);
    assert_int_equal(p.n, 10);
    sy_confusion c;
    assert_int_equal(sy_confusion_build(&t, &p, &c, &err), SY_OK);
    assert_int_equal(c.n_classes, 3);
    const size_t want[9] = {3, 1, 0, 0, 2, 1, 0, 0, 3};
    for (int i = 0; i < 9; i++) assert_int_equal(c.matrix[i], want[i]);
    assert_true(fabs(c.accuracy - 0.8) < 1e-12);
    double f_a = 2 * 1 * 0.75 / 1.75, f_b = 2.0 / 3, f_c = 2 * 0.75 / 1.75;
    assert_true(fabs(c.macro_f1 - (f_a + f_b + f_c) / 3) < 1e-12);
    /* PNG: decodes, with the planned size. */
    const char *png = tmp_path("confusion.png");
    assert_int_equal(sy_confusion_png(&c, png, &err), SY_OK);
    int w, h, ch, ww, hh;
    unsigned char *img = stbi_load(png, &w, &h, &ch, 3);
    assert_non_null(img);
    sy_confusion_png_size(&c, &ww, &hh);
    assert_int_equal(w, ww);
    assert_int_equal(h, hh);
    assert_int_equal(ch, 3);
    size_t dark = 0;
    for (int i = 0; i < w * h; i++) dark += img[3 * i] < 100;
    assert_true(dark > 200); /* text and the deep-blue diagonal cells */
    stbi_image_free(img);
    sy_confusion_free(&c);
    /* A missing prediction is a wrong answer in its own column. */
    sy_label_table_free(&p);
    const char *short_csv = "1,a\n2,a\n3,a\n4,b\n5,b\n6,b\n7,c\n8,c\n9,c\n";
    assert_int_equal(sy_label_table_parse_csv("p.csv", short_csv, strlen(short_csv), &p, &err), SY_OK);
    assert_int_equal(sy_confusion_build(&t, &p, &c, &err), SY_OK);
    assert_int_equal(c.n_classes, 4);
    assert_string_equal(c.labels[3], SY_MISSING_LABEL);
    assert_int_equal(c.n_missing, 1);
    assert_true(fabs(c.accuracy - 0.7) < 1e-12);
    assert_int_equal(c.matrix[2 * 4 + 3], 1);
    f_c = 2.0 / 3; /* c: 2 right of 3 true, 2 right of 3 predicted (one of them b) */
    assert_true(fabs(c.macro_f1 - (f_a + f_b + f_c) / 3) < 1e-12);
    sy_confusion_free(&c);
    sy_label_table_free(&p);
    sy_label_table_free(&t);
    /* Malformed CSV lines name the file and line. */
    const char *bad = "1,a\n2,a,x\n";
    assert_int_equal(sy_label_table_parse_csv("b.csv", bad, strlen(bad), &t, &err), SY_EINPUT);
    assert_string_equal(err.msg, "b.csv:2: expected two fields 'id,species', found more");
    const char *quote = "1,\"a\n";
    assert_int_equal(sy_label_table_parse_csv("q.csv", quote, strlen(quote), &t, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "q.csv:1:"));
}

/* Out-of-range options are errors naming the field; the stage checks them
 * too (no silent fallback to the default step). */
static void skeleton_metrics_options_are_checked(void **state)
{
    (void)state;
    sy_error err = {0};
    sy_skeleton_metrics_options d = sy_skeleton_metrics_options_default(), o;
    assert_int_equal(sy_skeleton_metrics_options_check(&d, &err), SY_OK);
    static const struct {
        size_t offset;
        double value;
        const char *field;
    } bad[] = {
        {offsetof(sy_skeleton_metrics_options, sample_step), 0, "sample_step"},
        {offsetof(sy_skeleton_metrics_options, sample_step), NAN, "sample_step"},
        {offsetof(sy_skeleton_metrics_options, min_tolerance), -0.01, "min_tolerance"},
        {offsetof(sy_skeleton_metrics_options, radius_factor), INFINITY, "radius_factor"},
        {offsetof(sy_skeleton_metrics_options, thick_radius), -1, "thick_radius"},
        {offsetof(sy_skeleton_metrics_options, bifurcation_radius), NAN, "bifurcation_radius"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        o = d;
        memcpy((char *)&o + bad[i].offset, &bad[i].value, sizeof(double));
        assert_int_equal(sy_skeleton_metrics_options_check(&o, &err), SY_EUSAGE);
        assert_non_null(strstr(err.msg, bad[i].field));
    }
    sy_forest t;
    planar_tree(&t, 1, zero3, 0, NULL);
    o = d;
    o.sample_step = -1;
    sy_skeleton_metrics m;
    assert_int_equal(sy_skeleton_metrics_compute(&t, &t, &o, &m, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "sample_step"));
    sy_forest_free(&t);
}

/* The silhouette of a 4 m x 3 m x 2 m box against points on its faces: with
 * a dense scan (2 cm: splats of a pixel or so, drawn point by point) and a
 * sparse one (0.5 m, an airborne spacing: 30-pixel splats, drawn at once by
 * the distance transform), both views agree with the model (IoU >= 0.85),
 * and the wide splats cover the union of the model's disks. */
static void box_faces(double step, double **pts, size_t *n)
{
    const double L[3] = {4, 3, 2};
    size_t cap = 0, k = 0;
    for (int ax = 0; ax < 3; ax++) {
        int a = (ax + 1) % 3, b = (ax + 2) % 3;
        cap += 2 * (size_t)(L[a] / step + 1) * (size_t)(L[b] / step + 1);
    }
    double *p = malloc(3 * cap * sizeof *p);
    assert_non_null(p);
    for (int ax = 0; ax < 3; ax++) {
        int a = (ax + 1) % 3, b = (ax + 2) % 3;
        for (int side = 0; side < 2; side++)
            for (double u = 0; u <= L[a] + 1e-9; u += step)
                for (double w = 0; w <= L[b] + 1e-9; w += step) {
                    p[3 * k + ax] = side * L[ax], p[3 * k + a] = u, p[3 * k + b] = w;
                    k++;
                }
    }
    *pts = p;
    *n = k;
}

static void silhouette_of_dense_and_sparse_scans(void **state)
{
    (void)state;
    const double L[3] = {4, 3, 2};
    double tri[12 * 9];
    size_t nt = 0;
    for (int ax = 0; ax < 3; ax++) {
        int a = (ax + 1) % 3, b = (ax + 2) % 3;
        for (int side = 0; side < 2; side++) {
            double q[4][3];
            for (int c = 0; c < 4; c++) {
                q[c][ax] = side * L[ax];
                q[c][a] = (c == 1 || c == 2) ? L[a] : 0;
                q[c][b] = (c >= 2) ? L[b] : 0;
            }
            const int t[2][3] = {{0, 1, 2}, {0, 2, 3}};
            for (int h = 0; h < 2; h++, nt++)
                for (int c = 0; c < 3; c++) memcpy(tri + 9 * nt + 3 * c, q[t[h][c]], sizeof q[0]);
        }
    }
    const double steps[2] = {0.02, 0.5};
    for (int k = 0; k < 2; k++) {
        double *pts;
        size_t n;
        box_faces(steps[k], &pts, &n);
        sy_silhouette_metrics m;
        sy_error err = {0};
        assert_int_equal(sy_silhouette_metrics_compute(tri, nt, NULL, pts, NULL, n, &m, NULL, &err), SY_OK);
        printf("box, scan spacing %.2f m: splat %.3f m, IoU mean %.4f min %.4f\n", steps[k], m.splat_radius, m.iou_mean,
               m.iou_min);
        assert_float_equal(m.splat_radius, steps[k], 0.01 * steps[k]);
        assert_true(m.iou_min >= 0.85 && m.iou_mean <= 1.0);
        free(pts);
    }
}

/* The asset's crown width counts its drawn area: a 1 m square plate beside
 * 3,000 triangles of a square millimetre each, 2 m off (0.3 % of the area),
 * against a scan of the plate. The sampler puts a few points on every
 * triangle however small; counted one each, the specks held a fifth of the
 * samples and the width came out 1.97 m. */
static void crown_width_counts_area(void **state)
{
    (void)state;
    const size_t specks = 3000;
    double *tri = malloc((2 + specks) * 9 * sizeof *tri);
    assert_non_null(tri);
    const double plate[18] = {0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 0, 1, 1, 1, 1, 0, 1, 1};
    memcpy(tri, plate, sizeof plate);
    for (size_t i = 0; i < specks; i++) {
        double x = 3 + 0.002 * (double)(i % 50), y = 0.002 * (double)(i / 50), *t = tri + 9 * (2 + i);
        const double v[9] = {x, y, 1, x + 0.0014, y, 1, x, y + 0.0014, 1};
        memcpy(t, v, sizeof v);
    }
    size_t n = 0;
    double *pts = malloc(101 * 101 * 3 * sizeof *pts);
    assert_non_null(pts);
    for (int i = 0; i <= 100; i++)
        for (int j = 0; j <= 100; j++, n++) pts[3 * n] = 0.01 * i, pts[3 * n + 1] = 0.01 * j, pts[3 * n + 2] = 1;
    sy_silhouette_metrics m;
    sy_error err = {0};
    assert_int_equal(sy_silhouette_metrics_compute(tri, 2 + specks, NULL, pts, NULL, n, &m, NULL, &err), SY_OK);
    printf("plate and specks: scan width %.3f m, asset %.3f m\n", m.scan_width, m.model_width);
    assert_float_equal(m.scan_width, 0.9, 0.01);
    assert_float_equal(m.model_width, 0.9, 0.05);
    free(pts);
    free(tri);
}

/* A 1 m square card upright in the x-z plane whose texture is clear on its
 * left half (alpha 0 for u < 0.5, cutoff 0.5), and a scan of its right half
 * every centimetre. The cut-out points into the card's own arrays. */
typedef struct {
    double tri[18];
    float uv[12];
    int32_t map[2];
    unsigned char alpha[2];
    sy_gltf_alpha_map am;
    sy_gltf_cutout cut;
    double *pts;
    size_t n;
} half_clear_card;

static void half_clear_card_make(half_clear_card *c)
{
    const double tri[18] = {0, 0, 0, 1, 0, 0, 1, 0, 1, 0, 0, 0, 1, 0, 1, 0, 0, 1};
    const float uv[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
    memcpy(c->tri, tri, sizeof tri);
    memcpy(c->uv, uv, sizeof uv);
    c->map[0] = c->map[1] = 0;
    c->alpha[0] = 0, c->alpha[1] = 255;
    c->am = (sy_gltf_alpha_map){2, 1, 0.5f, c->alpha};
    c->cut = (sy_gltf_cutout){c->uv, c->map, 1, &c->am};
    c->pts = malloc(51 * 101 * 3 * sizeof *c->pts);
    assert_non_null(c->pts);
    c->n = 0;
    for (int i = 0; i <= 50; i++)
        for (int j = 0; j <= 100; j++, c->n++)
            c->pts[3 * c->n] = 0.5 + 0.01 * i, c->pts[3 * c->n + 1] = 0, c->pts[3 * c->n + 2] = 0.01 * j;
}

/* An alpha-tested card counts where it is drawn: a 1 m square card whose
 * texture is clear on its left half, scanned on its right half only. With
 * the cut-out the asset's silhouette is the scan's; taken whole, the card
 * is twice as wide in the side views (IoU about 0.5 there). The profile's
 * area is the drawn half. */
static void alpha_tested_cards_count_where_drawn(void **state)
{
    (void)state;
    half_clear_card card;
    half_clear_card_make(&card);
    sy_silhouette_metrics with, whole;
    sy_error err = {0};
    assert_int_equal(sy_silhouette_metrics_compute(card.tri, 2, &card.cut, card.pts, NULL, card.n, &with, NULL, &err), SY_OK);
    assert_int_equal(sy_silhouette_metrics_compute(card.tri, 2, NULL, card.pts, NULL, card.n, &whole, NULL, &err), SY_OK);
    for (int v = 0; v < 6; v++) printf("view %d: IoU %.3f with the cut-out, %.3f whole\n", v, with.iou[v], whole.iou[v]);
    /* Every view but the edge-on one (azimuth 0) sees the clear half. */
    assert_true(with.iou_min >= 0.85 && with.iou_mean >= 0.95);
    assert_true(whole.iou[2] <= 0.6 && with.iou[2] >= 0.95);
    assert_true(with.width_error > -0.1 && with.width_error < 0.1);
    size_t nd = 0;
    double *drawn = sy_drawn_surface_points(card.tri, 2, &card.cut, 0.01, &nd, NULL, &err);
    assert_non_null(drawn);
    for (size_t i = 0; i < nd; i++) assert_true(drawn[3 * i] >= 0.49);
    free(drawn);
    free(card.pts);
}

/* The alpha test reads an RGB PNG whose tRNS chunk makes black clear:
 * stb's header scan says 3 components for it (it stops at the IHDR), so an
 * image is left undecoded as opaque only when no tRNS says otherwise. A
 * 1 m card (the fuzz corpus's alpha_mask_card, its texture a 2 x 1 RGB PNG,
 * black then white, black transparent) is drawn on its right half only. */
static void rgb_png_with_trns_is_cut(void **state)
{
    (void)state;
    static const char gltf[] =
        "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],"
        "\"meshes\":[{\"name\":\"leaf_card\",\"primitives\":[{\"attributes\":{\"POSITION\":0,\"TEXCOORD_0\":1"
        "},\"indices\":2,\"material\":0}]}],\"materials\":[{\"name\":\"leaf\",\"alphaMode\":\"MASK\",\"alphaC"
        "utoff\":0.5,\"doubleSided\":true,\"pbrMetallicRoughness\":{\"baseColorTexture\":{\"index\":0},\"base"
        "ColorFactor\":[1,1,1,1]}}],\"textures\":[{\"source\":0}],\"images\":[{\"uri\":\"data:image/png;base6"
        "4,iVBORw0KGgoAAAANSUhEUgAAAAIAAAABCAIAAAB7QOjdAAAABnRSTlMAAAAAAABupgeRAAAAD0lEQVR4nGNgYGD4//8/AAYBAv"
        "4CsjmuAAAAAElFTkSuQmCC\"}],\"buffers\":[{\"byteLength\":92,\"uri\":\"data:application/octet-stream;b"
        "ase64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAACAPwAAgD8AAAAAAAAAAAAAgD8AAAAAAAAAAAAAAAAAAIA/AAAAAAAAgD8AAI"
        "A/AAAAAAAAgD8AAAEAAgAAAAIAAwA=\"}],\"bufferViews\":[{\"buffer\":0,\"byteOffset\":0,\"byteLength\":48"
        "},{\"buffer\":0,\"byteOffset\":48,\"byteLength\":32},{\"buffer\":0,\"byteOffset\":80,\"byteLength\":"
        "12}],\"accessors\":[{\"bufferView\":0,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\",\"min\":["
        "0,0,0],\"max\":[1,1,0]},{\"bufferView\":1,\"componentType\":5126,\"count\":4,\"type\":\"VEC2\"},{\"b"
        "ufferView\":2,\"componentType\":5123,\"count\":6,\"type\":\"SCALAR\"}]}";
    static const unsigned char png[] = {137, 80, 78, 71, 13, 10, 26, 10, 0, 0, 0, 13, 73, 72, 68, 82, 0, 0, 0, 2,
                                        0, 0, 0, 1, 8, 2, 0, 0, 0};
    int w, h, c;
    /* Only the header: what stb's scan sees of this PNG. */
    assert_int_equal(stbi_info_from_memory(png, (int)sizeof png, &w, &h, &c), 1);
    assert_int_equal(c, 3);
    const char *path = tmp_path("trns_card.gltf");
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    fputs(gltf, f);
    fclose(f);
    double *tri = NULL;
    size_t nt = 0, n = 0;
    sy_gltf_cutout cut;
    sy_error err = {0};
    sy_code rc = sy_gltf_read_surface(path, &tri, &nt, &cut, &err);
    if (rc) printf("%s\n", err.msg);
    assert_int_equal(rc, SY_OK);
    assert_int_equal(nt, 2);
    double *p = sy_drawn_surface_points(tri, nt, &cut, 0.01, &n, NULL, &err);
    assert_non_null(p);
    size_t left = 0;
    for (size_t i = 0; i < n; i++) left += p[3 * i] < 0.45;
    printf("RGB + tRNS card: %zu drawn samples, %zu on the clear half\n", n, left);
    assert_true(n > 2000 && left == 0);
    free(p);
    free(tri);
    sy_gltf_cutout_free(&cut);
}

/* What the scores are made of: each view's mask pixels give its IoU exactly;
 * the profiles hold every scan point and the model's drawn area (the half-
 * clear card: 1 m^2 whole, 0.5 m^2 cut); the PNG shows each view's pixels in
 * their colours (3 x 2 views of 256^2 under 12-pixel labels, 4-pixel gutters). */
static void masks_and_profiles_behind_the_scores(void **state)
{
    (void)state;
    half_clear_card card;
    half_clear_card_make(&card);
    const size_t per = SY_SILHOUETTE_RES * SY_SILHOUETTE_RES;
    unsigned char *masks = malloc(SY_SILHOUETTE_VIEWS * per);
    assert_non_null(masks);
    for (int with_cut = 0; with_cut < 2; with_cut++) {
        sy_silhouette_metrics m;
        sy_error err = {0};
        assert_int_equal(sy_silhouette_metrics_compute(card.tri, 2, with_cut ? &card.cut : NULL, card.pts, NULL, card.n, &m, masks, &err), SY_OK);
        size_t model_only[SY_SILHOUETTE_VIEWS];
        double precision = 0, recall = 0;
        for (int v = 0; v < SY_SILHOUETTE_VIEWS; v++) {
            size_t both = 0, any = 0;
            model_only[v] = 0;
            for (size_t i = 0; i < per; i++) {
                unsigned char b = masks[(size_t)v * per + i];
                assert_true(b <= (SY_MASK_SCAN | SY_MASK_MODEL));
                both += b == (SY_MASK_SCAN | SY_MASK_MODEL), any += b != 0, model_only[v] += b == SY_MASK_MODEL;
            }
            assert_true(any > 0);
            assert_float_equal(m.iou[v], (double)both / (double)any, 1e-12);
            precision += (double)both / (double)(both + model_only[v]) / SY_SILHOUETTE_VIEWS;
            recall += (double)both / (double)(any - model_only[v]) / SY_SILHOUETTE_VIEWS;
        }
        /* Precision and recall are the views' means, counted from the same
         * masks; whole, the card's clear half draws where nothing was
         * scanned, which costs precision alone. */
        assert_float_equal(m.precision, precision, 1e-12);
        assert_float_equal(m.recall, recall, 1e-12);
        printf("%s: silhouette precision %.3f, recall %.3f\n", with_cut ? "cut out" : "whole", m.precision, m.recall);
        assert_true(m.recall >= 0.97);
        assert_true(with_cut ? m.precision >= 0.95 : m.precision <= 0.8);
        /* Whole, the clear half is drawn: model-only pixels at azimuth 90. */
        assert_true(with_cut ? model_only[2] < per / 100 : model_only[2] > per / 10);
        double pts_sum = 0, area = 0;
        for (int b = 0; b < SY_SILHOUETTE_BINS; b++) pts_sum += m.profile_scan[b], area += m.profile_model[b];
        assert_float_equal(pts_sum, (double)card.n, 0);
        assert_float_equal(area, with_cut ? 0.5 : 1.0, 0.02);
        assert_float_equal(m.profile_z0, 0, 1e-12);
        assert_float_equal(m.profile_z0 + SY_SILHOUETTE_BINS * m.profile_dz, 1.0, 1e-9);
        if (with_cut) continue;
        const char *png = tmp_path("silhouette.png");
        assert_int_equal(sy_silhouette_png(masks, png, &err), SY_OK);
        int w, h, ch;
        unsigned char *img = stbi_load(png, &w, &h, &ch, 3);
        assert_non_null(img);
        assert_int_equal(w, 3 * SY_SILHOUETTE_RES + 4 * 4);
        assert_int_equal(h, 2 * SY_SILHOUETTE_RES + 3 * 4 + 2 * 12);
        /* Azimuth 90 is the third view of the top row; blue is model only. */
        size_t blue = 0;
        for (int y = 4 + 12; y < 4 + 12 + SY_SILHOUETTE_RES; y++)
            for (int x = 4 + 2 * (SY_SILHOUETTE_RES + 4); x < 4 + 2 * (SY_SILHOUETTE_RES + 4) + SY_SILHOUETTE_RES; x++) {
                const unsigned char *q = img + 3 * ((size_t)y * (size_t)w + (size_t)x);
                blue += q[0] == 40 && q[1] == 80 && q[2] == 230;
            }
        assert_int_equal(blue, model_only[2]);
        stbi_image_free(img);
        /* An unwritable path is an error naming it, and nothing is left. */
        assert_int_not_equal(sy_silhouette_png(masks, "/nonexistent-dir/x.png", &err), SY_OK);
        assert_non_null(strstr(err.msg, "/nonexistent-dir"));
    }
    free(masks);
    free(card.pts);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(alpha_tested_cards_count_where_drawn),
        cmocka_unit_test(masks_and_profiles_behind_the_scores),
        cmocka_unit_test(rgb_png_with_trns_is_cut),
        cmocka_unit_test(skeleton_vs_itself_is_perfect),
        cmocka_unit_test(skeleton_metrics_options_are_checked),
        cmocka_unit_test(long_edges_take_bounded_samples),
        cmocka_unit_test(shifted_copies),
        cmocka_unit_test(removed_branches_lower_recall_by_their_length),
        cmocka_unit_test(radius_scaled_by_1_2),
        cmocka_unit_test(truth_json_round_trip_and_errors),
        cmocka_unit_test(point_triangle_distance_is_exact),
        cmocka_unit_test(point_cone_distance_is_exact),
        cmocka_unit_test(closed_cube_inside_is_zero),
        cmocka_unit_test(coverage_grows_with_distance),
        cmocka_unit_test(skeleton_model_vs_its_own_surface),
        cmocka_unit_test(glb_instances_and_axes),
        cmocka_unit_test(mixedconifer_instances),
        cmocka_unit_test(species_scores),
        cmocka_unit_test(silhouette_of_dense_and_sparse_scans), cmocka_unit_test(crown_width_counts_area),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
