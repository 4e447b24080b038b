/* The shared tail of every command that ends in a .glb (grow, run, mesh):
 * skeleton + leaves + species -> materials -> mesh (LOD chain, impostor, wind)
 * -> glTF export. */
#ifndef SYLVA_TREE_ASSET_H
#define SYLVA_TREE_ASSET_H

#include <stdint.h>

#include "pipeline/cli.h"
#include "stages/clusters/clusters.h"
#include "stages/core/asset.h"
#include "stages/core/json.h"
#include "stages/core/skeleton.h"
#include "stages/eval/eval.h"
#include "stages/grow/grow.h"
#include "stages/mesh/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int lods;          /* mesh levels before the impostor (default 4) */
    int impostor;      /* 1: add the impostor level */
    int impostor_size; /* pixels */
    int meshopt;       /* EXT_meshopt_compression */
    int instancing;    /* EXT_mesh_gpu_instancing (0 bakes leaves) */
    int texture_size;  /* longest side of material textures */
    uint64_t seed;
    int keep_leaf_order; /* 1: the leaves' order is their pruning order (synthesised trees) */
    /* Reconstructed trees: the cluster hulls (same frame as the skeleton),
     * drawn as one semi-transparent "foliage_proxy" mesh in every mesh level
     * and the impostor. NULL (the default) or no triangles: none. */
    const sy_clusters *hulls;
    /* Branches thinner than this are drawn lean (sy_mesh_options.lean_radius):
     * SY_MESH_LEAN_RADIUS for a tree with traced twigs
     * (sy_decoded_tree.lean_radius), 0 (the default) otherwise. */
    float lean_radius;
    /* Models from files (mesh, run): asset.extras gets "origin", the
     * skeleton's origin (the world position, Z up, of the glb's (0,0,0);
     * world = origin + (x, -z, y) of a vertex, which `sylva eval` applies),
     * "source" (source's file name; directories stay private) and
     * "source_format". NULL (the default): none of them (grown trees). */
    const char *source, *source_format;
    /* 1: measure the asset (sy_mesh_check: sails, slivers, welding, leaf
     * gaps, ground, LOD ratios) into the report (--check). */
    int check;
    /* The materials cache folder (species/material_cache.c: a species'
     * encoded textures, made once and embedded as they are by later trees),
     * or NULL (the default): every tree makes its own. Never changes bytes. */
    const char *texture_cache;
} sy_tree_asset_options;

sy_tree_asset_options sy_tree_asset_options_default(void);

/* Moves the root to (0,0,0) and hulls (may be NULL) with it, the origin
 * taking the root's world position: a tree from a survey frame comes out
 * standing at the glb's origin, and world = origin + pos keeps holding. */
void sy_tree_asset_root_to_origin(sy_skeleton *s, sy_clusters *hulls);

sy_code sy_tree_asset_options_check(const sy_tree_asset_options *o, sy_error *err);

/* The .glb output flags grow, mesh and run share: a sy_glb_args member of a
 * command's per-call argument struct, SY_GLB_OPTIONS(that member) in its
 * option table, sy_glb_args_default() before parsing and sy_glb_args_apply()
 * after it (copies them into o, which the command then checks with
 * sy_tree_asset_options_check). */
typedef struct {
    int lods, impostor_size, meshopt, no_instancing, no_impostor, check;
    /* The user's materials cache: $SYLVA_CACHE_DIR (empty: none), else
     * $XDG_CACHE_HOME/sylva, else $HOME/.cache/sylva; "" when none. */
    char texture_cache[4096];
} sy_glb_args;
#define SY_GLB_OPTIONS(g)                                                                                      \
    {"--lods", OPT_INT, &(g).lods, "N", "mesh levels of detail before the impostor (default 4)"},              \
    {"--impostor-size", OPT_INT, &(g).impostor_size, "PX", "impostor texture size (default 512)"},             \
    {"--no-impostor", OPT_FLAG, &(g).no_impostor, NULL, "no billboard level"},                                  \
    {"--meshopt", OPT_FLAG, &(g).meshopt, NULL, "compress with EXT_meshopt_compression"},                      \
    {"--no-instancing", OPT_FLAG, &(g).no_instancing, NULL,                                                    \
     "bake leaf instances into meshes (engines without EXT_mesh_gpu_instancing)"},                            \
    {"--check", OPT_FLAG, &(g).check, NULL,                                                                    \
     "measure the mesh (sails, slivers, welding, leaf gaps, ground, LOD ratios; docs/mesh.md) into the report"}
sy_glb_args sy_glb_args_default(void);
void sy_glb_args_apply(const sy_glb_args *g, sy_tree_asset_options *o);

/* What was written, for reports. */
typedef struct {
    size_t nodes, branches, leaves;
    size_t lods;
    size_t triangles[16];   /* per LOD: mesh triangles + card triangles x leaf instances */
    size_t bark_triangles[16]; /* per LOD: the bark (and proxy) meshes' triangles alone */
    size_t hull_triangles;  /* foliage proxy triangles (in every mesh level) */
    size_t leaf_cards[16];
    size_t bytes;
    double seconds_mesh, seconds_export;
    sy_mesh_weld_stats welds;   /* per mesh level: junctions drawn and welded (the rest capped) */
    int checked;                /* opt->check was set: check holds the figures */
    sy_mesh_check_report check;
} sy_tree_asset_report;

/* species may be NULL: default materials and leaf cards. extras_json (may be
 * NULL) is merged into asset.extras next to the species name. */
sy_code sy_tree_asset_build(const sy_skeleton *skel, const sy_leaves *leaves, const sy_species_params *species,
                            const sy_tree_asset_options *opt, sy_asset *out, sy_tree_asset_report *rep,
                            sy_error *err);

/* Builds and exports: *glb (malloc'd, the caller frees) and *size; name
 * names the output in messages. rep->bytes gets the size. */
sy_code sy_tree_asset_glb(const sy_skeleton *skel, const sy_leaves *leaves, const sy_species_params *species,
                          const sy_tree_asset_options *opt, const char *name, unsigned char **glb, size_t *size,
                          sy_tree_asset_report *rep, sy_error *err);

/* sy_tree_asset_glb, then writes path (.glb) atomically. */
sy_code sy_tree_asset_write(const char *path, const sy_skeleton *skel, const sy_leaves *leaves,
                            const sy_species_params *species, const sy_tree_asset_options *opt, sy_tree_asset_report *rep,
                            sy_error *err);

/* Prints the report as text (stderr). */
void sy_tree_asset_report_text(const sy_tree_asset_report *rep, const char *path);
/* The "lod_triangles" array (one count per level) into an open JSON object,
 * and "mesh_check" (one object per checked level) when the report has it. */
void sy_tree_asset_report_lods_json(sy_json *j, const sy_tree_asset_report *rep);

#ifdef __cplusplus
}
#endif

#endif
