/* LAZ files: the LASzip VLR, the chunk table and the chunked point block
 * (LAZ 1.4 specification). A LAZ file is a LAS file whose point format has
 * bit 7 set, with a "laszip encoded"/22204 VLR naming the compressed items;
 * its point block starts with the 64-bit offset of the chunk table, then the
 * chunks, each decodable on its own, then the table: version 0, the chunk
 * count, and the per-chunk byte sizes (and point counts when chunks vary in
 * size) coded with the integer compressor against the previous entry. */
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "../core/parallel.h"
#include "laz.h"

enum {
    ITEM_BYTE = 0,
    ITEM_POINT10 = 6,
    ITEM_GPSTIME11 = 7,
    ITEM_RGB12 = 8,
    ITEM_POINT14 = 10,
    ITEM_RGB14 = 11,
    ITEM_RGBNIR14 = 12,
    ITEM_BYTE14 = 14,
    COMPRESSOR_POINTWISE_CHUNKED = 2,
    COMPRESSOR_LAYERED_CHUNKED = 3,
    VLR_ITEMS_AT = 34,
    /* Coding costs at least ~0.003 bits per symbol at LASzip's model
     * precision, and a point codes several symbols, so no valid chunk holds
     * more points than this per byte; it bounds what a header can make us
     * allocate. */
    MAX_POINTS_PER_BYTE = 2048,
};

int laz_decode_chunk(const laz_layout *L, const unsigned char *in, size_t len, uint32_t n, unsigned char *out,
                     const char **why)
{
    return L->layered ? laz_chunk14_decode(L, in, len, n, out, why) : laz_chunk10_decode(L, in, len, n, out, why);
}

int laz_encode_chunk(const laz_layout *L, const unsigned char *records, uint32_t n, laz_buf *out)
{
    return L->layered ? laz_chunk14_encode(L, records, n, out) : laz_chunk10_encode(L, records, n, out);
}

static const char *item_name(unsigned type)
{
    switch (type) {
    case ITEM_BYTE: return "BYTE";
    case ITEM_POINT10: return "POINT10";
    case ITEM_GPSTIME11: return "GPSTIME11";
    case ITEM_RGB12: return "RGB12";
    case 9: return "WAVEPACKET13";
    case ITEM_POINT14: return "POINT14";
    case ITEM_RGB14: return "RGB14";
    case ITEM_RGBNIR14: return "RGBNIR14";
    case 13: return "WAVEPACKET14";
    case ITEM_BYTE14: return "BYTE14";
    default: return "unknown";
    }
}

/* The items a format's records need, in record order. */
static unsigned expected_items(int format, unsigned extra, unsigned types[4], unsigned sizes[4], unsigned *version)
{
    unsigned n = 0;
    if (format <= 3) {
        *version = 2;
        types[n] = ITEM_POINT10, sizes[n++] = 20;
        if (format == 1 || format == 3) types[n] = ITEM_GPSTIME11, sizes[n++] = 8;
        if (format >= 2) types[n] = ITEM_RGB12, sizes[n++] = 6;
        if (extra) types[n] = ITEM_BYTE, sizes[n++] = extra;
    } else {
        *version = 3;
        types[n] = ITEM_POINT14, sizes[n++] = 30;
        if (format == 7) types[n] = ITEM_RGB14, sizes[n++] = 6;
        if (format == 8) types[n] = ITEM_RGBNIR14, sizes[n++] = 8;
        if (extra) types[n] = ITEM_BYTE14, sizes[n++] = extra;
    }
    return n;
}

static unsigned core_size(int format)
{
    static const unsigned sizes[9] = {20, 28, 26, 34, 0, 0, 30, 36, 38};
    return sizes[format];
}

