/* LAS 1.0-1.4 reader: point data record formats 0-10, extra bytes, VLRs and
 * EVLRs, CRS summary; LAZ (LASzip-compressed LAS) decoded chunk by chunk on
 * all cores. Every header number is checked against the bytes actually
 * present before it sizes anything. */
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include "ingest.h"
#include "las_format.h"
#include "laz.h"

typedef struct {
    unsigned vmajor, vminor;
    unsigned header_size;
    uint16_t global_encoding;
    uint32_t point_offset;
    uint32_t n_vlrs;
    unsigned raw_format; /* as stored, LAZ bits included */
    int compressed;      /* LASzip's bit 7 (or 6) of the format */
    int format;
    unsigned record_length;
    uint64_t count;
    double scale[3], offset[3];
    uint64_t evlr_start;
    uint32_t n_evlrs;
} las_header;

/* What the (E)VLR walk found: pointers into the file buffer. */
typedef struct {
    int laszip;
    const unsigned char *laszip_vlr; /* the "laszip encoded" payload */
    size_t laszip_len;
    const unsigned char *extra_bytes;
    size_t extra_bytes_len;
    const unsigned char *geokeys;
    size_t geokeys_len;
    const unsigned char *wkt;
    size_t wkt_len;
    char *summary;
    size_t summary_len, summary_cap;
    unsigned summary_lines, summary_dropped;
    unsigned char *geotiff; /* GeoTIFF records kept for a writer, as VLRs */
    size_t geotiff_len;
    unsigned geotiff_vlrs;
} las_vlrs;

enum { SUMMARY_MAX_LINES = 64, WKT_MAX_CHARS = 512 };

/* Copies a fixed-width, maybe NUL-padded text field, replacing anything
 * unprintable so summaries stay one line per VLR. */
static void copy_text(char *dst, size_t cap, const unsigned char *src, size_t len)
{
    size_t n = 0;
    for (; n < len && n + 1 < cap && src[n]; n++) dst[n] = (src[n] >= 0x20 && src[n] < 0x7f) ? (char)src[n] : '?';
    while (n > 0 && dst[n - 1] == ' ') n--;
    dst[n] = '\0';
}

static sy_code parse_header(const char *path, const unsigned char *d, size_t size, las_header *h, sy_error *err)
{
    memset(h, 0, sizeof *h);
    if (size < 4 || memcmp(d, "LASF", 4) != 0)
        return sy_fail(err, SY_EINPUT, "%s: not a LAS file (no LASF signature)", path);
    if (size < LAS_HDR_MIN)
        return sy_fail(err, SY_EINPUT, "%s: truncated header (%zu bytes, a LAS header needs %d)", path, size,
                       LAS_HDR_MIN);
    h->vmajor = d[LAS_VERSION_MAJOR];
    h->vminor = d[LAS_VERSION_MINOR];
    if (h->vmajor != 1) return sy_fail(err, SY_EINPUT, "%s: unsupported LAS version %u.%u", path, h->vmajor, h->vminor);
    h->global_encoding = las_u16(d + 6);
    h->header_size = las_u16(d + LAS_HEADER_SIZE);
    if (h->header_size < LAS_HDR_MIN)
        return sy_fail(err, SY_EINPUT, "%s: header size %u is below the %d bytes LAS requires", path, h->header_size,
                       LAS_HDR_MIN);
    if (h->header_size > size)
        return sy_fail(err, SY_EINPUT, "%s: truncated header (header size %u, file has %zu bytes)", path,
                       h->header_size, size);
    h->point_offset = las_u32(d + LAS_POINT_OFFSET);
    h->n_vlrs = las_u32(d + LAS_N_VLRS);
    h->raw_format = d[LAS_POINT_FORMAT];
    h->record_length = las_u16(d + LAS_RECORD_LENGTH);
    /* LASzip marks compressed files by setting bit 7 (and 6 for some writers). */
    h->compressed = (h->raw_format & 0xC0) != 0;
    h->format = (int)(h->raw_format & 0x3F);
    if (h->format > LAS_MAX_FORMAT)
        return sy_fail(err, SY_EINPUT, "%s: unsupported point data record format %d", path, h->format);
    if (h->point_offset < h->header_size)
        return sy_fail(err, SY_EINPUT, "%s: point data offset %u lies inside the %u-byte header", path,
                       h->point_offset, h->header_size);
    if (h->point_offset > size)
        return sy_fail(err, SY_EINPUT, "%s: point data offset %u is past the end of the file (%zu bytes)", path,
                       h->point_offset, size);
    if (h->record_length < las_layouts[h->format].size)
        return sy_fail(err, SY_EINPUT, "%s: record length %u is smaller than the %u bytes point format %d needs",
                       path, h->record_length, las_layouts[h->format].size, h->format);
    for (int k = 0; k < 3; k++) {
        h->scale[k] = las_f64(d + LAS_SCALE + 8 * k);
        h->offset[k] = las_f64(d + LAS_OFFSET + 8 * k);
        if (!isfinite(h->scale[k]) || h->scale[k] == 0.0)
            return sy_fail(err, SY_EINPUT, "%s: invalid %c scale factor %g", path, "xyz"[k], h->scale[k]);
        if (!isfinite(h->offset[k]))
            return sy_fail(err, SY_EINPUT, "%s: invalid %c offset %g", path, "xyz"[k], h->offset[k]);
    }
    h->count = las_u32(d + LAS_LEGACY_COUNT);
    /* LAS 1.4 moves the count to 64 bits; the legacy field is 0 for formats
     * 6-10 or for more than 2^32 points. */
    if (h->vminor >= 4 && h->header_size >= LAS_HDR_14) {
        uint64_t count64 = las_u64(d + LAS_COUNT64);
        if (count64) h->count = count64;
        h->evlr_start = las_u64(d + LAS_EVLR_START);
        h->n_evlrs = las_u32(d + LAS_N_EVLRS);
    }
    return SY_OK;
}

