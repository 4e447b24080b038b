/* PCD reader (PCL's Point Cloud Data, v0.5 to v0.7) in plain C: PCL's pcl_io
 * would drag VTK into the binary. A text header (FIELDS SIZE TYPE COUNT WIDTH
 * HEIGHT VIEWPOINT POINTS DATA) is followed by ascii lines, binary point-major
 * records, or binary_compressed: two uint32 sizes, then LZF over field-major
 * data. NaN positions mean "no return" in PCL clouds; those points are skipped
 * and counted in meta.vlr_summary. */
#include "ingest.h"
#include "text_scan.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { PCD_ASCII, PCD_BINARY, PCD_COMPRESSED };
enum { ROLE_SKIP, ROLE_X, ROLE_Y, ROLE_Z, ROLE_NX, ROLE_NY, ROLE_NZ, ROLE_RGB, ROLE_INTENSITY, ROLE_ATTR };

/* A single field can be at most this wide (size x count); it keeps record
 * sizes far from overflow while allowing any real descriptor histogram. */
#define PCD_MAX_FIELD_BYTES (1u << 20)
/* LZF's densest token (3 bytes) expands to 264 bytes. */
#define LZF_MAX_RATIO 88

typedef struct {
    char name[32];
    char type;          /* 'I', 'U' or 'F' */
    unsigned size;      /* bytes per element: 1, 2, 4 or 8 */
    unsigned count;     /* elements per point */
    int role;
    double *attr;       /* ROLE_ATTR destination */
    const unsigned char *base; /* binary: first point's value */
    size_t stride;             /* binary: bytes between points */
    size_t column, column_nopad; /* ascii: token index with and without '_' columns */
} pcd_field;

typedef struct {
    const char *path;
    char version[16];
    pcd_field *f;
    size_t nf;
    int have_width, have_height, have_points;
    uint64_t width, height, points;
    int kind;
    size_t data;        /* offset of the first byte after the DATA line */
    size_t data_line;   /* line number of the DATA line */
    size_t record;      /* binary record bytes, '_' padding included */
    size_t record_packed; /* compressed record bytes, '_' padding excluded */
    size_t columns, columns_nopad;
} pcd_header;

/* A packed colour in ascii: new PCL writes the uint32, older PCL writes the
 * float whose bits hold it (e.g. 4.2108e+06 or 2.35e-38). */
static int tok_rgb_bits(const sy_tok *t, uint32_t *bits)
{
    uint64_t u;
    if (sy_tok_u64(t, &u)) {
        if (u > UINT32_MAX) return 0;
        *bits = (uint32_t)u;
        return 1;
    }
    double d;
    if (!sy_tok_double(t, &d)) return 0;
    float f = (float)d;
    memcpy(bits, &f, sizeof f);
    return 1;
}

static uint64_t load_le(const unsigned char *p, unsigned size)
{
    /* Fixed widths first: the compiler turns these into single loads. */
    if (size == 4) return (uint64_t)p[0] | (uint64_t)p[1] << 8 | (uint64_t)p[2] << 16 | (uint64_t)p[3] << 24;
    if (size == 8) return load_le(p, 4) | load_le(p + 4, 4) << 32;
    uint64_t v = 0;
    for (unsigned i = 0; i < size; i++) v |= (uint64_t)p[i] << (8 * i);
    return v;
}

/* ---- header ---------------------------------------------------------- */

static sy_code parse_fields(pcd_header *h, const char *p, const char *e, size_t line, sy_error *err)
{
    sy_tok t;
    size_t n = sy_tok_count(p, e);
    if (n == 0) return sy_fail(err, SY_EINPUT, "%s: line %zu: FIELDS lists no fields", h->path, line);
    free(h->f);
    h->f = sy_calloc(n, sizeof *h->f, err, "PCD fields");
    if (!h->f) return SY_EINTERNAL;
    h->nf = n;
    for (size_t i = 0; i < n && sy_tok_next(&p, e, &t); i++) {
        pcd_field *f = &h->f[i];
        snprintf(f->name, sizeof f->name, "%.*s", (int)(t.n < 31 ? t.n : 31), t.s);
        /* PCL's defaults for headers that predate SIZE/TYPE/COUNT. */
        f->type = 'F';
        f->size = 4;
        f->count = 1;
    }
    return SY_OK;
}

