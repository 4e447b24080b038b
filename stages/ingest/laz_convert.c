/* Lossless LAS <-> LAZ transcoding of whole files in memory: the header,
 * every VLR and EVLR and every record byte are kept; only the LASzip VLR,
 * the compression bit of the point format and the offsets that move with
 * them change. Compressing then decompressing gives back the input file
 * byte for byte. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ingest.h"
#include "las_format.h"
#include "laz.h"

/* The header numbers the transcoder moves, checked against the bytes present. */
typedef struct {
    unsigned header_size, format, record_length;
    uint32_t point_offset, n_vlrs;
    uint64_t count, evlr_start;
    int compressed;
    size_t vlrs_end;      /* end of the last VLR */
    size_t laszip_at;     /* the LASzip VLR's header, when present */
    size_t laszip_len;    /* its total length, header included */
    size_t points_end;    /* EVLRs start here (or the file ends) */
} las_frame;

static sy_code read_frame(const char *path, const unsigned char *d, size_t size, las_frame *f, sy_error *err)
{
    memset(f, 0, sizeof *f);
    if (size < LAS_HDR_MIN || memcmp(d, "LASF", 4) != 0)
        return sy_fail(err, SY_EINPUT, "%s: not a LAS/LAZ file (no LASF signature or short header)", path);
    f->header_size = las_u16(d + LAS_HEADER_SIZE);
    f->point_offset = las_u32(d + LAS_POINT_OFFSET);
    f->n_vlrs = las_u32(d + LAS_N_VLRS);
    f->format = d[LAS_POINT_FORMAT] & 0x3F;
    f->compressed = (d[LAS_POINT_FORMAT] & 0xC0) != 0;
    f->record_length = las_u16(d + LAS_RECORD_LENGTH);
    f->count = las_u32(d + LAS_LEGACY_COUNT);
    if (f->header_size < LAS_HDR_MIN || f->header_size > size || f->point_offset < f->header_size ||
        f->point_offset > size)
        return sy_fail(err, SY_EINPUT, "%s: header size or point data offset outside the file", path);
    if (d[LAS_VERSION_MINOR] >= 4 && f->header_size >= LAS_HDR_14) {
        uint64_t c64 = las_u64(d + LAS_COUNT64);
        if (c64) f->count = c64;
        if (las_u32(d + LAS_N_EVLRS)) f->evlr_start = las_u64(d + LAS_EVLR_START);
    }
    if (f->format > LAS_MAX_FORMAT || f->record_length < las_layouts[f->format].size)
        return sy_fail(err, SY_EINPUT, "%s: point format %u with record length %u is not valid", path, f->format,
                       f->record_length);
    size_t pos = f->header_size;
    f->laszip_at = 0;
    for (uint32_t i = 0; i < f->n_vlrs; i++) {
        if (f->point_offset - pos < LAS_VLR_HEADER || pos > f->point_offset)
            return sy_fail(err, SY_EINPUT, "%s: VLR %u runs into the point data", path, i + 1);
        size_t len = las_u16(d + pos + 20);
        if (len > f->point_offset - pos - LAS_VLR_HEADER)
            return sy_fail(err, SY_EINPUT, "%s: VLR %u runs into the point data", path, i + 1);
        if (memcmp(d + pos + 2, "laszip encoded", 14) == 0 && las_u16(d + pos + 18) == LAZ_VLR_RECORD_ID &&
            !f->laszip_at) {
            f->laszip_at = pos;
            f->laszip_len = LAS_VLR_HEADER + len;
        }
        pos += LAS_VLR_HEADER + len;
    }
    f->vlrs_end = pos;
    f->points_end = size;
    if (f->evlr_start) {
        if (f->evlr_start < f->point_offset || f->evlr_start > size)
            return sy_fail(err, SY_EINPUT, "%s: EVLR offset %llu outside the file", path,
                           (unsigned long long)f->evlr_start);
        f->points_end = (size_t)f->evlr_start;
    }
    return SY_OK;
}

typedef struct {
    unsigned char *records;
    size_t record_length;
} copy_sink;

static sy_code copy_chunk(void *user, size_t chunk, uint64_t first, uint32_t count, const unsigned char *records,
                          sy_error *err)
{
    (void)chunk;
    (void)err;
    copy_sink *s = user;
    memcpy(s->records + (size_t)first * s->record_length, records, (size_t)count * s->record_length);
    return SY_OK;
}

/* Copies d[0..size) minus the LASzip VLR, the records replaced by `records`. */
sy_code sy_laz_decompress_mem(const char *path, const unsigned char *d, size_t size, sy_buffer *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    las_frame f;
    sy_code rc = read_frame(path, d, size, &f, err);
    if (rc) return rc;
    if (!f.compressed || !f.laszip_at) return sy_fail(err, SY_EINPUT, "%s: not a LAZ file", path);
    laz_layout L;
    rc = laz_parse_vlr(path, d + f.laszip_at + LAS_VLR_HEADER, f.laszip_len - LAS_VLR_HEADER, (int)f.format,
                       f.record_length, &L, err);
    laz_chunk *chunks = NULL;
    size_t n_chunks = 0;
    if (rc == SY_OK)
        rc = laz_read_chunks(path, d, size, f.point_offset, f.points_end, &L, f.count, &chunks, &n_chunks, err);
    if (rc) return rc;
    size_t head = f.point_offset - f.laszip_len, points = (size_t)f.count * f.record_length;
    size_t tail = size - f.points_end;
    unsigned char *o = malloc(head + points + tail + 1);
    if (!o) {
        free(chunks);
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory for %llu decompressed points", path,
                       (unsigned long long)f.count);
    }
    memcpy(o, d, f.laszip_at);
    memcpy(o + f.laszip_at, d + f.laszip_at + f.laszip_len, f.point_offset - f.laszip_at - f.laszip_len);
    copy_sink sink = {o + head, f.record_length};
    rc = laz_decode_chunks(path, d, &L, chunks, n_chunks, copy_chunk, &sink, err);
    free(chunks);
    if (rc) {
        free(o);
        return rc;
    }
    memcpy(o + head + points, d + f.points_end, tail);
    o[LAS_POINT_FORMAT] &= 0x3F;
    las_put_u32(o + LAS_POINT_OFFSET, (uint32_t)head);
    las_put_u32(o + LAS_N_VLRS, f.n_vlrs - 1);
    if (f.evlr_start) las_put_u64(o + LAS_EVLR_START, head + points);
    o[head + points + tail] = 0;
    out->data = o;
    out->size = head + points + tail;
    return SY_OK;
}

