/* The .sylva file: round trip within the quantisation (branch orders
 * exact), byte-identical re-encoding, version 1 still read, < 40 kB per
 * scanned tree, and one-line SY_EINPUT errors for
 * every corrupted, truncated or malformed file. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/fileio.h"
#include "stages/encode/encode.h"
#include "stages/qsm/qsm.h"
#include "pipeline/run_tree.h"
#include "stages/skeleton/skeleton.h"
#include "synthetic_tree.h"
#include "xyz_text.h"

/* sy_mesh_bad_edges' count (the call itself must succeed). */
static size_t bad_edges(const uint32_t *tris, size_t n_tris, size_t n_verts)
{
    size_t bad = 0;
    sy_error err = {0};
    assert_int_equal(sy_mesh_bad_edges(tris, n_tris, n_verts, &bad, &err), SY_OK);
    return bad;
}


static uint32_t crc32_ref(const unsigned char *p, size_t n)
{
    uint32_t c = 0xffffffffu;
    for (size_t i = 0; i < n; i++) {
        c ^= p[i];
        for (int k = 0; k < 8; k++) c = (c & 1) ? (c >> 1) ^ 0xedb88320u : c >> 1;
    }
    return ~c;
}

static void reseal(unsigned char *p, size_t n)
{
    uint32_t c = crc32_ref(p, n - 4);
    for (int i = 0; i < 4; i++) p[n - 4 + i] = (unsigned char)(c >> (8 * i));
}

static void assert_one_line_input_error(sy_code rc, const sy_error *err, const char *path)
{
    assert_int_equal(rc, SY_EINPUT);
    assert_non_null(strstr(err->msg, path));
    assert_null(strchr(err->msg, '\n'));
}

/* Triangles as sorted canonical triples, for comparing hulls as sets. */
static int cmp3(const void *a, const void *b) { return memcmp(a, b, 3 * sizeof(uint32_t)) > 0 ? 1 : memcmp(a, b, 3 * sizeof(uint32_t)) < 0 ? -1 : 0; }
static uint32_t *canonical_tris(const sy_cluster *c)
{
    uint32_t *t = malloc(3 * c->n_tris * sizeof *t);
    for (size_t i = 0; i < c->n_tris; i++) {
        const uint32_t *x = c->tris + 3 * i;
        int m = x[0] <= x[1] && x[0] <= x[2] ? 0 : x[1] <= x[2] ? 1 : 2;
        for (int k = 0; k < 3; k++) {
            /* big-endian words so memcmp orders numerically */
            uint32_t v = x[(m + k) % 3];
            unsigned char *b = (unsigned char *)&t[3 * i + k];
            b[0] = (unsigned char)(v >> 24);
            b[1] = (unsigned char)(v >> 16);
            b[2] = (unsigned char)(v >> 8);
            b[3] = (unsigned char)v;
        }
    }
    qsort(t, c->n_tris, 3 * sizeof *t, cmp3);
    return t;
}

