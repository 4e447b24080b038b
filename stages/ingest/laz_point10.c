/* LASzip version-2 items for point formats 0-3 (Isenburg, "LASzip: lossless
 * compression of LiDAR data", 2013): POINT10 predicts x and y from the
 * streaming median of the last five differences in the same return context
 * and z from the last point at the same return level; GPSTIME11 codes time
 * as integer differences (of the doubles' bit patterns) against a multiple
 * of the last difference, tracking four interleaved time sequences;
 * RGB12 and BYTE code byte differences. */
#include <stdlib.h>
#include <string.h>

#include "laz_items.h"

/* Context of a (number of returns, return number) pair: which returns share
 * statistics. Defined for all 3-bit values so that files numbering returns
 * unusually still get distinct contexts. */
static const uint8_t return_map[8][8] = {
    {15, 14, 13, 12, 11, 10, 9, 8}, {14, 0, 1, 3, 6, 10, 10, 9},   {13, 1, 2, 4, 7, 11, 11, 10},
    {12, 3, 4, 5, 8, 12, 12, 11},   {11, 6, 7, 8, 9, 13, 13, 12},  {10, 10, 11, 12, 13, 14, 14, 13},
    {9, 10, 11, 12, 13, 14, 15, 14}, {8, 9, 10, 11, 12, 13, 14, 15},
};

static inline unsigned return_level(unsigned n, unsigned r) { return n > r ? n - r : r - n; }

void laz_median5_init(laz_median5 *m)
{
    memset(m->v, 0, sizeof m->v);
    m->high = 1;
}

/* Keeps the five most recent values sorted, dropping from the end opposite
 * to where the last value went, so the median follows the stream cheaply. */
void laz_median5_add(laz_median5 *m, int32_t x)
{
    int32_t *v = m->v;
    if (m->high) {
        if (x < v[2]) {
            v[4] = v[3];
            v[3] = v[2];
            if (x < v[0]) {
                v[2] = v[1];
                v[1] = v[0];
                v[0] = x;
            } else if (x < v[1]) {
                v[2] = v[1];
                v[1] = x;
            } else {
                v[2] = x;
            }
        } else {
            if (x < v[3]) {
                v[4] = v[3];
                v[3] = x;
            } else {
                v[4] = x;
            }
            m->high = 0;
        }
    } else {
        if (v[2] < x) {
            v[0] = v[1];
            v[1] = v[2];
            if (v[4] < x) {
                v[2] = v[3];
                v[3] = v[4];
                v[4] = x;
            } else if (v[3] < x) {
                v[2] = v[3];
                v[3] = x;
            } else {
                v[2] = x;
            }
        } else {
            if (v[1] < x) {
                v[0] = v[1];
                v[1] = x;
            } else {
                v[0] = x;
            }
            m->high = 1;
        }
    }
}

laz_model *laz_lazy_model(laz_model **slot, uint32_t symbols, int decoding, int *failed, laz_model *fallback)
{
    if (*slot) return *slot;
    laz_model *m = malloc(sizeof *m);
    if (!m || laz_model_init(m, symbols, decoding)) {
        free(m);
        *failed = 1;
        return fallback; /* keeps coding going; the chunk reports out of memory at its end */
    }
    return *slot = m;
}

static void free_lazy(laz_model **slots, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (slots[i]) {
            laz_model_free(slots[i]);
            free(slots[i]);
            slots[i] = NULL;
        }
}

int laz_rgb_models_init(laz_rgb_models *m, int decoding)
{
    memset(m, 0, sizeof *m);
    int bad = laz_model_init(&m->byte_used, 128, decoding);
    for (int i = 0; i < 6; i++) bad |= laz_model_init(&m->diff[i], 256, decoding);
    if (bad) laz_rgb_models_free(m);
    return bad ? -1 : 0;
}

void laz_rgb_models_free(laz_rgb_models *m)
{
    laz_model_free(&m->byte_used);
    for (int i = 0; i < 6; i++) laz_model_free(&m->diff[i]);
}