/* SIZE, TYPE or COUNT: one token per field. */
static sy_code parse_per_field(pcd_header *h, const sy_tok *key, const char *p, const char *e,
                               size_t line, sy_error *err)
{
    if (!h->nf)
        return sy_fail(err, SY_EINPUT, "%s: line %zu: %.*s before FIELDS", h->path, line, (int)key->n, key->s);
    sy_tok t;
    size_t i = 0;
    for (; sy_tok_next(&p, e, &t); i++) {
        if (i >= h->nf) break;
        pcd_field *f = &h->f[i];
        uint64_t v = 0;
        if (sy_tok_is(key, "TYPE")) {
            if (t.n != 1 || (t.s[0] != 'I' && t.s[0] != 'U' && t.s[0] != 'F'))
                return sy_fail(err, SY_EINPUT, "%s: line %zu: field %s has unknown TYPE '%.*s' (want I, U or F)",
                               h->path, line, f->name, (int)(t.n < 16 ? t.n : 16), t.s);
            f->type = t.s[0];
        } else if (!sy_tok_u64(&t, &v)) {
            return sy_fail(err, SY_EINPUT, "%s: line %zu: bad %.*s value for field %s", h->path, line,
                           (int)key->n, key->s, f->name);
        } else if (sy_tok_is(key, "SIZE")) {
            if (v != 1 && v != 2 && v != 4 && v != 8)
                return sy_fail(err, SY_EINPUT, "%s: line %zu: field %s has SIZE %llu (want 1, 2, 4 or 8)", h->path,
                               line, f->name, (unsigned long long)v);
            f->size = (unsigned)v;
        } else {
            if (v == 0 || v > PCD_MAX_FIELD_BYTES)
                return sy_fail(err, SY_EINPUT, "%s: line %zu: field %s has COUNT %llu", h->path, line, f->name,
                               (unsigned long long)v);
            f->count = (unsigned)v;
        }
    }
    if (i != h->nf)
        return sy_fail(err, SY_EINPUT, "%s: line %zu: %.*s has %s values than FIELDS has fields (%zu)", h->path, line,
                       (int)key->n, key->s, i < h->nf ? "fewer" : "more", h->nf);
    return SY_OK;
}

static sy_code parse_count(pcd_header *h, const sy_tok *key, const char *p, const char *e, size_t line,
                           uint64_t *v, int *have, sy_error *err)
{
    sy_tok t;
    if (!sy_tok_next(&p, e, &t) || !sy_tok_u64(&t, v))
        return sy_fail(err, SY_EINPUT, "%s: line %zu: %.*s needs a non-negative integer", h->path, line, (int)key->n,
                       key->s);
    *have = 1;
    return SY_OK;
}

static sy_code parse_data_kind(pcd_header *h, const char *p, const char *e, size_t line, sy_error *err)
{
    sy_tok t;
    if (!sy_tok_next(&p, e, &t)) return sy_fail(err, SY_EINPUT, "%s: line %zu: DATA without a kind", h->path, line);
    if (sy_tok_is(&t, "ascii")) h->kind = PCD_ASCII;
    else if (sy_tok_is(&t, "binary")) h->kind = PCD_BINARY;
    else if (sy_tok_is(&t, "binary_compressed")) h->kind = PCD_COMPRESSED;
    else
        return sy_fail(err, SY_EINPUT, "%s: line %zu: unknown DATA kind '%.*s' (want ascii, binary or binary_compressed)",
                       h->path, line, sy_tok_shown(&t), t.s);
    return SY_OK;
}

/* Fills in WIDTH/HEIGHT/POINTS the way PCL does for older headers and checks
 * that they agree. */
