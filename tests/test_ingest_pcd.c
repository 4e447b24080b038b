/* PCD reader against files written by PCL 1.13 (tests/data/pcd/README.md
 * lists their values), older hand-built layouts, and malformed inputs. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/fileio.h"
#include "stages/ingest/ingest.h"

static const char *fixture(const char *name)
{
    static char buf[4][4096];
    static int next;
    char *b = buf[next++ & 3];
    snprintf(b, 4096, "%s/tests/data/pcd/%s", SYLVA_SOURCE_DIR, name);
    return b;
}

/* cmocka's assert_float_equal compares in float; positions and attributes
 * need double. */
#define assert_near(a, b, tol) near_or_fail((a), (b), (tol), #a, __FILE__, __LINE__)
static void near_or_fail(double a, double b, double tol, const char *what, const char *file, int line)
{
    if (fabs(a - b) <= tol) return;
    print_error("%s = %.17g, want %.17g +- %g\n", what, a, b, tol);
    _fail(file, line);
}

static void world(const sy_cloud *c, size_t i, double p[3])
{
    for (int k = 0; k < 3; k++) p[k] = c->origin[k] + c->xyz[3 * i + k];
}

/* Errors are one line naming the file. */
static void assert_input_error(sy_code rc, const sy_error *err, const char *path, const char *needle)
{
    assert_int_equal(rc, SY_EINPUT);
    if (!strstr(err->msg, path) || !strstr(err->msg, needle) || strchr(err->msg, '\n'))
        fail_msg("unexpected message: '%s' (want '%s' and '%s')", err->msg, path, needle);
}

static void read_fixture(const char *name, sy_cloud *c)
{
    sy_error err = {0};
    sy_code rc = sy_read_cloud(fixture(name), c, &err);
    if (rc) fail_msg("%s: %s", name, err.msg);
}

static void check_xyzrgbnormal(const char *name, const char *version)
{
    sy_cloud c;
    read_fixture(name, &c);
    assert_string_equal(c.meta.format, "PCD");
    assert_string_equal(c.meta.version, version);
    assert_int_equal(c.n, 12);
    assert_int_equal(c.meta.header_count, 12);
    assert_non_null(c.normal);
    assert_non_null(c.rgb);
    assert_null(c.intensity);
    double *curv = sy_cloud_attr(&c, "curvature");
    assert_non_null(curv);
    /* The origin sits near the data, so float offsets stay small. */
    assert_true(c.origin[0] > 900 && c.origin[1] > 1900);
    for (size_t i = 0; i < 12; i++) {
        double p[3];
        world(&c, i, p);
        assert_near(p[0], 1000.0 + 0.5 * i, 1e-6);
        assert_near(p[1], 2000.0 - 0.25 * i, 1e-6);
        assert_near(p[2], 10.0 + 0.125 * i, 1e-6);
        assert_int_equal(c.rgb[3 * i + 0], 20 * i * 257);
        assert_int_equal(c.rgb[3 * i + 1], (255 - 20 * i) * 257);
        assert_int_equal(c.rgb[3 * i + 2], 7 * i * 257);
        for (size_t k = 0; k < 3; k++) assert_near(c.normal[3 * i + k], (i % 3 == k ? 1.0 : 0.0), 0);
        assert_near(curv[i], 0.01 * i, 1e-6);
    }
    assert_null(c.meta.vlr_summary);
    sy_cloud_free(&c);
}

static void xyzrgbnormal_all_encodings(void **state)
{
    (void)state;
    check_xyzrgbnormal("xyzrgbnormal_ascii.pcd", "0.7 ascii");
    check_xyzrgbnormal("xyzrgbnormal_binary.pcd", "0.7 binary");
    check_xyzrgbnormal("xyzrgbnormal_compressed.pcd", "0.7 binary_compressed");
}

