/* The entropy coder of LASzip (Isenburg, "LASzip: lossless compression of
 * LiDAR data", 2013): a 32-bit range coder after Said's "Introduction to
 * arithmetic coding - theory and practice" with adaptive bit and
 * multi-symbol models, and the integer compressor that codes a prediction
 * residual as a bit-length class k (a symbol) followed by the k low bits
 * (the high ones through a per-k model, the rest raw).
 *
 * The update schedules, the fixed-point widths and the order in which
 * symbols are coded are part of the LAZ format: a file decodes only when
 * every one of them matches the writer's, so they are written out here
 * exactly as the format defines them.
 *
 * Decoding never reads outside its buffer: bytes past the end read as 0 and
 * are counted in `overrun`, which the caller turns into a "truncated" error. */
#ifndef SYLVA_LAZ_CODEC_H
#define SYLVA_LAZ_CODEC_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

enum {
    LAZ_MIN_LENGTH = 0x01000000u, /* renormalise below this interval length */
    LAZ_BIT_SHIFT = 13,           /* bit model probabilities in 13 bits */
    LAZ_BIT_MAX_COUNT = 1 << 13,
    LAZ_SYM_SHIFT = 15, /* symbol model distributions in 15 bits */
    LAZ_SYM_MAX_COUNT = 1 << 15,
};

/* Adaptive binary model. */
typedef struct {
    uint32_t bit_0_count, bit_count, bit_0_prob, bits_until_update, update_cycle;
} laz_bit_model;

/* Adaptive model over 2..2048 symbols; the decoder side keeps a lookup table
 * that narrows the search for models over more than 16 symbols. */
typedef struct {
    uint32_t *distribution, *symbol_count, *decoder_table;
    uint32_t symbols, last_symbol, table_size, table_shift;
    uint32_t total_count, update_cycle, symbols_until_update;
} laz_model;

/* A growable output buffer; `failed` records an allocation failure. */
typedef struct {
    unsigned char *data;
    size_t len, cap;
    int failed;
} laz_buf;

typedef struct {
    const unsigned char *p, *end;
    uint32_t value, length;
    size_t overrun; /* bytes wanted past the end, plus 1 for an impossible interval */
} laz_decoder;

typedef struct {
    laz_buf *out;
    size_t start; /* where this coder's bytes begin in out */
    uint32_t base, length;
} laz_encoder;

/* Residual coder for integers of `bits` bits under `contexts` contexts. */
typedef struct {
    uint32_t k; /* bit-length class of the last residual (contexts of later fields use it) */
    uint32_t contexts, bits_high, corr_bits, corr_range;
    int32_t corr_min, corr_max;
    laz_model *m_bits;      /* [contexts], corr_bits + 1 symbols each */
    laz_bit_model corr0;    /* residual 0 or 1 when k == 0 */
    laz_model *m_corrector; /* [corr_bits], index k - 1 */
} laz_ic;

void laz_bit_model_init(laz_bit_model *m);
void laz_bit_model_update(laz_bit_model *m);
/* 0 on success, -1 when out of memory or symbols is outside 2..2048. */
int laz_model_init(laz_model *m, uint32_t symbols, int decoding);
void laz_model_update(laz_model *m);
void laz_model_free(laz_model *m);

/* range 0 means the full 2^bits range. Returns -1 when out of memory. */
int laz_ic_init(laz_ic *ic, uint32_t bits, uint32_t contexts, int decoding);
void laz_ic_free(laz_ic *ic);

/* Decoder: reads the 4 bytes that prime the interval. */
void laz_dec_init(laz_decoder *d, const unsigned char *data, size_t len);
uint32_t laz_dec_bits(laz_decoder *d, uint32_t bits); /* raw bits, 1..32 */
uint32_t laz_dec_int(laz_decoder *d);                 /* raw 32 bits */
int32_t laz_ic_decompress(laz_ic *ic, laz_decoder *d, int32_t pred, uint32_t context);

void laz_buf_put(laz_buf *b, const void *data, size_t len);
void laz_enc_init(laz_encoder *e, laz_buf *out);
void laz_enc_bits(laz_encoder *e, uint32_t bits, uint32_t value);
void laz_enc_int(laz_encoder *e, uint32_t value);
void laz_enc_done(laz_encoder *e);
void laz_ic_compress(laz_ic *ic, laz_encoder *e, int32_t pred, int32_t real, uint32_t context);

