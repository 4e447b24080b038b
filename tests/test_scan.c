/* The virtual scanner: analytic ray hits, BVH against brute force, scans of a
 * known cylinder (surface error, coverage, range noise), leaf occlusion,
 * determinism across seeds and threads, the truth file and airborne density. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/fileio.h"
#include "stages/core/parallel.h"
#include "stages/core/progress.h"
#include "stages/grow/grow.h"
#include "stages/ingest/ingest.h"
#include "stages/scan/scan.h"

#define PI 3.14159265358979323846

static const double down[3] = {0, 0, -1};

static void unit(double d[3])
{
    double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    for (int k = 0; k < 3; k++) d[k] /= l;
}

static int hits(const sy_prim *p, double ox, double oy, double oz, double dx, double dy, double dz, double *t)
{
    double o[3] = {ox, oy, oz}, d[3] = {dx, dy, dz};
    unit(d);
    return sy_prim_intersect(p, o, d, 1e-9, 1e9, t);
}

/* ------------------------------------------------------------ analytic hits */

static void ray_cone_analytic(void **state)
{
    (void)state;
    double t;
    float a[3] = {0, 0, 0}, b[3] = {0, 0, 10};
    sy_prim cyl = sy_prim_cone(a, 1, b, 1);
    assert_true(hits(&cyl, 5, 0, 5, -1, 0, 0, &t));
    assert_float_equal(t, 4.0, 1e-9);
    assert_true(hits(&cyl, 3, 4, 5, -3, -4, 0, &t)); /* from 5 m away, radius 1 */
    assert_float_equal(t, 4.0, 1e-9);
    assert_true(hits(&cyl, 0, 0, 5, 1, 0, 0, &t)); /* from inside: the far wall */
    assert_float_equal(t, 1.0, 1e-9);
    assert_false(hits(&cyl, 5, 0, 11, -1, 0, 0, &t)); /* above the end */
    assert_false(hits(&cyl, 5, 1.0001, 5, -1, 0, 0, &t)); /* grazing past */
    /* Oblique: from (5,0,0) towards (0,0,5) meets x = 1 at z = 4. */
    assert_true(hits(&cyl, 5, 0, 0, -1, 0, 1, &t));
    assert_float_equal(t, 4 * sqrt(2.0), 1e-9);

    /* Cone radius 2 at z = 0 narrowing to 0 at z = 2: r(z) = 2 - z. */
    float c[3] = {0, 0, 2};
    sy_prim cone = sy_prim_cone(a, 2, c, 0);
    assert_true(hits(&cone, 5, 0, 1, -1, 0, 0, &t));
    assert_float_equal(t, 4.0, 1e-9);
    assert_true(hits(&cone, 5, 0, 0.5, -1, 0, 0, &t));
    assert_float_equal(t, 3.5, 1e-9);
    /* Straight down onto the slanted side at x = 1: z = 1, from z = 5. */
    assert_true(hits(&cone, 1, 0, 5, 0, 0, -1, &t));
    assert_float_equal(t, 4.0, 1e-9);
    assert_false(hits(&cone, 2.5, 0, 5, 0, 0, -1, &t));
    double x[3] = {1, 0, 1}, n[3];
    sy_prim_normal(&cone, x, n);
    assert_float_equal(n[0], sqrt(0.5), 1e-9);
    assert_float_equal(n[2], sqrt(0.5), 1e-9);
}

static void ray_quad_analytic(void **state)
{
    (void)state;
    double t;
    float base[3] = {0, 0, 0}, xa[3] = {1, 0, 0}, ya[3] = {0, 1, 0};
    sy_prim rect = sy_prim_quad(base, xa, ya, 2, 1, 0), ell = sy_prim_quad(base, xa, ya, 2, 1, 1);
    assert_true(hits(&rect, 0.4, 1.9, 5, 0, 0, -1, &t));
    assert_float_equal(t, 5.0, 1e-9);
    /* (0.4/0.5)^2 + (0.9/1)^2 > 1: outside the inscribed ellipse. */
    assert_false(hits(&ell, 0.4, 1.9, 5, 0, 0, -1, &t));
    assert_true(hits(&ell, 0, 1, 5, 0, 0, -1, &t));
    assert_float_equal(t, 5.0, 1e-9);
    assert_false(hits(&rect, 0.6, 1, 5, 0, 0, -1, &t));
    assert_false(hits(&rect, 0, -0.1, 5, 0, 0, -1, &t)); /* behind the leaf base */
    assert_false(hits(&rect, 0, 2.1, 5, 0, 0, -1, &t));  /* past the tip */
    assert_true(hits(&rect, 0, 0, 1, 0, 1, -1, &t));     /* oblique, to (0,1,0) */
    assert_float_equal(t, sqrt(2.0), 1e-9);
    assert_true(hits(&rect, 0, 1, -3, 0, 0, 1, &t));     /* from below: cards are two-sided */
    assert_float_equal(t, 3.0, 1e-9);
}