static void check_mixed(const char *name, double t_tolerance)
{
    sy_cloud c;
    read_fixture(name, &c);
    assert_int_equal(c.n, 6);
    assert_non_null(c.intensity);
    const char *names[] = {"label", "ring", "flag", "t", "sid"};
    double *a[5];
    for (int k = 0; k < 5; k++) {
        a[k] = sy_cloud_attr(&c, names[k]);
        if (!a[k]) fail_msg("%s: attribute %s missing", name, names[k]);
    }
    /* The COUNT 5 histogram is skipped, and the fields after it still line up. */
    assert_null(sy_cloud_attr(&c, "hist"));
    assert_int_equal(c.n_attrs, 5);
    assert_non_null(strstr(c.meta.vlr_summary, "skipped field hist (COUNT 5)"));
    for (size_t i = 0; i < 6; i++) {
        double p[3];
        world(&c, i, p);
        assert_near(p[0], -1.5 + (double)i, 1e-6);
        assert_near(p[1], 2.25 * i, 1e-6);
        assert_near(p[2], 0.75 - 0.5 * i, 1e-6);
        /* Sensor counts (not within [0, 1]) are rounded, not scaled. */
        assert_int_equal(c.intensity[i], 100 * i + 7);
        assert_near(a[0][i], 40.0 + i, 0);
        assert_near(a[1][i], 60000.0 + i, 0);
        assert_near(a[2][i], -3.0 * i, 0);
        assert_near(a[3][i], 1e9 + 0.125 * i, t_tolerance);
        assert_near(a[4][i], -100000.0 * i, 0);
    }
    sy_cloud_free(&c);
}

static void mixed_types_all_encodings(void **state)
{
    (void)state;
    check_mixed("mixed_ascii.pcd", 0.01); /* PCL wrote 12 significant digits */
    check_mixed("mixed_binary.pcd", 0);
    check_mixed("mixed_compressed.pcd", 0);
}

static void check_organized(const char *name)
{
    sy_cloud c;
    read_fixture(name, &c);
    assert_int_equal(c.n, 9);
    assert_int_equal(c.meta.header_count, 12);
    assert_non_null(strstr(c.meta.vlr_summary, "skipped 3 NaN points"));
    assert_non_null(strstr(c.meta.vlr_summary, "organized 4x3 grid"));
    size_t j = 0;
    for (int k = 0; k < 12; k++) {
        if (k == 1 || k == 6 || k == 11) continue;
        int col = k % 4, row = k / 4;
        double p[3];
        world(&c, j, p);
        assert_near(p[0], 0.1 * col, 1e-6);
        assert_near(p[1], 0.1 * row, 1e-6);
        assert_near(p[2], 2.0 + 0.01 * k, 1e-6);
        assert_int_equal(c.rgb[3 * j + 0], 10 * col * 257);
        assert_int_equal(c.rgb[3 * j + 1], 10 * row * 257);
        assert_int_equal(c.rgb[3 * j + 2], 200 * 257);
        j++;
    }
    sy_cloud_free(&c);
}

static void organized_nan_points_skipped(void **state)
{
    (void)state;
    check_organized("organized_nan_ascii.pcd");
    check_organized("organized_nan_compressed.pcd");
}

static void unit_intensity_scaled(void **state)
{
    (void)state;
    sy_cloud c;
    read_fixture("xyzi_binary.pcd", &c);
    assert_int_equal(c.n, 5);
    for (size_t i = 0; i < 5; i++) {
        double p[3];
        world(&c, i, p);
        assert_near(p[0], (double)i, 1e-6);
        assert_near(p[1], -(double)i, 1e-6);
        assert_near(p[2], 0.5 * i, 1e-6);
        assert_int_equal(c.intensity[i], (long)lround(0.2 * i * 65535));
    }
    sy_cloud_free(&c);
}

/* A v0.6-style binary file: no VERSION, '_' padding, rgb packed in a float. */
static void old_binary_with_padding(void **state)
{
    (void)state;
    const char *head = "# .PCD v.6 - hand made\nFIELDS x y z _ rgb\nSIZE 4 4 4 4 4\nTYPE F F F U F\n"
                       "COUNT 1 1 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n";
    unsigned char buf[512];
    size_t n = strlen(head);
    memcpy(buf, head, n);
    for (int i = 0; i < 2; i++) {
        float xyz[3] = {1.5f + i, -2.0f, 3.25f};
        uint32_t pad = 0xdeadbeef, rgb = (uint32_t)(0x10 + i) << 16 | 0x20 << 8 | 0x30;
        memcpy(buf + n, xyz, 12);
        memcpy(buf + n + 12, &pad, 4);
        memcpy(buf + n + 16, &rgb, 4);
        n += 20;
    }
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_read_pcd_mem("old.pcd", buf, n, &c, &err), SY_OK);
    assert_int_equal(c.n, 2);
    assert_string_equal(c.meta.version, "binary");
    assert_int_equal(c.n_attrs, 0); /* padding is not an attribute */
    double p[3];
    world(&c, 1, p);
    assert_near(p[0], 2.5, 1e-6);
    assert_near(p[2], 3.25, 1e-6);
    assert_int_equal(c.rgb[3], 0x11 * 257);
    assert_int_equal(c.rgb[4], 0x20 * 257);
    assert_int_equal(c.rgb[5], 0x30 * 257);
    sy_cloud_free(&c);
}