/* Encodes, checks size, decodes, compares, re-encodes. */
static void round_trip(const char *name, const sy_skeleton *s, const sy_clusters *cl)
{
    sy_error err = {0};
    const char *path = tmp_path(name);
    assert_int_equal(sy_encode_write(path, s, cl, 7, 0x1234567890abcdefULL, &err), SY_OK);
    assert_int_equal(dir_entry_count(test_tmpdir()) >= 1, 1);
    sy_buffer file;
    assert_int_equal(sy_read_file(path, &file, &err), SY_OK);
    printf("%s: %zu nodes, %zu clusters -> %zu bytes\n", name, s->n, cl->n, file.size);
    assert_true(file.size < 40000);

    sy_skeleton d;
    sy_clusters dc;
    sy_sylva_meta meta;
    assert_int_equal(sy_decode_read(path, &d, &dc, &meta, &err), SY_OK);
    assert_int_equal(meta.species_id, 7);
    assert_true(meta.seed == 0x1234567890abcdefULL);
    assert_int_equal(sy_skeleton_validate(&d, &err), SY_OK);
    assert_int_equal(d.n, s->n);
    double half = ldexp(1.0, meta.quant.step_log2) / 2 * (1 + 1e-6);
    /* The extent bound stated in the header: the step is below extent/32767. */
    assert_true(half * 2 <= 40.0 / 32767 || s->n == 0);
    double rel = (meta.quant.log2_rmax - meta.quant.log2_rmin) / 65535.0 * log(2.0) / 2 * 1.001 + 1e-6;
    for (int k = 0; k < 3; k++) assert_true(d.origin[k] == s->origin[k]);
    for (size_t i = 0; i < s->n; i++) {
        /* The reconstruction writes breadth-first order, so indices match. */
        assert_int_equal(d.parent[i], s->parent[i]);
        assert_int_equal(d.branch[i], s->branch[i]);
        assert_int_equal(d.order[i], s->order[i]);
        for (int k = 0; k < 3; k++) assert_true(fabs(d.pos[3 * i + k] - s->pos[3 * i + k]) <= half);
        assert_true(fabs(d.radius[i] / s->radius[i] - 1) <= rel);
    }
    assert_int_equal(dc.n, cl->n);
    for (size_t c = 0; c < cl->n; c++) {
        const sy_cluster *a = &cl->items[c], *b = &dc.items[c];
        assert_int_equal(a->seed, b->seed);
        assert_int_equal(a->hull, b->hull);
        assert_int_equal(a->n_verts, b->n_verts);
        assert_int_equal(a->n_tris, b->n_tris);
        for (size_t v = 0; v < 3 * a->n_verts; v++) assert_true(fabs(a->verts[v] - b->verts[v]) <= half);
        uint32_t *ta = canonical_tris(a), *tb = canonical_tris(b);
        assert_memory_equal(ta, tb, 3 * a->n_tris * sizeof *ta);
        free(ta);
        free(tb);
        assert_int_equal(bad_edges(b->tris, b->n_tris, b->n_verts), 0);
    }
    /* Re-encoding the decoded tree with the file's own grid gives the same bytes. */
    unsigned char *again;
    size_t again_size;
    assert_int_equal(sy_encode_mem(&d, &dc, meta.species_id, meta.seed, &meta.quant, &again, &again_size, &err), SY_OK);
    assert_int_equal(again_size, file.size);
    assert_memory_equal(again, file.data, file.size);
    /* Decoding twice gives identical trees. */
    sy_skeleton d2;
    sy_clusters dc2;
    sy_sylva_meta meta2;
    assert_int_equal(sy_decode_mem(path, file.data, file.size, &d2, &dc2, &meta2, &err), SY_OK);
    assert_memory_equal(d2.pos, d.pos, 3 * d.n * sizeof *d.pos);
    assert_memory_equal(d2.radius, d.radius, d.n * sizeof *d.radius);
    free(again);
    sy_skeleton_free(&d2);
    sy_clusters_free(&dc2);
    sy_skeleton_free(&d);
    sy_clusters_free(&dc);
    sy_buffer_free(&file);
}

static void real_trees_round_trip_under_40kB(void **state)
{
    (void)state;
    const char *files[] = {"real/adtree/tree1.xyz", "real/adtree/tree7.xyz", "real/adtree/tree13.xyz"};
    const char *names[] = {"tree1.sylva", "tree7.sylva", "tree13.sylva"};
    for (int f = 0; f < 3; f++) {
        sy_cloud c;
        assert_int_equal(load_xyz(data_path(files[f]), &c), 0);
        sy_skeleton_options o;
        o = sy_skeleton_options_default();
        sy_skeleton s;
        sy_clusters cl;
        sy_error err = {0};
        assert_int_equal(sy_reconstruct_tree(&c, &o, 0, &s, &cl, NULL, NULL, &err), SY_OK);
        round_trip(names[f], &s, &cl);
        sy_clusters_free(&cl);
        sy_skeleton_free(&s);
        sy_cloud_free(&c);
    }
}

/* The twigs' room beside the hulls as built: none without clusters or
 * when the hulls fill the file, less by 6.5 / 4.1 nodes for every triangle
 * a hull keeps over its budget, at most about 16 kB of nodes. */
