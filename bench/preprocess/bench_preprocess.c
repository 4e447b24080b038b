/* Preprocessing figures: per-step timings on a 1 M-point synthetic plot and
 * on real tree scans, PMF on the full cloud against the lowest-point grid
 * copy, and up-axis detection on real files turned into all six
 * orientations. Usage: bench_preprocess DATA_DIR (the shared data folder). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "stages/core/parallel.h"
#include "stages/core/progress.h"
#include "stages/preprocess/pcl_filters.h"
#include "stages/preprocess/preprocess.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static uint64_t rng = 42;
static double uniform(void)
{
    uint64_t z = (rng += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return ((z ^ (z >> 31)) >> 11) * (1.0 / 9007199254740992.0);
}
static double gauss(void) { return sqrt(-2 * log(uniform() + 1e-300)) * cos(2 * M_PI * uniform()); }

/* A 40 m plot on a 10 degree slope with 8 trees and 1% far outliers;
 * label: 0 ground, 1 trunk, 2 crown, 3 outlier. */
static void make_plot(sy_cloud *c, size_t n_ground, size_t per_tree)
{
    const int trees = 8;
    size_t n_veg = trees * per_tree, n_out = (n_ground + n_veg) / 100, i = 0;
    sy_error err;
    if (sy_cloud_init(c, n_ground + n_veg + n_out, &err)) exit(3);
    double *label = sy_cloud_add_attr(c, "label", &err);
    double slope = tan(10 * M_PI / 180);
#define PUT(x, y, z, l) (c->xyz[3 * i] = (float)(x), c->xyz[3 * i + 1] = (float)(y), c->xyz[3 * i + 2] = (float)(z), label[i++] = (l))
    for (size_t k = 0; k < n_ground; k++) {
        double x = uniform() * 40, y = uniform() * 40;
        PUT(x, y, slope * x + 0.02 * gauss(), 0);
    }
    for (int t = 0; t < trees; t++) {
        double tx = 5 + 10 * (t % 4), ty = 10 + 20 * (t / 4), base = slope * tx, h = 8 + t;
        for (size_t k = 0; k < per_tree / 3; k++) {
            double a = uniform() * 2 * M_PI;
            PUT(tx + 0.25 * cos(a), ty + 0.25 * sin(a), base + uniform() * h, 1);
        }
        for (size_t k = per_tree / 3; k < per_tree;) {
            double u = 2 * uniform() - 1, v = 2 * uniform() - 1, w = 2 * uniform() - 1;
            if (u * u + v * v + w * w > 1) continue;
            PUT(tx + 3.5 * u, ty + 3.5 * v, base + h + 2.5 * w, 2);
            k++;
        }
    }
    for (size_t k = 0; k < n_out; k++) PUT(-30 + 100 * uniform(), -30 + 100 * uniform(), 40 + 20 * uniform(), 3);
#undef PUT
    c->n = i;
}

static void print_steps(const char *what, const sy_preprocess_result *r)
{
    printf("%s: %zu -> %zu points, up %s\n", what, r->point_count_in, r->point_count_out, sy_up_name(r->up_axis));
    for (int s = 0; s < SY_PREPROCESS_STEPS; s++)
        if (r->steps[s].ran)
            printf("  %-9s %8zu -> %8zu  %7.3f s  %s\n", r->steps[s].name, r->steps[s].before, r->steps[s].after,
                   r->steps[s].seconds, r->steps[s].detail);
}

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* Each step alone, wall and process CPU seconds (CPU sums all threads; the
 * build machine is shared, so CPU time is the steadier figure). */