sy_code laz_parse_vlr(const char *path, const unsigned char *v, size_t len, int format, unsigned record_length,
                      laz_layout *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    if (format == 4 || format == 5 || format > 8)
        return sy_fail(err, SY_EINPUT, "%s: LAZ point format %d (waveform data) is not supported", path, format);
    if (len < VLR_ITEMS_AT)
        return sy_fail(err, SY_EINPUT, "%s: LASzip VLR is truncated (%zu bytes)", path, len);
    unsigned compressor = las_u16(v), coder = las_u16(v + 2);
    unsigned n_items = las_u16(v + 32);
    if (len < VLR_ITEMS_AT + 6 * (size_t)n_items)
        return sy_fail(err, SY_EINPUT, "%s: LASzip VLR lists %u items but holds %zu bytes", path, n_items, len);
    if (coder != 0) return sy_fail(err, SY_EINPUT, "%s: LAZ coder %u is not LASzip's arithmetic coder", path, coder);
    int layered = format >= 6;
    unsigned want = layered ? COMPRESSOR_LAYERED_CHUNKED : COMPRESSOR_POINTWISE_CHUNKED;
    if (compressor != want)
        return sy_fail(err, SY_EINPUT, "%s: LAZ compressor %u is not supported for point format %d (expected %u)", path,
                       compressor, format, want);
    if (record_length < core_size(format))
        return sy_fail(err, SY_EINPUT, "%s: record length %u is smaller than point format %d needs", path,
                       record_length, format);
    unsigned extra = record_length - core_size(format);
    unsigned types[4], sizes[4], version;
    unsigned n_want = expected_items(format, extra, types, sizes, &version);
    if (n_items != n_want)
        return sy_fail(err, SY_EINPUT, "%s: LASzip VLR lists %u items, point format %d with %u extra bytes needs %u",
                       path, n_items, format, extra, n_want);
    for (unsigned i = 0; i < n_items; i++) {
        const unsigned char *it = v + VLR_ITEMS_AT + 6 * i;
        unsigned type = las_u16(it), size = las_u16(it + 2), ver = las_u16(it + 4);
        if (type != types[i] || size != sizes[i])
            return sy_fail(err, SY_EINPUT, "%s: LAZ item %u is %s of %u bytes, point format %d needs %s of %u", path,
                           i + 1, item_name(type), size, format, item_name(types[i]), sizes[i]);
        if (ver != version)
            return sy_fail(err, SY_EINPUT, "%s: LAZ item %s version %u is not supported (only version %u)", path,
                           item_name(type), ver, version);
    }
    out->format = format;
    out->record_length = record_length;
    out->extra = extra;
    out->layered = layered;
    out->chunk_size = las_u32(v + 12);
    if (out->chunk_size == 0)
        return sy_fail(err, SY_EINPUT, "%s: LASzip VLR has a chunk size of 0", path);
    return SY_OK;
}

size_t laz_make_vlr(const laz_layout *L, unsigned char out[LAZ_VLR_MAX])
{
    unsigned types[4], sizes[4], version;
    unsigned n = expected_items(L->format, L->extra, types, sizes, &version);
    size_t payload = VLR_ITEMS_AT + 6 * (size_t)n;
    memset(out, 0, LAZ_VLR_MAX);
    memcpy(out + 2, "laszip encoded", 14);
    las_put_u16(out + 18, LAZ_VLR_RECORD_ID);
    las_put_u16(out + 20, (uint16_t)payload);
    memcpy(out + 22, "Sylva LAZ codec", 15);
    unsigned char *v = out + 54;
    las_put_u16(v, L->layered ? COMPRESSOR_LAYERED_CHUNKED : COMPRESSOR_POINTWISE_CHUNKED);
    las_put_u16(v + 2, 0); /* arithmetic coder */
    v[4] = 3;            /* LASzip 3.4 r3 is the version whose items these are */
    v[5] = 4;
    las_put_u16(v + 6, 3);
    las_put_u32(v + 8, 0);
    las_put_u32(v + 12, L->chunk_size);
    las_put_u64(v + 16, UINT64_MAX); /* no special EVLRs */
    las_put_u64(v + 24, UINT64_MAX);
    las_put_u16(v + 32, (uint16_t)n);
    for (unsigned i = 0; i < n; i++) {
        las_put_u16(v + VLR_ITEMS_AT + 6 * i, (uint16_t)types[i]);
        las_put_u16(v + VLR_ITEMS_AT + 6 * i + 2, (uint16_t)sizes[i]);
        las_put_u16(v + VLR_ITEMS_AT + 6 * i + 4, (uint16_t)version);
    }
    return 54 + payload;
}

