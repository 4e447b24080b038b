/* libFuzzer target: the LAS reader over arbitrary bytes must return a code,
 * never crash, hang or allocate from an unchecked header count. */
#include <stddef.h>
#include <stdint.h>

#include "stages/ingest/ingest.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    sy_cloud c;
    sy_error err = {0};
    sy_read_las_mem("fuzz.las", data, size, &c, &err);
    sy_cloud_free(&c);
    return 0;
}
