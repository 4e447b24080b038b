/* Core plumbing: cloud arrays, filtering, bounds, atomic writes, JSON. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/cloud.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/core/parallel.h"
#include "stages/core/rng.h"
#include "stages/core/sort.h"
#include "stages/core/texture.h"

static void filter_keeps_every_array_aligned(void **state)
{
    (void)state;
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_cloud_init(&c, 5, &err), SY_OK);
    assert_int_equal(sy_cloud_add_intensity(&c, &err), SY_OK);
    double *id = sy_cloud_add_attr(&c, "treeID", &err);
    assert_non_null(id);
    for (int i = 0; i < 5; i++) {
        c.xyz[3 * i] = (float)i;
        c.intensity[i] = (uint16_t)(100 + i);
        id[i] = 10 + i;
    }
    uint8_t keep[5] = {1, 0, 1, 0, 1};
    assert_int_equal(sy_cloud_filter(&c, keep, &err), SY_OK);
    assert_int_equal(c.n, 3);
    assert_float_equal(c.xyz[3], 2.0f, 0);
    assert_int_equal(c.intensity[2], 104);
    assert_float_equal(sy_cloud_attr(&c, "treeID")[1], 12.0, 0);
    char names[256];
    sy_cloud_attribute_names(&c, names, sizeof names);
    assert_string_equal(names, "xyz,intensity,treeID");
    sy_cloud_free(&c);
}

/* Labels by name from standard fields and extra bytes alike. */
static void scalars_by_field_name(void **state)
{
    (void)state;
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(sy_cloud_init(&c, 3, &err), SY_OK);
    assert_int_equal(sy_cloud_add_classification(&c, &err), SY_OK);
    assert_int_equal(sy_cloud_add_rgb(&c, &err), SY_OK);
    double *id = sy_cloud_add_attr(&c, "treeID", &err);
    for (int i = 0; i < 3; i++) {
        c.classification[i] = (uint8_t)(2 + 3 * i);
        for (int k = 0; k < 3; k++) c.rgb[3 * i + k] = (uint16_t)(1000 * k + i);
        id[i] = 7 - i;
    }
    double *v;
    assert_int_equal(sy_cloud_scalar(&c, "classification", &v, &err), SY_OK);
    assert_non_null(v);
    assert_true(v[0] == 2 && v[1] == 5 && v[2] == 8);
    free(v);
    assert_int_equal(sy_cloud_scalar(&c, "blue", &v, &err), SY_OK);
    assert_true(v[0] == 2000 && v[2] == 2002);
    free(v);
    assert_int_equal(sy_cloud_scalar(&c, "treeID", &v, &err), SY_OK);
    assert_true(v[0] == 7 && v[2] == 5);
    free(v);
    /* Absent fields: no values, no error (the caller names what exists). */
    assert_int_equal(sy_cloud_scalar(&c, "intensity", &v, &err), SY_OK);
    assert_null(v);
    assert_int_equal(sy_cloud_scalar(&c, "nope", &v, &err), SY_OK);
    assert_null(v);
    sy_cloud_free(&c);
}

static void rebase_keeps_world_positions(void **state)
{
    (void)state;
    sy_cloud c;
    sy_error err = {0};
    sy_cloud_init(&c, 2, &err);
    c.origin[0] = 1176000.0;
    c.xyz[0] = 136.25f;
    c.xyz[3] = 142.5f;
    sy_cloud_rebase(&c);
    double lo[3], hi[3];
    sy_cloud_bounds(&c, lo, hi);
    assert_float_equal(lo[0], 1176136.25, 1e-9);
    assert_float_equal(hi[0], 1176142.5, 1e-9);
    assert_float_equal(c.origin[0], 1176136.0, 0);
    sy_cloud_free(&c);
}

static void atomic_write_leaves_nothing_on_abort(void **state)
{
    (void)state;
    const char *dir = tmp_path("atomic");
    char cmd[4200];
    snprintf(cmd, sizeof cmd, "mkdir -p %s", dir);
    assert_int_equal(system(cmd), 0);
    char path[4200];
    snprintf(path, sizeof path, "%s/out.bin", dir);
    sy_atomic_file f;
    sy_error err = {0};
    assert_int_equal(sy_atomic_open(&f, path, &err), SY_OK);
    fputs("half", f.fp);
    sy_atomic_abort(&f);
    assert_int_equal(dir_entry_count(dir), 0);
    assert_int_equal(sy_write_file_atomic(path, "whole", 5, &err), SY_OK);
    assert_int_equal(dir_entry_count(dir), 1);
    sy_buffer b;
    assert_int_equal(sy_read_file(path, &b, &err), SY_OK);
    assert_int_equal(b.size, 5);
    sy_buffer_free(&b);
    /* A directory is refused with its name in the message. */
    assert_int_equal(sy_read_file(dir, &b, &err), SY_EINPUT);
    assert_non_null(strstr(err.msg, "directory"));
}

