/* LASzip version-3 ("layered") items for the LAS 1.4 point formats 6-8:
 * POINT14, RGB14, RGBNIR14 and BYTE14 (LAZ 1.4 specification; Isenburg's
 * LASzip paper for the predictors it inherits from POINT10). Every field
 * group has its own arithmetic stream, and all predictions live in one of
 * four contexts chosen by the point's scanner channel, so interleaved
 * channels of a multi-beam scanner do not spoil each other's statistics.
 * A context starts from a copy of the previous point when its channel first
 * appears in the chunk. */
#include <stdlib.h>
#include <string.h>

#include "laz_items.h"

/* Contexts for (number of returns, return number) with 4-bit fields: six
 * classes for x/y, and the level of penetration (n - r, capped at 7) for z. */
static const uint8_t return_map_6ctx[16][16] = {
    {0, 1, 2, 3, 4, 5, 3, 4, 4, 5, 5, 5, 5, 5, 5, 5}, {1, 0, 1, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3, 3},
    {2, 1, 2, 4, 4, 4, 4, 4, 4, 4, 4, 3, 3, 3, 3, 3}, {3, 3, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
    {4, 3, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4}, {5, 3, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4},
    {3, 3, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4, 4}, {4, 3, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4, 4},
    {4, 3, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4, 4}, {5, 3, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4, 4},
    {5, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 4, 4, 4, 4, 4}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 4, 4, 4},
    {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4, 4}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5, 4},
    {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5, 5}, {5, 3, 3, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 4, 5, 5},
};

static inline unsigned level_8ctx(unsigned n, unsigned r)
{
    unsigned d = n > r ? n - r : r - n;
    return d > 7 ? 7 : d;
}

enum {
    GPS14_CODE_FULL = LAZ_GPS_MULTI - LAZ_GPS_MULTI_MINUS + 1, /* 511 */
    GPS14_TOTAL = LAZ_GPS_MULTI - LAZ_GPS_MULTI_MINUS + 5,     /* 515 */
    /* the layers of POINT14, in stream order */
    L_XY = 0, L_Z, L_CLASS, L_FLAGS, L_INTENSITY, L_SCAN_ANGLE, L_USER_DATA, L_POINT_SOURCE, L_GPS, N_POINT_LAYERS,
};

/* A format-6 record's fields, unpacked. */
typedef struct {
    int32_t x, y, z;
    uint16_t intensity;
    unsigned rn, nr, class_flags, channel, scan_dir, edge, classification, user_data;
    int16_t scan_angle;
    uint16_t point_source;
    uint64_t gps;
    int gps_change; /* coder state: whether this point's time differed from the one before */
} p14;

static void unpack14(const unsigned char *r, p14 *p)
{
    p->x = (int32_t)las_u32(r);
    p->y = (int32_t)las_u32(r + 4);
    p->z = (int32_t)las_u32(r + 8);
    p->intensity = las_u16(r + 12);
    p->rn = r[14] & 0x0F;
    p->nr = r[14] >> 4;
    p->class_flags = r[15] & 0x0F;
    p->channel = (r[15] >> 4) & 3;
    p->scan_dir = (r[15] >> 6) & 1;
    p->edge = r[15] >> 7;
    p->classification = r[16];
    p->user_data = r[17];
    p->scan_angle = (int16_t)las_u16(r + 18);
    p->point_source = las_u16(r + 20);
    p->gps = las_u64(r + 22);
    p->gps_change = 0;
}

static void pack14(const p14 *p, unsigned char *r)
{
    las_put_u32(r, (uint32_t)p->x);
    las_put_u32(r + 4, (uint32_t)p->y);
    las_put_u32(r + 8, (uint32_t)p->z);
    las_put_u16(r + 12, p->intensity);
    r[14] = (unsigned char)(p->rn | p->nr << 4);
    r[15] = (unsigned char)(p->class_flags | p->channel << 4 | p->scan_dir << 6 | p->edge << 7);
    r[16] = (unsigned char)p->classification;
    r[17] = (unsigned char)p->user_data;
    las_put_u16(r + 18, (uint16_t)p->scan_angle);
    las_put_u16(r + 20, p->point_source);
    las_put_u64(r + 22, p->gps);
}