static sy_code resolve_counts(pcd_header *h, sy_error *err)
{
    if (!h->have_width && !h->have_height) {
        if (!h->have_points) return sy_fail(err, SY_EINPUT, "%s: header has neither POINTS nor WIDTH", h->path);
        h->width = h->points;
        h->height = 1;
    } else if (!h->have_width) {
        return sy_fail(err, SY_EINPUT, "%s: header has HEIGHT but no WIDTH", h->path);
    } else if (!h->have_height) {
        h->height = 1;
    }
    if (h->height && h->width > UINT64_MAX / h->height)
        return sy_fail(err, SY_EINPUT, "%s: WIDTH x HEIGHT overflows", h->path);
    uint64_t grid = h->width * h->height;
    if (!h->have_points) h->points = grid;
    else if (h->points != grid)
        return sy_fail(err, SY_EINPUT, "%s: POINTS %llu does not match WIDTH %llu x HEIGHT %llu", h->path,
                       (unsigned long long)h->points, (unsigned long long)h->width, (unsigned long long)h->height);
    return SY_OK;
}

/* Checks the field table and lays out records and ascii columns. */
static sy_code layout_fields(pcd_header *h, sy_error *err)
{
    if (!h->nf) return sy_fail(err, SY_EINPUT, "%s: header has no FIELDS line", h->path);
    int have[3] = {0, 0, 0};
    uint64_t record = 0, packed = 0, columns = 0, nopad = 0;
    for (size_t i = 0; i < h->nf; i++) {
        pcd_field *f = &h->f[i];
        if (f->type == 'F' && f->size != 4 && f->size != 8)
            return sy_fail(err, SY_EINPUT, "%s: field %s: float of %u bytes is not supported", h->path, f->name, f->size);
        if ((uint64_t)f->size * f->count > PCD_MAX_FIELD_BYTES)
            return sy_fail(err, SY_EINPUT, "%s: field %s is %u x %u bytes wide", h->path, f->name, f->count, f->size);
        int pad = strcmp(f->name, "_") == 0;
        f->column = (size_t)columns;
        f->column_nopad = (size_t)nopad;
        record += (uint64_t)f->size * f->count;
        columns += f->count;
        if (!pad) {
            packed += (uint64_t)f->size * f->count;
            nopad += f->count;
        }
        for (int k = 0; k < 3; k++)
            if (strcmp(f->name, (const char *[]){"x", "y", "z"}[k]) == 0) {
                if (f->count != 1)
                    return sy_fail(err, SY_EINPUT, "%s: field %s has COUNT %u (want 1)", h->path, f->name, f->count);
                have[k] = 1;
            }
    }
    if (!have[0] || !have[1] || !have[2])
        return sy_fail(err, SY_EINPUT, "%s: FIELDS lacks %s (x, y and z are required)", h->path,
                       !have[0] ? "x" : !have[1] ? "y" : "z");
    if (record > SIZE_MAX / 4 || columns > SIZE_MAX / 4)
        return sy_fail(err, SY_EINPUT, "%s: point records are too wide", h->path);
    h->record = (size_t)record;
    h->record_packed = (size_t)packed;
    h->columns = (size_t)columns;
    h->columns_nopad = (size_t)nopad;
    return SY_OK;
}

static sy_code parse_header(pcd_header *h, const unsigned char *d, size_t size, sy_error *err)
{
    sy_lines lines;
    sy_lines_init(&lines, d, size);
    const char *p, *e;
    while (sy_lines_next(&lines, &p, &e)) {
        size_t line = lines.line;
        sy_tok key;
        sy_code rc = SY_OK;
        if (!sy_tok_next(&p, e, &key) || key.s[0] == '#') continue;
        if (sy_tok_is(&key, "VERSION")) {
            sy_tok v;
            if (sy_tok_next(&p, e, &v)) snprintf(h->version, sizeof h->version, "%.*s", (int)(v.n < 15 ? v.n : 15), v.s);
        } else if (sy_tok_is(&key, "FIELDS") || sy_tok_is(&key, "COLUMNS")) {
            rc = parse_fields(h, p, e, line, err);
        } else if (sy_tok_is(&key, "SIZE") || sy_tok_is(&key, "TYPE") || sy_tok_is(&key, "COUNT")) {
            rc = parse_per_field(h, &key, p, e, line, err);
        } else if (sy_tok_is(&key, "WIDTH")) {
            rc = parse_count(h, &key, p, e, line, &h->width, &h->have_width, err);
        } else if (sy_tok_is(&key, "HEIGHT")) {
            rc = parse_count(h, &key, p, e, line, &h->height, &h->have_height, err);
        } else if (sy_tok_is(&key, "POINTS")) {
            rc = parse_count(h, &key, p, e, line, &h->points, &h->have_points, err);
        } else if (sy_tok_is(&key, "VIEWPOINT")) {
            /* The sensor pose does not move the points; nothing to keep. */
        } else if (sy_tok_is(&key, "DATA")) {
            rc = parse_data_kind(h, p, e, line, err);
            if (rc) return rc;
            h->data = sy_lines_offset(&lines, d);
            h->data_line = line;
            rc = layout_fields(h, err);
            return rc ? rc : resolve_counts(h, err);
        } else {
            return sy_fail(err, SY_EINPUT, "%s: line %zu: unexpected header line starting '%.*s'", h->path, line,
                           sy_tok_shown(&key), key.s);
        }
        if (rc) return rc;
    }
    return sy_fail(err, SY_EINPUT, "%s: header ends without a DATA line", h->path);
}

