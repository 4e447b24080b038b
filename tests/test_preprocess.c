/* The preprocessing stage on synthetic scenes built here with a seeded RNG
 * (sloped noisy ground, a vertical trunk, a crown blob, far outliers) and on
 * real tree clouds read with a test-local "x y z" text parser. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/parallel.h"
#include "stages/core/rng.h"
#include "stages/preprocess/preprocess.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* ------------------------------------------------------------- test scene */

enum { GROUND = 0, TRUNK = 1, CROWN = 2, OUTLIER = 3 };

static uint64_t rng_state;
static double uniform(void)
{
    uint64_t z = (rng_state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return (z >> 11) * (1.0 / 9007199254740992.0);
}
static double gauss(void)
{
    double u = uniform(), v = uniform();
    return sqrt(-2 * log(u > 1e-300 ? u : 1e-300)) * cos(2 * M_PI * v);
}

#define PLOT 20.0
#define SLOPE_DEG 10.0
#define TRUNK_X 10.0
#define TRUNK_Y 10.0
#define TRUNK_R 0.2
#define TRUNK_H 6.0

static double ground_z(double x) { return tan(SLOPE_DEG * M_PI / 180) * x; }

typedef struct {
    sy_cloud c;
    double *label; /* attribute "label": GROUND, TRUNK, CROWN or OUTLIER */
    size_t counts[4];
} scene;

static void put(scene *s, size_t *i, double x, double y, double z, int label)
{
    s->c.xyz[3 * *i] = (float)x, s->c.xyz[3 * *i + 1] = (float)y, s->c.xyz[3 * *i + 2] = (float)z;
    s->label[*i] = label;
    s->counts[label]++;
    (*i)++;
}

/* Far from the plot's ground, trunk and crown. */
static int is_far(double x, double y, double z)
{
    int over_plot = x > -2 && x < PLOT + 2 && y > -2 && y < PLOT + 2;
    if (over_plot && fabs(z - ground_z(x)) < 3) return 0;
    double r = hypot(x - TRUNK_X, y - TRUNK_Y), base = ground_z(TRUNK_X);
    return !(r < 5 && z > base - 3 && z < base + TRUNK_H + 6);
}

static void make_scene(scene *s, uint64_t seed, int with_outliers)
{
    const size_t n_ground = 40000, n_trunk = 8000, n_crown = 20000;
    size_t n_out = with_outliers ? (n_ground + n_trunk + n_crown) / 100 : 0;
    memset(s, 0, sizeof *s);
    rng_state = seed;
    sy_error err;
    assert_int_equal(sy_cloud_init(&s->c, n_ground + n_trunk + n_crown + n_out, &err), SY_OK);
    s->c.origin[0] = 1000, s->c.origin[1] = 2000, s->c.origin[2] = 50;
    snprintf(s->c.meta.format, sizeof s->c.meta.format, "XYZ");
    s->label = sy_cloud_add_attr(&s->c, "label", &err);
    assert_non_null(s->label);
    size_t i = 0;
    for (size_t k = 0; k < n_ground; k++) {
        double x = uniform() * PLOT, y = uniform() * PLOT;
        put(s, &i, x, y, ground_z(x) + 0.02 * gauss(), GROUND);
    }
    double base = ground_z(TRUNK_X);
    for (size_t k = 0; k < n_trunk; k++) {
        double a = uniform() * 2 * M_PI, r = TRUNK_R + 0.005 * gauss();
        put(s, &i, TRUNK_X + r * cos(a), TRUNK_Y + r * sin(a), base + 0.02 + uniform() * TRUNK_H, TRUNK);
    }
    for (size_t k = 0; k < n_crown;) { /* a solid ellipsoid of leaves */
        double u = 2 * uniform() - 1, v = 2 * uniform() - 1, w = 2 * uniform() - 1;
        if (u * u + v * v + w * w > 1) continue;
        put(s, &i, TRUNK_X + 3 * u, TRUNK_Y + 3 * v, base + TRUNK_H + 1 + 2.5 * w, CROWN);
        k++;
    }
    for (size_t k = 0; k < n_out;) {
        double x = -20 + 60 * uniform(), y = -20 + 60 * uniform(), z = -15 + 45 * uniform();
        if (!is_far(x, y, z)) continue;
        put(s, &i, x, y, z, OUTLIER);
        k++;
    }
    assert_int_equal(i, s->c.n);
}

static void count_labels(const sy_cloud *c, size_t counts[4])
{
    const double *label = sy_cloud_attr(c, "label");
    assert_non_null(label);
    memset(counts, 0, 4 * sizeof counts[0]);
    for (size_t i = 0; i < c->n; i++) counts[(int)label[i]]++;
}

/* ---------------------------------------------------------------- options */

static void test_up_parse(void **state)
{
    (void)state;
    int up = 99;
    assert_int_equal(sy_up_parse("auto", &up), 0);
    assert_int_equal(up, SY_UP_AUTO);
    assert_int_equal(sy_up_parse("z", &up), 0);
    assert_int_equal(up, SY_UP_Z);
    assert_int_equal(sy_up_parse("-y", &up), 0);
    assert_int_equal(up, -SY_UP_Y);
    assert_int_equal(sy_up_parse("+x", &up), 0);
    assert_int_equal(up, SY_UP_X);
    assert_int_equal(sy_up_parse("w", &up), -1);
    assert_int_equal(sy_up_parse("zz", &up), -1);
    assert_int_equal(sy_up_parse("", &up), -1);
    assert_string_equal(sy_up_name(-SY_UP_Y), "-y");

    sy_preprocess_options o;
    sy_error err;
    o = sy_preprocess_options_default();
    assert_int_equal(sy_preprocess_options_check(&o, &err), SY_OK);
    o.voxel = -1;
    assert_int_equal(sy_preprocess_options_check(&o, &err), SY_EUSAGE);
    assert_non_null(strstr(err.msg, "--voxel"));
    o = sy_preprocess_options_default();
    o.crop = 1;
    double box[6] = {0, 0, 0, -1, 1, 1};
    memcpy(o.crop_box, box, sizeof box);
    assert_int_equal(sy_preprocess_options_check(&o, &err), SY_EUSAGE);
    o = sy_preprocess_options_default();
    o.ground_cell = 0;
    assert_int_equal(sy_preprocess_options_check(&o, &err), SY_EUSAGE);
}

/* ------------------------------------------------------------------- steps */

static void test_outliers(void **state)
{
    (void)state;
    scene s;
    make_scene(&s, 11, 1);
    sy_error err;
    sy_set_threads(2);
    assert_int_equal(sy_remove_outliers(&s.c, 16, 2.0, &err), SY_OK);
    size_t left[4];
    count_labels(&s.c, left);
    size_t inliers = s.counts[GROUND] + s.counts[TRUNK] + s.counts[CROWN];
    size_t inliers_left = left[GROUND] + left[TRUNK] + left[CROWN];
    print_message("outliers: %zu of %zu injected removed, %zu of %zu others removed\n",
                  s.counts[OUTLIER] - left[OUTLIER], s.counts[OUTLIER], inliers - inliers_left, inliers);
    assert_true(s.counts[OUTLIER] - left[OUTLIER] >= 0.90 * s.counts[OUTLIER]);
    assert_true(inliers - inliers_left < 0.02 * inliers);
    /* The neighbour pass runs on all threads: one and two keep the same points. */
    scene t;
    make_scene(&t, 11, 1);
    sy_set_threads(1);
    assert_int_equal(sy_remove_outliers(&t.c, 16, 2.0, &err), SY_OK);
    sy_set_threads(0);
    assert_int_equal(t.c.n, s.c.n);
    assert_memory_equal(t.c.xyz, s.c.xyz, 3 * s.c.n * sizeof(float));
    sy_cloud_free(&t.c);
    sy_cloud_free(&s.c);
}

static void test_ground(void **state)
{
    (void)state;
    scene s;
    make_scene(&s, 12, 1);
    sy_error err;
    assert_int_equal(sy_remove_outliers(&s.c, 16, 2.0, &err), SY_OK);
    sy_preprocess_options o;
    o = sy_preprocess_options_default();
    size_t n_ground = 0;
    assert_int_equal(sy_classify_ground(&s.c, &o, &n_ground, &err), SY_OK);
    const double *label = sy_cloud_attr(&s.c, "label"), *hag = sy_cloud_attr(&s.c, "height_above_ground");
    assert_non_null(hag);
    assert_non_null(s.c.classification);
    size_t truth = 0, found = 0, veg = 0, false_pos = 0, counted = 0;
    for (size_t i = 0; i < s.c.n; i++) {
        int g = s.c.classification[i] == 2;
        counted += g;
        if (label[i] == GROUND) truth++, found += g;
        else if (label[i] == TRUNK || label[i] == CROWN) veg++, false_pos += g;
        if (!g) assert_int_equal(s.c.classification[i], 1);
        if (label[i] == CROWN) assert_true(hag[i] > TRUNK_H + 1 - 2.5 - 0.5);
    }
    print_message("ground: %zu of %zu found, %zu of %zu trunk/crown points misclassified\n", found, truth, false_pos,
                  veg);
    assert_int_equal(counted, n_ground);
    assert_true(found >= 0.95 * truth);
    assert_true(false_pos < 0.03 * veg);
    sy_cloud_free(&s.c);
}

/* 1 if the cloud holds no two points in one voxel of edge size. */
static uint64_t voxel_key(const float *p, const float lo[3], double size)
{
    uint64_t key = 0;
    for (int k = 0; k < 3; k++) key = key << 21 | (uint64_t)floor((p[k] - lo[k]) / size);
    return key;
}
static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}
static size_t distinct_voxels(const sy_cloud *c, const float lo[3], double size, int *duplicates)
{
    uint64_t *keys = malloc(c->n * sizeof *keys);
    assert_non_null(keys);
    for (size_t i = 0; i < c->n; i++) keys[i] = voxel_key(c->xyz + 3 * i, lo, size);
    qsort(keys, c->n, sizeof *keys, cmp_u64);
    size_t distinct = c->n ? 1 : 0;
    *duplicates = 0;
    for (size_t i = 1; i < c->n; i++) {
        if (keys[i] == keys[i - 1]) *duplicates = 1;
        else distinct++;
    }
    free(keys);
    return distinct;
}

