/* The run driver: one scanned tree end to end (ingest -> preprocess ->
 * skeleton -> clusters -> mesh -> export, and the compact .sylva of the same
 * reconstruction), from options to bytes. `sylva run` and the batch runner
 * share it.
 *
 * Re-entrant: no globals, no file-scope state, nothing cached between calls;
 * a batch may call it thousands of times in one process and from several
 * threads at once, and the same scan and options give the same bytes every
 * time. The only process-wide settings it reads are the explicit setters
 * sy_set_threads() and sy_progress_set_quiet() (stages/core), which change
 * speed and stderr, never output bytes. Nothing is written to disk here:
 * sy_run_tree_write() writes a result atomically. */
#ifndef SYLVA_RUN_TREE_H
#define SYLVA_RUN_TREE_H

#include <stddef.h>
#include <stdint.h>

#include "pipeline/tree_asset.h"
#include "pipeline/tree_checks.h"
#include "stages/synthesize/synthesize.h"
#include "pipeline/tree_species.h"
#include "stages/clusters/clusters.h"
#include "stages/core/cloud.h"
#include "stages/core/status.h"
#include "stages/skeleton/skeleton.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SY_RUN_LOBE_SIZE 0.1 /* sylva run's lobes: a tenth of the tree's extent */

typedef struct {
    const char *species; /* library name or .ini path: its beta/gamma, bark and leaf materials and .sylva
                            species id; NULL: none (default materials, species id 0) */
    double beta, gamma;  /* skeleton edge weight / allometry exponents; NAN: the species', else 1 and 2 */
    double fs;           /* scan-density factor f_s in (0, 1] (1) */
    double wood_share;   /* wood/leaf separation share in [0, 1) (0: off) */
    double voxel;        /* thin the scan to one point per voxel of this edge in metres first (0: off) */
    size_t max_points;   /* after preprocessing, voxel-thin to at most this many points (SY_POINT_BUDGET;
                            0: never) */
    int spread_around;   /* skeleton: spread around the node, not the edge (0) */
    int keep_hairpins;   /* skeleton: leave chains that climb one limb and come down another as they are (0) */
    double fair_sigma;   /* skeleton: limbs smoothed over this many times their radius; NAN: the skeleton's
                            default (sy_skeleton_options.fair_sigma) */
    double return_cap;   /* skeleton: no limb thicker than this many times its returns' median distance;
                            NAN: the skeleton's default (sy_skeleton_options.return_cap) */
    int sylva;           /* 1: also keep the .sylva file (result->sylva); the asset is always made from it */
    int proxy;           /* 1: also draw the lobe hulls as the semi-transparent foliage_proxy mesh (0) */
    int leaf_off;        /* 1: a leaf-off scan: no leaf cards, and lobes with traced twigs keep them as
                            their wood without patches; 0: decided from the scan, leaf-off when at least
                            SY_LEAF_OFF_RETURNS of its returns lie within a scan spacing of the wood the
                            leaf-off tree draws (lobes with twigs traced at voxels of at least
                            SY_LEAF_OFF_MIN_VOXEL spacings only); -1: leaf cards whatever the
                            scan (0). A leaf-off tree's .sylva is marked so (SY_SYLVA_LEAF_OFF): `sylva
                            mesh OUT.sylva` gives the same asset */
    int roof;            /* lobes reach up to the crown's roof (sy_crown_roof): -1 when the scan's top
                            stands SY_ROOF_GAP_RATIO times (and SY_ROOF_GAP_MARGIN of the height) further
                            under it than its species' own crown's (a terrestrial scan of a known
                            species; default), 0 never, 1 always (a terrestrial scan) */
    double lobe_size;    /* largest lobe as a share of the tree's extent, [0, 1] (0: one cluster a cut);
                            -1: the species' (default): 1 for a crown of fronds (species twigs = 0),
                            else SY_RUN_LOBE_SIZE */
    int classify;        /* 1: without a species, the classifier names one from the cleaned cloud and a
                            confident answer's parameters and materials are used (1) */
    const char *model;   /* classifier model; NULL: the library's classifier.sjb */
    uint64_t seed;       /* every random choice (1) */
    sy_tree_asset_options asset; /* LODs, impostor, meshopt, instancing; seed, hulls and source are set
                                    by the driver */
    /* Step lines ("skeleton", seconds, "412 nodes, ..."), called on the calling
     * thread as each step ends; NULL: silent. */
    void (*on_step)(void *ctx, const char *step, double seconds, const char *detail);
    void *step_ctx;
} sy_run_tree_options;

