/* The segment stage on simulated plots whose answer is known (the scan
 * stage's treeID), and on hostile clouds. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cmocka.h>

#define PI 3.14159265358979323846

#include "stages/core/parallel.h"
#include "stages/core/rng.h"
#include "stages/eval/eval.h"
#include "stages/scan/scan.h"
#include "stages/segment/segment.h"

typedef struct {
    sy_scene scene;
    sy_cloud cloud;
} sim_plot;

/* A small plot of aspens and pines on gently sloping, rough ground. */
static void simulate(sim_plot *p, sy_scanner_kind kind, double size, int trees, uint64_t seed)
{
    sy_scene_options o = sy_scene_options_default();
    o.species[0] = "quaking_aspen";
    o.species[1] = "european_pine";
    o.n_species = 2;
    o.plot_size = size;
    o.trees = trees;
    o.slope_deg = 3;
    o.roughness = 0.08;
    o.seed = seed;
    sy_error err = {0};
    sy_scene_init(&p->scene);
    sy_code rc = sy_scene_build(&p->scene, &o, kind == SY_SCANNER_AIRBORNE ? 0 : 25, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, SY_OK);
    sy_scan_options sc = sy_scan_options_for(kind);
    sc.seed = seed;
    sc.subrays = 1;
    sc.divergence_mrad = 0;
    if (kind == SY_SCANNER_TERRESTRIAL) sc.step_deg = 0.3;
    else sc.density = 30;
    rc = sy_scan(&p->scene, &sc, &p->cloud, NULL, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, SY_OK);
}

static void sim_free(sim_plot *p)
{
    sy_scene_free(&p->scene);
    sy_cloud_free(&p->cloud);
}

static sy_segmentation_metrics score(const sy_cloud *c, const sy_segmentation *s)
{
    const double *truth = sy_cloud_attr(c, "treeID");
    assert_non_null(truth);
    double *pred = malloc(c->n * sizeof *pred);
    assert_non_null(pred);
    for (size_t i = 0; i < c->n; i++) pred[i] = s->tree_of[i] > 0 ? s->tree_of[i] : 0;
    sy_segmentation_metrics m;
    sy_error err = {0};
    assert_int_equal(sy_segmentation_metrics_labels(truth, pred, c->n, &m, &err), SY_OK);
    free(pred);
    return m;
}

/* Every point is in exactly one tree, on the ground or unassigned. */
static void check_accounting(const sy_segmentation *s)
{
    size_t ground = 0, unassigned = 0, *per = calloc(s->n_trees + 1, sizeof *per);
    assert_non_null(per);
    for (size_t i = 0; i < s->n_points; i++) {
        int32_t t = s->tree_of[i];
        assert_true(t >= -1 && t <= (int32_t)s->n_trees);
        if (t == 0) ground++;
        else if (t < 0) unassigned++;
        else per[t]++;
    }
    assert_int_equal(ground, s->n_ground);
    assert_int_equal(unassigned, s->n_unassigned);
    size_t sum = ground + unassigned;
    for (size_t t = 0; t < s->n_trees; t++) {
        assert_int_equal(s->trees[t].id, (int32_t)t + 1);
        assert_int_equal(per[t + 1], s->trees[t].n_points);
        assert_true(s->trees[t].n_points > 0);
        sum += s->trees[t].n_points;
    }
    assert_int_equal(sum, s->n_points);
    free(per);
}

/* The truth tree nearest (x, y). */
static const sy_scan_tree *nearest_truth(const sy_scene *sc, double x, double y, double *dist)
{
    const sy_scan_tree *best = NULL;
    *dist = INFINITY;
    for (size_t t = 0; t < sc->n_trees; t++) {
        double d = hypot(sc->trees[t].pos[0] - x, sc->trees[t].pos[1] - y);
        if (d < *dist) *dist = d, best = &sc->trees[t];
    }
    return best;
}

