/* libFuzzer target: COLMAP points3D contents. The first byte picks the kind
 * (even: points3D.txt, odd: points3D.bin); the rest is the file. */
#include <stddef.h>
#include <stdint.h>

#include "stages/ingest/ingest.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size == 0) return 0;
    int kind = data[0] & 1 ? 'b' : 't';
    sy_cloud c;
    sy_error err;
    if (sy_read_colmap_points_mem("fuzz_points3D", data + 1, size - 1, kind, &c, &err) == SY_OK) sy_cloud_free(&c);
    return 0;
}
