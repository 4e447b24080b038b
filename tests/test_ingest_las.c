/* LAS reader and writer: the real files in shared/data with their exact
 * counts and header bounds, every point format and extra-bytes type on files
 * built here byte by byte, malformed inputs, LAZ reading and round trips. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/cloud.h"
#include "stages/core/fileio.h"
#include "stages/ingest/ingest.h"

/* ---- little-endian helpers for building files by hand ---- */

static double getf64(const unsigned char *p)
{
    uint64_t u = 0;
    for (int i = 0; i < 8; i++) u |= (uint64_t)p[i] << (8 * i);
    double d;
    memcpy(&d, &u, 8);
    return d;
}

/* ---- a LAS builder independent of the writer under test ---- */

typedef struct {
    unsigned char type, options;
    const char *name;
    double scale, offset;
} eb_desc;

typedef struct {
    int format, minor;
    size_t n;
    const eb_desc *eb;
    size_t n_eb;
    const char *wkt;
    int wkt_as_evlr;
    unsigned n_empty_vlrs; /* extra zero-length VLRs, user "test" */
} las_spec;

static const unsigned base_size[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
static const int gps_at[11] = {-1, 20, -1, 20, 20, 20, 22, 22, 22, 22, 22};
static const int rgb_at[11] = {-1, -1, 20, 28, -1, 28, -1, 30, 30, -1, 30};
static const int nir_at[11] = {-1, -1, -1, -1, -1, -1, -1, -1, 36, -1, 36};

static size_t eb_width(const eb_desc *d)
{
    static const unsigned sizes[11] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
    if (d->type == 0) return d->options;
    if (d->type <= 10) return sizes[d->type];
    return sizes[(d->type - 1) % 10 + 1] * (d->type <= 20 ? 2u : 3u);
}

/* The raw value field k holds for point i (before its scale and offset). */
static double eb_raw(unsigned type, size_t i, size_t k)
{
    double v = (double)((i + 1) * (k + 1));
    if (type == 2 || type == 4 || type == 6 || type == 8) return -v;
    if (type == 9 || type == 10) return v + 0.25;
    return v;
}

static void eb_encode(unsigned char *p, unsigned type, double v)
{
    switch (type) {
    case 1: case 2: p[0] = (unsigned char)(int)v; break;
    case 3: case 4: put_le16(p, (unsigned)(int)v); break;
    case 5: case 6: put_le32(p, (uint32_t)(int32_t)v); break;
    case 7: case 8: put_le64(p, (uint64_t)(int64_t)v); break;
    case 9: put_lef32(p, (float)v); break;
    case 10: put_lef64(p, v); break;
    default: memset(p, 0xAB, 1); break; /* skipped fields: arbitrary bytes */
    }
}

/* Expected decoded fields for point i. */
static int32_t pt_x(size_t i) { return 1000 + 7 * (int32_t)i; }
static int32_t pt_y(size_t i) { return -2000 + 3 * (int32_t)i; }
static int32_t pt_z(size_t i) { return 50 * (int32_t)i; }
static const double SCALE = 0.01, OFF[3] = {481000.0, 3812000.0, 10.0};

static void put_vlr(unsigned char *q, const char *user, unsigned id, size_t len, int extended)
{
    memcpy(q + 2, user, strlen(user));
    put_le16(q + 18, id);
    if (extended) put_le64(q + 20, len);
    else put_le16(q + 20, (unsigned)len);
}

/* Builds the file into buf (64 KB is plenty for the sizes used); returns its size. */
static size_t build_las(const las_spec *s, unsigned char *buf, size_t cap)
{
    memset(buf, 0, cap);
    size_t hs = s->minor >= 4 ? 375 : 227, extra = 0;
    for (size_t k = 0; k < s->n_eb; k++) extra += eb_width(&s->eb[k]);
    size_t rl = base_size[s->format] + extra;
    memcpy(buf, "LASF", 4);
    buf[24] = 1;
    buf[25] = (unsigned char)s->minor;
    put_le16(buf + 94, (unsigned)hs);
    size_t pos = hs;
    unsigned n_vlrs = 0;
    if (s->n_eb) {
        put_vlr(buf + pos, "LASF_Spec", 4, 192 * s->n_eb, 0);
        unsigned char *d = buf + pos + 54;
        for (size_t k = 0; k < s->n_eb; k++, d += 192) {
            d[2] = s->eb[k].type;
            d[3] = s->eb[k].options;
            memcpy(d + 4, s->eb[k].name, strlen(s->eb[k].name));
            put_lef64(d + 112, s->eb[k].scale);
            put_lef64(d + 136, s->eb[k].offset);
        }
        pos += 54 + 192 * s->n_eb;
        n_vlrs++;
    }
    if (s->wkt && !s->wkt_as_evlr) {
        put_vlr(buf + pos, "LASF_Projection", 2112, strlen(s->wkt) + 1, 0);
        memcpy(buf + pos + 54, s->wkt, strlen(s->wkt));
        pos += 54 + strlen(s->wkt) + 1;
        n_vlrs++;
    }
    for (unsigned k = 0; k < s->n_empty_vlrs; k++, pos += 54, n_vlrs++) put_vlr(buf + pos, "test", k, 0, 0);
    put_le32(buf + 96, (uint32_t)pos);
    put_le32(buf + 100, n_vlrs);
    buf[104] = (unsigned char)s->format;
    put_le16(buf + 105, (unsigned)rl);
    if (s->format <= 5) put_le32(buf + 107, (uint32_t)s->n);
    for (int k = 0; k < 3; k++) {
        put_lef64(buf + 131 + 8 * k, SCALE);
        put_lef64(buf + 155 + 8 * k, OFF[k]);
    }
    if (hs == 375) put_le64(buf + 247, s->n);
    const int legacy = s->format <= 5;
    for (size_t i = 0; i < s->n; i++) {
        unsigned char *p = buf + pos + i * rl;
        put_le32(p, (uint32_t)pt_x(i));
        put_le32(p + 4, (uint32_t)pt_y(i));
        put_le32(p + 8, (uint32_t)pt_z(i));
        put_le16(p + 12, 100 + (unsigned)i);
        unsigned rn = 1 + i % 3, nr = 3 + (legacy ? 0 : 8), cls = 2 + i % 4;
        /* Neighbouring flag bits set on purpose: the reader must mask them. */
        p[14] = (unsigned char)(legacy ? (rn | nr << 3 | 0xC0) : (rn | nr << 4));
        if (legacy) p[15] = (unsigned char)(cls | 0xE0);
        else {
            p[15] = 0xFF;
            p[16] = (unsigned char)(cls + 40);
        }
        if (gps_at[s->format] >= 0) put_lef64(p + gps_at[s->format], 1000.5 + (double)i);
        if (rgb_at[s->format] >= 0) {
            put_le16(p + rgb_at[s->format], (unsigned)(i * 256));
            put_le16(p + rgb_at[s->format] + 2, (unsigned)(i * 512 + 1));
            put_le16(p + rgb_at[s->format] + 4, 65535 - (unsigned)i);
        }
        if (nir_at[s->format] >= 0) put_le16(p + nir_at[s->format], 7 * (unsigned)i + 1);
        unsigned char *e = p + base_size[s->format];
        for (size_t k = 0; k < s->n_eb; k++) {
            eb_encode(e, s->eb[k].type, eb_raw(s->eb[k].type, i, k));
            e += eb_width(&s->eb[k]);
        }
    }
    pos += s->n * rl;
    if (s->wkt && s->wkt_as_evlr) {
        put_le64(buf + 235, pos);
        put_le32(buf + 243, 1);
        put_vlr(buf + pos, "LASF_Projection", 2112, strlen(s->wkt) + 1, 1);
        memcpy(buf + pos + 60, s->wkt, strlen(s->wkt));
        pos += 60 + strlen(s->wkt) + 1;
    }
    assert_true(pos <= cap);
    return pos;
}

static unsigned char buf[1 << 16];

static sy_code read_built(const las_spec *s, sy_cloud *c, sy_error *err)
{
    size_t size = build_las(s, buf, sizeof buf);
    return sy_read_las_mem("built.las", buf, size, c, err);
}

/* ---- real files ---- */

typedef struct {
    const char *rel;
    size_t count;
    const char *version;
    int format;
} real_file;

static const real_file real_files[] = {
    {"real/lidr/MixedConifer.las", 37657, "1.2", 1}, {"real/lidr/Megaplot.las", 81590, "1.2", 1},
    {"real/lidr/dbh.las", 1369, "1.4", 1},           {"real/treels/pine.las", 73851, "1.2", 0},
    {"real/treels/pine_plot.las", 114024, "1.2", 0}, {"real/pytlidar/tree_1.las", 90239, "1.4", 6},
};

static void real_files_have_exact_counts_and_header_bounds(void **state)
{
    (void)state;
    for (size_t f = 0; f < sizeof real_files / sizeof real_files[0]; f++) {
        const char *path = data_path(real_files[f].rel);
        sy_cloud c;
        sy_error err = {0};
        if (sy_read_cloud(path, &c, &err) != SY_OK) fail_msg("%s", err.msg);
        assert_int_equal(c.n, real_files[f].count);
        assert_int_equal(c.meta.header_count, real_files[f].count);
        assert_string_equal(c.meta.format, "LAS");
        assert_string_equal(c.meta.version, real_files[f].version);
        assert_int_equal(c.meta.point_format, real_files[f].format);
        /* Header bounds, where the writer filled them, match the points
         * within one scale step. */
        sy_buffer b;
        assert_int_equal(sy_read_file(path, &b, &err), SY_OK);
        double lo[3], hi[3], hdr[6];
        sy_cloud_bounds(&c, lo, hi);
        int zero = 1;
        for (int k = 0; k < 6; k++) {
            hdr[k] = getf64(b.data + 179 + 8 * k);
            zero &= hdr[k] == 0.0;
        }
        for (int k = 0; k < 3 && !zero; k++) {
            double step = getf64(b.data + 131 + 8 * k);
            assert_float_equal(hi[k], hdr[2 * k], step + 1e-9);
            assert_float_equal(lo[k], hdr[2 * k + 1], step + 1e-9);
        }
        /* Float positions stay small next to the origin. */
        for (int k = 0; k < 3; k++) assert_true(fabs(lo[k] - c.origin[k]) < 1000.0);
        sy_buffer_free(&b);
        sy_cloud_free(&c);
    }
}

static void mixed_conifer_has_integer_tree_ids(void **state)
{
    (void)state;
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_read_cloud(data_path("real/lidr/MixedConifer.las"), &c, &err), SY_OK);
    const double *id = sy_cloud_attr(&c, "treeID");
    assert_non_null(id);
    /* Count distinct ids with a presence table over the plausible range. */
    static unsigned char seen[100000];
    memset(seen, 0, sizeof seen);
    size_t distinct = 0, unassigned = 0;
    for (size_t i = 0; i < c.n; i++) {
        /* Points in no tree carry the no_data value, read as NaN. */
        if (isnan(id[i])) {
            unassigned++;
            continue;
        }
        assert_true(id[i] == floor(id[i]));
        assert_true(id[i] >= 0 && id[i] < 100000);
        if (!seen[(size_t)id[i]]++) distinct++;
    }
    assert_true(distinct > 10);
    assert_true(distinct < 1000);
    assert_true(unassigned < c.n / 2);
    assert_string_equal(c.meta.crs, "EPSG:26912");
    assert_non_null(strstr(c.meta.vlr_summary, "LASF_Spec/4: "));
    assert_non_null(strstr(c.meta.vlr_summary, "\nLASF_Projection/34735: "));
    assert_non_null(c.gps_time);
    assert_non_null(c.classification);
    sy_cloud_free(&c);
}

