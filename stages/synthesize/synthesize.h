/* Cluster texturing (Pirk 2013 §3.4, Fig. 3.6-3.7): each lobe (a cluster
 * hull hanging off a seed node of the main skeleton) is filled with species
 * patches, in the manner of patch-based texture synthesis (Efros & Freeman
 * 2001). From the seed, candidate patches are chosen by thickness and
 * vertical angle, scored by the digest's consistent form of eq. 3.3 and by
 * how the patch sits in the lobe (share outside the hull, distance to the
 * lobe's occupied cells, room it fills); the best is placed, its docking
 * points are queued, and so on until the queue is empty or the lobe is full.
 * The hull is a soft constraint: patches mostly outside it are rejected and
 * docking points outside it dropped. Thickness strictly decreases from a
 * patch to those docked on it and the depth is capped, so it terminates.
 *
 * Output: the main skeleton extended by the placed patches' bark (new stems
 * hanging off skeleton nodes, so one mesher call makes one welded bark mesh)
 * and the patches' leaves, ordered so that every prefix of the list holds
 * the same leading share of each patch's stored random order (stochastic
 * pruning, Cook et al. 2007): the mesher's LOD chain keeps prefixes.
 * Deterministic per (skeleton, lobes, library, seed). Z up, metres. */
#ifndef SYLVA_SYNTHESIZE_H
#define SYLVA_SYNTHESIZE_H

#include <stddef.h>
#include <stdint.h>

#include "stages/clusters/clusters.h"
#include "stages/core/skeleton.h"
#include "stages/core/status.h"
#include "stages/synthesize/branchlets.h"

#define SY_SYNTH_WP_LEVELS 4 /* Weber & Penn's stem levels, trunk included (species/params.h SY_WP_LEVELS) */

typedef struct {
    uint64_t seed;          /* per-lobe random streams derive from it and the lobe's index */
    float leaf_size;        /* leaf card length, metres (> 0) */
    float leaf_density;     /* leaf area density (m^2 of leaf per m^3 of occupied lobe cell) at which a
                               cell is full; 0: 1.5 */
    int max_depth;          /* docking generations per lobe; 0: library's */
    int max_patches;        /* per lobe (default 3000) */
    int candidates;         /* best patches by eq. 3.3 tried against the lobe geometry (default 12) */
    int rolls;              /* roll angles tried per candidate (default 4) */
    float outside_max;      /* reject a patch with more than this share of its samples outside the hull (0.2) */
    float start_outside_max; /* the same for a start's first patch, which leaves from a seed that may lie outside
                               * the hull (0.35; 0.5 until stop 24 put the starts' twigs across empty space
                               * beside the scan's points: docs/synthesize.md) */
    int grid;               /* lobe grid cells along its longest side (default 16) */
    float ratio_power;      /* Weber & Penn's RatioPower of the species: the hidden limbs' radii (0: 1.2) */
    float level_length[SY_SYNTH_WP_LEVELS]; /* Weber & Penn's nLength of the species' stem levels 0..3: how long a
                                               hidden lateral would grow, so how thick it starts (0: unknown) */
    int levels;             /* the species' stem levels, Weber & Penn's Levels (0: unknown; the lengths unused) */
    float down_angle[2], down_angle_v[2]; /* the species' DownAngle and its variation, levels 1 and 2, degrees:
                                             the angles the hidden limbs branch at (0: 25 to 90) */
    int literal_eq33;       /* 1: eq. 3.3 as printed, max/min thickness ratio x (v_r . v_d), minimised */
    int bare;               /* 1: a leaf-off tree: a lobe with traced twigs (sy_cluster.n_twigs) gets no
                               leaves, its twigs are its wood (0: its leaves hang on its twigs; no lobe with
                               twigs gets patches either way) */
    int fronds;             /* > 0: a crown of this many fronds (a palm): no traced twigs, no hidden limbs;
                               every lobe hangs off the stem's top, and each frond, one whole branchlet,
                               reaches from there to the crown's edge in its own direction (0: none) */
} sy_synth_options;

/* What happened to a lobe that got no patch (sy_synth_report.bare_reason), as a phrase. */
const char *sy_synth_bare_reason(int reason);

sy_synth_options sy_synth_options_default(void);
sy_code sy_synth_options_check(const sy_synth_options *o, sy_error *err);

typedef struct {
    size_t lobes, lobes_bare;   /* lobes given; lobes that got no patch (no room or nothing fits) */
    int32_t bare_lobe[8];       /* the first bare lobes' indices */
    int bare_reason[8];         /* 0 no room inside the hull, 1 no candidate fitted, 2 no candidate fitted and
                                 * the lobe's twigs were grown toward its returns (sy_synth_bare_reason) */
    size_t patches, docks_filled, docks_outside, docks_depth, docks_full, docks_rejected;
    size_t nodes_added, leaves;
    size_t scaffold_nodes;      /* of nodes_added, the hidden limbs' (the scaffold; in a lobe without patches also
                                 * the small colony grown toward its returns instead) */
    size_t nodes_pruned;        /* of nodes_added, those dropped again: bark beyond every leaf of its lobe
                                 * (merge_lobe); out->n = skel->n + nodes_added - nodes_pruned */
    size_t leaves_in_hull;      /* leaves inside their lobe's hull or within 5 cm of it (exact test) */
    double coverage;            /* share of the lobes' occupied blocks (2 x 2 x 2 grid cells) holding a leaf */
    double fill;                /* share of the lobes' inside cells holding scan points (all lobes) */
    double leaf_size;           /* the leaf card length used, metres (the option's) */
    double seconds;
} sy_synth_report;

/* skel: the main skeleton (not modified); lobes: hulls with seeds on skel and
 * optional occupancy grids. out receives a copy of skel plus the patch
 * stems (no support), leaves the leaves (both initialised here). rep may be
 * NULL. */
sy_code sy_synthesize(const sy_skeleton *skel, const sy_clusters *lobes, const sy_branchlets *lib,
                      const sy_synth_options *o, sy_skeleton *out, sy_leaves *leaves, sy_synth_report *rep,
                      sy_error *err);

/* Generalised winding number of the closed triangle mesh at p (1 inside, 0
 * outside; Jacobson et al. 2013, solid angles by Van Oosterom & Strackee). */
double sy_winding_number(const float *verts, const uint32_t *tris, size_t n_tris, const float p[3]);

#endif
