/* PNG encoding (zlib, level 3). */
#ifndef SYLVA_CORE_PNG_H
#define SYLVA_CORE_PNG_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* PNG of w x h samples, c = 1..4 channels (grey, grey+alpha, RGB, RGBA),
 * 8 bits or 16 (big-endian pairs, as PNG stores them), rows packed. Filters
 * by the specification's heuristic (per row, the least sum of absolute
 * values); zlib level 3, within a few percent of the best size at a third of
 * the time. *png is malloc'ed. Returns 0, or -1 (bad arguments, memory). */
int sy_png_encode(const unsigned char *samples, int w, int h, int c, int bits, unsigned char **png, size_t *size);

#ifdef __cplusplus
}
#endif

#endif