/* ---- LZF --------------------------------------------------------------- */

/* Decompresses liblzf's format into exactly out_len bytes. Every literal run
 * and back-reference is checked against both buffers; returns a problem
 * description, or NULL on success. */
static const char *lzf_decompress(const unsigned char *in, size_t in_len, unsigned char *out, size_t out_len)
{
    size_t ip = 0, op = 0;
    while (ip < in_len) {
        unsigned ctrl = in[ip++];
        if (ctrl < 32) {
            size_t run = (size_t)ctrl + 1;
            if (run > in_len - ip) return "literal run past the end of the compressed data";
            if (run > out_len - op) return "literal run past the declared uncompressed size";
            memcpy(out + op, in + ip, run);
            ip += run;
            op += run;
            continue;
        }
        size_t len = ctrl >> 5;
        size_t back = ((size_t)(ctrl & 0x1f) << 8) + 1;
        if (len == 7) {
            if (ip >= in_len) return "back-reference cut short";
            len += in[ip++];
        }
        if (ip >= in_len) return "back-reference cut short";
        back += in[ip++];
        len += 2;
        if (back > op) return "back-reference before the start of the data";
        if (len > out_len - op) return "back-reference past the declared uncompressed size";
        /* Byte by byte only when source and destination overlap (the
         * run-length case); memcpy is several times faster otherwise. */
        if (back >= len) memcpy(out + op, out + op - back, len);
        else
            for (size_t k = 0; k < len; k++) out[op + k] = out[op - back + k];
        op += len;
    }
    if (op != out_len) return "decompressed data is shorter than declared";
    return NULL;
}

/* ---- body -------------------------------------------------------------- */

/* Points are decoded a block at a time into per-field columns of doubles,
 * then stored field by field: the type and role switches run once per field
 * and block instead of once per field and point. A block holds up to
 * PCD_BLOCK_VALUES values, so thousands of fields still cost only 512 KiB. */
enum { PCD_BLOCK = 1024, PCD_BLOCK_VALUES = 1 << 16 };

typedef struct {
    pcd_header *h;
    sy_lines lines;   /* ascii cursor */
    sy_tok *toks;     /* ascii: columns + 1 slots */
    size_t rows;      /* points per block */
    double *cols;     /* nf x rows: field k of block row i at cols[k * rows + i] */
    size_t *slot;     /* rows: the row's cloud index (kept rows only) */
    uint8_t *skip;    /* rows: 1 for a NaN point left out */
} pcd_body;

/* Points binary fields at their data: point-major records for binary,
 * field-major blocks (padding left out) for binary_compressed. */
static void bind_binary(pcd_header *h, const unsigned char *data)
{
    size_t offset = 0;
    for (size_t i = 0; i < h->nf; i++) {
        pcd_field *f = &h->f[i];
        size_t width = (size_t)f->size * f->count;
        if (h->kind == PCD_BINARY) {
            f->base = data + offset;
            f->stride = h->record;
            offset += width;
        } else if (strcmp(f->name, "_") != 0) {
            f->base = data + offset * h->points;
            f->stride = width;
            offset += width;
        }
    }
}