static inline int clamp_byte(int v) { return v <= 0 ? 0 : v >= 255 ? 255 : v; }

void laz_rgb_decode(laz_decoder *d, laz_rgb_models *m, const uint16_t last[3], uint16_t out[3])
{
    uint32_t sym = laz_dec_symbol(d, &m->byte_used);
    int lo0 = last[0] & 0xFF, hi0 = last[0] >> 8;
    int r_lo = sym & 1 ? (int)((laz_dec_symbol(d, &m->diff[0]) + (unsigned)lo0) & 0xFF) : lo0;
    int r_hi = sym & 2 ? (int)((laz_dec_symbol(d, &m->diff[1]) + (unsigned)hi0) & 0xFF) : hi0;
    out[0] = (uint16_t)(r_lo | r_hi << 8);
    if (!(sym & 64)) {
        out[1] = out[2] = out[0];
        return;
    }
    int lo1 = last[1] & 0xFF, hi1 = last[1] >> 8, lo2 = last[2] & 0xFF, hi2 = last[2] >> 8;
    int diff = r_lo - lo0;
    int g_lo = sym & 4 ? (int)((laz_dec_symbol(d, &m->diff[2]) + (unsigned)clamp_byte(diff + lo1)) & 0xFF) : lo1;
    int b_lo = lo2;
    if (sym & 16) {
        uint32_t corr = laz_dec_symbol(d, &m->diff[4]);
        diff = (diff + (g_lo - lo1)) / 2;
        b_lo = (int)((corr + (unsigned)clamp_byte(diff + lo2)) & 0xFF);
    }
    diff = r_hi - hi0;
    int g_hi = sym & 8 ? (int)((laz_dec_symbol(d, &m->diff[3]) + (unsigned)clamp_byte(diff + hi1)) & 0xFF) : hi1;
    int b_hi = hi2;
    if (sym & 32) {
        uint32_t corr = laz_dec_symbol(d, &m->diff[5]);
        diff = (diff + (g_hi - hi1)) / 2;
        b_hi = (int)((corr + (unsigned)clamp_byte(diff + hi2)) & 0xFF);
    }
    out[1] = (uint16_t)(g_lo | g_hi << 8);
    out[2] = (uint16_t)(b_lo | b_hi << 8);
}

void laz_rgb_encode(laz_encoder *e, laz_rgb_models *m, const uint16_t last[3], const uint16_t cur[3])
{
    int lo[3], hi[3], llo[3], lhi[3];
    for (int k = 0; k < 3; k++) {
        lo[k] = cur[k] & 0xFF;
        hi[k] = cur[k] >> 8;
        llo[k] = last[k] & 0xFF;
        lhi[k] = last[k] >> 8;
    }
    uint32_t sym = (uint32_t)(llo[0] != lo[0]) | (uint32_t)(lhi[0] != hi[0]) << 1 | (uint32_t)(llo[1] != lo[1]) << 2 |
                   (uint32_t)(lhi[1] != hi[1]) << 3 | (uint32_t)(llo[2] != lo[2]) << 4 |
                   (uint32_t)(lhi[2] != hi[2]) << 5 |
                   (uint32_t)(lo[0] != lo[1] || lo[0] != lo[2] || hi[0] != hi[1] || hi[0] != hi[2]) << 6;
    laz_enc_symbol(e, &m->byte_used, sym);
    if (sym & 1) laz_enc_symbol(e, &m->diff[0], (uint32_t)(lo[0] - llo[0]) & 0xFF);
    if (sym & 2) laz_enc_symbol(e, &m->diff[1], (uint32_t)(hi[0] - lhi[0]) & 0xFF);
    if (!(sym & 64)) return;
    int diff = lo[0] - llo[0];
    if (sym & 4) laz_enc_symbol(e, &m->diff[2], (uint32_t)(lo[1] - clamp_byte(diff + llo[1])) & 0xFF);
    if (sym & 16) {
        diff = (diff + (lo[1] - llo[1])) / 2;
        laz_enc_symbol(e, &m->diff[4], (uint32_t)(lo[2] - clamp_byte(diff + llo[2])) & 0xFF);
    }
    diff = hi[0] - lhi[0];
    if (sym & 8) laz_enc_symbol(e, &m->diff[3], (uint32_t)(hi[1] - clamp_byte(diff + lhi[1])) & 0xFF);
    if (sym & 32) {
        diff = (diff + (hi[1] - lhi[1])) / 2;
        laz_enc_symbol(e, &m->diff[5], (uint32_t)(hi[2] - clamp_byte(diff + lhi[2])) & 0xFF);
    }
}