static int summary_line(las_vlrs *v, const char *line)
{
    size_t len = strlen(line);
    if (v->summary_len + len + 2 > v->summary_cap) {
        size_t cap = v->summary_cap ? 2 * v->summary_cap : 1024;
        char *grown = realloc(v->summary, cap);
        if (!grown) return -1;
        v->summary = grown;
        v->summary_cap = cap;
    }
    if (v->summary_len) v->summary[v->summary_len++] = '\n';
    memcpy(v->summary + v->summary_len, line, len + 1);
    v->summary_len += len;
    return 0;
}

/* One line per VLR, up to SUMMARY_MAX_LINES; the rest are counted. */
static int summary_append(las_vlrs *v, const char *user, unsigned record_id, const char *desc)
{
    if (v->summary_lines >= SUMMARY_MAX_LINES) {
        v->summary_dropped++;
        return 0;
    }
    char line[128];
    snprintf(line, sizeof line, "%s/%u: %s", user, record_id, desc);
    v->summary_lines++;
    return summary_line(v, line);
}

/* Appends one GeoTIFF record (GeoKeyDirectory, DoubleParams or AsciiParams)
 * as a VLR with the input's user id, record id and description, so a writer
 * can copy the CRS verbatim. An EVLR too long for a VLR is not kept: nothing
 * could write it back where GeoTIFF keys belong. */
static int keep_geotiff(las_vlrs *v, const unsigned char *hdr, const unsigned char *desc,
                        const unsigned char *payload, size_t len)
{
    if (len > 65535) return 0;
    unsigned char *grown = realloc(v->geotiff, v->geotiff_len + LAS_VLR_HEADER + len);
    if (!grown) return -1;
    v->geotiff = grown;
    unsigned char *q = grown + v->geotiff_len;
    memset(q, 0, LAS_VLR_HEADER);
    memcpy(q + 2, hdr + 2, 18); /* user id and record id */
    las_put_u16(q + 20, (uint16_t)len);
    memcpy(q + 22, desc, 32);
    memcpy(q + LAS_VLR_HEADER, payload, len);
    v->geotiff_len += LAS_VLR_HEADER + len;
    v->geotiff_vlrs++;
    return 0;
}

/* Records one (E)VLR: its summary line and the payloads the reader uses. */
static sy_code note_vlr(const char *path, las_vlrs *v, const unsigned char *hdr, const unsigned char *payload,
                        size_t len, size_t desc_at, sy_error *err)
{
    char user[17], desc[33];
    copy_text(user, sizeof user, hdr + 2, 16);
    unsigned record_id = las_u16(hdr + 18);
    copy_text(desc, sizeof desc, hdr + desc_at, 32);
    if (summary_append(v, user, record_id, desc))
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory for the VLR summary", path);
    if (strcmp(user, "laszip encoded") == 0 && record_id == LAZ_VLR_RECORD_ID && !v->laszip) {
        v->laszip = 1;
        v->laszip_vlr = payload;
        v->laszip_len = len;
    }
    if (strcmp(user, "LASF_Spec") == 0 && record_id == 4 && !v->extra_bytes) {
        v->extra_bytes = payload;
        v->extra_bytes_len = len;
    }
    if (strcmp(user, "LASF_Projection") == 0 && record_id == 34735 && !v->geokeys) {
        v->geokeys = payload;
        v->geokeys_len = len;
    }
    if (strcmp(user, "LASF_Projection") == 0 && record_id >= 34735 && record_id <= 34737 &&
        keep_geotiff(v, hdr, hdr + desc_at, payload, len))
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory for the GeoTIFF keys", path);
    if (strcmp(user, "LASF_Projection") == 0 && record_id == 2112 && !v->wkt) {
        v->wkt = payload;
        v->wkt_len = len;
    }
    return SY_OK;
}

static sy_code walk_vlrs(const char *path, const unsigned char *d, size_t size, const las_header *h, las_vlrs *v,
                         sy_error *err)
{
    size_t pos = h->header_size;
    for (uint32_t i = 0; i < h->n_vlrs; i++) {
        if (pos > h->point_offset || h->point_offset - pos < LAS_VLR_HEADER)
            return sy_fail(err, SY_EINPUT, "%s: VLR %u of %u runs into the point data (offset %u)", path, i + 1,
                           h->n_vlrs, h->point_offset);
        size_t len = las_u16(d + pos + 20);
        size_t payload = pos + LAS_VLR_HEADER;
        if (len > size - payload)
            return sy_fail(err, SY_EINPUT, "%s: VLR %u length %zu runs past the end of the file", path, i + 1, len);
        if (len > h->point_offset - payload)
            return sy_fail(err, SY_EINPUT, "%s: VLR %u length %zu runs into the point data (offset %u)", path, i + 1,
                           len, h->point_offset);
        sy_code rc = note_vlr(path, v, d + pos, d + payload, len, 22, err);
        if (rc) return rc;
        pos = payload + len;
    }
    return SY_OK;
}