sy_code laz_read_chunks(const char *path, const unsigned char *data, size_t size, uint64_t point_offset,
                        uint64_t points_end, const laz_layout *L, uint64_t count, laz_chunk **chunks,
                        size_t *n_chunks, sy_error *err)
{
    *chunks = NULL;
    *n_chunks = 0;
    if (points_end > size || point_offset > points_end || points_end - point_offset < 8)
        return sy_fail(err, SY_EINPUT, "%s: LAZ point data too short for its chunk table offset", path);
    uint64_t table = las_u64(data + point_offset);
    if (table == UINT64_MAX) {
        /* written to a stream: the offset follows at the very end of the file */
        if (size < 8) return sy_fail(err, SY_EINPUT, "%s: LAZ chunk table offset missing", path);
        table = las_u64(data + size - 8);
    }
    const uint64_t chunks_start = point_offset + 8;
    if (count == 0) return SY_OK;
    if (table < chunks_start || table > points_end || points_end - table < 8)
        return sy_fail(err, SY_EINPUT, "%s: bad LAZ chunk table offset %llu (point data spans %llu-%llu)", path,
                       (unsigned long long)table, (unsigned long long)chunks_start, (unsigned long long)points_end);
    uint32_t version = las_u32(data + table), n = las_u32(data + table + 4);
    if (version != 0) return sy_fail(err, SY_EINPUT, "%s: LAZ chunk table version %u is not 0", path, version);
    /* Each chunk holds at least its raw first record. */
    uint64_t room = table - chunks_start;
    if (n == 0 || n > room / L->record_length)
        return sy_fail(err, SY_EINPUT, "%s: LAZ chunk table lists %u chunks, the point data has room for %llu", path,
                       n, (unsigned long long)(room / L->record_length));
    int variable = L->chunk_size == UINT32_MAX;
    if (!variable && ((uint64_t)n - 1) * L->chunk_size >= count)
        return sy_fail(err, SY_EINPUT, "%s: LAZ chunk table lists %u chunks of %u points for %llu points", path, n,
                       L->chunk_size, (unsigned long long)count);
    if (!variable && (uint64_t)n * L->chunk_size < count)
        return sy_fail(err, SY_EINPUT, "%s: %u LAZ chunks of %u points cannot hold the header's %llu points", path, n,
                       L->chunk_size, (unsigned long long)count);
    laz_chunk *c = calloc(n, sizeof *c);
    laz_ic ic;
    if (!c || laz_ic_init(&ic, 32, 2, 1)) {
        free(c);
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory for the LAZ chunk table", path);
    }
    laz_decoder d;
    laz_dec_init(&d, data + table + 8, (size_t)(points_end - table - 8));
    uint32_t prev_points = 0, prev_bytes = 0;
    uint64_t at = chunks_start, first = 0;
    sy_code rc = SY_OK;
    for (uint32_t i = 0; i < n && rc == SY_OK; i++) {
        uint32_t points = L->chunk_size;
        if (variable) points = prev_points = (uint32_t)laz_ic_decompress(&ic, &d, (int32_t)prev_points, 0);
        else if (i == n - 1) points = (uint32_t)(count - first);
        uint32_t bytes = prev_bytes = (uint32_t)laz_ic_decompress(&ic, &d, (int32_t)prev_bytes, 1);
        if (d.overrun)
            rc = sy_fail(err, SY_EINPUT, "%s: LAZ chunk table is truncated (entry %u of %u)", path, i + 1, n);
        else if (bytes < L->record_length || bytes > table - at)
            rc = sy_fail(err, SY_EINPUT, "%s: LAZ chunk %u of %u claims %u bytes, %llu remain before the chunk table",
                         path, i + 1, n, bytes, (unsigned long long)(table - at));
        else if (points == 0 || points > count - first || (uint64_t)points > (uint64_t)bytes * MAX_POINTS_PER_BYTE)
            rc = sy_fail(err, SY_EINPUT, "%s: LAZ chunk %u of %u claims %u points in %u bytes (%llu points left)",
                         path, i + 1, n, points, bytes, (unsigned long long)(count - first));
        c[i].offset = at;
        c[i].bytes = bytes;
        c[i].first = first;
        c[i].points = points;
        at += bytes;
        first += points;
    }
    laz_ic_free(&ic);
    if (rc == SY_OK && first != count)
        rc = sy_fail(err, SY_EINPUT, "%s: LAZ chunks hold %llu points, the header promises %llu", path,
                     (unsigned long long)first, (unsigned long long)count);
    if (rc) {
        free(c);
        return rc;
    }
    *chunks = c;
    *n_chunks = n;
    return SY_OK;
}