typedef struct {
    const unsigned char *records;
    size_t record_length;
} records_source;

static void copy_records(void *user, uint64_t first, uint32_t count, unsigned char *records)
{
    const records_source *s = user;
    memcpy(records, s->records + (size_t)first * s->record_length, (size_t)count * s->record_length);
}

sy_code sy_laz_compress_mem(const char *path, const unsigned char *d, size_t size, sy_buffer *out, sy_error *err)
{
    return laz_compress_mem_chunked(path, d, size, LAZ_DEFAULT_CHUNK, out, err);
}

sy_code laz_compress_mem_chunked(const char *path, const unsigned char *d, size_t size, uint32_t chunk_size,
                                 sy_buffer *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    las_frame f;
    sy_code rc = read_frame(path, d, size, &f, err);
    if (rc) return rc;
    if (f.compressed || f.laszip_at) return sy_fail(err, SY_EINPUT, "%s: already LAZ-compressed", path);
    if (f.format == 4 || f.format == 5 || f.format > 8)
        return sy_fail(err, SY_EINPUT, "%s: point format %u (waveforms) cannot be written as LAZ", path, f.format);
    if (f.count > (f.points_end - f.point_offset) / f.record_length)
        return sy_fail(err, SY_EINPUT, "%s: header promises %llu points, file holds %llu", path,
                       (unsigned long long)f.count,
                       (unsigned long long)((f.points_end - f.point_offset) / f.record_length));
    if (f.vlrs_end + LAZ_VLR_MAX > UINT32_MAX) return sy_fail(err, SY_EINPUT, "%s: header too large", path);
    laz_layout L = {(int)f.format, f.record_length, f.record_length - las_layouts[f.format].size, f.format >= 6,
                    chunk_size ? chunk_size : LAZ_DEFAULT_CHUNK};
    unsigned char vlr[LAZ_VLR_MAX];
    size_t vlr_len = laz_make_vlr(&L, vlr);
    /* A temporary file rather than a memory stream: the writer seeks back to
     * patch offsets, which memory streams do not all handle the same way. */
    FILE *fp = tmpfile();
    if (!fp) return sy_fail(err, SY_EINTERNAL, "%s: cannot create a temporary file", path);
    unsigned char *h = malloc(f.point_offset);
    if (!h) {
        fclose(fp);
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    }
    /* the LASzip VLR goes after the last VLR, before any padding */
    memcpy(h, d, f.point_offset);
    h[LAS_POINT_FORMAT] = (unsigned char)(f.format | 0x80);
    las_put_u32(h + LAS_POINT_OFFSET, (uint32_t)(f.point_offset + vlr_len));
    las_put_u32(h + LAS_N_VLRS, f.n_vlrs + 1);
    int ok = fwrite(h, 1, f.vlrs_end, fp) == f.vlrs_end && fwrite(vlr, 1, vlr_len, fp) == vlr_len &&
             fwrite(h + f.vlrs_end, 1, f.point_offset - f.vlrs_end, fp) == f.point_offset - f.vlrs_end;
    free(h);
    records_source src = {d + f.point_offset, f.record_length};
    rc = ok ? laz_write_points(fp, path, &L, f.count, copy_records, &src, err)
            : sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    long total = -1, evlrs = -1;
    if (rc == SY_OK) {
        evlrs = ftell(fp);
        size_t tail = size - f.points_end;
        if (evlrs < 0 || fwrite(d + f.points_end, 1, tail, fp) != tail || (total = ftell(fp)) < 0)
            rc = sy_fail(err, SY_EINTERNAL, "%s: temporary file write failed", path);
        if (rc == SY_OK && f.evlr_start) {
            unsigned char word[8];
            las_put_u64(word, (uint64_t)evlrs);
            if (fseek(fp, LAS_EVLR_START, SEEK_SET) || fwrite(word, 1, 8, fp) != 8)
                rc = sy_fail(err, SY_EINTERNAL, "%s: temporary file write failed", path);
        }
    }
    unsigned char *o = rc == SY_OK ? malloc((size_t)total + 1) : NULL;
    if (rc == SY_OK && !o) rc = sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    if (rc == SY_OK && (fflush(fp) || fseek(fp, 0, SEEK_SET) || fread(o, 1, (size_t)total, fp) != (size_t)total))
        rc = sy_fail(err, SY_EINTERNAL, "%s: temporary file read failed", path);
    fclose(fp);
    if (rc) {
        free(o);
        return rc;
    }
    o[total] = 0;
    out->data = o;
    out->size = (size_t)total;
    return SY_OK;
}
