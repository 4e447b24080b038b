/* EXT_meshopt_compression streams with meshoptimizer's C codec (0.18):
 * attribute streams in bitstream version 0 (header 0xa0) and triangle index
 * streams in version 1 (header 0xe1), the versions the extension specifies. */
#ifndef SYLVA_MESHOPT_CODEC_H
#define SYLVA_MESHOPT_CODEC_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Encodes count elements of stride bytes (stride % 4 == 0, <= 256) into a
 * malloc'd buffer. */
sy_code sy_meshopt_encode_attributes(const void *data, size_t count, size_t stride,
                                     unsigned char **out, size_t *out_size, sy_error *err);
/* Encodes a triangle list (count % 3 == 0) whose indices are < n_vertices. */
sy_code sy_meshopt_encode_triangles(const uint32_t *indices, size_t count, size_t n_vertices,
                                    unsigned char **out, size_t *out_size, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