static void test_voxel(void **state)
{
    (void)state;
    scene s;
    make_scene(&s, 13, 1);
    sy_error err;
    double *orig = sy_cloud_add_attr(&s.c, "orig_index", &err);
    assert_non_null(orig);
    for (size_t i = 0; i < s.c.n; i++) orig[i] = (double)i;
    sy_cloud before;
    assert_int_equal(sy_cloud_copy(&before, &s.c, &err), SY_OK);
    float lo[3] = {s.c.xyz[0], s.c.xyz[1], s.c.xyz[2]};
    for (size_t i = 0; i < s.c.n; i++)
        for (int k = 0; k < 3; k++)
            if (s.c.xyz[3 * i + k] < lo[k]) lo[k] = s.c.xyz[3 * i + k];
    const double size = 0.3;
    int dup;
    size_t occupied = distinct_voxels(&before, lo, size, &dup);
    assert_int_equal(sy_voxel_downsample(&s.c, size, &err), SY_OK);
    print_message("voxel: %zu -> %zu points, %zu voxels occupied\n", before.n, s.c.n, occupied);
    assert_true(s.c.n < before.n);
    assert_int_equal(distinct_voxels(&s.c, lo, size, &dup), s.c.n);
    assert_false(dup);
    assert_int_equal(s.c.n, occupied); /* one per voxel, none lost */
    orig = sy_cloud_attr(&s.c, "orig_index");
    const double *label = sy_cloud_attr(&s.c, "label"), *label0 = sy_cloud_attr(&before, "label");
    for (size_t i = 0; i < s.c.n; i++) {
        size_t j = (size_t)orig[i];
        assert_true(j < before.n);
        if (i) assert_true(orig[i] > orig[i - 1]); /* order kept */
        assert_memory_equal(s.c.xyz + 3 * i, before.xyz + 3 * j, 3 * sizeof(float));
        assert_true(label[i] == label0[j]);
    }
    /* Deterministic: a second run on the same input keeps the same points. */
    sy_cloud again;
    assert_int_equal(sy_cloud_copy(&again, &before, &err), SY_OK);
    assert_int_equal(sy_voxel_downsample(&again, size, &err), SY_OK);
    assert_int_equal(again.n, s.c.n);
    assert_memory_equal(again.xyz, s.c.xyz, 3 * s.c.n * sizeof(float));
    sy_cloud_free(&again);
    sy_cloud_free(&before);
    sy_cloud_free(&s.c);
}

