/* LAZ file structure around the chunk coders (laz_items.h): the "laszip
 * encoded" VLR that names the items, the chunk table, decoding chunks in
 * parallel and writing a compressed point block. Internal to ingest: the
 * LAS reader and writer (las.c, las_write.c) are its users. */
#ifndef SYLVA_LAZ_H
#define SYLVA_LAZ_H

#include <stdint.h>
#include <stdio.h>

#include "../core/fileio.h"
#include "../core/status.h"
#include "laz_items.h"

#ifdef __cplusplus
extern "C" {
#endif

enum {
    LAZ_VLR_RECORD_ID = 22204,
    LAZ_DEFAULT_CHUNK = 50000, /* LASzip's default points per chunk */
    LAZ_VLR_MAX = 54 + 34 + 6 * 4,
};

/* Where one chunk's bytes lie in the file and which points it holds. */
typedef struct {
    uint64_t offset, bytes; /* in the file */
    uint64_t first;         /* index of its first point */
    uint32_t points;
} laz_chunk;

/* Parses the LASzip VLR payload for a file of the given point format and
 * record length; rejects compressors, coders and item lists or versions
 * other than those Sylva decodes (point-wise chunked version-2 items for
 * formats 0-3, layered chunked version-3 items for 6-8). */
sy_code laz_parse_vlr(const char *path, const unsigned char *payload, size_t len, int format,
                      unsigned record_length, laz_layout *out, sy_error *err);

/* Reads the chunk table of the point block [point_offset, points_end) and
 * checks it against the header's point count and the bytes present before
 * anything is sized by it. *chunks is malloc'ed (NULL when count is 0). */
sy_code laz_read_chunks(const char *path, const unsigned char *data, size_t size, uint64_t point_offset,
                        uint64_t points_end, const laz_layout *L, uint64_t count, laz_chunk **chunks,
                        size_t *n_chunks, sy_error *err);

/* Receives the records of one decoded chunk, possibly on another thread, at
 * most once per chunk; chunks are disjoint point ranges. Returns SY_OK or
 * fills err. */
typedef sy_code (*laz_sink)(void *user, size_t chunk, uint64_t first, uint32_t count, const unsigned char *records,
                            sy_error *err);

/* Decodes every chunk on sy_threads() threads and hands each to sink. The
 * reported failure is that of the lowest failing chunk, so the message does
 * not depend on the thread count either. */
sy_code laz_decode_chunks(const char *path, const unsigned char *data, const laz_layout *L, const laz_chunk *chunks,
                          size_t n_chunks, laz_sink sink, void *user, sy_error *err);

/* The whole "laszip encoded" VLR (header and payload) for L; returns its length. */
size_t laz_make_vlr(const laz_layout *L, unsigned char out[LAZ_VLR_MAX]);

/* Fills records for points [first, first + count) (called on the writer's thread). */
typedef void (*laz_source)(void *user, uint64_t first, uint32_t count, unsigned char *records);

/* Writes the compressed point block at fp's position (which is the point
 * data offset): the chunk table pointer, the chunks (compressed on
 * sy_threads() threads, written in order) and the chunk table, then patches
 * the pointer. */
sy_code laz_write_points(FILE *fp, const char *path, const laz_layout *L, uint64_t n, laz_source source, void *user,
                         sy_error *err);

/* sy_laz_compress_mem with a chosen chunk size (UINT32_MAX: variable-size
 * chunks, their point counts in the chunk table, as COPC files have). */
sy_code laz_compress_mem_chunked(const char *path, const unsigned char *las, size_t size, uint32_t chunk_size,
                                 sy_buffer *out, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
