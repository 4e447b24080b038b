/* Mesh: skeleton + leaf placements -> a game-ready Asset (branch meshes as
 * generalised cylinders, instanced leaf cards, LOD chain ending in a
 * billboard/impostor level, wind attributes). The same code serves generated
 * and reconstructed trees. Input is Z-up (Sylva's frame); the Asset is Y-up
 * (glTF's frame). Deterministic for a given seed. */
#ifndef SYLVA_MESH_H
#define SYLVA_MESH_H

#include <stdint.h>

#include "stages/core/asset.h"
#include "stages/core/skeleton.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Bark slivers (issue 19): a triangle under this area (m^2, 0.005 mm^2) is
 * invisible and wastes rasteriser work; one whose height is under this
 * share of its longest edge is a needle, whatever its area. The mesher
 * avoids both; the mesh check counts them. */
#define SY_MESH_SLIVER_AREA 5e-9
#define SY_MESH_NEEDLE_ASPECT 1e-3
/* A stem with children at its last node, none of them going on as it,
 * goes on past that node along its last chord by this many radii (the
 * thicker of its tip and its thickest such child), so their base rings land
 * on its quads and weld instead of standing on its tip cap (stems.c,
 * tip_stretch; the mesh check draws the same stretch,
 * stages/eval/mesh_check.c). The stretch counts in the stem's length (wind,
 * leaves' places along it); at a coarser level whose budget drops those
 * children it stays: the tube ends two radii past its last node. */
/* The lean radius (sy_mesh_options.lean_radius) of trees whose crowns are
 * the twigs their scan's returns trace (sy_clusters_trace_twigs), metres. */
#define SY_MESH_LEAN_RADIUS 0.02f
#define SY_MESH_TIP_EXTENSION 2.0f

/* Junctions per mesh level (optional output of sy_mesh_tree): children
 * whose base ring is drawn on their parent, and those of them welded into
 * the parent's bark (the rest are capped inside it). */
#define SY_MESH_MAX_LEVELS 16
typedef struct {
    size_t levels;
    size_t junctions[SY_MESH_MAX_LEVELS], welded[SY_MESH_MAX_LEVELS];
} sy_mesh_weld_stats;

typedef struct {
    int radial_segments;       /* ring vertices at LOD0 on the trunk (default 16); thinner
                                  branches use fewer, never below 3 */
    float segment_length;      /* target metres between rings along a branch at LOD0
                                  (default: adaptive to curvature and radius) */
    int lod0_max_triangles;    /* bark triangle budget of LOD0 (default 54,000 before welding, which adds
                                  its strips: LOD0 bark stays under 60k; 0 = none):
                                  the least important twigs (r^2 L) go first, as the
                                  twig leaf cards depict them */
    int lod0_max_leaves;       /* leaf instance budget of LOD0 (default 30,000; 0 = none): past it LOD0
                                  keeps a prefix of the seeded order, grown to the same total leaf
                                  area, as the coarser levels do */
    int n_lods;                /* mesh levels before the impostor (default 4); each halves
                                  rings and segments and drops thin branches */
    int impostor;              /* add the final cross-card impostor level (default 1) */
    int impostor_size;         /* impostor texture size in pixels (default 512) */
    float min_radius;          /* bark is drawn at least this thick, metres (default 1.5 mm):
                                  thinner twig tips would be sub-pixel slivers */
    float lean_radius;         /* branches thinner than this at their base are drawn lean, those under
                                  half of it with three sides (sy_stem_lean in mesh_internal.h),
                                  metres (default 0: none; SY_MESH_LEAN_RADIUS for traced twigs) */
    float leaf_aspect;         /* leaf card width / length (default 0.6) */
    int leaf_shape;            /* Weber-Penn leafShape, picks the card outline (default 0) */
    uint64_t seed;             /* leaf pruning order */
    int keep_leaf_order;       /* 1: the leaves' own order is the pruning order (synthesised
                                  patches store theirs); 0 (default): a seeded permutation */
    /* Materials to use (indices into the asset's materials, which the caller
     * adds first, e.g. with sy_materials_add); -1 gives plain defaults. */
    int bark_material;
    int leaf_material;
    sy_mesh_weld_stats *weld_stats; /* optional output, filled per mesh level (default NULL) */
} sy_mesh_options;

sy_mesh_options sy_mesh_options_default(void);
/* SY_EUSAGE naming the field when a value is out of range. */
sy_code sy_mesh_options_check(const sy_mesh_options *o, sy_error *err);

/* Builds the asset. leaves may be NULL or empty (leafless tree). */
sy_code sy_mesh_tree(const sy_skeleton *skel, const sy_leaves *leaves, const sy_mesh_options *opt, sy_asset *out,
                     sy_error *err);

/* Appends the impostor level: crossed cards textured with renders of level
 * lod0 (every mesh and instance it holds, whatever their materials). For
 * callers that add parts to the mesh levels after sy_mesh_tree (run with
 * impostor = 0) and want them in the billboard too. */
sy_code sy_mesh_add_impostor(sy_asset *a, size_t lod0, int size, sy_error *err);

/* Bounds (glTF frame) of everything level lod draws: meshes and instances. */
void sy_mesh_lod_bounds(const sy_asset *a, size_t lod, float lo[3], float hi[3]);

/* Coverage of level lod by the impostor's rasteriser (conservative: a pixel
 * a triangle touches counts; alpha-masked cards use their texture): seen
 * along -Z (front: x right) and along -X (side: -z right), y up, each over
 * the box lo..hi as size x size pixels, row 0 at the top; 1 = covered. */
sy_code sy_mesh_silhouettes(const sy_asset *a, size_t lod, const float lo[3], const float hi[3], int size,
                            uint8_t *front, uint8_t *side, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