/* Everything one scanner channel predicts from. */
typedef struct {
    int used;
    p14 last;
    uint16_t last_intensity[8];
    laz_median5 x_med[12], y_med[12];
    int32_t last_z[8];
    laz_model changed_values[8], scanner_channel, return_number_gps_same;
    laz_model *number_of_returns[16], *return_number[16];
    laz_ic ic_dx, ic_dy, ic_z;
    laz_model *classification[64], *flags[64], *user_data[64];
    laz_ic ic_intensity, ic_scan_angle, ic_point_source;
    laz_gps_state gps;
    /* RGB14 / RGBNIR14 */
    int rgb_used;
    uint16_t last_rgb[4]; /* red, green, blue, near infrared */
    laz_rgb_models rgb;
    laz_model nir_used, nir_diff[2];
    /* BYTE14 */
    int bytes_used;
    unsigned char *last_bytes;
    laz_model *byte_models;
} ctx14;

typedef struct {
    int decoding, failed;
    int has_rgb, has_nir;
    unsigned extra;
    unsigned current, rgb_current, bytes_current;
    ctx14 ctx[4];
    laz_model fallback;
} state14;

static void free_slots(laz_model **slots, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (slots[i]) {
            laz_model_free(slots[i]);
            free(slots[i]);
        }
}

static void ctx_free(ctx14 *c, unsigned extra)
{
    for (int i = 0; i < 8; i++) laz_model_free(&c->changed_values[i]);
    laz_model_free(&c->scanner_channel);
    laz_model_free(&c->return_number_gps_same);
    free_slots(c->number_of_returns, 16);
    free_slots(c->return_number, 16);
    free_slots(c->classification, 64);
    free_slots(c->flags, 64);
    free_slots(c->user_data, 64);
    laz_ic_free(&c->ic_dx);
    laz_ic_free(&c->ic_dy);
    laz_ic_free(&c->ic_z);
    laz_ic_free(&c->ic_intensity);
    laz_ic_free(&c->ic_scan_angle);
    laz_ic_free(&c->ic_point_source);
    laz_model_free(&c->gps.multi);
    laz_model_free(&c->gps.zero_diff);
    laz_ic_free(&c->gps.ic);
    laz_rgb_models_free(&c->rgb);
    laz_model_free(&c->nir_used);
    laz_model_free(&c->nir_diff[0]);
    laz_model_free(&c->nir_diff[1]);
    if (c->byte_models)
        for (unsigned i = 0; i < extra; i++) laz_model_free(&c->byte_models[i]);
    free(c->byte_models);
    free(c->last_bytes);
}

static void state14_free(state14 *s)
{
    for (int c = 0; c < 4; c++) ctx_free(&s->ctx[c], s->extra);
    laz_model_free(&s->fallback);
}

/* The POINT14 part of a context, from the item it starts at. */
static void ctx_start_point(state14 *s, unsigned channel, const p14 *from)
{
    ctx14 *c = &s->ctx[channel];
    const int dec = s->decoding;
    int bad = 0;
    for (int i = 0; i < 8; i++) bad |= laz_model_init(&c->changed_values[i], 128, dec);
    bad |= laz_model_init(&c->scanner_channel, 3, dec) | laz_model_init(&c->return_number_gps_same, 13, dec);
    bad |= laz_ic_init(&c->ic_dx, 32, 2, dec) | laz_ic_init(&c->ic_dy, 32, 22, dec) | laz_ic_init(&c->ic_z, 32, 20, dec);
    bad |= laz_ic_init(&c->ic_intensity, 16, 4, dec) | laz_ic_init(&c->ic_scan_angle, 16, 2, dec);
    bad |= laz_ic_init(&c->ic_point_source, 16, 1, dec);
    bad |= laz_model_init(&c->gps.multi, GPS14_TOTAL, dec) | laz_model_init(&c->gps.zero_diff, 5, dec);
    bad |= laz_ic_init(&c->gps.ic, 32, 9, dec);
    if (bad) s->failed = 1;
    for (int i = 0; i < 12; i++) {
        laz_median5_init(&c->x_med[i]);
        laz_median5_init(&c->y_med[i]);
    }
    for (int i = 0; i < 8; i++) {
        c->last_z[i] = from->z;
        c->last_intensity[i] = from->intensity;
    }
    c->gps.last = c->gps.next = 0;
    memset(c->gps.last_diff, 0, sizeof c->gps.last_diff);
    memset(c->gps.extreme_count, 0, sizeof c->gps.extreme_count);
    c->gps.last_time[0] = from->gps;
    c->gps.last_time[1] = c->gps.last_time[2] = c->gps.last_time[3] = 0;
    c->last = *from;
    c->last.gps_change = 0;
    c->used = 1;
}

