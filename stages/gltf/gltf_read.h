/* The one glTF reader: what tests check in an exported .glb, what eval
 * scores and what the viewer draws. Three views of a file: its JSON and BIN
 * chunks with values at JSON pointers (sy_gltf_open), its triangles in
 * Sylva's Z-up world frame (sy_gltf_read_triangles), and the whole scene in
 * glTF's frame for drawing (sy_gltf_read_scene). Production export
 * (stages/export) writes glTF and never reads it back. */
#ifndef SYLVA_GLTF_READ_H
#define SYLVA_GLTF_READ_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A GLB's JSON chunk (parsed) and BIN chunk. */
typedef struct sy_gltf_file sy_gltf_file;
sy_code sy_gltf_open(const char *path, sy_gltf_file **out, sy_error *err);
void sy_gltf_close(sy_gltf_file *f);
/* Values at an RFC 6901 JSON pointer ("/materials/1/alphaMode"). */
int sy_gltf_has(const sy_gltf_file *f, const char *pointer);
double sy_gltf_number(const sy_gltf_file *f, const char *pointer, double fallback);
/* Copies the string into buf ("" when absent or not a string); returns buf. */
const char *sy_gltf_string(const sy_gltf_file *f, const char *pointer, char *buf, size_t size);
/* Length of the array or object at pointer, -1 when absent or a scalar. */
int sy_gltf_size(const sy_gltf_file *f, const char *pointer);
/* The index-th key of the object at pointer (in the JSON's key order), ""
 * when absent; returns buf. */
const char *sy_gltf_key(const sy_gltf_file *f, const char *pointer, int index, char *buf, size_t size);
/* The BIN chunk (buffer 0). */
const unsigned char *sy_gltf_bin(const sy_gltf_file *f, size_t *size);
/* SY_OK if tinygltf itself loads the file without errors or warnings, else
 * SY_EINPUT with tinygltf's complaint (files whose only buffer is the BIN
 * chunk; a meshopt fallback buffer has no data to load). */
sy_code sy_gltf_tinygltf_check(const char *path, sy_error *err);

/* Reads every triangle of the default scene (or of scene 0, or of all root
 * nodes when the file names no scene): node transforms and
 * EXT_mesh_gpu_instancing instance transforms applied, then glTF's Y-up
 * turned into Sylva's Z-up: (x, y, z) -> (x, -z, y), then moved by
 * asset.extras.origin [x, y, z] (Z-up world, as `sylva mesh` writes it)
 * when the file has one. *tri gets 9 doubles per
 * triangle (malloc'd); *hull one entry per triangle (malloc'd): 0, or k >= 1
 * when the triangle belongs to the k-th closed hull, a connected part of a
 * mesh named "foliage_proxy" (Sylva's cluster hulls, each closed and facing
 * outward; one hull per part and instance). SY_EINPUT (not a readable
 * glTF) or SY_EINTERNAL (out of memory) with a one-line message naming path. */
sy_code sy_gltf_read_triangles(const char *path, double **tri, size_t *n_tri, size_t **hull, sy_error *err);

/* Where alpha-tested triangles are drawn. A renderer discards the texels of
 * an alphaMode MASK material whose alpha (baseColorFactor's times the
 * baseColorTexture's) falls below alphaCutoff: a leaf card is a quad of
 * which the leaves are a fraction (the shipped aspen card: 14 %). Per
 * triangle, its corners' TEXCOORD_0 and the alpha map it is tested
 * against; opaque and blended triangles are drawn whole. */
typedef struct {
    int w, h;
    float cutoff;         /* drawn where alpha >= cutoff (0..1) */
    unsigned char *alpha; /* w * h, row 0 at v = 0; 8-bit */
} sy_gltf_alpha_map;

typedef struct {
    float *uv;       /* 6 per triangle (its corners' u v), or NULL when no triangle is tested */
    int32_t *map;    /* per triangle: index into maps, -1: drawn whole; NULL likewise */
    size_t n_maps;
    sy_gltf_alpha_map *maps;
} sy_gltf_cutout;

/* The surface a viewer draws of the default scene (LOD0: MSFT_lod's other
 * levels hang off their nodes' extension, not the scene): the triangles of
 * sy_gltf_read_triangles without the foliage proxy, and with cut non-NULL
 * their cut-out (images decoded). Triangles as sy_gltf_read_triangles. */
sy_code sy_gltf_read_surface(const char *path, double **tri, size_t *n_tri, sy_gltf_cutout *cut, sy_error *err);
void sy_gltf_cutout_free(sy_gltf_cutout *c);

/* Is triangle t of cut drawn at the point with barycentric weights w[3] of
 * its corners? Nearest texel, coordinates wrapped (REPEAT). */
int sy_gltf_cutout_drawn(const sy_gltf_cutout *cut, size_t t, const double w[3]);

/* The whole scene, for drawing it (the GL preview): meshes with every
 * attribute a renderer needs, materials, decoded images, node transforms,
 * EXT_mesh_gpu_instancing copies, MSFT_lod levels with their
 * MSFT_screencoverage, Sylva's wind data (docs/wind.md) and
 * asset.extras.origin. Everything stays in glTF's frame (Y up, metres). */
#define SY_GLTF_MAX_LODS 16