typedef struct {
    const char *path;
    const unsigned char *data;
    const laz_layout *L;
    const laz_chunk *chunks;
    size_t n_chunks;
    laz_sink sink;
    void *user;
    pthread_mutex_t lock;
    size_t failed_chunk; /* lowest failing chunk, n_chunks when none */
    sy_error failure;
} decode_job;

static void fail_chunk(decode_job *j, size_t chunk, const sy_error *e)
{
    pthread_mutex_lock(&j->lock);
    if (chunk < j->failed_chunk) {
        j->failed_chunk = chunk;
        j->failure = *e;
    }
    pthread_mutex_unlock(&j->lock);
}

static void decode_one(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)begin;
    (void)end;
    decode_job *j = ctx;
    pthread_mutex_lock(&j->lock);
    int skip = j->failed_chunk < chunk; /* an earlier chunk failed: this one cannot change the report */
    pthread_mutex_unlock(&j->lock);
    if (skip) return;
    const laz_chunk *c = &j->chunks[chunk];
    sy_error e;
    sy_error_clear(&e);
    unsigned char *records = malloc((size_t)c->points * j->L->record_length);
    if (!records) {
        sy_fail(&e, SY_EINTERNAL, "%s: out of memory for LAZ chunk %zu", j->path, chunk + 1);
        fail_chunk(j, chunk, &e);
        return;
    }
    const char *why = "";
    int rc = laz_decode_chunk(j->L, j->data + c->offset, (size_t)c->bytes, c->points, records, &why);
    if (rc == LAZ_NOMEM) {
        sy_fail(&e, SY_EINTERNAL, "%s: out of memory decoding LAZ chunk %zu", j->path, chunk + 1);
        fail_chunk(j, chunk, &e);
    } else if (rc) {
        sy_fail(&e, SY_EINPUT, "%s: LAZ chunk %zu of %zu: %s", j->path, chunk + 1, j->n_chunks, why);
        fail_chunk(j, chunk, &e);
    } else if (j->sink(j->user, chunk, c->first, c->points, records, &e)) {
        fail_chunk(j, chunk, &e);
    }
    free(records);
}

sy_code laz_decode_chunks(const char *path, const unsigned char *data, const laz_layout *L, const laz_chunk *chunks,
                          size_t n_chunks, laz_sink sink, void *user, sy_error *err)
{
    decode_job j;
    memset(&j, 0, sizeof j);
    j.path = path;
    j.data = data;
    j.L = L;
    j.chunks = chunks;
    j.n_chunks = n_chunks;
    j.sink = sink;
    j.user = user;
    j.failed_chunk = n_chunks;
    pthread_mutex_init(&j.lock, NULL);
    sy_parallel_for(n_chunks, 1, decode_one, &j);
    pthread_mutex_destroy(&j.lock);
    if (j.failed_chunk < n_chunks) {
        if (err) *err = j.failure;
        return j.failure.code ? j.failure.code : SY_EINTERNAL;
    }
    return SY_OK;
}

typedef struct {
    const laz_layout *L;
    unsigned char **records;
    laz_buf *out;
    uint32_t *points;
    int *rc;
} encode_batch;

static void encode_one(void *ctx, size_t begin, size_t end, size_t k)
{
    (void)begin;
    (void)end;
    encode_batch *b = ctx;
    b->out[k].len = 0;
    b->out[k].failed = 0;
    b->rc[k] = laz_encode_chunk(b->L, b->records[k], b->points[k], &b->out[k]);
}

/* The chunk table: version, count, then (count,) bytes per chunk coded
 * against the previous entry. */
static int write_table(FILE *fp, const laz_layout *L, const uint32_t *points, const uint32_t *bytes, size_t n)
{
    laz_buf buf = {0};
    unsigned char head[8];
    las_put_u32(head, 0);
    las_put_u32(head + 4, (uint32_t)n);
    laz_buf_put(&buf, head, 8);
    laz_ic ic;
    if (laz_ic_init(&ic, 32, 2, 0)) {
        free(buf.data);
        return -1;
    }
    laz_encoder e;
    laz_enc_init(&e, &buf);
    for (size_t i = 0; i < n; i++) {
        if (L->chunk_size == UINT32_MAX) laz_ic_compress(&ic, &e, i ? (int32_t)points[i - 1] : 0, (int32_t)points[i], 0);
        laz_ic_compress(&ic, &e, i ? (int32_t)bytes[i - 1] : 0, (int32_t)bytes[i], 1);
    }
    laz_enc_done(&e);
    laz_ic_free(&ic);
    int ok = !buf.failed && fwrite(buf.data, 1, buf.len, fp) == buf.len;
    free(buf.data);
    return ok ? 0 : -1;
}