static void json_nests_and_escapes(void **state)
{
    (void)state;
    char *text = NULL;
    size_t len = 0;
    FILE *fp = open_memstream(&text, &len);
    sy_json j;
    sy_json_begin(&j, fp, 0);
    sy_json_object(&j, NULL);
    sy_json_string(&j, "a", "q\"x");
    sy_json_array(&j, "b");
    sy_json_int(&j, NULL, 1);
    sy_json_number(&j, NULL, NAN);
    sy_json_end(&j);
    sy_json_object(&j, "c");
    sy_json_end(&j);
    sy_json_end(&j);
    fclose(fp);
    assert_string_equal(text, "{\"a\":\"q\\\"x\",\"b\":[1,null],\"c\":{}}");
    free(text);
}

/* The arithmetic shortest decimal is the printed one: the double strtod
 * makes of sy_format_float's text, for short values, values needing all
 * nine digits, the extremes (the printing fallback) and random bit patterns
 * and scaled values over 40 decades; and it always reads back as the float. */
static void shortest_float_matches_the_printed_one(void **state)
{
    (void)state;
    const float fixed[] = {0.8f, 0.05f, 1000.0f, 1e-3f, -2.5f, 0.1f + 0.2f, 3.14159274f, 16777216.0f, 1e-38f, 3.4e38f,
                           1.4e-45f, 7.0f / 3.0f, -123456.789f};
    uint64_t rng = 11;
    for (size_t i = 0; i < 200000 + sizeof fixed / sizeof fixed[0]; i++) {
        float v;
        if (i < sizeof fixed / sizeof fixed[0]) v = fixed[i];
        else if (i % 2) {
            uint32_t bits = (uint32_t)sy_splitmix64(&rng);
            memcpy(&v, &bits, sizeof v);
            if (!isfinite(v)) continue;
        } else {
            uint64_t r = sy_splitmix64(&rng);
            v = (float)((double)(r >> 40) / (1 << 20) * pow(10, (int)(r % 41) - 20));
        }
        char buf[32];
        sy_format_float(buf, sizeof buf, v);
        double got = sy_float_shortest(v);
        assert_true((float)got == v);
        assert_true(got == strtod(buf, NULL));
    }
    assert_true(sy_float_shortest(0.8f) == 0.8);
    assert_true(isnan(sy_float_shortest(NAN)));
}

typedef struct {
    double partial[64];
} sum_ctx;

/* The selection gives the sorted array's k-th value, with the rest split
 * round it, and the quantile what a sort gives, on runs of equal values,
 * sorted and reversed input and small arrays. */
static void select_matches_a_sort(void **state)
{
    (void)state;
    uint64_t rng = 7;
    for (int trial = 0; trial < 60; trial++) {
        size_t n = trial < 20 ? (size_t)trial + 1 : 100 + 37 * (size_t)trial;
        double *v = malloc(n * sizeof *v), *w = malloc(n * sizeof *w), *x = malloc(n * sizeof *x);
        for (size_t i = 0; i < n; i++) {
            double r = (double)(sy_splitmix64(&rng) % 1000);
            v[i] = trial % 4 == 1 ? (double)i : trial % 4 == 2 ? (double)(n - i) : trial % 4 == 3 ? r / 100 : floor(r / 250);
        }
        memcpy(w, v, n * sizeof *v);
        qsort(w, n, sizeof *w, sy_cmp_double);
        size_t ks[] = {0, n / 20, n / 2, (19 * n) / 20, n - 1};
        for (int q = 0; q < 5; q++) {
            memcpy(x, v, n * sizeof *v);
            size_t k = ks[q];
            assert_true(sy_select_double(x, n, k) == w[k]);
            assert_true(x[k] == w[k]);
            for (size_t i = 0; i < n; i++) assert_true(i < k ? x[i] <= x[k] : i > k ? x[i] >= x[k] : 1);
        }
        for (double qq = 0; qq <= 1.0; qq += 0.05) {
            memcpy(x, v, n * sizeof *v);
            double pos = qq * (double)(n - 1), f = pos - floor(pos);
            size_t i = (size_t)pos;
            double want = i + 1 < n ? w[i] * (1 - f) + w[i + 1] * f : w[i];
            assert_true(sy_quantile_double(x, n, qq) == want);
        }
        free(v), free(w), free(x);
    }
    assert_true(isnan(sy_quantile_double(NULL, 0, 0.5)));
}

static void sum_chunk(void *ctx, size_t b, size_t e, size_t chunk)
{
    double s = 0;
    for (size_t i = b; i < e; i++) s += 1.0 / (1.0 + i);
    ((sum_ctx *)ctx)->partial[chunk] = s;
}

