/* PLY reader and writer: every encoding and type, elements around the vertex
 * element, list properties, round trips at survey coordinates, bad input. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/cloud.h"
#include "stages/ingest/ingest.h"

/* ---- a small PLY builder: the test's own writer, independent of Sylva's ---- */

typedef struct {
    unsigned char *data;
    size_t size, cap;
} bytes;

static void put(bytes *b, const void *p, size_t n)
{
    if (b->size + n + 1 > b->cap) {
        b->cap = (b->size + n + 1) * 2;
        b->data = realloc(b->data, b->cap);
        assert_non_null(b->data);
    }
    memcpy(b->data + b->size, p, n);
    b->size += n;
    b->data[b->size] = 0;
}

static void puts_b(bytes *b, const char *s)
{
    put(b, s, strlen(s));
}

enum { ASCII, LE, BE };

static size_t size_of(const char *type)
{
    if (!strcmp(type, "char") || !strcmp(type, "uchar") || !strcmp(type, "int8") || !strcmp(type, "uint8"))
        return 1;
    if (!strcmp(type, "short") || !strcmp(type, "ushort") || !strcmp(type, "int16") ||
        !strcmp(type, "uint16"))
        return 2;
    if (!strcmp(type, "double") || !strcmp(type, "float64")) return 8;
    return 4;
}

static int is_float_type(const char *type)
{
    return !strcmp(type, "float") || !strcmp(type, "float32") || !strcmp(type, "double") ||
           !strcmp(type, "float64");
}

/* One value of a PLY type in the given encoding (ascii: followed by a space). */
static void put_value(bytes *b, int enc, const char *type, double v)
{
    size_t n = size_of(type);
    if (enc == ASCII) {
        char s[64];
        if (is_float_type(type)) snprintf(s, sizeof s, "%.17g ", n == 4 ? (double)(float)v : v);
        else snprintf(s, sizeof s, "%lld ", (long long)v);
        puts_b(b, s);
        return;
    }
    unsigned char raw[8];
    uint64_t u = 0;
    if (n == 8 && is_float_type(type)) memcpy(&u, &v, 8);
    else if (n == 4 && is_float_type(type)) {
        float f = (float)v;
        uint32_t w;
        memcpy(&w, &f, 4);
        u = w;
    } else {
        u = (uint64_t)(int64_t)v;
    }
    for (size_t i = 0; i < n; i++) raw[enc == LE ? i : n - 1 - i] = (unsigned char)(u >> (8 * i));
    put(b, raw, n);
}

typedef struct {
    const char *type, *name; /* type "list" means "list uchar int" */
} prop;

#define NPTS 6
static const prop vertex_props[] = {
    {"double", "x"},       {"float64", "y"},     {"float32", "z"},    {"float", "nx"},
    {"float", "ny"},       {"float", "nz"},      {"uchar", "red"},    {"uint8", "green"},
    {"uchar", "blue"},     {"uchar", "alpha"},   {"ushort", "intensity"},
    {"int", "scalar_treeID"}, {"int16", "label"}, {"float64", "quality"}, {"list", "vlist"},
    {"char", "flag"},      {"uint", "count32"},  {"uint16", "u16"},  {"int8", "i8"},
    {"int32", "i32"},      {"uint32", "u32"},    {"short", "s16"},
};
#define NPROPS (sizeof vertex_props / sizeof vertex_props[0])

/* The value of property p for point i: survey-scale x and y, small z. */
static double value(size_t p, int i)
{
    const char *n = vertex_props[p].name;
    if (!strcmp(n, "x")) return 1176136.125 + 0.25 * i;
    if (!strcmp(n, "y")) return 5000123.5 - 0.125 * i;
    if (!strcmp(n, "z")) return 0.75 + i;
    if (!strcmp(n, "nx")) return 0.5;
    if (!strcmp(n, "ny")) return -0.25 * (i % 2);
    if (!strcmp(n, "nz")) return 0.75;
    if (!strcmp(n, "red")) return 10 * i;
    if (!strcmp(n, "green")) return 255 - i;
    if (!strcmp(n, "blue")) return 128;
    if (!strcmp(n, "alpha")) return 200;
    if (!strcmp(n, "intensity")) return 1000 * i + 7;
    if (!strcmp(n, "scalar_treeID")) return 40000 + i;
    if (!strcmp(n, "label")) return -3 * i;
    if (!strcmp(n, "quality")) return 0.1 * i + 1e-9;
    if (!strcmp(n, "flag")) return -i;
    if (!strcmp(n, "count32")) return 3000000000.0 + i;
    if (!strcmp(n, "i8")) return -100 + i;
    if (!strcmp(n, "i32")) return -2000000000 + i;
    if (!strcmp(n, "u32")) return 4000000000.0 + i;
    if (!strcmp(n, "s16")) return -30000 + i;
    return 60000 + i; /* u16 */
}