/* ---- the version-2 chunk state ---- */

enum {
    GPS10_UNCHANGED = LAZ_GPS_MULTI - LAZ_GPS_MULTI_MINUS + 1, /* 511 */
    GPS10_CODE_FULL = LAZ_GPS_MULTI - LAZ_GPS_MULTI_MINUS + 2, /* 512 */
    GPS10_TOTAL = LAZ_GPS_MULTI - LAZ_GPS_MULTI_MINUS + 6,     /* 516 */
};

typedef struct {
    int decoding, failed;
    /* POINT10 */
    unsigned char last[20];
    uint16_t last_intensity[16];
    laz_median5 x_med[16], y_med[16];
    int32_t last_height[8];
    laz_model changed_values, scan_angle[2];
    laz_model *bit_byte[256], *classification[256], *user_data[256];
    laz_model fallback;
    laz_ic ic_intensity, ic_point_source, ic_dx, ic_dy, ic_z;
    /* GPSTIME11 */
    int has_gps;
    laz_gps_state gps;
    /* RGB12 */
    int has_rgb;
    uint16_t last_rgb[3];
    laz_rgb_models rgb;
    /* BYTE */
    unsigned extra;
    unsigned char *last_extra;
    laz_model *extra_models;
} state10;

static void state10_free(state10 *s)
{
    laz_model_free(&s->changed_values);
    laz_model_free(&s->scan_angle[0]);
    laz_model_free(&s->scan_angle[1]);
    laz_model_free(&s->fallback);
    free_lazy(s->bit_byte, 256);
    free_lazy(s->classification, 256);
    free_lazy(s->user_data, 256);
    laz_ic_free(&s->ic_intensity);
    laz_ic_free(&s->ic_point_source);
    laz_ic_free(&s->ic_dx);
    laz_ic_free(&s->ic_dy);
    laz_ic_free(&s->ic_z);
    laz_model_free(&s->gps.multi);
    laz_model_free(&s->gps.zero_diff);
    laz_ic_free(&s->gps.ic);
    laz_rgb_models_free(&s->rgb);
    if (s->extra_models)
        for (unsigned i = 0; i < s->extra; i++) laz_model_free(&s->extra_models[i]);
    free(s->extra_models);
    free(s->last_extra);
}

/* Sets up every model from the chunk's first record, as stored raw. */
static int state10_init(state10 *s, const laz_layout *L, const unsigned char *first, int decoding)
{
    memset(s, 0, sizeof *s);
    s->decoding = decoding;
    s->has_gps = L->format == 1 || L->format == 3;
    s->has_rgb = L->format >= 2;
    s->extra = L->extra;
    int bad = laz_model_init(&s->changed_values, 64, decoding);
    bad |= laz_model_init(&s->scan_angle[0], 256, decoding) | laz_model_init(&s->scan_angle[1], 256, decoding);
    bad |= laz_model_init(&s->fallback, 256, decoding);
    bad |= laz_ic_init(&s->ic_intensity, 16, 4, decoding) | laz_ic_init(&s->ic_point_source, 16, 1, decoding);
    bad |= laz_ic_init(&s->ic_dx, 32, 2, decoding) | laz_ic_init(&s->ic_dy, 32, 22, decoding);
    bad |= laz_ic_init(&s->ic_z, 32, 20, decoding);
    for (int i = 0; i < 16; i++) {
        laz_median5_init(&s->x_med[i]);
        laz_median5_init(&s->y_med[i]);
    }
    memcpy(s->last, first, 20);
    s->last[12] = s->last[13] = 0; /* intensity is predicted per return context, from 0 */
    const unsigned char *p = first + 20;
    if (s->has_gps) {
        bad |= laz_model_init(&s->gps.multi, GPS10_TOTAL, decoding) | laz_model_init(&s->gps.zero_diff, 6, decoding);
        bad |= laz_ic_init(&s->gps.ic, 32, 9, decoding);
        s->gps.last_time[0] = las_u64(p);
        p += 8;
    }
    if (s->has_rgb) {
        bad |= laz_rgb_models_init(&s->rgb, decoding);
        for (int k = 0; k < 3; k++) s->last_rgb[k] = las_u16(p + 2 * k);
        p += 6;
    }
    if (s->extra) {
        s->last_extra = malloc(s->extra);
        s->extra_models = calloc(s->extra, sizeof(laz_model));
        if (!s->last_extra || !s->extra_models) return -1;
        memcpy(s->last_extra, p, s->extra);
        for (unsigned i = 0; i < s->extra; i++) bad |= laz_model_init(&s->extra_models[i], 256, decoding);
    }
    return bad ? -1 : 0;
}

