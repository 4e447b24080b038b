/* A reconstruction that knows when it failed: thins very dense scans to a
 * point budget first, judges the result (sy_skeleton_judge), retries with
 * what the evidence says, and fails with SY_EINPUT naming the scan and the
 * reason rather than returning a tree that is not one. */
#ifndef SYLVA_TREE_CHECKS_H
#define SYLVA_TREE_CHECKS_H

#include "stages/clusters/clusters.h"
#include "stages/core/cloud.h"
#include "stages/skeleton/skeleton.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Points the graph steps get by default: denser scans are voxel-thinned to
 * this many first (docs/skeleton.md, "Dense scans"). */
#define SY_POINT_BUDGET 300000

typedef struct {
    size_t points_before_thinning; /* the cloud as given */
    size_t points_after_thinning;  /* what the first reconstruction got */
    double thinning_voxel;         /* the budget's voxel edge in metres, 0: not thinned */
    int attempts;                  /* reconstructions run (1: the first one passed) */
    char retried[160];             /* what the retries changed, "" when none ran */
    sy_skeleton_verdict verdict;   /* of the reconstruction returned (or the last one tried) */
} sy_tree_checks;

/* sy_reconstruct_tree on c with the checks: c is first thinned in place to at
 * most budget points (0: never); a failed verdict retries with twice the
 * spacing, then on c thinned to one point per two spacings; if all fail,
 * SY_EINPUT "NAME: no plausible tree: REASON". checks may be NULL. */
sy_code sy_reconstruct_tree_checked(sy_cloud *c, const char *name, const sy_skeleton_options *o, double alpha_scale,
                                    size_t budget, sy_skeleton *out, sy_clusters *clusters, sy_skeleton_report *report,
                                    sy_hull_report *hulls, sy_tree_checks *checks, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
