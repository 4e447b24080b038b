/* Thread count shared by the stages (`--threads N`; 0 means all cores) and a
 * parallel-for over index ranges. Work is split into fixed chunks whose
 * results callers combine in chunk order, so output never depends on N. */
#ifndef SYLVA_PARALLEL_H
#define SYLVA_PARALLEL_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

void sy_set_threads(int n);
int sy_threads(void); /* resolved count, >= 1 */

/* Calls fn(ctx, begin, end, chunk) for consecutive chunks of [0, n) on up to
 * sy_threads() threads. Chunk boundaries depend only on n and chunk_size. */
void sy_parallel_for(size_t n, size_t chunk_size, void (*fn)(void *ctx, size_t begin, size_t end, size_t chunk),
                     void *ctx);

#ifdef __cplusplus
}
#endif

#endif