/* A v0.5-style ascii file: COLUMNS, no SIZE/TYPE/COUNT/WIDTH (all default to
 * F 4 1), and rgb written as the float whose bits pack the colour. */
static void old_ascii_defaults(void **state)
{
    (void)state;
    uint32_t packed = 0x00ff8000u;
    float f;
    memcpy(&f, &packed, 4);
    char text[512];
    snprintf(text, sizeof text, "COLUMNS x y z rgb\nPOINTS 2\nDATA ascii\n1 2 3 %.9g\n\n4 5 6 %.9g\n", f, f);
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_read_pcd_mem("v5.pcd", (const unsigned char *)text, strlen(text), &c, &err), SY_OK);
    assert_int_equal(c.n, 2);
    double p[3];
    world(&c, 1, p);
    assert_near(p[0], 4, 0);
    assert_near(p[1], 5, 0);
    assert_near(p[2], 6, 0);
    assert_int_equal(c.rgb[0], 255 * 257);
    assert_int_equal(c.rgb[1], 128 * 257);
    assert_int_equal(c.rgb[2], 0);
    sy_cloud_free(&c);
}

/* ---- malformed input ---------------------------------------------------- */

typedef struct {
    unsigned char *data;
    size_t size;
} blob;

static blob load(const char *name)
{
    sy_buffer b;
    sy_error err = {0};
    assert_int_equal(sy_read_file(fixture(name), &b, &err), SY_OK);
    return (blob){b.data, b.size};
}

/* Replaces the first occurrence of old by new (same or different length). */
static void patch(blob *b, const char *old, const char *new)
{
    unsigned char *at = NULL;
    size_t lo = strlen(old), ln = strlen(new);
    for (size_t i = 0; i + lo <= b->size && !at; i++)
        if (memcmp(b->data + i, old, lo) == 0) at = b->data + i;
    assert_non_null(at);
    size_t head = (size_t)(at - b->data), tail = b->size - head - lo;
    unsigned char *d = malloc(head + ln + tail + 1);
    memcpy(d, b->data, head);
    memcpy(d + head, new, ln);
    memcpy(d + head + ln, at + lo, tail);
    free(b->data);
    b->data = d;
    b->size = head + ln + tail;
}

static size_t data_start(const blob *b)
{
    const char *kw = "\nDATA ";
    for (size_t i = 0; i + 6 <= b->size; i++)
        if (memcmp(b->data + i, kw, 6) == 0) {
            size_t j = i + 1;
            while (j < b->size && b->data[j] != '\n') j++;
            return j + 1;
        }
    fail_msg("no DATA line");
    return 0;
}

static void expect_error(blob *b, const char *path, const char *needle)
{
    sy_cloud c;
    sy_error err = {0};
    assert_input_error(sy_read_pcd_mem(path, b->data, b->size, &c, &err), &err, path, needle);
    assert_null(c.xyz); /* nothing left allocated */
    free(b->data);
}

static void truncated_files(void **state)
{
    (void)state;
    blob b = load("xyzrgbnormal_binary.pcd");
    b.size -= 10;
    expect_error(&b, "cut_binary.pcd", "truncated");
    b = load("xyzrgbnormal_ascii.pcd");
    b.size -= 100; /* drops the last three lines */
    expect_error(&b, "cut_ascii.pcd", "truncated");
    b = load("xyzrgbnormal_ascii.pcd");
    b.size -= 5; /* the last line loses its last value */
    expect_error(&b, "cut_line.pcd", "too few values");
    b = load("xyzrgbnormal_compressed.pcd");
    b.size -= 5;
    expect_error(&b, "cut_compressed.pcd", "truncated");
    b = load("xyzrgbnormal_compressed.pcd");
    b.size = data_start(&b) + 6;
    expect_error(&b, "cut_sizes.pcd", "truncated");
}