static void terrestrial_plot_scores(void **state)
{
    (void)state;
    sim_plot p;
    simulate(&p, SY_SCANNER_TERRESTRIAL, 14, 5, 11);
    sy_segment_options o = sy_segment_options_default();
    sy_segmentation s;
    sy_error err = {0};
    sy_code rc = sy_segment(&p.cloud, &o, &s, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, SY_OK);
    assert_int_equal(s.airborne, 0); /* auto chose stems: TLS is dense */
    check_accounting(&s);
    sy_segmentation_metrics m = score(&p.cloud, &s);
    printf("terrestrial: %zu trees found of %zu, F1 %.3f, mean IoU %.3f\n", s.n_trees, m.n_truth, m.f1, m.mean_iou);
    assert_true(m.f1 >= 0.8);
    assert_true(m.mean_iou >= 0.8);
    /* Stems where the trees stand, DBH and height close to the truth. */
    for (size_t t = 0; t < s.n_trees; t++) {
        double d;
        const sy_scan_tree *tr = nearest_truth(&p.scene, s.trees[t].stem[0], s.trees[t].stem[1], &d);
        assert_true(d < 0.15);
        assert_false(isnan(s.trees[t].dbh));
        assert_true(fabs(s.trees[t].dbh - tr->dbh) < 0.05);
        assert_true(fabs(s.trees[t].stem[2] - tr->pos[2]) < 0.2);
        printf("  tree %zu: dbh %.3f (truth %.3f) height %.2f (truth %.2f)\n", t + 1, s.trees[t].dbh, tr->dbh, s.trees[t].height, tr->height);
        assert_true(s.trees[t].height > 0.6 * tr->height && s.trees[t].height < tr->height + 0.5);
    }
    /* Same labels on one thread and on two. */
    sy_set_threads(1);
    sy_segmentation s1;
    assert_int_equal(sy_segment(&p.cloud, &o, &s1, &err), SY_OK);
    sy_set_threads(2);
    assert_int_equal(s1.n_trees, s.n_trees);
    assert_memory_equal(s1.tree_of, s.tree_of, s.n_points * sizeof *s.tree_of);
    /* A tree out of the plot keeps every attribute. */
    sy_cloud tree;
    assert_int_equal(sy_segmentation_tree_cloud(&p.cloud, &s, 0, &tree, &err), SY_OK);
    assert_int_equal(tree.n, s.trees[0].n_points);
    assert_int_equal(tree.n_attrs, p.cloud.n_attrs);
    assert_non_null(tree.intensity);
    assert_non_null(tree.gps_time);
    sy_cloud_free(&tree);
    assert_int_equal(sy_segmentation_tree_cloud(&p.cloud, &s, s.n_trees, &tree, &err), SY_EUSAGE);
    assert_int_equal(sy_segment_is_plot(&p.cloud, &o), 1);
    sy_segmentation_free(&s1);
    sy_segmentation_free(&s);
    sim_free(&p);
}

static void airborne_plot_scores(void **state)
{
    (void)state;
    sim_plot p;
    simulate(&p, SY_SCANNER_AIRBORNE, 30, 8, 5);
    sy_segment_options o = sy_segment_options_default();
    sy_segmentation s;
    sy_error err = {0};
    sy_code rc = sy_segment(&p.cloud, &o, &s, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, SY_OK);
    assert_int_equal(s.airborne, 1); /* auto chose the canopy: ALS is sparse */
    check_accounting(&s);
    sy_segmentation_metrics m = score(&p.cloud, &s);
    printf("airborne: %zu trees found of %zu, F1 %.3f, mean IoU %.3f\n", s.n_trees, m.n_truth, m.f1, m.mean_iou);
    assert_true(m.f1 >= 0.7);
    for (size_t t = 0; t < s.n_trees; t++) assert_true(isnan(s.trees[t].dbh));
    sy_segmentation_free(&s);
    sim_free(&p);
}