static void ctx_start_rgb(state14 *s, unsigned channel, const uint16_t from[4])
{
    ctx14 *c = &s->ctx[channel];
    int bad = 0;
    if (s->has_rgb) bad |= laz_rgb_models_init(&c->rgb, s->decoding);
    if (s->has_nir) {
        bad |= laz_model_init(&c->nir_used, 4, s->decoding);
        bad |= laz_model_init(&c->nir_diff[0], 256, s->decoding) | laz_model_init(&c->nir_diff[1], 256, s->decoding);
    }
    if (bad) s->failed = 1;
    memcpy(c->last_rgb, from, sizeof c->last_rgb);
    c->rgb_used = 1;
}

static void ctx_start_bytes(state14 *s, unsigned channel, const unsigned char *from)
{
    ctx14 *c = &s->ctx[channel];
    c->last_bytes = malloc(s->extra);
    c->byte_models = calloc(s->extra, sizeof(laz_model));
    if (!c->last_bytes || !c->byte_models) {
        s->failed = 1;
        free(c->byte_models);
        c->byte_models = NULL;
        if (c->last_bytes) memcpy(c->last_bytes, from, s->extra);
        else c->last_bytes = NULL;
        c->bytes_used = 0;
        return;
    }
    for (unsigned i = 0; i < s->extra; i++)
        if (laz_model_init(&c->byte_models[i], 256, s->decoding)) s->failed = 1;
    memcpy(c->last_bytes, from, s->extra);
    c->bytes_used = 1;
}

static int state14_init(state14 *s, const laz_layout *L, const unsigned char *first, int decoding)
{
    memset(s, 0, sizeof *s);
    s->decoding = decoding;
    s->has_rgb = L->format >= 7;
    s->has_nir = L->format == 8;
    s->extra = L->extra;
    if (laz_model_init(&s->fallback, 256, decoding)) return -1;
    p14 p;
    unpack14(first, &p);
    s->current = s->rgb_current = s->bytes_current = p.channel;
    ctx_start_point(s, p.channel, &p);
    if (s->has_rgb) {
        uint16_t rgb[4] = {las_u16(first + 30), las_u16(first + 32), las_u16(first + 34),
                           s->has_nir ? las_u16(first + 36) : 0};
        ctx_start_rgb(s, p.channel, rgb);
    }
    if (s->extra) ctx_start_bytes(s, p.channel, first + (L->record_length - L->extra));
    return s->failed ? -1 : 0;
}

/* RGB14 and BYTE14 follow POINT14's scanner channel. A channel seen for the
 * first time starts from the previous point's values; on a switch to a
 * channel already in use LASzip keeps predicting from the previous
 * channel's last values (with the new channel's models) for that point, and
 * writes them back there. That is the format as LASzip defines it, so both
 * directions do the same. */
static ctx14 *follow_rgb(state14 *s, uint16_t **last)
{
    ctx14 *c = &s->ctx[s->rgb_current];
    *last = c->last_rgb;
    if (s->rgb_current != s->current) {
        s->rgb_current = s->current;
        if (!s->ctx[s->current].rgb_used) {
            ctx_start_rgb(s, s->current, *last);
            *last = s->ctx[s->current].last_rgb;
        }
        c = &s->ctx[s->current];
    }
    return c;
}

static ctx14 *follow_bytes(state14 *s, unsigned char **last)
{
    ctx14 *c = &s->ctx[s->bytes_current];
    *last = c->last_bytes;
    if (s->bytes_current != s->current) {
        s->bytes_current = s->current;
        if (!s->ctx[s->current].bytes_used) {
            ctx_start_bytes(s, s->current, *last);
            *last = s->ctx[s->current].last_bytes;
        }
        c = &s->ctx[s->current];
    }
    return c;
}

static laz_model *lazy(state14 *s, laz_model **slot, uint32_t symbols)
{
    return laz_lazy_model(slot, symbols, s->decoding, &s->failed, &s->fallback);
}

/* POINT14's GPS time: "unchanged" lives in the point's change bits, so the
 * zero-difference model has five symbols and the full-value code is 511. */