static void corrupt_lzf(void **state)
{
    (void)state;
    blob b = load("xyzrgbnormal_compressed.pcd");
    size_t s = data_start(&b);
    b.data[s + 8] = 0x20; /* a back-reference before any output */
    expect_error(&b, "lzf_backref.pcd", "back-reference before the start");
    b = load("xyzrgbnormal_compressed.pcd");
    b.data[s + 8] = 0x1f; /* a 32-byte literal run where a shorter one was */
    expect_error(&b, "lzf_literal.pcd", "corrupt LZF data");
    b = load("xyzrgbnormal_compressed.pcd");
    b.data[s] -= 3; /* compressed stream cut short inside a token */
    expect_error(&b, "lzf_short.pcd", "corrupt LZF data");
    b = load("xyzrgbnormal_compressed.pcd");
    b.data[s + 4] += 4; /* uncompressed size disagrees with the fields */
    expect_error(&b, "lzf_size.pcd", "declares");
}

static void inflated_counts(void **state)
{
    (void)state;
    blob b = load("xyzrgbnormal_binary.pcd");
    patch(&b, "WIDTH 12", "WIDTH 400000000");
    patch(&b, "POINTS 12", "POINTS 400000000");
    expect_error(&b, "inflated.pcd", "do not fit");
    b = load("xyzrgbnormal_ascii.pcd");
    patch(&b, "WIDTH 12", "WIDTH 4000000000000");
    patch(&b, "POINTS 12", "POINTS 4000000000000");
    expect_error(&b, "inflated_ascii.pcd", "more than the");
    b = load("xyzrgbnormal_compressed.pcd");
    patch(&b, "WIDTH 12", "WIDTH 1200000");
    patch(&b, "POINTS 12", "POINTS 1200000");
    expect_error(&b, "inflated_compressed.pcd", "declares");
    b = load("xyzrgbnormal_binary.pcd");
    patch(&b, "POINTS 12", "POINTS 11");
    expect_error(&b, "mismatch.pcd", "does not match WIDTH");
}

static void bad_headers(void **state)
{
    (void)state;
    blob b = load("xyzrgbnormal_binary.pcd");
    patch(&b, "DATA binary", "DATA binary_lz4");
    expect_error(&b, "kind.pcd", "unknown DATA kind 'binary_lz4'");
    b = load("xyzrgbnormal_binary.pcd");
    patch(&b, "FIELDS x y z", "FIELDS x y w");
    expect_error(&b, "noz.pcd", "lacks z");
    b = load("xyzrgbnormal_binary.pcd");
    patch(&b, "SIZE 4 4 4 4", "SIZE 4 4 4");
    expect_error(&b, "size.pcd", "fewer values");
    b = load("xyzrgbnormal_binary.pcd");
    patch(&b, "TYPE F", "TYPE Q");
    expect_error(&b, "type.pcd", "unknown TYPE 'Q'");
    b = load("xyzrgbnormal_binary.pcd");
    b.size = data_start(&b) - 5; /* header cut inside the DATA line's kind */
    patch(&b, "DATA", "DAT_");
    expect_error(&b, "header.pcd", "unexpected header line");
    b = load("xyzrgbnormal_ascii.pcd");
    patch(&b, "1000.5 1999.75", "1000.5 19x9.75");
    expect_error(&b, "value.pcd", "bad value '19x9.75' for field y");
}

/* ---- generated binary files larger than one decoding block ---- */

static unsigned char *append(unsigned char *q, const void *v, size_t n)
{
    memcpy(q, v, n);
    return q + n;
}

/* 2500 points (blocks are 1024 rows) with NaN points on both sides of block
 * edges: every kept point lands in its own slot with all its fields. */