static void single_tree_is_not_a_plot(void **state)
{
    (void)state;
    sim_plot p;
    simulate(&p, SY_SCANNER_TERRESTRIAL, 0, 1, 3);
    sy_segment_options o = sy_segment_options_default();
    assert_int_equal(sy_segment_is_plot(&p.cloud, &o), 0);
    sim_free(&p);
}

static void hostile_clouds(void **state)
{
    (void)state;
    sy_segment_options o = sy_segment_options_default();
    sy_segmentation s;
    sy_error err = {0};
    sy_cloud c;
    /* Empty. */
    assert_int_equal(sy_cloud_init(&c, 0, &err), SY_OK);
    assert_int_equal(sy_segment(&c, &o, &s, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "no points"));
    assert_int_equal(sy_segment_is_plot(&c, &o), 0);
    sy_cloud_free(&c);
    /* One point. */
    assert_int_equal(sy_cloud_init(&c, 1, &err), SY_OK);
    c.xyz[2] = 5;
    assert_int_equal(sy_segment(&c, &o, &s, &err), SY_OK);
    assert_int_equal(s.n_trees, 0);
    check_accounting(&s);
    sy_segmentation_free(&s);
    sy_cloud_free(&c);
    /* A flat cloud: ground only, no tree, whichever method. */
    size_t side = 120;
    assert_int_equal(sy_cloud_init(&c, side * side, &err), SY_OK);
    for (size_t i = 0; i < side * side; i++) {
        c.xyz[3 * i] = (float)(i % side) * 0.05f;
        c.xyz[3 * i + 1] = (float)(i / side) * 0.05f;
    }
    for (int method = 0; method < 3; method++) {
        o.method = (sy_segment_method)method;
        assert_int_equal(sy_segment(&c, &o, &s, &err), SY_OK);
        assert_int_equal(s.n_trees, 0);
        check_accounting(&s);
        assert_true(s.n_ground > c.n / 2);
        sy_segmentation_free(&s);
    }
    /* A thin vertical line of points (a pole, no circle). */
    for (size_t i = 0; i < c.n; i++) {
        c.xyz[3 * i] = c.xyz[3 * i + 1] = 0;
        c.xyz[3 * i + 2] = (float)i * 0.001f;
    }
    o = sy_segment_options_default();
    assert_int_equal(sy_segment(&c, &o, &s, &err), SY_OK);
    check_accounting(&s);
    sy_segmentation_free(&s);
    /* The same point many times over. */
    memset(c.xyz, 0, c.n * 3 * sizeof(float));
    assert_int_equal(sy_segment(&c, &o, &s, &err), SY_OK);
    check_accounting(&s);
    sy_segmentation_free(&s);
    sy_cloud_free(&c);
}

/* A trunk, and beside it a column of leaves hanging to the ground (an oak's
 * drooping limb): leaves 20 cm across facing every way, their centres on a
 * 0.25 m cylinder. The column's outside fits a circle and passes every test
 * of a trunk's section (full arc, empty inside, upright, standing on the
 * ground) but the bark test: it is no thin sheet facing away from the
 * centre. */