/* LAS 1.4 extended VLRs follow the points; returns where the point region ends. */
static sy_code walk_evlrs(const char *path, const unsigned char *d, size_t size, const las_header *h, las_vlrs *v,
                          size_t *points_end, sy_error *err)
{
    *points_end = size;
    if (h->n_evlrs == 0 || h->evlr_start == 0) return SY_OK;
    if (h->evlr_start > size)
        return sy_fail(err, SY_EINPUT, "%s: first EVLR offset %llu is past the end of the file (%zu bytes)", path,
                       (unsigned long long)h->evlr_start, size);
    if (h->evlr_start < h->point_offset)
        return sy_fail(err, SY_EINPUT, "%s: first EVLR offset %llu lies before the point data (offset %u)", path,
                       (unsigned long long)h->evlr_start, h->point_offset);
    size_t pos = (size_t)h->evlr_start;
    *points_end = pos;
    for (uint32_t i = 0; i < h->n_evlrs; i++) {
        if (size - pos < LAS_EVLR_HEADER)
            return sy_fail(err, SY_EINPUT, "%s: EVLR %u of %u runs past the end of the file", path, i + 1, h->n_evlrs);
        uint64_t len = las_u64(d + pos + 20);
        size_t payload = pos + LAS_EVLR_HEADER;
        if (len > size - payload)
            return sy_fail(err, SY_EINPUT, "%s: EVLR %u length %llu runs past the end of the file", path, i + 1,
                           (unsigned long long)len);
        sy_code rc = note_vlr(path, v, d + pos, d + payload, (size_t)len, 28, err);
        if (rc) return rc;
        pos = payload + (size_t)len;
    }
    return SY_OK;
}

/* "EPSG:<code>" from the GeoKeyDirectory (projected CRS preferred). */
static char *geokeys_crs(const unsigned char *k, size_t len)
{
    if (len < 8) return NULL;
    unsigned n_keys = las_u16(k + 6);
    unsigned projected = 0, geographic = 0;
    for (unsigned i = 0; i < n_keys && 8 + 8 * (size_t)(i + 1) <= len; i++) {
        const unsigned char *e = k + 8 + 8 * (size_t)i;
        unsigned id = las_u16(e), location = las_u16(e + 2), value = las_u16(e + 6);
        if (location != 0) continue; /* value stored elsewhere: not an EPSG code */
        if (id == 3072) projected = value;
        if (id == 2048) geographic = value;
    }
    unsigned code = projected ? projected : geographic;
    char buf[64];
    if (code && code != 32767) snprintf(buf, sizeof buf, "EPSG:%u", code);
    else snprintf(buf, sizeof buf, "GeoTIFF keys (%u, no EPSG code)", n_keys);
    char *s = malloc(strlen(buf) + 1);
    if (s) strcpy(s, buf);
    return s;
}

/* The WKT text on one line, cut at WKT_MAX_CHARS with "..." (the CRS name
 * comes first in WKT, so the cut keeps what a reader needs). *out stays NULL
 * for blank text; returns -1 when out of memory. */
static int wkt_crs(const unsigned char *w, size_t len, char **out)
{
    size_t cap = (len < WKT_MAX_CHARS ? len : WKT_MAX_CHARS) + 4;
    char *s = malloc(cap);
    if (!s) return -1;
    size_t n = 0;
    int space = 0;
    size_t i = 0;
    for (; i < len && w[i] && n < WKT_MAX_CHARS; i++) {
        int ch = w[i];
        if (ch <= 0x20 || ch >= 0x7f) {
            space = n > 0;
            continue;
        }
        if (space && n + 1 < WKT_MAX_CHARS) s[n++] = ' ';
        space = 0;
        s[n++] = (char)ch;
    }
    while (i < len && w[i] && (w[i] <= 0x20 || w[i] >= 0x7f)) i++;
    if (i < len && w[i]) { /* text remains: mark the cut */
        memcpy(s + n, "...", 3);
        n += 3;
    }
    s[n] = '\0';
    if (n == 0) free(s);
    else *out = s;
    return 0;
}

static void drop_if_zero(void **array, int any)
{
    if (!any) {
        free(*array);
        *array = NULL;
    }
}

/* Allocates the arrays a point format carries. */
static sy_code add_format_arrays(sy_cloud *c, const las_layout *lay, sy_error *err)
{
    if (sy_cloud_add_intensity(c, err) || sy_cloud_add_returns(c, err) || sy_cloud_add_classification(c, err))
        return SY_EINTERNAL;
    if (lay->gps >= 0 && sy_cloud_add_gps_time(c, err)) return SY_EINTERNAL;
    if (lay->rgb >= 0 && sy_cloud_add_rgb(c, err)) return SY_EINTERNAL;
    if (lay->nir >= 0) {
        c->nir = sy_calloc(c->n, sizeof(uint16_t), err, "near infrared");
        if (!c->nir) return SY_EINTERNAL;
    }
    return SY_OK;
}

