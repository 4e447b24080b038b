/* Species materials: bark (baseColor + normal map derived from the bark photo)
 * and leaf (baseColor with alpha MASK, normal map, diffuse transmission) from
 * the texture files a species names. Images are decoded, resized to a
 * game-friendly power of two and stored as PNG bytes in the asset. */
#ifndef SYLVA_SPECIES_MATERIALS_H
#define SYLVA_SPECIES_MATERIALS_H

#include "stages/core/asset.h"

typedef struct {
    const char *bark_image;  /* path or NULL for a neutral procedural bark */
    const char *leaf_image;  /* RGBA leaf/twig card or NULL for a plain green card */
    float leaf_translucency; /* diffuse transmission factor 0..1 (default 0.4) */
    int max_size;            /* longest side after resizing (default 512) */
    /* A leaf material made by `sylva leaf` (its leaf.material) or NULL: when
     * given it replaces leaf_image and leaf_translucency (docs/leafmaps.md). */
    const char *leaf_maps;
    float leaf_length_m;     /* card length, the unit of the volume thickness (default 0.1) */
} sy_material_spec;

/* SYLVA_SPECIES_DIR/leafmaps/<species_name>/leaf.material into buf when that
 * file exists; returns buf or NULL. */
const char *sy_species_leaf_maps(const char *species_name, char *buf, size_t size);

/* Adds the bark and leaf materials (and their images) to the asset. */
sy_code sy_species_materials(const sy_material_spec *spec, sy_asset *asset, int *bark_material,
                             int *leaf_material, sy_error *err);

#endif
