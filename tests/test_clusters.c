/* Clusters: the low-confidence rule, the cut, hulls (closed, outward, holding
 * their points) and the fallbacks for tiny and flat clusters. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/clusters/alpha_shape_cgal.h"
#include "stages/clusters/clusters.h"
#include "pipeline/run_tree.h"
#include "stages/skeleton/skeleton.h"
#include "synthetic_tree.h"

/* sy_mesh_bad_edges' count (the call itself must succeed). */
static size_t bad_edges(const uint32_t *tris, size_t n_tris, size_t n_verts)
{
    size_t bad = 0;
    sy_error err = {0};
    assert_int_equal(sy_mesh_bad_edges(tris, n_tris, n_verts, &bad, &err), SY_OK);
    return bad;
}


static void assert_good_hull(const sy_cluster *c, const float *xyz)
{
    assert_true(c->n_tris >= 4);
    assert_int_equal(bad_edges(c->tris, c->n_tris, c->n_verts), 0);
    assert_true(sy_mesh_signed_volume(c->verts, c->tris, c->n_tris) > 0);
    double in = sy_mesh_containment(c->verts, c->tris, c->n_tris, xyz, c->points, c->n_points, 0.01);
    assert_true(in >= 0.95);
}

static const float cube_v[24] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 0, 1, 1, 0, 1, 0, 1, 1, 1, 1, 1};
static const uint32_t cube_t[36] = {0, 2, 3, 0, 3, 1, 4, 5, 7, 4, 7, 6, 0, 1, 5, 0, 5, 4,
                                    2, 6, 7, 2, 7, 3, 0, 4, 6, 0, 6, 2, 1, 3, 7, 1, 7, 5};

static void mesh_checks_detect_open_and_flipped(void **state)
{
    (void)state;
    uint32_t t[36];
    memcpy(t, cube_t, sizeof t);
    assert_int_equal(bad_edges(t, 12, 8), 0);
    assert_float_equal(sy_mesh_signed_volume(cube_v, t, 12), 1.0, 1e-9);
    /* Inside, outside, and just outside within tolerance. */
    float pts[9] = {0.5f, 0.5f, 0.5f, 2, 2, 2, 1.005f, 0.5f, 0.5f};
    uint32_t idx[3] = {0, 1, 2};
    assert_float_equal(sy_mesh_containment(cube_v, t, 12, pts, idx, 1, 0.01), 1.0, 0);
    assert_float_equal(sy_mesh_containment(cube_v, t, 12, pts, idx + 1, 1, 0.01), 0.0, 0);
    assert_float_equal(sy_mesh_containment(cube_v, t, 12, pts, idx + 2, 1, 0.01), 1.0, 0);
    assert_float_equal(sy_mesh_containment(cube_v, t, 12, pts, idx + 2, 1, 0.001), 0.0, 0);
    /* One flipped triangle, then one missing: both break closure. */
    uint32_t s = t[1];
    t[1] = t[2];
    t[2] = s;
    assert_true(bad_edges(t, 12, 8) > 0);
    memcpy(t, cube_t, sizeof t);
    assert_true(bad_edges(t, 11, 8) > 0);
    /* Reversed everywhere: closed but inside out. */
    for (int i = 0; i < 12; i++) {
        s = t[3 * i + 1];
        t[3 * i + 1] = t[3 * i + 2];
        t[3 * i + 2] = s;
    }
    assert_int_equal(bad_edges(t, 12, 8), 0);
    assert_true(sy_mesh_signed_volume(cube_v, t, 12) < 0);
}

