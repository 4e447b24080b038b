/* Evaluation: one scoring for synthetic and real data (docs/eval.md).
 *  - skeleton vs truth skeleton: length-weighted recall/precision, by order
 *    and for thick branches, bifurcation, radius, DBH and height errors;
 *  - model vs input points without truth: point->model distances, coverage,
 *    Hausdorff both ways (triangle meshes, closed hulls, skeleton cones);
 *  - segmentation: instance precision/recall/F1 at IoU > 0.5;
 *  - species: accuracy, macro-F1, confusion matrix (text, JSON, PNG).
 * Metrics that do not apply are NaN. All coordinates: world, metres, Z up. */
#ifndef SYLVA_EVAL_H
#define SYLVA_EVAL_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "stages/core/asset.h"
#include "stages/core/cloud.h"
#include "stages/core/json.h"
#include "stages/core/skeleton.h"
#include "stages/gltf/gltf_read.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- Trees: a truth file, a skeleton file, or a decoded reconstruction ---- */

typedef struct {
    long long tree_id;   /* -1 when the file has none */
    char species[64];    /* "" when unknown */
    int species_id;      /* -1 when unknown */
    double position[3];  /* trunk base (world) */
    double height, dbh, crown_width; /* metres; NaN when the file has none */
    sy_skeleton skel;    /* world = skel.origin + pos */
} sy_eval_tree;

typedef struct {
    size_t n_trees;
    sy_eval_tree *trees;
} sy_forest;

/* Reads a truth JSON (docs/truth-format.md: {"format":"sylva-truth","trees":[...]}),
 * a skeleton JSON ({"nodes":[...]} in the same node layout, world
 * coordinates; optional "origin" (the float origin, as sylva-skeleton files
 * name it), "tree_id", "species", "dbh", "height"), or any other skeleton
 * file sy_skeleton_read takes (PLY, cylinder CSV, TreeQSM text, OBJ, .sylva)
 * as one tree. Nodes go through stages/qsm's JSON node reader: missing
 * order/branch are derived (the child heading the longest subtree continues
 * the stem). Missing dbh/height are measured on the skeleton. */
sy_code sy_forest_read(const char *path, sy_forest *out, sy_error *err);
sy_code sy_forest_parse(const char *name, const char *text, size_t len, sy_forest *out, sy_error *err);
void sy_forest_free(sy_forest *f);
/* Appends a tree; the forest takes ownership of t->skel. */
sy_code sy_forest_add(sy_forest *f, const sy_eval_tree *t, sy_error *err);
/* DBH (2 x trunk radius 1.3 m above the root) and height (highest node above
 * the root) of a skeleton; NaN when the trunk is shorter than 1.3 m. */
double sy_skeleton_dbh(const sy_skeleton *s);

/* ---- Models compared with points ---- */

typedef struct {
    size_t n;    /* triangles */
    double *tri; /* 9n: world coordinates, Z up */
    int closed;  /* a closed hull: points inside are at distance 0 */
} sy_tri_mesh;

typedef struct {
    size_t n_meshes;
    sy_tri_mesh *meshes;
    sy_forest skeletons; /* each edge a truncated cone */
} sy_eval_model;

/* Loads MODEL by kind: a .glb/.gltf (triangles of the default scene, node
 * and EXT_mesh_gpu_instancing transforms applied, Y-up turned to Z-up), a
 * .sylva file (its skeleton, plus each cluster hull as a closed mesh), or a
 * truth JSON or skeleton file (.json .ply .csv .txt .obj, see sy_forest_read).
 * closed marks the loaded glTF meshes as closed hulls. */
sy_code sy_eval_load_model(const char *path, int closed, sy_eval_model *out, sy_error *err);
/* Adds a copy of n triangles (9n doubles) as one mesh. */
sy_code sy_eval_model_add_mesh(sy_eval_model *m, const double *tri, size_t n, int closed, sy_error *err);
void sy_eval_model_free(sy_eval_model *m);

typedef struct {
    size_t n_points;
    double mean_distance, rms_distance, p95_distance;
    double coverage, coverage_eps;  /* share of points within coverage_eps */
    double hausdorff;               /* max point -> model */
    double hausdorff_model_to_points; /* max model surface sample -> nearest point */
    size_t n_model_samples;
} sy_surface_metrics;

