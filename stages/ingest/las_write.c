/* LAS 1.4 writer: point format 6 (7 with RGB, 8 with near infrared), named
 * attributes and normals (float NormalX/Y/Z, PDAL's names) as extra bytes,
 * the CRS carried over the way LAS 1.4 allows: formats 6-10 must declare WKT
 * (global encoding bit 4), so a WKT CRS goes out with them as a WKT VLR; a
 * CRS known only as GeoTIFF keys (turning keys into WKT needs a projection
 * database) goes out verbatim with a legacy point format 0-3, where GeoTIFF
 * is the CRS encoding, whenever the cloud fits one.
 * docs/formats.md has the full rule.
 *
 * Scale 0.0001 m with offset = the cloud origin: positions are float offsets
 * from the origin, whose precision near 100 m is ~8 um, so 0.1 mm steps lose
 * nothing real and still reach +-214 km. Wider clouds get a coarser decimal
 * scale so every coordinate fits in int32. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "../core/fileio.h"
#include "ingest.h"
#include "las_format.h"
#include "laz.h"

enum { CHUNK_POINTS = 4096, MAX_DESCRIPTORS = 65535 / LAS_EB_DESCRIPTOR };

typedef struct {
    int format;
    int laz; /* a .laz path: the same file, its points LASzip-compressed */
    unsigned record_length;
    double scale;
    int32_t lo[3], hi[3]; /* quantised bounds */
    uint64_t by_return[15];
    unsigned char *eb_types; /* per attribute: LAS_EB_INT32 or LAS_EB_DOUBLE */
    unsigned char *header;   /* header + VLRs */
    size_t header_len;
    const char *wkt;               /* CRS to write as a WKT VLR, or NULL */
    const unsigned char *geotiff;  /* GeoTIFF VLRs to copy, or NULL */
    size_t geotiff_len;
    unsigned geotiff_vlrs;
    unsigned char made_geotiff[LAS_VLR_HEADER + 24]; /* keys made from an "EPSG:<code>" summary */
} las_plan;

static int32_t quantise(float v, double scale) { return (int32_t)llround((double)v / scale); }

/* Smallest decimal scale >= 0.0001 that keeps every coordinate in int32. */
static sy_code choose_scale(const char *path, const sy_cloud *c, las_plan *p, sy_error *err)
{
    double reach = 0.0;
    for (size_t i = 0; i < 3 * c->n; i++) {
        double a = fabs((double)c->xyz[i]);
        if (!isfinite(a))
            return sy_fail(err, SY_EINPUT, "%s: point %zu has a non-finite coordinate", path, i / 3);
        if (a > reach) reach = a;
    }
    for (int k = 0; k < 3; k++)
        if (!isfinite(c->origin[k])) return sy_fail(err, SY_EINPUT, "%s: the cloud origin is not finite", path);
    p->scale = 0.0001;
    while (reach / p->scale > 2.0e9) p->scale *= 10.0;
    return SY_OK;
}

static void scan_points(const sy_cloud *c, las_plan *p)
{
    for (int k = 0; k < 3; k++) {
        p->lo[k] = INT32_MAX;
        p->hi[k] = INT32_MIN;
    }
    for (size_t i = 0; i < c->n; i++)
        for (int k = 0; k < 3; k++) {
            int32_t q = quantise(c->xyz[3 * i + k], p->scale);
            if (q < p->lo[k]) p->lo[k] = q;
            if (q > p->hi[k]) p->hi[k] = q;
        }
    if (c->n == 0)
        for (int k = 0; k < 3; k++) p->lo[k] = p->hi[k] = 0;
    if (c->return_number)
        for (size_t i = 0; i < c->n; i++) {
            unsigned r = c->return_number[i] & 0x0F;
            if (r >= 1) p->by_return[r - 1]++;
        }
}

/* int32 when every value is integral and fits (ids, counts), else double.
 * NaN (no value) is allowed in int32 columns: it is written as no_data. */
static unsigned char attr_type(const sy_attr *a, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        double v = a->values[i];
        if (isnan(v)) continue;
        if (!(v > INT32_MIN && v <= INT32_MAX) || v != floor(v)) return LAS_EB_DOUBLE;
    }
    return LAS_EB_INT32;
}

static void put_text(unsigned char *dst, size_t width, const char *s)
{
    size_t n = strlen(s);
    memcpy(dst, s, n < width ? n : width);
}

