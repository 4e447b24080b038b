/* The JSON DOM reader: values, escapes, errors with line/column, limits. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "stages/core/json_read.h"

static sy_jv *parse_ok(const char *text)
{
    sy_jv *v = NULL;
    sy_error err = {0};
    sy_code rc = sy_jv_parse("t.json", text, strlen(text), NULL, &v, &err);
    if (rc) fprintf(stderr, "unexpected failure: %s\n", err.msg);
    assert_int_equal(rc, SY_OK);
    assert_non_null(v);
    return v;
}

/* Parses text expecting failure; returns the message. */
static const char *parse_bad(const char *text, size_t len, const sy_jv_limits *lim)
{
    static sy_error err;
    sy_jv *v = (sy_jv *)1;
    memset(&err, 0, sizeof err);
    sy_code rc = sy_jv_parse("t.json", text, len, lim, &v, &err);
    assert_int_equal(rc, SY_EINPUT);
    assert_null(v);
    assert_null(strchr(err.msg, '\n'));
    return err.msg;
}

static void values_and_lookups(void **state)
{
    (void)state;
    sy_jv *v = parse_ok(" {\"a\": [1, -2.5e2, 0, -0, 1E-3], \"b\": {\"c\": true, \"d\": false, \"e\": null},"
                        " \"s\": \"x\", \"a\": 7}\n");
    assert_int_equal(v->type, SY_JV_OBJECT);
    assert_int_equal(sy_jv_count(v), 4);
    const sy_jv *a = sy_jv_get(v, "a"); /* first of duplicate keys */
    assert_int_equal(a->type, SY_JV_ARRAY);
    assert_int_equal(sy_jv_count(a), 5);
    double x;
    assert_true(sy_jv_number(sy_jv_at(a, 1), &x));
    assert_true(x == -250.0);
    assert_true(sy_jv_number(sy_jv_at(a, 4), &x));
    assert_true(x == 0.001);
    assert_null(sy_jv_at(a, 5));
    assert_int_equal(sy_jv_get(sy_jv_get(v, "b"), "c")->boolean, 1);
    assert_int_equal(sy_jv_get(sy_jv_get(v, "b"), "d")->type, SY_JV_BOOL);
    assert_int_equal(sy_jv_get(sy_jv_get(v, "b"), "e")->type, SY_JV_NULL);
    assert_string_equal(sy_jv_string(sy_jv_get(v, "s")), "x");
    /* Chained lookups through missing or mistyped members give NULL. */
    assert_null(sy_jv_get(sy_jv_get(v, "zz"), "c"));
    assert_null(sy_jv_at(sy_jv_get(v, "b"), 0));
    assert_false(sy_jv_number(sy_jv_get(v, "s"), &x));
    /* Positions point at the value. */
    assert_int_equal(sy_jv_get(v, "b")->line, 1);
    assert_int_equal(sy_jv_get(v, "b")->col, 39);
    sy_jv_free(v);
    v = parse_ok("[]");
    assert_int_equal(sy_jv_count(v), 0);
    sy_jv_free(v);
    v = parse_ok("\xEF\xBB\xBF 42");
    assert_true(v->type == SY_JV_NUMBER && v->number == 42);
    sy_jv_free(v);
}

static void string_escapes_decode_to_utf8(void **state)
{
    (void)state;
    sy_jv *v = parse_ok("\"q\\\" b\\\\ s\\/ \\b\\f\\n\\r\\t \\u00e9 \\u20AC \\ud83c\\udf33 \\u0000end h\xC3\xA9\"");
    const char want[] = "q\" b\\ s/ \b\f\n\r\t \xC3\xA9 \xE2\x82\xAC \xF0\x9F\x8C\xB3 \0end h\xC3\xA9";
    assert_int_equal(v->len, sizeof want - 1);
    assert_memory_equal(v->str, want, sizeof want - 1);
    sy_jv_free(v);
}

