/* XYZ/TXT/CSV reader and writer: the real ASCII scans, column rules, the
 * number parser, round trips at survey coordinates, bad input. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/cloud.h"
#include "stages/ingest/ingest.h"
#include "stages/ingest/textnum.h"

typedef struct {
    const char *rel;
    size_t points;
    double extent[3], tol; /* metres, as listed in data/README.md */
} real_file;

/* Counts are the real number of point rows. data/README.md lists one fewer
 * for tree1, tree7 and tree13 (it counted newlines; their last row has none). */
static const real_file real_files[] = {
    {"real/adtree/tree1.xyz", 11855, {2.5, 3.7, 5.5}, 0.1},
    {"real/adtree/tree7.xyz", 15130, {3.1, 3.2, 5.2}, 0.1},
    {"real/adtree/tree13.xyz", 6992, {8.7, 9.9, 9.9}, 0.1},
    {"real/adtree/tree33.xyz", 10005, {6.5, 11.6, 10.5}, 0.1},
    {"real/adtree/Lille_11.xyz", 19337, {4, 5, 9}, 0.6},
    {"real/adtree/ahn3_delft.xyz", 2488, {9.5, 10.5, 13}, 0.5},
    {"real/adtree/tiny(for_debug).xyz", 245, {7, 5, 7}, 0.5},
    {"real/adtree/house.xyz", 7706, {10, 10, 8}, 0.5},
    {"real/rtwig/cloud.txt", 14667, {2.5, 2.0, 3.7}, 0.1},
};

static void real_files_read_with_exact_counts(void **state)
{
    (void)state;
    for (size_t f = 0; f < sizeof real_files / sizeof real_files[0]; f++) {
        const real_file *r = &real_files[f];
        sy_cloud c;
        sy_error err = {0};
        if (sy_read_cloud(data_path(r->rel), &c, &err)) fail_msg("%s: %s", r->rel, err.msg);
        if (c.n != r->points) fail_msg("%s: %zu points, expected %zu", r->rel, c.n, r->points);
        assert_string_equal(c.meta.format, "XYZ");
        assert_null(c.rgb);
        assert_int_equal(c.n_attrs, 0);
        double lo[3], hi[3];
        sy_cloud_bounds(&c, lo, hi);
        for (int k = 0; k < 3; k++)
            if (fabs(hi[k] - lo[k] - r->extent[k]) > r->tol)
                fail_msg("%s: extent[%d] %.3f, expected %.1f", r->rel, k, hi[k] - lo[k], r->extent[k]);
        sy_cloud_free(&c);
    }
}

static void tree1_keeps_its_coordinates(void **state)
{
    (void)state;
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_read_cloud(data_path("real/adtree/tree1.xyz"), &c, &err), SY_OK);
    /* First row "0.132 18.645 3.971 \r" and last "-2.355 17.254 3.132 " (no newline). */
    assert_float_equal(c.origin[0] + c.xyz[0], 0.132, 1e-6);
    assert_float_equal(c.origin[1] + c.xyz[1], 18.645, 1e-6);
    assert_float_equal(c.origin[2] + c.xyz[2], 3.971, 1e-6);
    size_t l = c.n - 1;
    assert_float_equal(c.origin[0] + c.xyz[3 * l], -2.355, 1e-6);
    assert_float_equal(c.origin[2] + c.xyz[3 * l + 2], 3.132, 1e-6);
    sy_cloud_free(&c);
}

/* ---- the number parser ---- */

static double parse(const char *s)
{
    double v = -12345;
    const char *e = sy_parse_number(s, s + strlen(s), &v);
    assert_non_null(e);
    assert_ptr_equal(e, s + strlen(s));
    return v;
}