static inline uint32_t even(uint32_t k) { return k & ~1u; }

static void decode_point10(state10 *s, laz_decoder *d, unsigned char *out)
{
    unsigned char *last = s->last;
    uint32_t changed = laz_dec_symbol(d, &s->changed_values);
    unsigned r, n, m, l;
    if (changed) {
        if (changed & 32) {
            laz_model *mb = laz_lazy_model(&s->bit_byte[last[14]], 256, 1, &s->failed, &s->fallback);
            last[14] = (unsigned char)laz_dec_symbol(d, mb);
        }
        r = last[14] & 7;
        n = (last[14] >> 3) & 7;
        m = return_map[n][r];
        l = return_level(n, r);
        if (changed & 16) {
            uint16_t v = (uint16_t)laz_ic_decompress(&s->ic_intensity, d, s->last_intensity[m], m < 3 ? m : 3);
            s->last_intensity[m] = v;
            las_put_u16(last + 12, v);
        } else {
            las_put_u16(last + 12, s->last_intensity[m]);
        }
        if (changed & 8) {
            laz_model *mc = laz_lazy_model(&s->classification[last[15]], 256, 1, &s->failed, &s->fallback);
            last[15] = (unsigned char)laz_dec_symbol(d, mc);
        }
        if (changed & 4) {
            uint32_t v = laz_dec_symbol(d, &s->scan_angle[(last[14] >> 6) & 1]);
            last[16] = (unsigned char)(v + last[16]);
        }
        if (changed & 2) {
            laz_model *mu = laz_lazy_model(&s->user_data[last[17]], 256, 1, &s->failed, &s->fallback);
            last[17] = (unsigned char)laz_dec_symbol(d, mu);
        }
        if (changed & 1)
            las_put_u16(last + 18, (uint16_t)laz_ic_decompress(&s->ic_point_source, d, las_u16(last + 18), 0));
    } else {
        r = last[14] & 7;
        n = (last[14] >> 3) & 7;
        m = return_map[n][r];
        l = return_level(n, r);
    }
    int32_t diff = laz_ic_decompress(&s->ic_dx, d, s->x_med[m].v[2], n == 1);
    las_put_u32(last, las_u32(last) + (uint32_t)diff);
    laz_median5_add(&s->x_med[m], diff);
    uint32_t k = s->ic_dx.k;
    diff = laz_ic_decompress(&s->ic_dy, d, s->y_med[m].v[2], (n == 1) + (k < 20 ? even(k) : 20));
    las_put_u32(last + 4, las_u32(last + 4) + (uint32_t)diff);
    laz_median5_add(&s->y_med[m], diff);
    k = (s->ic_dx.k + s->ic_dy.k) / 2;
    int32_t z = laz_ic_decompress(&s->ic_z, d, s->last_height[l], (n == 1) + (k < 18 ? even(k) : 18));
    las_put_u32(last + 8, (uint32_t)z);
    s->last_height[l] = z;
    memcpy(out, last, 20);
}