/* A PLY with a fixed-size element and a face list element before the vertex
 * element and an edge element after it; vertex properties in `order`. */
static bytes build_ply(int enc, const size_t *order, size_t nprops, int crlf)
{
    bytes b = {0};
    const char *eol = crlf ? "\r\n" : "\n";
    const char *encs[] = {"ascii", "binary_little_endian", "binary_big_endian"};
    char line[256];
#define H(...) (snprintf(line, sizeof line, __VA_ARGS__), puts_b(&b, line), puts_b(&b, eol))
    H("ply");
    H("format %s 1.0", encs[enc]);
    H("comment made by test_ingest_ply");
    H("obj_info nothing to see");
    H("element material 2");
    H("property float shininess");
    H("property uchar kind");
    H("element face 3");
    H("property list uchar int vertex_indices");
    H("property ushort flags");
    H("element vertex %d", NPTS);
    for (size_t k = 0; k < nprops; k++) {
        const prop *p = &vertex_props[order[k]];
        if (!strcmp(p->type, "list")) H("property list uchar int %s", p->name);
        else H("property %s %s", p->type, p->name);
    }
    H("element edge 1");
    H("property int vertex1");
    H("property int vertex2");
    H("end_header");
#undef H
    const char *item_end = enc == ASCII ? "\n" : "";
    for (int m = 0; m < 2; m++) {
        put_value(&b, enc, "float", 0.5 * m);
        put_value(&b, enc, "uchar", m);
        puts_b(&b, item_end);
    }
    for (int f = 0; f < 3; f++) {
        put_value(&b, enc, "uchar", f + 3); /* lengths 3, 4, 5 */
        for (int k = 0; k < f + 3; k++) put_value(&b, enc, "int", k);
        put_value(&b, enc, "ushort", 65535);
        puts_b(&b, item_end);
    }
    for (int i = 0; i < NPTS; i++) {
        for (size_t k = 0; k < nprops; k++) {
            const prop *p = &vertex_props[order[k]];
            if (!strcmp(p->type, "list")) {
                put_value(&b, enc, "uchar", i % 3);
                for (int j = 0; j < i % 3; j++) put_value(&b, enc, "int", 99);
            } else {
                put_value(&b, enc, p->type, value(order[k], i));
            }
        }
        puts_b(&b, item_end);
    }
    put_value(&b, enc, "int", 0);
    put_value(&b, enc, "int", 1);
    puts_b(&b, item_end);
    return b;
}