static void parser_agrees_with_strtod(void **state)
{
    (void)state;
    const char *fixed[] = {"0", "-0.0", "+1", "1.", ".5", "-.5e1", "1e5", "1E+05", "2.5e-3",
                           "1176136.123456", "-835.4466552734375", "0.460999995470047",
                           "123456789012345678901234567890", "0.000000000000000000000000123",
                           "1e-310", "1.7976931348623157e308", "4.9e-324", "9007199254740993",
                           "3.14159265358979323846264338327950288"};
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++) {
        double want = strtod(fixed[i], NULL), got = parse(fixed[i]);
        if (!(fabs(got - want) <= 2.3e-16 * fabs(want)) && !(want < 1e-300 && fabs(got - want) < 1e-320))
            fail_msg("%s: got %.17g want %.17g", fixed[i], got, want);
    }
    /* Random values in the shapes scanners print; short ones must be exact. */
    srand(7);
    const char *fmts[] = {"%.3f", "%.6f", "%.9g", "%.17g", "%.4e"};
    for (int i = 0; i < 200000; i++) {
        double v = ((double)rand() / RAND_MAX - 0.5) * pow(10, rand() % 14 - 4);
        char s[64];
        int fmt = i % 5;
        snprintf(s, sizeof s, fmts[fmt], v);
        double want = strtod(s, NULL), got = parse(s);
        if (fmt != 3 ? got != want : fabs(got - want) > 2.3e-16 * fabs(want))
            fail_msg("%s: got %.17g want %.17g", s, got, want);
    }
    assert_true(isnan(parse("nan")));
    assert_true(isinf(parse("-Infinity")) && parse("-inf") < 0);
    assert_true(isinf(parse("1e400")));
    double v;
    const char *junk[] = {"", "-", ".", "e5", "abc", "+.e1"};
    for (size_t i = 0; i < sizeof junk / sizeof junk[0]; i++)
        assert_null(sy_parse_number(junk[i], junk[i] + strlen(junk[i]), &v));
    const char *part = "1.5e";
    /* An "e" without digits is not an exponent. */
    assert_ptr_equal(sy_parse_number(part, part + 4, &v), part + 3);
    assert_float_equal(v, 1.5, 0);
}

/* ---- column rules ---- */

static sy_cloud read_text(const char *text)
{
    sy_cloud c;
    sy_error err = {0};
    sy_code rc = sy_read_xyz_mem("mem.xyz", (const unsigned char *)text, strlen(text), &c, &err);
    if (rc) fail_msg("%s\n-> %s", text, err.msg);
    return c;
}

static void header_maps_columns_by_name(void **state)
{
    (void)state;
    const char *text = "# scanned with something\r\n"
                       "\r\n"
                       "//X;Y;Z;Red;Green;Blue;Intensity;treeID;label;extra\r\n"
                       "10.5;20.25;1.0;255;0;128;1200;7;3;0.5;99  \r\n"
                       "// a comment between rows\r\n"
                       "11.5 ; 21.25 ; 2.0 ; 0 ; 255 ; 1 ; 65535 ; 8 ; 4 ; 0.25 ; 98\r\n";
    sy_cloud c = read_text(text);
    assert_int_equal(c.n, 2);
    assert_float_equal(c.origin[0] + c.xyz[3], 11.5, 1e-6);
    assert_float_equal(c.origin[1] + c.xyz[1], 20.25, 1e-6);
    assert_non_null(c.rgb);
    assert_int_equal(c.rgb[0], 65535);
    assert_int_equal(c.rgb[2], 128 * 257);
    assert_int_equal(c.rgb[4], 65535);
    assert_int_equal(c.intensity[1], 65535);
    assert_float_equal(sy_cloud_attr(&c, "treeID")[1], 8, 0);
    assert_float_equal(sy_cloud_attr(&c, "label")[0], 3, 0);
    assert_float_equal(sy_cloud_attr(&c, "extra")[1], 0.25, 0);
    assert_float_equal(sy_cloud_attr(&c, "col11")[0], 99, 0); /* beyond the named columns */
    sy_cloud_free(&c);

    /* CSV with a plain header, reordered columns and normals. */
    c = read_text("label,nx,ny,nz,z,y,x\n1,0,0,1,3,2,1\n2,1,0,0,6,5,4\n");
    assert_int_equal(c.n, 2);
    assert_float_equal(c.origin[0] + c.xyz[3], 4, 0);
    assert_float_equal(c.origin[2] + c.xyz[5], 6, 0);
    assert_float_equal(c.normal[3], 1, 0);
    assert_float_equal(sy_cloud_attr(&c, "label")[1], 2, 0);
    sy_cloud_free(&c);
}