static void leaf_columns_are_not_stems(void **state)
{
    (void)state;
    const size_t ground = 200 * 200, trunk = 180 * 200, leaves = 120, per_leaf = 80;
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_cloud_init(&c, ground + trunk + leaves * per_leaf, &err), SY_OK);
    float *p = c.xyz;
    for (size_t i = 0; i < ground; i++, p += 3) p[0] = (float)(i % 200) * 0.05f, p[1] = (float)(i / 200) * 0.05f, p[2] = 0;
    for (size_t i = 0; i < trunk; i++, p += 3) {
        double a = (double)(i % 180) * 2 * PI / 180, z = (double)(i / 180) * 0.02;
        p[0] = (float)(3 + 0.2 * cos(a)), p[1] = (float)(3 + 0.2 * sin(a)), p[2] = (float)z;
    }
    uint64_t rng = 11;
    for (size_t k = 0; k < leaves; k++) {
        double a = 2 * PI * sy_unit53(sy_splitmix64(&rng)), z = 0.2 + 2.3 * sy_unit53(sy_splitmix64(&rng));
        double centre[3] = {7 + 0.25 * cos(a), 7 + 0.25 * sin(a), z};
        /* A random unit normal and two axes in the leaf's plane. */
        double nz = 2 * sy_unit53(sy_splitmix64(&rng)) - 1, phi = 2 * PI * sy_unit53(sy_splitmix64(&rng));
        double n[3] = {sqrt(1 - nz * nz) * cos(phi), sqrt(1 - nz * nz) * sin(phi), nz};
        double u[3] = {-n[1], n[0], 0}, lu = hypot(u[0], u[1]);
        if (lu < 1e-6) u[0] = 1, u[1] = 0, lu = 1;
        u[0] /= lu, u[1] /= lu;
        double v[3] = {n[1] * u[2] - n[2] * u[1], n[2] * u[0] - n[0] * u[2], n[0] * u[1] - n[1] * u[0]};
        for (size_t j = 0; j < per_leaf; j++, p += 3) {
            double r = 0.1 * sqrt(sy_unit53(sy_splitmix64(&rng))), t = 2 * PI * sy_unit53(sy_splitmix64(&rng));
            for (int d = 0; d < 3; d++) p[d] = (float)(centre[d] + r * (cos(t) * u[d] + sin(t) * v[d]));
        }
    }
    sy_segment_options o = sy_segment_options_default();
    o.method = SY_SEGMENT_TERRESTRIAL;
    sy_segmentation s;
    assert_int_equal(sy_segment(&c, &o, &s, &err), SY_OK);
    check_accounting(&s);
    assert_int_equal(s.n_trees, 1);
    assert_true(hypot(s.trees[0].stem[0] - 3, s.trees[0].stem[1] - 3) < 0.05);
    assert_true(fabs(s.trees[0].dbh - 0.4) < 0.02);
    sy_segmentation_free(&s);
    /* Without the bark test the column is a second stem: the test sees it. */
    o.min_facing = 0;
    assert_int_equal(sy_segment(&c, &o, &s, &err), SY_OK);
    assert_int_equal(s.n_trees, 2);
    sy_segmentation_free(&s);
    sy_cloud_free(&c);
}

static void options_are_checked(void **state)
{
    (void)state;
    sy_error err = {0};
    sy_segment_options o = sy_segment_options_default();
    assert_int_equal(sy_segment_options_check(&o, &err), SY_OK);
    o.voxel = 0;
    assert_int_equal(sy_segment_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "voxel"));
    o = sy_segment_options_default();
    o.stem_min_radius = 2;
    assert_int_equal(sy_segment_options_check(&o, &err), SY_EUSAGE);
    o = sy_segment_options_default();
    o.chm_cell = NAN;
    assert_int_equal(sy_segment_options_check(&o, &err), SY_EUSAGE);
    o = sy_segment_options_default();
    o.min_facing = 1.5;
    assert_int_equal(sy_segment_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "min_facing"));
    o = sy_segment_options_default();
    o.single_band_arc = -0.1;
    assert_int_equal(sy_segment_options_check(&o, &err), SY_EUSAGE);
    o = sy_segment_options_default();
    o.method = (sy_segment_method)7;
    assert_int_equal(sy_segment_options_check(&o, &err), SY_EUSAGE);
    sy_segment_method m;
    assert_int_equal(sy_segment_method_parse("als", &m), 0);
    assert_int_equal(m, SY_SEGMENT_AIRBORNE);
    assert_int_equal(sy_segment_method_parse("ground", &m), -1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(options_are_checked),
        cmocka_unit_test(hostile_clouds),
        cmocka_unit_test(leaf_columns_are_not_stems),
        cmocka_unit_test(terrestrial_plot_scores),
        cmocka_unit_test(airborne_plot_scores),
        cmocka_unit_test(single_tree_is_not_a_plot),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