typedef struct {
    size_t n_vertices;
    float *position;             /* 3n */
    float *normal;               /* 3n or NULL */
    float *tangent;              /* 4n or NULL */
    float *uv;                   /* 2n (TEXCOORD_0) or NULL */
    float *color;                /* 4n (COLOR_0, RGB gets alpha 1) or NULL */
    float *wind_w;               /* 4n (_WIND_W) or NULL */
    float *wind_branch;          /* n (_WIND_BRANCH, exact integers) or NULL */
    float *wind_anchor;          /* 3n (_WIND_ANCHOR) or NULL */
    float *wind_level_stiffness; /* 2n (_WIND_LEVEL_STIFFNESS) or NULL */
    size_t n_indices;
    uint32_t *indices;           /* triangle list; strips and fans are unrolled */
    int material;                /* index into materials, -1: the glTF default material */
} sy_gltf_primitive;

typedef struct {
    char name[64];
    int first_primitive, n_primitives; /* range in sy_gltf_scene.primitives */
} sy_gltf_mesh;

typedef struct {
    int width, height;
    int bits;             /* 8 or 16 per channel */
    unsigned char *pixels; /* width*height RGBA, 4 or 8 bytes per texel (16-bit native endian) */
} sy_gltf_image;

typedef struct {
    int image;                    /* index into images */
    int wrap_s, wrap_t;           /* GL enums (REPEAT 10497, CLAMP_TO_EDGE 33071, MIRRORED 33648) */
    int min_filter, mag_filter;   /* GL enums, -1 unspecified */
} sy_gltf_texture;

typedef enum { SY_GLTF_OPAQUE = 0, SY_GLTF_MASK = 1, SY_GLTF_BLEND = 2 } sy_gltf_alpha;

typedef struct {
    char name[64];
    float base_color[4];
    int base_color_texture;          /* index into textures, -1 none (as every *_texture) */
    float metallic, roughness;
    int metallic_roughness_texture;  /* G roughness, B metallic */
    int normal_texture;
    float normal_scale;
    float emissive[3];
    sy_gltf_alpha alpha_mode;
    float alpha_cutoff;
    int double_sided;
    /* KHR_materials_diffuse_transmission (factor 0 when absent). */
    float diffuse_transmission;
    float diffuse_transmission_color[3];
    int diffuse_transmission_texture;       /* A channel */
    int diffuse_transmission_color_texture; /* RGB */
    /* Half-Life 2 translucency (Habel 2009 §3.3.8-3.3.9) from the material extension
     * SYLVA_leaf_translucency (docs/leafmaps.md): RGB = h1 h2 h3 for light arriving on the
     * adaxial (normal) side / the abaxial side, decoded as min + texel (max - min). -1 absent. */
    int hl2_adaxial_texture, hl2_abaxial_texture;
    float hl2_min, hl2_max;
} sy_gltf_material;

/* One node that has a mesh, flattened: its world transform and its copies. */
typedef struct {
    int mesh;
    int object, level;          /* the root object and the LOD level it belongs to */
    double world[16];           /* column-major node-to-world matrix */
    size_t n_instances;         /* 0: no EXT_mesh_gpu_instancing, the node is drawn once */
    float *instance_matrix;     /* 16n column-major, instance-to-node, or NULL */
    float *inst_wind_w;         /* 4n (_WIND_W per instance) or NULL */
    float *inst_wind_branch;    /* n or NULL */
    float *inst_wind_anchor;    /* 3n or NULL */
    float *inst_wind_level_stiffness; /* 2n or NULL */
} sy_gltf_draw;

/* Sylva's per-branch wind table (extras.sylva_wind, docs/gltf.md). */
typedef struct {
    int parent, level;
    float anchor[3], axis[3];
    float length, c2, c4, frequency, stiffness;
} sy_gltf_wind_branch;

/* A root node of the scene: one tree, with its levels of detail. */
typedef struct {
    char name[64];
    int n_levels;                          /* 1 without MSFT_lod */
    float coverage[SY_GLTF_MAX_LODS];      /* MSFT_screencoverage per level, -1 when not given */
    double bounds_min[3], bounds_max[3];   /* LOD0 in world (glTF frame), instances included */
    size_t n_triangles[SY_GLTF_MAX_LODS];  /* per level, instances counted */
    size_t n_wind;
    sy_gltf_wind_branch *wind;             /* NULL when the object has no table */
} sy_gltf_object;

typedef struct {
    sy_gltf_primitive *primitives; size_t n_primitives;
    sy_gltf_mesh *meshes; size_t n_meshes;
    sy_gltf_material *materials; size_t n_materials;
    sy_gltf_texture *textures; size_t n_textures;
    sy_gltf_image *images; size_t n_images;
    sy_gltf_draw *draws; size_t n_draws;
    sy_gltf_object *objects; size_t n_objects;
    int has_origin;
    double origin[3]; /* asset.extras.origin: world position of the glTF origin, Z-up survey frame */
} sy_gltf_scene;

/* Reads a .glb or .gltf for drawing. SY_EINPUT (one-line reason naming the
 * file) on an unreadable file, a broken reference or accessor, an image that
 * does not decode or is missing, a scene with no triangle mesh, or a malformed
 * sylva_wind table; SY_EINTERNAL on out of memory. EXT_meshopt_compression
 * views are decoded. On success the caller owns *out (sy_gltf_scene_free). */
sy_code sy_gltf_read_scene(const char *path, sy_gltf_scene *out, sy_error *err);
void sy_gltf_scene_free(sy_gltf_scene *s);


#ifdef __cplusplus
}
#endif

#endif
