/* Species classification: features (invariance to position and heading,
 * robustness to density), JointBoost (separable data, determinism across
 * thread counts, sharing), the model file (round trip, damage, foreign files)
 * and the confidence rule and spatial voting. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "classify/classify.h"
#include "stages/core/parallel.h"
#include "synthetic_tree.h"

static float *features_of(const sy_cloud *c)
{
    float *f = calloc(sy_feature_count(), sizeof *f);
    sy_error err = {0};
    sy_features_options o = sy_features_options_default();
    assert_non_null(f);
    assert_int_equal(sy_features_compute(c, &o, f, NULL, &err), SY_OK);
    return f;
}

static void features_have_names_and_count(void **state)
{
    (void)state;
    size_t n = sy_feature_count();
    assert_true(n > 200);
    char (*names)[SY_FEATURE_NAME_MAX] = malloc(n * sizeof *names), extra[SY_FEATURE_NAME_MAX];
    assert_non_null(names);
    for (size_t i = 0; i < n; i++) {
        assert_ptr_equal(sy_feature_name(i, names[i]), names[i]);
        for (size_t j = 0; j < i; j++) assert_string_not_equal(names[i], names[j]);
    }
    assert_null(sy_feature_name(n, extra));
    free(names);
}

static size_t index_of(const char *name)
{
    char at[SY_FEATURE_NAME_MAX];
    for (size_t i = 0; i < sy_feature_count(); i++)
        if (!strcmp(sy_feature_name(i, at), name)) return i;
    fail_msg("no feature %s", name);
    return 0;
}

/* Moving and turning the tree changes the voxel grid's alignment only: the
 * scalar features agree to a few per cent, the histograms closely. */
static void features_invariant_to_position_and_heading(void **state)
{
    (void)state;
    syn_tree t;
    syn_tree_make(&t, 1, 1);
    sy_cloud a, b;
    sy_error err = {0};
    assert_int_equal(syn_sample(&t, 60000, 0.4, 0.003, 5, &a, &err), SY_OK);
    assert_int_equal(sy_cloud_copy(&b, &a, &err), SY_OK);
    double ang = 37 * 3.14159265358979323846 / 180, cs = cos(ang), sn = sin(ang);
    for (size_t i = 0; i < b.n; i++) {
        float x = b.xyz[3 * i], y = b.xyz[3 * i + 1];
        b.xyz[3 * i] = (float)(cs * x - sn * y + 3.5);
        b.xyz[3 * i + 1] = (float)(sn * x + cs * y - 2.25);
        b.xyz[3 * i + 2] += 1.5f;
    }
    b.origin[0] += 512000, b.origin[1] += 5400000;
    float *fa = features_of(&a), *fb = features_of(&b);
    const char *scalars[] = {"height_m", "crown_width_m", "crown_base_m", "crown_pca_major_m", "height_mean_rel",
                             "radius_mean_rel", "hull_volume_m3"};
    for (size_t k = 0; k < sizeof scalars / sizeof *scalars; k++) {
        size_t i = index_of(scalars[k]);
        assert_true(fa[i] > 0);
        if (fabsf(fa[i] - fb[i]) > 0.05f * fabsf(fa[i]) + 0.05f)
            fail_msg("%s: %g vs %g after moving and turning", scalars[k], fa[i], fb[i]);
    }
    double l1 = 0;
    for (int b2 = 0; b2 < 32; b2++) {
        char name[40];
        snprintf(name, sizeof name, "vertical_density_b%02d", b2);
        size_t i = index_of(name);
        l1 += fabs(fa[i] - fb[i]);
    }
    assert_true(l1 < 0.1);
    free(fa), free(fb);
    sy_cloud_free(&a), sy_cloud_free(&b);
}

/* A quarter of the points (a sparser scan of the same tree): the shape
 * features stay within 10%. */
