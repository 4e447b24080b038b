/* Shared between the skeleton sources; not part of the public API. */
#ifndef SYLVA_SKELETON_INTERNAL_H
#define SYLVA_SKELETON_INTERNAL_H

#include "stages/skeleton/skeleton.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double dbh, rms, d_root, height, dbh_z;
    double centre[2]; /* the breast-height circle's centre, when fitted */
    size_t inliers;   /* the slab points it was fitted to */
    double allometric_dbh; /* the species' allometry at this height (0: unknown) */
    int fitted;
} sy_radii_info;

/* Radii by the allometry d(u) = d_root * (l(u) / l(root))^(1/gamma), with
 * d_root chosen so the trunk node at breast height gets the fitted DBH.
 * node_of[i] is the node supporting point i. Breast height and the tree's
 * height are measured from ground_z when it is finite, else from the root.
 * Where no circle stands, dbh_per_height > 0 (the species' allometry) gives
 * the DBH from the height when ground_z is known, else the slab's extent. */
sy_code sy_assign_radii(sy_skeleton *s, const float *xyz, const int32_t *node_of, size_t n, double gamma,
                        double spacing, double ground_z, double dbh_height, double slab, double dbh_per_height,
                        sy_radii_info *info, sy_error *err);

/* Measured radii: for each node a circle fitted across its local branch axis
 * to its own points and its neighbours' on the branch. fit[i] is the radius
 * where the points lie on a circle (most within the band, round at least half
 * of it, the circle no wider than the points), else 0; shift (3 per node, may
 * be NULL) the circle's centre less the node, across the axis (0 where no
 * circle fits). *fitted gets how many nodes got one; SY_EINTERNAL when memory
 * ran out (err set). */
sy_code sy_measure_node_radii(const sy_skeleton *s, const float *xyz, double spacing, float *fit, float *shift,
                              size_t *fitted, sy_error *err);

/* Scales the allometric radii of each branch (trunk excepted) by the median
 * ratio of its measured radii (fit, 0 = none) to the allometric ones;
 * branches with fewer than two measurements keep the allometry. The trunk
 * above breast_z (the height the DBH stands at, in s's frame) thins where
 * its rings show it thinner. Radii stay non-increasing toward the tips.
 * Needs breadth-first order. */
sy_code sy_calibrate_radii(sy_skeleton *s, const float *fit, double breast_z, sy_error *err);

/* The Dijkstra sources: the points of the base slab (z <= ztop) connected to
 * the root within the slab, written to src; mark (n entries) is scratch. */
size_t sy_base_sources(const float *xyz, size_t n, const sy_graph *g, uint32_t root, double ztop, int32_t *src,
                       int32_t *mark);

/* Wood/leaf separation by path frequency (wood_leaf.c): wood[i] = 1 when
 * point i's shortest-path subtree holds at least min_share of all points (or
 * it is a source), or it is a graph neighbour of such a point. order receives
 * the points by ascending dist (parents before children). */
sy_code sy_classify_wood(const sy_graph *g, const int32_t *spt, const double *dist, double min_share, uint8_t *wood,
                         uint32_t *order, size_t *n_wood, sy_error *err);

/* The occluded stem of an excurrent crown and the meandering chains of a
 * decurrent one (stem.c). */
typedef struct {
    int rebuilt;         /* 1: the trunk chain left the crown's axis and was rebuilt on it */
    int excurrent;       /* the crown narrows upward */
    double dome;         /* above the widest slab, the mean crown radius over the widest (a cone 0.5-0.65) */
    double fork;         /* a domed crown's rebuilt stem ends this high above the root (0: at the top) */
    int crown_to_ground; /* the crown's radius at the foot is at least half its median: no bole in view */
    double excursion;    /* the trunk chain's largest horizontal distance from the axis, metres */
    double crown_radius; /* median over height slabs of the points' mean distance from the axis */
    double axis_rms;     /* RMS distance of the slab centroids from the axis */
    double axis[4];      /* x, y at the root and dx/dz, dy/dz */
    double measured_r, measured_z, measured_rms; /* a stem circle fit (radius 0: none stood) */
    double upper_r, upper_z; /* a run of stem returns higher up on that circle's centre (0: none) */
    double fallback_r;   /* radius at breast height when no stem fit stood (slenderness) */
    double meander;      /* the trunk chain's path length over its root-to-end distance */
    double crown_fill;   /* the crown slabs' median / 95th-percentile radius (CROWN_FOLIAGE_RATIO) */
    int crown_regrown;   /* 1: a meandering chain in a foliage crown; the crown above its base regrown */
    double crown_base;   /* that crown base's height above the root, metres */
    int stem_unseen;     /* 1: no return on the stem (an airborne scan): trunk drawn from the ground */
    double crown_gap;    /* the lowest return's height above the ground, metres (0: ground unknown) */
    int columnar;        /* 1: a crown of fronds' stem, rebuilt without limbs: tapered linearly, not by
                            the pipe model (sy_apply_stem_radius) */
} sy_stem_info;