static void check_cloud(const sy_cloud *c)
{
    assert_int_equal(c->n, NPTS);
    assert_non_null(c->normal);
    assert_non_null(c->rgb);
    assert_non_null(c->intensity);
    assert_null(sy_cloud_attr(c, "alpha"));
    assert_null(sy_cloud_attr(c, "vlist"));
    assert_null(sy_cloud_attr(c, "scalar_treeID"));
    for (int i = 0; i < NPTS; i++) {
        assert_float_equal(c->origin[0] + c->xyz[3 * i], 1176136.125 + 0.25 * i, 1e-4);
        assert_float_equal(c->origin[1] + c->xyz[3 * i + 1], 5000123.5 - 0.125 * i, 1e-4);
        assert_float_equal(c->origin[2] + c->xyz[3 * i + 2], 0.75 + i, 1e-6);
        assert_float_equal(c->normal[3 * i + 1], -0.25 * (i % 2), 0);
        assert_int_equal(c->rgb[3 * i], 10 * i * 257);
        assert_int_equal(c->rgb[3 * i + 1], (255 - i) * 257);
        assert_int_equal(c->rgb[3 * i + 2], 128 * 257);
        assert_int_equal(c->intensity[i], 1000 * i + 7);
        assert_float_equal(sy_cloud_attr(c, "treeID")[i], 40000 + i, 0);
        assert_float_equal(sy_cloud_attr(c, "label")[i], -3 * i, 0);
        assert_float_equal(sy_cloud_attr(c, "quality")[i], 0.1 * i + 1e-9, 0);
        assert_float_equal(sy_cloud_attr(c, "flag")[i], -i, 0);
        assert_float_equal(sy_cloud_attr(c, "count32")[i], 3000000000.0 + i, 0);
        assert_float_equal(sy_cloud_attr(c, "u16")[i], 60000 + i, 0);
        assert_float_equal(sy_cloud_attr(c, "i8")[i], -100 + i, 0);
        assert_float_equal(sy_cloud_attr(c, "i32")[i], -2000000000 + i, 0);
        assert_float_equal(sy_cloud_attr(c, "u32")[i], 4000000000.0 + i, 0);
        assert_float_equal(sy_cloud_attr(c, "s16")[i], -30000 + i, 0);
    }
}

static void every_encoding_and_order_reads_the_same(void **state)
{
    (void)state;
    size_t orders[4][NPROPS], counts[4] = {NPROPS, NPROPS, NPROPS, 0};
    for (size_t k = 0; k < NPROPS; k++) {
        orders[0][k] = k;                             /* as declared */
        orders[1][k] = NPROPS - 1 - k;                /* reversed: the list comes early */
        orders[2][k] = (k * 7 + 3) % NPROPS;          /* shuffled (7 is coprime to 22) */
        if (strcmp(vertex_props[(k * 5) % NPROPS].type, "list"))
            orders[3][counts[3]++] = (k * 5) % NPROPS; /* no list: fixed-size binary records */
    }
    const char *versions[] = {"ascii 1.0", "binary_little_endian 1.0", "binary_big_endian 1.0"};
    for (int enc = ASCII; enc <= BE; enc++)
        for (int o = 0; o < 4; o++) {
            bytes b = build_ply(enc, orders[o], counts[o], o == 2);
            sy_cloud c;
            sy_error err = {0};
            sy_code rc = sy_read_ply_mem("mem.ply", b.data, b.size, &c, &err);
            if (rc) fail_msg("encoding %d order %d: %s", enc, o, err.msg);
            check_cloud(&c);
            assert_string_equal(c.meta.format, "PLY");
            assert_string_equal(c.meta.version, versions[enc]);
            assert_int_equal(c.meta.header_count, NPTS);
            sy_cloud_free(&c);
            free(b.data);
        }
}

static void reads_through_dispatch_from_a_file(void **state)
{
    (void)state;
    size_t order[NPROPS];
    for (size_t k = 0; k < NPROPS; k++) order[k] = k;
    bytes b = build_ply(BE, order, NPROPS, 1);
    const char *path = tmp_path("dispatch.ply");
    assert_int_equal(write_bytes(path, b.data, b.size), 0);
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_read_cloud(path, &c, &err), SY_OK);
    check_cloud(&c);
    sy_cloud_free(&c);
    free(b.data);
}

/* A cloud at survey coordinates with every array and two attributes. */
static void make_survey_cloud(sy_cloud *c, size_t n)
{
    sy_error err = {0};
    assert_int_equal(sy_cloud_init(c, n, &err), SY_OK);
    c->origin[0] = 1176136.0;
    c->origin[1] = 5000100.0;
    c->origin[2] = 12.0;
    assert_int_equal(sy_cloud_add_normals(c, &err), SY_OK);
    assert_int_equal(sy_cloud_add_rgb(c, &err), SY_OK);
    assert_int_equal(sy_cloud_add_intensity(c, &err), SY_OK);
    assert_int_equal(sy_cloud_add_classification(c, &err), SY_OK);
    double *tree = sy_cloud_add_attr(c, "treeID", &err);
    double *frac = sy_cloud_add_attr(c, "x", &err); /* collides with a coordinate name */
    assert_non_null(tree);
    assert_non_null(frac);
    for (size_t i = 0; i < n; i++) {
        c->xyz[3 * i] = (float)(0.0137 * (double)i);
        c->xyz[3 * i + 1] = (float)(27.5 - 0.0071 * (double)i);
        c->xyz[3 * i + 2] = (float)(0.25 * (double)(i % 40));
        c->normal[3 * i + 2] = 1.0f;
        c->rgb[3 * i] = (uint16_t)((i % 256) * 257);
        c->rgb[3 * i + 1] = (uint16_t)(((i * 7) % 256) * 257);
        c->rgb[3 * i + 2] = 65535;
        c->intensity[i] = (uint16_t)(i * 13);
        c->classification[i] = (uint8_t)(i % 3 ? 5 : 2);
        tree[i] = (double)(i / 100);
        frac[i] = 1.0 / 3.0 + (double)i;
    }
}