static void bench_plot(double voxel)
{
    sy_cloud c;
    make_plot(&c, 520000, 60000);
    sy_preprocess_options o;
    o = sy_preprocess_options_default();
    sy_error err;
    printf("synthetic plot, %zu points, voxel %g:\n", c.n, voxel);
    const char *names[] = {"up", "voxel", "outliers", "ground", "normals"};
    for (int s = 0; s < 5; s++) {
        if (s == 1 && voxel <= 0) continue;
        size_t before = c.n, n_ground = 0;
        int up = 0;
        double w = sy_now(), t = cpu_now();
        sy_code rc = SY_OK;
        if (s == 0) rc = sy_detect_up(&c, &up, NULL, &err);
        if (s == 1) rc = sy_voxel_downsample(&c, voxel, &err);
        if (s == 2) rc = sy_remove_outliers(&c, o.sor_k, o.sor_std, &err);
        if (s == 3) rc = sy_classify_ground(&c, &o, &n_ground, &err);
        if (s == 4) rc = sy_estimate_normals(&c, o.normal_k, &err);
        if (rc) printf("  %s failed: %s\n", names[s], err.msg);
        printf("  %-9s %8zu -> %8zu  wall %6.2f s  cpu %6.2f s%s%s\n", names[s], before, c.n, sy_now() - w,
               cpu_now() - t, s == 0 ? "  up " : "", s == 0 ? sy_up_name(up) : "");
    }
    const double *label = sy_cloud_attr(&c, "label");
    size_t g = 0, gt = 0, fp = 0, veg = 0;
    for (size_t i = 0; i < c.n; i++) {
        if (label[i] == 0) gt++, g += c.classification[i] == 2;
        if (label[i] == 1 || label[i] == 2) veg++, fp += c.classification[i] == 2;
    }
    printf("  ground recall %.2f%%, trunk/crown false positives %.2f%%\n", 100.0 * g / gt, 100.0 * fp / veg);
    sy_cloud_free(&c);
}

/* PMF straight on raw points: the cost the grid copy avoids. */
static void bench_pmf_full(void)
{
    for (size_t n = 12500; n <= 400000; n *= 2) {
        sy_cloud c;
        make_plot(&c, n / 2, n / 16);
        uint8_t *g = malloc(c.n);
        sy_error err = {0};
        double t = sy_now();
        sy_pcl_ground_pmf(c.xyz, c.n, 0.5, 0.3, 16, 0.15, 7.8, g, &err);
        t = sy_now() - t;
        printf("PMF on all %zu raw points: %.2f s\n", c.n, t);
        free(g);
        sy_cloud_free(&c);
        if (t > 20) break;
    }
}

static int load_text(const char *path, sy_cloud *c)
{
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    size_t cap = 1 << 16, n = 0;
    double *p = malloc(cap * 24);
    char line[1024];
    while (fgets(line, sizeof line, f)) {
        double v[3];
        if (sscanf(line, "%lf %lf %lf", &v[0], &v[1], &v[2]) != 3) continue;
        if (n == cap) p = realloc(p, (cap *= 2) * 24);
        memcpy(p + 3 * n++, v, 24);
    }
    fclose(f);
    sy_error err;
    sy_cloud_init(c, n, &err);
    for (int k = 0; k < 3; k++) c->origin[k] = n ? floor(p[k]) : 0;
    for (size_t i = 0; i < 3 * n; i++) c->xyz[i] = (float)(p[i] - c->origin[i % 3]);
    free(p);
    return n > 0;
}

/* Just enough LAS (1.0-1.4, any point format) for positions. */
static int load_las(const char *path, sy_cloud *c)
{
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    unsigned char h[375] = {0};
    size_t got = fread(h, 1, sizeof h, f);
    uint32_t off, count;
    uint16_t len;
    uint64_t count64;
    double scale[3], shift[3];
    memcpy(&off, h + 96, 4), memcpy(&len, h + 105, 2), memcpy(&count, h + 107, 4);
    memcpy(scale, h + 131, 24), memcpy(shift, h + 155, 24), memcpy(&count64, h + 247, 8);
    if (got < 227 || memcmp(h, "LASF", 4) || len < 12) return fclose(f), 0;
    uint64_t total = count ? count : count64;
    sy_error err;
    if (sy_cloud_init(c, (size_t)total, &err)) return fclose(f), 0;
    for (int k = 0; k < 3; k++) c->origin[k] = floor(shift[k]);
    unsigned char rec[512];
    fseek(f, off, SEEK_SET);
    size_t i = 0;
    for (; i < total && fread(rec, 1, len, f) == len; i++)
        for (int k = 0; k < 3; k++) {
            int32_t v;
            memcpy(&v, rec + 4 * k, 4);
            c->xyz[3 * i + k] = (float)(v * scale[k] + shift[k] - c->origin[k]);
        }
    c->n = i;
    fclose(f);
    return i > 0;
}

