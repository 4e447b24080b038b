/* LAZ chunk coders: one chunk of point records <-> its compressed bytes.
 *
 * Point formats 0-3 use LASzip's point-wise items (version 2): POINT10,
 * GPSTIME11, RGB12 and BYTE for the extra bytes, all coded into one
 * arithmetic stream after the chunk's first record, which is stored raw.
 * Formats 6-8 use the layered items of LAS 1.4 (version 3): POINT14, RGB14,
 * RGBNIR14 and BYTE14, each field group in its own stream (its "layer") so
 * that a reader could skip what it does not need and a field constant over
 * the chunk costs no bytes at all; the chunk holds the raw first record, the
 * point count, the layer sizes and then the layers. Both follow the LASzip
 * paper (Isenburg 2013) and the LAZ 1.4 specification. */
#ifndef SYLVA_LAZ_ITEMS_H
#define SYLVA_LAZ_ITEMS_H

#include <stdint.h>

#include "las_format.h"
#include "laz_codec.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int format;             /* LAS point data record format: 0-3 or 6-8 */
    unsigned record_length; /* the format's core plus `extra` bytes */
    unsigned extra;         /* extra bytes per record (BYTE / BYTE14 item) */
    int layered;            /* formats 6-8 */
    uint32_t chunk_size;    /* points per chunk; UINT32_MAX: variable, from the chunk table */
} laz_layout;

/* Outcome of a chunk coder. */
enum { LAZ_OK = 0, LAZ_NOMEM = -1, LAZ_CORRUPT = -2 };

/* Decodes a chunk of n >= 1 records from in[0..len) into out
 * (n * record_length bytes). LAZ_CORRUPT when the bytes run out or
 * contradict themselves (the chunk's own point count, layer sizes past the
 * chunk); *why then names the problem. Never reads outside in. */
int laz_decode_chunk(const laz_layout *L, const unsigned char *in, size_t len, uint32_t n, unsigned char *out,
                     const char **why);

/* Appends the compressed form of n >= 1 records to out. */
int laz_encode_chunk(const laz_layout *L, const unsigned char *records, uint32_t n, laz_buf *out);

/* Shared by both item versions. */
typedef struct {
    int32_t v[5];
    int high;
} laz_median5;

void laz_median5_init(laz_median5 *m);
void laz_median5_add(laz_median5 *m, int32_t v);

/* LASzip's RGB coding: which bytes changed, then each byte's difference
 * from a prediction built from the red channel's change. */
typedef struct {
    laz_model byte_used, diff[6];
} laz_rgb_models;

int laz_rgb_models_init(laz_rgb_models *m, int decoding);
void laz_rgb_models_free(laz_rgb_models *m);
void laz_rgb_decode(laz_decoder *d, laz_rgb_models *m, const uint16_t last[3], uint16_t out[3]);
void laz_rgb_encode(laz_encoder *e, laz_rgb_models *m, const uint16_t last[3], const uint16_t cur[3]);

/* A lazily created model (LASzip creates context models on first use; a
 * model created late starts fresh, as one created early but unused would). */
laz_model *laz_lazy_model(laz_model **slot, uint32_t symbols, int decoding, int *failed, laz_model *fallback);

/* GPS time state shared by GPSTIME11 (v2) and POINT14 (v3): four time
 * sequences (interleaved pulses), each with its last value and last integer
 * difference; differences are coded against a multiple of the last one. */
enum { LAZ_GPS_MULTI = 500, LAZ_GPS_MULTI_MINUS = -10 };
typedef struct {
    uint32_t last, next;
    uint64_t last_time[4]; /* bit patterns of the doubles */
    int32_t last_diff[4];
    int32_t extreme_count[4];
    laz_model multi, zero_diff;
    laz_ic ic;
} laz_gps_state;

/* Which symbol means what in the two item versions (-1: no such code). */
typedef struct {
    int32_t zero_unchanged, zero_delta, zero_full, zero_switch; /* the model used after a zero difference */
    int32_t multi_unchanged, multi_full;                        /* the multiplier model */
} laz_gps_codes;
extern const laz_gps_codes laz_gps_codes_v2;

/* One GPS time (as its bit pattern) through the state: decode leaves it in
 * g->last_time[g->last]. */
void laz_gps_decode(laz_gps_state *g, laz_decoder *d, const laz_gps_codes *codes);
void laz_gps_encode(laz_gps_state *g, laz_encoder *e, uint64_t t, const laz_gps_codes *codes);
void laz_gps_decode_full(laz_gps_state *g, laz_decoder *d);
int32_t laz_gps_decode_multi(laz_gps_state *g, laz_decoder *d, int32_t multi);
void laz_gps_encode_diff(laz_gps_state *g, laz_encoder *e, laz_model *multi_model, int32_t diff);
void laz_gps_encode_full(laz_gps_state *g, laz_encoder *e, uint64_t t);
uint32_t laz_gps_other_sequence(const laz_gps_state *g, uint64_t t);

int laz_chunk10_decode(const laz_layout *L, const unsigned char *in, size_t len, uint32_t n, unsigned char *out,
                       const char **why);
int laz_chunk10_encode(const laz_layout *L, const unsigned char *records, uint32_t n, laz_buf *out);
int laz_chunk14_decode(const laz_layout *L, const unsigned char *in, size_t len, uint32_t n, unsigned char *out,
                       const char **why);
int laz_chunk14_encode(const laz_layout *L, const unsigned char *records, uint32_t n, laz_buf *out);

#ifdef __cplusplus
}
#endif

#endif