/* Which optional fields held a non-zero value, per block of points (ORed
 * together at the end, so blocks decoded in any order agree). */
typedef struct {
    unsigned intensity, returns, classification, rgb, nir, gps;
} nonzero_fields;

/* One extra-bytes field read into a named attribute. */
typedef struct {
    unsigned type;
    size_t at; /* byte offset in the record */
    double *values;
    int has_none;
    double none, scale, offset;
} extra_field;

/* What decoding a block of records needs: shared, read-only while blocks
 * decode (possibly on several threads), each block writing its own range. */
typedef struct {
    const char *path;
    const las_header *h;
    sy_cloud *c;
    extra_field *fields;
    size_t n_fields;
    nonzero_fields *nonzero; /* per block */
} point_sink;

/* The hot loop: records [first, first + count) of the cloud from pts (count
 * records), fixed byte offsets, no per-field dispatch. */
static sy_code decode_points(const point_sink *k, const unsigned char *pts, size_t first, size_t count,
                             nonzero_fields *nz, sy_error *err)
{
    const las_header *h = k->h;
    sy_cloud *c = k->c;
    const las_layout *lay = &las_layouts[h->format];
    const size_t stride = h->record_length;
    const int legacy = h->format <= 5;
    const unsigned rn_mask = legacy ? 0x07 : 0x0F, nr_shift = legacy ? 3 : 4, nr_mask = legacy ? 0x07 : 0x0F;
    const unsigned class_at = legacy ? 15 : 16, class_mask = legacy ? 0x1F : 0xFF;
    const double sx = h->scale[0], sy = h->scale[1], sz = h->scale[2];
    const double ox = h->offset[0], oy = h->offset[1], oz = h->offset[2];
    const double o0 = c->origin[0], o1 = c->origin[1], o2 = c->origin[2];
    /* Local pointers: byte stores could alias *c and defeat hoisting. */
    float *xyz = c->xyz + 3 * first;
    uint16_t *inten = c->intensity + first, *rgb = c->rgb ? c->rgb + 3 * first : NULL;
    uint16_t *nir = c->nir ? c->nir + first : NULL;
    uint8_t *rnum = c->return_number + first, *nret = c->num_returns + first, *cls = c->classification + first;
    double *gps = c->gps_time ? c->gps_time + first : NULL;
    const int gps_at = lay->gps, rgb_at = lay->rgb, nir_at = lay->nir;
    unsigned any_intensity = 0, any_returns = 0, any_class = 0, any_rgb = 0, any_nir = 0, any_gps = 0;
    for (size_t i = 0; i < count; i++) {
        const unsigned char *p = pts + i * stride;
        double x = las_i32(p) * sx + ox, y = las_i32(p + 4) * sy + oy, z = las_i32(p + 8) * sz + oz;
        if (!(isfinite(x) && isfinite(y) && isfinite(z))) return sy_check_finite(k->path, x, y, z, first + i, err);
        xyz[3 * i] = (float)(x - o0);
        xyz[3 * i + 1] = (float)(y - o1);
        xyz[3 * i + 2] = (float)(z - o2);
        uint16_t intensity = las_u16(p + 12);
        unsigned flags = p[14];
        uint8_t rn = (uint8_t)(flags & rn_mask), nr = (uint8_t)((flags >> nr_shift) & nr_mask);
        uint8_t cl = (uint8_t)(p[class_at] & class_mask);
        inten[i] = intensity;
        rnum[i] = rn;
        nret[i] = nr;
        cls[i] = cl;
        any_intensity |= intensity;
        any_returns |= rn | nr;
        any_class |= cl;
        if (gps) {
            double t = las_f64(p + gps_at);
            gps[i] = t;
            any_gps |= t != 0.0;
        }
        if (rgb) {
            for (int q = 0; q < 3; q++) {
                uint16_t v = las_u16(p + rgb_at + 2 * q);
                rgb[3 * i + q] = v;
                any_rgb |= v;
            }
        }
        if (nir) {
            nir[i] = las_u16(p + nir_at);
            any_nir |= nir[i];
        }
    }
    nz->intensity |= any_intensity;
    nz->returns |= any_returns;
    nz->classification |= any_class;
    nz->gps |= any_gps;
    nz->rgb |= any_rgb;
    nz->nir |= any_nir;
    return SY_OK;
}

/* Arrays that hold only zeros are dropped: LAS always has the fields, but an
 * all-zero field carries no information. */
static void drop_zero_fields(sy_cloud *c, const nonzero_fields *blocks, size_t n_blocks)
{
    nonzero_fields nz = {0, 0, 0, 0, 0, 0};
    for (size_t b = 0; b < n_blocks; b++) {
        nz.intensity |= blocks[b].intensity;
        nz.returns |= blocks[b].returns;
        nz.classification |= blocks[b].classification;
        nz.gps |= blocks[b].gps;
        nz.rgb |= blocks[b].rgb;
        nz.nir |= blocks[b].nir;
    }
    drop_if_zero((void **)&c->intensity, nz.intensity != 0);
    drop_if_zero((void **)&c->return_number, nz.returns != 0);
    drop_if_zero((void **)&c->num_returns, nz.returns != 0);
    drop_if_zero((void **)&c->classification, nz.classification != 0);
    drop_if_zero((void **)&c->gps_time, nz.gps != 0);
    drop_if_zero((void **)&c->rgb, nz.rgb != 0);
    drop_if_zero((void **)&c->nir, nz.nir != 0);
}