/* Inverse of sy_rotate_to_z_up(up): the transpose of its signed permutation. */
static void rotate_from_z_up(sy_cloud *c, int up)
{
    sy_cloud unit;
    sy_error err;
    sy_cloud_init(&unit, 3, &err);
    for (int k = 0; k < 3; k++) unit.xyz[4 * k] = 1;
    sy_rotate_to_z_up(&unit, up);
    for (size_t i = 0; i < c->n; i++) {
        float p[3] = {c->xyz[3 * i], c->xyz[3 * i + 1], c->xyz[3 * i + 2]};
        for (int r = 0; r < 3; r++)
            c->xyz[3 * i + r] = unit.xyz[3 * r] * p[0] + unit.xyz[3 * r + 1] * p[1] + unit.xyz[3 * r + 2] * p[2];
    }
    sy_cloud_free(&unit);
}

static void bench_up(const char *dir)
{
    const char *files[] = {"real/adtree/tree1.xyz",   "real/adtree/tree7.xyz",    "real/adtree/tree13.xyz",
                           "real/adtree/tree33.xyz",  "real/adtree/Lille_11.xyz", "real/rtwig/cloud.txt",
                           "real/treels/pine.las",    "real/treels/pine_plot.las", "real/pytlidar/tree_1.las",
                           "real/lidr/MixedConifer.las", "real/lidr/Megaplot.las"};
    const int ups[6] = {3, -3, 2, -2, 1, -1};
    for (size_t f = 0; f < sizeof files / sizeof *files; f++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", dir, files[f]);
        sy_cloud c;
        int ok = strstr(path, ".las") ? load_las(path, &c) : load_text(path, &c);
        if (!ok) {
            printf("%s: unreadable\n", files[f]);
            continue;
        }
        int right = 0;
        double seconds = 0;
        sy_up_evidence ev0;
        for (int u = 0; u < 6; u++) {
            sy_cloud r;
            sy_error err;
            sy_cloud_copy(&r, &c, &err);
            rotate_from_z_up(&r, ups[u]);
            int found;
            sy_up_evidence ev;
            double t = sy_now();
            sy_detect_up(&r, &found, &ev, &err);
            seconds += sy_now() - t;
            if (u == 0) ev0 = ev;
            right += found == ups[u];
            sy_cloud_free(&r);
        }
        double other = fmax(ev0.axis_score[0], ev0.axis_score[1]);
        printf("%-28s %8zu pts: %d/6 orientations, z axis score %.3f vs %.3f, sign %+.4f, %.3f s each\n", files[f],
               c.n, right, ev0.axis_score[2], other, ev0.sign_score[2], seconds / 6);
        sy_cloud_free(&c);
    }
}

static void bench_trees(const char *dir)
{
    const char *files[] = {"real/adtree/tree1.xyz", "real/adtree/tree7.xyz", "real/adtree/tree13.xyz",
                           "real/adtree/tree33.xyz", "real/adtree/Lille_11.xyz"};
    for (size_t f = 0; f < sizeof files / sizeof *files; f++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", dir, files[f]);
        sy_cloud c;
        if (!load_text(path, &c)) continue;
        sy_preprocess_options o;
        o = sy_preprocess_options_default();
        sy_preprocess_result r;
        sy_error err;
        if (sy_preprocess(&c, &o, &r, &err)) printf("failed: %s\n", err.msg);
        print_steps(files[f], &r);
        sy_cloud_free(&c);
    }
}

int main(int argc, char **argv)
{
    const char *dir = argc > 1 ? argv[1] : getenv("SYLVA_DATA_DIR");
    if (!dir) {
        fprintf(stderr, "usage: bench_preprocess DATA_DIR\n");
        return 1;
    }
    sy_progress_set_quiet(1);
    printf("threads: %d\n", sy_threads());
    bench_up(dir);
    if (argc > 2 && strcmp(argv[2], "--up-only") == 0) return 0;
    bench_trees(dir);
    bench_plot(0);
    bench_plot(0.05);
    if (argc > 2 && strcmp(argv[2], "--pmf-full") == 0) bench_pmf_full();
    return 0;
}