static void twig_room_counts_the_hulls_as_built(void **state)
{
    (void)state;
    assert_int_equal(sy_sylva_twig_room(NULL, 100), 0);
    sy_clusters none = {0};
    assert_int_equal(sy_sylva_twig_room(&none, 100), 0);
    sy_cluster items[100];
    memset(items, 0, sizeof items);
    sy_clusters cl = {100, items};
    for (int c = 0; c < 100; c++) items[c].n_tris = 24;
    size_t room24 = sy_sylva_twig_room(&cl, 1500);
    for (int c = 0; c < 100; c++) items[c].n_tris = 32;
    size_t room32 = sy_sylva_twig_room(&cl, 1500);
    assert_true(room32 < room24);
    assert_true(fabs((double)(room24 - room32) - 800 * 6.5 / 4.1) <= 1.5);
    /* 40 kB of triangles leave nothing; a small tree is capped. */
    for (int c = 0; c < 100; c++) items[c].n_tris = 62;
    assert_int_equal(sy_sylva_twig_room(&cl, 600), 0);
    for (int c = 0; c < 100; c++) items[c].n_tris = 0;
    assert_int_equal(sy_sylva_twig_room(&cl, 10), (size_t)(16000 / 4.1));
    assert_true(sy_sylva_twig_room(&cl, 10) <= sy_sylva_twig_budget(1, 10));
}

/* Lobes fit while each keeps 24 triangles and its occupancy grid beside
 * the skeleton under 36 kB: AdTree's tree1 (118 lobes, 486 nodes) and
 * Lille_11 (133, 528) do; the simulated London plane's first cut (517,
 * 824) and the Lombardy poplar's at 0.39 (197, 558) do not. */
static void lobes_fit_at_24_triangles_a_hull(void **state)
{
    (void)state;
    assert_true(sy_sylva_lobes_fit(118, 486));
    assert_true(sy_sylva_lobes_fit(133, 528));
    assert_false(sy_sylva_lobes_fit(517, 824));
    assert_false(sy_sylva_lobes_fit(197, 558));
    assert_true(sy_sylva_lobes_fit(0, 10));
    assert_false(sy_sylva_lobes_fit(1, 4000)); /* the skeleton alone fills the file */
    /* The edge: (36000 - 64 - 10 n_nodes) / (24 x 6.5 + 70) lobes. */
    size_t edge = (size_t)((36000.0 - 64 - 10 * 500) / (24 * 6.5 + 70));
    assert_true(sy_sylva_lobes_fit(edge, 500));
    assert_false(sy_sylva_lobes_fit(edge + 1, 500));
    /* Lobes that fit leave each hull at least the budget twigs assume. */
    assert_true(sy_sylva_hull_budget(edge, 500, 0) >= 24);
}

static void synthetic_tree_round_trips(void **state)
{
    (void)state;
    syn_tree t;
    syn_tree_make(&t, 1, 1);
    sy_cloud c;
    sy_error err = {0};
    assert_int_equal(syn_sample(&t, 20000, 0.4, 0.002, 4, &c, &err), SY_OK);
    c.origin[0] = 1.17e6; /* survey coordinates survive in the double origin */
    c.origin[1] = -4.2e5;
    sy_skeleton_options o;
    o = sy_skeleton_options_default();
    sy_skeleton s;
    sy_clusters cl;
    assert_int_equal(sy_reconstruct_tree(&c, &o, 0, &s, &cl, NULL, NULL, &err), SY_OK);
    round_trip("synthetic.sylva", &s, &cl);
    /* Same input, same bytes, whatever ran before in the process (CGAL's
     * facet order follows heap addresses; the hull builder must not). */
    unsigned char *a, *b;
    size_t na, nb;
    assert_int_equal(sy_encode_mem(&s, &cl, 0, 1, NULL, &a, &na, &err), SY_OK);
    sy_clusters_free(&cl);
    sy_skeleton_free(&s);
    assert_int_equal(sy_reconstruct_tree(&c, &o, 0, &s, &cl, NULL, NULL, &err), SY_OK);
    assert_int_equal(sy_encode_mem(&s, &cl, 0, 1, NULL, &b, &nb, &err), SY_OK);
    assert_int_equal(na, nb);
    assert_memory_equal(a, b, na);
    free(a);
    free(b);
    sy_clusters_free(&cl);
    sy_skeleton_free(&s);
    sy_cloud_free(&c);
}