static float bits_float(uint32_t b)
{
    float f;
    memcpy(&f, &b, sizeof f);
    return f;
}

static double bits_double(uint64_t b)
{
    double d;
    memcpy(&d, &b, sizeof d);
    return d;
}

/* One binary field for points [start, start + m). A packed colour (always 4
 * bytes, see role_of) gives its raw bits. */
static void decode_column(const pcd_field *f, size_t start, size_t m, double *out)
{
    const unsigned char *p = f->base + start * f->stride;
    const size_t s = f->stride;
#define COLUMN_LOOP(expr)                              \
    for (size_t i = 0; i < m; i++) out[i] = (double)(expr); \
    return
    if (f->role == ROLE_RGB) {
        COLUMN_LOOP((uint32_t)load_le(p + i * s, 4));
    }
    switch (f->type == 'F' ? f->size : f->type == 'U' ? 16 + f->size : 32 + f->size) {
    case 4: COLUMN_LOOP(bits_float((uint32_t)load_le(p + i * s, 4)));
    case 8: COLUMN_LOOP(bits_double(load_le(p + i * s, 8)));
    case 16 + 1: COLUMN_LOOP(p[i * s]);
    case 16 + 2: COLUMN_LOOP(load_le(p + i * s, 2));
    case 16 + 4: COLUMN_LOOP(load_le(p + i * s, 4));
    case 16 + 8: COLUMN_LOOP(load_le(p + i * s, 8));
    case 32 + 1: COLUMN_LOOP((int8_t)p[i * s]);
    case 32 + 2: COLUMN_LOOP((int16_t)load_le(p + i * s, 2));
    case 32 + 4: COLUMN_LOOP((int32_t)load_le(p + i * s, 4));
    default: COLUMN_LOOP((int64_t)load_le(p + i * s, 8));
    }
#undef COLUMN_LOOP
}

/* Tokenizes the next non-empty ascii line into block row `row`. */
static sy_code ascii_point(pcd_body *b, size_t i, size_t row, sy_error *err)
{
    const pcd_header *h = b->h;
    size_t ntok = 0;
    while (ntok == 0) {
        const char *p, *e;
        if (!sy_lines_next(&b->lines, &p, &e))
            return sy_fail(err, SY_EINPUT, "%s: truncated: data ends after %zu of %llu points", h->path, i,
                           (unsigned long long)h->points);
        while (ntok <= h->columns && sy_tok_next(&p, e, &b->toks[ntok])) ntok++;
    }
    int nopad = ntok != h->columns;
    if (nopad && (ntok != h->columns_nopad || h->columns_nopad == h->columns))
        return sy_fail(err, SY_EINPUT, "%s: line %zu: %s values, expected %zu", h->path, b->lines.line,
                       ntok > h->columns ? "too many" : "too few", h->columns);
    for (size_t k = 0; k < h->nf; k++) {
        const pcd_field *f = &h->f[k];
        if (f->role == ROLE_SKIP) continue;
        const sy_tok *t = &b->toks[nopad ? f->column_nopad : f->column];
        double *v = &b->cols[k * b->rows + row];
        uint32_t bits = 0;
        int ok = f->role == ROLE_RGB ? tok_rgb_bits(t, &bits) : sy_tok_double(t, v);
        if (ok && f->role == ROLE_RGB) *v = bits;
        if (!ok)
            return sy_fail(err, SY_EINPUT, "%s: line %zu: bad value '%.*s' for field %s", h->path, b->lines.line,
                           sy_tok_shown(t), t->s, f->name);
    }
    return SY_OK;
}

static int role_of(const pcd_field *f)
{
    static const struct { const char *name; int role; } fixed[] = {
        {"x", ROLE_X},         {"y", ROLE_Y},         {"z", ROLE_Z},     {"normal_x", ROLE_NX},
        {"normal_y", ROLE_NY}, {"normal_z", ROLE_NZ}, {"rgb", ROLE_RGB}, {"rgba", ROLE_RGB},
        {"intensity", ROLE_INTENSITY},
    };
    if (strcmp(f->name, "_") == 0 || f->count != 1) return ROLE_SKIP;
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++)
        if (strcmp(f->name, fixed[i].name) == 0) {
            if (fixed[i].role == ROLE_RGB && f->size != 4) return ROLE_ATTR;
            return fixed[i].role;
        }
    return ROLE_ATTR;
}

