/* Checked reconstruction (pipeline/tree_checks.h). */
#include "pipeline/tree_checks.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "pipeline/run_tree.h"
#include "stages/preprocess/preprocess.h"

static void drop(sy_skeleton *out, sy_clusters *clusters)
{
    sy_skeleton_free(out);
    if (clusters) sy_clusters_free(clusters);
}

sy_code sy_reconstruct_tree_checked(sy_cloud *c, const char *name, const sy_skeleton_options *o, double alpha_scale,
                                    size_t budget, sy_skeleton *out, sy_clusters *clusters, sy_skeleton_report *report,
                                    sy_hull_report *hulls, sy_tree_checks *checks, sy_error *err)
{
    sy_tree_checks local;
    if (!checks) checks = &local;
    memset(checks, 0, sizeof *checks);
    checks->points_before_thinning = c->n;
    sy_code rc;
    if (budget && c->n > budget) {
        /* The level sets need a few points across a branch, not millions:
         * beyond the budget the graph, the Dijkstra and the hulls only grow
         * (docs/skeleton.md, "Dense scans", measures what it costs in
         * fidelity). */
        if ((rc = sy_voxel_size_for_count(c, budget, &checks->thinning_voxel, err))) return rc;
        if (checks->thinning_voxel > 0 && (rc = sy_voxel_downsample(c, checks->thinning_voxel, err))) return rc;
    }
    checks->points_after_thinning = c->n;
    sy_skeleton_options so = *o;
    sy_skeleton_report local_rep;
    if (!report) report = &local_rep;
    char first_reason[sizeof checks->verdict.reason] = "";
    for (int attempt = 0; attempt < 3; attempt++) {
        if (attempt == 1) {
            /* Other spacing: a graph too fine for the density falls apart. */
            so.spacing = 2 * report->spacing;
            snprintf(checks->retried, sizeof checks->retried, "spacing %.4f m", so.spacing);
        } else if (attempt == 2) {
            /* Thinned input: one point per two spacings evens out the density. */
            double voxel = so.spacing;
            size_t before = c->n;
            so.spacing = o->spacing;
            if ((rc = sy_voxel_downsample(c, voxel, err))) return rc;
            size_t used = strlen(checks->retried);
            snprintf(checks->retried + used, sizeof checks->retried - used, ", thinned %zu -> %zu points", before,
                     c->n);
        }
        checks->attempts = attempt + 1;
        if ((rc = sy_reconstruct_tree(c, &so, alpha_scale, out, clusters, report, hulls, err))) {
            /* A retry that cannot run at all reports the first verdict. */
            if (attempt > 0 && rc == SY_EINPUT) break;
            return rc;
        }
        sy_skeleton_judge(c, out, report, &checks->verdict);
        if (!checks->verdict.failed) return SY_OK;
        if (attempt == 0) memcpy(first_reason, checks->verdict.reason, sizeof first_reason);
        drop(out, clusters);
    }
    memset(out, 0, sizeof *out);
    if (clusters) memset(clusters, 0, sizeof *clusters);
    return sy_fail(err, SY_EINPUT, "%s: no plausible tree: %s (retried with %s: %s)", name, first_reason,
                   checks->retried, checks->verdict.reason[0] ? checks->verdict.reason : "no reconstruction");
}