static void encode_point10(state10 *s, laz_encoder *e, const unsigned char *item)
{
    unsigned char *last = s->last;
    unsigned r = item[14] & 7, n = (item[14] >> 3) & 7;
    unsigned m = return_map[n][r], l = return_level(n, r);
    uint16_t intensity = las_u16(item + 12);
    uint32_t changed = (uint32_t)(last[14] != item[14]) << 5 | (uint32_t)(s->last_intensity[m] != intensity) << 4 |
                       (uint32_t)(last[15] != item[15]) << 3 | (uint32_t)(last[16] != item[16]) << 2 |
                       (uint32_t)(last[17] != item[17]) << 1 | (uint32_t)(las_u16(last + 18) != las_u16(item + 18));
    laz_enc_symbol(e, &s->changed_values, changed);
    if (changed & 32)
        laz_enc_symbol(e, laz_lazy_model(&s->bit_byte[last[14]], 256, 0, &s->failed, &s->fallback), item[14]);
    if (changed & 16) {
        laz_ic_compress(&s->ic_intensity, e, s->last_intensity[m], intensity, m < 3 ? m : 3);
        s->last_intensity[m] = intensity;
    }
    if (changed & 8)
        laz_enc_symbol(e, laz_lazy_model(&s->classification[last[15]], 256, 0, &s->failed, &s->fallback), item[15]);
    if (changed & 4) laz_enc_symbol(e, &s->scan_angle[(item[14] >> 6) & 1], (uint32_t)(item[16] - last[16]) & 0xFF);
    if (changed & 2)
        laz_enc_symbol(e, laz_lazy_model(&s->user_data[last[17]], 256, 0, &s->failed, &s->fallback), item[17]);
    if (changed & 1) laz_ic_compress(&s->ic_point_source, e, las_u16(last + 18), las_u16(item + 18), 0);
    int32_t diff = (int32_t)(las_u32(item) - las_u32(last));
    laz_ic_compress(&s->ic_dx, e, s->x_med[m].v[2], diff, n == 1);
    laz_median5_add(&s->x_med[m], diff);
    uint32_t k = s->ic_dx.k;
    diff = (int32_t)(las_u32(item + 4) - las_u32(last + 4));
    laz_ic_compress(&s->ic_dy, e, s->y_med[m].v[2], diff, (n == 1) + (k < 20 ? even(k) : 20));
    laz_median5_add(&s->y_med[m], diff);
    k = (s->ic_dx.k + s->ic_dy.k) / 2;
    int32_t z = (int32_t)las_u32(item + 8);
    laz_ic_compress(&s->ic_z, e, s->last_height[l], z, (n == 1) + (k < 18 ? even(k) : 18));
    s->last_height[l] = z;
    memcpy(last, item, 20);
}

static inline int32_t wrap_mul(int32_t a, int32_t b) { return (int32_t)((uint32_t)a * (uint32_t)b); }

/* Starts a new time sequence from a full 64-bit value: the high word coded
 * against the current sequence's, the low word raw. */
void laz_gps_decode_full(laz_gps_state *g, laz_decoder *d)
{
    g->next = (g->next + 1) & 3;
    uint32_t high = (uint32_t)laz_ic_decompress(&g->ic, d, (int32_t)(uint32_t)(g->last_time[g->last] >> 32), 8);
    g->last_time[g->next] = (uint64_t)high << 32 | laz_dec_int(d);
    g->last = g->next;
    g->last_diff[g->last] = 0;
    g->extreme_count[g->last] = 0;
}

/* A difference coded against a multiple of the last one (contexts 2-7);
 * after four "extreme" multipliers the last difference is replaced. */