static void low_confidence_rule(void **state)
{
    (void)state;
    /* Points on a cylinder of radius 5 cm around a vertical edge (0,0,0) -> (0,0,1). */
    float pts[3 * 64];
    uint32_t idx[64];
    for (int i = 0; i < 64; i++) {
        double a = i * 0.7;
        pts[3 * i] = (float)(0.05 * cos(a));
        pts[3 * i + 1] = (float)(0.05 * sin(a));
        pts[3 * i + 2] = (float)(i / 64.0);
        idx[i] = (uint32_t)i;
    }
    float p[3] = {0, 0, 0}, c[3] = {0, 0, 1};
    /* Distance 0.05 against a 0.1 m diameter: a branch. */
    assert_int_equal(sy_edge_low_confidence(p, c, 0, NULL, 0, pts, idx, 64, 0.1, 1.0), 0);
    /* The same points against a 4 cm branch: spread too wide, low confidence. */
    assert_int_equal(sy_edge_low_confidence(p, c, 0, NULL, 0, pts, idx, 64, 0.04, 1.0), 1);
    /* f_s shrinks the diameter: 0.1 m * 0.4 < 0.05 m. */
    assert_int_equal(sy_edge_low_confidence(p, c, 0, NULL, 0, pts, idx, 64, 0.1, 0.4), 1);
    /* No points, no evidence against the edge. */
    assert_int_equal(sy_edge_low_confidence(p, c, 0, NULL, 0, pts, idx, 0, 0.1, 1.0), 0);

    /* Around the node, every case above is judged the same. */
    assert_int_equal(sy_edge_low_confidence(p, c, 1, NULL, 0, pts, idx, 64, 0.1, 1.0), 0);
    assert_int_equal(sy_edge_low_confidence(p, c, 1, NULL, 0, pts, idx, 64, 0.04, 1.0), 1);

    /* A tip's level set straddles the node: a thin limb (r = 1 cm) in a 14 cm
     * bin (sparse scans' bins are 4 spacings) reaches 7 cm past the tip node. The edge segment, ending at the
     * tip, sees the axial offset as spread; the ray around the node does not. */
    float thin[3 * 40];
    for (int i = 0; i < 40; i++) {
        double a = i * 0.9;
        thin[3 * i] = (float)(0.01 * cos(a));
        thin[3 * i + 1] = (float)(0.01 * sin(a));
        thin[3 * i + 2] = (float)(0.93 + 0.14 * i / 39.0);
    }
    assert_int_equal(sy_edge_low_confidence(p, c, 0, NULL, 0, thin, idx, 40, 0.02, 1.0), 1);
    assert_int_equal(sy_edge_low_confidence(p, c, 1, NULL, 0, thin, idx, 40, 0.02, 1.0), 0);

    /* A fork: half the points on each of two limbs leaving the child. They lie
     * far from the incoming edge but on the segments to the grandchildren. */
    float fork[3 * 64], next[6] = {0.3f, 0, 1.3f, -0.3f, 0, 1.3f};
    for (int i = 0; i < 64; i++) {
        float t = (float)(i / 2) / 32.0f, side = i % 2 ? 1.0f : -1.0f;
        fork[3 * i] = side * 0.3f * t + 0.01f;
        fork[3 * i + 1] = 0.01f;
        fork[3 * i + 2] = 1 + 0.3f * t;
    }
    assert_int_equal(sy_edge_low_confidence(p, c, 1, next, 2, fork, idx, 64, 0.05, 1.0), 0);
    assert_int_equal(sy_edge_low_confidence(p, c, 0, next, 2, fork, idx, 64, 0.05, 1.0), 1);
    /* A leaf mass: points scattered 20-40 cm around the node, off every segment. */
    float blob[3 * 64];
    for (int i = 0; i < 64; i++) {
        double a = i * 2.4, r = 0.2 + 0.2 * (i % 8) / 7.0;
        blob[3 * i] = (float)(r * cos(a));
        blob[3 * i + 1] = (float)(r * sin(a) + 0.3);
        blob[3 * i + 2] = (float)(1 + 0.1 * sin(3 * a));
    }
    assert_int_equal(sy_edge_low_confidence(p, c, 1, next, 2, blob, idx, 64, 0.05, 1.0), 1);
    assert_int_equal(sy_edge_low_confidence(p, c, 0, next, 2, blob, idx, 64, 0.05, 1.0), 1);
}