/* A needle shoot's card (leaf_fill 0.2) stops about a fifth of the rays that
 * cross it, each ray always the same way; a solid card stops them all. */
static void needle_card_stops_its_fill(void **state)
{
    (void)state;
    float base[3] = {0, 0, 0}, xa[3] = {1, 0, 0}, ya[3] = {0, 1, 0};
    sy_prim card = sy_prim_quad(base, xa, ya, 0.8f, 0.6f, 0), solid = card;
    sy_prim_quad_gaps(&card, 0.2);
    sy_prim_quad_gaps(&solid, 1);
    assert_int_equal(solid.gaps, 0);
    int stopped = 0, n = 0;
    double t;
    for (int i = 0; i < 100; i++)
        for (int j = 0; j < 100; j++, n++) {
            double x = -0.29 + 0.58 * i / 99.0, y = 0.01 + 0.78 * j / 99.0;
            int hit = hits(&card, x, y, 5, 0, 0, -1, &t);
            stopped += hit;
            assert_int_equal(hit, hits(&card, x, y, 5, 0, 0, -1, &t));
            assert_true(hits(&solid, x, y, 5, 0, 0, -1, &t));
        }
    assert_float_equal((double)stopped / n, 0.2, 0.03);
}

static void ray_terrain_analytic(void **state)
{
    (void)state;
    sy_terrain tr = {10, 0, 0, 6, 0, 1, {-20, -20}, {20, 20}, 0.5};
    sy_prims prims = {0};
    sy_error err = {0};
    assert_int_equal(sy_terrain_triangulate(&tr, &prims, &err), SY_OK);
    sy_bvh bvh;
    assert_int_equal(sy_prims_index(&prims, &bvh, &err), SY_OK);
    double g = tan(10 * PI / 180);
    /* A plane is triangulated exactly: z = tan(10 deg) x. */
    double o[3] = {3.3, 1.7, 50};
    sy_hit h;
    assert_true(sy_bvh_closest(&bvh, o, down, 1e3, sy_prim_ray_hit, prims.p, &h));
    assert_float_equal(h.t, 50 - g * 3.3, 1e-5);
    /* From (-10, 0, 10) along (1, 0, -1): 10 - s = g (s - 10) gives s = 10,
     * the origin, whatever the slope. */
    double o2[3] = {-10, 0, 10}, d2[3] = {1, 0, -1};
    unit(d2);
    assert_true(sy_bvh_closest(&bvh, o2, d2, 1e3, sy_prim_ray_hit, prims.p, &h));
    assert_float_equal(h.t, 10 * sqrt(2.0), 1e-5);
    assert_float_equal(sy_terrain_height(&tr, 3.3, 1.7), g * 3.3, 1e-5);
    sy_bvh_free(&bvh);
    prims.n = 0;

    /* A rough surface: every vertical ray lands on sy_terrain_height. */
    sy_terrain rough = {5, 30, 0.4, 4, 1, 7, {-10, -10}, {10, 10}, 0.5};
    assert_int_equal(sy_terrain_triangulate(&rough, &prims, &err), SY_OK);
    assert_int_equal(sy_prims_index(&prims, &bvh, &err), SY_OK);
    srand(5);
    for (int i = 0; i < 200; i++) {
        double p[3] = {-9.5 + 19.0 * rand() / RAND_MAX, -9.5 + 19.0 * rand() / RAND_MAX, 40};
        assert_true(sy_bvh_closest(&bvh, p, down, 1e3, sy_prim_ray_hit, prims.p, &h));
        assert_float_equal(40 - h.t, sy_terrain_height(&rough, p[0], p[1]), 1e-5);
    }
    /* Grid vertices sit on the continuous field. */
    assert_float_equal(sy_terrain_height(&rough, 2.0, -3.5), sy_terrain_field(&rough, 2.0, -3.5), 1e-5);
    sy_bvh_free(&bvh);
    sy_prims_free(&prims);
}