/* Origin at the metre floor of the first point keeps the floats small. */
static sy_code set_origin(const char *path, const las_header *h, const unsigned char *first, sy_cloud *c,
                          sy_error *err)
{
    if (!first) {
        memcpy(c->origin, h->offset, sizeof c->origin);
        return SY_OK;
    }
    double x = las_i32(first) * h->scale[0] + h->offset[0], y = las_i32(first + 4) * h->scale[1] + h->offset[1];
    double z = las_i32(first + 8) * h->scale[2] + h->offset[2];
    sy_code rc = sy_check_finite(path, x, y, z, 0, err);
    if (rc) return rc;
    c->origin[0] = floor(x);
    c->origin[1] = floor(y);
    c->origin[2] = floor(z);
    return SY_OK;
}

/* Bytes one extra-bytes field occupies; 0 with *known = 0 when the type is
 * not one the spec sizes (the rest of the layout is then unknowable). */
static size_t extra_field_size(unsigned type, unsigned options, int *known)
{
    static const unsigned char sizes[11] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
    *known = 1;
    if (type == 0) return options; /* undocumented: options holds the byte count */
    if (type <= 10) return sizes[type];
    if (type <= 30) return (size_t)sizes[(type - 1) % 10 + 1] * (type <= 20 ? 2 : 3); /* deprecated arrays */
    *known = 0;
    return 0;
}

/* One column of extra bytes as doubles; the type switch sits outside the loop. */
static void decode_extra(unsigned type, const unsigned char *src, size_t stride, size_t n, double *out)
{
#define EXTRA_LOOP(expr)                                                  \
    for (size_t i = 0; i < n; i++) {                                      \
        const unsigned char *q = src + i * stride;                        \
        out[i] = (double)(expr);                                          \
    }                                                                     \
    break
    switch (type) {
    case 1: EXTRA_LOOP(q[0]);
    case 2: EXTRA_LOOP((int8_t)q[0]);
    case 3: EXTRA_LOOP(las_u16(q));
    case 4: EXTRA_LOOP((int16_t)las_u16(q));
    case 5: EXTRA_LOOP(las_u32(q));
    case 6: EXTRA_LOOP(las_i32(q));
    case 7: EXTRA_LOOP(las_u64(q));
    case 8: EXTRA_LOOP((int64_t)las_u64(q));
    case 9: EXTRA_LOOP(las_f32(q));
    default: EXTRA_LOOP(las_f64(q));
    }
#undef EXTRA_LOOP
}

/* A descriptor's 8-byte "anyval" (no_data, min, max) as a double: unsigned
 * types store it as u64, signed ones as i64, floating ones as double. */
static double extra_anyval(unsigned type, const unsigned char *v)
{
    if (type == 9 || type == 10) return las_f64(v);
    if (type % 2 == 0) return (double)(int64_t)las_u64(v);
    return (double)las_u64(v);
}

/* A unique attribute name: the descriptor's, or extra_<i> when empty. */
static void attr_name(const sy_cloud *c, const unsigned char *desc, unsigned index, char *name, size_t cap)
{
    char base[32];
    copy_text(base, sizeof base, desc + LAS_EB_NAME, 32);
    if (!base[0]) snprintf(base, sizeof base, "extra_%u", index);
    snprintf(name, cap, "%s", base);
    for (unsigned k = 2; sy_cloud_attr(c, name) && k < 100000; k++) snprintf(name, cap, "%.24s_%u", base, k);
}

/* Extra bytes (LAS 1.4 "LASF_Spec"/4): each sized field of type 1-10 becomes a
 * named attribute, with the descriptor's scale and offset applied and its
 * no_data value read as NaN. This creates the attributes; decode_extra_bytes
 * fills them block by block. */
