/* Asset: what export writes and the viewer shows. Meshes, materials, images,
 * instanced leaves, LOD levels and wind data, in glTF's frame: Y up, metres,
 * counter-clockwise front faces. The asset owns every array (sy_asset_free). */
#ifndef SYLVA_ASSET_H
#define SYLVA_ASSET_H

#include <stddef.h>
#include <stdint.h>

#include "status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    char name[48];
    size_t n_vertices;
    float *position;    /* 3n */
    float *normal;      /* 3n, unit */
    float *tangent;     /* 4n (xyz unit, w = ±1 handedness) or NULL */
    float *uv;          /* 2n or NULL */
    /* Wind (Habel 2009 ch. 4, docs/wind.md): per vertex the index of its branch
     * in sy_asset.wind and w = normalized positions x in [0,1] along its own
     * branch (w[level]) and the attachment positions on each ancestor
     * (w[0..level-1]); unused levels are 0. NULL when the mesh does not sway. */
    float *wind_w;         /* 4n or NULL */
    uint16_t *wind_branch; /* n or NULL */
    size_t n_indices;
    uint32_t *indices;  /* triangles */
    int material;       /* index into sy_asset.materials */
} sy_mesh;

typedef enum { SY_ALPHA_OPAQUE = 0, SY_ALPHA_MASK = 1, SY_ALPHA_BLEND = 2 } sy_alpha_mode;

typedef struct {
    unsigned char *png; /* encoded PNG bytes */
    size_t size;
    char name[48];
} sy_image;

typedef struct {
    char name[48];
    float base_color[4];
    float metallic, roughness;
    int base_color_image; /* index into sy_asset.images, -1 none */
    int normal_image;     /* -1 none */
    sy_alpha_mode alpha_mode;
    float alpha_cutoff;
    int double_sided;
    /* KHR_materials_diffuse_transmission; factor 0 means the extension is omitted. */
    float diffuse_transmission;
    float diffuse_transmission_color[3];
    int diffuse_transmission_image; /* RGB colour, A factor (both slots), -1 none */
    /* KHR_materials_volume: thickness in mesh units (leaf cards: one leaf
     * length), green channel of thickness_image; factor 0 omits it. */
    float thickness_factor;
    int thickness_image; /* -1 none */
    /* SYLVA_leaf_translucency (docs/leafmaps.md "HL2 maps"): the Half-Life 2
     * coefficient maps for light arriving on the adaxial [0] and abaxial [1]
     * side, decoded as h = hl2_min + texel * (hl2_max - hl2_min); -1 none. */
    int hl2_image[2];
    float hl2_min, hl2_max;
    float hl2_transmit[2]; /* mean L_t^D at normal incidence per lit side */
    /* emissiveFactor (linear RGB, 0 = omitted): a leaf's fallback for the
     * light it would pass in engines without diffuse transmission. */
    float emissive[3];
} sy_material;

/* Copies of one mesh (leaf cards): TRS per instance, rotation as (x,y,z,w). */
typedef struct {
    int mesh;
    size_t n;
    float *translation; /* 3n */
    float *rotation;    /* 4n */
    float *scale;       /* 3n */
    /* Wind of each copy (docs/wind.md), as sy_mesh.wind_branch / wind_w at
     * the point where the copy hangs on its branch; NULL when it does not sway. */
    uint16_t *wind_branch; /* n or NULL */
    float *wind_w;         /* 4n or NULL */
} sy_instances;

#define SY_LOD_MAX_PARTS 8
/* One level of detail. Level 0 is full detail; each further level is coarser.
 * screen_coverage: the MSFT_lod hint, the share of screen height at or above
 * which this level is used. */
typedef struct {
    float screen_coverage;
    int n_meshes;
    int meshes[SY_LOD_MAX_PARTS];
    int n_instances;
    sy_instances instances[SY_LOD_MAX_PARTS];
} sy_lod;

/* Per-branch wind data (Habel 2009 Table 4.2): the branch's anchor on its
 * parent, its axis frame, length, beam polynomial u(x) = c2 x^2 + c4 x^4, its
 * natural frequency f_h = 2.55 L^-0.59 Hz, and stiffness in [0,1]. */
typedef struct {
    int32_t parent; /* index in sy_asset.wind, -1 for the trunk */
    int level;      /* hierarchy level, 0 = trunk */
    float anchor[3];
    float axis[3];  /* t: unit direction base->tip */
    float length;
    float c2, c4;
    float frequency;
    float stiffness;
} sy_wind_branch;

typedef struct {
    char name[64];
    sy_mesh *meshes;
    size_t n_meshes;
    sy_material *materials;
    size_t n_materials;
    sy_image *images;
    size_t n_images;
    sy_lod *lods;
    size_t n_lods;
    sy_wind_branch *wind;
    size_t n_wind;
    char *extras_json; /* a JSON object for asset.extras (species, parameters), owned, or NULL */
} sy_asset;

void sy_asset_free(sy_asset *a);
void sy_mesh_free(sy_mesh *m);
void sy_instances_free(sy_instances *in);

/* Appends and returns the index (or -1, err set). The asset takes ownership
 * of the arrays inside the passed struct (which is copied shallowly). */
int sy_asset_add_mesh(sy_asset *a, const sy_mesh *m, sy_error *err);
int sy_asset_add_material(sy_asset *a, const sy_material *m, sy_error *err);
int sy_asset_add_image(sy_asset *a, const sy_image *img, sy_error *err);
int sy_asset_add_lod(sy_asset *a, const sy_lod *lod, sy_error *err);

/* A material with sensible defaults: white, roughness 0.8, no textures, opaque. */
sy_material sy_material_default(const char *name);

#ifdef __cplusplus
}
#endif

#endif