/* ----------------------------------------------------------------- BVH */

static double frand(double lo, double hi) { return lo + (hi - lo) * rand() / (double)RAND_MAX; }

static void bvh_matches_brute_force(void **state)
{
    (void)state;
    srand(11);
    sy_prims prims = {0};
    sy_error err = {0};
    for (int i = 0; i < 900; i++) {
        float a[3], b[3], c[3];
        for (int k = 0; k < 3; k++) {
            a[k] = (float)frand(-10, 10);
            b[k] = a[k] + (float)frand(-1.5, 1.5);
            c[k] = a[k] + (float)frand(-1.5, 1.5);
        }
        sy_prim p;
        if (i % 3 == 0) {
            p = sy_prim_cone(a, (float)frand(0.01, 0.4), b, (float)frand(0.0, 0.4));
        } else if (i % 3 == 1) {
            double x[3] = {frand(-1, 1), frand(-1, 1), frand(-1, 1)}, y[3] = {frand(-1, 1), frand(-1, 1), frand(-1, 1)};
            unit(x);
            double dot = x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
            for (int k = 0; k < 3; k++) y[k] -= dot * x[k];
            unit(y);
            float fx[3] = {(float)x[0], (float)x[1], (float)x[2]}, fy[3] = {(float)y[0], (float)y[1], (float)y[2]};
            p = sy_prim_quad(a, fx, fy, (float)frand(0.1, 1), (float)frand(0.05, 0.5), i % 2);
        } else {
            p = sy_prim_tri(a, b, c);
        }
        assert_int_equal(sy_prims_push(&prims, &p, &err), SY_OK);
    }
    sy_bvh bvh;
    assert_int_equal(sy_prims_index(&prims, &bvh, &err), SY_OK);
    int n_hit = 0;
    for (int r = 0; r < 1000; r++) {
        double o[3] = {frand(-15, 15), frand(-15, 15), frand(-15, 15)};
        double d[3];
        if (r % 2) {
            /* Aim at a random primitive so most rays hit something. */
            const sy_prim *p = &prims.p[rand() % prims.n];
            for (int k = 0; k < 3; k++) d[k] = p->v[k] + frand(-0.2, 0.2) - o[k];
        } else {
            for (int k = 0; k < 3; k++) d[k] = frand(-1, 1);
        }
        unit(d);
        sy_hit a = {0, 0}, b = {0, 0};
        int ha = sy_bvh_closest(&bvh, o, d, 100, sy_prim_ray_hit, prims.p, &a);
        int hb = sy_bvh_closest_brute(&bvh, o, d, 100, sy_prim_ray_hit, prims.p, &b);
        assert_int_equal(ha, hb);
        if (ha) {
            n_hit++;
            assert_true(a.t == b.t);
            assert_int_equal(a.prim, b.prim);
        }
    }
    assert_true(n_hit > 300);
    sy_bvh_free(&bvh);
    sy_prims_free(&prims);
}

/* ---------------------------------------------------------- cylinder scans */

#define CYL_R 0.15

/* A hand-built vertical cylinder: two nodes, no leaves, no ground. */
static void cylinder_scene(sy_scene *s)
{
    sy_error err = {0};
    sy_skeleton sk;
    sy_skeleton_init(&sk, 0, &err);
    float a[3] = {0, 0, 0}, b[3] = {0, 0, 4};
    assert_int_equal(sy_skeleton_add(&sk, a, CYL_R, -1, 0, 0, &err), 0);
    assert_int_equal(sy_skeleton_add(&sk, b, CYL_R, 0, 0, 0, &err), 1);
    sy_scene_init(s);
    double pos[3] = {0, 0, 0};
    assert_int_equal(sy_scene_add_tree(s, &sk, NULL, NULL, "cylinder", -1, 1, pos, 0, &err), SY_OK);
    s->area_lo[0] = s->area_lo[1] = -5;
    s->area_hi[0] = s->area_hi[1] = 5;
    assert_int_equal(sy_scene_finish(s, &err), SY_OK);
    sy_skeleton_free(&sk);
}

static void scan_ok(const sy_scene *s, const sy_scan_options *sc, sy_cloud *c)
{
    sy_error err = {0};
    sy_code rc = sy_scan(s, sc, c, NULL, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, SY_OK);
}