/* Gives each field a role and the cloud the arrays those roles fill. */
static sy_code assign_roles(pcd_header *h, sy_cloud *c, double **intensity, sy_error *err)
{
    for (size_t i = 0; i < h->nf; i++) {
        pcd_field *f = &h->f[i];
        f->role = role_of(f);
        sy_code rc = SY_OK;
        if (f->role >= ROLE_NX && f->role <= ROLE_NZ) rc = sy_cloud_add_normals(c, err);
        else if (f->role == ROLE_RGB) rc = sy_cloud_add_rgb(c, err);
        else if (f->role == ROLE_INTENSITY && !*intensity) {
            rc = sy_cloud_add_intensity(c, err);
            *intensity = rc ? NULL : sy_calloc(c->n, sizeof(double), err, "PCD intensity");
            if (!*intensity) rc = SY_EINTERNAL;
        } else if (f->role == ROLE_ATTR) {
            f->attr = sy_cloud_add_attr(c, f->name, err);
            if (!f->attr) rc = SY_EINTERNAL;
        }
        if (rc) return rc;
    }
    return SY_OK;
}

/* Intensity is float in most PCD files: either normalised to [0, 1] (scaled
 * to the full 16-bit range) or sensor counts (rounded, clamped to 16 bits). */
static void store_intensity(sy_cloud *c, const double *raw)
{
    int unit = 1;
    for (size_t i = 0; i < c->n && unit; i++) unit = raw[i] >= 0.0 && raw[i] <= 1.0;
    double scale = unit ? 65535.0 : 1.0;
    for (size_t i = 0; i < c->n; i++) {
        double v = raw[i] * scale;
        c->intensity[i] = (uint16_t)(v != v || v < 0 ? 0 : v > 65535 ? 65535 : lround(v));
    }
}

/* Positions of the block's m rows: NaN points (PCL's "no return") are
 * skipped, the rest get cloud slots from *j on. The origin is the metre floor
 * of the first point kept, as in the LAS reader, so float offsets stay small
 * without a second pass over the cloud. */
static sy_code store_positions(pcd_body *b, sy_cloud *c, size_t start, size_t m, const size_t axis[3], size_t *j,
                               size_t *nan_skipped, sy_error *err)
{
    const double *x = b->cols + axis[0] * b->rows, *y = b->cols + axis[1] * b->rows,
                 *z = b->cols + axis[2] * b->rows;
    for (size_t i = 0; i < m; i++) {
        if (isnan(x[i]) || isnan(y[i]) || isnan(z[i])) {
            b->skip[i] = 1;
            ++*nan_skipped;
            continue;
        }
        if (!(isfinite(x[i]) && isfinite(y[i]) && isfinite(z[i])))
            return sy_check_finite(b->h->path, x[i], y[i], z[i], start + i, err);
        if (*j == 0) {
            c->origin[0] = floor(x[i]);
            c->origin[1] = floor(y[i]);
            c->origin[2] = floor(z[i]);
        }
        float *q = c->xyz + 3 * *j;
        q[0] = (float)(x[i] - c->origin[0]);
        q[1] = (float)(y[i] - c->origin[1]);
        q[2] = (float)(z[i] - c->origin[2]);
        b->skip[i] = 0;
        b->slot[i] = (*j)++;
    }
    return SY_OK;
}