static void test_normals(void **state)
{
    (void)state;
    scene s;
    make_scene(&s, 14, 0);
    sy_error err;
    sy_cloud other;
    assert_int_equal(sy_cloud_copy(&other, &s.c, &err), SY_OK);
    sy_set_threads(1);
    assert_int_equal(sy_estimate_normals(&s.c, 16, &err), SY_OK);
    sy_set_threads(3);
    assert_int_equal(sy_estimate_normals(&other, 16, &err), SY_OK);
    sy_set_threads(0);
    assert_memory_equal(s.c.normal, other.normal, 3 * s.c.n * sizeof(float));

    double a = SLOPE_DEG * M_PI / 180, plane[3] = {-sin(a), 0, cos(a)};
    const double *label = sy_cloud_attr(&s.c, "label");
    size_t ground = 0, close = 0, close_down = 0, up = 0, trunk = 0, outward = 0;
    for (size_t i = 0; i < s.c.n; i++) {
        const float *nv = s.c.normal + 3 * i;
        double len = sqrt(nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2]);
        assert_true(fabs(len - 1) < 1e-4);
        if (label[i] == GROUND) {
            ground++;
            /* Sign-blind angle first, then the orientation on its own. */
            double dot = fabs(nv[0] * plane[0] + nv[1] * plane[1] + nv[2] * plane[2]);
            int near = dot > cos(10 * M_PI / 180);
            close += near;
            close_down += near && nv[2] < 0;
            up += nv[2] > 0;
        } else if (label[i] == TRUNK) {
            trunk++;
            double rx = s.c.xyz[3 * i] - TRUNK_X, ry = s.c.xyz[3 * i + 1] - TRUNK_Y;
            outward += nv[0] * rx + nv[1] * ry > 0;
        }
    }
    print_message("normals: %zu of %zu ground within 10 deg, %zu up; %zu of %zu trunk outward\n", close, ground, up,
                  outward, trunk);
    assert_true(close >= 0.95 * ground);
    assert_int_equal(close_down, 0); /* ground-like normals all face up */
    assert_true(up >= 0.99 * ground); /* the rest are mixed ground/trunk patches */
    assert_true(outward >= 0.95 * trunk);
    sy_cloud_free(&other);
    sy_cloud_free(&s.c);
}