static void features_robust_to_density(void **state)
{
    (void)state;
    syn_tree t;
    syn_tree_make(&t, 1, 1);
    sy_cloud a, b;
    sy_error err = {0};
    assert_int_equal(syn_sample(&t, 80000, 0.4, 0.003, 9, &a, &err), SY_OK);
    assert_int_equal(syn_sample(&t, 20000, 0.4, 0.003, 10, &b, &err), SY_OK);
    float *fa = features_of(&a), *fb = features_of(&b);
    const char *scalars[] = {"height_m", "crown_width_m", "crown_pca_major_m", "height_mean_rel", "hull_volume_m3"};
    for (size_t k = 0; k < sizeof scalars / sizeof *scalars; k++) {
        size_t i = index_of(scalars[k]);
        if (fabsf(fa[i] - fb[i]) > 0.1f * fabsf(fa[i]))
            fail_msg("%s: %g at 80k points vs %g at 20k", scalars[k], fa[i], fb[i]);
    }
    /* The 7 m trunk's last metre is a thin twig; the crown reaches ~6.5 m. */
    float h = fa[index_of("height_m")];
    assert_true(h > 6.0f && h < 7.2f);
    free(fa), free(fb);
    sy_cloud_free(&a), sy_cloud_free(&b);
}

static void features_reject_tiny_clouds(void **state)
{
    (void)state;
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_cloud_init(&c, 10, &err), SY_OK);
    float f[512];
    sy_features_options o = sy_features_options_default();
    assert_int_equal(sy_features_compute(&c, &o, f, NULL, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "32"));
    o.voxel = 0;
    assert_int_equal(sy_features_options_check(&o, &err), SY_EUSAGE);
    sy_cloud_free(&c);
}

/* Three Gaussian classes in 6 dimensions, 6 sigma apart along two of them
 * (Bayes error ~0.1%). */
static void blobs(size_t n, uint64_t seed, float *X, int *y)
{
    uint64_t s = seed;
    for (size_t i = 0; i < n; i++) {
        int c = (int)(i % 3);
        y[i] = c;
        for (int f = 0; f < 6; f++) X[i * 6 + f] = (float)syn_normal(&s);
        X[i * 6 + 1] += 6.0f * (float)(c == 1);
        X[i * 6 + 4] += 6.0f * (float)(c == 2);
    }
}

static void jointboost_learns_separable_classes(void **state)
{
    (void)state;
    enum { N = 300, NT = 300 };
    float X[N * 6], XT[NT * 6];
    int y[N], yt[NT];
    blobs(N, 1, X, y);
    blobs(NT, 2, XT, yt);
    const char *names[3] = {"alpha", "beta", "gamma"};
    sy_jb_options o = sy_jb_options_default();
    sy_jb_model m;
    sy_jb_report r;
    sy_error err = {0};
    assert_int_equal(sy_jb_train(X, N, 6, y, 3, names, 7, &o, &m, &r, &err), SY_OK);
    assert_true(m.n_rounds >= 1 && m.n_rounds <= (size_t)o.rounds);
    assert_true(r.holdout_accuracy >= 0.95);
    size_t ok = 0;
    for (size_t i = 0; i < NT; i++) {
        double p[3];
        sy_jb_predict(&m, XT + i * 6, p);
        assert_float_equal(p[0] + p[1] + p[2], 1.0, 1e-9);
        for (int c = 0; c < 3; c++) assert_true(p[c] >= 0 && p[c] <= 1);
        ok += (p[yt[i]] > p[(yt[i] + 1) % 3] && p[yt[i]] > p[(yt[i] + 2) % 3]);
    }
    assert_true(ok >= (size_t)(0.97 * NT));
    /* Only features 1 and 4 carry information: they dominate the stumps. */
    size_t useful = 0;
    for (size_t k = 0; k < m.n_rounds; k++) useful += m.feature[k] == 1 || m.feature[k] == 4;
    assert_true(useful * 10 >= m.n_rounds * 6);
    /* A shared stump: "gamma vs the rest" on feature 4 carries alpha and beta together at least once. */
    int shared = 0;
    for (size_t k = 0; k < m.n_rounds; k++) shared |= __builtin_popcountll(m.mask[k]) >= 2;
    assert_true(shared);
    sy_jb_model_free(&m);
}

/* Three classes in 24 dimensions, class c offset by 6 sigma in features
 * 8c..8c+7. */