static void round_trip_keeps_positions_and_attributes(void **state)
{
    (void)state;
    sy_cloud a, b;
    sy_error err = {0};
    make_survey_cloud(&a, 1000);
    const char *path = tmp_path("round.ply");
    assert_int_equal(sy_write_ply(path, &a, &err), SY_OK);
    assert_int_equal(sy_read_cloud(path, &b, &err), SY_OK);
    assert_int_equal(b.n, a.n);
    assert_string_equal(b.meta.version, "binary_little_endian 1.0");
    for (size_t i = 0; i < a.n; i++) {
        for (int k = 0; k < 3; k++) {
            double wa = a.origin[k] + a.xyz[3 * i + k], wb = b.origin[k] + b.xyz[3 * i + k];
            assert_true(fabs(wa - wb) < 1e-4);
            assert_int_equal(b.rgb[3 * i + k], a.rgb[3 * i + k]);
            assert_float_equal(b.normal[3 * i + k], a.normal[3 * i + k], 0);
        }
        assert_int_equal(b.intensity[i], a.intensity[i]);
        assert_int_equal(b.classification[i], a.classification[i]);
        assert_float_equal(sy_cloud_attr(&b, "treeID")[i], a.attrs[0].values[i], 0);
        assert_float_equal(sy_cloud_attr(&b, "x")[i], a.attrs[1].values[i], 0);
    }
    sy_cloud_free(&a);
    sy_cloud_free(&b);
}

/* ---- malformed input ---- */

static void expect_input_error(const char *name, const void *data, size_t size, const char *words)
{
    const char *path = tmp_path(name);
    sy_cloud c;
    sy_error err = {0};
    sy_code rc = sy_read_ply_mem(path, data, size, &c, &err);
    if (rc != SY_EINPUT) fail_msg("%s: expected SY_EINPUT, got %d (%s)", name, rc, err.msg);
    if (!strstr(err.msg, path)) fail_msg("%s: message does not name the file: %s", name, err.msg);
    if (strchr(err.msg, '\n')) fail_msg("%s: message spans lines: %s", name, err.msg);
    if (words && !strstr(err.msg, words)) fail_msg("%s: message lacks '%s': %s", name, words, err.msg);
    assert_null(c.xyz);
    /* And through the file dispatcher, which must leave nothing behind either. */
    assert_int_equal(write_bytes(path, data, size), 0);
    assert_int_equal(sy_read_cloud(path, &c, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, path));
}

#define HDR(body) "ply\nformat ascii 1.0\n" body
#define BIN(body) "ply\nformat binary_little_endian 1.0\n" body

static void malformed_headers_are_input_errors(void **state)
{
    (void)state;
    const char *no_magic = "plx\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n";
    expect_input_error("no_magic.ply", no_magic, strlen(no_magic), "magic");
    const char *no_end =
        HDR("element vertex 1\nproperty float x\nproperty float y\nproperty float z\n1 2 3\n");
    expect_input_error("no_end.ply", no_end, strlen(no_end), "end_header");
    const char *bad_type = HDR("element vertex 1\nproperty float128 x\nend_header\n1\n");
    expect_input_error("bad_type.ply", bad_type, strlen(bad_type), "float128");
    const char *bad_enc = "ply\nformat binary_middle_endian 1.0\nelement vertex 0\nend_header\n";
    expect_input_error("bad_enc.ply", bad_enc, strlen(bad_enc), "encoding");
    const char *no_z = HDR("element vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n");
    expect_input_error("no_z.ply", no_z, strlen(no_z), "x, y or z");
    const char *list_z = HDR("element vertex 1\nproperty float x\nproperty float y\n"
                             "property list uchar float z\nend_header\n1 2 1 3\n");
    expect_input_error("list_z.ply", list_z, strlen(list_z), "x, y or z");
    const char *bad_count = HDR("element vertex -4\nproperty float x\nend_header\n");
    expect_input_error("bad_count.ply", bad_count, strlen(bad_count), "count");
    const char *no_vertex = HDR("element face 0\nproperty list uchar int vertex_indices\nend_header\n");
    expect_input_error("no_vertex.ply", no_vertex, strlen(no_vertex), "vertex");
}