static unsigned char *put_vlr_header(unsigned char *q, const char *user, unsigned record_id, size_t len,
                                     const char *desc)
{
    put_text(q + 2, 16, user);
    las_put_u16(q + 18, (uint16_t)record_id);
    las_put_u16(q + 20, (uint16_t)len);
    put_text(q + 22, 32, desc);
    return q + LAS_VLR_HEADER;
}

/* The non-NaN extremes of a column (NaN when it has none) and whether NaN occurs. */
typedef struct {
    double lo, hi;
    int any_nan;
} value_range;

static void range_add(value_range *r, double v)
{
    r->any_nan |= isnan(v);
    if (isnan(v)) return;
    if (isnan(r->lo) || v < r->lo) r->lo = v;
    if (isnan(r->hi) || v > r->hi) r->hi = v;
}

static void put_descriptor(unsigned char *d, const char *name, unsigned char type, value_range r)
{
    int has_range = !isnan(r.lo) && !isinf(r.lo) && !isinf(r.hi);
    int no_data = r.any_nan && type == LAS_EB_INT32;
    d[LAS_EB_TYPE] = type;
    d[LAS_EB_OPTIONS] = (unsigned char)((has_range ? LAS_EB_OPT_MIN | LAS_EB_OPT_MAX : 0) |
                                        (no_data ? LAS_EB_OPT_NO_DATA : 0));
    put_text(d + LAS_EB_NAME, 32, name);
    if (type == LAS_EB_INT32) {
        if (no_data) las_put_u64(d + LAS_EB_NO_DATA, (uint64_t)(int64_t)INT32_MIN);
        if (has_range) {
            las_put_u64(d + LAS_EB_MIN, (uint64_t)(int64_t)r.lo);
            las_put_u64(d + LAS_EB_MAX, (uint64_t)(int64_t)r.hi);
        }
    } else if (has_range) { /* float and double fields both store the range as double */
        las_put_f64(d + LAS_EB_MIN, r.lo);
        las_put_f64(d + LAS_EB_MAX, r.hi);
    }
    char desc[32];
    snprintf(desc, sizeof desc, "%.20s (%s)", name, type == LAS_EB_INT32 ? "integer" : "real");
    put_text(d + LAS_EB_DESCRIPTION, 32, desc);
}

/* A WKT CRS starts with an upper-case keyword and '[' (PROJCS[, GEOGCRS[ ...);
 * summaries the reader cut with "..." are not valid WKT any more. */
static int is_wkt(const char *s)
{
    size_t k = 0;
    while ((s[k] >= 'A' && s[k] <= 'Z') || s[k] == '_') k++;
    size_t len = strlen(s);
    return k > 0 && s[k] == '[' && !(len >= 3 && strcmp(s + len - 3, "...") == 0);
}

/* GeoKeyDirectory with GTModelType and the projected or geographic EPSG key. */
static size_t geokeys_payload(unsigned char *q, unsigned code)
{
    int geographic = code >= 4000 && code < 5000; /* EPSG's geographic 2D range */
    uint16_t keys[12] = {1, 1, 0, 2, 1024, 0, 1, (uint16_t)(geographic ? 2 : 1),
                         (uint16_t)(geographic ? 2048 : 3072), 0, 1, (uint16_t)code};
    for (int i = 0; i < 12; i++) las_put_u16(q + 2 * i, keys[i]);
    return sizeof keys;
}