static void tls(sy_scan_options *sc, double step, double noise, double divergence)
{
    *sc = sy_scan_options_for(SY_SCANNER_TERRESTRIAL);
    sc->positions = 4;
    sc->radius = 5;
    sc->step_deg = step;
    sc->noise = noise;
    sc->divergence_mrad = divergence;
}

static void cylinder_surface_and_coverage(void **state)
{
    (void)state;
    sy_scene s;
    cylinder_scene(&s);
    sy_scan_options sc;
    tls(&sc, 0.05, 0, 0.3);
    sy_cloud c;
    scan_ok(&s, &sc, &c);
    assert_true(c.n > 1000);
    double *wood = sy_cloud_attr(&c, "isWood"), *tree = sy_cloud_attr(&c, "treeID"), *br = sy_cloud_attr(&c, "branchID");
    assert_non_null(wood);
    /* 5-degree arcs (13 mm at this radius, three beam spacings). */
    int bins[72] = {0};
    for (size_t i = 0; i < c.n; i++) {
        double x = c.origin[0] + c.xyz[3 * i], y = c.origin[1] + c.xyz[3 * i + 1], z = c.origin[2] + c.xyz[3 * i + 2];
        assert_true(wood[i] == 1 && tree[i] == 1 && br[i] == 0);
        assert_true(fabs(hypot(x, y) - CYL_R) < 1e-3);
        if (z > 1.2 && z < 1.4) {
            int bin = (int)floor((atan2(y, x) + PI) * 36 / PI);
            bins[bin < 0 ? 0 : bin > 71 ? 71 : bin]++;
        }
    }
    int covered = 0;
    for (int i = 0; i < 72; i++) covered += bins[i] > 0;
    if (covered < 65) fprintf(stderr, "breast-height coverage %d of 72 arcs\n", covered);
    assert_true(covered >= 65); /* 90% */
    sy_cloud_free(&c);
    sy_scene_free(&s);
}

static void cylinder_range_noise(void **state)
{
    (void)state;
    sy_scene s;
    cylinder_scene(&s);
    const double sigma = 0.005;
    sy_scan_options sc;
    tls(&sc, 0.1, 0, 0);
    sy_cloud clean, noisy;
    scan_ok(&s, &sc, &clean);
    sc.noise = sigma;
    scan_ok(&s, &sc, &noisy);
    /* No divergence: the same rays hit, so points pair up one to one and the
     * displacement along each beam is the noise drawn. */
    assert_int_equal(clean.n, noisy.n);
    double sum = 0, sum2 = 0;
    for (size_t i = 0; i < clean.n; i++) {
        double dv[3], r = 0, radial = 0;
        for (int k = 0; k < 3; k++) dv[k] = (double)noisy.xyz[3 * i + k] - clean.xyz[3 * i + k];
        r = sqrt(dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]);
        double cx = clean.origin[0] + clean.xyz[3 * i], cy = clean.origin[1] + clean.xyz[3 * i + 1];
        radial = dv[0] * cx + dv[1] * cy;
        double signed_r = radial < 0 ? r : -r; /* deeper along the beam = into the cylinder */
        sum += signed_r;
        sum2 += signed_r * signed_r;
    }
    double mean = sum / clean.n, sd = sqrt(sum2 / clean.n - mean * mean);
    assert_true(fabs(mean) < 0.2 * sigma);
    assert_true(fabs(sd - sigma) < 0.2 * sigma);
    sy_cloud_free(&clean);
    sy_cloud_free(&noisy);
    sy_scene_free(&s);
}

/* ------------------------------------------------------------ grown trees */

static size_t count_wood(const sy_cloud *c)
{
    const double *w = sy_cloud_attr(c, "isWood");
    size_t n = 0;
    for (size_t i = 0; i < c->n; i++) n += w[i] == 1;
    return n;
}