static void columns_without_header_follow_the_rules(void **state)
{
    (void)state;
    sy_cloud c = read_text("1 2 3 100\n4 5 6 65535\n");
    assert_non_null(c.intensity);
    assert_int_equal(c.intensity[1], 65535);
    sy_cloud_free(&c);

    c = read_text("1 2 3 0.5\n4 5 6 7\n");
    assert_null(c.intensity);
    assert_float_equal(sy_cloud_attr(&c, "col4")[0], 0.5, 0);
    sy_cloud_free(&c);

    c = read_text("1,2,3,255,0,10\n4,5,6,1,2,3\n");
    assert_non_null(c.rgb);
    assert_int_equal(c.rgb[0], 65535);
    assert_int_equal(c.rgb[5], 3 * 257);
    sy_cloud_free(&c);

    c = read_text("1 2 3 0 0 1\n4 5 6 0.6 0.8 0\n");
    assert_null(c.rgb);
    assert_non_null(c.normal);
    assert_float_equal(c.normal[4], 0.8f, 0);
    sy_cloud_free(&c);

    c = read_text("1 2 3 300 0 1\n4 5 6 7 8 9\n");
    assert_null(c.rgb);
    assert_null(c.normal);
    assert_float_equal(sy_cloud_attr(&c, "col4")[0], 300, 0);
    assert_float_equal(sy_cloud_attr(&c, "col6")[1], 9, 0);
    sy_cloud_free(&c);

    c = read_text("1 2 3 10 20 30 500\n4 5 6 11 21 31 600\n");
    assert_int_equal(c.rgb[3], 11 * 257);
    assert_int_equal(c.intensity[1], 600);
    sy_cloud_free(&c);

    /* PTS: a count line, then x y z intensity r g b. */
    c = read_text("2\n1 2 3 -1500 10 20 30\n4 5 6 -20 11 21 31\n");
    assert_int_equal(c.n, 2);
    assert_int_equal(c.meta.header_count, 2);
    assert_int_equal(c.rgb[5], 31 * 257);
    assert_null(c.intensity);
    assert_float_equal(sy_cloud_attr(&c, "col4")[0], -1500, 0);
    sy_cloud_free(&c);

    c = read_text("1 2 3 4 5\n");
    assert_float_equal(sy_cloud_attr(&c, "col5")[0], 5, 0);
    sy_cloud_free(&c);
}

/* ---- round trips ---- */