static void put_header(unsigned char *h, const sy_cloud *c, const las_plan *p, uint32_t n_vlrs)
{
    memcpy(h, "LASF", 4);
    unsigned encoding = (c->meta.gps_time_standard ? LAS_GLOBAL_GPS_STANDARD : 0) |
                        (p->format >= 6 ? LAS_GLOBAL_WKT : 0); /* LAS 1.4: required for formats 6-10 */
    las_put_u16(h + 6, (uint16_t)encoding);
    h[LAS_VERSION_MAJOR] = 1;
    h[LAS_VERSION_MINOR] = 4;
    put_text(h + LAS_SYSTEM_ID, 32, "Sylva");
    put_text(h + LAS_SOFTWARE, 32, "Sylva " SYLVA_VERSION);
    /* SOURCE_DATE_EPOCH makes output reproducible when a build asks for it. */
    const char *epoch = getenv("SOURCE_DATE_EPOCH");
    time_t now = epoch && *epoch ? (time_t)strtoll(epoch, NULL, 10) : time(NULL);
    struct tm tm;
    if (gmtime_r(&now, &tm)) {
        las_put_u16(h + LAS_CREATION_DAY, (uint16_t)(tm.tm_yday + 1));
        las_put_u16(h + LAS_CREATION_YEAR, (uint16_t)(tm.tm_year + 1900));
    }
    las_put_u16(h + LAS_HEADER_SIZE, LAS_HDR_14);
    las_put_u32(h + LAS_POINT_OFFSET, (uint32_t)p->header_len);
    las_put_u32(h + LAS_N_VLRS, n_vlrs);
    h[LAS_POINT_FORMAT] = (unsigned char)p->format;
    las_put_u16(h + LAS_RECORD_LENGTH, (uint16_t)p->record_length);
    /* Legacy counts stay 0 for point formats 6-10, as LAS 1.4 requires;
     * formats 0-5 fill them (the writer only picks those below 2^32 points). */
    if (p->format <= 5) {
        las_put_u32(h + LAS_LEGACY_COUNT, (uint32_t)c->n);
        for (int r = 0; r < 5; r++) las_put_u32(h + LAS_LEGACY_BY_RETURN + 4 * r, (uint32_t)p->by_return[r]);
    }
    for (int k = 0; k < 3; k++) {
        las_put_f64(h + LAS_SCALE + 8 * k, p->scale);
        las_put_f64(h + LAS_OFFSET + 8 * k, c->origin[k]);
        las_put_f64(h + LAS_BOUNDS + 16 * k, p->hi[k] * p->scale + c->origin[k]);
        las_put_f64(h + LAS_BOUNDS + 16 * k + 8, p->lo[k] * p->scale + c->origin[k]);
    }
    las_put_u64(h + LAS_COUNT64, (uint64_t)c->n);
    for (int r = 0; r < 15; r++) las_put_u64(h + LAS_BY_RETURN64 + 8 * r, p->by_return[r]);
}

/* Picks the CRS records: the whole WKT text when the input had one (a
 * complete WKT summary counts too), else the input's GeoTIFF VLRs, else keys
 * made from an "EPSG:<code>" summary. */
static void choose_crs(const sy_cloud *c, las_plan *p)
{
    const char *crs = c->meta.crs;
    p->wkt = c->meta.crs_wkt ? c->meta.crs_wkt : crs && is_wkt(crs) ? crs : NULL;
    if (p->wkt && strlen(p->wkt) >= 65535) p->wkt = NULL; /* past a VLR's 16-bit length */
    if (p->wkt) return;
    if (c->meta.geotiff) {
        p->geotiff = c->meta.geotiff;
        p->geotiff_len = c->meta.geotiff_len;
        p->geotiff_vlrs = c->meta.geotiff_vlrs;
    } else if (crs && strncmp(crs, "EPSG:", 5) == 0) {
        unsigned long code = strtoul(crs + 5, NULL, 10);
        if (code == 0 || code >= 32767) return;
        unsigned char *q = put_vlr_header(p->made_geotiff, "LASF_Projection", 34735, 24, "GeoKeyDirectoryTag");
        geokeys_payload(q, (unsigned)code);
        p->geotiff = p->made_geotiff;
        p->geotiff_len = sizeof p->made_geotiff;
        p->geotiff_vlrs = 1;
    }
}

/* Whether a legacy point format (0-3) holds every field the cloud has: no
 * near infrared, classes below 32 and at most 7 returns (their 5- and 3-bit
 * fields), and a count that fits the 32-bit legacy fields. */
static int legacy_fits(const sy_cloud *c)
{
    if (c->nir || c->n > UINT32_MAX) return 0;
    for (size_t i = 0; i < c->n; i++)
        if ((c->classification && c->classification[i] > 31) || (c->return_number && c->return_number[i] > 7) ||
            (c->num_returns && c->num_returns[i] > 7))
            return 0;
    return 1;
}

/* GeoTIFF keys are the CRS encoding of the legacy formats only, so a GeoTIFF
 * CRS picks one when the cloud fits; otherwise (e.g. near infrared) formats
 * 6-8 with the keys kept as they were, which a strict reader ignores but
 * loses nothing. */
static int choose_format(const sy_cloud *c, const las_plan *p)
{
    if (p->geotiff && legacy_fits(c)) return (c->gps_time ? 1 : 0) + (c->rgb ? 2 : 0);
    return c->nir ? 8 : c->rgb ? 7 : 6;
}

