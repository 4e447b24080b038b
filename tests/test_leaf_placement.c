/* Leaf cards on a QSM (stages/qsm/leaf_placement.c): density from the
 * species, counts per metre of twig, leaves sitting on the bark of their
 * twig, leaning forward along it, determinism. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/qsm/leaf_placement.h"
#include "stages/qsm/qsm.h"

static void rotate(const float q[4], const double v[3], double out[3])
{
    /* v' = v + 2w (u x v) + 2 u x (u x v), u = (x, y, z) */
    double u[3] = {q[0], q[1], q[2]}, w = q[3], t[3], c[3];
    t[0] = 2 * (u[1] * v[2] - u[2] * v[1]);
    t[1] = 2 * (u[2] * v[0] - u[0] * v[2]);
    t[2] = 2 * (u[0] * v[1] - u[1] * v[0]);
    c[0] = u[1] * t[2] - u[2] * t[1];
    c[1] = u[2] * t[0] - u[0] * t[2];
    c[2] = u[0] * t[1] - u[1] * t[0];
    for (int k = 0; k < 3; k++) out[k] = v[k] + w * t[k] + c[k];
}

static void read_qsm(sy_skeleton *s)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/real/rtwig/QSM.csv", SYLVA_DATA_DIR);
    sy_error err = {0};
    assert_int_equal(sy_skeleton_read(path, s, &err), SY_OK);
}

static void density_from_species(void **state)
{
    (void)state;
    sy_species_params sp;
    sy_error err = {0};
    assert_int_equal(sy_species_params_find("quaking_aspen", &sp, &err), SY_OK);
    sy_leaf_placement p = sy_leaf_placement_from_species(&sp, 3);
    /* Leaves 16 on a last-level stem of 13 * 0.9 * 0.3 * 0.6 m. */
    assert_true(fabs(p.per_metre - 16.0 / (13 * 0.9 * 0.3 * 0.6)) < 1e-4);
    assert_true(fabs(p.size - 0.55f) < 1e-6);
    assert_int_equal(p.max_reverse_order, 2);
    sy_species_params_free(&sp);
}

static void leaves_sit_on_their_twigs(void **state)
{
    (void)state;
    sy_skeleton s;
    read_qsm(&s);
    sy_leaf_placement p = {12.5, 0.1f, 2, 7};
    sy_leaves lv, again;
    double twigs;
    sy_error err = {0};
    assert_int_equal(sy_place_leaves(&s, &p, &lv, &twigs, &err), SY_OK);
    int32_t *rbo = calloc(s.n, sizeof *rbo);
    assert_int_equal(sy_skeleton_reverse_order(&s, rbo, &err), SY_OK);
    double expect = 0;
    for (size_t i = 1; i < s.n; i++)
        if (rbo[i] <= 2) expect += sqrt(pow(s.pos[3 * i] - s.pos[3 * s.parent[i]], 2) +
                                        pow(s.pos[3 * i + 1] - s.pos[3 * s.parent[i] + 1], 2) +
                                        pow(s.pos[3 * i + 2] - s.pos[3 * s.parent[i] + 2], 2));
    printf("rTwig QSM: %.2f m of twig (of %.2f m), %zu leaves at 12.5 / m\n", twigs, sy_skeleton_length(&s), lv.n);
    assert_true(fabs(twigs - expect) < 1e-6);
    assert_true(twigs > 0.2 * sy_skeleton_length(&s) && twigs < sy_skeleton_length(&s));
    /* Fractions carry from edge to edge: the count is the total, floored. */
    assert_true((double)lv.n <= 12.5 * twigs + 1e-6 && (double)lv.n > 12.5 * twigs - 1 - 1e-6);
    for (size_t k = 0; k < lv.n; k++) {
        int32_t i = lv.node[k], par = s.parent[i];
        assert_true(par >= 0 && rbo[i] <= 2);
        double a[3], d[3], len2 = 0, t = 0;
        for (int c = 0; c < 3; c++) {
            a[c] = s.pos[3 * par + c];
            d[c] = s.pos[3 * i + c] - a[c];
            len2 += d[c] * d[c];
            t += (lv.pos[3 * k + c] - a[c]) * d[c];
        }
        t /= len2;
        assert_true(t > -1e-3 && t < 1 + 1e-3);
        double off = 0, r = s.radius[par] + t * (s.radius[i] - s.radius[par]);
        for (int c = 0; c < 3; c++) off += pow(lv.pos[3 * k + c] - (a[c] + t * d[c]), 2);
        assert_true(fabs(sqrt(off) - r) < 1e-4); /* on the bark */
        const float *q = lv.rot + 4 * k;
        assert_true(fabs(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3] - 1) < 1e-5);
        double y[3] = {0, 1, 0}, ya[3], z[3] = {0, 0, 1}, za[3];
        rotate(q, y, ya);
        rotate(q, z, za);
        double along = (ya[0] * d[0] + ya[1] * d[1] + ya[2] * d[2]) / sqrt(len2);
        assert_true(along > 0.5 - 1e-4 && along < sqrt(3) / 2 + 1e-4);
        assert_true(za[2] >= -1e-6); /* the blade never faces the ground */
        assert_true(lv.scale[k] == 0.1f);
    }
    assert_int_equal(sy_place_leaves(&s, &p, &again, NULL, &err), SY_OK);
    assert_int_equal(again.n, lv.n);
    assert_memory_equal(again.pos, lv.pos, 3 * lv.n * sizeof(float));
    assert_memory_equal(again.rot, lv.rot, 4 * lv.n * sizeof(float));
    sy_leaves_free(&again);
    p.seed = 8;
    assert_int_equal(sy_place_leaves(&s, &p, &again, NULL, &err), SY_OK);
    assert_true(memcmp(again.pos, lv.pos, 3 * lv.n * sizeof(float)) != 0);
    sy_leaves_free(&again);
    p.per_metre = 0;
    assert_int_equal(sy_place_leaves(&s, &p, &again, NULL, &err), SY_OK);
    assert_int_equal(again.n, 0);
    p.size = 0;
    assert_int_equal(sy_place_leaves(&s, &p, &again, NULL, &err), SY_EUSAGE);
    free(rbo);
    sy_leaves_free(&lv);
    sy_skeleton_free(&s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(density_from_species),
        cmocka_unit_test(leaves_sit_on_their_twigs),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