/* The block's other fields into their cloud arrays, one field at a time. */
static void store_fields(const pcd_body *b, sy_cloud *c, size_t m, double *intensity)
{
    for (size_t k = 0; k < b->h->nf; k++) {
        const pcd_field *f = &b->h->f[k];
        const double *v = b->cols + k * b->rows;
        const size_t *slot = b->slot;
        const uint8_t *skip = b->skip;
        switch (f->role) {
        case ROLE_NX: case ROLE_NY: case ROLE_NZ: {
            size_t axis = (size_t)(f->role - ROLE_NX);
            for (size_t i = 0; i < m; i++)
                if (!skip[i]) c->normal[3 * slot[i] + axis] = (float)v[i];
            break;
        }
        case ROLE_RGB:
            for (size_t i = 0; i < m; i++) {
                if (skip[i]) continue;
                uint32_t bits = (uint32_t)v[i];
                for (int ch = 0; ch < 3; ch++)
                    c->rgb[3 * slot[i] + ch] = (uint16_t)(((bits >> (16 - 8 * ch)) & 0xff) * 257);
            }
            break;
        case ROLE_INTENSITY:
            for (size_t i = 0; i < m; i++)
                if (!skip[i]) intensity[slot[i]] = v[i];
            break;
        case ROLE_ATTR:
            for (size_t i = 0; i < m; i++)
                if (!skip[i]) f->attr[slot[i]] = v[i];
            break;
        default: break;
        }
    }
}

static sy_code read_points(pcd_body *b, sy_cloud *c, double *intensity, size_t *nan_skipped, sy_error *err)
{
    const pcd_header *h = b->h;
    size_t axis[3] = {0, 0, 0}, j = 0;
    for (size_t k = 0; k < h->nf; k++)
        if (h->f[k].role >= ROLE_X && h->f[k].role <= ROLE_Z) axis[h->f[k].role - ROLE_X] = k;
    for (size_t start = 0; start < (size_t)h->points; start += b->rows) {
        size_t m = (size_t)h->points - start < b->rows ? (size_t)h->points - start : b->rows;
        for (size_t k = 0; k < h->nf; k++)
            if (h->f[k].role != ROLE_SKIP && h->kind != PCD_ASCII)
                decode_column(&h->f[k], start, m, b->cols + k * b->rows);
        for (size_t i = 0; h->kind == PCD_ASCII && i < m; i++) {
            sy_code rc = ascii_point(b, start + i, i, err);
            if (rc) return rc;
        }
        sy_code rc = store_positions(b, c, start, m, axis, &j, nan_skipped, err);
        if (rc) return rc;
        store_fields(b, c, m, intensity);
    }
    c->n = j;
    return SY_OK;
}

/* Where the point data lives once checked against the bytes present: the
 * record area itself, or a freshly decompressed copy in *owned. */
static sy_code locate_data(pcd_header *h, const unsigned char *d, size_t size, unsigned char **owned, sy_error *err)
{
    size_t avail = size - h->data;
    *owned = NULL;
    if (h->kind == PCD_ASCII) {
        size_t min_cols = h->columns_nopad < h->columns ? h->columns_nopad : h->columns;
        if (min_cols == 0) min_cols = 1;
        if (h->points > (uint64_t)(avail + 1) / (2 * min_cols))
            return sy_fail(err, SY_EINPUT, "%s: POINTS %llu is more than the %zu data bytes can hold", h->path,
                           (unsigned long long)h->points, avail);
        return SY_OK;
    }
    if (h->kind == PCD_BINARY) {
        if (h->points > (uint64_t)avail / h->record)
            return sy_fail(err, SY_EINPUT, "%s: truncated: %llu points of %zu bytes do not fit in the %zu data bytes",
                           h->path, (unsigned long long)h->points, h->record, avail);
        bind_binary(h, d + h->data);
        return SY_OK;
    }
    if (avail < 8) return sy_fail(err, SY_EINPUT, "%s: truncated: binary_compressed sizes missing", h->path);
    uint32_t csize = (uint32_t)load_le(d + h->data, 4), usize = (uint32_t)load_le(d + h->data + 4, 4);
    if (h->record_packed == 0 || h->points > UINT32_MAX / h->record_packed ||
        (uint64_t)usize != h->points * h->record_packed)
        return sy_fail(err, SY_EINPUT, "%s: binary_compressed declares %u bytes, %llu points need %llu", h->path, usize,
                       (unsigned long long)h->points, (unsigned long long)(h->points * h->record_packed));
    if (csize > avail - 8)
        return sy_fail(err, SY_EINPUT, "%s: truncated: %u compressed bytes declared, %zu present", h->path, csize,
                       avail - 8);
    if ((uint64_t)usize > (uint64_t)csize * LZF_MAX_RATIO)
        return sy_fail(err, SY_EINPUT, "%s: corrupt LZF data: %u compressed bytes cannot expand to %u", h->path, csize,
                       usize);
    *owned = sy_calloc(usize, 1, err, "PCD decompression");
    if (!*owned) return SY_EINTERNAL;
    const char *problem = lzf_decompress(d + h->data + 8, csize, *owned, usize);
    if (problem) return sy_fail(err, SY_EINPUT, "%s: corrupt LZF data: %s", h->path, problem);
    bind_binary(h, *owned);
    return SY_OK;
}