/* A small valid file to damage: a 3-node skeleton and one tetrahedron. */
static unsigned char *tiny_file(size_t *size)
{
    sy_skeleton s;
    sy_error err = {0};
    assert_int_equal(sy_skeleton_init(&s, 0, &err), SY_OK);
    float p0[3] = {0, 0, 0}, p1[3] = {0, 0, 1}, p2[3] = {0.3f, 0, 1.4f};
    sy_skeleton_add(&s, p0, 0.1f, -1, 0, 0, &err);
    sy_skeleton_add(&s, p1, 0.08f, 0, 0, 0, &err);
    sy_skeleton_add(&s, p2, 0.02f, 1, 1, 1, &err);
    sy_cluster cc = {0};
    float v[12] = {0, 0, 1, 1, 0, 1, 0, 1, 1, 0, 0, 2};
    uint32_t tr[12] = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2};
    cc.seed = 1;
    cc.verts = v;
    cc.n_verts = 4;
    cc.tris = tr;
    cc.n_tris = 4;
    sy_clusters cl = {1, &cc};
    assert_true(sy_mesh_signed_volume(v, tr, 4) > 0);
    unsigned char *data;
    assert_int_equal(sy_encode_mem(&s, &cl, 3, 99, NULL, &data, size, &err), SY_OK);
    sy_skeleton_free(&s);
    return data;
}

/* The tiny file's branch-order bytes (version 2): after the 64-byte header,
 * the node count and its three nodes (8, 1 + 8, 1 + 8 bytes), one a branch. */
enum { TINY_ORDERS_AT = 64 + 1 + 8 + 9 + 9, TINY_BRANCHES = 2 };

/* Version 1 files (no branch orders) still read, their orders derived from
 * the branch starts; a stored order out of 0..255 is refused. */
static void version1_files_still_read(void **state)
{
    (void)state;
    size_t size;
    unsigned char *v2 = tiny_file(&size);
    assert_int_equal(v2[4], 4);
    /* Both branches follow the derived rule: each order is stored as 0. */
    assert_int_equal(v2[TINY_ORDERS_AT], 0);
    assert_int_equal(v2[TINY_ORDERS_AT + 1], 0);
    unsigned char *v1 = malloc(size);
    memcpy(v1, v2, TINY_ORDERS_AT);
    memcpy(v1 + TINY_ORDERS_AT, v2 + TINY_ORDERS_AT + TINY_BRANCHES, size - TINY_ORDERS_AT - TINY_BRANCHES);
    size_t size1 = size - TINY_BRANCHES;
    /* Version 3's occupancy (0 0 0: none) and version 4's twig count (0)
     * before the checksum: version 1 has neither. */
    assert_int_equal(v1[size1 - 8] | v1[size1 - 7] | v1[size1 - 6] | v1[size1 - 5], 0);
    memmove(v1 + size1 - 8, v1 + size1 - 4, 4);
    size1 -= 4;
    v1[4] = 1;
    reseal(v1, size1);
    sy_skeleton a, b;
    sy_clusters ca, cb;
    sy_sylva_meta ma, mb;
    sy_error err = {0};
    assert_int_equal(sy_decode_mem("v2.sylva", v2, size, &a, &ca, &ma, &err), SY_OK);
    assert_int_equal(sy_decode_mem("v1.sylva", v1, size1, &b, &cb, &mb, &err), SY_OK);
    assert_int_equal(b.n, 3);
    assert_memory_equal(a.order, b.order, 3 * sizeof *a.order);
    assert_memory_equal(a.pos, b.pos, 9 * sizeof *a.pos);
    assert_int_equal(b.order[2], 1);
    assert_int_equal(cb.n, 1);
    sy_skeleton_free(&a);
    sy_skeleton_free(&b);
    sy_clusters_free(&ca);
    sy_clusters_free(&cb);
    /* zigzag 1 = -1: the root's order would be -1. */
    v2[TINY_ORDERS_AT] = 1;
    reseal(v2, size);
    sy_code rc = sy_decode_mem("neg.sylva", v2, size, &a, &ca, &ma, &err);
    assert_one_line_input_error(rc, &err, "neg.sylva");
    assert_non_null(strstr(err.msg, "branch order"));
    free(v1);
    free(v2);
}

