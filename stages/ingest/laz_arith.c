/* LASzip's adaptive models, range coder ends and integer compressor; see
 * laz_codec.h. The model update rules (halving at the count limits, the
 * update cycle growing by 5/4 up to a cap) follow Said's adaptive coder as
 * LASzip adopted it; they must match bit for bit. */
#include <stdlib.h>
#include <string.h>

#include "laz_codec.h"

void laz_bit_model_init(laz_bit_model *m)
{
    m->bit_0_count = 1;
    m->bit_count = 2;
    m->bit_0_prob = 1u << (LAZ_BIT_SHIFT - 1);
    m->update_cycle = m->bits_until_update = 4;
}

void laz_bit_model_update(laz_bit_model *m)
{
    if ((m->bit_count += m->update_cycle) > LAZ_BIT_MAX_COUNT) {
        m->bit_count = (m->bit_count + 1) >> 1;
        m->bit_0_count = (m->bit_0_count + 1) >> 1;
        if (m->bit_0_count == m->bit_count) ++m->bit_count;
    }
    uint32_t scale = 0x80000000u / m->bit_count;
    m->bit_0_prob = (m->bit_0_count * scale) >> (31 - LAZ_BIT_SHIFT);
    m->update_cycle = (5 * m->update_cycle) >> 2;
    if (m->update_cycle > 64) m->update_cycle = 64;
    m->bits_until_update = m->update_cycle;
}

int laz_model_init(laz_model *m, uint32_t symbols, int decoding)
{
    memset(m, 0, sizeof *m);
    if (symbols < 2 || symbols > 2048) return -1;
    m->symbols = symbols;
    m->last_symbol = symbols - 1;
    size_t words = 2 * (size_t)symbols;
    if (decoding && symbols > 16) {
        uint32_t table_bits = 3;
        while (symbols > (1u << (table_bits + 2))) ++table_bits;
        m->table_size = 1u << table_bits;
        m->table_shift = LAZ_SYM_SHIFT - table_bits;
        words += m->table_size + 2;
    }
    m->distribution = malloc(words * sizeof(uint32_t));
    if (!m->distribution) return -1;
    m->symbol_count = m->distribution + symbols;
    if (m->table_size) m->decoder_table = m->distribution + 2 * symbols;
    for (uint32_t k = 0; k < symbols; k++) m->symbol_count[k] = 1;
    m->total_count = 0;
    m->update_cycle = symbols;
    laz_model_update(m);
    m->symbols_until_update = m->update_cycle = (symbols + 6) >> 1;
    return 0;
}

void laz_model_update(laz_model *m)
{
    if ((m->total_count += m->update_cycle) > LAZ_SYM_MAX_COUNT) {
        m->total_count = 0;
        for (uint32_t n = 0; n < m->symbols; n++)
            m->total_count += (m->symbol_count[n] = (m->symbol_count[n] + 1) >> 1);
    }
    uint32_t sum = 0, s = 0;
    uint32_t scale = 0x80000000u / m->total_count;
    if (!m->decoder_table) {
        for (uint32_t k = 0; k < m->symbols; k++) {
            m->distribution[k] = (scale * sum) >> (31 - LAZ_SYM_SHIFT);
            sum += m->symbol_count[k];
        }
    } else {
        for (uint32_t k = 0; k < m->symbols; k++) {
            m->distribution[k] = (scale * sum) >> (31 - LAZ_SYM_SHIFT);
            sum += m->symbol_count[k];
            uint32_t w = m->distribution[k] >> m->table_shift;
            while (s < w) m->decoder_table[++s] = k - 1;
        }
        m->decoder_table[0] = 0;
        while (s <= m->table_size) m->decoder_table[++s] = m->symbols - 1;
    }
    m->update_cycle = (5 * m->update_cycle) >> 2;
    uint32_t max_cycle = (m->symbols + 6) << 3;
    if (m->update_cycle > max_cycle) m->update_cycle = max_cycle;
    m->symbols_until_update = m->update_cycle;
}

void laz_model_free(laz_model *m)
{
    free(m->distribution);
    m->distribution = NULL;
}

