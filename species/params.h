/* Weber-Penn species parameters (Weber & Penn 1995, "Creation and rendering
 * of realistic trees"): the tree-type .ini files of the species library (the
 * thesis's .tsp layout plus a [Sylva] section), their strict parser and their
 * JSON form. docs/species.md lists every key. */
#ifndef SYLVA_SPECIES_PARAMS_H
#define SYLVA_SPECIES_PARAMS_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/json.h"
#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

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
    float leaf_fill;        /* share of a leaf card a scanner's beam meets: 1 (default) a leaf, less a needle shoot */
    float beta;             /* edge-weight exponent for skeleton reconstruction, default 1 */
    float gamma;            /* allometry exponent (pipe model r^gamma), default 2 */
    float bark_color[3];    /* sRGB 0..255 the bark photo is recoloured to (its pattern kept); negative: its own */
    int twigs;              /* 1 (default): a scan's traced twigs are its crown's wood; 0: a crown of fronds,
                               no twigs (the palm): synthesis leaves them out */
} sy_species_params;

/* Fills every parameter with its Weber-Penn default (docs/species.md). */
sy_species_params sy_species_params_default(void);

/* The share of the species' leaf size a tree tree_height metres tall takes:
 * a species' cards are sized for its grown tree (Scale metres tall), so a
 * shorter tree takes them shrunk by k = tree_height / (seen * Scale), at
 * most 1 and never below a quarter (1 for unknown sizes). seen in (0, 1] is
 * the share of a tree's height the measurement is sure to show: 1 for a QSM,
 * less for a scan that may miss the top (so a full-grown tree whose top the
 * scanner did not reach keeps full-size cards). Keeping the leaf area along
 * a twig means 1/k^2 as many. */
double sy_species_leaf_fit(const sy_species_params *sp, double tree_height, double seen);
/* Parses INI text; `path` names the file in messages, `base_dir` resolves
 * relative texture paths (NULL: keep as written). Unknown keys, keys whose
 * level does not match their section, malformed or out-of-range values fail
 * with "<path>:<line>: <problem>". On failure *sp holds nothing to free. */
sy_code sy_species_params_parse(const char *text, size_t size, const char *path, const char *base_dir,
                         sy_species_params *sp, sy_error *err);
sy_code sy_species_params_load(const char *path, sy_species_params *sp, sy_error *err);
/* A library species by name ("quaking_aspen": its manifest entry's parameter
 * file, species/library.h locates the library); a name containing '/' or
 * ending in ".ini" is loaded as a path. */
sy_code sy_species_params_find(const char *name, sy_species_params *sp, sy_error *err);
void sy_species_params_free(sy_species_params *sp);

/* Writes every parameter into the open JSON object j, one object per
 * species-file section ("General", "ParamLevel0".."ParamLevel3", "Sylva")
 * keyed by the file's key names, floats as their shortest round-tripping
 * decimals: "[Section]" plus "Key = value" per entry ({a, b, c} for the
 * arrays) parses back to the same species. Unset strings are left out;
 * bark and leaf are written relative to the species library's folder when
 * they lie in it, else as file names only (the resolved absolute paths belong to the
 * machine that grew the tree). */
void sy_species_params_write_json(const sy_species_params *sp, sy_json *j);

#ifdef __cplusplus
}
#endif

#endif
