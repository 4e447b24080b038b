/* The glTF document export.c assembles, in glTF's own terms (bufferViews,
 * accessors, nodes), and the thin tinygltf shim that serialises it to GLB
 * bytes. export.c decides everything; the shim only maps fields onto
 * tinygltf::Model, adds the JSON tinygltf 2.7 cannot express (buffer and
 * bufferView extensions) and reads GLB files back for tests. */
#ifndef SYLVA_GLTF_TINYGLTF_H
#define SYLVA_GLTF_TINYGLTF_H

#include <stddef.h>
#include <stdint.h>

/* The core headers carry no extern "C" of their own. */
#ifdef __cplusplus
extern "C" {
#endif

#include "stages/core/asset.h"

/* glTF enums used below (the spec's numbers). */
enum {
    SY_GLTF_UNSIGNED_SHORT = 5123,
    SY_GLTF_UNSIGNED_INT = 5125,
    SY_GLTF_FLOAT = 5126,
    SY_GLTF_ARRAY_BUFFER = 34962,
    SY_GLTF_ELEMENT_ARRAY_BUFFER = 34963
};

typedef enum { SY_MESHOPT_NONE = 0, SY_MESHOPT_ATTRIBUTES, SY_MESHOPT_TRIANGLES } sy_meshopt_mode;

typedef struct {
    int buffer;        /* 0 = the GLB binary chunk, 1 = the meshopt fallback buffer */
    size_t offset, length;
    int stride;        /* 0 = tightly packed / not vertex data */
    int target;        /* 0, SY_GLTF_ARRAY_BUFFER or SY_GLTF_ELEMENT_ARRAY_BUFFER */
    /* EXT_meshopt_compression: the compressed bytes in buffer 0. */
    sy_meshopt_mode meshopt;
    size_t meshopt_offset, meshopt_length, meshopt_count;
    int meshopt_stride;
} sy_gltf_view;

typedef struct {
    int view;
    int component_type; /* SY_GLTF_* */
    int components;     /* 1 SCALAR, 2 VEC2, 3 VEC3, 4 VEC4 */
    size_t count;
    int has_bounds;
    double min[4], max[4];
} sy_gltf_accessor;

typedef struct {
    char name[48];
    int position, normal, tangent, texcoord, wind_w, wind_branch; /* accessors, -1 absent */
    int wind_anchor, wind_level_stiffness;                      /* idem */
    int indices;
    int material;
} sy_gltf_mesh;

typedef struct {
    int image;
    int sampler; /* 0 = REPEAT (bark), 1 = CLAMP_TO_EDGE (cards, impostors) */
} sy_gltf_texture;

typedef struct {
    const sy_material *src;
    int base_color_texture, normal_texture, transmission_texture; /* -1 none */
} sy_gltf_material;

#define SY_GLTF_MAX_CHILDREN (2 * SY_LOD_MAX_PARTS)
typedef struct {
    char name[96];
    int mesh; /* -1 for a group node */
    int n_children;
    int children[SY_GLTF_MAX_CHILDREN];
    /* EXT_mesh_gpu_instancing accessors, -1 when the node is not instanced. */
    int inst_translation, inst_rotation, inst_scale;
    /* Per-instance wind (_WIND_W VEC4, _WIND_BRANCH SCALAR, _WIND_ANCHOR VEC3,
     * _WIND_LEVEL_STIFFNESS VEC2, all float), -1 none. */
    int inst_wind_w, inst_wind_branch, inst_wind_anchor, inst_wind_level_stiffness;
    /* MSFT_lod on the LOD0 node: ids of lower levels, coverage per level. */
    int n_lod_ids;
    int lod_ids[64];
    float coverage[65];
    int carries_wind; /* writes sy_gltf_doc.wind into this node's extras */
} sy_gltf_node;

typedef struct {
    unsigned char *bin; /* buffer 0: the GLB BIN chunk */
    size_t bin_size, bin_capacity;
    size_t fallback_size; /* byteLength of buffer 1; 0 = no fallback buffer */

    sy_gltf_view *views;
    size_t n_views, cap_views;
    sy_gltf_accessor *accessors;
    size_t n_accessors, cap_accessors;
    int *image_views; /* per asset image, its bufferView */
    char (*image_names)[48];
    size_t n_images;
    sy_gltf_texture *textures;
    size_t n_textures, cap_textures;
    sy_gltf_material *materials;
    size_t n_materials;
    sy_gltf_mesh *meshes;
    size_t n_meshes, cap_meshes;
    sy_gltf_node *nodes;
    size_t n_nodes, cap_nodes;
    int scene_root;

    int uses_instancing, uses_transmission, uses_lod, uses_meshopt;
    const sy_wind_branch *wind;
    size_t n_wind;
    const char *generator;
    const char *extras_json; /* may be NULL */
    const char *asset_name;
} sy_gltf_doc;

/* Serialises doc to GLB bytes (malloc'd, caller frees). path only names the
 * output in error messages. */
sy_code sy_gltf_write_glb(const sy_gltf_doc *doc, const char *path, unsigned char **out,
                          size_t *out_size, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