static const laz_gps_codes gps_codes_v3 = {-1, 0, 1, 1, -1, GPS14_CODE_FULL};

static inline uint32_t even(uint32_t k) { return k & ~1u; }

/* The layer decoders of one chunk; present[i] is 0 for an empty layer
 * (the field is constant over the chunk). */
typedef struct {
    laz_decoder point[N_POINT_LAYERS], rgb, nir, *bytes;
    int present[N_POINT_LAYERS], rgb_present, nir_present, *bytes_present;
} layers;

static void decode_point14(state14 *s, layers *ly, unsigned char *out)
{
    laz_decoder *xy = &ly->point[L_XY];
    ctx14 *c = &s->ctx[s->current];
    unsigned lpr = (c->last.rn == 1) + 2u * (c->last.rn >= c->last.nr) + 4u * (unsigned)c->last.gps_change;
    uint32_t changed = laz_dec_symbol(xy, &c->changed_values[lpr]);
    if (changed & 64) {
        unsigned channel = (s->current + laz_dec_symbol(xy, &c->scanner_channel) + 1) % 4;
        if (!s->ctx[channel].used) ctx_start_point(s, channel, &c->last);
        s->current = channel;
        c = &s->ctx[channel];
        c->last.channel = channel;
    }
    int point_source_change = (changed >> 5) & 1, gps_change = (changed >> 4) & 1, angle_change = (changed >> 3) & 1;
    p14 *p = &c->last;
    unsigned last_n = p->nr, last_r = p->rn, n = last_n, r = last_r;
    if (changed & 4) p->nr = n = laz_dec_symbol(xy, lazy(s, &c->number_of_returns[last_n], 16));
    switch (changed & 3) {
    case 1: r = (last_r + 1) % 16; break;
    case 2: r = (last_r + 15) % 16; break;
    case 3:
        if (gps_change) r = laz_dec_symbol(xy, lazy(s, &c->return_number[last_r], 16));
        else r = (last_r + laz_dec_symbol(xy, &c->return_number_gps_same) + 2) % 16;
        break;
    default: break;
    }
    p->rn = r;
    unsigned m = return_map_6ctx[n][r], l = level_8ctx(n, r);
    unsigned cpr = (r == 1 ? 2u : 0u) + (r >= n ? 1u : 0u);
    unsigned xi = (m << 1) | (unsigned)gps_change;
    int32_t diff = laz_ic_decompress(&c->ic_dx, xy, c->x_med[xi].v[2], n == 1);
    p->x = (int32_t)((uint32_t)p->x + (uint32_t)diff);
    laz_median5_add(&c->x_med[xi], diff);
    uint32_t k = c->ic_dx.k;
    diff = laz_ic_decompress(&c->ic_dy, xy, c->y_med[xi].v[2], (n == 1) + (k < 20 ? even(k) : 20));
    p->y = (int32_t)((uint32_t)p->y + (uint32_t)diff);
    laz_median5_add(&c->y_med[xi], diff);
    if (ly->present[L_Z]) {
        k = (c->ic_dx.k + c->ic_dy.k) / 2;
        p->z = laz_ic_decompress(&c->ic_z, &ly->point[L_Z], c->last_z[l], (n == 1) + (k < 18 ? even(k) : 18));
        c->last_z[l] = p->z;
    }
    if (ly->present[L_CLASS]) {
        unsigned ccc = ((p->classification & 0x1F) << 1) + (cpr == 3);
        p->classification = laz_dec_symbol(&ly->point[L_CLASS], lazy(s, &c->classification[ccc], 256));
    }
    if (ly->present[L_FLAGS]) {
        unsigned last_flags = p->edge << 5 | p->scan_dir << 4 | p->class_flags;
        unsigned flags = laz_dec_symbol(&ly->point[L_FLAGS], lazy(s, &c->flags[last_flags], 64));
        p->edge = (flags >> 5) & 1;
        p->scan_dir = (flags >> 4) & 1;
        p->class_flags = flags & 0x0F;
    }
    if (ly->present[L_INTENSITY]) {
        unsigned ii = (cpr << 1) | (unsigned)gps_change;
        p->intensity =
            (uint16_t)laz_ic_decompress(&c->ic_intensity, &ly->point[L_INTENSITY], c->last_intensity[ii], cpr);
        c->last_intensity[ii] = p->intensity;
    }
    if (ly->present[L_SCAN_ANGLE] && angle_change)
        p->scan_angle = (int16_t)(uint16_t)laz_ic_decompress(&c->ic_scan_angle, &ly->point[L_SCAN_ANGLE],
                                                             p->scan_angle, (uint32_t)gps_change);
    if (ly->present[L_USER_DATA])
        p->user_data = laz_dec_symbol(&ly->point[L_USER_DATA], lazy(s, &c->user_data[p->user_data / 4], 256));
    if (ly->present[L_POINT_SOURCE] && point_source_change)
        p->point_source =
            (uint16_t)laz_ic_decompress(&c->ic_point_source, &ly->point[L_POINT_SOURCE], p->point_source, 0);
    if (ly->present[L_GPS] && gps_change) {
        laz_gps_decode(&c->gps, &ly->point[L_GPS], &gps_codes_v3);
        p->gps = c->gps.last_time[c->gps.last];
    }
    pack14(p, out);
    p->gps_change = gps_change;
}

