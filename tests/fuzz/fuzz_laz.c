/* libFuzzer target: the LAZ decoder. An input starting with "LASF" is a
 * whole file, read as a cloud and transcoded to LAS; anything else is one
 * raw chunk for the chunk decoder, its first byte picking the point format
 * (0-3, 6-8) and extra bytes, its second the point count, so mutations reach
 * the arithmetic decoder without first having to forge a chunk table.
 * Either way: a code back, never a crash, a hang or a read outside the input. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "stages/ingest/ingest.h"
#include "stages/ingest/laz_items.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static void one_chunk(const uint8_t *data, size_t size)
{
    static const int formats[7] = {0, 1, 2, 3, 6, 7, 8};
    static const unsigned core[9] = {20, 28, 26, 34, 0, 0, 30, 36, 38};
    if (size < 2) return;
    int format = formats[(data[0] & 0x7) % 7];
    unsigned extra = data[0] >> 5;
    uint32_t n = 1 + (uint32_t)data[1] * 8;
    laz_layout L = {format, core[format] + extra, extra, format >= 6, 50000};
    unsigned char *out = malloc((size_t)n * L.record_length);
    if (!out) return;
    const char *why = "";
    laz_decode_chunk(&L, data + 2, size - 2, n, out, &why);
    free(out);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size >= 4 && memcmp(data, "LASF", 4) == 0) {
        sy_cloud c;
        sy_error err = {0};
        if (sy_read_las_mem("fuzz.laz", data, size, &c, &err) == SY_OK) sy_cloud_free(&c);
        sy_buffer las;
        if (sy_laz_decompress_mem("fuzz.laz", data, size, &las, &err) == SY_OK) free(las.data);
        return 0;
    }
    one_chunk(data, size);
    return 0;
}