static void dbh_las14_extra_bytes(void **state)
{
    (void)state;
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_read_cloud(data_path("real/lidr/dbh.las"), &c, &err), SY_OK);
    const double *hag = sy_cloud_attr(&c, "hag"), *cluster = sy_cloud_attr(&c, "cluster");
    assert_non_null(hag);
    assert_non_null(cluster);
    assert_non_null(sy_cloud_attr(&c, "Range"));
    assert_non_null(sy_cloud_attr(&c, "Ring"));
    for (size_t i = 0; i < c.n; i++) {
        assert_true(cluster[i] == floor(cluster[i])); /* int32 field */
        assert_true(hag[i] > -1.0 && hag[i] < 50.0);   /* height above ground of a stem slice */
    }
    sy_cloud_free(&c);
}

static void tree_1_las14_zero_legacy_count_and_bounds(void **state)
{
    (void)state;
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_read_cloud(data_path("real/pytlidar/tree_1.las"), &c, &err), SY_OK);
    assert_int_equal(c.n, 90239);
    double lo[3], hi[3];
    sy_cloud_bounds(&c, lo, hi);
    /* Extremes computed independently (Python struct over the raw records). */
    assert_float_equal(lo[0], 1176135.939, 0.0015);
    assert_float_equal(hi[0], 1176148.652, 0.0015);
    assert_float_equal(lo[1], 2857157.829, 0.0015);
    assert_float_equal(hi[1], 2857176.041, 0.0015);
    assert_float_equal(lo[2], 0.647, 0.0015);
    assert_float_equal(hi[2], 13.531, 0.0015);
    sy_cloud_free(&c);
}

