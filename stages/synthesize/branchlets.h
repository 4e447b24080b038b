/* Species branchlets: a bracketed, stochastic L-system per species
 * (Prusinkiewicz & Lindenmayer, "The Algorithmic Beauty of Plants", 1990,
 * ch. 1.6-1.7) grows 20-30 complete branchlets, each partitioned into patches
 * (Pirk 2013 §3.4, Fig. 3.5): a root (position, direction, thickness), docking
 * points where smaller patches may be placed, bark nodes and leaves in a
 * stored random order (stochastic pruning draws a prefix, Cook et al. 2007).
 *
 * The grammar and its parameters live in species/NAME.lsys beside the
 * species' .ini (docs/synthesize.md documents the format). Frame: Z up,
 * metres, every patch with its root at the origin and its root direction in
 * the x-z half-plane (azimuth 0), so the direction's vertical angle is what
 * candidate selection compares. Deterministic for a given file and seed. */
#ifndef SYLVA_BRANCHLETS_H
#define SYLVA_BRANCHLETS_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/status.h"

#define SY_LSYS_MAX_RULES 16
#define SY_LSYS_MAX_RULE_LEN 96

typedef struct {
    char pred;                          /* the variable it rewrites (A-Z, not F or L) */
    char succ[SY_LSYS_MAX_RULE_LEN];    /* successor word */
    float weight;                       /* stochastic rules of one predecessor: relative weights */
} sy_lsys_rule;

typedef struct {
    char axiom[SY_LSYS_MAX_RULE_LEN];
    sy_lsys_rule rules[SY_LSYS_MAX_RULES];
    int n_rules;
    int iterations;       /* rewriting steps, 1..8 */
    int count;            /* branchlets generated, 20..30 */
    float angle, angle_v; /* + - & ^ turn by angle +- angle_v degrees */
    float roll;           /* / \ roll about the heading, degrees (phyllotaxis, 137.5) */
    float step, step_decay; /* F length (m) at bracket depth 0, times step_decay per depth */
    float step_v;         /* relative random variation of each F */
    float tropism;        /* per F, bend of the heading towards -Z (> 0) or +Z (< 0), radians per metre */
    float elevation, elevation_v; /* root heading above the horizontal, degrees, per branchlet */
    float tip_radius;     /* radius of a twig tip, metres; radii grow toward the root by the pipe model */
    float pipe_exponent;  /* r^e summed over children (2 = da Vinci areas) */
    int leaves_per_l;     /* leaves an L draws */
    float leaf_angle;     /* leaf axis to twig, degrees */
    float leaf_size;      /* leaf (card) length, metres, when the asset names no species */
    int patch_depth;      /* bracket levels per patch, >= 1 */
    /* Texturing: */
    float leaf_density;   /* leaf area density a lobe is filled to, m^2 of leaf per m^3 of occupied cell */
    int max_depth;        /* docking generations a lobe may grow, >= 1 */
} sy_lsystem;

/* Defaults of every field (a generic broadleaf). */
sy_lsystem sy_lsystem_default(void);
/* Checks ranges; the message names the field. */
sy_code sy_lsystem_check(const sy_lsystem *ls, sy_error *err);
/* Parses the [Branchlets] text ("key = value" lines, "rule = A -> WORD : W",
 * ';' comments). path names the file in "<path>:<line>: <problem>". */
sy_code sy_lsystem_parse(const char *text, size_t size, const char *path, sy_lsystem *ls, sy_error *err);
sy_code sy_lsystem_load(const char *path, sy_lsystem *ls, sy_error *err);

typedef struct {
    float pos[3], dir[3]; /* patch frame */
    float thickness;      /* radius of the patch that would dock there, metres */
    int32_t node;         /* the patch node it hangs from */
} sy_dock;

typedef struct {
    float thickness;      /* root radius, metres */
    float dir[3];         /* root direction, azimuth 0 */
    float elevation;      /* angle of dir above the horizontal, radians */
    double elevation_cos, elevation_sin; /* of elevation, for eq. 3.3 at every dock */
    size_t n_nodes;
    float *pos;           /* 3 n_nodes, root at the origin (the root itself is not a node) */
    float *radius;        /* n_nodes, never above thickness, never increasing along a stem */
    int32_t *parent;      /* n_nodes: -1 = hangs from the root, else an earlier node */
    uint8_t *starts_branch; /* n_nodes: 1 = first node of a side stem (or the patch's first) */
    size_t n_docks;
    sy_dock *docks;
    size_t n_leaves;      /* in the stored random order */
    float *leaf_pos;      /* 3 n_leaves */
    float *leaf_dir;      /* 3 n_leaves, unit, base -> tip */
    float *leaf_normal;   /* 3 n_leaves, unit, perpendicular to dir */
    int32_t *leaf_node;   /* n_leaves */
    float extent;         /* largest distance of a node or leaf from the root */
} sy_patch;

typedef struct {
    size_t n_branchlets;  /* complete branchlets grown */
    size_t n_patches;
    sy_patch *patches;    /* complete branchlets' root patches and their sub-patches */
    size_t n_docks, n_leaves;
} sy_branchlets;

/* Grows ls->count branchlets from seed and partitions them into patches. */
sy_code sy_branchlets_generate(const sy_lsystem *ls, uint64_t seed, sy_branchlets *out, sy_error *err);
void sy_branchlets_free(sy_branchlets *b);

/* splitmix64 (Steele et al. 2014): tiny, seedable, identical on every platform. */
uint64_t sy_synth_rand(uint64_t *state);
/* Uniform in [0, 1). */
double sy_synth_uniform(uint64_t *state);

#endif