/* Version 4: a cluster's traced twigs come back on their grid (a quarter of
 * their voxel) with the same parents, its occupancy derived from them in
 * place of the bits it no longer stores, and re-encode to the same bytes;
 * a parent link past the seed is refused. */
static void twigs_round_trip(void **state)
{
    (void)state;
    sy_skeleton s;
    sy_error err = {0};
    assert_int_equal(sy_skeleton_init(&s, 0, &err), SY_OK);
    float p0[3] = {0, 0, 0}, p1[3] = {0, 0, 1};
    sy_skeleton_add(&s, p0, 0.1f, -1, 0, 0, &err);
    sy_skeleton_add(&s, p1, 0.08f, 0, 0, 0, &err);
    float v[12] = {-0.5f, -0.5f, 1, 0.5f, -0.5f, 1, -0.5f, 0.5f, 1, 0, 0, 2};
    uint32_t tr[12] = {0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2};
    /* A fork: 0 -> 1 -> 2 on one arm, 3 off node 0, 4 off the seed. */
    float tw[15] = {0.05f, 0, 1.1f, 0.1f, 0.01f, 1.2f, 0.15f, 0, 1.3f, -0.05f, 0.02f, 1.2f, 0, -0.1f, 1.05f};
    int32_t par[5] = {-1, 0, 1, 0, -1};
    uint8_t occ[1] = {0xff};
    sy_cluster cc = {0};
    cc.seed = 1, cc.verts = v, cc.n_verts = 4, cc.tris = tr, cc.n_tris = 4;
    cc.occ_dims[0] = cc.occ_dims[1] = cc.occ_dims[2] = 2, cc.occupancy = occ;
    cc.n_twigs = 5, cc.twig_pos = tw, cc.twig_parent = par, cc.twig_voxel = 0.04f;
    sy_clusters cl = {1, &cc};
    unsigned char *a, *b;
    size_t na, nb;
    assert_int_equal(sy_encode_mem(&s, &cl, 3, 99, NULL, &a, &na, &err), SY_OK);
    assert_int_equal(a[4], 4);
    sy_skeleton d;
    sy_clusters dc;
    sy_sylva_meta m;
    assert_int_equal(sy_decode_mem("t.sylva", a, na, &d, &dc, &m, &err), SY_OK);
    assert_int_equal(dc.n, 1);
    const sy_cluster *c = &dc.items[0];
    assert_int_equal(c->n_twigs, 5);
    assert_memory_equal(c->twig_parent, par, sizeof par);
    /* The grid: the largest power-of-two multiple of the position step
     * under a quarter of the voxel; every node within half a cell a side. */
    double cell = c->twig_voxel / 4;
    assert_true(cell <= 0.01 + 1e-9 && cell > 0.005);
    for (int i = 0; i < 15; i++) assert_float_equal(c->twig_pos[i], tw[i], 0.5 * cell + 1e-6);
    /* The occupancy comes from the twigs: set in every node's own cell, and
     * not in a cell more than a voxel from every node. */
    assert_non_null(c->occupancy);
    size_t cells = (size_t)c->occ_dims[0] * c->occ_dims[1] * c->occ_dims[2], set = 0;
    float lo[3] = {-0.5f, -0.5f, 1}, hi[3] = {0.5f, 0.5f, 2};
    for (int z = 0; z < c->occ_dims[2]; z++)
        for (int y = 0; y < c->occ_dims[1]; y++)
            for (int x = 0; x < c->occ_dims[0]; x++) {
                size_t q = (size_t)x + c->occ_dims[0] * ((size_t)y + c->occ_dims[1] * (size_t)z);
                int bit = (c->occupancy[q >> 3] >> (q & 7)) & 1, idx[3] = {x, y, z}, holds = 0, near = 0;
                set += bit;
                for (int i = 0; i < 5; i++) {
                    int in = 1, close = 1;
                    for (int k = 0; k < 3; k++) {
                        double w = (hi[k] - lo[k]) / c->occ_dims[k], a = lo[k] + idx[k] * w, p = c->twig_pos[3 * i + k];
                        in &= p >= a && p < a + w;
                        close &= p >= a - c->twig_voxel && p <= a + w + c->twig_voxel;
                    }
                    holds |= in, near |= close;
                }
                if (holds) assert_true(bit);
                if (!near) assert_false(bit);
            }
    assert_true(set >= 1 && set < cells);
    assert_int_equal(sy_encode_mem(&d, &dc, 3, 99, NULL, &b, &nb, &err), SY_OK);
    assert_int_equal(na, nb);
    assert_memory_equal(a, b, na);
    sy_skeleton_free(&d);
    sy_clusters_free(&dc);
    /* The same cluster without twigs or bits ends in its empty grid, a zero
     * twig count and the checksum: with twigs, that count's byte is the
     * twigs' (5), then their grid's shift and the first node's link (1: the
     * seed). Made 2, the link reaches before the seed. */
    cc.n_twigs = 0, cc.occupancy = NULL;
    unsigned char *bare;
    size_t nbare;
    assert_int_equal(sy_encode_mem(&s, &cl, 3, 99, NULL, &bare, &nbare, &err), SY_OK);
    size_t count_at = nbare - 5;
    assert_int_equal(bare[count_at], 0);
    assert_memory_equal(bare, a, count_at);
    assert_int_equal(a[count_at], 5);
    assert_int_equal(a[count_at + 2], 1);
    free(bare);
    unsigned char *bad = malloc(na);
    memcpy(bad, a, na);
    bad[count_at + 2] = 2;
    reseal(bad, na);
    sy_code rc = sy_decode_mem("bad.sylva", bad, na, &d, &dc, &m, &err);
    assert_one_line_input_error(rc, &err, "bad.sylva");
    assert_non_null(strstr(err.msg, "twig"));
    free(bad);
    free(a);
    free(b);
    sy_skeleton_free(&s);
}