static void test_crop(void **state)
{
    (void)state;
    scene s;
    make_scene(&s, 15, 1);
    sy_error err;
    double *orig = sy_cloud_add_attr(&s.c, "orig_index", &err);
    for (size_t i = 0; i < s.c.n; i++) orig[i] = (double)i;
    sy_cloud before;
    assert_int_equal(sy_cloud_copy(&before, &s.c, &err), SY_OK);
    double box[6] = {1005, 2003, 50, 1012.5, 2015, 58};
    size_t inside = 0;
    for (size_t i = 0; i < before.n; i++) {
        int in = 1;
        for (int k = 0; k < 3; k++) {
            double w = before.origin[k] + before.xyz[3 * i + k];
            in &= w >= box[k] && w <= box[k + 3];
        }
        inside += in;
    }
    assert_int_equal(sy_crop(&s.c, box, &err), SY_OK);
    assert_true(inside > 1000 && inside < before.n);
    assert_int_equal(s.c.n, inside);
    orig = sy_cloud_attr(&s.c, "orig_index");
    for (size_t i = 0; i < s.c.n; i++) {
        for (int k = 0; k < 3; k++) {
            double w = s.c.origin[k] + s.c.xyz[3 * i + k];
            assert_true(w >= box[k] && w <= box[k + 3]);
        }
        assert_memory_equal(s.c.xyz + 3 * i, before.xyz + 3 * (size_t)orig[i], 3 * sizeof(float));
    }
    sy_cloud_free(&before);
    sy_cloud_free(&s.c);
}

