/* Skeleton reconstruction: one segmented, Z-up tree scan becomes a rooted
 * skeleton of the whole tree, every point assigned to a node. Follows Pirk
 * 2013 ch. 3 / Livny et al. 2011; the choices the thesis leaves open are
 * documented in docs/skeleton.md.
 *
 * Steps: neighbour graph (kNN joined with a radius graph, disconnected parts
 * bridged by their shortest gap edge) -> Dijkstra shortest-path tree from the
 * base with weights |u-v|^beta -> geodesic level sets split into connected
 * sub-clusters, one node each -> pruning, sibling merging, smoothing -> DBH
 * circle fit, allometric radii (gamma) and measured radii.
 *
 * The result is the full skeleton (sy_full_skeleton, stages/core/skeleton.h).
 * The clusters stage (sy_clusters_extract) then cuts it at low-confidence
 * edges (f_s) into the main structure and clusters, and builds one hull per
 * cluster; the pipeline (sy_reconstruct_tree) calls the two in turn. */
#ifndef SYLVA_STAGE_SKELETON_H
#define SYLVA_STAGE_SKELETON_H

#include <stddef.h>

#include "stages/core/cloud.h"
#include "stages/core/skeleton.h"
#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double beta;          /* Dijkstra edge weight |u-v|^beta (1) */
    double gamma;         /* allometry: d^gamma is additive over children (2 = da Vinci areas) */
    double spacing;       /* point spacing s in metres; 0 = median nearest-neighbour distance */
    int k;                /* neighbours per point in the kNN graph (12) */
    double radius_factor; /* also join all points within radius_factor * s (2.0) */
    double bin_factor;    /* geodesic level-set width = bin_factor * s (4.0) */
    double min_bin;       /* ... but at least this many metres (0.02) */
    double prune_factor;  /* drop side subtrees shorter than prune_factor * local radius (2.5) */
    double merge_cos;     /* merge sibling nodes whose directions have cos above this (0.9) */
    int smooth_iters;     /* Laplacian passes along chains (3) */
    double fair_sigma;    /* limb fairing after the cut: each chain node of the main skeleton smoothed
                             over this many times its radius (4; 0 = off; fair.c) */
    double return_cap;    /* after the cut, before the fairing: no main-skeleton edge thicker than this
                             many times the median distance of its returns (2; 0 = off; radii.c,
                             sy_cap_radii_by_returns) */
    double dbh_height;    /* breast height above the base in metres (1.3) */
    double dbh_slab;      /* slab thickness for the DBH circle fit in metres (0.10) */
    double dbh_per_height; /* the species' allometry, DBH over height of its nominal tree: the DBH
                              where no trunk circle stands at breast height (0: unknown, then the
                              slab's extent or the stem's slenderness) */
    int unfold_hairpins;  /* turn round chains that climb one limb and come down another (1;
                             skeletonize.c, unfold_hairpins) */
    int fork_domed_stems; /* an occluded stem rebuilt under a domed crown ends where the crown's widest
                             part ends, and the limbs spread from there (1; stem.c) */
    double crown_meander; /* a leaf-on crown is regrown when the trunk chain's path is more than this
                             many times its reach (1.45; 1.8 until stop 24; stem.c) */
    int crown_base_above_root; /* the regrown crown's base measured from the node above the root, which
                                  can lie off the stem (1; 0 until stop 24; stem.c) */
    double crown_base_share; /* the species' crown base over its height, from its nominal tree: an
                                airborne crown's lobes reach down at least that far (0: unknown; the
                                pipeline's hulls read it, as lobe_size below) */
    float crown_profile[8]; /* the same tree's crown radius in 8 height slabs from its crown base to
                               its top (any scale; all 0: unknown): an airborne crown's lobes narrow
                               as it does below what the scan saw (the pipeline's hulls read it) */
    double crown_roof_gap; /* the species' own crown top under its roof (sy_crown_roof_gap of its nominal
                              tree's branch nodes; 0: unknown): a terrestrial scan whose top stands
                              SY_ROOF_GAP_RATIO times this under its roof, and SY_ROOF_GAP_MARGIN more,
                              gets its lobes roofed (the pipeline's hulls read it) */
    int crown_roof;       /* -1: roofed so when the species is known (default); 0: never; 1: always
                             (terrestrial scans) */
    int no_twigs;         /* 1: the species' crown has no twigs to trace (a palm's fronds): the
                             pipeline traces none and keeps the lobes' occupancy bits (0); an
                             unseen stem then grows no limbs and tapers by stem_taper */
    double stem_taper;    /* the species' trunk taper (Weber & Penn's 0Taper, [0, 1]: the radius falls
                             linearly by this share from the foot to the top; 0: a cylinder) */
    int unseen_stems;     /* a scan that shows no stem (its lowest return high over the ground, or
                             spacing >= 0.2 m: airborne) gets a trunk from the ground and limbs grown
                             into its returns (1; 0 until stop 25; stem.c, docs/skeleton.md 8d) */
    double wood_share;    /* wood/leaf separation: wood = shortest-path subtrees holding at least this
                             share of the points, plus their neighbours; 0 = off, all wood (default:
                             on leafy TLS scans it gained little and hurt leafless trees, docs/skeleton.md) */
    /* The cut's options, carried here so one struct configures a
     * reconstruction; the skeleton stage does not read them, the pipeline
     * hands them to the clusters stage (sy_cut_options) and checks them there. */
    double fs;            /* scan-density factor f_s of eq. 3.2, in (0, 1] (1 = leafless) */
    int min_cluster_points; /* smaller low-confidence groups stay on the skeleton (24) */
    int clusters;         /* 0: skeleton only, every point stays on the skeleton */
    int spread_around;    /* low-confidence spread from the skeleton around the node, not the
                             incoming edge (0; 1 recovers more limbs on leaf-off scans but cuts
                             less in leafy crowns and sparse scans: docs/skeleton.md) */
    double lobe_size;     /* lobes: low-confidence regions split into parts no larger than this share of
                             the tree's largest extent, each hanging off the skeleton node next to it
                             (0.25; 0 = one cluster per cut, as Pirk 2013 §3.3.2 alone gives) */
} sy_skeleton_options;