/* Rebuilds the trunk of s (branch ids assigned, breadth-first, support
 * filled) on the crown's slab-centroid axis when the trunk chain wanders off
 * it (see stem.c); point_node is remapped to the new nodes. s comes back in
 * breadth-first order with support, radii 1 and branch ids to reassign.
 * info->rebuilt says whether it changed anything. With fork_domes, the stem
 * of a domed crown stops where its widest part ends (info->fork). */
sy_code sy_rebuild_occluded_stem(sy_skeleton *s, const float *xyz, size_t n, int32_t *point_node,
                                 const uint8_t *wood, double w, double spacing, int fork_domes, sy_stem_info *info,
                                 sy_error *err);
/* A decurrent crown's occluded limbs (stem.c): when the trunk chain of s
 * meanders (its path over `meander` times its root-to-end distance: it
 * follows the shell of a leaf-on crown, down one limb and up the next) and
 * the crown's returns are foliage (CROWN_FOLIAGE_RATIO), keeps the trunk up
 * to its crown base (measured from the node above the root when
 * base_above_root, else from the root) and regrows the crown above it by
 * space colonisation; s comes back as from sy_rebuild_occluded_stem.
 * info->crown_regrown says whether it changed anything. */
sy_code sy_regrow_meandering_crown(sy_skeleton *s, const float *xyz, size_t n, int32_t *point_node,
                                   const uint8_t *wood, double w, double meander, int base_above_root,
                                   sy_stem_info *info, sy_error *err);
/* An airborne scan's tree (stem.c, docs/skeleton.md step 8d): when the
 * lowest return lies more than max(1 m, UNSEEN_STEM_GAP of the height) above
 * the ground under it (ground: NaN when unknown, then the lowest return), or
 * the point spacing is UNSEEN_SPACING or more, the scan saw no stem. s is
 * replaced by a vertical trunk from the ground under the crown's returns:
 * to the top of a cone-shaped crown, every return on its nearest trunk
 * node; or into a domed one as far as its widest part, with limbs grown
 * from that fork by space colonisation into the returns (none where limbs
 * is 0: a crown of fronds, whose stem carries no limbs; info->columnar is
 * then set, for sy_apply_stem_radius). s comes back as
 * from sy_rebuild_occluded_stem, info->stem_unseen and info->rebuilt set,
 * the radius from the species' allometry or the slenderness
 * (sy_apply_stem_radius). */
sy_code sy_rebuild_unseen_stem(sy_skeleton *s, const float *xyz, size_t n, int32_t *point_node, const uint8_t *wood,
                               double w, double spacing, double ground, int limbs, sy_stem_info *info, sy_error *err);
/* Space colonisation (colonize.c, Runions et al. 2007): from the n_seed
 * nodes at seed, grows nodes one step at a time toward the attraction points
 * (pts thinned to one per step-sized voxel) until each is within kill of a
 * node, no node grows, or max_nodes exist. Returns all nodes (the seeds
 * first, unchanged) and their parents (-1 for the seeds), malloc'ed. */
sy_code sy_colonize(const float *seed, size_t n_seed, const float *pts, size_t n_pts, double step, double kill,
                    size_t max_nodes, float **pos_out, int32_t **parent_out, size_t *n_out, sy_error *err);
/* After sy_assign_radii on a rebuilt stem: the allometry runs from the
 * measured stem circle (or the slenderness estimate) instead of the
 * breast-height slab fit, which on such scans rings the lowest branches.
 * A columnar stem (stem->columnar) tapers linearly by taper from its foot
 * to its top instead. */
void sy_apply_stem_radius(sy_skeleton *s, const sy_stem_info *stem, double gamma, double taper, double spacing,
                          sy_radii_info *ri);

#ifdef __cplusplus
}
#endif

#endif