static void errors_name_line_and_column(void **state)
{
    (void)state;
    const char *m = parse_bad("{\n  \"a\": 1,\n  \"b\" 2\n}", 20, NULL);
    assert_string_equal(m, "t.json:3:7: expected ':' after object key");
    m = parse_bad("[1, 2", 5, NULL);
    assert_string_equal(m, "t.json:1:6: unexpected end of input in array");
    m = parse_bad("[1 2]", 5, NULL);
    assert_string_equal(m, "t.json:1:4: expected ',' or ']' in array");
    m = parse_bad("{\"a\":1,}", 8, NULL);
    assert_string_equal(m, "t.json:1:8: expected a string key in object");
    m = parse_bad("[1] x", 5, NULL);
    assert_string_equal(m, "t.json:1:5: unexpected data after the JSON value");
    assert_non_null(strstr(parse_bad("\"abc", 4, NULL), "unterminated string"));
    assert_non_null(strstr(parse_bad("\"a\nb\"", 5, NULL), "newline inside"));
    assert_non_null(strstr(parse_bad("\"\\x\"", 4, NULL), "invalid escape"));
    assert_non_null(strstr(parse_bad("\"\\u12G4\"", 8, NULL), "invalid hex digit"));
    assert_non_null(strstr(parse_bad("\"\\ud800\"", 8, NULL), "unpaired high surrogate"));
    assert_non_null(strstr(parse_bad("\"\\udc00\"", 8, NULL), "unpaired low surrogate"));
    assert_non_null(strstr(parse_bad("\"\xC3\"", 3, NULL), "invalid UTF-8"));
    assert_non_null(strstr(parse_bad("\"\xC0\xAF\"", 4, NULL), "invalid UTF-8")); /* overlong */
    assert_non_null(strstr(parse_bad("\"\xED\xA0\x80\"", 5, NULL), "invalid UTF-8")); /* surrogate */
    assert_non_null(strstr(parse_bad("01", 2, NULL), "unexpected data"));
    assert_non_null(strstr(parse_bad("1.", 2, NULL), "digit expected after '.'"));
    assert_non_null(strstr(parse_bad("1e+", 3, NULL), "exponent"));
    assert_non_null(strstr(parse_bad("-", 1, NULL), "invalid number"));
    assert_non_null(strstr(parse_bad("1e400", 5, NULL), "out of range"));
    assert_non_null(strstr(parse_bad("tru", 3, NULL), "a value was expected"));
    assert_non_null(strstr(parse_bad("", 0, NULL), "unexpected end of input"));
    assert_non_null(strstr(parse_bad("NaN", 3, NULL), "a value was expected"));
    /* Text is bounded by len, not by a NUL. */
    assert_non_null(strstr(parse_bad("[1, 2]", 4, NULL), "unexpected end of input"));
}

static void limits_hold(void **state)
{
    (void)state;
    char deep[600];
    memset(deep, '[', 300);
    memset(deep + 300, ']', 300);
    sy_jv_limits lim = {100, 0};
    assert_non_null(strstr(parse_bad(deep, 600, &lim), "nesting too deep"));
    assert_non_null(strstr(parse_bad(deep, 600, NULL), "nesting too deep")); /* default 256 */
    sy_jv *v = NULL;
    sy_error err = {0};
    lim.max_depth = 300;
    assert_int_equal(sy_jv_parse("t.json", deep, 600, &lim, &v, &err), SY_OK);
    sy_jv_free(v);
    sy_jv_limits small = {0, 4};
    assert_non_null(strstr(parse_bad("[1,2,3]", 7, &small), "exceeds the 4 byte limit"));
}

static void file_errors_name_the_path(void **state)
{
    (void)state;
    sy_jv *v;
    sy_error err = {0};
    const char *p = tmp_path("bad.json");
    assert_int_equal(write_bytes(p, "{\"a\": }", 7), 0);
    assert_int_equal(sy_jv_parse_file(p, &v, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "bad.json:1:7:"));
    assert_int_equal(sy_jv_parse_file(tmp_path("missing.json"), &v, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "missing.json"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(values_and_lookups),
        cmocka_unit_test(string_escapes_decode_to_utf8),
        cmocka_unit_test(errors_name_line_and_column),
        cmocka_unit_test(limits_hold),
        cmocka_unit_test(file_errors_name_the_path),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