/* Each real .laz reads to the same cloud as the .las beside it (the raw
 * record comparison lives in test_ingest_laz). */
static void laz_files_read_like_their_las(void **state)
{
    (void)state;
    const char *names[] = {"real/lidr/MixedConifer", "real/lidr/Megaplot", "real/lidr/dbh", "real/treels/pine",
                           "real/treels/pine_plot"};
    for (size_t f = 0; f < sizeof names / sizeof names[0]; f++) {
        char las[256], laz[256];
        snprintf(las, sizeof las, "%s.las", names[f]);
        snprintf(laz, sizeof laz, "%s.laz", names[f]);
        sy_cloud a, b;
        sy_error err = {0};
        assert_int_equal(sy_read_cloud(data_path(las), &a, &err), SY_OK);
        assert_int_equal(sy_read_cloud(data_path(laz), &b, &err), SY_OK);
        assert_string_equal(b.meta.format, "LAZ");
        assert_int_equal(a.n, b.n);
        assert_memory_equal(a.xyz, b.xyz, 3 * a.n * sizeof(float));
        assert_true((a.intensity == NULL) == (b.intensity == NULL));
        if (a.intensity) assert_memory_equal(a.intensity, b.intensity, a.n * sizeof(uint16_t));
        assert_true((a.gps_time == NULL) == (b.gps_time == NULL));
        if (a.gps_time) assert_memory_equal(a.gps_time, b.gps_time, a.n * sizeof(double));
        assert_int_equal(a.n_attrs, b.n_attrs);
        for (size_t k = 0; k < a.n_attrs; k++) {
            assert_string_equal(a.attrs[k].name, b.attrs[k].name);
            assert_memory_equal(a.attrs[k].values, b.attrs[k].values, a.n * sizeof(double));
        }
        sy_cloud_free(&a);
        sy_cloud_free(&b);
    }
    /* The LASzip VLR alone (format bits clear) still marks the points as compressed. */
    sy_buffer buf;
    sy_error err = {0};
    assert_int_equal(sy_read_file(data_path("real/lidr/dbh.laz"), &buf, &err), SY_OK);
    buf.data[104] &= 0x3F;
    sy_cloud c;
    assert_int_equal(sy_read_las_mem("x.laz", buf.data, buf.size, &c, &err), SY_OK);
    assert_int_equal(c.n, 1369);
    sy_cloud_free(&c);
    sy_buffer_free(&buf);
}

/* ---- every point format and extra-bytes type, built by hand ---- */

static void every_point_format_decodes(void **state)
{
    (void)state;
    for (int f = 0; f <= 10; f++) {
        for (int minor = 0; minor <= 4; minor += 2) {
            las_spec s = {.format = f, .minor = minor, .n = 9};
            if (f >= 6) s.minor = 4; /* formats 6-10 arrived with 1.4 */
            sy_cloud c;
            sy_error err = {0};
            if (read_built(&s, &c, &err) != SY_OK) fail_msg("format %d: %s", f, err.msg);
            assert_int_equal(c.n, 9);
            assert_int_equal(c.meta.point_format, f);
            for (size_t i = 0; i < c.n; i++) {
                double x = c.origin[0] + c.xyz[3 * i], z = c.origin[2] + c.xyz[3 * i + 2];
                assert_float_equal(x, pt_x(i) * SCALE + OFF[0], 1e-3);
                assert_float_equal(z, pt_z(i) * SCALE + OFF[2], 1e-3);
                assert_int_equal(c.intensity[i], 100 + i);
                assert_int_equal(c.return_number[i], 1 + i % 3);
                assert_int_equal(c.num_returns[i], f <= 5 ? 3 : 11);
                assert_int_equal(c.classification[i], 2 + i % 4 + (f <= 5 ? 0 : 40));
            }
            assert_int_equal(c.gps_time != NULL, gps_at[f] >= 0);
            if (c.gps_time) assert_float_equal(c.gps_time[8], 1008.5, 0);
            assert_int_equal(c.rgb != NULL, rgb_at[f] >= 0);
            if (c.rgb) {
                assert_int_equal(c.rgb[3 * 8], 8 * 256);
                assert_int_equal(c.rgb[3 * 8 + 1], 8 * 512 + 1);
                assert_int_equal(c.rgb[3 * 8 + 2], 65535 - 8);
            }
            assert_int_equal(c.nir != NULL, nir_at[f] >= 0);
            if (c.nir) assert_int_equal(c.nir[8], 57);
            char v[8];
            snprintf(v, sizeof v, "1.%d", s.minor);
            assert_string_equal(c.meta.version, v);
            sy_cloud_free(&c);
        }
    }
}

static void every_extra_bytes_type_decodes(void **state)
{
    (void)state;
    const eb_desc eb[] = {
        {0, 3, "raw3", 0, 0},          /* undocumented: 3 raw bytes, skipped */
        {1, 0, "u8", 0, 0},           {2, 0, "i8", 0, 0},
        {13, 0, "pair_u16", 0, 0},     /* deprecated 2-element array, skipped */
        {3, 0, "u16", 0, 0},          {4, 0, "i16", 0, 0},
        {5, 0, "u32", 0, 0},          {6, 0, "treeID", 0, 0},
        {7, 0, "u64", 0, 0},          {8, 0, "i64", 0, 0},
        {9, 0, "f32", 0, 0},          {10, 0, "f64", 0, 0},
        {6, 0x18, "scaled", 0.5, 100}, /* scale and offset bits */
        {3, 0x08, "scale_only", 0.1, 7}, /* offset bit clear: 7 ignored */
    };
    const size_t n_eb = sizeof eb / sizeof eb[0];
    for (int f = 0; f <= 10; f += 5) {
        las_spec s = {.format = f, .minor = 4, .n = 20, .eb = eb, .n_eb = n_eb};
        sy_cloud c;
        sy_error err = {0};
        if (read_built(&s, &c, &err) != SY_OK) fail_msg("%s", err.msg);
        assert_int_equal(c.n_attrs, n_eb - 2);
        assert_null(sy_cloud_attr(&c, "raw3"));
        assert_null(sy_cloud_attr(&c, "pair_u16"));
        for (size_t k = 0; k < n_eb; k++) {
            if (eb[k].type == 0 || eb[k].type > 10) continue;
            const double *v = sy_cloud_attr(&c, eb[k].name);
            assert_non_null(v);
            for (size_t i = 0; i < c.n; i++) {
                double want = eb_raw(eb[k].type, i, k);
                if (eb[k].options & 0x08) want *= eb[k].scale;
                if (eb[k].options & 0x10) want += eb[k].offset;
                assert_float_equal(v[i], want, 1e-12);
            }
        }
        /* Positions still right with the extra bytes after them. */
        assert_float_equal(c.origin[1] + c.xyz[3 * 19 + 1], pt_y(19) * SCALE + OFF[1], 1e-3);
        sy_cloud_free(&c);
    }
}

