/* Is this reconstruction a tree? Checks on the finished skeleton against
 * the cloud it came from (skeleton.h, sy_skeleton_judge). Each threshold is
 * far from what a real tree gives, so the check fires on failures, not on
 * unusual trees: on the six AdTree trees, the TreeLS pine, the PyTLidar tree,
 * the rTwig cloud and the simulated scans the main skeleton spans 45-100% of
 * the height and the largest graph piece holds most of the points. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/skeleton/skeleton.h"
#include "stages/core/sort.h"

/* Below this many points nothing is judged: a sketch of a tree is all they hold. */
#define JUDGE_MIN_POINTS 1000
/* A tree from thousands of points has at least a stem's worth of level sets. */
#define MIN_NODES 8
/* The main skeleton's height share of the cloud; crowns cut into clusters
 * still leave the stem and the main limbs. */
#define MIN_SKELETON_SHARE 0.25
/* Level sets along the stem: at least this share of height / bin width. */
#define MIN_NODE_SHARE 0.3
/* The neighbour graph's largest piece before bridging. */
#define MIN_LARGEST_SHARE 0.2

void sy_skeleton_judge(const sy_cloud *c, const sy_skeleton *s, const sy_skeleton_report *r,
                       sy_skeleton_verdict *v)
{
    memset(v, 0, sizeof *v);
    size_t n = c->n;
    if (n < JUDGE_MIN_POINTS) return;
    /* Height percentiles from a deterministic sample. */
    size_t m = n < 20000 ? n : 20000, stride = n / m;
    float *z = malloc(m * sizeof *z);
    if (!z) return; /* no verdict without memory: the reconstruction stands */
    for (size_t i = 0; i < m; i++) z[i] = c->xyz[3 * (i * stride) + 2];
    qsort(z, m, sizeof *z, sy_cmp_float);
    v->cloud_height = (double)z[m - 1 - m / 100] - (double)z[m / 100];
    free(z);
    float lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < s->n; i++) {
        if (s->pos[3 * i + 2] < lo) lo = s->pos[3 * i + 2];
        if (s->pos[3 * i + 2] > hi) hi = s->pos[3 * i + 2];
    }
    v->skeleton_share = s->n && v->cloud_height > 0 ? ((double)hi - lo) / v->cloud_height : 0;
    v->expected_nodes = r->bin_width > 0 ? MIN_NODE_SHARE * v->cloud_height / r->bin_width : 0;
    v->largest_share = r->points ? (double)r->largest_component / (double)r->points : 1;
    if (s->n < MIN_NODES || (double)s->n < v->expected_nodes)
        snprintf(v->reason, sizeof v->reason,
                 "a skeleton of %zu nodes from %zu points (a %.1f m tree at %.3f m level sets needs at least %.0f)",
                 s->n, n, v->cloud_height, r->bin_width, fmax(MIN_NODES, v->expected_nodes));
    else if (v->skeleton_share < MIN_SKELETON_SHARE)
        snprintf(v->reason, sizeof v->reason, "the skeleton spans %.0f%% of the cloud's %.1f m height",
                 100 * v->skeleton_share, v->cloud_height);
    else if (v->largest_share < MIN_LARGEST_SHARE)
        snprintf(v->reason, sizeof v->reason,
                 "the neighbour graph fell apart into %zu pieces, the largest %.0f%% of the points (spacing %.4f m "
                 "too fine for the scan's density)",
                 r->components, 100 * v->largest_share, r->spacing);
    v->failed = v->reason[0] != 0;
}