/* Builds header and VLRs into p->header. */
static sy_code build_header(const char *path, const sy_cloud *c, las_plan *p, sy_error *err)
{
    size_t n_fields = c->n_attrs + (c->normal ? 3 : 0);
    if (n_fields > MAX_DESCRIPTORS)
        return sy_fail(err, SY_EINPUT, "%s: %zu attributes exceed the %d a LAS extra-bytes record can describe",
                       path, n_fields, MAX_DESCRIPTORS);
    size_t eb_len = n_fields * LAS_EB_DESCRIPTOR, wkt_len = p->wkt ? strlen(p->wkt) + 1 : 0;
    size_t len = LAS_HDR_14 + (eb_len ? LAS_VLR_HEADER + eb_len : 0) + p->geotiff_len +
                 (wkt_len ? LAS_VLR_HEADER + wkt_len : 0);
    p->header = sy_calloc(len, 1, err, "LAS header");
    if (!p->header) return SY_EINTERNAL;
    p->header_len = len;
    unsigned char *q = p->header + LAS_HDR_14;
    uint32_t n_vlrs = 0;
    if (eb_len) {
        q = put_vlr_header(q, "LASF_Spec", 4, eb_len, "Extra bytes: Sylva attributes");
        for (size_t a = 0; a < c->n_attrs; a++) {
            value_range r = {NAN, NAN, 0};
            for (size_t i = 0; i < c->n; i++) range_add(&r, c->attrs[a].values[i]);
            put_descriptor(q + a * LAS_EB_DESCRIPTOR, c->attrs[a].name, p->eb_types[a], r);
        }
        for (int k = 0; c->normal && k < 3; k++) {
            value_range r = {NAN, NAN, 0};
            for (size_t i = 0; i < c->n; i++) range_add(&r, c->normal[3 * i + k]);
            put_descriptor(q + (c->n_attrs + (size_t)k) * LAS_EB_DESCRIPTOR, las_normal_names[k], LAS_EB_FLOAT, r);
        }
        q += eb_len;
        n_vlrs++;
    }
    if (p->geotiff_len) {
        memcpy(q, p->geotiff, p->geotiff_len);
        q += p->geotiff_len;
        n_vlrs += p->geotiff_vlrs;
    }
    if (wkt_len) {
        q = put_vlr_header(q, "LASF_Projection", 2112, wkt_len, "OGC coordinate system WKT");
        memcpy(q, p->wkt, wkt_len);
        n_vlrs++;
    }
    put_header(p->header, c, p, n_vlrs);
    return SY_OK;
}

/* Formats 0-5 pack return number and count in 3 bits each and the class in 5
 * bits of byte 15; formats 6-10 use 4 bits each and all of byte 16. */
static void encode_point(unsigned char *r, const sy_cloud *c, const las_plan *p, size_t i)
{
    const las_layout *lay = &las_layouts[p->format];
    const int legacy = p->format <= 5;
    memset(r, 0, p->record_length);
    for (int k = 0; k < 3; k++) las_put_u32(r + 4 * k, (uint32_t)quantise(c->xyz[3 * i + k], p->scale));
    if (c->intensity) las_put_u16(r + 12, c->intensity[i]);
    if (c->return_number) {
        unsigned rn = c->return_number[i], nr = c->num_returns ? c->num_returns[i] : 0;
        r[14] = (unsigned char)(legacy ? (rn & 0x07) | (nr & 0x07) << 3 : (rn & 0x0F) | (nr & 0x0F) << 4);
    }
    if (c->classification) {
        if (legacy) r[15] = c->classification[i] & 0x1F;
        else r[16] = c->classification[i];
    }
    if (c->gps_time && lay->gps >= 0) las_put_f64(r + lay->gps, c->gps_time[i]);
    if (c->rgb && lay->rgb >= 0)
        for (int k = 0; k < 3; k++) las_put_u16(r + lay->rgb + 2 * k, c->rgb[3 * i + k]);
    if (c->nir && lay->nir >= 0) las_put_u16(r + lay->nir, c->nir[i]);
    unsigned char *e = r + lay->size;
    for (size_t a = 0; a < c->n_attrs; a++) {
        double v = c->attrs[a].values[i];
        if (p->eb_types[a] == LAS_EB_INT32) {
            las_put_u32(e, (uint32_t)(isnan(v) ? INT32_MIN : (int32_t)v));
            e += 4;
        } else {
            las_put_f64(e, v);
            e += 8;
        }
    }
    for (int k = 0; c->normal && k < 3; k++, e += 4) las_put_f32(e, c->normal[3 * i + k]);
}