/* An airborne lobe (docs/skeleton.md 8d): returns on a crown's top, a dome
 * cap 5.6-6 m up. With a floor and an anchor its hull is a closed column
 * from the top down to the floor that also holds the anchor; seen from
 * above, its occupancy marks the cells under each return. */
static void hull_seen_from_above(void **state)
{
    (void)state;
    size_t n = 400;
    sy_cluster c = {0};
    float *xyz = malloc(3 * n * sizeof *xyz);
    c.points = malloc(n * sizeof *c.points);
    uint64_t st = 5;
    for (size_t i = 0; i < n; i++) {
        double x = 2 * syn_uniform(&st) - 1, y = 2 * syn_uniform(&st) - 1;
        xyz[3 * i] = (float)x, xyz[3 * i + 1] = (float)y;
        xyz[3 * i + 2] = (float)(6 - 0.4 * (x * x + y * y) / 2);
        c.points[i] = (uint32_t)i;
    }
    c.n_points = n;
    sy_error err = {0};
    const float anchor[3] = {0, 0, 3.5f};
    const sy_hull_floor base = {4.0, {0, 0}, 6.0, {0}}; /* no profile: a column */
    assert_int_equal(sy_cluster_build_hull(&c, xyz, 5.0, 160, 0.01, anchor, &base, NULL, NULL, &err), SY_OK);
    assert_good_hull(&c, xyz);
    double zmin = INFINITY, zmax = -INFINITY;
    for (size_t v = 0; v < c.n_verts; v++) zmin = fmin(zmin, c.verts[3 * v + 2]), zmax = fmax(zmax, c.verts[3 * v + 2]);
    assert_float_equal(zmin, 3.5, 0.02); /* the anchor, under the floor (within the hull tolerance) */
    assert_true(zmax <= 6.0 + 0.02);
    /* Without a floor or anchor the cap stays a cap. */
    assert_int_equal(sy_cluster_build_hull(&c, xyz, 5.0, 160, 0.01, NULL, NULL, NULL, NULL, &err), SY_OK);
    zmin = INFINITY;
    for (size_t v = 0; v < c.n_verts; v++) zmin = fmin(zmin, c.verts[3 * v + 2]);
    assert_true(zmin >= 5.5);
    /* Occupancy over the column: from above, every cell under a return's. */
    assert_int_equal(sy_cluster_build_hull(&c, xyz, 5.0, 160, 0.01, anchor, &base, NULL, NULL, &err), SY_OK);
    size_t set[2];
    for (int from_above = 0; from_above < 2; from_above++) {
        assert_int_equal(sy_cluster_occupancy(&c, xyz, 8, from_above, NULL, &err), SY_OK);
        size_t nb = (size_t)c.occ_dims[0] * c.occ_dims[1] * c.occ_dims[2];
        set[from_above] = 0;
        for (size_t b = 0; b < nb; b++) set[from_above] += (c.occupancy[b >> 3] >> (b & 7)) & 1;
        if (from_above) /* the lowest layer under the returns is set */
            for (int x = 0; x < c.occ_dims[0]; x++)
                for (int y = 0; y < c.occ_dims[1]; y++) {
                    int top = 0;
                    for (int z = 0; z < c.occ_dims[2]; z++) {
                        size_t b = (size_t)x + c.occ_dims[0] * ((size_t)y + c.occ_dims[1] * (size_t)z);
                        top |= (c.occupancy[b >> 3] >> (b & 7)) & 1;
                    }
                    size_t b0 = (size_t)x + c.occ_dims[0] * (size_t)y;
                    if (top) assert_true((c.occupancy[b0 >> 3] >> (b0 & 7)) & 1);
                }
    }
    assert_true(set[1] >= 3 * set[0]); /* the column under the cap, not only the cap */
    /* A crown that narrows toward its base (a dome: half as wide at the
     * floor as where the returns are): the hull's floor narrows with it,
     * to half the cap's width within a tenth, and still holds the cap. */
    double cap_w = 0, floor_w = 0;
    for (size_t v = 0; v < c.n_verts; v++)
        if (c.verts[3 * v + 2] > 5.5) cap_w = fmax(cap_w, fabs(c.verts[3 * v]));
    const sy_hull_floor dome = {4.0, {0, 0}, 6.0, {1, 1, 2, 2, 2, 2, 2, 2}};
    assert_int_equal(sy_cluster_build_hull(&c, xyz, 5.0, 160, 0.01, NULL, &dome, NULL, NULL, &err), SY_OK);
    assert_good_hull(&c, xyz);
    for (size_t v = 0; v < c.n_verts; v++)
        if (c.verts[3 * v + 2] < 4.05) floor_w = fmax(floor_w, fabs(c.verts[3 * v]));
    if (!(fabs(floor_w - 0.5 * cap_w) < 0.1 * cap_w))
        fail_msg("floor half-width %.3f m against the cap's %.3f m (want half)", floor_w, cap_w);
    free(c.points), free(c.verts), free(c.tris), free(c.occupancy), free(xyz);
}