/* The hot paths, inline. */
static inline void laz_dec_renorm(laz_decoder *d)
{
    if (d->length == 0) { /* only corrupt data collapses the interval; renormalising would never end */
        d->overrun++;
        d->length = 0xFFFFFFFFu;
        return;
    }
    do {
        uint32_t byte = 0;
        if (d->p < d->end) byte = *d->p++;
        else d->overrun++;
        d->value = (d->value << 8) | byte;
    } while ((d->length <<= 8) < LAZ_MIN_LENGTH);
}

static inline uint32_t laz_dec_bit(laz_decoder *d, laz_bit_model *m)
{
    uint32_t x = m->bit_0_prob * (d->length >> LAZ_BIT_SHIFT);
    uint32_t sym = d->value >= x;
    if (!sym) {
        d->length = x;
        m->bit_0_count++;
    } else {
        d->value -= x;
        d->length -= x;
    }
    if (d->length < LAZ_MIN_LENGTH) laz_dec_renorm(d);
    if (--m->bits_until_update == 0) laz_bit_model_update(m);
    return sym;
}

static inline uint32_t laz_dec_symbol(laz_decoder *d, laz_model *m)
{
    uint32_t n, sym, x, y = d->length;
    if (m->decoder_table) {
        d->length >>= LAZ_SYM_SHIFT;
        uint32_t dv = d->value / d->length;
        uint32_t t = dv >> m->table_shift;
        if (t > m->table_size) t = m->table_size; /* only a corrupt stream gets here */
        sym = m->decoder_table[t];
        n = m->decoder_table[t + 1] + 1;
        while (n > sym + 1) {
            uint32_t k = (sym + n) >> 1;
            if (m->distribution[k] > dv) n = k;
            else sym = k;
        }
        x = m->distribution[sym] * d->length;
        if (sym != m->last_symbol) y = m->distribution[sym + 1] * d->length;
    } else {
        x = sym = 0;
        d->length >>= LAZ_SYM_SHIFT;
        n = m->symbols;
        uint32_t k = n >> 1;
        do {
            uint32_t z = d->length * m->distribution[k];
            if (z > d->value) {
                n = k;
                y = z;
            } else {
                sym = k;
                x = z;
            }
        } while ((k = (sym + n) >> 1) != sym);
    }
    d->value -= x;
    d->length = y - x;
    if (d->length < LAZ_MIN_LENGTH) laz_dec_renorm(d);
    m->symbol_count[sym]++;
    if (--m->symbols_until_update == 0) laz_model_update(m);
    return sym;
}

static inline void laz_enc_carry(laz_encoder *e)
{
    size_t p = e->out->len;
    while (p > e->start) {
        p--;
        if (e->out->data[p] == 0xFF) {
            e->out->data[p] = 0;
        } else {
            e->out->data[p]++;
            return;
        }
    }
}

static inline void laz_enc_byte_out(laz_encoder *e, unsigned char byte)
{
    laz_buf *b = e->out;
    if (b->len == b->cap) {
        laz_buf_put(b, &byte, 1);
        return;
    }
    b->data[b->len++] = byte;
}

static inline void laz_enc_renorm(laz_encoder *e)
{
    do {
        laz_enc_byte_out(e, (unsigned char)(e->base >> 24));
        e->base <<= 8;
    } while ((e->length <<= 8) < LAZ_MIN_LENGTH);
}

static inline void laz_enc_bit(laz_encoder *e, laz_bit_model *m, uint32_t sym)
{
    uint32_t x = m->bit_0_prob * (e->length >> LAZ_BIT_SHIFT);
    if (sym == 0) {
        e->length = x;
        m->bit_0_count++;
    } else {
        uint32_t init_base = e->base;
        e->base += x;
        e->length -= x;
        if (init_base > e->base) laz_enc_carry(e);
    }
    if (e->length < LAZ_MIN_LENGTH) laz_enc_renorm(e);
    if (--m->bits_until_update == 0) laz_bit_model_update(m);
}

static inline void laz_enc_symbol(laz_encoder *e, laz_model *m, uint32_t sym)
{
    uint32_t x, init_base = e->base;
    if (sym == m->last_symbol) {
        x = m->distribution[sym] * (e->length >> LAZ_SYM_SHIFT);
        e->base += x;
        e->length -= x;
    } else {
        e->length >>= LAZ_SYM_SHIFT;
        x = m->distribution[sym] * e->length;
        e->base += x;
        e->length = m->distribution[sym + 1] * e->length - x;
    }
    if (init_base > e->base) laz_enc_carry(e);
    if (e->length < LAZ_MIN_LENGTH) laz_enc_renorm(e);
    m->symbol_count[sym]++;
    if (--m->symbols_until_update == 0) laz_model_update(m);
}

#ifdef __cplusplus
}
#endif

#endif