int laz_ic_init(laz_ic *ic, uint32_t bits, uint32_t contexts, int decoding)
{
    memset(ic, 0, sizeof *ic);
    ic->contexts = contexts;
    ic->bits_high = 8;
    if (bits && bits < 32) {
        ic->corr_bits = bits;
        ic->corr_range = 1u << bits;
        ic->corr_min = -(int32_t)(ic->corr_range / 2);
        ic->corr_max = (int32_t)(ic->corr_min + (int64_t)ic->corr_range - 1);
    } else {
        ic->corr_bits = 32;
        ic->corr_range = 0;
        ic->corr_min = INT32_MIN;
        ic->corr_max = INT32_MAX;
    }
    ic->m_bits = calloc(contexts, sizeof(laz_model));
    ic->m_corrector = calloc(ic->corr_bits, sizeof(laz_model));
    if (!ic->m_bits || !ic->m_corrector) {
        laz_ic_free(ic);
        return -1;
    }
    for (uint32_t c = 0; c < contexts; c++)
        if (laz_model_init(&ic->m_bits[c], ic->corr_bits + 1, decoding)) {
            laz_ic_free(ic);
            return -1;
        }
    laz_bit_model_init(&ic->corr0);
    for (uint32_t i = 1; i <= ic->corr_bits; i++) {
        uint32_t symbols = i <= ic->bits_high ? 1u << i : 1u << ic->bits_high;
        if (laz_model_init(&ic->m_corrector[i - 1], symbols, decoding)) {
            laz_ic_free(ic);
            return -1;
        }
    }
    return 0;
}

void laz_ic_free(laz_ic *ic)
{
    if (ic->m_bits)
        for (uint32_t c = 0; c < ic->contexts; c++) laz_model_free(&ic->m_bits[c]);
    if (ic->m_corrector)
        for (uint32_t i = 0; i < ic->corr_bits; i++) laz_model_free(&ic->m_corrector[i]);
    free(ic->m_bits);
    free(ic->m_corrector);
    ic->m_bits = ic->m_corrector = NULL;
}

void laz_dec_init(laz_decoder *d, const unsigned char *data, size_t len)
{
    d->p = data;
    d->end = data + len;
    d->overrun = 0;
    d->length = 0xFFFFFFFFu;
    d->value = 0;
    for (int i = 0; i < 4; i++) {
        uint32_t byte = 0;
        if (d->p < d->end) byte = *d->p++;
        else d->overrun++;
        d->value = (d->value << 8) | byte;
    }
}

/* Up to 19 bits at once keep length >> bits well above zero. */
static uint32_t dec_low_bits(laz_decoder *d, uint32_t bits)
{
    d->length >>= bits;
    uint32_t sym = d->value / d->length;
    d->value -= d->length * sym;
    if (d->length < LAZ_MIN_LENGTH) laz_dec_renorm(d);
    return sym;
}

uint32_t laz_dec_bits(laz_decoder *d, uint32_t bits)
{
    if (bits > 19) {
        uint32_t low = dec_low_bits(d, 16);
        return (laz_dec_bits(d, bits - 16) << 16) | low;
    }
    return dec_low_bits(d, bits);
}

uint32_t laz_dec_int(laz_decoder *d)
{
    uint32_t low = dec_low_bits(d, 16);
    return (dec_low_bits(d, 16) << 16) | low;
}

int32_t laz_ic_decompress(laz_ic *ic, laz_decoder *d, int32_t pred, uint32_t context)
{
    uint32_t k = laz_dec_symbol(d, &ic->m_bits[context]);
    ic->k = k;
    int32_t corr;
    if (k == 0) {
        corr = (int32_t)laz_dec_bit(d, &ic->corr0);
    } else if (k < 32) {
        uint32_t c;
        if (k <= ic->bits_high) {
            c = laz_dec_symbol(d, &ic->m_corrector[k - 1]);
        } else {
            uint32_t k1 = k - ic->bits_high;
            c = laz_dec_symbol(d, &ic->m_corrector[k - 1]);
            c = (c << k1) | laz_dec_bits(d, k1);
        }
        /* c in [0, 2^k): the upper half is positive, the lower maps to negative */
        if (c >= (1u << (k - 1))) corr = (int32_t)(c + 1);
        else corr = (int32_t)(c - ((1u << k) - 1));
    } else {
        corr = ic->corr_min;
    }
    /* Arithmetic modulo the range (2^32 wraps by itself). */
    uint32_t real = (uint32_t)pred + (uint32_t)corr;
    if (ic->corr_range) {
        int32_t r = (int32_t)real;
        if (r < 0) real += ic->corr_range;
        else if (real >= ic->corr_range) real -= ic->corr_range;
    }
    return (int32_t)real;
}