enum { NOV_D = 24 };
static void blobs24(size_t n, uint64_t seed, float *X, int *y)
{
    uint64_t s = seed;
    for (size_t i = 0; i < n; i++) {
        int c = (int)(i % 3);
        y[i] = c;
        for (int f = 0; f < NOV_D; f++) X[i * NOV_D + f] = (float)syn_normal(&s) + 6.0f * (float)(f / 8 == c);
    }
}

/* The joint novelty test: held-out samples of the training classes stay below
 * the calibrated threshold; a sample inside every feature's training range
 * but in a combination no class has (the offsets of two classes at once), and
 * one far off along a few features, come out novel. The model file keeps
 * the test. */
static void novelty_flags_what_no_class_looks_like(void **state)
{
    (void)state;
    enum { N = 300, NT = 300 };
    static float X[N * NOV_D], XT[NT * NOV_D];
    int y[N], yt[NT];
    blobs24(N, 1, X, y);
    blobs24(NT, 2, XT, yt);
    sy_jb_options o = sy_jb_options_default();
    o.rounds = 40;
    sy_jb_model m, back;
    sy_error err = {0};
    assert_int_equal(sy_jb_train(X, N, NOV_D, y, 3, NULL, 1, &o, &m, NULL, &err), SY_OK);
    assert_true(m.nov_threshold > 0);
    size_t novel = 0;
    double worst = 0;
    for (size_t i = 0; i < NT; i++) {
        double v = sy_jb_novelty(&m, XT + i * NOV_D);
        novel += v > 1;
        worst = fmax(worst, v);
    }
    assert_int_equal(novel, 0); /* the threshold is twice the 99.5th percentile */
    float corner[NOV_D] = {0}, far[NOV_D] = {0}, typical[NOV_D] = {0};
    for (int f = 0; f < 16; f++) corner[f] = 6; /* classes 0 and 1 at once */
    for (int f = 0; f < 8; f++) typical[8 + f] = 6; /* class 1 */
    for (int f = 16; f < 24; f++) far[f] = f < 20 ? 30.0f : 0.0f; /* 4 features at 30 sigma */
    for (int f = 0; f < NOV_D; f++) {
        float lo = INFINITY, hi = -INFINITY;
        for (size_t i = 0; i < N; i++) lo = fminf(lo, X[i * NOV_D + f]), hi = fmaxf(hi, X[i * NOV_D + f]);
        assert_true(corner[f] > lo && corner[f] < hi); /* per-feature ranges would call it known */
    }
    assert_true(sy_jb_novelty(&m, corner) > 1.5);
    assert_true(sy_jb_novelty(&m, far) > 1);
    assert_true(sy_jb_novelty(&m, typical) < 0.6);
    assert_true(worst < 1);
    const char *path = tmp_path("novelty.sjb");
    assert_int_equal(sy_jb_save(&m, path, &err), SY_OK);
    assert_int_equal(sy_jb_load(path, &back, &err), SY_OK);
    assert_float_equal(sy_jb_novelty(&back, corner), sy_jb_novelty(&m, corner), 1e-5);
    sy_jb_model_free(&m);
    sy_jb_model_free(&back);
}

static void jointboost_same_model_for_any_thread_count(void **state)
{
    (void)state;
    enum { N = 240 };
    float X[N * 6];
    int y[N];
    blobs(N, 3, X, y);
    sy_jb_options o = sy_jb_options_default();
    o.rounds = 80;
    char *text[2];
    size_t len[2];
    for (int t = 0; t < 2; t++) {
        sy_set_threads(t ? 3 : 1);
        sy_jb_model m;
        sy_error err = {0};
        assert_int_equal(sy_jb_train(X, N, 6, y, 3, NULL, 1, &o, &m, NULL, &err), SY_OK);
        assert_int_equal(sy_jb_serialize(&m, &text[t], &len[t], &err), SY_OK);
        sy_jb_model_free(&m);
    }
    sy_set_threads(0);
    assert_int_equal(len[0], len[1]);
    assert_memory_equal(text[0], text[1], len[0]);
    /* Another seed moves the held-out split, so the model changes. */
    o.seed = 99;
    sy_jb_model m;
    sy_error err = {0};
    char *t3;
    size_t l3;
    assert_int_equal(sy_jb_train(X, N, 6, y, 3, NULL, 1, &o, &m, NULL, &err), SY_OK);
    assert_int_equal(sy_jb_serialize(&m, &t3, &l3, &err), SY_OK);
    assert_true(l3 != len[0] || memcmp(t3, text[0], l3) != 0);
    sy_jb_model_free(&m);
    free(t3), free(text[0]), free(text[1]);
}