static void unknown_extra_type_is_refused(void **state)
{
    (void)state;
    /* Type 200 has no known size, so nothing after it can be located: the
     * file is refused rather than read without "after" (a dropped treeID). */
    const eb_desc eb[] = {{6, 0, "first", 0, 0}, {200, 0, "mystery", 0, 0}, {6, 0, "after", 0, 0}};
    las_spec s = {.format = 6, .minor = 4, .n = 5, .eb = eb, .n_eb = 3};
    sy_cloud c;
    sy_error err = {0};
    size_t size = build_las(&s, buf, sizeof buf);
    assert_int_equal(sy_read_las_mem("u.las", buf, size, &c, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "u.las"));
    assert_non_null(strstr(err.msg, "descriptor 1"));
}

static void wkt_crs_from_vlr_and_evlr(void **state)
{
    (void)state;
    const char *wkt = "PROJCS[\"NAD83 / UTM zone 12N\",\n  GEOGCS[\"NAD83\"],UNIT[\"metre\",1]]";
    for (int evlr = 0; evlr <= 1; evlr++) {
        las_spec s = {.format = 6, .minor = 4, .n = 4, .wkt = wkt, .wkt_as_evlr = evlr};
        sy_cloud c;
        sy_error err = {0};
        if (read_built(&s, &c, &err) != SY_OK) fail_msg("%s", err.msg);
        assert_int_equal(c.n, 4);
        assert_string_equal(c.meta.crs, "PROJCS[\"NAD83 / UTM zone 12N\", GEOGCS[\"NAD83\"],UNIT[\"metre\",1]]");
        assert_non_null(strstr(c.meta.vlr_summary, "LASF_Projection/2112: "));
        sy_cloud_free(&c);
    }
}

/* A WKT of about 2000 characters, far past the 512 of the CRS summary. */
static const char *long_wkt(void)
{
    static char wkt[2000];
    snprintf(wkt, sizeof wkt, "PROJCS[\"Long\",");
    while (strlen(wkt) < sizeof wkt - 20) strcat(wkt, "PARAMETER[\"x\",1],");
    strcat(wkt, "]");
    return wkt;
}

static void long_wkt_is_cut_and_many_vlrs_are_counted(void **state)
{
    (void)state;
    const char *wkt = long_wkt();
    las_spec s = {.format = 1, .minor = 2, .n = 3, .wkt = wkt, .n_empty_vlrs = 100};
    sy_cloud c;
    sy_error err = {0};
    if (read_built(&s, &c, &err) != SY_OK) fail_msg("%s", err.msg);
    assert_int_equal(strlen(c.meta.crs), 512 + 3);
    assert_memory_equal(c.meta.crs, wkt, 512);
    assert_string_equal(c.meta.crs + 512, "...");
    /* 101 VLRs: 64 lines, then a count of the rest. */
    size_t lines = 1;
    for (const char *p = c.meta.vlr_summary; *p; p++) lines += *p == '\n';
    assert_int_equal(lines, 65);
    assert_non_null(strstr(c.meta.vlr_summary, "\n... and 37 more VLRs"));
    assert_non_null(strstr(c.meta.vlr_summary, "test/62: "));
    sy_cloud_free(&c);
}

/* ---- malformed input ---- */

typedef enum {
    TRUNCATE_HEADER, TRUNCATE_POINTS, BAD_SIGNATURE, INFLATE_COUNT, HUGE_COUNT, ZERO_SCALE, NAN_SCALE,
    VLR_PAST_EOF, SHORT_RECORD, OFFSET_PAST_EOF, INF_COORD, EVLR_PAST_EOF, HEADER_SIZE_SMALL, N_DAMAGE
} damage;

static size_t damage_file(unsigned char *b, size_t size, damage d)
{
    switch (d) {
    case TRUNCATE_HEADER: return 200;
    case TRUNCATE_POINTS: return size - 7;
    case BAD_SIGNATURE: b[3] = 'X'; break;
    case INFLATE_COUNT: put_le64(b + 247, 11); break;
    case HUGE_COUNT: put_le64(b + 247, UINT64_C(1) << 62); break;
    case ZERO_SCALE: put_lef64(b + 139, 0.0); break;
    case NAN_SCALE: put_lef64(b + 147, NAN); break;
    case VLR_PAST_EOF: put_le16(b + 375 + 20, 65535); break;
    case SHORT_RECORD: put_le16(b + 105, 29); break;
    case OFFSET_PAST_EOF: put_le32(b + 96, (uint32_t)size + 10); break;
    case INF_COORD: put_lef64(b + 131, 1e307); break;
    case EVLR_PAST_EOF: put_le64(b + 235, size + 100); put_le32(b + 243, 1); break;
    case HEADER_SIZE_SMALL: put_le16(b + 94, 100); break;
    case N_DAMAGE: break;
    }
    return size;
}

static void malformed_files_fail_with_the_path(void **state)
{
    (void)state;
    const eb_desc eb[] = {{6, 0, "treeID", 0, 0}};
    las_spec s = {.format = 6, .minor = 4, .n = 10, .eb = eb, .n_eb = 1};
    size_t size = build_las(&s, buf, sizeof buf);
    static unsigned char copy[sizeof buf];
    for (int d = 0; d < N_DAMAGE; d++) {
        memcpy(copy, buf, size);
        size_t len = damage_file(copy, size, (damage)d);
        char name[64];
        snprintf(name, sizeof name, "damaged_%d.las", d);
        const char *path = tmp_path(name);
        assert_int_equal(write_bytes(path, copy, len), 0);
        sy_cloud c;
        sy_error err = {0};
        sy_code rc = sy_read_cloud(path, &c, &err);
        if (rc != SY_EINPUT) fail_msg("damage %d: rc %d, %s", d, rc, err.msg);
        assert_non_null(strstr(err.msg, path));
        assert_null(strchr(err.msg, '\n'));
        if (d == INFLATE_COUNT) assert_non_null(strstr(err.msg, "header promises 11 points, file holds 10"));
        if (d == HUGE_COUNT) assert_non_null(strstr(err.msg, "file holds 10"));
        if (d == INF_COORD) assert_non_null(strstr(err.msg, "non-finite"));
    }
    /* The undamaged original reads, so each failure above is the damage. */
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_read_las_mem("ok.las", buf, size, &c, &err), SY_OK);
    assert_int_equal(c.n, 10);
    sy_cloud_free(&c);
    /* Every proper prefix fails cleanly: the points fill the file exactly. */
    for (size_t len = 0; len < size; len++) {
        sy_error e = {0};
        assert_int_equal(sy_read_las_mem("cut.las", buf, len, &c, &e), SY_EINPUT);
        assert_non_null(strstr(e.msg, "cut.las"));
    }
}

