/* bench_segment [DATA_DIR]: instance F1 at IoU > 0.5 of `sylva segment` on
 * simulated plots (the scan stage's truth treeID; terrestrial and airborne,
 * aspen/pine and the default aspen/oak/pine mix), on lidR's MixedConifer
 * (airborne treeID), and the run time and memory on the real plots
 * (MixedConifer, Megaplot, TreeLS pine_plot). Prints a table with the
 * targets beside the figures; CPU seconds (getrusage), the machine shared. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "stages/eval/eval.h"
#include "stages/ingest/ingest.h"
#include "stages/scan/scan.h"
#include "stages/segment/segment.h"

static double cpu_seconds(void)
{
    struct rusage u;
    getrusage(RUSAGE_SELF, &u);
    return (double)u.ru_utime.tv_sec + 1e-6 * (double)u.ru_utime.tv_usec + (double)u.ru_stime.tv_sec +
           1e-6 * (double)u.ru_stime.tv_usec;
}

static double peak_mb(void)
{
    struct rusage u;
    getrusage(RUSAGE_SELF, &u);
    return (double)u.ru_maxrss / 1024.0;
}

typedef struct {
    const char *name;
    sy_scanner_kind kind;
    double size;
    int trees;
    int mix; /* 0: aspen + pine, 1: aspen + oak + pine */
    uint64_t seed;
} plot_case;

/* Segments c, scores it against its treeID; prints one row. Returns F1. */
static double run_case(const char *name, const sy_cloud *c, const char *kind, double target)
{
    sy_segment_options o = sy_segment_options_default();
    sy_segmentation s;
    sy_error err = {0};
    double t0 = cpu_seconds();
    if (sy_segment(c, &o, &s, &err)) {
        printf("| %s | %s | failed: %s |\n", name, kind, err.msg);
        return NAN;
    }
    double t = cpu_seconds() - t0;
    const double *truth = sy_cloud_attr(c, "treeID");
    double f1 = NAN;
    sy_segmentation_metrics m = {0};
    if (truth) {
        double *pred = malloc(c->n * sizeof *pred);
        for (size_t i = 0; pred && i < c->n; i++) pred[i] = s.tree_of[i] > 0 ? s.tree_of[i] : 0;
        if (pred && sy_segmentation_metrics_labels(truth, pred, c->n, &m, &err) == SY_OK) f1 = m.f1;
        free(pred);
    }
    char tgt[32] = "-";
    if (!isnan(target)) snprintf(tgt, sizeof tgt, ">= %.2f", target);
    printf("| %s | %s | %zu | %zu | %zu | %.3f | %.2f | %.2f | %.3f | %zu | %zu | %s | %.2f | %.0f |\n", name,
           s.airborne ? "airborne" : "terrestrial", c->n, m.n_truth, s.n_trees, f1, m.precision, m.recall, m.mean_iou,
           m.n_over_segmented, m.n_under_segmented, tgt, t, peak_mb());
    fflush(stdout);
    sy_segmentation_free(&s);
    (void)kind;
    return f1;
}

int main(int argc, char **argv)
{
    const char *data = argc > 1 ? argv[1] : "../shared/data";
    printf("| plot | method | points | truth trees | found | F1 | precision | recall | mean IoU | over | under | target | CPU s | peak MB |\n");
    printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    const plot_case cases[] = {
        {"TLS 20 m, 8 aspen/pine, seed 1", SY_SCANNER_TERRESTRIAL, 20, 8, 0, 1},
        {"TLS 20 m, 8 aspen/pine, seed 2", SY_SCANNER_TERRESTRIAL, 20, 8, 0, 2},
        {"TLS 30 m, 8 aspen/oak/pine, seed 1", SY_SCANNER_TERRESTRIAL, 30, 8, 1, 1},
        {"TLS 30 m, 8 aspen/oak/pine, seed 2", SY_SCANNER_TERRESTRIAL, 30, 8, 1, 2},
        {"TLS 30 m, 8 aspen/oak/pine, seed 3", SY_SCANNER_TERRESTRIAL, 30, 8, 1, 3},
        {"ALS 30 m, 8 aspen/pine, seed 5", SY_SCANNER_AIRBORNE, 30, 8, 0, 5},
        {"ALS 30 m, 8 aspen/oak/pine, seed 1", SY_SCANNER_AIRBORNE, 30, 8, 1, 1},
        {"ALS 40 m, 12 aspen/oak/pine, seed 3", SY_SCANNER_AIRBORNE, 40, 12, 1, 3},
    };
    double sum[2] = {0, 0};
    int cnt[2] = {0, 0};
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        const plot_case *pc = &cases[k];
        sy_scene_options so = sy_scene_options_default();
        /* The scene options name no species by default: each case names its mix. */
        so.species[0] = "quaking_aspen";
        so.species[1] = "european_pine";
        so.n_species = 2;
        if (pc->mix == 1) so.species[2] = "black_oak", so.n_species = 3;
        so.plot_size = pc->size;
        so.trees = pc->trees;
        so.seed = pc->seed;
        sy_error err = {0};
        sy_scene scene;
        if (sy_scene_build(&scene, &so, pc->kind == SY_SCANNER_AIRBORNE ? 0 : 30, &err)) {
            printf("| %s | scene failed: %s |\n", pc->name, err.msg);
            continue;
        }
        sy_scan_options sc = sy_scan_options_for(pc->kind);
        sc.seed = pc->seed;
        sc.subrays = 1;
        sc.divergence_mrad = 0;
        if (pc->kind == SY_SCANNER_TERRESTRIAL) sc.step_deg = 0.1;
        sy_cloud c;
        if (sy_scan(&scene, &sc, &c, NULL, &err)) {
            printf("| %s | scan failed: %s |\n", pc->name, err.msg);
            sy_scene_free(&scene);
            continue;
        }
        int als = pc->kind == SY_SCANNER_AIRBORNE;
        double f1 = run_case(pc->name, &c, als ? "ALS" : "TLS", als ? NAN : 0.80);
        if (!isnan(f1)) sum[als] += f1, cnt[als]++;
        sy_cloud_free(&c);
        sy_scene_free(&scene);
    }
    /* Real plots. */
    const char *real[] = {"real/lidr/MixedConifer.las", "real/lidr/Megaplot.las", "real/treels/pine_plot.las"};
    for (size_t k = 0; k < 3; k++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", data, real[k]);
        sy_cloud c;
        sy_error err = {0};
        if (sy_read_cloud(path, &c, &err)) {
            printf("| %s | missing (%s) |\n", real[k], err.msg);
            continue;
        }
        run_case(real[k], &c, "real", NAN);
        sy_cloud_free(&c);
    }
    printf("\nmean F1: simulated TLS %.3f over %d plots (target >= 0.80), simulated ALS %.3f over %d plots\n",
           cnt[0] ? sum[0] / cnt[0] : NAN, cnt[0], cnt[1] ? sum[1] / cnt[1] : NAN, cnt[1]);
    printf("published: lidR classical (Li 2012, Dalponte 2016, Silva 2016) F1 ~0.8-0.9 on open stands;\n"
           "deep models 0.73-0.85 on FOR-instance (ForestFormer3D 73.3 on FGI-EMIT, SegmentAnyTreeV2 85.0).\n"
           "MixedConifer's treeID ships with lidR's example data (no field survey): the score is agreement with it.\n");
    return 0;
}
