/* Leaf card meshes (stages/mesh/leaves.c, docs/mesh.md "Leaves"): every
 * LeafShape gives a valid card (finite, UVs in [0,1], counter-clockwise
 * triangles facing +Z), and each outline is the one the table defines. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/mesh/mesh_internal.h"

#define PI 3.14159265358979323846

static const float ASPECTS[] = {0.25f, 0.6f, 1.0f, 1.7f};
#define N_ASPECTS (sizeof ASPECTS / sizeof ASPECTS[0])

static void card(int shape, float aspect, sy_mesh *m)
{
    sy_error err = {0};
    assert_int_equal(sy_leaf_card(shape, aspect, 3, m, &err), SY_OK);
    assert_string_equal(m->name, "leaf_card");
    assert_int_equal(m->material, 3);
}

static double cross2(const float *o, const float *a, const float *b)
{
    return ((double)a[0] - o[0]) * ((double)b[1] - o[1]) - ((double)a[1] - o[1]) * ((double)b[0] - o[0]);
}

/* The properties every card must have whatever its shape; returns the area. */
static double check_card(const sy_mesh *m, float aspect)
{
    assert_true(m->n_vertices >= 3);
    assert_true(m->n_indices >= 3 && m->n_indices % 3 == 0);
    for (size_t i = 0; i < m->n_vertices; i++) {
        const float *p = m->position + 3 * i, *n = m->normal + 3 * i, *t = m->tangent + 4 * i, *uv = m->uv + 2 * i;
        for (int k = 0; k < 3; k++) assert_true(isfinite(p[k]));
        assert_true(p[2] == 0);
        /* Inside the card's box: that is what keeps the UVs in [0,1]. */
        assert_true(fabsf(p[0]) <= 0.5f * aspect * (1 + 1e-5f));
        assert_true(p[1] >= 0 && p[1] <= 1);
        assert_true(n[0] == 0 && n[1] == 0 && n[2] == 1);
        assert_true(t[0] == 1 && t[1] == 0 && t[2] == 0 && t[3] == 1);
        assert_true(uv[0] >= 0 && uv[0] <= 1 && uv[1] >= 0 && uv[1] <= 1);
        /* The texture mapping every shape shares (u across the width, v = y). */
        assert_float_equal(uv[0], p[0] / aspect + 0.5f, 1e-6);
        assert_float_equal(uv[1], p[1], 1e-7);
    }
    double area = 0;
    for (size_t t = 0; t < m->n_indices; t += 3) {
        uint32_t a = m->indices[t], b = m->indices[t + 1], c = m->indices[t + 2];
        assert_true(a < m->n_vertices && b < m->n_vertices && c < m->n_vertices);
        /* Counter-clockwise seen from +Z, the way the normals point; no
         * degenerate slivers. */
        double tri = 0.5 * cross2(m->position + 3 * a, m->position + 3 * b, m->position + 3 * c);
        assert_true(tri > 1e-7 * aspect);
        area += tri;
    }
    return area;
}

/* Fans from vertex 0 (the interior centre) must go exactly once round it, so
 * the triangles tile the outline without overlapping. */
static void check_fan_turns_once(const sy_mesh *m)
{
    double turn = 0;
    const float *c = m->position;
    for (size_t t = 0; t < m->n_indices; t += 3) {
        assert_int_equal(m->indices[t], 0);
        const float *a = m->position + 3 * m->indices[t + 1], *b = m->position + 3 * m->indices[t + 2];
        double ax = a[0] - c[0], ay = a[1] - c[1], bx = b[0] - c[0], by = b[1] - c[1];
        turn += atan2(ax * by - ay * bx, ax * bx + ay * by);
    }
    assert_float_equal(turn, 2 * PI, 1e-5);
}

/* Shapes 0..3 are the outlines docs/mesh.md has described since they were
 * added: their vertices are pinned here so new shapes cannot move them. */
static double old_width(int shape, double y)
{
    switch (shape) {
    case 1: return sqrt(fmax(0, 1 - (2 * y - 1) * (2 * y - 1)));
    case 2: return sin(PI * pow(y, 0.7));
    default: return pow(fmax(0, sin(PI * y)), 1.5);
    }
}

static void shapes_0_to_3_keep_their_outlines(void **state)
{
    (void)state;
    for (size_t ai = 0; ai < N_ASPECTS; ai++) {
        float aspect = ASPECTS[ai], h = 0.5f * aspect;
        /* 0, and values outside 0..9: the quad over the whole card. */
        const int quads[] = {0, -1, 10, 1000};
        for (size_t q = 0; q < sizeof quads / sizeof quads[0]; q++) {
            sy_mesh m;
            card(quads[q], aspect, &m);
            assert_int_equal(m.n_vertices, 4);
            assert_int_equal(m.n_indices, 6);
            assert_float_equal(check_card(&m, aspect), aspect, 1e-6);
            const float want[4][2] = {{-h, 0}, {h, 0}, {h, 1}, {-h, 1}};
            for (int i = 0; i < 4; i++) {
                assert_true(m.position[3 * i] == want[i][0]);
                assert_true(m.position[3 * i + 1] == want[i][1]);
            }
            sy_mesh_free(&m);
        }
        for (int shape = 1; shape <= 3; shape++) {
            sy_mesh m;
            card(shape, aspect, &m);
            assert_int_equal(m.n_vertices, 11);
            assert_int_equal(m.n_indices, 30);
            check_card(&m, aspect);
            check_fan_turns_once(&m);
            assert_float_equal(m.position[0], 0, 0);
            assert_float_equal(m.position[1], 0.45, 1e-7);
            /* Right side stem to tip, then the left side back down. */
            for (int i = 0; i <= 5; i++) {
                const float *p = m.position + 3 * (1 + i);
                double w = (i == 0 || i == 5) ? 0 : h * old_width(shape, i / 5.0);
                assert_float_equal(p[0], w, 1e-6);
                assert_float_equal(p[1], i / 5.0, 1e-7);
            }
            for (int i = 4; i >= 1; i--) {
                const float *p = m.position + 3 * (7 + (4 - i));
                assert_float_equal(p[0], -h * old_width(shape, i / 5.0), 1e-6);
                assert_float_equal(p[1], i / 5.0, 1e-7);
            }
            sy_mesh_free(&m);
        }
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(shapes_0_to_3_keep_their_outlines),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
