/* libFuzzer target: the PCD reader over arbitrary bytes (all three DATA kinds
 * and the LZF decompressor are reached from the header the input carries). */
#include <stddef.h>
#include <stdint.h>

#include "stages/ingest/ingest.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sy_cloud c;
    sy_error err;
    if (sy_read_pcd_mem("fuzz.pcd", data, size, &c, &err) == SY_OK) sy_cloud_free(&c);
    return 0;
}
