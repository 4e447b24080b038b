/* FNV-1a, 64 bits (Fowler, Noll, Vo): the project's content hash for change
 * detection (batch records, model files, the materials cache), not a defence
 * against crafted collisions. */
#ifndef SYLVA_CORE_HASH_H
#define SYLVA_CORE_HASH_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SY_FNV1A64_INIT 14695981039346656037ull

/* h carried on over size bytes (start from SY_FNV1A64_INIT). */
uint64_t sy_fnv1a64(uint64_t h, const void *data, size_t size);

#ifdef __cplusplus
}
#endif

#endif