sy_code laz_write_points(FILE *fp, const char *path, const laz_layout *L, uint64_t n, laz_source source, void *user,
                         sy_error *err)
{
    /* variable-size chunks (COPC's layout) are written LAZ_DEFAULT_CHUNK / 5
     * points each, their counts in the table */
    const uint32_t chunk = L->chunk_size == UINT32_MAX ? LAZ_DEFAULT_CHUNK / 5 : L->chunk_size;
    const size_t n_chunks = (size_t)((n + chunk - 1) / chunk);
    long start = ftell(fp);
    unsigned char word[8] = {0};
    if (start < 0 || fwrite(word, 1, 8, fp) != 8) return sy_fail(err, SY_EINPUT, "%s: write failed", path);
    /* A batch of chunks per round keeps memory at threads x chunk records. */
    size_t batch = (size_t)sy_threads();
    if (batch > 64) batch = 64;
    uint32_t *sizes = calloc(n_chunks ? n_chunks : 1, sizeof(uint32_t));
    uint32_t *counts = calloc(n_chunks ? n_chunks : 1, sizeof(uint32_t));
    unsigned char **records = calloc(batch, sizeof *records);
    laz_buf *out = calloc(batch, sizeof *out);
    uint32_t *points = calloc(batch, sizeof *points);
    int *rcs = calloc(batch, sizeof *rcs);
    sy_code rc = SY_OK;
    if (!sizes || !counts || !records || !out || !points || !rcs) rc = sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    for (size_t k = 0; rc == SY_OK && k < batch; k++)
        if (!(records[k] = malloc((size_t)chunk * L->record_length)))
            rc = sy_fail(err, SY_EINTERNAL, "%s: out of memory for LAZ chunks", path);
    for (size_t c0 = 0; rc == SY_OK && c0 < n_chunks; c0 += batch) {
        size_t m = n_chunks - c0 < batch ? n_chunks - c0 : batch;
        for (size_t k = 0; k < m; k++) {
            uint64_t first = (uint64_t)(c0 + k) * chunk;
            points[k] = (uint32_t)(n - first < chunk ? n - first : chunk);
            source(user, first, points[k], records[k]);
        }
        encode_batch b = {L, records, out, points, rcs};
        sy_parallel_for(m, 1, encode_one, &b);
        for (size_t k = 0; k < m && rc == SY_OK; k++) {
            if (rcs[k] || out[k].len > UINT32_MAX)
                rc = sy_fail(err, SY_EINTERNAL, "%s: out of memory compressing LAZ chunk %zu", path, c0 + k + 1);
            else if (fwrite(out[k].data, 1, out[k].len, fp) != out[k].len)
                rc = sy_fail(err, SY_EINPUT, "%s: write failed", path);
            sizes[c0 + k] = (uint32_t)out[k].len;
            counts[c0 + k] = points[k];
        }
    }
    long table = rc == SY_OK ? ftell(fp) : -1;
    if (rc == SY_OK && (table < 0 || write_table(fp, L, counts, sizes, n_chunks)))
        rc = sy_fail(err, SY_EINPUT, "%s: write failed", path);
    if (rc == SY_OK) {
        las_put_u64(word, (uint64_t)table);
        long end = ftell(fp);
        if (end < 0 || fseek(fp, start, SEEK_SET) || fwrite(word, 1, 8, fp) != 8 || fseek(fp, end, SEEK_SET))
            rc = sy_fail(err, SY_EINPUT, "%s: write failed", path);
    }
    for (size_t k = 0; records && k < batch; k++) free(records[k]);
    for (size_t k = 0; out && k < batch; k++) free(out[k].data);
    free(records);
    free(out);
    free(points);
    free(rcs);
    free(sizes);
    free(counts);
    return rc;
}