static void round_trip_keeps_survey_positions_and_attributes(void **state)
{
    (void)state;
    sy_cloud a, b;
    sy_error err = {0};
    size_t n = 2000;
    assert_int_equal(sy_cloud_init(&a, n, &err), SY_OK);
    a.origin[0] = 1176136.0;
    a.origin[1] = 5000100.0;
    a.origin[2] = -3.0;
    assert_int_equal(sy_cloud_add_rgb(&a, &err), SY_OK);
    assert_int_equal(sy_cloud_add_intensity(&a, &err), SY_OK);
    double *tree = sy_cloud_add_attr(&a, "treeID", &err);
    double *third = sy_cloud_add_attr(&a, "ratio", &err);
    for (size_t i = 0; i < n; i++) {
        a.xyz[3 * i] = (float)(0.0137 * (double)i);
        a.xyz[3 * i + 1] = (float)(27.5 - 0.0071 * (double)i);
        a.xyz[3 * i + 2] = (float)(0.001 * (double)(i % 500));
        for (int k = 0; k < 3; k++) a.rgb[3 * i + k] = (uint16_t)(((i * (size_t)(k + 3)) % 256) * 257);
        a.intensity[i] = (uint16_t)(i * 31);
        tree[i] = (double)(i % 17);
        third[i] = 1.0 / 3.0 * (double)i - 1e-12;
    }
    const char *path = tmp_path("round.xyz");
    assert_int_equal(sy_write_xyz(path, &a, &err), SY_OK);
    assert_int_equal(sy_read_cloud(path, &b, &err), SY_OK);
    assert_int_equal(b.n, n);
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++) {
            double wa = a.origin[k] + a.xyz[3 * i + k], wb = b.origin[k] + b.xyz[3 * i + k];
            if (fabs(wa - wb) >= 1e-4) fail_msg("point %zu axis %d: %.6f vs %.6f", i, k, wa, wb);
            assert_int_equal(b.rgb[3 * i + k], a.rgb[3 * i + k]);
        }
        assert_int_equal(b.intensity[i], a.intensity[i]);
        assert_float_equal(sy_cloud_attr(&b, "treeID")[i], tree[i], 0);
        assert_float_equal(sy_cloud_attr(&b, "ratio")[i], third[i], 0);
    }
    sy_cloud_free(&a);
    sy_cloud_free(&b);
}

/* ---- malformed input ---- */

static void expect_input_error(const char *name, const char *text, const char *words)
{
    const char *path = tmp_path(name);
    assert_int_equal(write_bytes(path, text, strlen(text)), 0);
    sy_cloud c;
    sy_error err = {0};
    sy_code rc = sy_read_cloud(path, &c, &err);
    if (rc != SY_EINPUT) fail_msg("%s: expected SY_EINPUT, got %d (%s)", name, rc, err.msg);
    if (!strstr(err.msg, path)) fail_msg("%s: message does not name the file: %s", name, err.msg);
    if (strchr(err.msg, '\n')) fail_msg("%s: message spans lines: %s", name, err.msg);
    if (words && !strstr(err.msg, words)) fail_msg("%s: message lacks '%s': %s", name, words, err.msg);
    assert_null(c.xyz);
}

static void malformed_text_is_an_input_error(void **state)
{
    (void)state;
    expect_input_error("ragged.xyz", "1 2 3\n4 5 6\n\n# c\n7 8 9 10\n", "line 5: 4 columns, expected 3");
    expect_input_error("short.xyz", "x y z\n1 2 3\n4 5\n", "line 3: 2 columns");
    expect_input_error("word.xyz", "1 2 3\n4 five 6\n", "line 2: malformed number 'five'");
    expect_input_error("dots.csv", "1,2,3\n4,5.5.5,6\n", "'5.5.5'");
    expect_input_error("two_cols.txt", "1 2\n3 4\n", "need at least 3");
    expect_input_error("nan.xyz", "1 2 3\n4 NaN 6\n", "non-finite");
    expect_input_error("inf.xyz", "1 2 3\n4 5 1e999\n", "non-finite");
    expect_input_error("header_only.xyz", "//X Y Z\n# nothing\n", "no point rows");
    expect_input_error("late_header.xyz", "1 2 3\nX Y Z\n", "line 2");
    expect_input_error("ctrl.xyz", "1 2 3\n4 5\x01 6\n", "'5?'");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(real_files_read_with_exact_counts),
        cmocka_unit_test(tree1_keeps_its_coordinates),
        cmocka_unit_test(parser_agrees_with_strtod),
        cmocka_unit_test(header_maps_columns_by_name),
        cmocka_unit_test(columns_without_header_follow_the_rules),
        cmocka_unit_test(round_trip_keeps_survey_positions_and_attributes),
        cmocka_unit_test(malformed_text_is_an_input_error),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