typedef struct {
    const sy_cloud *c;
    const las_plan *p;
} record_source;

static void fill_records(void *user, uint64_t first, uint32_t count, unsigned char *records)
{
    const record_source *src = user;
    for (uint32_t i = 0; i < count; i++)
        encode_point(records + (size_t)i * src->p->record_length, src->c, src->p, (size_t)first + i);
}

/* LAZ: the LAS header with the compression bit on the point format, the
 * LASzip VLR after the others, then the chunked compressed points. */
static sy_code write_laz(FILE *fp, const char *path, const sy_cloud *c, const las_plan *p, sy_error *err)
{
    laz_layout L = {p->format, p->record_length, p->record_length - las_layouts[p->format].size, p->format >= 6,
                    LAZ_DEFAULT_CHUNK};
    unsigned char vlr[LAZ_VLR_MAX];
    size_t vlr_len = laz_make_vlr(&L, vlr);
    unsigned char *h = malloc(p->header_len);
    if (!h) return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    memcpy(h, p->header, p->header_len);
    h[LAS_POINT_FORMAT] = (unsigned char)(p->format | 0x80);
    las_put_u32(h + LAS_POINT_OFFSET, (uint32_t)(p->header_len + vlr_len));
    las_put_u32(h + LAS_N_VLRS, las_u32(h + LAS_N_VLRS) + 1);
    int ok = fwrite(h, 1, p->header_len, fp) == p->header_len && fwrite(vlr, 1, vlr_len, fp) == vlr_len;
    free(h);
    if (!ok) return sy_fail(err, SY_EINPUT, "%s: write failed", path);
    record_source src = {c, p};
    return laz_write_points(fp, path, &L, c->n, fill_records, &src, err);
}

static sy_code write_file(const char *path, const sy_cloud *c, const las_plan *p, sy_error *err)
{
    sy_atomic_file f;
    sy_code rc = sy_atomic_open(&f, path, err);
    if (rc) return rc;
    if (p->laz) {
        rc = write_laz(f.fp, path, c, p, err);
        if (rc) {
            sy_atomic_abort(&f);
            return rc;
        }
        return sy_atomic_commit(&f, err);
    }
    unsigned char *chunk = sy_calloc(CHUNK_POINTS, p->record_length, err, "LAS write buffer");
    if (!chunk) {
        sy_atomic_abort(&f);
        return SY_EINTERNAL;
    }
    int ok = fwrite(p->header, 1, p->header_len, f.fp) == p->header_len;
    for (size_t start = 0; ok && start < c->n; start += CHUNK_POINTS) {
        size_t m = c->n - start < CHUNK_POINTS ? c->n - start : CHUNK_POINTS;
        for (size_t i = 0; i < m; i++) encode_point(chunk + i * p->record_length, c, p, start + i);
        ok = fwrite(chunk, p->record_length, m, f.fp) == m;
    }
    free(chunk);
    if (!ok) {
        sy_atomic_abort(&f);
        return sy_fail(err, SY_EINPUT, "%s: write failed", path);
    }
    return sy_atomic_commit(&f, err);
}

sy_code sy_write_las(const char *path, const sy_cloud *c, sy_error *err)
{
    las_plan p;
    memset(&p, 0, sizeof p);
    char ext[16];
    p.laz = strcmp(sy_extension(path, ext, sizeof ext), "laz") == 0;
    choose_crs(c, &p);
    p.format = choose_format(c, &p);
    sy_code rc = choose_scale(path, c, &p, err);
    if (rc) return rc;
    scan_points(c, &p);
    p.eb_types = sy_calloc(c->n_attrs, 1, err, "attribute types");
    if (!p.eb_types) return SY_EINTERNAL;
    size_t record = las_layouts[p.format].size;
    for (size_t a = 0; a < c->n_attrs; a++) {
        p.eb_types[a] = attr_type(&c->attrs[a], c->n);
        record += p.eb_types[a] == LAS_EB_INT32 ? 4 : 8;
    }
    if (c->normal) record += 3 * sizeof(float);
    if (record > 65535) {
        free(p.eb_types);
        return sy_fail(err, SY_EINPUT, "%s: %zu attributes make a %zu-byte record, over LAS's 65535", path,
                       c->n_attrs, record);
    }
    p.record_length = (unsigned)record;
    rc = build_header(path, c, &p, err);
    if (rc == SY_OK) rc = write_file(path, c, &p, err);
    free(p.header);
    free(p.eb_types);
    return rc;
}