static void parallel_result_independent_of_threads(void **state)
{
    (void)state;
    double totals[2];
    for (int t = 0; t < 2; t++) {
        sy_set_threads(t ? 4 : 1);
        sum_ctx ctx = {{0}};
        sy_parallel_for(6400, 100, sum_chunk, &ctx);
        totals[t] = 0;
        for (int c = 0; c < 64; c++) totals[t] += ctx.partial[c];
    }
    assert_true(totals[0] == totals[1]);
    assert_true(totals[0] > 9.0);
}

/* Push-pull bleeding: covered texels and the channels left out keep their
 * values; every clear texel takes a blend of covered colours, the nearer
 * ones more; one colour fills the clear texels with itself, so a far mip
 * level (the image's mean) is the surface's colour. */
static void bleeding_fills_clear_texels_with_covered_colours(void **state)
{
    (void)state;
    enum { W = 37, H = 23 };
    float px[W * H * 4];
    unsigned char cov[W * H];
    sy_error err = {0};
    /* A red blob at the left, a blue one at the right, alpha 1 there, the
     * rest a stray colour (0.5, 0.3, 0.5) with alpha 0. */
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            size_t i = (size_t)y * W + (size_t)x;
            int left = (x - 4) * (x - 4) + (y - 11) * (y - 11) <= 9, right = (x - 32) * (x - 32) + (y - 11) * (y - 11) <= 9;
            cov[i] = (unsigned char)(left || right);
            float *p = px + 4 * i;
            p[0] = left ? 0.9f : 0.5f, p[1] = cov[i] ? 0.5f : 0.3f, p[2] = right ? 0.8f : 0.5f, p[3] = cov[i] ? 1.0f : 0.0f;
            if (left) p[2] = 0.1f;
            if (right) p[0] = 0.2f;
        }
    float before[W * H * 4];
    memcpy(before, px, sizeof px);
    assert_int_equal(sy_texture_bleed(px, W, H, 4, 3, cov, &err), SY_OK);
    for (size_t i = 0; i < (size_t)W * H; i++) {
        assert_float_equal(px[4 * i + 3], before[4 * i + 3], 0); /* alpha untouched */
        if (cov[i]) {
            for (int k = 0; k < 3; k++) assert_float_equal(px[4 * i + k], before[4 * i + k], 0);
            continue;
        }
        /* A blend of red (0.9, 0.5, 0.1) and blue (0.2, 0.5, 0.8): nothing of the stray left. */
        double t = (px[4 * i] - 0.9) / (0.2 - 0.9);
        assert_true(t >= -1e-5 && t <= 1 + 1e-5);
        assert_float_equal(px[4 * i + 1], 0.5, 1e-5);
        assert_float_equal(px[4 * i + 2], 0.1 + t * 0.7, 1e-4);
    }
    /* Nearer the red blob, redder. */
    assert_true(px[4 * (11 * W + 9)] > px[4 * (11 * W + 27)] + 0.3f);

    /* One colour: every clear texel is that colour; odd 1 x N sizes too. */
    float one[5 * 4] = {0};
    unsigned char c1[5] = {0, 0, 0, 1, 0};
    one[4 * 3] = 0.25f, one[4 * 3 + 1] = 0.5f, one[4 * 3 + 2] = 0.75f;
    assert_int_equal(sy_texture_bleed(one, 5, 1, 4, 3, c1, &err), SY_OK);
    for (int i = 0; i < 5; i++) {
        assert_float_equal(one[4 * i], 0.25f, 1e-6);
        assert_float_equal(one[4 * i + 2], 0.75f, 1e-6);
        assert_float_equal(one[4 * i + 3], 0.0f, 0);
    }
    /* Nothing covered: nothing changes. */
    unsigned char none[5] = {0}, u8[5 * 3] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15}, copy[15];
    memcpy(copy, u8, sizeof u8);
    assert_int_equal(sy_texture_bleed_u8(u8, 5, 1, 3, 3, none, &err), SY_OK);
    assert_memory_equal(u8, copy, sizeof u8);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(filter_keeps_every_array_aligned),
        cmocka_unit_test(scalars_by_field_name),
        cmocka_unit_test(rebase_keeps_world_positions),
        cmocka_unit_test(atomic_write_leaves_nothing_on_abort),
        cmocka_unit_test(json_nests_and_escapes),
        cmocka_unit_test(shortest_float_matches_the_printed_one),
        cmocka_unit_test(parallel_result_independent_of_threads),
        cmocka_unit_test(select_matches_a_sort),
        cmocka_unit_test(bleeding_fills_clear_texels_with_covered_colours),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