static void impossible_counts_are_refused_before_allocating(void **state)
{
    (void)state;
    const char *huge = BIN("element vertex 1000000000000000\nproperty double x\nproperty double y\n"
                           "property double z\nend_header\n0123456789abcdef01234567");
    expect_input_error("huge.ply", huge, strlen(huge), "1000000000000000");
    const char *huge_ascii = HDR("element vertex 1000000000000000\nproperty float x\nproperty float y\n"
                                 "property float z\nend_header\n1 2 3\n");
    expect_input_error("huge_ascii.ply", huge_ascii, strlen(huge_ascii), "claims");
    const char *huge_face = BIN("element face 1000000000000000\nproperty list uchar int idx\n"
                                "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                                "end_header\n\x01\x00\x00\x00\x00");
    expect_input_error("huge_face.ply", huge_face, strlen(huge_face) + 4, "face");
    const char *long_list = HDR("element face 1\nproperty list uint int idx\nelement vertex 1\n"
                                "property float x\nproperty float y\nproperty float z\nend_header\n"
                                "4000000000 1 2\n1 2 3\n");
    expect_input_error("long_list.ply", long_list, strlen(long_list), "length");
    /* 2.5 records of 12 bytes. */
    const char *trunc = BIN("element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                            "end_header\n");
    unsigned char buf[256] = {0};
    size_t h = strlen(trunc);
    memcpy(buf, trunc, h);
    expect_input_error("trunc.ply", buf, h + 30, "3 items");
    const char *trunc_list = BIN("element vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
                                 "property list uchar double extra\nend_header\n");
    h = strlen(trunc_list);
    memcpy(buf, trunc_list, h);
    memset(buf + h, 0, 26);
    buf[h + 12] = 200; /* the first list claims 200 doubles */
    expect_input_error("trunc_list.ply", buf, h + 26, "truncated");
}

static void bad_values_are_input_errors(void **state)
{
    (void)state;
    const char *word = HDR("element vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
                           "end_header\n1 2 3\n1.0 abc 3\n");
    expect_input_error("word.ply", word, strlen(word), "abc");
    const char *two_dots = HDR("element vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                               "end_header\n1 2.2.2 3\n");
    expect_input_error("two_dots.ply", two_dots, strlen(two_dots), "2.2.2");
    const char *short_ascii = HDR("element vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
                                  "end_header\n1 2 3\n4       5      \n");
    expect_input_error("short_ascii.ply", short_ascii, strlen(short_ascii), "truncated");
    const char *nan = HDR("element vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
                          "end_header\n1 2 3\n4 nan 6\n");
    expect_input_error("nan.ply", nan, strlen(nan), "non-finite");
    /* +Inf as a little-endian double z. */
    const char *inf = BIN("element vertex 1\nproperty double x\nproperty double y\nproperty double z\n"
                          "end_header\n");
    unsigned char buf[256] = {0};
    size_t h = strlen(inf);
    memcpy(buf, inf, h);
    double v = INFINITY;
    memcpy(buf + h + 16, &v, 8); /* the test host is little endian like every supported one */
    expect_input_error("inf.ply", buf, h + 24, "non-finite");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(every_encoding_and_order_reads_the_same),
        cmocka_unit_test(reads_through_dispatch_from_a_file),
        cmocka_unit_test(round_trip_keeps_positions_and_attributes),
        cmocka_unit_test(malformed_headers_are_input_errors),
        cmocka_unit_test(impossible_counts_are_refused_before_allocating),
        cmocka_unit_test(bad_values_are_input_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
