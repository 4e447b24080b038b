/* libFuzzer target: arbitrary bytes through the XYZ reader. */
#include <stddef.h>
#include <stdint.h>

#include "stages/ingest/ingest.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sy_cloud c;
    sy_error err = {0};
    sy_read_xyz_mem("fuzz.xyz", data, size, &c, &err);
    sy_cloud_free(&c);
    return 0;
}