sy_skeleton_options sy_skeleton_options_default(void);
/* SY_EUSAGE naming the field when a value is out of range. */
sy_code sy_skeleton_options_check(const sy_skeleton_options *o, sy_error *err);

/* Limb fairing (fair.c): each chain node smoothed along its branch over
 * sigma_factor x its radius (Laplacian passes, a Gaussian of that width),
 * the radii too within each branch; branches parents first, each bent by
 * as much as its fork moved (in full at its first node, none from
 * sigma_factor x the fork's radius on); the root and the tips stay put. The
 * root's chain keeps its radius at height breast_z (s's frame; NAN: none):
 * the fairing reshapes the trunk, not its DBH. No radius then grows toward
 * a tip. 0 does nothing. Any node order. */
sy_code sy_skeleton_fair_limbs(sy_skeleton *s, double sigma_factor, double breast_z, sy_error *err);
/* Radii the returns bound (radii.c): each edge of s (a main skeleton with
 * its support) is made no thicker than cap times the median distance from
 * it of the returns nearest to it of all its edges, pooled along its branch
 * over four of its radii either way, when they are at least 20 (and a
 * millimetre at least), but for
 * trunk nodes (branch 0) below keep_below_z (breast height: the DBH fit
 * stands there); then no radius grows toward a tip. capped counts the
 * edges cut. cap 0 does nothing. */
sy_code sy_cap_radii_by_returns(sy_skeleton *s, const float *xyz, double cap, double keep_below_z, size_t *capped,
                                sy_error *err);