static void alpha_shape_of_a_ball(void **state)
{
    (void)state;
    size_t n = 2000;
    sy_cluster c = {0};
    float *xyz = malloc(3 * n * sizeof *xyz);
    c.points = malloc(n * sizeof *c.points);
    uint64_t st = 9;
    for (size_t i = 0; i < n; i++) {
        double p[3];
        do {
            for (int k = 0; k < 3; k++) p[k] = 2 * syn_uniform(&st) - 1;
        } while (p[0] * p[0] + p[1] * p[1] + p[2] * p[2] > 1);
        for (int k = 0; k < 3; k++) xyz[3 * i + k] = (float)(0.4 * p[k] + (k == 2 ? 5 : 1));
        c.points[i] = (uint32_t)i;
    }
    c.n_points = n;
    sy_error err = {0};
    assert_int_equal(sy_cluster_build_hull(&c, xyz, 5.0, 60, 0.01, NULL, NULL, NULL, NULL, &err), SY_OK);
    assert_int_equal(c.hull, SY_HULL_ALPHA);
    assert_true(c.alpha > 0);
    assert_true(c.n_tris <= 120); /* simplified toward the budget */
    assert_good_hull(&c, xyz);
    /* CGAL's alpha is a squared radius: alpha = 5 * alpha_min exactly. */
    sy_alpha_mesh m;
    sy_error shape_err = {0};
    assert_int_equal(sy_alpha_shape_boundary(xyz, n, 5.0, &m, &shape_err), SY_OK);
    assert_float_equal(m.alpha, 5.0 * m.alpha_min, 1e-12 * m.alpha);
    assert_int_equal(bad_edges(m.tris, m.n_tris, m.n_verts), 0);
    assert_true(sy_mesh_signed_volume(m.verts, m.tris, m.n_tris) > 0);
    sy_alpha_mesh_free(&m);
    /* Flat input: CGAL refuses, the builder falls back to a padded box. */
    for (size_t i = 0; i < n; i++) xyz[3 * i + 2] = 5;
    assert_int_equal(sy_alpha_shape_boundary(xyz, n, 5.0, &m, &shape_err), SY_EINPUT);
    assert_non_null(strstr(shape_err.msg, "dimensions"));
    assert_int_equal(sy_cluster_build_hull(&c, xyz, 5.0, 60, 0.01, NULL, NULL, NULL, NULL, &err), SY_OK);
    assert_int_equal(c.hull, SY_HULL_BOX);
    assert_good_hull(&c, xyz);
    /* Three points: a box too. */
    c.n_points = 3;
    assert_int_equal(sy_cluster_build_hull(&c, xyz, 5.0, 60, 0.01, NULL, NULL, NULL, NULL, &err), SY_OK);
    assert_int_equal(c.hull, SY_HULL_BOX);
    assert_good_hull(&c, xyz);
    free(c.points);
    free(c.verts);
    free(c.tris);
    free(xyz);
}

