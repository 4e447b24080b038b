/* libFuzzer target: arbitrary bytes as a species' bark and leaf texture
 * (decode, size checks, resize, normal map, alpha, PNG re-encode) through
 * sy_materials_add, small textures so each input stays quick; and the same
 * bytes as a leaf map through the stb reader of the leaf-maps stage. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_util.h"
#include "species/materials.h"
#include "stages/leafmaps/leafmaps_cv.h"
#include "stages/core/asset.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    const char *path = fuzz_file("png", data, size);
    sy_material_spec spec = {.bark_image = path, .leaf_image = size & 1 ? path : NULL, .leaf_translucency = 0.4f,
                             .max_size = 32, .cache_dir = NULL};
    sy_asset a = {0};
    int bark, leaf;
    sy_error err = {0};
    sy_materials_add(&spec, &a, &bark, &leaf, &err);
    sy_asset_free(&a);
    float *px = NULL;
    int w, h, c, depth;
    if (sy_lcv_read(path, &px, &w, &h, &c, &depth, &err) == SY_OK) free(px);
    return 0;
}