static sy_code prepare_extra_bytes(const char *path, const las_header *h, const las_vlrs *v, sy_cloud *c, extra_field **out,
                                   size_t *n_out, sy_error *err)
{
    *out = NULL;
    *n_out = 0;
    if (!v->extra_bytes) return SY_OK;
    size_t base = las_layouts[h->format].size, at = 0;
    size_t extra = h->record_length > base ? h->record_length - base : 0;
    size_t n_desc = v->extra_bytes_len / LAS_EB_DESCRIPTOR;
    /* A descriptor table that cannot be read whole is refused: dropping the
     * fields behind a bad one would silently lose treeID or speciesID. */
    if (v->extra_bytes_len % LAS_EB_DESCRIPTOR)
        return sy_fail(err, SY_EINPUT, "%s: extra-bytes VLR of %zu bytes is not a whole number of %d-byte descriptors",
                       path, v->extra_bytes_len, LAS_EB_DESCRIPTOR);
    extra_field *fields = sy_calloc(n_desc ? n_desc : 1, sizeof *fields, err, "extra-bytes fields");
    if (!fields) return SY_EINTERNAL;
    size_t n = 0;
    for (size_t i = 0; i < n_desc; i++) {
        const unsigned char *desc = v->extra_bytes + i * LAS_EB_DESCRIPTOR;
        unsigned type = desc[LAS_EB_TYPE], options = desc[LAS_EB_OPTIONS];
        int known;
        size_t width = extra_field_size(type, options, &known);
        if (!known) {
            free(fields);
            return sy_fail(err, SY_EINPUT, "%s: extra-bytes descriptor %zu has unknown data type %u", path, i, type);
        }
        if (width > extra - at) {
            free(fields);
            return sy_fail(err, SY_EINPUT,
                           "%s: extra-bytes descriptors need more than the %zu bytes each point record holds past "
                           "its format's fields (descriptor %zu)",
                           path, extra, i);
        }
        if (type >= 1 && type <= 10) {
            char name[32];
            attr_name(c, desc, (unsigned)i, name, sizeof name);
            extra_field *f = &fields[n++];
            if (!(f->values = sy_cloud_add_attr(c, name, err))) {
                free(fields);
                return SY_EINTERNAL;
            }
            f->type = type;
            f->at = base + at;
            /* no_data (e.g. treeID = DBL_MAX for points in no tree) becomes NaN. */
            f->has_none = (options & LAS_EB_OPT_NO_DATA) != 0;
            if (f->has_none) f->none = extra_anyval(type, desc + LAS_EB_NO_DATA);
            f->scale = (options & LAS_EB_OPT_SCALE) ? las_f64(desc + LAS_EB_SCALE) : 1.0;
            f->offset = (options & LAS_EB_OPT_OFFSET) ? las_f64(desc + LAS_EB_OFFSET) : 0.0;
        }
        at += width;
    }
    *out = fields;
    *n_out = n;
    return SY_OK;
}

static void decode_extra_bytes(const point_sink *k, const unsigned char *pts, size_t first, size_t count)
{
    for (size_t f = 0; f < k->n_fields; f++) {
        const extra_field *e = &k->fields[f];
        double *values = e->values + first;
        decode_extra(e->type, pts + e->at, k->h->record_length, count, values);
        if (e->has_none)
            for (size_t p = 0; p < count; p++)
                if (values[p] == e->none) values[p] = NAN;
        if (e->scale != 1.0 || e->offset != 0.0)
            for (size_t p = 0; p < count; p++) values[p] = values[p] * e->scale + e->offset;
    }
}

/* Receives one decoded LAZ chunk. */
static sy_code laz_chunk_sink(void *user, size_t chunk, uint64_t first, uint32_t count, const unsigned char *records,
                              sy_error *err)
{
    point_sink *k = user;
    sy_code rc = decode_points(k, records, (size_t)first, count, &k->nonzero[chunk], err);
    if (rc == SY_OK) decode_extra_bytes(k, records, (size_t)first, count);
    return rc;
}

/* NormalX/NormalY/NormalZ extra bytes (PDAL's names, which the writer uses)
 * are the cloud's normals, not three attributes: moved over when all three
 * are present. */
static sy_code adopt_normals(sy_cloud *c, sy_error *err)
{
    size_t at[3];
    for (int k = 0; k < 3; k++) {
        at[k] = c->n_attrs;
        for (size_t a = 0; a < c->n_attrs && at[k] == c->n_attrs; a++)
            if (strcasecmp(c->attrs[a].name, las_normal_names[k]) == 0) at[k] = a;
        if (at[k] == c->n_attrs) return SY_OK;
    }
    if (sy_cloud_add_normals(c, err)) return SY_EINTERNAL;
    for (int k = 0; k < 3; k++) {
        const double *v = c->attrs[at[k]].values;
        for (size_t i = 0; i < c->n; i++) c->normal[3 * i + k] = (float)v[i];
    }
    size_t kept = 0;
    for (size_t a = 0; a < c->n_attrs; a++) {
        if (a == at[0] || a == at[1] || a == at[2]) free(c->attrs[a].values);
        else c->attrs[kept++] = c->attrs[a];
    }
    c->n_attrs = kept;
    return SY_OK;
}

static sy_code fill_meta(const char *path, const las_header *h, las_vlrs *v, sy_cloud *c, sy_error *err)
{
    snprintf(c->meta.format, sizeof c->meta.format, "LAS");
    snprintf(c->meta.version, sizeof c->meta.version, "%u.%u", h->vmajor, h->vminor);
    c->meta.point_format = h->format;
    c->meta.header_count = h->count;
    if (v->summary_dropped) {
        char more[64];
        snprintf(more, sizeof more, "... and %u more VLRs", v->summary_dropped);
        if (summary_line(v, more)) return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    }
    c->meta.vlr_summary = v->summary;
    v->summary = NULL;
    if (v->geokeys && !(c->meta.crs = geokeys_crs(v->geokeys, v->geokeys_len)))
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory for the CRS summary", path);
    if (!c->meta.crs && v->wkt && wkt_crs(v->wkt, v->wkt_len, &c->meta.crs))
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory for the CRS summary", path);
    if (v->wkt && v->wkt_len && v->wkt[0]) {
        /* The WKT payload is NUL-terminated text; a missing terminator is tolerated. */
        size_t len = strnlen((const char *)v->wkt, v->wkt_len);
        if (!(c->meta.crs_wkt = malloc(len + 1)))
            return sy_fail(err, SY_EINTERNAL, "%s: out of memory for the WKT", path);
        memcpy(c->meta.crs_wkt, v->wkt, len);
        c->meta.crs_wkt[len] = '\0';
    }
    c->meta.geotiff = v->geotiff;
    c->meta.geotiff_len = v->geotiff_len;
    c->meta.geotiff_vlrs = v->geotiff_vlrs;
    v->geotiff = NULL;
    c->meta.las_global_encoding = h->global_encoding;
    c->meta.gps_time_standard = h->global_encoding & LAS_GLOBAL_GPS_STANDARD;
    return SY_OK;
}