/* ---- sylva info's streaming pass ---- */

/* sy_cloud_info (headers + one pass, no cloud) against the whole reader:
 * the same count, bounds, attribute names and header summary, or the same
 * error, for every point format, the real files and each damaged file. */
static void assert_info_like_reader(const char *path)
{
    sy_cloud c, meta;
    sy_error e1 = {0}, e2 = {0};
    size_t n = 0;
    double lo[3], hi[3], flo[3], fhi[3];
    sy_code r1 = sy_read_cloud(path, &c, &e1), r2 = sy_cloud_info(path, &meta, &n, lo, hi, &e2);
    assert_int_equal(r1, r2);
    if (r1) {
        assert_string_equal(e1.msg, e2.msg);
        return;
    }
    assert_int_equal(n, c.n);
    sy_cloud_bounds(&c, flo, fhi);
    for (int k = 0; k < 3; k++) {
        assert_true(lo[k] == flo[k]);
        assert_true(hi[k] == fhi[k]);
    }
    char a1[1024], a2[1024];
    sy_cloud_attribute_names(&c, a1, sizeof a1);
    sy_cloud_attribute_names(&meta, a2, sizeof a2);
    assert_string_equal(a1, a2);
    assert_string_equal(c.meta.format, meta.meta.format);
    assert_string_equal(c.meta.version, meta.meta.version);
    assert_int_equal(c.meta.point_format, meta.meta.point_format);
    assert_int_equal(c.meta.header_count, meta.meta.header_count);
    assert_true((c.meta.crs == NULL) == (meta.meta.crs == NULL));
    if (c.meta.crs) assert_string_equal(c.meta.crs, meta.meta.crs);
    assert_true((c.meta.vlr_summary == NULL) == (meta.meta.vlr_summary == NULL));
    if (c.meta.vlr_summary) assert_string_equal(c.meta.vlr_summary, meta.meta.vlr_summary);
    sy_cloud_free(&c);
    sy_cloud_free(&meta);
}

static void info_streams_like_the_reader(void **state)
{
    (void)state;
    const eb_desc eb[] = {{6, 0, "treeID", 0, 0}, {9, 0, "NormalX", 0, 0}, {9, 0, "NormalY", 0, 0},
                          {9, 0, "NormalZ", 0, 0}};
    for (int f = 0; f <= 10; f++) {
        las_spec s = {.format = f, .minor = 4, .n = 9, .eb = eb, .n_eb = f % 2 ? 4 : 1, .wkt = f == 6 ? "GEOGCS[x]" : NULL};
        size_t size = build_las(&s, buf, sizeof buf);
        char name[64];
        snprintf(name, sizeof name, "info_%d.las", f);
        const char *path = tmp_path(name);
        assert_int_equal(write_bytes(path, buf, size), 0);
        assert_info_like_reader(path);
        /* ... and it is the streaming pass that answered, not the fallback. */
        sy_cloud m;
        size_t n = 0;
        double lo[3], hi[3];
        int done = 0;
        sy_error e = {0};
        assert_int_equal(sy_las_info_mem(path, buf, size, -1, &m, &n, lo, hi, &done, &e), SY_OK);
        assert_int_equal(done, 1);
        assert_int_equal(n, 9);
        sy_cloud_free(&m);
    }
    for (size_t f = 0; f < sizeof real_files / sizeof real_files[0]; f++) assert_info_like_reader(data_path(real_files[f].rel));
    const eb_desc one[] = {{6, 0, "treeID", 0, 0}};
    las_spec s = {.format = 6, .minor = 4, .n = 10, .eb = one, .n_eb = 1};
    size_t size = build_las(&s, buf, sizeof buf);
    static unsigned char copy[sizeof buf];
    for (int d = 0; d < N_DAMAGE; d++) {
        memcpy(copy, buf, size);
        size_t len = damage_file(copy, size, (damage)d);
        char name[64];
        snprintf(name, sizeof name, "info_damaged_%d.las", d);
        const char *path = tmp_path(name);
        assert_int_equal(write_bytes(path, copy, len), 0);
        assert_info_like_reader(path);
    }
}

/* ---- writer round trips ---- */

static void fill_cloud(sy_cloud *c, size_t n, int with_rgb, int with_nir)
{
    sy_error err = {0};
    assert_int_equal(sy_cloud_init(c, n, &err), SY_OK);
    c->origin[0] = 684766.0;
    c->origin[1] = 5017773.0;
    c->origin[2] = 120.0;
    assert_int_equal(sy_cloud_add_intensity(c, &err), SY_OK);
    assert_int_equal(sy_cloud_add_returns(c, &err), SY_OK);
    assert_int_equal(sy_cloud_add_classification(c, &err), SY_OK);
    assert_int_equal(sy_cloud_add_gps_time(c, &err), SY_OK);
    if (with_rgb) assert_int_equal(sy_cloud_add_rgb(c, &err), SY_OK);
    if (with_nir) c->nir = calloc(n, sizeof(uint16_t));
    double *tree = sy_cloud_add_attr(c, "treeID", &err);
    double *height = sy_cloud_add_attr(c, "height_above_ground", &err);
    double *big = sy_cloud_add_attr(c, "big_count", &err);
    assert_non_null(tree);
    assert_non_null(height);
    assert_non_null(big);
    for (size_t i = 0; i < n; i++) {
        c->xyz[3 * i] = (float)(i % 97) * 0.731f;
        c->xyz[3 * i + 1] = (float)(i % 89) * 1.113f;
        c->xyz[3 * i + 2] = 0.0173f * (float)i;
        c->intensity[i] = (uint16_t)(i * 37);
        c->return_number[i] = (uint8_t)(1 + i % 5);
        c->num_returns[i] = 5;
        c->classification[i] = (uint8_t)(i % 7 == 0 ? 2 : 5);
        c->gps_time[i] = 3.0e8 + 0.001 * (double)i;
        if (with_rgb)
            for (int k = 0; k < 3; k++) c->rgb[3 * i + k] = (uint16_t)(i * (k + 3) * 11);
        if (with_nir) c->nir[i] = (uint16_t)(i + 5);
        tree[i] = i % 13 == 0 ? NAN : (double)(i / 10) - 3.0; /* NaN: in no tree */
        height[i] = 0.1 * (double)i + 1.0 / 3.0;
        big[i] = 3.0e9 + (double)i; /* integral but past int32: needs double */
    }
}