static void foliage_becomes_clusters(void **state)
{
    (void)state;
    syn_tree t;
    syn_tree_make(&t, 1, 1);
    sy_cloud cloud;
    sy_error err = {0};
    assert_int_equal(syn_sample(&t, 40000, 0.4, 0.002, 21, &cloud, &err), SY_OK);
    sy_skeleton_options o;
    o = sy_skeleton_options_default();
    sy_skeleton s;
    sy_clusters cl;
    sy_skeleton_report r;
    sy_hull_report h;
    assert_int_equal(sy_reconstruct_tree(&cloud, &o, 0, &s, &cl, &r, &h, &err), SY_OK);
    printf("foliage tree: %zu nodes, %zu clusters (%zu alpha, %zu convex, %zu box), %zu of %zu points in clusters\n",
           r.nodes, r.clusters, h.alpha, h.convex, h.box, r.cluster_points, cloud.n);
    /* Most blob points (40% of the cloud) end in clusters. */
    assert_true(cl.n >= 4);
    assert_true(r.cluster_points >= 0.3 * (double)cloud.n);
    size_t assigned = r.skeleton_points;
    for (size_t c = 0; c < cl.n; c++) {
        assert_true(cl.items[c].seed >= 0 && (size_t)cl.items[c].seed < s.n);
        assert_true(cl.items[c].n_points >= (size_t)o.min_cluster_points);
        assert_good_hull(&cl.items[c], cloud.xyz);
        assigned += cl.items[c].n_points;
    }
    assert_int_equal(assigned, cloud.n);
    sy_clusters_free(&cl);
    sy_skeleton_free(&s);

    /* Monotone in f_s: a smaller f_s never keeps more on the main skeleton. */
    o.clusters = 0;
    assert_int_equal(sy_reconstruct_tree(&cloud, &o, 0, &s, NULL, NULL, NULL, &err), SY_OK);
    int32_t *prev = malloc(s.n * sizeof *prev), *cur = malloc(s.n * sizeof *cur), *seeds = malloc(s.n * sizeof *seeds);
    double fs[4] = {0.3, 0.6, 0.9, 1.0};
    size_t last_main = 0;
    for (int f = 0; f < 4; f++) {
        size_t nc, main_nodes = 0;
        assert_int_equal(sy_clusters_cut(&s, cloud.xyz, NULL, 0, fs[f], 0, cur, seeds, &nc, &err), SY_OK);
        for (size_t i = 0; i < s.n; i++) {
            main_nodes += cur[i] < 0;
            if (f > 0 && prev[i] < 0) assert_true(cur[i] < 0);
        }
        assert_true(main_nodes >= last_main);
        last_main = main_nodes;
        memcpy(prev, cur, s.n * sizeof *cur);
    }
    free(prev);
    free(cur);
    free(seeds);
    sy_skeleton_free(&s);
    sy_cloud_free(&cloud);
}

/* Returns every 5 mm along a Y (a 0.5 m stem from the seed, two 0.64 m
 * arms), jittered by up to 3 mm: the traced twigs run along it. */
static float *twig_y(size_t *n)
{
    const float ends[3][6] = {{0, 0, 1, 0, 0, 1.5f}, {0, 0, 1.5f, 0.4f, 0, 2}, {0, 0, 1.5f, -0.4f, 0, 2}};
    float *xyz = malloc(3 * 400 * sizeof *xyz);
    size_t m = 0;
    uint64_t rng = 7;
    for (int a = 0; a < 3; a++) {
        double len = 0;
        for (int k = 0; k < 3; k++) len += (ends[a][3 + k] - ends[a][k]) * (ends[a][3 + k] - ends[a][k]);
        int steps = (int)(sqrt(len) / 0.005);
        for (int i = a ? 1 : 0; i <= steps; i++)
            for (int k = 0; k < 3; k++) {
                rng = rng * 6364136223846793005ull + 1442695040888963407ull;
                double jitter = ((double)(rng >> 11) / 9007199254740992.0 - 0.5) * 0.006;
                xyz[3 * m + k] = (float)(ends[a][k] + (ends[a][3 + k] - ends[a][k]) * i / steps + jitter);
                if (k == 2) m++;
            }
    }
    *n = m;
    return xyz;
}