static sy_code read_las(const char *path, const unsigned char *data, size_t size, sy_cloud *out, las_vlrs *v,
                        sy_error *err)
{
    las_header h;
    sy_code rc = parse_header(path, data, size, &h, err);
    if (rc) return rc;
    if ((rc = walk_vlrs(path, data, size, &h, v, err))) return rc;
    size_t points_end;
    if ((rc = walk_evlrs(path, data, size, &h, v, &points_end, err))) return rc;
    int laz = h.compressed || v->laszip;
    if (laz && !v->laszip)
        return sy_fail(err, SY_EINPUT, "%s: point format says LAZ but there is no LASzip VLR", path);
    laz_chunk *chunks = NULL;
    size_t n_chunks = 0;
    laz_layout L;
    const unsigned char *pts = data + h.point_offset;
    if (laz) {
        /* The chunk table is checked against the bytes present before it sizes anything. */
        if ((rc = laz_parse_vlr(path, v->laszip_vlr, v->laszip_len, h.format, h.record_length, &L, err)) ||
            (rc = laz_read_chunks(path, data, size, h.point_offset, points_end, &L, h.count, &chunks, &n_chunks, err)))
            return rc;
    } else {
        /* The count is checked against the bytes present before it sizes anything. */
        uint64_t held = (points_end - h.point_offset) / h.record_length;
        if (h.count > held)
            return sy_fail(err, SY_EINPUT, "%s: header promises %llu points, file holds %llu", path,
                           (unsigned long long)h.count, (unsigned long long)held);
    }
    point_sink k = {path, &h, out, NULL, 0, NULL};
    size_t n_blocks = laz ? n_chunks : 1;
    k.nonzero = sy_calloc(n_blocks ? n_blocks : 1, sizeof *k.nonzero, err, "field flags");
    if (!k.nonzero || (rc = sy_cloud_init(out, (size_t)h.count, err)) ||
        (rc = add_format_arrays(out, &las_layouts[h.format], err)) ||
        (rc = set_origin(path, &h, h.count ? (laz ? data + chunks[0].offset : pts) : NULL, out, err)) ||
        (rc = prepare_extra_bytes(path, &h, v, out, &k.fields, &k.n_fields, err))) {
        free(chunks);
        free(k.nonzero);
        return rc ? rc : SY_EINTERNAL;
    }
    if (laz) {
        /* chunk by chunk on all cores, each straight into its range of the cloud */
        rc = laz_decode_chunks(path, data, &L, chunks, n_chunks, laz_chunk_sink, &k, err);
    } else {
        rc = decode_points(&k, pts, 0, out->n, &k.nonzero[0], err);
        if (rc == SY_OK) decode_extra_bytes(&k, pts, 0, out->n);
    }
    if (rc == SY_OK) drop_zero_fields(out, k.nonzero, n_blocks);
    free(chunks);
    free(k.nonzero);
    free(k.fields);
    if (rc == SY_OK) rc = adopt_normals(out, err);
    if (rc) return rc;
    if ((rc = fill_meta(path, &h, v, out, err))) return rc;
    if (laz) snprintf(out->meta.format, sizeof out->meta.format, "LAZ");
    return SY_OK;
}

sy_code sy_read_las_mem(const char *path, const unsigned char *data, size_t size, sy_cloud *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    out->meta.point_format = -1;
    las_vlrs v;
    memset(&v, 0, sizeof v);
    sy_code rc = read_las(path, data, size, out, &v, err);
    free(v.summary);
    free(v.geotiff);
    if (rc) sy_cloud_free(out);
    return rc;
}

/* ------------------------------------------------ `sylva info`, streaming */

/* Uncompressed LAS without the cloud: the same checks and the same numbers
 * as sy_read_las_mem + sy_cloud_check_range + sy_cloud_bounds, from the
 * header, the (E)VLRs and one pass over the records that keeps only the
 * per-axis extremes of the stored integers and which optional fields are
 * non-zero (so the memory is bounded whatever the file). A coordinate is
 * i * scale + offset - origin rounded to float, monotonic in i, so the
 * extremes of the integers give the bounds, the finiteness and the span
 * check of every point exactly. *done = 0 (and nothing set) when the file
 * is LAZ or a check fails: the caller then reads it whole, for the reader's
 * own message. */