/* Kinks: chain nodes of limbs at least min_radius thick whose chain turns
 * by more than max_turn_deg between max(4 radii, 10 cm) of it on either
 * side (a limb bends; a hook or a level crossing turns). worst (may be
 * NULL) gets the largest turn of any such node, in degrees. */
size_t sy_skeleton_limb_kinks(const sy_skeleton *s, double min_radius, double max_turn_deg, double *worst);

typedef struct {
    size_t points, graph_edges, components, bridges;
    size_t largest_component; /* points in the largest graph component before bridging */
    size_t wood_points;   /* points classified wood (all of them with wood_share 0) */
    double spacing, bin_width;
    size_t raw_nodes, pruned_nodes, merged_nodes;
    size_t hairpins;      /* descending chains turned round to grow up from the wood below them */
    size_t radii_capped;  /* after sy_reconstruct_tree: main-skeleton edges thinned to their returns
                             (sy_cap_radii_by_returns) */
    size_t limb_kinks;    /* after sy_reconstruct_tree: main-skeleton nodes on limbs >= 2 cm turning
                             more than 60 degrees (sy_skeleton_limb_kinks), after the fairing */
    double limb_turn_max; /* ... and the largest such turn, degrees */
    /* After the stage: the full skeleton's; after sy_reconstruct_tree: the
     * main skeleton's and the clusters' (the clusters stage's cut). */
    size_t nodes, branches;
    size_t clusters, cluster_points, skeleton_points;
    double lobe_size;     /* after sy_reconstruct_tree: the lobe size the cut took, as a share of the
                             cloud's extent (the option's, or larger where the .sylva could not hold
                             that many lobes) */
    double dbh, dbh_rms, height;
    double breast_z;      /* the height the DBH stands at, in the skeleton's frame (the ground's, or the
                             root's, plus 1.3 m or a quarter of a short tree's height) */
    int dbh_fitted;       /* 1: circle fit at breast height, 0: fallback estimate */
    double d_root;        /* root diameter from which the allometry runs */
    size_t radii_measured; /* nodes whose radius a circle fit measured (they rescale their branch) */
    int stem_rebuilt;     /* 1: the trunk chain circled the crown's axis (an occluded conifer stem) and
                             the stem was rebuilt on the axis of the crown's slab centroids */
    double stem_excursion, crown_radius; /* the trunk chain's largest distance from that axis; the crown's radius */
    double crown_dome;    /* above the crown's widest slab, its mean radius over the widest (a cone 0.6) */
    double stem_fork;     /* a domed crown's rebuilt stem ends this high above the root, metres (0: at the top) */
    int crown_regrown;    /* 1: the trunk chain meandered through a foliage crown (a decurrent crown's
                             shell) and the crown above its base was regrown by space colonisation */
    double trunk_meander, crown_fill, crown_base; /* path over chord of the trunk chain; the crown's
                             median/95th-percentile radius; the kept trunk's top above the root, metres */
    int stem_unseen;      /* 1: the lowest return stood crown_gap metres over the ground (an airborne
                             scan): a trunk from the ground, limbs grown into the crown (step 8d) */
    double crown_gap;
    double roof_gap, roof_gap_species; /* the scan's crown top under its roof (sy_crown_roof_gap; 0: not
                                          measured), and its species' (crown_roof_gap) */
    int roofed;           /* 1: the lobes reach up to the crown's roof */
    double t_graph, t_dijkstra, t_levels, t_radii, t_clusters, t_total; /* seconds */
} sy_skeleton_report;

/* Reconstructs cloud into out: the full skeleton (positions relative to
 * cloud->origin, nodes in breadth-first order from the root, support filled),
 * each point's node, the wood mask, the measured radii and the ground under
 * the base. report (may be NULL) gets everything up to the radii; its node
 * and point counts are the full skeleton's. Fails with SY_EUSAGE for options
 * sy_skeleton_options_check rejects, SY_EINPUT for clouds too small to hold a
 * tree (< 16 points); on failure out holds nothing to free. */