static void nan_points_across_blocks(void **state)
{
    (void)state;
    enum { N = 2500 };
    static unsigned char file[256 + N * 28]; /* header, then 28-byte records */
    int head = snprintf((char *)file, 256,
                        "VERSION 0.7\nFIELDS x y z rgb label weight\nSIZE 4 4 4 4 4 8\nTYPE F F F U I F\n"
                        "COUNT 1 1 1 1 1 1\nWIDTH %d\nHEIGHT 1\nPOINTS %d\nDATA binary\n", N, N);
    unsigned char *q = file + head;
    for (int i = 0; i < N; i++) {
        int skip = i == 0 || i == 1023 || i == 1024 || i == N - 1;
        float xyz[3] = {skip ? NAN : 5000.0f + 0.5f * (float)(i % 50), -20.0f + 0.25f * (float)(i % 40),
                        0.01f * (float)i};
        uint32_t rgb = (uint32_t)((i % 256) << 16 | (255 - i % 256) << 8 | 7);
        int32_t label = i - 1000;
        double weight = 1.0 / (1.0 + i);
        q = append(append(append(append(q, xyz, 12), &rgb, 4), &label, 4), &weight, 8);
    }
    sy_cloud c;
    sy_error err = {0};
    if (sy_read_pcd_mem("blocks.pcd", file, (size_t)(q - file), &c, &err)) fail_msg("%s", err.msg);
    assert_int_equal(c.n, N - 4);
    assert_non_null(strstr(c.meta.vlr_summary, "skipped 4 NaN points"));
    const double *label = sy_cloud_attr(&c, "label"), *weight = sy_cloud_attr(&c, "weight");
    assert_non_null(label);
    assert_non_null(weight);
    size_t j = 0;
    for (int i = 0; i < N; i++) {
        if (i == 0 || i == 1023 || i == 1024 || i == N - 1) continue;
        double p[3];
        world(&c, j, p);
        assert_near(p[0], 5000.0 + 0.5 * (i % 50), 1e-3);
        assert_near(p[1], -20.0 + 0.25 * (i % 40), 1e-4);
        assert_near(p[2], (double)(0.01f * (float)i), 1e-4);
        assert_int_equal(c.rgb[3 * j], (i % 256) * 257);
        assert_int_equal(c.rgb[3 * j + 1], (255 - i % 256) * 257);
        assert_int_equal(c.rgb[3 * j + 2], 7 * 257);
        assert_near(label[j], i - 1000, 0);
        assert_near(weight[j], 1.0 / (1.0 + i), 0);
        j++;
    }
    /* The origin is the metre floor of the first point kept (point 1). */
    assert_near(c.origin[0], 5000.0, 0);
    assert_near(c.origin[1], -20.0, 0);
    sy_cloud_free(&c);
}

/* 200 fields make a block shorter than 1024 rows; values still line up. */
static void many_fields_shorten_the_block(void **state)
{
    (void)state;
    enum { N = 700, F = 200 };
    static unsigned char file[8192 + (size_t)N * F * 4];
    char *h = (char *)file;
    size_t used = (size_t)sprintf(h, "VERSION 0.7\nFIELDS x y z");
    for (int k = 3; k < F; k++) used += (size_t)sprintf(h + used, " a%d", k);
    used += (size_t)sprintf(h + used, "\nSIZE");
    for (int k = 0; k < F; k++) used += (size_t)sprintf(h + used, " 4");
    used += (size_t)sprintf(h + used, "\nTYPE");
    for (int k = 0; k < F; k++) used += (size_t)sprintf(h + used, " F");
    used += (size_t)sprintf(h + used, "\nPOINTS %d\nDATA binary\n", N);
    unsigned char *q = file + used;
    for (int i = 0; i < N; i++)
        for (int k = 0; k < F; k++) {
            float v = (float)(i * 1000 + k);
            q = append(q, &v, 4);
        }
    sy_cloud c;
    sy_error err = {0};
    if (sy_read_pcd_mem("wide.pcd", file, (size_t)(q - file), &c, &err)) fail_msg("%s", err.msg);
    assert_int_equal(c.n, N);
    assert_int_equal(c.n_attrs, F - 3);
    for (int k = 3; k < F; k += 49) {
        char name[16];
        snprintf(name, sizeof name, "a%d", k);
        const double *v = sy_cloud_attr(&c, name);
        assert_non_null(v);
        for (int i = 0; i < N; i++) assert_near(v[i], i * 1000 + k, 0);
    }
    for (int i = 0; i < N; i++) {
        double p[3];
        world(&c, (size_t)i, p);
        assert_near(p[2], i * 1000 + 2, 0);
    }
    sy_cloud_free(&c);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(xyzrgbnormal_all_encodings),
        cmocka_unit_test(mixed_types_all_encodings),
        cmocka_unit_test(organized_nan_points_skipped),
        cmocka_unit_test(unit_intensity_scaled),
        cmocka_unit_test(old_binary_with_padding),
        cmocka_unit_test(old_ascii_defaults),
        cmocka_unit_test(truncated_files),
        cmocka_unit_test(corrupt_lzf),
        cmocka_unit_test(inflated_counts),
        cmocka_unit_test(bad_headers),
        cmocka_unit_test(nan_points_across_blocks),
        cmocka_unit_test(many_fields_shorten_the_block),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