/* A scan is leaf-off when this share of its returns lies within a scan
 * spacing of the wood its leaf-off tree draws (the skeleton and the traced
 * twigs as cones): rTwig's leaf-off sapling 0.89; AdTree's tree7 0.71, its
 * other scans 0.42-0.71, the bundled leafy aspen 0.65, the TreeLS pine 0.41,
 * PyTLidar's oak 0.20. Twigs traced at voxels much coarser than the spacing
 * run as chords past their returns: simulated leaf-off scans of 11-27k
 * returns (twig voxels 15-29 cm) reach 0.47-0.63 and keep their cards. Only
 * judged when the twig voxel is at least SY_LEAF_OFF_MIN_VOXEL spacings:
 * finer twigs take nearly every return as a node, and a leafy simulated
 * aspen of 4,388 returns (6 cm voxels, 10 cm spacing) lay 0.94 on its wood,
 * the airborne AHN3 tree 0.95 (docs/synthesize.md, "Stop 39"). */
#define SY_LEAF_OFF_RETURNS 0.8
#define SY_LEAF_OFF_MIN_VOXEL 1.5

sy_run_tree_options sy_run_tree_options_default(void);
/* SY_EUSAGE naming the field for out-of-range values (fs, wood_share, ...). */
sy_code sy_run_tree_options_check(const sy_run_tree_options *o, sy_error *err);

typedef struct {
    unsigned char *glb;   /* the .glb file's bytes (malloc'd) */
    size_t glb_size;
    unsigned char *sylva; /* the .sylva file's bytes when options.sylva (malloc'd), else NULL */
    size_t sylva_size;
    int species_id;       /* library id of options.species (or of the classified species), -1 when none */
    int classified;       /* 1: the species came from the classifier (guess holds its answer) */
    sy_species_guess guess;
    size_t points_in, points_clean; /* after ingest, after preprocessing */
    double top_z, clean_top_z;      /* world z: the highest supported point before the outlier filter, the
                                       highest left after preprocessing (height is measured to the first) */
    sy_skeleton_report skeleton;
    sy_hull_report hulls;
    sy_tree_checks checks; /* thinning, retries and the verdict (pipeline/tree_checks.h) */
    sy_tree_asset_report asset;
    sy_synth_report synth; /* the lobes' texturing (docs/synthesize.md) */
    int leaf_off;          /* 1: the asset carries no leaf cards (asked for, or the scan's returns lie on its wood) */
    double returns_on_wood; /* share of the returns within a scan spacing of the leaf-off tree's wood; NaN when
                               not measured (leaf_off given, or no lobe has traced twigs) */
    double t_synth;        /* decode + branchlets + texturing, seconds */
    double t_ingest, t_preprocess; /* seconds; skeleton and mesh times are in the reports */
} sy_run_tree_result;

void sy_run_tree_result_free(sy_run_tree_result *r);

/* Reconstructs the one tree in the scan file at path (any format ingest
 * reads). Bad input fails with SY_EINPUT and a message naming path; on
 * failure r holds nothing to free. */
sy_code sy_run_tree(const char *path, const sy_run_tree_options *o, sy_run_tree_result *r, sy_error *err);

/* As sy_run_tree from a cloud in memory (Z up not required: preprocessing
 * finds up). c is consumed (freed) whatever the outcome; name names it in
 * messages and becomes asset.extras.source. */
sy_code sy_run_tree_cloud(sy_cloud *c, const char *name, const sy_run_tree_options *o, sy_run_tree_result *r,
                          sy_error *err);

/* The reconstruction steps alone: the skeleton stage (the full skeleton),
 * then the clusters stage: its cut (o's fs, min_cluster_points, clusters,
 * spread_around, lobe_size) into out and clusters, and their hulls with the
 * encode stage's .sylva triangle budget. clusters NULL: skeleton only
 * (o->clusters is then ignored). hulls may be NULL; the hull options are the
 * defaults except alpha_scale (0: the default). On failure out and clusters
 * hold nothing to free. */
sy_code sy_reconstruct_tree(const sy_cloud *c, const sy_skeleton_options *o, double alpha_scale, sy_skeleton *out,
                            sy_clusters *clusters, sy_skeleton_report *report, sy_hull_report *hulls, sy_error *err);
/* The checks of both stages' options in o (SY_EUSAGE naming the field), the
 * ones sy_reconstruct_tree makes, for a caller to run before it reads a cloud.
 * Not an sy_X_options_check: a reconstruction has no options type of its
 * own, it takes the skeleton stage's, which carry the cut's share. */
sy_code sy_reconstruct_check(const sy_skeleton_options *o, sy_error *err);

/* Writes r->glb to glb_path and, when sylva_path is not NULL, r->sylva there:
 * each atomically, both or neither. */
sy_code sy_run_tree_write(const sy_run_tree_result *r, const char *glb_path, const char *sylva_path, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