static void leaves_occlude_wood(void **state)
{
    (void)state;
    sy_species_params sp;
    sy_error err = {0};
    assert_int_equal(sy_species_params_find("quaking_aspen", &sp, &err), SY_OK);
    sy_skeleton sk;
    sy_leaves lv;
    assert_int_equal(sy_grow_tree(&sp, 1, &sk, &lv, &err), SY_OK);
    size_t wood[2];
    double pos[3] = {0, 0, 0};
    sy_card_form cards = {sp.leaf_scale_x, 1, 1};
    for (int with = 0; with < 2; with++) {
        sy_scene s;
        sy_scene_init(&s);
        assert_int_equal(sy_scene_add_tree(&s, &sk, with ? &lv : NULL, &cards, sp.name, 6, 1, pos, 0, &err),
                         SY_OK);
        assert_int_equal(sy_scene_finish(&s, &err), SY_OK);
        sy_scan_options sc;
        tls(&sc, 0.4, 0.005, 0.3);
        sc.radius = 10;
        sy_cloud c;
        scan_ok(&s, &sc, &c);
        wood[with] = count_wood(&c);
        sy_cloud_free(&c);
        sy_scene_free(&s);
    }
    assert_true(wood[1] > 0);
    assert_true(wood[1] < wood[0] * 0.9);
    sy_skeleton_free(&sk);
    sy_leaves_free(&lv);
    sy_species_params_free(&sp);
}

static void small_plot(sy_scene *s, uint64_t seed)
{
    sy_scene_options o;
    o = sy_scene_options_default();
    o.species[0] = "quaking_aspen";
    o.species[1] = "european_pine";
    o.n_species = 2;
    o.plot_size = 12;
    o.trees = 3;
    o.slope_deg = 4;
    o.roughness = 0.1;
    o.seed = seed;
    sy_error err = {0};
    sy_code rc = sy_scene_build(s, &o, 0, &err);
    if (rc) fprintf(stderr, "%s\n", err.msg);
    assert_int_equal(rc, SY_OK);
}

static void plot_scanner(sy_scan_options *sc, uint64_t seed)
{
    *sc = sy_scan_options_for(SY_SCANNER_TERRESTRIAL);
    sc->step_deg = 0.5;
    sc->seed = seed;
}

static int clouds_equal(const sy_cloud *a, const sy_cloud *b)
{
    if (a->n != b->n || memcmp(a->xyz, b->xyz, 3 * a->n * sizeof(float)) ||
        memcmp(a->intensity, b->intensity, a->n * 2) || memcmp(a->gps_time, b->gps_time, a->n * sizeof(double)) ||
        memcmp(a->return_number, b->return_number, a->n) || a->n_attrs != b->n_attrs)
        return 0;
    for (size_t k = 0; k < a->n_attrs; k++)
        if (memcmp(a->attrs[k].values, b->attrs[k].values, a->n * sizeof(double))) return 0;
    return 1;
}

static void deterministic_across_threads_and_runs(void **state)
{
    (void)state;
    setenv("SOURCE_DATE_EPOCH", "1700000000", 1);
    sy_scene s;
    small_plot(&s, 4);
    sy_scan_options sc;
    plot_scanner(&sc, 4);
    sy_cloud one, two, again;
    sy_set_threads(1);
    scan_ok(&s, &sc, &one);
    sy_set_threads(2);
    scan_ok(&s, &sc, &two);
    assert_true(one.n > 10000);
    assert_true(clouds_equal(&one, &two));
    /* Same seed, a freshly built scene: the same LAS bytes. */
    sy_scene s2;
    small_plot(&s2, 4);
    scan_ok(&s2, &sc, &again);
    sy_error err = {0};
    const char *pa = tmp_path("det_a.las"), *pb = tmp_path("det_b.las");
    assert_int_equal(sy_write_las(pa, &one, &err), SY_OK);
    assert_int_equal(sy_write_las(pb, &again, &err), SY_OK);
    sy_buffer ba, bb;
    assert_int_equal(sy_read_file(pa, &ba, &err), SY_OK);
    assert_int_equal(sy_read_file(pb, &bb, &err), SY_OK);
    assert_int_equal(ba.size, bb.size);
    assert_memory_equal(ba.data, bb.data, ba.size);
    sy_buffer_free(&ba);
    sy_buffer_free(&bb);
    /* Another seed changes the noise. */
    sy_cloud other;
    sc.seed = 5;
    scan_ok(&s, &sc, &other);
    assert_false(clouds_equal(&one, &other));
    sy_set_threads(0);
    sy_cloud_free(&one);
    sy_cloud_free(&two);
    sy_cloud_free(&again);
    sy_cloud_free(&other);
    sy_scene_free(&s);
    sy_scene_free(&s2);
}

static char *truth_text(const sy_scene *s, const sy_scan_options *sc)
{
    const char *path = tmp_path("truth.json");
    FILE *fp = fopen(path, "w");
    assert_non_null(fp);
    sy_write_truth(fp, s, sc, 4);
    assert_int_equal(fclose(fp), 0);
    sy_buffer b;
    sy_error err = {0};
    assert_int_equal(sy_read_file(path, &b, &err), SY_OK);
    return (char *)b.data;
}

