/* Photogrammetry through COLMAP on photos of a generated tree with known
 * cameras (tests/photo_render.h): most views must register; the stage's
 * levelling (mean camera up) and scale (known camera spacing) must put the
 * cameras where they were up to a turn about Z and a shift; the points,
 * aligned that way, must lie on the true surface (mean distance printed and
 * bounded). Failures explain themselves; `sylva run PHOTOS/` goes end to end. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <stb_image_write.h>

#include "photo_render.h"
#include "stages/photogrammetry/photogrammetry.h"

enum { N_VIEWS = 18, W = 640, H = 480 };
static const double FOCAL = 480, RING = 5.5;

static syn_tree tree;
static double true_centre[N_VIEWS][3];
static char photos[4096];

static void render_views(const char *dir)
{
    mkdir(dir, 0755);
    unsigned char *rgb = malloc((size_t)W * H * 3);
    assert_non_null(rgb);
    for (int i = 0; i < N_VIEWS; i++) {
        /* low views look at the trunk, high ones at the crown */
        double a = 2 * 3.14159265358979323846 * i / N_VIEWS;
        double c[3] = {RING * cos(a), RING * sin(a), i % 2 ? 3.2 : 1.4}, target[3] = {0, 0, i % 2 ? 4.2 : 2.2};
        memcpy(true_centre[i], c, sizeof c);
        pr_camera cam = pr_look_at(c, target, FOCAL, W, H);
        pr_render(&tree, &cam, rgb);
        char path[4200];
        snprintf(path, sizeof path, "%s/cam%02d.png", dir, i);
        assert_true(stbi_write_png(path, W, H, 3, rgb, W * 3) != 0);
    }
    free(rgb);
}

static int setup(void **state)
{
    (void)state;
    (void)syn_sample; /* the header also samples points; these tests photograph instead */
    syn_tree_make(&tree, 1, 0);
    snprintf(photos, sizeof photos, "%s", tmp_path("photos"));
    render_views(photos);
    return 0;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static double true_spacing(void)
{
    double s = 0;
    for (int i = 1; i < N_VIEWS; i++) {
        double d = 0;
        for (int k = 0; k < 3; k++) d += pow(true_centre[i][k] - true_centre[i - 1][k], 2);
        s += sqrt(d);
    }
    return s / (N_VIEWS - 1);
}

/* The turn about Z and shift that best map the reconstructed cameras onto
 * the true ones (the only freedom left once the stage levelled and scaled). */
typedef struct {
    double c, s, shift[3];
} yaw_fit;

static yaw_fit fit_yaw(const sy_photogrammetry_result *r, int *index)
{
    double mr[3] = {0}, mt[3] = {0};
    size_t n = r->n_cameras;
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            mr[k] += r->camera_centres[3 * i + k] / n;
            mt[k] += true_centre[index[i]][k] / n;
        }
    double sxx = 0, sxy = 0;
    for (size_t i = 0; i < n; i++) {
        double ax = r->camera_centres[3 * i] - mr[0], ay = r->camera_centres[3 * i + 1] - mr[1];
        double bx = true_centre[index[i]][0] - mt[0], by = true_centre[index[i]][1] - mt[1];
        sxx += ax * bx + ay * by;
        sxy += ax * by - ay * bx;
    }
    double ang = atan2(sxy, sxx);
    yaw_fit f = {cos(ang), sin(ang), {0, 0, 0}};
    f.shift[0] = mt[0] - (f.c * mr[0] - f.s * mr[1]);
    f.shift[1] = mt[1] - (f.s * mr[0] + f.c * mr[1]);
    f.shift[2] = mt[2] - mr[2];
    return f;
}

static void apply(const yaw_fit *f, const double p[3], double q[3])
{
    q[0] = f->c * p[0] - f->s * p[1] + f->shift[0];
    q[1] = f->s * p[0] + f->c * p[1] + f->shift[1];
    q[2] = p[2] + f->shift[2];
}