int32_t laz_gps_decode_multi(laz_gps_state *g, laz_decoder *d, int32_t multi)
{
    int32_t ld = g->last_diff[g->last], diff;
    int extreme = 0;
    if (multi == 0) {
        diff = laz_ic_decompress(&g->ic, d, 0, 7);
        extreme = 1;
    } else if (multi < LAZ_GPS_MULTI) {
        diff = laz_ic_decompress(&g->ic, d, wrap_mul(multi, ld), multi < 10 ? 2 : 3);
    } else if (multi == LAZ_GPS_MULTI) {
        diff = laz_ic_decompress(&g->ic, d, wrap_mul(LAZ_GPS_MULTI, ld), 4);
        extreme = 1;
    } else {
        multi = LAZ_GPS_MULTI - multi;
        if (multi > LAZ_GPS_MULTI_MINUS) {
            diff = laz_ic_decompress(&g->ic, d, wrap_mul(multi, ld), 5);
        } else {
            diff = laz_ic_decompress(&g->ic, d, wrap_mul(LAZ_GPS_MULTI_MINUS, ld), 6);
            extreme = 1;
        }
    }
    if (extreme && ++g->extreme_count[g->last] > 3) {
        g->last_diff[g->last] = diff;
        g->extreme_count[g->last] = 0;
    }
    return diff;
}

/* Both item versions code GPS time the same way and differ only in which
 * symbols mean what: version 2 has an "unchanged" code in each model,
 * version 3 leaves that to POINT14's change bits and shifts the others down. */
const laz_gps_codes laz_gps_codes_v2 = {0, 1, 2, 2, GPS10_UNCHANGED, GPS10_CODE_FULL};

void laz_gps_decode(laz_gps_state *g, laz_decoder *d, const laz_gps_codes *codes)
{
    for (int hops = 0; hops < 8; hops++) { /* a sequence switch restarts; a valid stream switches once */
        if (g->last_diff[g->last] == 0) {
            int32_t multi = (int32_t)laz_dec_symbol(d, &g->zero_diff);
            if (multi == codes->zero_unchanged) {
            } else if (multi == codes->zero_delta) {
                g->last_diff[g->last] = laz_ic_decompress(&g->ic, d, 0, 0);
                g->last_time[g->last] += (uint64_t)(int64_t)g->last_diff[g->last];
                g->extreme_count[g->last] = 0;
            } else if (multi == codes->zero_full) {
                laz_gps_decode_full(g, d);
            } else {
                g->last = (g->last + (uint32_t)(multi - codes->zero_switch)) & 3;
                continue;
            }
        } else {
            int32_t multi = (int32_t)laz_dec_symbol(d, &g->multi);
            if (multi == 1) {
                g->last_time[g->last] += (uint64_t)(int64_t)laz_ic_decompress(&g->ic, d, g->last_diff[g->last], 1);
                g->extreme_count[g->last] = 0;
            } else if (multi < LAZ_GPS_MULTI - LAZ_GPS_MULTI_MINUS + 1) {
                g->last_time[g->last] += (uint64_t)(int64_t)laz_gps_decode_multi(g, d, multi);
            } else if (multi == codes->multi_unchanged) {
            } else if (multi == codes->multi_full) {
                laz_gps_decode_full(g, d);
            } else {
                g->last = (g->last + (uint32_t)(multi - codes->multi_full)) & 3;
                continue;
            }
        }
        return;
    }
}

static inline int fits32(int64_t v) { return v == (int64_t)(int32_t)v; }

/* I32_QUANTIZE of the multiplier, clamped first so a huge ratio stays defined. */
static int32_t quantise_multi(int32_t diff, int32_t last_diff)
{
    float f = (float)diff / (float)last_diff;
    if (f > 1000.0f) return 1000;
    if (f < -1000.0f) return -1000;
    return f >= 0 ? (int32_t)(f + 0.5f) : (int32_t)(f - 0.5f);
}