/* rTwig's QSM: its segments run fork to fork, so rebuilding orders from
 * branch starts gave max order 17 instead of 4; version 2 stores them. */
static void qsm_branch_orders_round_trip(void **state)
{
    (void)state;
    sy_skeleton s, d;
    sy_clusters dc;
    sy_sylva_meta meta;
    sy_error err = {0};
    assert_int_equal(sy_skeleton_read(data_path("real/rtwig/QSM.csv"), &s, &err), SY_OK);
    unsigned char *data;
    size_t size;
    assert_int_equal(sy_encode_mem(&s, NULL, 0, 1, NULL, &data, &size, &err), SY_OK);
    assert_int_equal(sy_decode_mem("qsm.sylva", data, size, &d, &dc, &meta, &err), SY_OK);
    size_t branches = (size_t)sy_skeleton_branch_count(&s);
    printf("QSM.csv: %zu nodes, %zu branches -> %zu bytes\n", s.n, branches, size);
    /* 8 bytes a node plus its parent link; orders add about a byte a branch. */
    assert_true(size < 10 * s.n + 2 * branches + 100);
    assert_int_equal(d.n, s.n);
    /* The encoder renumbers nodes breadth-first: match them by position
     * (the 2^-14 m grid puts each within 31 microns of its original). */
    double half = ldexp(1.0, meta.quant.step_log2) / 2 * (1 + 1e-6);
    int max_order = 0;
    for (size_t i = 0; i < d.n; i++) {
        size_t best = 0;
        double bd = INFINITY;
        for (size_t j = 0; j < s.n; j++) {
            double e = 0;
            for (int k = 0; k < 3; k++) e = fmax(e, fabs((double)d.pos[3 * i + k] - s.pos[3 * j + k]));
            if (e < bd) bd = e, best = j;
        }
        assert_true(bd <= half);
        assert_int_equal(d.order[i], s.order[best]);
        if (d.order[i] > max_order) max_order = d.order[i];
    }
    assert_int_equal(max_order, 4);
    free(data);
    sy_skeleton_free(&s);
    sy_skeleton_free(&d);
    sy_clusters_free(&dc);
}