static void assert_round_trip(const sy_cloud *a, const sy_cloud *b, int format)
{
    assert_int_equal(b->n, a->n);
    assert_int_equal(b->meta.point_format, format);
    assert_string_equal(b->meta.version, "1.4");
    for (size_t i = 0; i < a->n; i++) {
        for (int k = 0; k < 3; k++) {
            double wa = a->origin[k] + a->xyz[3 * i + k], wb = b->origin[k] + b->xyz[3 * i + k];
            assert_float_equal(wa, wb, 0.00005 + 1e-5);
        }
        assert_int_equal(b->intensity[i], a->intensity[i]);
        assert_int_equal(b->return_number[i], a->return_number[i]);
        assert_int_equal(b->num_returns[i], a->num_returns[i]);
        assert_int_equal(b->classification[i], a->classification[i]);
        assert_true(b->gps_time[i] == a->gps_time[i]);
        if (a->rgb)
            for (int k = 0; k < 3; k++) assert_int_equal(b->rgb[3 * i + k], a->rgb[3 * i + k]);
        if (a->nir) assert_int_equal(b->nir[i], a->nir[i]);
    }
    assert_int_equal(b->n_attrs, a->n_attrs);
    for (size_t t = 0; t < a->n_attrs; t++) {
        const double *v = sy_cloud_attr(b, a->attrs[t].name);
        assert_non_null(v);
        for (size_t i = 0; i < a->n; i++) {
            double want = a->attrs[t].values[i];
            assert_true(v[i] == want || (isnan(v[i]) && isnan(want)));
        }
    }
    assert_int_equal(b->rgb != NULL, a->rgb != NULL);
    assert_int_equal(b->nir != NULL, a->nir != NULL);
}

static void round_trip(int with_rgb, int with_nir, int format)
{
    sy_cloud a, b;
    sy_error err = {0};
    fill_cloud(&a, 5000, with_rgb, with_nir);
    char name[32];
    snprintf(name, sizeof name, "rt%d.las", format);
    const char *path = tmp_path(name);
    assert_int_equal(sy_write_las(path, &a, &err), SY_OK);
    if (sy_read_cloud(path, &b, &err) != SY_OK) fail_msg("%s", err.msg);
    assert_round_trip(&a, &b, format);
    /* Header: legacy count 0 (formats 6-10), 64-bit count, bounds = points. */
    sy_buffer f;
    assert_int_equal(sy_read_file(path, &f, &err), SY_OK);
    assert_int_equal(f.data[107] | f.data[108] | f.data[109] | f.data[110], 0);
    uint64_t count64 = 0;
    for (int i = 0; i < 8; i++) count64 |= (uint64_t)f.data[247 + i] << (8 * i);
    assert_int_equal(count64, a.n);
    /* Formats 6-10 must declare WKT (global encoding bit 4), CRS or not; the
     * cloud's GPS time is week time, so bit 0 stays clear. */
    assert_int_equal(f.data[6] | f.data[7] << 8, 16);
    double lo[3], hi[3];
    sy_cloud_bounds(&b, lo, hi);
    for (int k = 0; k < 3; k++) {
        assert_float_equal(getf64(f.data + 179 + 16 * k), hi[k], 1e-6);
        assert_float_equal(getf64(f.data + 187 + 16 * k), lo[k], 1e-6);
    }
    /* by-return counts: returns 1..5 in turn. */
    for (int r = 0; r < 5; r++) {
        uint64_t by = 0;
        for (int i = 0; i < 8; i++) by |= (uint64_t)f.data[255 + 8 * r + i] << (8 * i);
        assert_int_equal(by, 1000);
    }
    /* treeID is integral and small: stored as int32 (type 6) with its NaNs as
     * no_data (option bit 0); height and big_count as double (type 10).
     * Descriptors follow the 54-byte VLR header. */
    const unsigned char *desc = f.data + 375 + 54;
    assert_string_equal((const char *)desc + 4, "treeID");
    assert_int_equal(desc[2], 6);
    assert_int_equal(desc[3] & 1, 1);
    assert_int_equal(desc[192 + 2], 10);
    assert_int_equal(desc[384 + 2], 10);
    sy_buffer_free(&f);
    sy_cloud_free(&a);
    sy_cloud_free(&b);
}

static void round_trip_format_6(void **state)
{
    (void)state;
    round_trip(0, 0, 6);
}
static void round_trip_format_7_rgb(void **state)
{
    (void)state;
    round_trip(1, 0, 7);
}
static void round_trip_format_8_nir(void **state)
{
    (void)state;
    round_trip(1, 1, 8);
}

static void round_trip_real_file_and_crs(void **state)
{
    (void)state;
    sy_cloud a, b;
    sy_error err = {0};
    assert_int_equal(sy_read_cloud(data_path("real/lidr/MixedConifer.las"), &a, &err), SY_OK);
    const char *path = tmp_path("mixed.las");
    assert_int_equal(sy_write_las(path, &a, &err), SY_OK);
    assert_int_equal(sy_read_cloud(path, &b, &err), SY_OK);
    assert_int_equal(b.n, 37657);
    assert_string_equal(b.meta.crs, "EPSG:26912");
    const double *ta = sy_cloud_attr(&a, "treeID"), *tb = sy_cloud_attr(&b, "treeID");
    assert_non_null(tb);
    for (size_t i = 0; i < a.n; i++) {
        assert_true(ta[i] == tb[i] || (isnan(ta[i]) && isnan(tb[i])));
        for (int k = 0; k < 3; k++)
            assert_float_equal(a.origin[k] + a.xyz[3 * i + k], b.origin[k] + b.xyz[3 * i + k], 0.00005 + 1e-5);
    }
    sy_cloud_free(&b);
    /* A WKT CRS goes out as a WKT VLR. */
    free(a.meta.crs);
    a.meta.crs = strdup("PROJCS[\"WGS 84 / UTM zone 12N\",GEOGCS[\"WGS 84\"]]");
    assert_int_equal(sy_write_las(path, &a, &err), SY_OK);
    assert_int_equal(sy_read_cloud(path, &b, &err), SY_OK);
    assert_string_equal(b.meta.crs, a.meta.crs);
    sy_cloud_free(&b);
    sy_cloud_free(&a);
}