static void decode_rgb14(state14 *s, layers *ly, unsigned char *out)
{
    uint16_t *last;
    ctx14 *c = follow_rgb(s, &last);
    if (ly->rgb_present) {
        uint16_t rgb[3];
        laz_rgb_decode(&ly->rgb, &c->rgb, last, rgb);
        memcpy(last, rgb, sizeof rgb);
    }
    for (int k = 0; k < 3; k++) las_put_u16(out + 30 + 2 * k, last[k]);
    if (!s->has_nir) return;
    if (ly->nir_present) {
        uint32_t sym = laz_dec_symbol(&ly->nir, &c->nir_used);
        unsigned lo = last[3] & 0xFF, hi = last[3] >> 8;
        if (sym & 1) lo = (laz_dec_symbol(&ly->nir, &c->nir_diff[0]) + lo) & 0xFF;
        if (sym & 2) hi = (laz_dec_symbol(&ly->nir, &c->nir_diff[1]) + hi) & 0xFF;
        last[3] = (uint16_t)(lo | hi << 8);
    }
    las_put_u16(out + 36, last[3]);
}

static void decode_bytes14(state14 *s, layers *ly, unsigned char *out)
{
    unsigned char *last;
    ctx14 *c = follow_bytes(s, &last);
    if (!c->bytes_used || !last) return; /* out of memory: reported at the chunk's end */
    for (unsigned i = 0; i < s->extra; i++) {
        if (ly->bytes_present[i])
            last[i] = (unsigned char)(last[i] + laz_dec_symbol(&ly->bytes[i], &c->byte_models[i]));
        out[i] = last[i];
    }
}