/* A root at the origin, the seed node 1 m above it, and one lobe on the
 * seed holding points 0..n-1 (no hull: the twigs read only its points). */
static void root_and_lobe(size_t n, sy_skeleton *s, sy_cluster *c)
{
    sy_error err = {0};
    assert_int_equal(sy_skeleton_init(s, 0, &err), SY_OK);
    sy_skeleton_add(s, (float[3]){0, 0, 0}, 0.05f, -1, 0, 0, &err);
    sy_skeleton_add(s, (float[3]){0, 0, 1}, 0.03f, 0, 0, 0, &err);
    memset(c, 0, sizeof *c);
    c->seed = 1;
    c->points = malloc(n * sizeof *c->points);
    for (size_t i = 0; i < n; i++) c->points[i] = (uint32_t)i;
    c->n_points = n;
}

/* The twigs a lobe's returns trace: one return per voxel, each node one of
 * the returns, parents before children, hanging off the seed, the spanning
 * tree as long as the Y it traces (no chord across its fork); a smaller
 * budget coarsens the voxel, one no voxel of the ladder meets gives none;
 * the same input gives the same twigs. */
static void traced_twigs_follow_the_returns(void **state)
{
    (void)state;
    size_t n;
    float *xyz = twig_y(&n);
    const float seed[3] = {0, 0, 1};
    sy_skeleton s;
    sy_cluster c;
    sy_error err = {0};
    root_and_lobe(n, &s, &c);
    sy_clusters cl = {1, &c};
    sy_twig_options o = sy_twig_options_default();
    o.max_nodes = 1000;
    sy_twig_report r;
    assert_int_equal(sy_clusters_trace_twigs(&cl, &s, xyz, &o, &r, &err), SY_OK);
    assert_float_equal(r.voxel, o.voxel_min, 1e-9);
    assert_int_equal(r.nodes, c.n_twigs);
    assert_true(c.n_twigs >= 70 && c.n_twigs <= 1000); /* 1.78 m of Y at 2 cm voxels */
    double length = 0;
    int off_seed = 0;
    for (size_t i = 0; i < c.n_twigs; i++) {
        int found = 0;
        for (size_t j = 0; j < n && !found; j++) found = !memcmp(c.twig_pos + 3 * i, xyz + 3 * j, 3 * sizeof *xyz);
        assert_true(found);
        int32_t p = c.twig_parent[i];
        assert_true(p >= -1 && p < (int32_t)i);
        off_seed += p < 0;
        const float *q = p < 0 ? seed : c.twig_pos + 3 * (size_t)p;
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += (double)(c.twig_pos[3 * i + k] - q[k]) * (c.twig_pos[3 * i + k] - q[k]);
        length += sqrt(d2);
    }
    assert_int_equal(off_seed, 1);
    double y = 0.5 + 2 * sqrt(0.4 * 0.4 + 0.5 * 0.5);
    if (!(length > 0.9 * y && length < 1.2 * y)) fail_msg("twigs %.3f m long over a %.3f m Y", length, y);
    float *first = malloc(c.n_twigs * 3 * sizeof *first);
    int32_t *first_parent = malloc(c.n_twigs * sizeof *first_parent);
    memcpy(first, c.twig_pos, c.n_twigs * 3 * sizeof *first);
    memcpy(first_parent, c.twig_parent, c.n_twigs * sizeof *first_parent);
    size_t n_first = c.n_twigs;
    assert_int_equal(sy_clusters_trace_twigs(&cl, &s, xyz, &o, &r, &err), SY_OK);
    assert_int_equal(c.n_twigs, n_first);
    assert_memory_equal(c.twig_pos, first, n_first * 3 * sizeof *first);
    assert_memory_equal(c.twig_parent, first_parent, n_first * sizeof *first_parent);
    /* Beside an empty lobe and a one-point lobe, sharing the budget: those
     * get none and one (off the seed); the Y keeps its twigs. */
    sy_cluster three[3] = {c, {0}, {0}};
    uint32_t one = 5;
    three[1].seed = three[2].seed = 1;
    three[2].points = &one, three[2].n_points = 1;
    sy_clusters cl3 = {3, three};
    assert_int_equal(sy_clusters_trace_twigs(&cl3, &s, xyz, &o, &r, &err), SY_OK);
    assert_int_equal(three[0].n_twigs, n_first);
    assert_int_equal(three[1].n_twigs, 0);
    assert_true(three[1].twig_voxel == 0);
    assert_int_equal(three[2].n_twigs, 1);
    assert_int_equal(three[2].twig_parent[0], -1);
    assert_memory_equal(three[2].twig_pos, xyz + 15, 3 * sizeof *xyz);
    assert_int_equal(r.nodes, n_first + 1);
    c = three[0];
    sy_cluster_twigs_free(&three[2]);
    free(first_parent);
    o.max_nodes = 30;
    assert_int_equal(sy_clusters_trace_twigs(&cl, &s, xyz, &o, &r, &err), SY_OK);
    assert_true(r.voxel > o.voxel_min && c.n_twigs <= 30 && c.n_twigs >= 5);
    o.max_nodes = 3; /* 1.78 m at 0.25 m voxels is still more than three */
    assert_int_equal(sy_clusters_trace_twigs(&cl, &s, xyz, &o, &r, &err), SY_OK);
    assert_int_equal(c.n_twigs, 0);
    assert_true(r.voxel == 0);
    sy_cluster_twigs_free(&c);
    free(first), free(c.points), free(xyz);
    sy_skeleton_free(&s);
}