/* The encoder side of gps_decode_multi (and of the multiplier choice). */
void laz_gps_encode_diff(laz_gps_state *g, laz_encoder *e, laz_model *multi_model, int32_t diff)
{
    int32_t ld = g->last_diff[g->last];
    int32_t multi = quantise_multi(diff, ld);
    int extreme = 0;
    if (multi == 1) {
        laz_enc_symbol(e, multi_model, 1);
        laz_ic_compress(&g->ic, e, ld, diff, 1);
        g->extreme_count[g->last] = 0;
        return;
    }
    if (multi > 0) {
        if (multi < LAZ_GPS_MULTI) {
            laz_enc_symbol(e, multi_model, (uint32_t)multi);
            laz_ic_compress(&g->ic, e, wrap_mul(multi, ld), diff, multi < 10 ? 2 : 3);
        } else {
            laz_enc_symbol(e, multi_model, LAZ_GPS_MULTI);
            laz_ic_compress(&g->ic, e, wrap_mul(LAZ_GPS_MULTI, ld), diff, 4);
            extreme = 1;
        }
    } else if (multi < 0) {
        if (multi > LAZ_GPS_MULTI_MINUS) {
            laz_enc_symbol(e, multi_model, (uint32_t)(LAZ_GPS_MULTI - multi));
            laz_ic_compress(&g->ic, e, wrap_mul(multi, ld), diff, 5);
        } else {
            laz_enc_symbol(e, multi_model, LAZ_GPS_MULTI - LAZ_GPS_MULTI_MINUS);
            laz_ic_compress(&g->ic, e, wrap_mul(LAZ_GPS_MULTI_MINUS, ld), diff, 6);
            extreme = 1;
        }
    } else {
        laz_enc_symbol(e, multi_model, 0);
        laz_ic_compress(&g->ic, e, 0, diff, 7);
        extreme = 1;
    }
    if (extreme && ++g->extreme_count[g->last] > 3) {
        g->last_diff[g->last] = diff;
        g->extreme_count[g->last] = 0;
    }
}

void laz_gps_encode_full(laz_gps_state *g, laz_encoder *e, uint64_t t)
{
    laz_ic_compress(&g->ic, e, (int32_t)(uint32_t)(g->last_time[g->last] >> 32), (int32_t)(uint32_t)(t >> 32), 8);
    laz_enc_int(e, (uint32_t)t);
    g->next = (g->next + 1) & 3;
    g->last = g->next;
    g->last_diff[g->last] = 0;
    g->extreme_count[g->last] = 0;
}

/* Another of the four sequences within 32 bits of t, or 0. */
uint32_t laz_gps_other_sequence(const laz_gps_state *g, uint64_t t)
{
    for (uint32_t i = 1; i < 4; i++)
        if (fits32((int64_t)(t - g->last_time[(g->last + i) & 3]))) return i;
    return 0;
}

void laz_gps_encode(laz_gps_state *g, laz_encoder *e, uint64_t t, const laz_gps_codes *codes)
{
    for (;;) {
        int64_t diff64 = (int64_t)(t - g->last_time[g->last]);
        if (g->last_diff[g->last] == 0) {
            if (diff64 == 0 && codes->zero_unchanged >= 0) {
                laz_enc_symbol(e, &g->zero_diff, (uint32_t)codes->zero_unchanged);
                return;
            }
            if (fits32(diff64)) {
                laz_enc_symbol(e, &g->zero_diff, (uint32_t)codes->zero_delta);
                laz_ic_compress(&g->ic, e, 0, (int32_t)diff64, 0);
                g->last_diff[g->last] = (int32_t)diff64;
                g->extreme_count[g->last] = 0;
            } else {
                uint32_t i = laz_gps_other_sequence(g, t);
                if (i) {
                    laz_enc_symbol(e, &g->zero_diff, (uint32_t)codes->zero_switch + i);
                    g->last = (g->last + i) & 3;
                    continue;
                }
                laz_enc_symbol(e, &g->zero_diff, (uint32_t)codes->zero_full);
                laz_gps_encode_full(g, e, t);
            }
        } else {
            if (diff64 == 0 && codes->multi_unchanged >= 0) {
                laz_enc_symbol(e, &g->multi, (uint32_t)codes->multi_unchanged);
                return;
            }
            if (fits32(diff64)) {
                laz_gps_encode_diff(g, e, &g->multi, (int32_t)diff64);
            } else {
                uint32_t i = laz_gps_other_sequence(g, t);
                if (i) {
                    laz_enc_symbol(e, &g->multi, (uint32_t)codes->multi_full + i);
                    g->last = (g->last + i) & 3;
                    continue;
                }
                laz_enc_symbol(e, &g->multi, (uint32_t)codes->multi_full);
                laz_gps_encode_full(g, e, t);
            }
        }
        g->last_time[g->last] = t;
        return;
    }
}