/* The payload of the first VLR with this record id in a LAS file, or NULL. */
static const unsigned char *find_vlr(const sy_buffer *f, unsigned record_id, size_t *len)
{
    size_t pos = f->data[94] | (size_t)f->data[95] << 8;
    uint32_t n = (uint32_t)(f->data[100] | f->data[101] << 8 | f->data[102] << 16 | (uint32_t)f->data[103] << 24);
    for (uint32_t i = 0; i < n && pos + 54 <= f->size; i++) {
        size_t l = f->data[pos + 20] | (size_t)f->data[pos + 21] << 8;
        if ((unsigned)(f->data[pos + 18] | f->data[pos + 19] << 8) == record_id) {
            *len = l;
            return f->data + pos + 54;
        }
        pos += 54 + l;
    }
    return NULL;
}

static unsigned global_encoding(const sy_buffer *f) { return f->data[6] | (unsigned)f->data[7] << 8; }

/* Writes c to name, reads the bytes and the cloud back. */
static void write_and_reread(const sy_cloud *c, const char *name, sy_buffer *f, sy_cloud *back)
{
    sy_error err = {0};
    const char *path = tmp_path(name);
    if (sy_write_las(path, c, &err) != SY_OK) fail_msg("%s", err.msg);
    assert_int_equal(sy_read_file(path, f, &err), SY_OK);
    if (sy_read_cloud(path, back, &err) != SY_OK) fail_msg("%s", err.msg);
}

/* GeoTIFF keys are legal only with point formats 0-5: MixedConifer (format 1,
 * EPSG:26912 as keys) comes out as format 1 with its keys byte for byte, the
 * WKT bit clear and the legacy count filled; every field survives. */
static void geotiff_crs_keeps_a_legacy_format(void **state)
{
    (void)state;
    sy_cloud a, b;
    sy_buffer in, out;
    sy_error err = {0};
    const char *src = data_path("real/lidr/MixedConifer.las");
    assert_int_equal(sy_read_cloud(src, &a, &err), SY_OK);
    assert_int_equal(sy_read_file(src, &in, &err), SY_OK);
    write_and_reread(&a, "geotiff.las", &out, &b);
    assert_int_equal(b.meta.point_format, 1);
    assert_int_equal(global_encoding(&out) & 16, 0);
    size_t in_len = 0, out_len = 0;
    const unsigned char *in_keys = find_vlr(&in, 34735, &in_len), *out_keys = find_vlr(&out, 34735, &out_len);
    assert_non_null(in_keys);
    assert_non_null(out_keys);
    assert_int_equal(out_len, in_len);
    assert_memory_equal(out_keys, in_keys, in_len);
    assert_int_equal(out.data[107] | out.data[108] << 8 | out.data[109] << 16, 37657);
    assert_null(find_vlr(&out, 2112, &out_len));
    assert_string_equal(b.meta.crs, "EPSG:26912");
    for (size_t i = 0; i < a.n; i++) {
        assert_int_equal(b.classification[i], a.classification[i]);
        assert_int_equal(b.return_number[i], a.return_number[i]);
        assert_int_equal(b.num_returns[i], a.num_returns[i]);
        assert_int_equal(b.intensity[i], a.intensity[i]);
        assert_true(b.gps_time[i] == a.gps_time[i]);
    }
    sy_cloud_free(&b);
    sy_buffer_free(&out);
    /* Near infrared or a class above 31 fits no legacy format: formats 6-10
     * with the WKT bit they require, the keys still kept verbatim. */
    a.nir = calloc(a.n, sizeof(uint16_t));
    assert_non_null(a.nir);
    a.nir[0] = 7;
    write_and_reread(&a, "geotiff_nir.las", &out, &b);
    assert_int_equal(b.meta.point_format, 8);
    assert_int_equal(global_encoding(&out) & 16, 16);
    out_keys = find_vlr(&out, 34735, &out_len);
    assert_non_null(out_keys);
    assert_memory_equal(out_keys, in_keys, in_len);
    assert_string_equal(b.meta.crs, "EPSG:26912");
    sy_cloud_free(&b);
    sy_buffer_free(&out);
    free(a.nir);
    a.nir = NULL;
    a.classification[5] = 40;
    write_and_reread(&a, "geotiff_class.las", &out, &b);
    assert_int_equal(b.meta.point_format, 6);
    assert_int_equal(b.classification[5], 40);
    assert_int_equal(global_encoding(&out) & 16, 16);
    sy_cloud_free(&b);
    sy_buffer_free(&out);
    sy_buffer_free(&in);
    sy_cloud_free(&a);
}

/* A WKT CRS goes out whole (the 512-character summary is only for `info`)
 * with point format 6 and the WKT bit. */
static void wkt_crs_is_written_whole(void **state)
{
    (void)state;
    const char *wkt = long_wkt();
    las_spec s = {.format = 1, .minor = 2, .n = 3, .wkt = wkt};
    sy_cloud a, b;
    sy_buffer out;
    sy_error err = {0};
    if (read_built(&s, &a, &err) != SY_OK) fail_msg("%s", err.msg);
    assert_string_equal(a.meta.crs_wkt, wkt);
    write_and_reread(&a, "wkt.las", &out, &b);
    assert_int_equal(b.meta.point_format, 6);
    assert_int_equal(global_encoding(&out) & 16, 16);
    size_t len = 0;
    const unsigned char *w = find_vlr(&out, 2112, &len);
    assert_non_null(w);
    assert_int_equal(len, strlen(wkt) + 1);
    assert_memory_equal(w, wkt, len);
    assert_null(find_vlr(&out, 34735, &len));
    assert_string_equal(b.meta.crs_wkt, wkt);
    sy_cloud_free(&b);
    sy_buffer_free(&out);
    sy_cloud_free(&a);
}

/* dbh.las has global encoding 17: adjusted standard GPS time (bit 0) and WKT.
 * Dropping bit 0 would shift every gps_time by the GPS week it was taken in. */
static void gps_time_type_survives(void **state)
{
    (void)state;
    sy_cloud a, b;
    sy_buffer out;
    sy_error err = {0};
    assert_int_equal(sy_read_cloud(data_path("real/lidr/dbh.las"), &a, &err), SY_OK);
    assert_int_equal(a.meta.las_global_encoding, 17);
    assert_int_equal(a.meta.gps_time_standard, 1);
    write_and_reread(&a, "gps.las", &out, &b);
    assert_int_equal(global_encoding(&out), 17);
    assert_int_equal(b.meta.gps_time_standard, 1);
    for (size_t i = 0; i < a.n; i++) assert_true(b.gps_time[i] == a.gps_time[i]);
    sy_cloud_free(&b);
    sy_buffer_free(&out);
    sy_cloud_free(&a);
}