sy_code sy_las_info_mem(const char *path, const unsigned char *data, size_t size, int fd, sy_cloud *meta, size_t *n,
                        double lo[3], double hi[3], int *done, sy_error *err)
{
    enum { INFO_BUFFER = 1 << 20 };
    *done = 0;
    memset(meta, 0, sizeof *meta);
    meta->meta.point_format = -1;
    las_header h;
    las_vlrs v;
    memset(&v, 0, sizeof v);
    size_t points_end;
    sy_code rc = parse_header(path, data, size, &h, err);
    if (!rc) rc = walk_vlrs(path, data, size, &h, &v, err);
    if (!rc) rc = walk_evlrs(path, data, size, &h, &v, &points_end, err);
    if (rc || h.compressed || v.laszip || h.count == 0 || (points_end - h.point_offset) / h.record_length < h.count) {
        free(v.summary), free(v.geotiff);
        return rc; /* an error, or the whole reader's case */
    }
    const unsigned char *pts = data + h.point_offset;
    const las_layout *lay = &las_layouts[h.format];
    const size_t stride = h.record_length;
    const int legacy = h.format <= 5, gps_at = lay->gps, rgb_at = lay->rgb, nir_at = lay->nir;
    const unsigned rn_mask = legacy ? 0x07 : 0x0F, nr_shift = legacy ? 3 : 4, nr_mask = legacy ? 0x07 : 0x0F;
    const unsigned class_at = legacy ? 15 : 16, class_mask = legacy ? 0x1F : 0xFF;
    int32_t mn[3] = {INT32_MAX, INT32_MAX, INT32_MAX}, mx[3] = {INT32_MIN, INT32_MIN, INT32_MIN};
    unsigned any_int = 0, any_ret = 0, any_cls = 0, any_gps = 0, any_rgb = 0, any_nir = 0;
    /* With a descriptor, the records come through a buffer of INFO_BUFFER
     * bytes (whole records) by pread: no page of them stays mapped. */
    size_t per = INFO_BUFFER / stride ? INFO_BUFFER / stride : 1, held = 0, base = 0;
    unsigned char *buf = fd >= 0 ? malloc(per * stride) : NULL;
    if (fd >= 0 && !buf) {
        free(v.summary), free(v.geotiff);
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    }
    for (uint64_t i = 0; i < h.count; i++) {
        const unsigned char *p = pts + (size_t)i * stride;
        if (buf) {
            if (i >= base + held) {
                base = (size_t)i;
                held = h.count - i < per ? (size_t)(h.count - i) : per;
                size_t want = held * stride, got = 0;
                off_t at = (off_t)h.point_offset + (off_t)(base * stride);
                while (got < want) {
                    ssize_t r = pread(fd, buf + got, want - got, at + (off_t)got);
                    if (r <= 0) break;
                    got += (size_t)r;
                }
                if (got < want) { /* the file changed under us: read it whole */
                    free(buf);
                    free(v.summary), free(v.geotiff);
                    return SY_OK;
                }
            }
            p = buf + (size_t)(i - base) * stride;
        }
        for (int a = 0; a < 3; a++) {
            int32_t q = las_i32(p + 4 * a);
            mn[a] = q < mn[a] ? q : mn[a];
            mx[a] = q > mx[a] ? q : mx[a];
        }
        unsigned flags = p[14];
        any_int |= las_u16(p + 12);
        any_ret |= (flags & rn_mask) | ((flags >> nr_shift) & nr_mask);
        any_cls |= p[class_at] & class_mask;
        if (gps_at >= 0) any_gps |= las_f64(p + gps_at) != 0.0;
        if (rgb_at >= 0) any_rgb |= las_u16(p + rgb_at) | las_u16(p + rgb_at + 2) | las_u16(p + rgb_at + 4);
        if (nir_at >= 0) any_nir |= las_u16(p + nir_at);
    }
    free(buf);
    nonzero_fields nz = {any_int, any_ret, any_cls, any_rgb, any_nir, any_gps};
    extra_field *fields = NULL;
    size_t n_fields = 0;
    if ((rc = sy_cloud_init(meta, 1, err)) || (rc = add_format_arrays(meta, lay, err)) ||
        (rc = set_origin(path, &h, pts, meta, err)) ||
        (rc = prepare_extra_bytes(path, &h, &v, meta, &fields, &n_fields, err)))
        goto out;
    int ok = fabs(meta->origin[0]) <= SY_WORLD_MAX && fabs(meta->origin[1]) <= SY_WORLD_MAX &&
             fabs(meta->origin[2]) <= SY_WORLD_MAX;
    for (int a = 0; ok && a < 3; a++) {
        float f[2];
        for (int e = 0; e < 2; e++) {
            double x = (e ? mx[a] : mn[a]) * h.scale[a] + h.offset[a];
            f[e] = (float)(x - meta->origin[a]);
            ok &= isfinite(x) && fabsf(f[e]) <= (float)SY_CLOUD_MAX_SPAN;
        }
        lo[a] = meta->origin[a] + (f[0] < f[1] ? f[0] : f[1]);
        hi[a] = meta->origin[a] + (f[0] < f[1] ? f[1] : f[0]);
    }
    if (!ok) goto out; /* the whole reader words the error */
    drop_zero_fields(meta, &nz, 1);
    if ((rc = adopt_normals(meta, err)) || (rc = fill_meta(path, &h, &v, meta, err))) goto out;
    *n = (size_t)h.count;
    *done = 1;
out:
    free(fields);
    free(v.summary), free(v.geotiff);
    if (!*done) sy_cloud_free(meta);
    return rc;
}