/* ---------------------------------------------------------------- up axis */

/* The matrix of sy_rotate_to_z_up for up, row by row: out = M in. */
static void rotation_matrix(int up, double m[3][3])
{
    sy_cloud unit;
    sy_error err;
    assert_int_equal(sy_cloud_init(&unit, 3, &err), SY_OK);
    for (int k = 0; k < 3; k++) unit.xyz[3 * k + k] = 1;
    sy_rotate_to_z_up(&unit, up);
    for (int col = 0; col < 3; col++)
        for (int row = 0; row < 3; row++) m[row][col] = unit.xyz[3 * col + row];
    sy_cloud_free(&unit);
}

static void test_rotations_are_proper(void **state)
{
    (void)state;
    const int ups[6] = {3, -3, 2, -2, 1, -1};
    for (int u = 0; u < 6; u++) {
        double m[3][3];
        rotation_matrix(ups[u], m);
        double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                     m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        assert_true(fabs(det - 1) < 1e-9);
        /* The input's up axis lands on +z. */
        int axis = abs(ups[u]) - 1;
        assert_true(fabs(m[2][axis] - (ups[u] > 0 ? 1 : -1)) < 1e-9);
    }
}

/* Turns a Z-up cloud into one whose up is the signed axis up (the inverse of
 * sy_rotate_to_z_up: the transpose of its matrix). */
static void rotate_from_z_up(sy_cloud *c, int up)
{
    double m[3][3];
    rotation_matrix(up, m);
    for (size_t i = 0; i < c->n; i++) {
        double p[3] = {c->xyz[3 * i], c->xyz[3 * i + 1], c->xyz[3 * i + 2]};
        for (int r = 0; r < 3; r++) c->xyz[3 * i + r] = (float)(m[0][r] * p[0] + m[1][r] * p[1] + m[2][r] * p[2]);
    }
    double o[3] = {c->origin[0], c->origin[1], c->origin[2]};
    for (int r = 0; r < 3; r++) c->origin[r] = m[0][r] * o[0] + m[1][r] * o[1] + m[2][r] * o[2];
}

/* Detects the up axis of c rotated into each of the six orientations and
 * checks that rotating back restores c. Returns the number recovered. */
static int recover_all_orientations(const sy_cloud *c, const char *what)
{
    const int ups[6] = {3, -3, 2, -2, 1, -1};
    int ok = 0;
    sy_error err;
    for (int u = 0; u < 6; u++) {
        sy_cloud r;
        assert_int_equal(sy_cloud_copy(&r, c, &err), SY_OK);
        rotate_from_z_up(&r, ups[u]);
        int found = 0;
        sy_up_evidence ev;
        assert_int_equal(sy_detect_up(&r, &found, &ev, &err), SY_OK);
        if (found == ups[u]) ok++;
        else
            print_message("%s rotated to %s: detected %s (axis %.3f %.3f %.3f, sign %+.4f %+.4f %+.4f)\n", what,
                          sy_up_name(ups[u]), sy_up_name(found), ev.axis_score[0], ev.axis_score[1], ev.axis_score[2],
                          ev.sign_score[0], ev.sign_score[1], ev.sign_score[2]);
        sy_rotate_to_z_up(&r, found);
        if (found == ups[u]) {
            for (size_t i = 0; i < c->n; i++)
                for (int k = 0; k < 3; k++) {
                    double w0 = c->origin[k] + c->xyz[3 * i + k], w1 = r.origin[k] + r.xyz[3 * i + k];
                    assert_true(fabs(w0 - w1) < 1e-3);
                }
        }
        sy_cloud_free(&r);
    }
    return ok;
}