static void reconstructs_the_tree(void **state)
{
    (void)state;
    sy_photogrammetry_options o = sy_photogrammetry_options_default();
    o.workspace = tmp_path("ws");
    o.quality = SY_PHOTO_LOW;
    o.camera_spacing = true_spacing();
    o.sequential_overlap = 3; /* photos in walking order: a third of the exhaustive pairs */
    sy_photogrammetry_result r;
    sy_error err = {0};
    sy_code rc = sy_photogrammetry_run(photos, &o, &r, &err);
    if (rc) fail_msg("%s", err.msg);
    printf("  %zu of %d views registered, %zu points (%s), scale %.4f m/unit, camera ups spread %.1f deg\n",
           r.n_registered, N_VIEWS, r.cloud.n, r.dense ? "dense" : "sparse", r.scale, r.up_spread_deg);
    assert_true(r.n_registered >= N_VIEWS * 8 / 10);
    assert_true(r.scaled);
    int index[N_VIEWS];
    for (size_t i = 0; i < r.n_cameras; i++) {
        int k = -1;
        assert_int_equal(sscanf(r.camera_names[i], "cam%d.png", &k), 1);
        assert_true(k >= 0 && k < N_VIEWS);
        index[i] = k;
    }
    yaw_fit f = fit_yaw(&r, index);
    double cam_err = 0, cam_max = 0;
    for (size_t i = 0; i < r.n_cameras; i++) {
        double q[3], d = 0;
        apply(&f, &r.camera_centres[3 * i], q);
        for (int k = 0; k < 3; k++) d += pow(q[k] - true_centre[index[i]][k], 2);
        cam_err += d / r.n_cameras;
        cam_max = fmax(cam_max, sqrt(d));
    }
    cam_err = sqrt(cam_err);
    /* points on the true surface */
    double sum = 0, sum_tree = 0, tree_d[8192];
    size_t n = 0, n_tree = 0, within = 0;
    for (size_t i = 0; i < r.cloud.n; i++) {
        double p[3], q[3];
        for (int k = 0; k < 3; k++) p[k] = r.cloud.origin[k] + r.cloud.xyz[3 * i + k];
        apply(&f, p, q);
        if (q[0] * q[0] + q[1] * q[1] > 13 * 13) continue; /* past the ground disc: sky-line noise */
        double d = pr_surface_distance(&tree, q);
        sum += d;
        n++;
        within += d < 0.05;
        if (q[2] > 0.3 && q[0] * q[0] + q[1] * q[1] < 3 * 3 && n_tree < 8192) {
            tree_d[n_tree] = fabs(pr_tree_sdf(&tree, q, NULL));
            sum_tree += tree_d[n_tree++];
        }
    }
    qsort(tree_d, n_tree, sizeof tree_d[0], cmp_double);
    double tree_median = n_tree ? tree_d[n_tree / 2] : 0;
    printf("  cameras after a turn about Z: RMS %.3f m, worst %.3f m (ring radius %.1f m)\n", cam_err, cam_max, RING);
    printf("  near the tree (13 m; the backdrop at 22 m left out): mean distance to the true surface %.4f m over %zu "
           "points (%.0f%% within 5 cm)\n",
           n ? sum / (double)n : 0.0, n, n ? 100.0 * (double)within / (double)n : 0.0);
    printf("  on the tree: %zu points, mean distance %.4f m, median %.4f m\n", n_tree,
           n_tree ? sum_tree / (double)n_tree : 0.0, tree_median);
    assert_true(cam_err < 0.08);
    assert_true(n > 200);
    assert_true(sum / (double)n < 0.04);
    assert_true(n_tree > 60);
    assert_true(tree_median < 0.03);
    assert_true(sum_tree / (double)n_tree < 0.05);
    sy_photogrammetry_result_free(&r);
}

static void failures_explain_themselves(void **state)
{
    (void)state;
    /* two photos */
    char dir[4200];
    snprintf(dir, sizeof dir, "%s", tmp_path("two"));
    mkdir(dir, 0755);
    unsigned char *sky = malloc((size_t)W * H * 3);
    assert_non_null(sky);
    memset(sky, 180, (size_t)W * H * 3);
    for (int i = 0; i < 3; i++) {
        char p[4300];
        snprintf(p, sizeof p, "%s/flat%d.png", dir, i);
        if (i < 2) assert_true(stbi_write_png(p, W, H, 3, sky, W * 3) != 0);
    }
    sy_photogrammetry_options o = sy_photogrammetry_options_default();
    o.workspace = tmp_path("ws_two");
    o.quality = SY_PHOTO_LOW;
    sy_photogrammetry_result r;
    sy_error err = {0};
    assert_int_equal(sy_photogrammetry_run(dir, &o, &r, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "at least 3"));
    /* three featureless photos: no model, and the message says why */
    char p[4300];
    snprintf(p, sizeof p, "%s/flat2.png", dir);
    assert_true(stbi_write_png(p, W, H, 3, sky, W * 3) != 0);
    assert_int_equal(sy_photogrammetry_run(dir, &o, &r, &err), SY_EINPUT);
    printf("  %s\n", err.msg);
    assert_non_null(strstr(err.msg, "no model"));
    assert_non_null(strstr(err.msg, "colmap.log"));
    /* options */
    o.camera_spacing = -1;
    assert_int_equal(sy_photogrammetry_options_check(&o, &err), SY_EUSAGE);
    free(sky);
}

/* `sylva run PHOTOS/ -o tree.glb`: photos -> points -> tree. */
static void run_goes_end_to_end(void **state)
{
    (void)state;
    const char *glb = tmp_path("tree.glb");
    char cmd[9000];
    snprintf(cmd, sizeof cmd, "'%s' run '%s' -o '%s' --camera-spacing %.6f --quality low --sequential 3 --quiet 2>'%s'", SYLVA_BIN,
             photos, glb, true_spacing(), tmp_path("run.err"));
    int rc = system(cmd);
    if (rc != 0) {
        char show[600] = "";
        FILE *f = fopen(tmp_path("run.err"), "r");
        if (f) {
            size_t k = fread(show, 1, sizeof show - 1, f);
            show[k] = 0;
            fclose(f);
        }
        fail_msg("sylva run PHOTOS/ failed (%d): %s", rc, show);
    }
    struct stat st;
    assert_int_equal(stat(glb, &st), 0);
    assert_true(st.st_size > 2000);
    char log[4200];
    snprintf(log, sizeof log, "%s.colmap/colmap.log", glb);
    assert_int_equal(stat(log, &st), 0); /* COLMAP's log kept beside the output */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(reconstructs_the_tree),
        cmocka_unit_test(failures_explain_themselves),
        cmocka_unit_test(run_goes_end_to_end),
    };
    return cmocka_run_group_tests(tests, setup, NULL);
}
