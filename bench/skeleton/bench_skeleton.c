/* Skeleton + clusters benchmark: synthetic trees of 100k and 1M points (trunk,
 * 4 primary and 8 secondary branches, foliage blobs at the tips; 40% of the
 * points in foliage), one thread. Prints the time of each step, peak RSS and
 * the .sylva size. Targets: 100k <= 1 s, 1M <= 10 s and <= 2 GB.
 * Usage: bench_skeleton [points...]  (default: 100000 1000000) */
#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>

#include "stages/core/parallel.h"
#include "stages/encode/encode.h"
#include "pipeline/run_tree.h"
#include "stages/skeleton/skeleton.h"
#include "tests/synthetic_tree.h"

static double peak_rss_mb(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_maxrss / 1024.0; /* kB on Linux */
}

static int run(size_t n)
{
    syn_tree t;
    syn_tree_make(&t, 1, 1);
    sy_cloud c;
    sy_error err = {0};
    if (syn_sample(&t, n, 0.4, 0.002, 42, &c, &err)) return 1;
    sy_skeleton_options o;
    o = sy_skeleton_options_default();
    sy_skeleton s;
    sy_clusters cl;
    sy_skeleton_report r;
    sy_hull_report h;
    if (sy_reconstruct_tree(&c, &o, 0, &s, &cl, &r, &h, &err)) {
        fprintf(stderr, "bench_skeleton: %s\n", err.msg);
        return 1;
    }
    unsigned char *file;
    size_t bytes = 0;
    if (sy_encode_mem(&s, &cl, 0, 1, NULL, &file, &bytes, &err) == SY_OK) free(file);
    printf("%8zu points: total %6.3f s | graph %.3f  dijkstra %.3f  level sets %.3f  radii %.3f  clusters %.3f  "
           "hulls %.3f | %zu nodes, %zu branches, %zu clusters (%zu alpha, %zu convex, %zu box), "
           "graph %zu edges, %zu components, spacing %.4f m, DBH %.3f m | peak RSS %.0f MB | .sylva %zu bytes\n",
           n, r.t_total, r.t_graph, r.t_dijkstra, r.t_levels, r.t_radii, r.t_clusters, h.seconds, r.nodes, r.branches,
           r.clusters, h.alpha, h.convex, h.box, r.graph_edges, r.components, r.spacing, r.dbh,
           peak_rss_mb(), bytes);
    sy_clusters_free(&cl);
    sy_skeleton_free(&s);
    sy_cloud_free(&c);
    return 0;
}

int main(int argc, char **argv)
{
    sy_set_threads(1);
    printf("bench_skeleton: one thread, synthetic tree (DBH truth %.3f m)\n", 2 * syn_trunk_radius(1.3));
    if (argc > 1) {
        for (int i = 1; i < argc; i++)
            if (run((size_t)strtoull(argv[i], NULL, 10))) return 1;
        return 0;
    }
    return run(100000) || run(1000000);
}