/* Distance from each of n points (3n world coordinates) to the model. */
sy_code sy_model_distances(const sy_eval_model *m, const double *pts, size_t n, double *dist, sy_error *err);
/* Share of distances <= eps. */
double sy_coverage(const double *dist, size_t n, double eps);
/* All surface metrics. For the model -> points direction the model surface
 * is sampled about every max(spacing, half the mean point spacing over the
 * model's area) metres. */
sy_code sy_surface_metrics_compute(const sy_eval_model *m, const double *pts, size_t n, double coverage_eps,
                                   double spacing, sy_surface_metrics *out, sy_error *err);
/* Samples of the model surface about every spacing metres (triangle
 * vertices plus area-proportional samples; rings along each cone), 3 *n
 * doubles (caller frees), deterministic. The spacing widens so that the
 * area-proportional part stays within ~4 million samples. */
double *sy_model_surface_samples(const sy_eval_model *m, double spacing, size_t *n, sy_error *err);
/* How an asset looks against its scan (docs/eval.md): silhouette IoU of six
 * orthographic views (azimuth 0, 45, 90, 135 degrees, top, 30 degrees
 * oblique; 256 x 256 masks over the union's extent, each set splatted with a
 * disk of the scan's median spacing, the model's surface sampled finer than
 * a pixel), the Pearson correlation of the vertical profiles (40 height
 * bins: scan points against model surface area) and the relative height and
 * crown-width (5-95% extent along x and y, averaged; the model's by its
 * drawn area) errors, signed (model - scan) / scan. tri: 9 doubles per
 * triangle, world Z up; pts: 3 per point; pts_w: NULL (a scan: one each) or
 * the area each point stands for (a reference mesh's surface points,
 * sy_drawn_surface_points), counted so in the profile and the width.
 * cut (NULL: every triangle drawn whole) leaves out what a viewer's alpha
 * test discards: an alpha-masked leaf card counts where its leaves are, not
 * as its whole quad (sy_gltf_read_surface). */
#define SY_SILHOUETTE_VIEWS 6
#define SY_SILHOUETTE_RES 256
#define SY_SILHOUETTE_BINS 40
typedef struct {
    double iou[SY_SILHOUETTE_VIEWS], iou_mean, iou_min;
    /* Means over the views of the share of the asset's pixels the scan
     * holds too (precision) and of the scan's pixels the asset covers
     * (recall): which way the IoU is lost, an asset drawing where the scan
     * shows nothing or missing what it shows. */
    double precision, recall;
    double profile_correlation;
    /* The profiles it correlates: bin b spans world z profile_z0 + [b, b + 1)
     * profile_dz; the scan's points and the model's drawn area (m^2) in each. */
    double profile_z0, profile_dz, profile_scan[SY_SILHOUETTE_BINS], profile_model[SY_SILHOUETTE_BINS];
    double scan_height, model_height, height_error;
    double scan_width, model_width, width_error;
    double splat_radius; /* the scan's median spacing, metres */
} sy_silhouette_metrics;
/* masks: NULL, or room for SY_SILHOUETTE_VIEWS masks of SY_SILHOUETTE_RES^2
 * bytes, view after view in the order of iou[], row 0 at the bottom of the
 * view; each pixel the SY_MASK_SCAN and SY_MASK_MODEL bits it holds. */
enum { SY_MASK_SCAN = 1, SY_MASK_MODEL = 2 };
sy_code sy_silhouette_metrics_compute(const double *tri, size_t n_tri, const sy_gltf_cutout *cut, const double *pts,
                                      const double *pts_w, size_t n_pts, sy_silhouette_metrics *out, unsigned char *masks,
                                      sy_error *err);
/* The six masks as one PNG at path (written whole or not at all), 784 x
 * 548: azimuths 0, 45 and 90 degrees on the top row, 135, top and oblique
 * below, each under a 12-pixel band naming it with its IoU, 4-pixel
 * gutters; scan only red, model only blue, both dark grey, neither white. */
sy_code sy_silhouette_png(const unsigned char *masks, const char *path, sy_error *err);

/* The triangles' drawn surface as points no more than step apart (cut, which
 * may be NULL, leaves out the texels an alpha test discards); 3 doubles
 * each, *n of them (malloc'd; NULL when out of memory). area_out, when not
 * NULL, gets the surface area each point stands for (malloc'd): every
 * triangle takes a few points however small, so they are not uniform. */
double *sy_drawn_surface_points(const double *tri, size_t n_tri, const sy_gltf_cutout *cut, double step, size_t *n,
                                double **area_out, sy_error *err);