int laz_chunk14_decode(const laz_layout *L, const unsigned char *in, size_t len, uint32_t n, unsigned char *out,
                       const char **why)
{
    const size_t rl = L->record_length;
    const unsigned n_layers = N_POINT_LAYERS + (L->format >= 7) + (L->format == 8) + L->extra;
    if (len < rl + 4 + 4 * (size_t)n_layers) {
        *why = "chunk shorter than its first point and layer sizes";
        return LAZ_CORRUPT;
    }
    memcpy(out, in, rl);
    uint32_t count = las_u32(in + rl);
    if (count != n) {
        *why = "chunk point count disagrees with the chunk table";
        return LAZ_CORRUPT;
    }
    const unsigned char *sizes = in + rl + 4, *at = sizes + 4 * (size_t)n_layers, *end = in + len;
    layers ly;
    memset(&ly, 0, sizeof ly);
    ly.bytes = calloc(L->extra ? L->extra : 1, sizeof(laz_decoder));
    ly.bytes_present = calloc(L->extra ? L->extra : 1, sizeof(int));
    if (!ly.bytes || !ly.bytes_present) {
        free(ly.bytes);
        free(ly.bytes_present);
        return LAZ_NOMEM;
    }
    int corrupt = 0;
    for (unsigned i = 0; i < n_layers; i++) {
        uint32_t size = las_u32(sizes + 4 * i);
        if (size > (size_t)(end - at)) {
            corrupt = 1;
            break;
        }
        laz_decoder *d;
        int *present;
        if (i < N_POINT_LAYERS) {
            d = &ly.point[i];
            present = &ly.present[i];
        } else if (L->format >= 7 && i == N_POINT_LAYERS) {
            d = &ly.rgb;
            present = &ly.rgb_present;
        } else if (L->format == 8 && i == N_POINT_LAYERS + 1) {
            d = &ly.nir;
            present = &ly.nir_present;
        } else {
            unsigned b = i - N_POINT_LAYERS - (L->format >= 7) - (L->format == 8);
            d = &ly.bytes[b];
            present = &ly.bytes_present[b];
        }
        *present = size > 0;
        if (size) laz_dec_init(d, at, size);
        at += size;
    }
    if (corrupt || (n > 1 && !ly.present[L_XY])) {
        free(ly.bytes);
        free(ly.bytes_present);
        *why = corrupt ? "layer sizes run past the chunk" : "chunk has no coordinate layer";
        return LAZ_CORRUPT;
    }
    state14 s;
    int rc = state14_init(&s, L, out, 1) ? LAZ_NOMEM : LAZ_OK;
    const size_t extra_at = rl - L->extra;
    size_t overrun = 0;
    for (uint32_t i = 1; rc == LAZ_OK && i < n && !overrun; i++) {
        unsigned char *rec = out + i * rl;
        decode_point14(&s, &ly, rec);
        if (s.has_rgb) decode_rgb14(&s, &ly, rec);
        if (s.extra) decode_bytes14(&s, &ly, rec + extra_at);
        if (s.failed) rc = LAZ_NOMEM;
        /* checking every layer each point bounds the work a corrupt chunk can cause */
        overrun = ly.point[L_XY].overrun;
    }
    for (unsigned i = 0; i < N_POINT_LAYERS; i++) overrun += ly.point[i].overrun;
    overrun += ly.rgb.overrun + ly.nir.overrun;
    for (unsigned b = 0; b < L->extra; b++) overrun += ly.bytes[b].overrun;
    state14_free(&s);
    free(ly.bytes);
    free(ly.bytes_present);
    if (rc == LAZ_OK && overrun) {
        *why = "truncated or corrupt chunk (a layer's bytes ran out before its points)";
        rc = LAZ_CORRUPT;
    }
    return rc;
}

/* ---- encoding ---- */

typedef struct {
    laz_buf buf[N_POINT_LAYERS], rgb_buf, nir_buf, *bytes_buf;
    laz_encoder point[N_POINT_LAYERS], rgb, nir, *bytes;
    int changed[N_POINT_LAYERS], rgb_changed, nir_changed, *bytes_changed;
} out_layers;