void laz_buf_put(laz_buf *b, const void *data, size_t len)
{
    if (b->failed) return;
    if (len > b->cap - b->len) {
        size_t cap = b->cap ? b->cap : 4096;
        while (cap - b->len < len) cap *= 2;
        unsigned char *grown = realloc(b->data, cap);
        if (!grown) {
            b->failed = 1;
            return;
        }
        b->data = grown;
        b->cap = cap;
    }
    memcpy(b->data + b->len, data, len);
    b->len += len;
}

void laz_enc_init(laz_encoder *e, laz_buf *out)
{
    e->out = out;
    e->start = out->len;
    e->base = 0;
    e->length = 0xFFFFFFFFu;
}

void laz_enc_bits(laz_encoder *e, uint32_t bits, uint32_t value)
{
    if (bits > 19) {
        laz_enc_bits(e, 16, value & 0xFFFF);
        value >>= 16;
        bits -= 16;
    }
    uint32_t init_base = e->base;
    e->base += value * (e->length >>= bits);
    if (init_base > e->base) laz_enc_carry(e);
    if (e->length < LAZ_MIN_LENGTH) laz_enc_renorm(e);
}

void laz_enc_int(laz_encoder *e, uint32_t value)
{
    laz_enc_bits(e, 16, value & 0xFFFF);
    laz_enc_bits(e, 16, value >> 16);
}

/* Flushes the interval so that the decoder's 4-byte look-ahead ends exactly
 * on the last byte written: one or two bytes of base, then zeros. */
void laz_enc_done(laz_encoder *e)
{
    uint32_t init_base = e->base;
    int another_byte = 1;
    if (e->length > 2 * LAZ_MIN_LENGTH) {
        e->base += LAZ_MIN_LENGTH;
        e->length = LAZ_MIN_LENGTH >> 1;
    } else {
        e->base += LAZ_MIN_LENGTH >> 1;
        e->length = LAZ_MIN_LENGTH >> 9;
        another_byte = 0;
    }
    if (init_base > e->base) laz_enc_carry(e);
    laz_enc_renorm(e);
    static const unsigned char zeros[3] = {0, 0, 0};
    laz_buf_put(e->out, zeros, another_byte ? 3 : 2);
}

void laz_ic_compress(laz_ic *ic, laz_encoder *e, int32_t pred, int32_t real, uint32_t context)
{
    /* The residual folded into [corr_min, corr_max] (2^32 wraps by itself). */
    int64_t c64 = (int64_t)real - (int64_t)pred;
    if (ic->corr_range) {
        if (c64 < ic->corr_min) c64 += ic->corr_range;
        else if (c64 > ic->corr_max) c64 -= ic->corr_range;
    }
    int32_t c = ic->corr_range ? (int32_t)c64 : (int32_t)((uint32_t)real - (uint32_t)pred);
    uint32_t c1 = c <= 0 ? (uint32_t)0 - (uint32_t)c : (uint32_t)c - 1;
    uint32_t k = 0;
    while (c1) {
        c1 >>= 1;
        k++;
    }
    ic->k = k;
    laz_enc_symbol(e, &ic->m_bits[context], k);
    if (k == 0) {
        laz_enc_bit(e, &ic->corr0, (uint32_t)c);
    } else if (k < 32) {
        uint32_t u = c < 0 ? (uint32_t)c + ((1u << k) - 1) : (uint32_t)c - 1;
        if (k <= ic->bits_high) {
            laz_enc_symbol(e, &ic->m_corrector[k - 1], u);
        } else {
            uint32_t k1 = k - ic->bits_high;
            laz_enc_symbol(e, &ic->m_corrector[k - 1], u >> k1);
            laz_enc_bits(e, k1, u & ((1u << k1) - 1));
        }
    }
}