static void test_up_synthetic(void **state)
{
    (void)state;
    scene s;
    make_scene(&s, 16, 1);
    assert_int_equal(recover_all_orientations(&s.c, "synthetic plot"), 6);
    sy_cloud_free(&s.c);
}

/* A plain "x y z ..." text reader (CRLF tolerated), so these tests do not
 * depend on the ingest stage. Returns 0 when the file is absent. */
static int load_xyz(const char *path, sy_cloud *c)
{
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    size_t cap = 1 << 16, n = 0;
    double *p = malloc(cap * 3 * sizeof *p);
    assert_non_null(p);
    char line[1024];
    while (fgets(line, sizeof line, f)) {
        double v[3];
        if (sscanf(line, "%lf %lf %lf", &v[0], &v[1], &v[2]) != 3) continue;
        if (n == cap) {
            cap *= 2;
            p = realloc(p, cap * 3 * sizeof *p);
            assert_non_null(p);
        }
        memcpy(p + 3 * n++, v, sizeof v);
    }
    fclose(f);
    sy_error err;
    assert_int_equal(sy_cloud_init(c, n, &err), SY_OK);
    for (int k = 0; k < 3; k++) c->origin[k] = n ? floor(p[k]) : 0;
    for (size_t i = 0; i < 3 * n; i++) c->xyz[i] = (float)(p[i] - c->origin[i % 3]);
    free(p);
    return n > 0;
}

static void test_up_real(void **state)
{
    (void)state;
    const char *files[] = {"real/adtree/tree1.xyz", "real/adtree/tree7.xyz", "real/adtree/tree13.xyz",
                           "real/adtree/tree33.xyz", "real/adtree/Lille_11.xyz", "real/rtwig/cloud.txt"};
    int tested = 0;
    for (size_t f = 0; f < sizeof files / sizeof files[0]; f++) {
        sy_cloud c;
        if (!load_xyz(data_path(files[f]), &c)) {
            print_message("%s: not found, left out\n", files[f]);
            continue;
        }
        assert_int_equal(recover_all_orientations(&c, files[f]), 6);
        tested++;
        sy_cloud_free(&c);
    }
    if (!tested) skip();
}

/* --------------------------------------------------------------- pipeline */

static void test_pipeline(void **state)
{
    (void)state;
    scene s;
    make_scene(&s, 17, 1);
    rotate_from_z_up(&s.c, 2); /* a Y-up scan */
    sy_preprocess_options o;
    o = sy_preprocess_options_default();
    o.voxel = 0.05;
    sy_preprocess_result r;
    sy_error err;
    assert_int_equal(sy_preprocess(&s.c, &o, &r, &err), SY_OK);
    assert_int_equal(r.up_axis, SY_UP_Y);
    assert_true(r.up_detected);
    assert_int_equal(r.point_count_in, s.c.n + (r.point_count_in - r.point_count_out));
    assert_int_equal(r.point_count_out, s.c.n);
    size_t n = r.point_count_in;
    for (int i = 0; i < SY_PREPROCESS_STEPS; i++) {
        assert_int_equal(r.steps[i].before, n);
        assert_true(r.steps[i].after <= r.steps[i].before);
        assert_true(r.steps[i].seconds >= 0);
        n = r.steps[i].after;
    }
    assert_int_equal(n, s.c.n);
    assert_false(r.steps[1].ran); /* no crop asked */
    assert_true(r.steps[3].before > r.steps[3].after);
    assert_non_null(s.c.normal);
    assert_non_null(s.c.classification);
    assert_non_null(sy_cloud_attr(&s.c, "height_above_ground"));
    size_t left[4];
    count_labels(&s.c, left);
    assert_true(left[OUTLIER] <= s.counts[OUTLIER] / 10);
    /* Z-up again: the crown sits above the trunk base. */
    double min[3], max[3];
    sy_cloud_bounds(&s.c, min, max);
    assert_true(max[2] - min[2] > TRUNK_H);

    /* --remove-ground drops exactly the ground class. */
    size_t ground = r.ground_points;
    assert_true(ground > 0);
    sy_cloud_free(&s.c);
    make_scene(&s, 17, 1);
    o.remove_ground = 1;
    o.up = SY_UP_Z;
    assert_int_equal(sy_preprocess(&s.c, &o, &r, &err), SY_OK);
    assert_int_equal(r.steps[4].before - r.steps[4].after, r.ground_points);
    for (size_t i = 0; i < s.c.n; i++) assert_int_not_equal(s.c.classification[i], 2);
    sy_cloud_free(&s.c);
}