/* A twig ends where its returns do: returns every 5 mm along x from the
 * seed to 0.995 m, traced at 10 cm voxels. Its tip is the last voxel's
 * return farthest from the node it hangs from (stop 49); the return
 * nearest the voxel's middle stood 4.5 cm short, at 0.950 m. */
static void traced_twig_tips_reach_the_last_return(void **state)
{
    (void)state;
    size_t n = 200;
    float *xyz = malloc(3 * n * sizeof *xyz);
    for (size_t i = 0; i < n; i++) xyz[3 * i] = 0.005f * (float)i, xyz[3 * i + 1] = 0.001f, xyz[3 * i + 2] = 1;
    sy_skeleton s;
    sy_cluster c;
    sy_error err = {0};
    root_and_lobe(n, &s, &c);
    sy_clusters cl = {1, &c};
    sy_twig_options o = sy_twig_options_default();
    o.voxel_min = o.voxel_max = 0.1;
    o.max_nodes = 100;
    sy_twig_report r;
    assert_int_equal(sy_clusters_trace_twigs(&cl, &s, xyz, &o, &r, &err), SY_OK);
    assert_int_equal(c.n_twigs, 10);
    double far = 0;
    for (size_t i = 0; i < c.n_twigs; i++) far = fmax(far, c.twig_pos[3 * i]);
    printf("# the twig reaches x = %.3f m, its last return 0.995 m\n", far);
    assert_float_equal(far, 0.995, 1e-6);
    sy_cluster_twigs_free(&c);
    free(c.points), free(xyz);
    sy_skeleton_free(&s);
}

/* A terrestrial crown's hidden top (docs/synthesize.md "Stop 46"): a dome
 * of returns 4-6 m up whose top quadrant x, y > 0 the stations missed
 * below 5 m (a notch 1-1.5 m deep). The roof closes the notch to within a
 * cell's slope of the dome, the notch stands further under it than the
 * whole dome does, a return on the notch's floor reaches up to the roof and
 * one inside the crown does not; a lobe of the notch's returns is hulled
 * up to the roof and its occupancy marks the cells between. */
static double dome_z(double x, double y) { return 6 - 2 * (x * x + y * y) / 8; }

