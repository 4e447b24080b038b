/* libFuzzer target: arbitrary bytes as the glb/glTF model of `sylva eval`
 * (tinygltf, then Sylva's accessor, index, node, instancing and coordinate
 * checks). The first byte picks the container: even as a .glb, odd as a
 * .gltf (JSON). Every triangle returned must be finite. The drawn surface
 * (images decoded, alpha maps built) is read too, and every triangle's
 * alpha test is asked at its corners and centre. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include "fuzz_util.h"
#include "stages/gltf/gltf_read.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    const char *path = fuzz_file(data[0] & 1 ? "gltf" : "glb", data + 1, size - 1);
    double *tri;
    size_t n, *hull;
    sy_error err = {0};
    if (sy_gltf_read_triangles(path, &tri, &n, &hull, &err) == SY_OK) {
        for (size_t i = 0; i < 9 * n; i++)
            if (!isfinite(tri[i])) abort();
        free(tri);
        free(hull);
    }
    sy_gltf_cutout cut;
    if (sy_gltf_read_surface(path, &tri, &n, &cut, &err) == SY_OK) {
        static const double w[4][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1 / 3.0, 1 / 3.0, 1 / 3.0}};
        for (size_t t = 0; t < n; t++)
            for (int k = 0; k < 4; k++) (void)sy_gltf_cutout_drawn(&cut, t, w[k]);
        sy_gltf_cutout_free(&cut);
        free(tri);
    }
    return 0;
}