static void encode_point14(state14 *s, out_layers *o, const p14 *item)
{
    laz_encoder *xy = &o->point[L_XY];
    ctx14 *c = &s->ctx[s->current];
    const p14 *last = &c->last;
    unsigned lpr = (last->rn == 1) + 2u * (last->rn >= last->nr) + 4u * (unsigned)last->gps_change;
    unsigned channel = item->channel;
    if (channel != s->current && s->ctx[channel].used) last = &s->ctx[channel].last;
    int point_source_change = item->point_source != last->point_source;
    int gps_change = item->gps != last->gps; /* bit patterns: -0.0 and NaNs survive */
    int angle_change = item->scan_angle != last->scan_angle;
    unsigned last_n = last->nr, last_r = last->rn, n = item->nr, r = item->rn;
    uint32_t changed = (uint32_t)(channel != s->current) << 6 | (uint32_t)point_source_change << 5 |
                       (uint32_t)gps_change << 4 | (uint32_t)angle_change << 3 | (uint32_t)(n != last_n) << 2;
    if (r != last_r) changed |= r == (last_r + 1) % 16 ? 1u : r == (last_r + 15) % 16 ? 2u : 3u;
    laz_enc_symbol(xy, &c->changed_values[lpr], changed);
    if (channel != s->current) {
        int diff = (int)channel - (int)s->current;
        laz_enc_symbol(xy, &c->scanner_channel, (uint32_t)(diff > 0 ? diff - 1 : diff + 4 - 1));
        if (!s->ctx[channel].used) ctx_start_point(s, channel, &c->last);
        s->current = channel;
        c = &s->ctx[channel];
        last = &c->last;
    }
    if (changed & 4) laz_enc_symbol(xy, lazy(s, &c->number_of_returns[last_n], 16), n);
    if ((changed & 3) == 3) {
        if (gps_change) {
            laz_enc_symbol(xy, lazy(s, &c->return_number[last_r], 16), r);
        } else {
            int diff = (int)r - (int)last_r;
            laz_enc_symbol(xy, &c->return_number_gps_same, (uint32_t)(diff > 1 ? diff - 2 : diff + 16 - 2));
        }
    }
    unsigned m = return_map_6ctx[n][r], l = level_8ctx(n, r);
    unsigned cpr = (r == 1 ? 2u : 0u) + (r >= n ? 1u : 0u);
    unsigned xi = (m << 1) | (unsigned)gps_change;
    int32_t diff = (int32_t)((uint32_t)item->x - (uint32_t)last->x);
    laz_ic_compress(&c->ic_dx, xy, c->x_med[xi].v[2], diff, n == 1);
    laz_median5_add(&c->x_med[xi], diff);
    uint32_t k = c->ic_dx.k;
    diff = (int32_t)((uint32_t)item->y - (uint32_t)last->y);
    laz_ic_compress(&c->ic_dy, xy, c->y_med[xi].v[2], diff, (n == 1) + (k < 20 ? even(k) : 20));
    laz_median5_add(&c->y_med[xi], diff);
    k = (c->ic_dx.k + c->ic_dy.k) / 2;
    laz_ic_compress(&c->ic_z, &o->point[L_Z], c->last_z[l], item->z, (n == 1) + (k < 18 ? even(k) : 18));
    c->last_z[l] = item->z;
    if (item->classification != last->classification) o->changed[L_CLASS] = 1;
    unsigned ccc = ((last->classification & 0x1F) << 1) + (cpr == 3);
    laz_enc_symbol(&o->point[L_CLASS], lazy(s, &c->classification[ccc], 256), item->classification);
    unsigned last_flags = last->edge << 5 | last->scan_dir << 4 | last->class_flags;
    unsigned flags = item->edge << 5 | item->scan_dir << 4 | item->class_flags;
    if (flags != last_flags) o->changed[L_FLAGS] = 1;
    laz_enc_symbol(&o->point[L_FLAGS], lazy(s, &c->flags[last_flags], 64), flags);
    if (item->intensity != last->intensity) o->changed[L_INTENSITY] = 1;
    unsigned ii = (cpr << 1) | (unsigned)gps_change;
    laz_ic_compress(&c->ic_intensity, &o->point[L_INTENSITY], c->last_intensity[ii], item->intensity, cpr);
    c->last_intensity[ii] = item->intensity;
    if (angle_change) {
        o->changed[L_SCAN_ANGLE] = 1;
        laz_ic_compress(&c->ic_scan_angle, &o->point[L_SCAN_ANGLE], last->scan_angle, item->scan_angle,
                        (uint32_t)gps_change);
    }
    if (item->user_data != last->user_data) o->changed[L_USER_DATA] = 1;
    laz_enc_symbol(&o->point[L_USER_DATA], lazy(s, &c->user_data[last->user_data / 4], 256), item->user_data);
    if (point_source_change) {
        o->changed[L_POINT_SOURCE] = 1;
        laz_ic_compress(&c->ic_point_source, &o->point[L_POINT_SOURCE], last->point_source, item->point_source, 0);
    }
    if (gps_change) {
        o->changed[L_GPS] = 1;
        laz_gps_encode(&c->gps, &o->point[L_GPS], item->gps, &gps_codes_v3);
    }
    c->last = *item;
    c->last.gps_change = gps_change;
}

static void encode_rgb14(state14 *s, out_layers *o, const unsigned char *rec)
{
    uint16_t *last;
    ctx14 *c = follow_rgb(s, &last);
    uint16_t cur[3] = {las_u16(rec + 30), las_u16(rec + 32), las_u16(rec + 34)};
    if (memcmp(cur, last, sizeof cur) != 0) o->rgb_changed = 1;
    laz_rgb_encode(&o->rgb, &c->rgb, last, cur);
    memcpy(last, cur, sizeof cur);
    if (!s->has_nir) return;
    uint16_t nir = las_u16(rec + 36);
    unsigned lo = nir & 0xFF, hi = nir >> 8, llo = last[3] & 0xFF, lhi = last[3] >> 8;
    uint32_t sym = (uint32_t)(lo != llo) | (uint32_t)(hi != lhi) << 1;
    laz_enc_symbol(&o->nir, &c->nir_used, sym);
    if (sym & 1) laz_enc_symbol(&o->nir, &c->nir_diff[0], (lo - llo) & 0xFF);
    if (sym & 2) laz_enc_symbol(&o->nir, &c->nir_diff[1], (hi - lhi) & 0xFF);
    if (sym) o->nir_changed = 1;
    last[3] = nir;
}