int laz_chunk10_decode(const laz_layout *L, const unsigned char *in, size_t len, uint32_t n, unsigned char *out,
                       const char **why)
{
    const size_t rl = L->record_length;
    if (len < rl) {
        *why = "chunk shorter than its first point";
        return LAZ_CORRUPT;
    }
    memcpy(out, in, rl);
    state10 s;
    if (state10_init(&s, L, out, 1)) {
        state10_free(&s);
        return LAZ_NOMEM;
    }
    laz_decoder d;
    laz_dec_init(&d, in + rl, len - rl);
    const size_t gps_at = 20, rgb_at = s.has_gps ? 28 : 20, extra_at = rgb_at + (s.has_rgb ? 6 : 0);
    for (uint32_t i = 1; i < n && !d.overrun; i++) {
        unsigned char *rec = out + i * rl;
        decode_point10(&s, &d, rec);
        if (s.has_gps) {
            laz_gps_decode(&s.gps, &d, &laz_gps_codes_v2);
            las_put_u64(rec + gps_at, s.gps.last_time[s.gps.last]);
        }
        if (s.has_rgb) {
            uint16_t rgb[3];
            laz_rgb_decode(&d, &s.rgb, s.last_rgb, rgb);
            for (int k = 0; k < 3; k++) las_put_u16(rec + rgb_at + 2 * k, s.last_rgb[k] = rgb[k]);
        }
        for (unsigned b = 0; b < s.extra; b++) {
            s.last_extra[b] = (unsigned char)(s.last_extra[b] + laz_dec_symbol(&d, &s.extra_models[b]));
            rec[extra_at + b] = s.last_extra[b];
        }
    }
    int failed = s.failed;
    state10_free(&s);
    if (failed) return LAZ_NOMEM;
    if (d.overrun) {
        *why = "truncated or corrupt chunk (its bytes ran out before its points)";
        return LAZ_CORRUPT;
    }
    return LAZ_OK;
}

int laz_chunk10_encode(const laz_layout *L, const unsigned char *records, uint32_t n, laz_buf *out)
{
    const size_t rl = L->record_length;
    laz_buf_put(out, records, rl);
    state10 s;
    if (state10_init(&s, L, records, 0)) {
        state10_free(&s);
        return LAZ_NOMEM;
    }
    laz_encoder e;
    laz_enc_init(&e, out);
    const size_t gps_at = 20, rgb_at = s.has_gps ? 28 : 20, extra_at = rgb_at + (s.has_rgb ? 6 : 0);
    for (uint32_t i = 1; i < n; i++) {
        const unsigned char *rec = records + i * rl;
        encode_point10(&s, &e, rec);
        if (s.has_gps) laz_gps_encode(&s.gps, &e, las_u64(rec + gps_at), &laz_gps_codes_v2);
        if (s.has_rgb) {
            uint16_t rgb[3];
            for (int k = 0; k < 3; k++) rgb[k] = las_u16(rec + rgb_at + 2 * k);
            laz_rgb_encode(&e, &s.rgb, s.last_rgb, rgb);
            memcpy(s.last_rgb, rgb, sizeof rgb);
        }
        for (unsigned b = 0; b < s.extra; b++) {
            laz_enc_symbol(&e, &s.extra_models[b], (uint32_t)(rec[extra_at + b] - s.last_extra[b]) & 0xFF);
            s.last_extra[b] = rec[extra_at + b];
        }
    }
    laz_enc_done(&e);
    int failed = s.failed || out->failed;
    state10_free(&s);
    return failed ? LAZ_NOMEM : LAZ_OK;
}