/* World coordinates of a cloud as 3n doubles (caller frees). */
double *sy_cloud_world_points(const sy_cloud *c, sy_error *err);

/* ---- Skeleton vs truth skeleton ---- */

#define SY_EVAL_ORDERS 4 /* orders 0, 1, 2, 3+ */

typedef struct {
    double sample_step;        /* metres between samples along edges (0.01; widened for skeletons with
                                  more than 1 km of axes, see sy_skeleton_metrics.sample_step) */
    double min_tolerance;      /* metres (0.05) */
    double radius_factor;      /* tolerance = max(radius_factor * r, min_tolerance) (2) */
    double thick_radius;       /* "thick" branches: base radius >= this (0.02) */
    double bifurcation_radius; /* branch points further apart do not match (0.25) */
} sy_skeleton_metrics_options;

sy_skeleton_metrics_options sy_skeleton_metrics_options_default(void);
/* SY_EUSAGE naming the field: sample_step must be > 0, the rest >= 0, all
 * finite. */
sy_code sy_skeleton_metrics_options_check(const sy_skeleton_metrics_options *o, sy_error *err);

typedef struct {
    double truth_length, model_length;
    double recall, precision;
    double recall_r2cm, precision_r2cm;
    double recall_order[SY_EVAL_ORDERS], precision_order[SY_EVAL_ORDERS];
    double radius_error_median, radius_error_order[SY_EVAL_ORDERS];
    size_t bifurcations_truth, bifurcations_matched;
    double bifurcation_error_mean, bifurcation_error_median;
    size_t trees_truth, trees_matched;
    double dbh_error, height_error; /* mean |model - truth| over matched trees */
    double sample_step; /* the step used: options' sample_step, widened so that the samples stay
                           within max(1e5, 256 per edge) a direction (never more than 2e7) */
    size_t n_samples;   /* samples matched, both directions */
} sy_skeleton_metrics;

sy_code sy_skeleton_metrics_compute(const sy_forest *truth, const sy_forest *model, const sy_skeleton_metrics_options *opts,
                                    sy_skeleton_metrics *out, sy_error *err);

/* ---- Segmentation ---- */

typedef struct {
    size_t n_points;            /* points compared */
    size_t n_unmatched_points;  /* truth points with no prediction point within the match distance */
    size_t n_truth, n_pred;     /* instances (labels other than 0/NaN) */
    size_t n_matched;           /* pairs with IoU > 0.5 */
    double precision, recall, f1, mean_iou; /* mean_iou over matched pairs */
    /* Over-segmentation: truth trees holding most (> 50%) of the points of
     * two or more predicted trees (one tree cut into pieces). Under-
     * segmentation: predicted trees holding most of two or more truth trees
     * (neighbours merged). */
    size_t n_over_segmented, n_under_segmented;
} sy_segmentation_metrics;

/* Per-point labels (0 or NaN: not a tree). */
sy_code sy_segmentation_metrics_labels(const double *truth, const double *pred, size_t n, sy_segmentation_metrics *out,
                                       sy_error *err);
/* Two clouds: by index when they hold the same points in the same order,
 * else each truth point takes the label of the nearest prediction point
 * within match_dist (none: unassigned). */
sy_code sy_segmentation_metrics_clouds(const sy_cloud *truth, const char *truth_path, const char *truth_attr,
                                       const sy_cloud *pred, const char *pred_path, const char *pred_attr,
                                       double match_dist, sy_segmentation_metrics *out, sy_error *err);

/* ---- Species ---- */

typedef struct {
    size_t n;
    char **id;
    char **label;
} sy_label_table;

/* CSV "id,species" (an optional header line naming the columns, blank lines
 * and lines starting with '#' skipped; fields may be double-quoted). */
sy_code sy_label_table_read_csv(const char *path, sy_label_table *out, sy_error *err);
sy_code sy_label_table_parse_csv(const char *name, const char *text, size_t len, sy_label_table *out, sy_error *err);
/* tree_id -> species of a forest. */
sy_code sy_label_table_from_forest(const sy_forest *f, const char *path, sy_label_table *out, sy_error *err);
sy_code sy_label_table_add(sy_label_table *t, const char *id, const char *label, sy_error *err);
void sy_label_table_free(sy_label_table *t);

#define SY_MISSING_LABEL "(missing)"