static void damaged_files_fail_cleanly(void **state)
{
    (void)state;
    size_t size;
    unsigned char *good = tiny_file(&size);
    unsigned char *buf = malloc(size + 16);
    sy_skeleton s;
    sy_clusters cl;
    sy_sylva_meta meta;
    sy_error err = {0};
    const char *name = "damaged.sylva";
    assert_int_equal(sy_decode_mem(name, good, size, &s, &cl, &meta, &err), SY_OK);
    assert_int_equal(s.n, 3);
    assert_int_equal(cl.n, 1);
    assert_int_equal(meta.species_id, 3);
    sy_skeleton_free(&s);
    sy_clusters_free(&cl);
    /* Every truncation. */
    for (size_t n = 0; n < size; n++)
        assert_one_line_input_error(sy_decode_mem(name, good, n, &s, &cl, &meta, &err), &err, name);
    /* Every single-bit flip is caught (by the checksum or the header checks). */
    for (size_t i = 0; i < size; i++)
        for (int bit = 0; bit < 8; bit++) {
            memcpy(buf, good, size);
            buf[i] ^= (unsigned char)(1 << bit);
            assert_one_line_input_error(sy_decode_mem(name, buf, size, &s, &cl, &meta, &err), &err, name);
        }
    /* Damage behind a valid checksum: the structural checks must catch it. */
    const size_t payload = 64;
    memcpy(buf, good, size);
    buf[payload] = 0xff; /* node count: an unterminated varint */
    reseal(buf, size);
    assert_one_line_input_error(sy_decode_mem(name, buf, size, &s, &cl, &meta, &err), &err, name);
    memcpy(buf, good, size);
    buf[payload] = 100; /* more nodes than the bytes can hold */
    reseal(buf, size);
    assert_one_line_input_error(sy_decode_mem(name, buf, size, &s, &cl, &meta, &err), &err, name);
    memcpy(buf, good, size);
    buf[payload + 1 + 8] = 0x7f; /* node 1's parent delta far beyond its index */
    reseal(buf, size);
    assert_one_line_input_error(sy_decode_mem(name, buf, size, &s, &cl, &meta, &err), &err, name);
    memcpy(buf, good, size);
    buf[4] = 9; /* version */
    reseal(buf, size);
    assert_one_line_input_error(sy_decode_mem(name, buf, size, &s, &cl, &meta, &err), &err, name);
    assert_non_null(strstr(err.msg, "version"));
    memcpy(buf, good, size);
    buf[40] = 100; /* step 2^100 */
    reseal(buf, size);
    assert_one_line_input_error(sy_decode_mem(name, buf, size, &s, &cl, &meta, &err), &err, name);
    /* Trailing garbage behind a valid checksum. */
    memcpy(buf, good, size - 4);
    memset(buf + size - 4, 0, 8);
    reseal(buf, size + 4);
    assert_one_line_input_error(sy_decode_mem(name, buf, size + 4, &s, &cl, &meta, &err), &err, name);
    assert_non_null(strstr(err.msg, "unexpected bytes"));
    /* Files on disk: missing, empty, not ours. */
    assert_one_line_input_error(sy_decode_read(tmp_path("missing.sylva"), &s, &cl, &meta, &err), &err,
                                "missing.sylva");
    assert_int_equal(write_bytes(tmp_path("empty.sylva"), "", 0), 0);
    assert_one_line_input_error(sy_decode_read(tmp_path("empty.sylva"), &s, &cl, &meta, &err), &err, "empty.sylva");
    assert_int_equal(write_bytes(tmp_path("text.sylva"), "ply\nformat ascii 1.0\n", 21), 0);
    assert_one_line_input_error(sy_decode_read(tmp_path("text.sylva"), &s, &cl, &meta, &err), &err, "text.sylva");
    assert_non_null(strstr(err.msg, "not a .sylva file"));
    free(buf);
    free(good);
}

/* The header's flags: a leaf-off tree (SY_SYLVA_LEAF_OFF) round-trips with
 * its checksum rewritten and nothing else changed; a flag readers do not
 * know is refused, by the setter and, sealed into a file, by the reader. */