static void encode_bytes14(state14 *s, out_layers *o, const unsigned char *bytes)
{
    unsigned char *last;
    ctx14 *c = follow_bytes(s, &last);
    if (!c->bytes_used || !last) return;
    for (unsigned i = 0; i < s->extra; i++) {
        unsigned diff = (unsigned)(bytes[i] - last[i]) & 0xFF;
        laz_enc_symbol(&o->bytes[i], &c->byte_models[i], diff);
        if (diff) o->bytes_changed[i] = 1;
        last[i] = bytes[i];
    }
}

int laz_chunk14_encode(const laz_layout *L, const unsigned char *records, uint32_t n, laz_buf *out)
{
    const size_t rl = L->record_length;
    const unsigned extra = L->extra;
    out_layers o;
    memset(&o, 0, sizeof o);
    o.bytes_buf = calloc(extra ? extra : 1, sizeof(laz_buf));
    o.bytes = calloc(extra ? extra : 1, sizeof(laz_encoder));
    o.bytes_changed = calloc(extra ? extra : 1, sizeof(int));
    state14 s;
    int rc = state14_init(&s, L, records, 0);
    if (rc || !o.bytes_buf || !o.bytes || !o.bytes_changed) rc = LAZ_NOMEM;
    if (rc == LAZ_OK) {
        for (int i = 0; i < N_POINT_LAYERS; i++) laz_enc_init(&o.point[i], &o.buf[i]);
        laz_enc_init(&o.rgb, &o.rgb_buf);
        laz_enc_init(&o.nir, &o.nir_buf);
        for (unsigned b = 0; b < extra; b++) laz_enc_init(&o.bytes[b], &o.bytes_buf[b]);
        const size_t extra_at = rl - extra;
        for (uint32_t i = 1; i < n; i++) {
            const unsigned char *rec = records + i * rl;
            p14 item;
            unpack14(rec, &item);
            encode_point14(&s, &o, &item);
            if (s.has_rgb) encode_rgb14(&s, &o, rec);
            if (extra) encode_bytes14(&s, &o, rec + extra_at);
        }
        /* XY and Z always go out; a layer whose field never changed is dropped */
        o.changed[L_XY] = o.changed[L_Z] = 1;
        laz_buf_put(out, records, rl);
        unsigned char word[4];
        las_put_u32(word, n);
        laz_buf_put(out, word, 4);
        for (int pass = 0; pass < 2; pass++) { /* sizes, then the bytes */
            for (int i = 0; i < N_POINT_LAYERS + 2 + (int)extra; i++) {
                laz_buf *b;
                laz_encoder *e;
                int used;
                if (i < N_POINT_LAYERS) {
                    b = &o.buf[i];
                    e = &o.point[i];
                    used = o.changed[i];
                } else if (i == N_POINT_LAYERS) {
                    if (!s.has_rgb) continue;
                    b = &o.rgb_buf;
                    e = &o.rgb;
                    used = o.rgb_changed;
                } else if (i == N_POINT_LAYERS + 1) {
                    if (!s.has_nir) continue;
                    b = &o.nir_buf;
                    e = &o.nir;
                    used = o.nir_changed;
                } else {
                    unsigned k = (unsigned)i - N_POINT_LAYERS - 2;
                    b = &o.bytes_buf[k];
                    e = &o.bytes[k];
                    used = o.bytes_changed[k];
                }
                if (pass == 0) {
                    if (used) laz_enc_done(e);
                    las_put_u32(word, used ? (uint32_t)b->len : 0);
                    laz_buf_put(out, word, 4);
                } else if (used) {
                    laz_buf_put(out, b->data, b->len);
                }
                if (b->failed) rc = LAZ_NOMEM;
            }
        }
    }
    if (s.failed || out->failed) rc = LAZ_NOMEM;
    state14_free(&s);
    for (int i = 0; i < N_POINT_LAYERS; i++) free(o.buf[i].data);
    free(o.rgb_buf.data);
    free(o.nir_buf.data);
    if (o.bytes_buf)
        for (unsigned b = 0; b < extra; b++) free(o.bytes_buf[b].data);
    free(o.bytes_buf);
    free(o.bytes);
    free(o.bytes_changed);
    return rc;
}