static void jointboost_rejects_bad_training_sets(void **state)
{
    (void)state;
    float X[12] = {0};
    int y[6] = {0, 0, 0, 1, 1, 5};
    sy_jb_options o = sy_jb_options_default();
    sy_jb_model m;
    sy_error err = {0};
    assert_int_equal(sy_jb_train(X, 6, 2, y, 2, NULL, 1, &o, &m, NULL, &err), SY_EINPUT);
    y[5] = 0;
    int only0[6] = {0, 0, 0, 0, 0, 0};
    assert_int_equal(sy_jb_train(X, 6, 2, only0, 2, NULL, 1, &o, &m, NULL, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "no sample"));
    X[3] = NAN;
    assert_int_equal(sy_jb_train(X, 6, 2, y, 2, NULL, 1, &o, &m, NULL, &err), SY_EINPUT);
    o.shrinkage = 0;
    assert_int_equal(sy_jb_options_check(&o, &err), SY_EUSAGE);
}

static void model_file_round_trip_and_damage(void **state)
{
    (void)state;
    enum { N = 150 };
    float X[N * 6];
    int y[N];
    blobs(N, 4, X, y);
    const char *names[3] = {"silver_birch", "black_oak", "palm"};
    sy_jb_options o = sy_jb_options_default();
    o.rounds = 40;
    sy_jb_model m, back;
    sy_error err = {0};
    assert_int_equal(sy_jb_train(X, N, 6, y, 3, names, SY_FEATURES_VERSION, &o, &m, NULL, &err), SY_OK);
    const char *path = tmp_path("model.sjb");
    assert_int_equal(sy_jb_save(&m, path, &err), SY_OK);
    assert_int_equal(sy_jb_load(path, &back, &err), SY_OK);
    assert_int_equal(back.n_rounds, m.n_rounds);
    assert_int_equal(back.features_version, SY_FEATURES_VERSION);
    assert_string_equal(back.classes[2], "palm");
    for (size_t i = 0; i < N; i++) {
        double p[3], q[3];
        sy_jb_predict(&m, X + i * 6, p);
        sy_jb_predict(&back, X + i * 6, q);
        for (int c = 0; c < 3; c++) assert_float_equal(p[c], q[c], 1e-12);
    }
    char *text;
    size_t len;
    assert_int_equal(sy_jb_serialize(&back, &text, &len, &err), SY_OK);
    sy_jb_model_free(&back); /* the parses below write into it again */
    /* Damage one digit of a stump: the checksum catches it. */
    char *s = strstr(text, "stump ");
    assert_non_null(s);
    s[6] = s[6] == '1' ? '2' : '1';
    assert_int_equal(sy_jb_parse("bad.sjb", text, len, &back, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "bad.sjb"));
    assert_non_null(strstr(err.msg, "damaged"));
    s[6] = s[6] == '1' ? '2' : '1';
    assert_int_equal(sy_jb_parse("cut.sjb", text, len / 2, &back, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "truncated"));
    assert_int_equal(sy_jb_parse("x.ply", "ply\nformat ascii 1.0\n", 21, &back, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "not a Sylva JointBoost model"));
    memcpy(text + 17, "9", 1);
    assert_int_equal(sy_jb_parse("v9.sjb", text, len, &back, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "version"));
    assert_int_equal(sy_jb_parse("empty.sjb", "", 0, &back, &err), SY_EINPUT);
    free(text);
    sy_jb_model_free(&m);
    sy_jb_model_free(&back);
}

