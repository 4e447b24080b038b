/* The shared tail of every command that ends in a .glb (grow, run, mesh):
 * skeleton + leaves + species -> materials -> mesh (LOD chain, impostor, wind)
 * -> glTF export. */
#ifndef SYLVA_TREE_ASSET_H
#define SYLVA_TREE_ASSET_H

#include <stdint.h>

#include "stages/clusters/clusters.h"
#include "stages/core/asset.h"
#include "stages/core/skeleton.h"
#include "stages/grow/grow.h"

typedef struct {
    int lods;          /* mesh levels before the impostor (default 4) */
    int impostor;      /* 1: add the impostor level */
    int impostor_size; /* pixels */
    int meshopt;       /* EXT_meshopt_compression */
    int instancing;    /* EXT_mesh_gpu_instancing (0 bakes leaves) */
    int texture_size;  /* longest side of material textures */
    uint64_t seed;
    /* Reconstructed trees: the cluster hulls (same frame as the skeleton),
     * drawn as one semi-transparent "foliage_proxy" mesh in every mesh level
     * and the impostor. NULL (the default) or no triangles: none. */
    const sy_clusters *hulls;
} sy_tree_asset_options;

sy_tree_asset_options sy_tree_asset_options_default(void);

/* What was written, for reports. */
typedef struct {
    size_t nodes, branches, leaves;
    size_t lods;
    size_t triangles[16];   /* per LOD: mesh triangles + 2 per leaf card instance */
    size_t hull_triangles;  /* foliage proxy triangles (in every mesh level) */
    size_t leaf_cards[16];
    size_t bytes;
    double seconds_mesh, seconds_export;
} sy_tree_asset_report;

/* species may be NULL: default materials and leaf cards. extras_json (may be
 * NULL) is merged into asset.extras next to the species name. */
sy_code sy_tree_asset_build(const sy_skeleton *skel, const sy_leaves *leaves, const sy_species *species,
                            const sy_tree_asset_options *opt, sy_asset *out, sy_tree_asset_report *rep,
                            sy_error *err);

/* Builds and writes path (.glb) atomically. */
sy_code sy_tree_asset_write(const char *path, const sy_skeleton *skel, const sy_leaves *leaves,
                            const sy_species *species, const sy_tree_asset_options *opt, sy_tree_asset_report *rep,
                            sy_error *err);

/* Prints the report as text (stderr) or flat JSON keys into an open object. */
void sy_tree_asset_report_text(const sy_tree_asset_report *rep, const char *path);

#endif
