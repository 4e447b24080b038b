/* Species materials: bark (baseColor + normal map derived from the bark photo)
 * and leaf (baseColor with alpha MASK, normal map, diffuse transmission) from
 * the texture files a species names. Images are decoded, resized to a
 * game-friendly power of two and stored as PNG bytes in the asset. */
#ifndef SYLVA_SPECIES_MATERIALS_H
#define SYLVA_SPECIES_MATERIALS_H

#include "stages/core/asset.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    const char *bark_image;  /* path or NULL for a neutral procedural bark */
    const char *leaf_image;  /* RGBA leaf/twig card or NULL for a plain green card */
    float leaf_translucency; /* diffuse transmission factor 0..1 (default 0.4) */
    int max_size;            /* longest side after resizing (default 512) */
    /* A leaf material made by `sylva leaf` (its leaf.material) or NULL: when
     * given it replaces leaf_image and leaf_translucency (docs/leafmaps.md). */
    const char *leaf_maps;
    float leaf_length_m;     /* card length, the unit of the volume thickness (default 0.1) */
    /* A folder for the materials cache (material_cache.c: the encoded images
     * of this spec, read back by later trees instead of made again), or NULL. */
    const char *cache_dir;
    /* The bark's colour, sRGB 0..255, or NULL for the photo's own: the photo
     * is recoloured so its mean is this colour and each texel keeps its
     * brightness relative to the mean (the pattern, and the normal map,
     * stay the photo's). One bark photo serves the library; a birch is
     * white and a Scots pine's upper bark orange. */
    const float *bark_color;
} sy_material_spec;

/* The absolute path of the library species' leaf material (its manifest's
 * files column names leafmaps/<name>/leaf.material) into buf; NULL when the
 * species is not in the library, has no leaf maps or there is no library. */
const char *sy_species_leaf_maps(const char *species_name, char *buf, size_t size);

/* Adds the bark and leaf materials (and their images) to the asset. */
sy_code sy_materials_add(const sy_material_spec *spec, sy_asset *asset, int *bark_material,
                             int *leaf_material, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