/* Preprocesses c (+z up, no ground, no normals) into r; the highest
 * point left. */
static double preprocess_top(sy_cloud *c, sy_preprocess_result *r)
{
    sy_error err = {0};
    sy_preprocess_options o = sy_preprocess_options_default();
    o.up = SY_UP_Z;
    o.ground = 0;
    o.normals = 0;
    assert_int_equal(sy_preprocess(c, &o, r, &err), SY_OK);
    double min[3], max[3];
    sy_cloud_bounds(c, min, max);
    return max[2];
}

/* The top a height is measured to: the highest point with company, before
 * the outlier filter, which strips a sparse crown top along with the strays.
 * The filter's output keeps that top (keep_supported_top): every tuft's
 * return is there, the stray is not. */
static void test_top_before_outliers(void **state)
{
    (void)state;
    const size_t dense = 20000, tufts = 12;
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_cloud_init(&c, dense + 4 * tufts + 1, &err), SY_OK);
    uint64_t rng = 3;
    size_t i = 0;
    for (; i < dense; i++) { /* a 2 m cube of crown, 1 to 3 m up */
        for (int a = 0; a < 3; a++) c.xyz[3 * i + a] = (float)(2 * sy_unit53(sy_splitmix64(&rng)) + (a == 2));
    }
    for (size_t t = 0; t < tufts; t++) /* sparse tufts of four returns, rising to 5.5 m */
        for (int k = 0; k < 4; k++, i++) {
            c.xyz[3 * i] = (float)(1 + 0.05 * k), c.xyz[3 * i + 1] = (float)(1 + 0.6 * (double)t);
            c.xyz[3 * i + 2] = (float)(3.2 + 0.2 * (double)t + 0.03 * k);
        }
    c.xyz[3 * i] = c.xyz[3 * i + 1] = 1, c.xyz[3 * i + 2] = 9; /* one stray high above */
    sy_preprocess_result r;
    double kept_top = preprocess_top(&c, &r);
    printf("top %.3f, after the outlier filter %.3f\n", r.top_z, kept_top);
    assert_true(fabs(r.top_z - (3.2 + 0.2 * (double)(tufts - 1) + 0.09)) < 1e-4);
    assert_true(fabs(kept_top - r.top_z) < 1e-4); /* the tufts' top is kept, the stray is not */
    size_t tuft_points = 0;
    for (size_t j = 0; j < c.n; j++) tuft_points += c.xyz[3 * j + 2] > 3.1f;
    assert_int_equal(tuft_points, 4 * tufts);
    assert_true(strstr(r.steps[3].detail, "crown's top kept") != NULL);
    sy_cloud_free(&c);
}

/* A crown's top seen as lone returns 0.8 m apart (no company within 0.5 m):
 * the top follows them up, each within 1 m of the one below; a stray 1.6 m
 * above the last is not the tree, and the filter's output keeps the chain
 * but not the stray. */
static void test_top_follows_sparse_returns(void **state)
{
    (void)state;
    const size_t dense = 20000, lone = 5;
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_cloud_init(&c, dense + lone + 1, &err), SY_OK);
    uint64_t rng = 5;
    size_t i = 0;
    for (; i < dense; i++) /* a 2 m cube of crown, 1 to 3 m up */
        for (int a = 0; a < 3; a++) c.xyz[3 * i + a] = (float)(2 * sy_unit53(sy_splitmix64(&rng)) + (a == 2));
    for (size_t t = 0; t < lone; t++, i++) /* rising 0.8 m a step from the cube's top */
        c.xyz[3 * i] = 1, c.xyz[3 * i + 1] = 1, c.xyz[3 * i + 2] = (float)(3 + 0.8 * (double)(t + 1));
    c.xyz[3 * i] = 1, c.xyz[3 * i + 1] = 1, c.xyz[3 * i + 2] = (float)(3 + 0.8 * lone + 1.6); /* the stray */
    sy_preprocess_result r;
    double kept_top = preprocess_top(&c, &r);
    printf("sparse top %.3f (last lone return %.3f), after the filter %.3f\n", r.top_z, 3 + 0.8 * lone, kept_top);
    assert_true(fabs(r.top_z - (3 + 0.8 * (double)lone)) < 1e-4);
    assert_true(fabs(kept_top - r.top_z) < 1e-4);
    sy_cloud_free(&c);
}