/* The number after `"key":` at the n-th occurrence. */
static double json_number(const char *text, const char *key, int nth)
{
    char pat[64];
    snprintf(pat, sizeof pat, "\"%s\":", key);
    const char *p = text;
    for (int i = 0; i <= nth; i++) {
        p = strstr(p, pat);
        assert_non_null(p);
        p += strlen(pat);
    }
    return strtod(p, NULL);
}

/* Radius at `above` m over the root, walking the trunk node by node. */
static double walk_trunk_radius(const sy_skeleton *sk, double above)
{
    int32_t node = 0;
    double z0 = sk->pos[2];
    for (;;) {
        int32_t next = -1;
        for (size_t i = 0; i < sk->n; i++)
            if (sk->parent[i] == node && sk->branch[i] == sk->branch[0]) next = (int32_t)i;
        if (next < 0) return NAN;
        double za = sk->pos[3 * node + 2] - z0, zb = sk->pos[3 * next + 2] - z0;
        if (zb >= above) return sk->radius[node] + (above - za) / (zb - za) * (sk->radius[next] - sk->radius[node]);
        node = next;
    }
}

static void truth_dbh_and_tree_ids(void **state)
{
    (void)state;
    sy_error err = {0};
    /* An analytic tapered trunk: r = 0.3 - 0.04 z, so dbh = 2 * 0.248; one
     * branch from mid-trunk stays below the top. */
    sy_skeleton sk;
    sy_skeleton_init(&sk, 0, &err);
    float a[3] = {0, 0, 0}, m[3] = {0, 0, 2.5f}, b[3] = {0, 0, 5}, c[3] = {1, 0, 3};
    sy_skeleton_add(&sk, a, 0.3f, -1, 0, 0, &err);
    sy_skeleton_add(&sk, m, 0.2f, 0, 0, 0, &err);
    sy_skeleton_add(&sk, b, 0.1f, 1, 0, 0, &err);
    sy_skeleton_add(&sk, c, 0.05f, 1, 1, 1, &err);
    sy_scene s;
    sy_scene_init(&s);
    double pos[3] = {2, 3, 1};
    assert_int_equal(sy_scene_add_tree(&s, &sk, NULL, NULL, "cone", -1, 9, pos, 30, &err), SY_OK);
    sy_scan_options sc;
    plot_scanner(&sc, 1);
    char *text = truth_text(&s, &sc);
    assert_float_equal(json_number(text, "dbh", 0), 2 * (0.3 - 0.04 * 1.3), 1e-3);
    assert_float_equal(json_number(text, "height", 0), 5.0, 1e-3);
    assert_float_equal(json_number(text, "z", 2), 6.0, 1e-5); /* world coordinates */
    assert_non_null(strstr(text, "\"format\":\"sylva-truth\""));
    free(text);
    sy_scene_free(&s);
    sy_skeleton_free(&sk);

    /* A plot: every tree's dbh matches its trunk, point tree ids match the file. */
    small_plot(&s, 8);
    plot_scanner(&sc, 8);
    text = truth_text(&s, &sc);
    for (size_t t = 0; t < s.n_trees; t++) {
        double r = walk_trunk_radius(&s.trees[t].skel, 1.3);
        assert_float_equal(json_number(text, "dbh", (int)t), 2 * r, 1e-3);
        assert_float_equal(json_number(text, "tree_id", (int)t), (double)(t + 1), 0);
    }
    size_t entries = 0;
    for (const char *q = strstr(text, "\"tree_id\":"); q; q = strstr(q + 1, "\"tree_id\":")) entries++;
    assert_int_equal(entries, s.n_trees);
    sy_cloud cl;
    scan_ok(&s, &sc, &cl);
    const double *tid = sy_cloud_attr(&cl, "treeID"), *sid = sy_cloud_attr(&cl, "speciesID");
    size_t per_tree[4] = {0};
    for (size_t i = 0; i < cl.n; i++) {
        assert_true(tid[i] >= 0 && tid[i] <= (double)s.n_trees);
        int t = (int)tid[i];
        per_tree[t]++;
        if (t > 0) assert_true(sid[i] == json_number(text, "species_id", t - 1));
        else assert_true(sid[i] == -1);
    }
    for (size_t t = 1; t <= s.n_trees; t++) assert_true(per_tree[t] > 100);
    assert_true(per_tree[0] > 0); /* ground */
    free(text);
    sy_cloud_free(&cl);
    sy_scene_free(&s);
}