/* meta.vlr_summary: grid shape, skipped NaN points and skipped fields. */
static sy_code summarize(const pcd_header *h, sy_cloud *c, size_t nan_skipped, sy_error *err)
{
    size_t cap = 256 + 64 * h->nf;
    char *s = sy_calloc(cap, 1, err, "PCD summary");
    if (!s) return SY_EINTERNAL;
    size_t used = 0;
    if (h->height > 1)
        used += (size_t)snprintf(s + used, cap - used, "organized %llux%llu grid\n", (unsigned long long)h->width,
                                 (unsigned long long)h->height);
    if (nan_skipped) used += (size_t)snprintf(s + used, cap - used, "skipped %zu NaN points\n", nan_skipped);
    for (size_t i = 0; i < h->nf && used < cap; i++)
        if (h->f[i].count > 1)
            used += (size_t)snprintf(s + used, cap - used, "skipped field %s (COUNT %u)\n", h->f[i].name, h->f[i].count);
    if (used && used < cap) s[used - 1] = '\0';
    if (!used) {
        free(s);
        return SY_OK;
    }
    c->meta.vlr_summary = s;
    return SY_OK;
}

sy_code sy_read_pcd_mem(const char *path, const unsigned char *data, size_t size, sy_cloud *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    pcd_header h;
    memset(&h, 0, sizeof h);
    h.path = path;
    pcd_body b;
    memset(&b, 0, sizeof b);
    unsigned char *owned = NULL;
    double *intensity = NULL;
    size_t nan_skipped = 0;
    sy_code rc = parse_header(&h, data, size, err);
    if (!rc) rc = locate_data(&h, data, size, &owned, err);
    if (!rc) rc = sy_cloud_init(out, (size_t)h.points, err);
    if (!rc) rc = assign_roles(&h, out, &intensity, err);
    if (!rc) {
        b.h = &h;
        sy_lines_init(&b.lines, data + h.data, size - h.data);
        b.lines.line = h.data_line;
        b.rows = PCD_BLOCK_VALUES / h.nf < PCD_BLOCK ? PCD_BLOCK_VALUES / h.nf : PCD_BLOCK;
        if (b.rows == 0) b.rows = 1;
        b.cols = sy_calloc(h.nf, b.rows * sizeof *b.cols, err, "PCD values");
        b.slot = sy_calloc(b.rows, sizeof *b.slot, err, "PCD values");
        b.skip = sy_calloc(b.rows, sizeof *b.skip, err, "PCD values");
        if (h.kind == PCD_ASCII) b.toks = sy_calloc(h.columns + 1, sizeof *b.toks, err, "PCD tokens");
        if (!b.cols || !b.slot || !b.skip || (h.kind == PCD_ASCII && !b.toks)) rc = SY_EINTERNAL;
    }
    if (!rc) rc = read_points(&b, out, intensity, &nan_skipped, err);
    if (!rc && intensity) store_intensity(out, intensity);
    if (!rc) rc = summarize(&h, out, nan_skipped, err);
    if (!rc) {
        snprintf(out->meta.format, sizeof out->meta.format, "PCD");
        const char *kind = h.kind == PCD_ASCII ? "ascii" : h.kind == PCD_BINARY ? "binary" : "binary_compressed";
        if (h.version[0]) snprintf(out->meta.version, sizeof out->meta.version, "%.12s %s", h.version, kind);
        else snprintf(out->meta.version, sizeof out->meta.version, "%s", kind);
        out->meta.header_count = h.points;
    }
    free(b.cols);
    free(b.slot);
    free(b.skip);
    free(b.toks);
    free(intensity);
    free(owned);
    free(h.f);
    if (rc) sy_cloud_free(out);
    return rc;
}