static void confidence_rule_is_h1_over_1_5_h2(void **state)
{
    (void)state;
    double p[6] = {0.6, 0.4, 0.0, 0.61, 0.39, 0.0};
    sy_tree_decision d[2];
    sy_vote_options o = sy_vote_options_default();
    sy_error err = {0};
    assert_int_equal(sy_vote(2, 3, p, NULL, NULL, &o, d, &err), SY_OK);
    assert_false(d[0].confident); /* 0.6 is not > 1.5 * 0.4 */
    assert_int_equal(d[0].species, -1);
    assert_true(d[1].confident);
    assert_int_equal(d[1].species, 0);
    double nov[2] = {0, 1.2}; /* 1.2 times the calibrated threshold */
    assert_int_equal(sy_vote(2, 3, p, nov, NULL, &o, d, &err), SY_OK);
    assert_false(d[1].confident);
    assert_true(d[1].novel);
    nov[1] = 0.9;
    assert_int_equal(sy_vote(2, 3, p, nov, NULL, &o, d, &err), SY_OK);
    assert_true(d[1].confident);
}

static void voting_reads_confident_neighbours_within_the_radius(void **state)
{
    (void)state;
    /* Tree 0 unsure between classes 0 and 1 (prefers 0); tree 1, 10 m away,
     * confidently class 1; tree 2, 40 m away, confidently class 0. */
    double p[9] = {0.45, 0.40, 0.15, 0.05, 0.9, 0.05, 0.9, 0.05, 0.05};
    double xy[6] = {0, 0, 10, 0, -40, 0};
    sy_tree_decision d[3];
    sy_vote_options o = sy_vote_options_default();
    sy_error err = {0};
    assert_int_equal(sy_vote(3, 3, p, NULL, xy, &o, d, &err), SY_OK);
    assert_true(d[0].voted);
    assert_int_equal(d[0].species, 1);
    assert_int_equal(d[0].votes, 1);
    assert_false(d[1].voted);
    assert_int_equal(d[1].species, 1);
    /* With a 50 m radius both vote; the tree's own preference picks class 0. */
    o.radius = 50;
    assert_int_equal(sy_vote(3, 3, p, NULL, xy, &o, d, &err), SY_OK);
    assert_int_equal(d[0].species, 0);
    /* A 5 m radius: nobody near, unknown. */
    o.radius = 5;
    assert_int_equal(sy_vote(3, 3, p, NULL, xy, &o, d, &err), SY_OK);
    assert_int_equal(d[0].species, -1);
    assert_false(d[0].voted);
    /* Switched off: unknown. */
    o.radius = 25, o.voting = 0;
    assert_int_equal(sy_vote(3, 3, p, NULL, xy, &o, d, &err), SY_OK);
    assert_int_equal(d[0].species, -1);
    o.ratio = 0.5;
    assert_int_equal(sy_vote(3, 3, p, NULL, xy, &o, d, &err), SY_EUSAGE);
    o.ratio = INFINITY;
    assert_int_equal(sy_vote(3, 3, p, NULL, xy, &o, d, &err), SY_EUSAGE);
    /* A model sure of its trees gives ratios of 1e11 and more (p2 ~ 1e-12):
     * a ratio between two of them is a valid option, not a usage error. */
    o.ratio = 1.6e11;
    assert_int_equal(sy_vote(3, 3, p, NULL, xy, &o, d, &err), SY_OK);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(features_have_names_and_count),
        cmocka_unit_test(features_invariant_to_position_and_heading),
        cmocka_unit_test(features_robust_to_density),
        cmocka_unit_test(features_reject_tiny_clouds),
        cmocka_unit_test(jointboost_learns_separable_classes),
        cmocka_unit_test(novelty_flags_what_no_class_looks_like),
        cmocka_unit_test(jointboost_same_model_for_any_thread_count),
        cmocka_unit_test(jointboost_rejects_bad_training_sets),
        cmocka_unit_test(model_file_round_trip_and_damage),
        cmocka_unit_test(confidence_rule_is_h1_over_1_5_h2),
        cmocka_unit_test(voting_reads_confident_neighbours_within_the_radius),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
