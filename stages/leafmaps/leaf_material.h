/* The leaf material's files (docs/leafmaps.md "Files"): the maps as PNG, the
 * `leaf.material` text that names them and records the physical scales, and
 * the atlas of several leaves; writing them to a folder, installing them in
 * the species library (leafmaps/NAME/), and reading a material back. */
#ifndef SYLVA_LEAF_MATERIAL_H
#define SYLVA_LEAF_MATERIAL_H

#include <stddef.h>

#include "stages/leafmaps/leafmaps.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SY_LEAF_MAX_FILES 24
#define SY_LEAF_MATERIAL_FILE "leaf.material"
/* HL2 coefficients in the 16-bit PNGs: value = (h - MIN) / (MAX - MIN). */
#define SY_LEAF_HL2_MIN (-1.0)
#define SY_LEAF_HL2_MAX 3.0

typedef struct {
    int n;
    char name[SY_LEAF_MAX_FILES][48];
    unsigned char *data[SY_LEAF_MAX_FILES];
    size_t size[SY_LEAF_MAX_FILES];
} sy_leaf_files;

void sy_leaf_files_free(sy_leaf_files *f);

/* Encodes the maps of leaf 0 and the atlas of all n leaves (sources: their
 * photo paths, for the record; file names only are written). */
sy_code sy_leaf_material_encode(const sy_leaf_maps *maps, int n, const char *const *sources,
                                const sy_leafmaps_options *o, sy_leaf_files *out, sy_error *err);

/* Writes every file into dir (created if missing), each atomically. */
sy_code sy_leaf_files_write(const sy_leaf_files *f, const char *dir, sy_error *err);
/* Replaces library/leafmaps/name/ as a whole: the files are written into a
 * temporary folder beside it that is renamed into place. */
sy_code sy_leaf_files_install(const sy_leaf_files *f, const char *library, const char *name, sy_error *err);

/* 1 if name is a plain species name (letters, digits, '_', '-'). */
int sy_leaf_material_valid_name(const char *name);

/* A leaf material read back: absolute paths of its maps ("" if absent) and
 * the scales the glTF needs. */
typedef struct {
    char albedo[4096], normal[4096], thickness[4096], translucency[4096], hl2[2][4096];
    double texel_mm, thickness_max_mm, transmit_normal[2];
    int size;
} sy_leaf_material;

/* Parses dir/leaf.material. Missing or malformed: SY_EINPUT, message names the file. */
sy_code sy_leaf_material_load(const char *path, sy_leaf_material *m, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
