/* Segment: a plot (many trees on the ground) becomes individual trees.
 *
 * Two methods, both over the normalised heights of the preprocess stage's
 * ground classification (heights above a progressive-morphological ground
 * surface):
 *  - terrestrial (TLS, MLS, dense UAV): stems are found as circles in thin
 *    horizontal slices around breast height (RANSAC + geometric least
 *    squares), then every point reaches a stem along the shortest path of a
 *    voxel adjacency graph (the comparative shortest-path idea of Tao et al.
 *    2015, "Segmenting tree crowns from terrestrial and mobile LiDAR data by
 *    exploring ecological theories", ISPRS J. 110:66-76);
 *  - airborne (ALS): a canopy height model, tree tops as local maxima in a
 *    window that widens with height (Popescu & Wynne 2004), and a
 *    marker-controlled watershed grown from the tops with the crown rules of
 *    Dalponte & Coomes 2016 (Methods Ecol. Evol. 7:1236-1245).
 * Every point ends up in exactly one tree, on the ground, or unassigned, and
 * the result counts each. Deterministic: the same cloud and options give
 * the same labels for any thread count. See docs/segment.md. */
#ifndef SYLVA_SEGMENT_H
#define SYLVA_SEGMENT_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/cloud.h"
#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { SY_SEGMENT_AUTO = 0, SY_SEGMENT_TERRESTRIAL = 1, SY_SEGMENT_AIRBORNE = 2 } sy_segment_method;

/* "auto", "terrestrial", "airborne" (also "tls", "als"): 0 and *m set, or -1. */
int sy_segment_method_parse(const char *text, sy_segment_method *m);
const char *sy_segment_method_name(sy_segment_method m);

typedef struct {
    sy_segment_method method;  /* auto: stems when any show, else the canopy (and always below auto_density) */
    double auto_density;       /* points per m^2 of occupied ground area under which no stem is looked for (10) */
    /* ground (the preprocess stage's progressive morphological filter) */
    double ground_cell;        /* metres (0.5) */
    double ground_threshold;   /* metres above the surface still ground (0.15) */
    double ground_max_window;  /* metres: the widest object the filter flattens (16) */
    /* stems (terrestrial) */
    double breast_height;      /* metres above ground where stems are looked for (1.3) */
    double slice;              /* thickness of the band around breast height, metres (0.6) */
    double stem_min_radius;    /* metres (0.025) */
    double stem_max_radius;    /* metres (1.0) */
    double circle_tolerance;   /* inlier band of the circle fit, metres (0.025) */
    size_t stem_min_points;    /* points a stem circle needs within the tolerance (30) */
    double stem_cluster_gap;   /* slice points closer than this join one stem candidate, metres (0.1) */
    double min_arc;            /* fraction of the circle the inliers must surround (0.35) */
    double single_band_arc;    /* ... when only one of the two bands shows the circle (0.5) */
    double min_facing;         /* share of inliers whose local surface faces away from the centre (0.5) */
    /* crowns (terrestrial) */
    double voxel;              /* graph voxel edge, metres (0.15) */
    int graph_reach;           /* neighbours up to this many voxels away along each axis (2) */
    double gap_penalty;        /* edge cost = length * (length / voxel)^gap_penalty: long jumps cost more (1.0) */
    /* airborne */
    double chm_cell;           /* canopy height model cell, metres (0.5) */
    double min_height;         /* lowest tree top and crown edge above ground, metres (2.0) */
    double window_base;        /* local-maximum window diameter = base + slope * height, metres (3) */
    double window_slope;       /* (0.15) */
    double window_max;         /* the widest window, metres (10) */
    double seed_ratio;         /* a crown cell is at least this fraction of its top's height (0.45) */
    double crown_ratio;        /* ... and of the crown's running mean height (0.55) */
    double max_crown_radius;   /* metres from the top (8) */
    /* both */
    size_t min_points;         /* a tree with fewer points is dissolved into unassigned (20) */
    uint64_t seed;             /* RANSAC sampling */
} sy_segment_options;

sy_segment_options sy_segment_options_default(void);
/* SY_EUSAGE with a message naming the field when a value is out of range. */
sy_code sy_segment_options_check(const sy_segment_options *o, sy_error *err);

typedef struct {
    int32_t id;            /* 1..n_trees */
    double stem[3];        /* world x, y of the stem (or tree top for airborne), ground z there */
    double height;         /* metres above ground of the highest point */
    double dbh;            /* metres; NAN when no stem circle was fitted */
    double crown_width;    /* metres: mean of the x and y extents of the tree's points */
    size_t n_points;
} sy_segment_tree;

typedef struct {
    size_t n_points;           /* of the input plot */
    int32_t *tree_of;          /* per point: 1..n_trees, 0 ground, -1 unassigned */
    size_t n_trees;
    sy_segment_tree *trees;    /* trees[i].id == i + 1 */
    size_t n_ground, n_unassigned; /* n_points = n_ground + n_unassigned + sum of trees' n_points */
    int airborne;              /* 1: the CHM watershed ran, 0: stems + crown growing */
    size_t n_stem_candidates;  /* terrestrial: slice clusters tried */
    double density;            /* points per m^2 of occupied ground area (what auto decided on) */
    double seconds;
} sy_segmentation;

/* Segments plot into trees. plot needs at least one point; out is
 * overwritten (free it with sy_segmentation_free). A plot where no tree is
 * found is not an error: n_trees is 0 and the points are ground or
 * unassigned. */
sy_code sy_segment(const sy_cloud *plot, const sy_segment_options *o, sy_segmentation *out, sy_error *err);
void sy_segmentation_free(sy_segmentation *s);

/* Copies tree `index` (0-based) out of the plot with all its attributes. */
sy_code sy_segmentation_tree_cloud(const sy_cloud *plot, const sy_segmentation *s, size_t index, sy_cloud *out,
                                   sy_error *err);

/* Adds (or overwrites) the attribute "treeID" on c, which must be the cloud
 * s was computed from: tree ids 1..n, 0 for ground and unassigned. */
sy_code sy_segmentation_label(sy_cloud *c, const sy_segmentation *s, sy_error *err);

/* 1 when the cloud holds several trees (a plot) and should be segmented, 0
 * for a single-tree scan (or on any failure: a cloud that cannot be judged
 * goes through as one tree). Runs the detection half of sy_segment only
 * (ground, then stems or CHM tops). */
int sy_segment_is_plot(const sy_cloud *c, const sy_segment_options *o);

#ifdef __cplusplus
}
#endif

#endif
