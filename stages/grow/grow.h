/* Procedural species trees after Weber & Penn (1995), as digested from seed
 * 004 (docs/species.md): a species parameter file (INI, the thesis's .tsp
 * layout plus a [Sylva] section) grows a skeleton and leaf placements.
 *
 * Output frame: Z up, metres, the trunk base at the origin. Every stem (the
 * trunk, each branch, each split clone) gets its own branch id; a stem's first
 * node lies at its attachment point on the parent stem's axis and its parent
 * is the parent-stem node nearest that point. Leaves: pos is the leaf base
 * (where it meets the twig), local +Y runs base->tip, +Z is the blade normal,
 * scale is the leaf length; the width is scale * leaf_scale_x. */
#ifndef SYLVA_GROW_H
#define SYLVA_GROW_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/json.h"
#include "stages/core/skeleton.h"
#include "stages/core/status.h"

/* Weber-Penn stem levels 0 (trunk) .. 3; leaves use the level after the last
 * stem level (clamped to 3) for their DownAngle/Rotate. */
#define SY_WP_LEVELS 4

typedef struct {
    float down_angle, down_angle_v; /* degrees; negative V: gradient along the parent */
    float rotate, rotate_v;         /* degrees; negative rotate: alternating two rows */
    float branches, branches_v;     /* children of a level-(n-1) stem (n >= 1) */
    float length, length_v;         /* level 0: fraction of scale; else of the parent */
    float taper;                    /* [0,3]: 0 cylinder, 1 cone, (1,2] spherical end, (2,3] periodic */
    float base_splits;              /* level 0 only: clones in the first trunk segment */
    float seg_splits;               /* clones per segment (fractional, error-diffused) */
    float split_angle, split_angle_v;
    int curve_res;                  /* segments per stem, >= 1 */
    float curve, curve_back, curve_v; /* degrees over the whole stem */
} sy_wp_level;

typedef struct {
    /* [General]: Weber & Penn */
    int shape;            /* 0..8, see sy_shape_ratio */
    float base_size;      /* bare fraction of the trunk */
    float scale, scale_v; /* tree size, metres */
    float zscale, zscale_v; /* vertical stretch of the whole tree */
    int levels;           /* stem levels 1..4 */
    float ratio, ratio_power;
    int lobes;
    float lobe_depth, flare;
    float scale0, scale0_v; /* 0Scale: trunk radius multiplier */
    float leaves;         /* per last-level stem; negative: a fan at the stem tip */
    int leaf_shape;       /* 0..9, for the card mesher */
    float leaf_scale, leaf_scale_x, leaf_bend, leaf_quality;
    float attraction_up;
    float prune_ratio, prune_width, prune_width_peak, prune_power_low, prune_power_high;
    /* [General]: thesis renderer keys, kept for compatibility */
    char *material, *material_normal;
    float ka[3], kd[3], ks[3];
    sy_wp_level level[SY_WP_LEVELS];
    /* [Sylva] */
    char *name;             /* defaults to the file name without .ini */
    char *bark_texture;     /* absolute path (resolved against the file's dir) or NULL */
    char *leaf_texture;     /* idem */
    float leaf_translucency; /* 0..1, default 0.4 */
    float beta;             /* edge-weight exponent for skeleton reconstruction, default 1 */
    float gamma;            /* allometry exponent (pipe model r^gamma), default 2 */
} sy_species;

/* Fills every parameter with its Weber-Penn default (docs/species.md). */
void sy_species_defaults(sy_species *sp);
/* Parses INI text; `path` names the file in messages, `base_dir` resolves
 * relative texture paths (NULL: keep as written). Unknown keys, keys whose
 * level does not match their section, malformed or out-of-range values fail
 * with "<path>:<line>: <problem>". On failure *sp holds nothing to free. */
sy_code sy_species_parse(const char *text, size_t size, const char *path, const char *base_dir,
                         sy_species *sp, sy_error *err);
sy_code sy_species_load(const char *path, sy_species *sp, sy_error *err);
/* "quaking_aspen" -> SYLVA_SPECIES_DIR/quaking_aspen.ini; a name containing
 * '/' or ending in ".ini" is loaded as a path. */
sy_code sy_species_find(const char *name, sy_species *sp, sy_error *err);
void sy_species_free(sy_species *sp);

/* Writes every parameter into the open JSON object j, one object per
 * species-file section ("General", "ParamLevel0".."ParamLevel3", "Sylva")
 * keyed by the file's key names, floats as their shortest round-tripping
 * decimals: "[Section]" plus "Key = value" per entry ({a, b, c} for the
 * arrays) parses back to the same species. Unset strings are left out;
 * bark and leaf are written relative to SYLVA_SPECIES_DIR when they lie in
 * it, else as file names only (the resolved absolute paths belong to the
 * machine that grew the tree). */
void sy_species_write_json(const sy_species *sp, sy_json *j);

/* Weber-Penn ShapeRatio; shape 8 is the pruning envelope of sp (may be NULL
 * for shapes 0..7). Ratios outside [0,1] are clamped. */
float sy_shape_ratio(const sy_species *sp, int shape, float ratio);
/* Stem radius at normalized position z in [0,1] (thesis getRadiusZ, NaN-safe). */
float sy_stem_radius_z(float z, float taper, float radius, float length);
/* Trunk flare multiplier at z: 1 + 0.99 flare at the base, 1 from z = 1/8. */
float sy_flare_z(float z, float flare);

/* Grows one tree. The same species and seed give byte-identical output;
 * out and leaves_out (may be NULL) are initialised here and owned by the
 * caller. */
sy_code sy_grow_tree(const sy_species *sp, uint64_t seed, sy_skeleton *out, sy_leaves *leaves_out,
                     sy_error *err);

#endif