/* Normals go out as float extra bytes NormalX/Y/Z after the attributes and
 * come back as the cloud's normals, bit for bit, not as attributes. */
static void normals_round_trip_as_extra_bytes(void **state)
{
    (void)state;
    sy_cloud a, b;
    sy_buffer out;
    sy_error err = {0};
    fill_cloud(&a, 3000, 0, 0);
    assert_int_equal(sy_cloud_add_normals(&a, &err), SY_OK);
    for (size_t i = 0; i < a.n; i++) {
        double t = 0.01 * (double)i, p = 0.37 * (double)i;
        a.normal[3 * i] = (float)(sin(t) * cos(p));
        a.normal[3 * i + 1] = (float)(sin(t) * sin(p));
        a.normal[3 * i + 2] = (float)cos(t);
    }
    write_and_reread(&a, "normals.las", &out, &b);
    assert_int_equal(b.meta.point_format, 6);
    assert_non_null(b.normal);
    for (size_t i = 0; i < 3 * a.n; i++) assert_true(b.normal[i] == a.normal[i]);
    assert_int_equal(b.n_attrs, a.n_attrs);
    assert_null(sy_cloud_attr(&b, "NormalX"));
    assert_non_null(sy_cloud_attr(&b, "treeID"));
    size_t len = 0;
    const unsigned char *desc = find_vlr(&out, 4, &len);
    assert_non_null(desc);
    assert_int_equal(len, (a.n_attrs + 3) * 192);
    const char *names[3] = {"NormalX", "NormalY", "NormalZ"};
    for (int k = 0; k < 3; k++) {
        const unsigned char *d = desc + (a.n_attrs + (size_t)k) * 192;
        assert_string_equal((const char *)d + 4, names[k]);
        assert_int_equal(d[2], 9); /* float */
        assert_true(getf64(d + 64) >= -1.0 && getf64(d + 88) <= 1.0);
    }
    /* 30 bytes of format 6, 4 + 8 + 8 for the attributes, 12 for the normals. */
    assert_int_equal(out.data[105] | out.data[106] << 8, 30 + 20 + 12);
    sy_cloud_free(&b);
    sy_buffer_free(&out);
    sy_cloud_free(&a);
    /* Another writer's double NormalX/Y/Z (names in any case, any order among
     * the fields) are normals too. */
    const eb_desc eb[] = {{10, 0, "normalz", 0, 0}, {6, 0, "treeID", 0, 0}, {10, 0, "NormalX", 0, 0},
                          {10, 0, "NORMALY", 0, 0}};
    las_spec sp = {.format = 6, .minor = 4, .n = 10, .eb = eb, .n_eb = 4};
    if (read_built(&sp, &b, &err) != SY_OK) fail_msg("%s", err.msg);
    assert_non_null(b.normal);
    assert_int_equal(b.n_attrs, 1);
    assert_non_null(sy_cloud_attr(&b, "treeID"));
    for (size_t i = 0; i < b.n; i++) {
        assert_float_equal(b.normal[3 * i], eb_raw(10, i, 2), 1e-6);
        assert_float_equal(b.normal[3 * i + 1], eb_raw(10, i, 3), 1e-6);
        assert_float_equal(b.normal[3 * i + 2], eb_raw(10, i, 0), 1e-6);
    }
    sy_cloud_free(&b);
}

static void wide_cloud_gets_a_coarser_scale(void **state)
{
    (void)state;
    sy_cloud a, b;
    sy_error err = {0};
    assert_int_equal(sy_cloud_init(&a, 3, &err), SY_OK);
    a.xyz[0] = 500000.0f; /* 500 km from the origin: past int32 at 0.1 mm */
    a.xyz[4] = -250000.5f;
    a.xyz[8] = 12.25f;
    const char *path = tmp_path("wide.las");
    assert_int_equal(sy_write_las(path, &a, &err), SY_OK);
    assert_int_equal(sy_read_cloud(path, &b, &err), SY_OK);
    for (size_t i = 0; i < 9; i++)
        assert_float_equal(a.origin[i % 3] + a.xyz[i], b.origin[i % 3] + b.xyz[i], 0.0005 + 0.02);
    sy_cloud_free(&a);
    sy_cloud_free(&b);
}

static void failed_write_leaves_no_file(void **state)
{
    (void)state;
    sy_cloud a;
    sy_error err = {0};
    assert_int_equal(sy_cloud_init(&a, 2, &err), SY_OK);
    a.xyz[4] = NAN;
    const char *path = tmp_path("nan.las");
    assert_int_equal(sy_write_las(path, &a, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, path));
    assert_false(file_exists(path));
    assert_int_equal(sy_write_las("/nonexistent-dir/x.las", &a, &err) != SY_OK, 1);
    sy_cloud_free(&a);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(real_files_have_exact_counts_and_header_bounds),
        cmocka_unit_test(mixed_conifer_has_integer_tree_ids),
        cmocka_unit_test(dbh_las14_extra_bytes),
        cmocka_unit_test(tree_1_las14_zero_legacy_count_and_bounds),
        cmocka_unit_test(laz_files_read_like_their_las),
        cmocka_unit_test(every_point_format_decodes),
        cmocka_unit_test(info_streams_like_the_reader),
        cmocka_unit_test(every_extra_bytes_type_decodes),
        cmocka_unit_test(unknown_extra_type_is_refused),
        cmocka_unit_test(wkt_crs_from_vlr_and_evlr),
        cmocka_unit_test(long_wkt_is_cut_and_many_vlrs_are_counted),
        cmocka_unit_test(malformed_files_fail_with_the_path),
        cmocka_unit_test(round_trip_format_6),
        cmocka_unit_test(round_trip_format_7_rgb),
        cmocka_unit_test(round_trip_format_8_nir),
        cmocka_unit_test(round_trip_real_file_and_crs),
        cmocka_unit_test(geotiff_crs_keeps_a_legacy_format),
        cmocka_unit_test(wkt_crs_is_written_whole),
        cmocka_unit_test(gps_time_type_survives),
        cmocka_unit_test(normals_round_trip_as_extra_bytes),
        cmocka_unit_test(wide_cloud_gets_a_coarser_scale),
        cmocka_unit_test(failed_write_leaves_no_file),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