/* A scan that stops at the stem's foot (rTwig's sapling, AdTree's trees):
 * the ground filter's lowest points are a slab of the stem, as tall as it
 * is wide. That is no terrain: every point is kept, so the stem keeps its
 * foot. Before the width/thickness test the slab passed as ground (the
 * plane's median residual and the footprint it covers pass) and was cut. */
static void test_stem_foot_is_not_ground(void **state)
{
    (void)state;
    const size_t stem = 6000, crown = 6000;
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_cloud_init(&c, stem + crown, &err), SY_OK);
    uint64_t rng = 11;
    size_t i = 0;
    for (; i < stem; i++) { /* a stem 5 cm in radius, 0 to 3 m up */
        double a = 2 * M_PI * sy_unit53(sy_splitmix64(&rng)), z = 3 * sy_unit53(sy_splitmix64(&rng));
        c.xyz[3 * i] = (float)(0.05 * cos(a)), c.xyz[3 * i + 1] = (float)(0.05 * sin(a)), c.xyz[3 * i + 2] = (float)z;
    }
    for (; i < stem + crown; i++) /* a crown 2 m wide, 2 to 4 m up */
        for (int k = 0; k < 3; k++) c.xyz[3 * i + k] = (float)(2 * sy_unit53(sy_splitmix64(&rng)) - (k < 2 ? 1 : -2));
    sy_preprocess_options o = sy_preprocess_options_default();
    o.up = SY_UP_Z;
    o.sor = 0;
    o.normals = 0;
    o.remove_ground = 1;
    sy_preprocess_result r;
    assert_int_equal(sy_preprocess(&c, &o, &r, &err), SY_OK);
    printf("stem foot: %s\n", r.steps[4].detail);
    assert_int_equal(r.ground_points, 0);
    assert_int_equal(c.n, stem + crown);
    assert_non_null(strstr(r.steps[4].detail, "no ground"));
    sy_cloud_free(&c);

    /* The same on rTwig's sapling: its lowest return stays. */
    if (!load_xyz(data_path("real/rtwig/cloud.txt"), &c)) skip();
    float low = INFINITY;
    for (size_t j = 0; j < c.n; j++) low = fminf(low, c.xyz[3 * j + 2]);
    o.sor = 1;
    assert_int_equal(sy_preprocess(&c, &o, &r, &err), SY_OK);
    printf("rTwig sapling: %s\n", r.steps[4].detail);
    assert_int_equal(r.ground_points, 0);
    float kept_low = INFINITY;
    for (size_t j = 0; j < c.n; j++) kept_low = fminf(kept_low, c.xyz[3 * j + 2]);
    assert_true(kept_low - low < 0.02f); /* the cut took 23 cm of stem */
    sy_cloud_free(&c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_up_parse),     cmocka_unit_test(test_outliers),
        cmocka_unit_test(test_ground),       cmocka_unit_test(test_voxel),
        cmocka_unit_test(test_normals),      cmocka_unit_test(test_crop),
        cmocka_unit_test(test_rotations_are_proper), cmocka_unit_test(test_up_synthetic),
        cmocka_unit_test(test_up_real),      cmocka_unit_test(test_pipeline),
        cmocka_unit_test(test_top_before_outliers),
        cmocka_unit_test(test_top_follows_sparse_returns),
        cmocka_unit_test(test_stem_foot_is_not_ground),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