static void roof_over_a_notched_top(void **state)
{
    (void)state;
    size_t n = 6000, m = 0;
    float *dome = malloc(3 * n * sizeof *dome), *notched = malloc(3 * n * sizeof *notched);
    uint64_t st = 9;
    for (size_t i = 0; i < n; i++) {
        double x = 4 * syn_uniform(&st) - 2, y = 4 * syn_uniform(&st) - 2, z = dome_z(x, y);
        dome[3 * i] = (float)x, dome[3 * i + 1] = (float)y, dome[3 * i + 2] = (float)z;
        if (x > 0.25 && y > 0.25 && x < 1.75 && y < 1.75) z = fmin(z, 4.5);
        notched[3 * m] = (float)x, notched[3 * m + 1] = (float)y, notched[3 * m + 2] = (float)z, m++;
    }
    sy_error err = {0};
    sy_crown_roof whole, roof;
    assert_int_equal(sy_crown_roof_build(dome, n, 16, 0.05, &whole, &err), SY_OK);
    assert_int_equal(sy_crown_roof_build(notched, m, 16, 0.05, &roof, &err), SY_OK);
    /* The notch's centre (1, 1): the dome stands at 5.5 there. */
    float floor_pt[3] = {1.0f, 1.0f, 4.5f}, inner[3] = {1.0f, 1.0f, 3.0f};
    double up = sy_crown_roof_lift(&roof, floor_pt);
    if (!(fabs(up - dome_z(1, 1)) < 0.15)) fail_msg("roof over the notch at %.3f m, the dome at %.3f m", up, dome_z(1, 1));
    assert_true(isnan(sy_crown_roof_lift(&roof, inner)));
    assert_true(isnan(sy_crown_roof_lift(&whole, floor_pt))); /* no notch, nothing to reach */
    double g_whole = sy_crown_roof_gap(&whole), g_notched = sy_crown_roof_gap(&roof);
    if (!(g_whole < 0.01 && g_notched > 3 * g_whole + 0.01))
        fail_msg("gaps: whole dome %.4f, notched %.4f", g_whole, g_notched);
    /* A lobe of the notch's floor: hulled up to the roof. */
    sy_cluster c = {0};
    c.points = malloc(m * sizeof *c.points);
    for (size_t i = 0; i < m; i++) {
        const float *p = notched + 3 * i;
        if (p[0] > 0.5f && p[1] > 0.5f && p[0] < 1.5f && p[1] < 1.5f) c.points[c.n_points++] = (uint32_t)i;
    }
    int lifted = 0;
    assert_int_equal(sy_cluster_build_hull(&c, notched, 5.0, 160, 0.01, NULL, NULL, &roof, &lifted, &err), SY_OK);
    assert_good_hull(&c, notched);
    assert_true(lifted > 0);
    double zmax = -INFINITY;
    for (size_t v = 0; v < c.n_verts; v++) zmax = fmax(zmax, c.verts[3 * v + 2]);
    if (!(zmax > 5.3)) fail_msg("the lobe's hull reaches %.3f m, its roof 5.5-5.9 m", zmax);
    size_t set[2];
    for (int with_roof = 0; with_roof < 2; with_roof++) {
        assert_int_equal(sy_cluster_occupancy(&c, notched, 8, 0, with_roof ? &roof : NULL, &err), SY_OK);
        size_t nb = (size_t)c.occ_dims[0] * c.occ_dims[1] * c.occ_dims[2];
        set[with_roof] = 0;
        for (size_t b = 0; b < nb; b++) set[with_roof] += (c.occupancy[b >> 3] >> (b & 7)) & 1;
    }
    assert_true(set[1] >= 3 * set[0]); /* the cells up to the roof, not only the floor's */
    sy_crown_roof_free(&whole), sy_crown_roof_free(&roof);
    free(c.points), free(c.verts), free(c.tris), free(c.occupancy), free(dome), free(notched);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(traced_twigs_follow_the_returns),
        cmocka_unit_test(traced_twig_tips_reach_the_last_return),
        cmocka_unit_test(mesh_checks_detect_open_and_flipped),
        cmocka_unit_test(low_confidence_rule),
        cmocka_unit_test(alpha_shape_of_a_ball),
        cmocka_unit_test(hull_seen_from_above),
        cmocka_unit_test(roof_over_a_notched_top),
        cmocka_unit_test(foliage_becomes_clusters),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