static void airborne_density_on_flat_ground(void **state)
{
    (void)state;
    sy_error err = {0};
    sy_scene s;
    sy_scene_init(&s);
    sy_terrain flat = {0, 0, 0, 6, 0, 1, {-80, -80}, {80, 80}, 1.0};
    assert_int_equal(sy_scene_add_terrain(&s, &flat, &err), SY_OK);
    s.area_lo[0] = s.area_lo[1] = -40;
    s.area_hi[0] = s.area_hi[1] = 40;
    assert_int_equal(sy_scene_finish(&s, &err), SY_OK);
    const double density[2] = {4, 15};
    for (int k = 0; k < 2; k++) {
        sy_scan_options sc;
        sc = sy_scan_options_for(SY_SCANNER_AIRBORNE);
        sc.altitude = 30;
        sc.density = density[k];
        sy_cloud c;
        scan_ok(&s, &sc, &c);
        size_t inside = 0;
        for (size_t i = 0; i < c.n; i++) {
            double x = c.origin[0] + c.xyz[3 * i], y = c.origin[1] + c.xyz[3 * i + 1];
            assert_int_equal(c.classification[i], 2);
            if (fabs(x) < 20 && fabs(y) < 20 && c.return_number[i] == 1) inside++;
        }
        double got = inside / 1600.0;
        if (fabs(got - density[k]) > 0.2 * density[k]) fprintf(stderr, "density %g, got %g\n", density[k], got);
        assert_true(fabs(got - density[k]) <= 0.2 * density[k]);
        sy_cloud_free(&c);
    }
    sy_scene_free(&s);
}

/* Out-of-range scene options are errors naming the field, before anything
 * grows. */
static void scene_options_are_checked(void **state)
{
    (void)state;
    sy_error err = {0};
    sy_scene_options d = sy_scene_options_default(), o;
    d.species[0] = "quaking_aspen";
    d.n_species = 1;
    assert_int_equal(sy_scene_options_check(&d, &err), SY_OK);
    o = d;
    o.n_species = 0;
    assert_int_equal(sy_scene_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "n_species"));
    o = d;
    o.species[0] = "";
    assert_int_equal(sy_scene_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "species[0]"));
    o = d;
    o.plot_size = -5;
    assert_int_equal(sy_scene_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "plot_size"));
    o = d;
    o.plot_size = 20;
    o.trees = 10001;
    assert_int_equal(sy_scene_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "trees"));
    o = d;
    o.neighbours = 13;
    assert_int_equal(sy_scene_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "neighbours"));
    o = d;
    o.plot_size = 20;
    o.neighbours = 2;
    assert_int_equal(sy_scene_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "neighbours"));
    o = d;
    o.forest = 1.5;
    assert_int_equal(sy_scene_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "forest"));
    o = d;
    o.understory = NAN;
    assert_int_equal(sy_scene_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "understory"));
    o = d;
    o.slope_deg = 90;
    assert_int_equal(sy_scene_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "slope_deg"));
    o = d;
    o.aspect_deg = INFINITY;
    assert_int_equal(sy_scene_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "aspect_deg"));
    o = d;
    o.roughness = -0.1;
    assert_int_equal(sy_scene_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "roughness"));
    /* The stage checks them itself. */
    sy_scene s;
    o = d;
    o.forest = -1;
    assert_int_equal(sy_scene_build(&s, &o, 0, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "forest"));
    sy_scene_free(&s);
}

int main(void)
{
    sy_progress_set_quiet(1);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(ray_cone_analytic),
        cmocka_unit_test(ray_quad_analytic),
        cmocka_unit_test(needle_card_stops_its_fill),
        cmocka_unit_test(ray_terrain_analytic),
        cmocka_unit_test(bvh_matches_brute_force),
        cmocka_unit_test(cylinder_surface_and_coverage),
        cmocka_unit_test(cylinder_range_noise),
        cmocka_unit_test(leaves_occlude_wood),
        cmocka_unit_test(deterministic_across_threads_and_runs),
        cmocka_unit_test(truth_dbh_and_tree_ids),
        cmocka_unit_test(airborne_density_on_flat_ground),
        cmocka_unit_test(scene_options_are_checked),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