sy_code sy_reconstruct_skeleton(const sy_cloud *cloud, const sy_skeleton_options *o, sy_full_skeleton *out,
                                sy_skeleton_report *report, sy_error *err);

/* Whether a reconstruction is a plausible tree (sanity.c). A failed one
 * says why in reason; the figures behind the verdict are kept. */
typedef struct {
    int failed;
    char reason[240];
    double cloud_height;   /* z span of the cloud, 1st to 99th percentile, metres */
    double skeleton_share; /* z span of the main skeleton's nodes over cloud_height */
    double expected_nodes; /* the fewest nodes a tree of that height gives at this level-set width */
    double largest_share;  /* the largest graph component's share of the points (before bridging) */
} sy_skeleton_verdict;

/* Judges s (from sy_reconstruct_skeleton on cloud, with its report r): a
 * handful of nodes from thousands of points, a main skeleton spanning far
 * less of the cloud's height than a tree's stem does, or a neighbour graph
 * that fell apart into pieces none of which holds a fair share of the points
 * (the spacing too fine for the scan's density) each fail it. */
void sy_skeleton_judge(const sy_cloud *cloud, const sy_skeleton *s, const sy_skeleton_report *r,
                       sy_skeleton_verdict *v);

/* ---- The pieces, exposed for tests and benchmarks. ---- */

/* Symmetric neighbour graph in CSR form. */
typedef struct {
    size_t n;
    size_t *start; /* n+1 */
    uint32_t *adj;
    float *len;    /* Euclidean edge lengths, parallel to adj */
    size_t components; /* before bridging */
    size_t largest;    /* points in the largest of them */
    size_t bridges;    /* edges added to connect them */
} sy_graph;

/* Median nearest-neighbour distance over a deterministic sample of points. */
double sy_estimate_spacing(const float *xyz, size_t n);
/* kNN (k in [1, 32], else SY_EUSAGE) joined with all neighbours within
 * radius; components bridged to the one holding `anchor` by their shortest
 * gap edges. */
sy_code sy_graph_build(const float *xyz, size_t n, int k, double radius, uint32_t anchor, sy_graph *g,
                       sy_error *err);
void sy_graph_free(sy_graph *g);
/* Dijkstra from the sources (all at distance 0) with weights len^beta:
 * dist (weighted), parent (-1 at sources and unreachable points), path
 * (Euclidean length along the shortest-path tree). */
sy_code sy_graph_dijkstra(const sy_graph *g, const uint32_t *sources, size_t n_sources, double beta, double *dist,
                          int32_t *parent, double *path, sy_error *err);

/* Circle fit (Kasa algebraic start, RANSAC over triples, geometric
 * Gauss-Newton refinement on the inliers) to n 2-D points. Returns 0 on
 * success with centre, radius and the inlier RMS residual. */
int sy_fit_circle(const double *xy, size_t n, double inlier_tol, unsigned long long seed, double centre[2],
                  double *radius, double *rms);

/* Root of the tree: the point of the lowest slab nearest its robust centre.
 * The slab starts at the base (sy_base_height); *z0 (may be NULL) receives
 * that height. */
uint32_t sy_find_root(const float *xyz, size_t n, double slab, double *z0);
/* The tree's base: the 0.5th percentile of z, or lower, the lowest z with 8
 * more points within `slab` above it. With the ground removed a trunk's foot
 * is a tiny share of the points: on a 100k-point plane tree the percentile
 * sat 1.25 m up the trunk, too far above the ground to trust the ground
 * found under it, so breast height was measured from there, at 2.5 m. (Not
 * the rule alone: an airborne tree's trunk is a few scattered returns under
 * its crown, each a "stray" by it.) */
double sy_base_height(const float *xyz, size_t n, double slab);

#ifdef __cplusplus
}
#endif

#endif