static void leaf_off_flag_round_trips(void **state)
{
    (void)state;
    sy_skeleton s;
    sy_error err = {0};
    assert_int_equal(sy_skeleton_init(&s, 0, &err), SY_OK);
    float p0[3] = {0, 0, 0}, p1[3] = {0, 0, 2};
    sy_skeleton_add(&s, p0, 0.1f, -1, 0, 0, &err);
    sy_skeleton_add(&s, p1, 0.05f, 0, 0, 0, &err);
    unsigned char *img, *plain;
    size_t size, plain_size;
    assert_int_equal(sy_encode_mem(&s, NULL, 3, 9, NULL, &img, &size, &err), SY_OK);
    assert_int_equal(sy_encode_mem(&s, NULL, 3, 9, NULL, &plain, &plain_size, &err), SY_OK);
    sy_skeleton d;
    sy_clusters cl;
    sy_sylva_meta meta;
    assert_int_equal(sy_decode_mem("plain", img, size, &d, &cl, &meta, &err), SY_OK);
    assert_int_equal(meta.flags, 0);
    sy_skeleton_free(&d), sy_clusters_free(&cl);
    assert_int_equal(sy_sylva_set_flags(img, size, SY_SYLVA_LEAF_OFF, &err), SY_OK);
    assert_int_equal(sy_decode_mem("off", img, size, &d, &cl, &meta, &err), SY_OK);
    assert_int_equal(meta.flags, SY_SYLVA_LEAF_OFF);
    assert_int_equal(meta.species_id, 3);
    assert_int_equal(d.n, 2);
    sy_skeleton_free(&d), sy_clusters_free(&cl);
    /* Only byte 5 and the checksum differ. */
    assert_int_equal(size, plain_size);
    for (size_t i = 0; i + 4 < size; i++)
        if (i != 5) assert_int_equal(img[i], plain[i]);
    /* Unknown bits: refused by the setter (the image unchanged) and by the reader. */
    assert_int_equal(sy_sylva_set_flags(img, size, 0x80, &err), SY_EINPUT);
    assert_int_equal(img[5], SY_SYLVA_LEAF_OFF);
    assert_int_equal(sy_sylva_set_flags(img, 10, SY_SYLVA_LEAF_OFF, &err), SY_EINPUT);
    img[5] = 0x82;
    reseal(img, size);
    assert_one_line_input_error(sy_decode_mem("odd.sylva", img, size, &d, &cl, &meta, &err), &err, "odd.sylva");
    assert_non_null(strstr(err.msg, "unknown header flags"));
    free(img), free(plain);
    sy_skeleton_free(&s);
}

static void encoder_rejects_bad_input(void **state)
{
    (void)state;
    sy_skeleton s;
    sy_error err = {0};
    unsigned char *out;
    size_t size;
    assert_int_equal(sy_skeleton_init(&s, 0, &err), SY_OK);
    assert_int_equal(sy_encode_mem(&s, NULL, 0, 0, NULL, &out, &size, &err), SY_EINPUT);
    float p[3] = {0, 0, 0};
    sy_skeleton_add(&s, p, 0.1f, -1, 0, 0, &err);
    sy_cluster c = {0};
    c.seed = 5; /* no such node */
    sy_clusters cl = {1, &c};
    assert_int_equal(sy_encode_mem(&s, &cl, 0, 0, NULL, &out, &size, &err), SY_EINPUT);
    /* A single node without clusters is a valid (tiny) tree. */
    assert_int_equal(sy_encode_mem(&s, NULL, 0, 0, NULL, &out, &size, &err), SY_OK);
    assert_true(size < 100);
    free(out);
    /* Writing into a missing directory fails and leaves nothing behind. */
    assert_int_not_equal(sy_encode_write("/nonexistent-dir/x.sylva", &s, NULL, 0, 0, &err), SY_OK);
    sy_skeleton_free(&s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(damaged_files_fail_cleanly),
        cmocka_unit_test(encoder_rejects_bad_input),
        cmocka_unit_test(version1_files_still_read),
        cmocka_unit_test(twigs_round_trip),
        cmocka_unit_test(qsm_branch_orders_round_trip),
        cmocka_unit_test(synthetic_tree_round_trips),
        cmocka_unit_test(real_trees_round_trip_under_40kB),
        cmocka_unit_test(twig_room_counts_the_hulls_as_built),
        cmocka_unit_test(lobes_fit_at_24_triangles_a_hull),
        cmocka_unit_test(leaf_off_flag_round_trips),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
