#include "meshopt_codec.h"

#include <meshoptimizer.h>
#include <stdlib.h>

sy_code sy_meshopt_encode_attributes(const void *data, size_t count, size_t stride,
                                     unsigned char **out, size_t *out_size, sy_error *err)
{
    *out = NULL;
    *out_size = 0;
    if (stride == 0 || stride % 4 != 0 || stride > 256)
        return sy_fail(err, SY_EINTERNAL, "meshopt: attribute stride %zu is not a multiple of 4 up to 256", stride);
    size_t bound = meshopt_encodeVertexBufferBound(count, stride);
    unsigned char *buf = malloc(bound);
    if (!buf) return sy_fail(err, SY_EINTERNAL, "meshopt: out of memory (%zu bytes)", bound);
    /* Version 0 is the only attribute bitstream the extension defines. */
    meshopt_encodeVertexVersion(0);
    size_t n = meshopt_encodeVertexBuffer(buf, bound, data, count, stride);
    if (n == 0) {
        free(buf);
        return sy_fail(err, SY_EINTERNAL, "meshopt: vertex encoder failed (%zu x %zu bytes)", count, stride);
    }
    *out = buf;
    *out_size = n;
    return SY_OK;
}

sy_code sy_meshopt_encode_triangles(const uint32_t *indices, size_t count, size_t n_vertices,
                                    unsigned char **out, size_t *out_size, sy_error *err)
{
    *out = NULL;
    *out_size = 0;
    if (count % 3 != 0) return sy_fail(err, SY_EINTERNAL, "meshopt: %zu indices is not a triangle list", count);
    size_t bound = meshopt_encodeIndexBufferBound(count, n_vertices);
    unsigned char *buf = malloc(bound);
    if (!buf) return sy_fail(err, SY_EINTERNAL, "meshopt: out of memory (%zu bytes)", bound);
    /* Mode TRIANGLES requires bitstream version 1 (header byte 0xe1). */
    meshopt_encodeIndexVersion(1);
    size_t n = meshopt_encodeIndexBuffer(buf, bound, indices, count);
    if (n == 0) {
        free(buf);
        return sy_fail(err, SY_EINTERNAL, "meshopt: index encoder failed (%zu indices)", count);
    }
    *out = buf;
    *out_size = n;
    return SY_OK;
}