typedef struct {
    size_t n_classes;
    char **labels;      /* sorted; SY_MISSING_LABEL last when some prediction is missing */
    size_t *matrix;     /* n_classes^2, row = truth, column = prediction */
    size_t n_samples;   /* truth entries */
    size_t n_missing;   /* truth ids without a prediction */
    double accuracy, macro_f1;
    double *f1;         /* per class (NaN for the missing column) */
} sy_confusion;

/* Every truth id is scored; ids only in the prediction are ignored. Macro-F1
 * averages the per-class F1 over the classes seen in truth or prediction. */
sy_code sy_confusion_build(const sy_label_table *truth, const sy_label_table *pred, sy_confusion *out, sy_error *err);
void sy_confusion_free(sy_confusion *c);
void sy_confusion_print(const sy_confusion *c, FILE *fp);
/* "labels": [...] and "confusion": [[row of truth label 0]...] into an open object. */
void sy_confusion_json(const sy_confusion *c, sy_json *j);
/* Heatmap PNG with row/column labels and counts; written atomically. */
sy_code sy_confusion_png(const sy_confusion *c, const char *path, sy_error *err);
void sy_confusion_png_size(const sy_confusion *c, int *width, int *height);


/* ---- Mesh quality of a tree asset (mesh_check.c; docs/mesh.md) ---- */

typedef struct {
    double min_radius;       /* the mesher's drawn radius floor, metres (sy_mesh_options.min_radius) */
    double ground;           /* ground height (Sylva Z, metres): 0 for trees rooted at the origin */
    double ground_tolerance; /* metres below the ground still counted as on it (default 5 mm) */
    double sail_radii;       /* an edge midpoint farther than this many local radii (or 5 % of
                                the nearest skeleton segment's length, the room a smooth curve
                                through the nodes takes) outside the skeleton's surface makes
                                its triangle a sail (default 3; a junction flank, whose base sits on
                                the parent, reaches about 2) */
    double across_radii;     /* reported only: max_across is measured against it (default 4) */
} sy_mesh_check_options;

sy_mesh_check_options sy_mesh_check_options_default(void);
sy_code sy_mesh_check_options_check(const sy_mesh_check_options *o, sy_error *err);

typedef struct {
    size_t lod;              /* index into asset.lods */
    size_t triangles;        /* bark + leaf instances x card triangles */
    size_t bark_triangles;
    double ratio;            /* triangles / the previous checked level's (0 at the first) */
    double silhouette_iou;   /* coverage vs the first level's, intersection over union, front and
                                side views averaged (256 px over the first level's box) */
    size_t sails;            /* triangles with an edge off the surface or too wide (options) */
    double max_off_surface;  /* largest edge-midpoint distance outside the surface, in local radii */
    double max_across;       /* largest edge extent across its nearest axis, in local radii */
    double max_edge_radii;   /* longest edge / its triangle's local radius */
    double max_edge;         /* longest edge, metres */
    size_t degenerate;       /* area < 0.005 mm^2 (issue 19's near-degenerate triangle) */
    size_t slivers;          /* degenerate, or height < 1/1000 of the longest edge */
    size_t collapsed;        /* triangles with two welded corners equal */
    size_t boundary_edges, nonmanifold_edges, misoriented_edges; /* after welding by position */
    size_t components;       /* connected parts of the welded bark */
    size_t below_ground;     /* bark vertices below ground - tolerance */
    size_t leaves, leaves_far, leaves_below_ground; /* far: petiole more than a leaf length from bark */
    double max_leaf_gap, mean_leaf_gap;             /* petiole to bark, in leaf lengths */
    double bark_top, leaf_top;                      /* highest bark vertex / petiole (Z, metres) */
} sy_mesh_check_level;

#define SY_MESH_CHECK_MAX_LEVELS 16
typedef struct {
    size_t n_levels; /* levels with bark (the impostor is not checked) */
    sy_mesh_check_level level[SY_MESH_CHECK_MAX_LEVELS];
} sy_mesh_check_report;

/* Checks every level of a mesh-stage asset against the skeleton it was built
 * from (same frame: the asset's Y-up positions are the skeleton's Z-up ones
 * rotated). */
sy_code sy_mesh_check(const sy_asset *a, const sy_skeleton *sk, const sy_mesh_check_options *o,
                      sy_mesh_check_report *out, sy_error *err);
#ifdef __cplusplus
}
#endif

#endif
