/* The materials cache (material_cache.c): sy_materials_add's images and
 * materials stored once per key, read back by the trees after the first. */
#ifndef SYLVA_SPECIES_MATERIAL_CACHE_H
#define SYLVA_SPECIES_MATERIAL_CACHE_H

#include <stddef.h>
#include <stdint.h>

#include "species/materials.h"

/* The key of what sy_materials_add makes of spec (at max_size, with the
 * resolved translucency); 0 when a named file cannot be read (no caching). */
int sy_material_cache_key(const sy_material_spec *spec, int max_size, float translucency, uint64_t *key);
/* Appends the entry's images and materials to asset and sets bark and leaf:
 * 1. 0 when there is no intact entry (asset unchanged). */
int sy_material_cache_load(const char *dir, uint64_t key, sy_asset *asset, int *bark, int *leaf);
/* Stores the images from img0 and materials from mat0 of asset under key
 * (dir is created; any failure just leaves no entry), and removes entries
 * not used for 30 days. */
void sy_material_cache_store(const char *dir, uint64_t key, const sy_asset *asset, size_t img0, size_t mat0,
                             int bark, int leaf);

#endif
