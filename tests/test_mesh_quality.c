/* What a game artist sees on every library species, grown with two seeds
 * and built by the pipeline (sy_tree_asset_build), measured by sy_mesh_check
 * (docs/mesh.md, "Quality checks"): no sails or slivers, welded bark, LOD0
 * within its triangle budget, leaves on twigs and nothing below the ground,
 * a LOD chain without cliffs whose silhouettes stay close to LOD0's. */
#include "testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline/tree_asset.h"
#include "species/library.h"
#include "stages/eval/eval.h"
#include "stages/grow/grow.h"
#include "stages/mesh/mesh_internal.h"

/* Budgets and tolerances, with the worst value measured over the library
 * (two seeds) when they were set. */
#define LOD0_BARK_MAX 60000     /* issue budget; measured <= 59.5k (quaking aspen) */
/* Flagged "sails" left are twig quads on looping Weber-Penn curves a few
 * radii off the skeleton's straight segments (measured <= 3.6 %); the sail
 * the asset had, 5.85 m across, stood 600 radii off. */
#define SAIL_SHARE 0.04         /* sails / bark triangles */
/* Coarser levels: measured <= 0.57 % (the Norway spruce's LOD3, junction
 * flanks) since stop 49 kept their chords within two radii of the rings
 * they skip; 2.5 % before (the London plane's LOD3). */
#define SAIL_SHARE_ANY 0.01
#define OFF_SURFACE_MAX 60      /* local radii (measured <= 46) */
/* An edge's extent across the branches it runs by (docs/mesh.md, "Stop 28"):
 * the aspen's 0.59 m chord between two twigs measured 15 at LOD0 (before the room units: stop 28). */
#define ACROSS_LOD0 12          /* measured <= 11.1 (the London plane's and black oak's curved limbs) */
#define ACROSS_ANY 40           /* coarser levels, measured <= 34 */
/* No triangle under 0.005 mm^2 at any level (the tubes' edge flips and the
 * caps' cones, docs/mesh.md "Slivers"); needles, thinner than 1/1000 of
 * their longest edge, are the thin sides of tapering twig tips and of strips
 * meeting 1.5 mm twigs (measured <= 0.11 %). */
#define SLIVER_SHARE 0.002      /* slivers / bark triangles */
/* Bark is closed at every level: each junction is welded into its parent
 * (one strip per group of crowded children) or, where its ring cannot be
 * (a ring off the parent's end, a fold), capped inside the parent. */
#define NONMANIFOLD_SHARE 0.001 /* coincident stems of a grown tree share edges */
/* Junctions welded into the parent, not capped inside it: a ring still
 * capped wraps most of its parent, stands partly off the parent's tube
 * (a child at its parent's base) or its strip would fold. */
#define WELDED_LOD0 0.77 /* measured >= 78.5 % (weeping willow; 75.5 % before the bands), aspen >= 95 %, oak >= 90 % */
#define WELDED_ANY 0.33  /* coarser levels, measured >= 47 % (one LOD3 of a few dozen junctions) */
/* Over the whole library (both seeds): the capped ones are mostly rings that
 * cross, rectangles that wrap their parent and strips that fold
 * (docs/mesh.md, "Welding"). */
/* Stop 28 counts 538 more LOD0 junctions: children whose base lay in the
 * part of their parent buried in the grandparent started as loose tubes
 * with a base disc (uncounted), and now leave the grandparent (457 welded,
 * 81 capped). Counting those loose tubes as unwelded, the library was at
 * 92.9 % before (9237 of 9940) and is at 97.5 % now. */
#define WELDED_LIBRARY_LOD0 0.98 /* measured 98.6 % (98.0 % before a child could slide past a
                                    thicker sibling, stop 40; 97.5 % at stop 28; 98.2 % of the
                                    junctions counted before stop 28, 97.4 % before the unfolding
                                    flips and the wider rectangles, 96.5 % before the bands) */
#define WELDED_LIBRARY_ANY 0.93  /* coarser levels, measured 93.6 % (92.8 % before stop 40; 92.5 % at
                                    stop 28; 93.9 % of those counted before stop 28, 91.9 % before
                                    the unfolding flips and the wider rectangles, 88.0 % before the
                                    bands) */
/* Base-ring vertices pushed onto the parent as far as their tube's next
 * ring (first_row_folds): measured <= 7 (the black oak, seed 2; 38 before
 * the push stopped short of that ring, stop 50; the library 96 -> 12).
 * Those left are vertices the push's radial fallback carries on. */
#define FIRST_ROW_FOLDS_MAX 8
#define LEAF_GAP_MAX 1.0        /* petiole to LOD0 bark, in leaf lengths */
#define RATIO_MIN 0.25          /* each level's triangles over the previous level's */
#define RATIO_MAX 0.5
#define IOU_LOD1 0.75           /* silhouette vs LOD0 (measured >= 0.805, the willow; >= 0.77 before
                                   narrow cards widened first and bark lent cards triangles, stop 48;
                                   the weeping willow was 0.56 until stop 21, its LOD1 dropping the
                                   thin hanging twigs) */
#define IOU_ANY 0.6             /* (measured >= 0.653, the palm's LOD3; 0.54 with its leaflets grown
                                   in length and halved at every level, stop 48) */

/* Junctions and welds over every species, LOD0 and the coarser levels. */
typedef struct {
    size_t junctions[2], welded[2];
} weld_tally;

static void check_asset(const char *name, const sy_tree_asset_report *rep, weld_tally *tally)
{
    const sy_mesh_check_report *c = &rep->check;
    assert_true(c->n_levels >= 3);
    const sy_mesh_check_level *l0 = &c->level[0];
    double bark = (double)l0->bark_triangles;
    printf("%s: LOD0 %zu bark + %zu leaves, sails %zu across %.1f slivers %zu open %zu nonmanifold %zu "
           "misoriented %zu, leaf gap %.2f, top bark %.2f leaf %.2f\n",
           name, l0->bark_triangles, l0->leaves, l0->sails, l0->max_across, l0->slivers, l0->boundary_edges, l0->nonmanifold_edges,
           l0->misoriented_edges, l0->max_leaf_gap, l0->bark_top, l0->leaf_top);
    assert_true(l0->bark_triangles <= LOD0_BARK_MAX);
    assert_true(l0->sails <= SAIL_SHARE * bark);
    assert_true(l0->max_off_surface <= OFF_SURFACE_MAX);
    assert_true(l0->max_across <= ACROSS_LOD0);
    assert_true(l0->slivers <= SLIVER_SHARE * bark);
    assert_true(l0->nonmanifold_edges <= NONMANIFOLD_SHARE * bark);
    assert_int_equal(l0->misoriented_edges, 0);
    /* Leaves on twigs, bark reaching the leafy tips. */
    if (l0->leaves) {
        assert_true(l0->max_leaf_gap <= LEAF_GAP_MAX);
        assert_int_equal(l0->leaves_far, 0);
        assert_true(l0->leaf_top <= l0->bark_top + 1.0);
    }
    for (size_t l = 0; l < c->n_levels; l++) {
        const sy_mesh_check_level *v = &c->level[l];
        assert_true(v->lod < rep->welds.levels);
        size_t nj = rep->welds.junctions[v->lod], nw = rep->welds.welded[v->lod];
        double welded = nj ? (double)nw / (double)nj : 1;
        printf("  LOD%zu: %zu of %zu junctions welded (%.1f %%)\n", v->lod, nw, nj, 100 * welded);
        assert_true(welded >= (l == 0 ? WELDED_LOD0 : WELDED_ANY));
        tally->junctions[l > 0] += nj, tally->welded[l > 0] += nw;
        assert_int_equal(v->below_ground, 0);
        assert_int_equal(v->leaves_below_ground, 0);
        assert_int_equal(v->degenerate, 0);
        assert_true(v->max_across <= ACROSS_ANY);
        assert_true(v->sails <= SAIL_SHARE_ANY * (double)v->bark_triangles || l == 0);
        assert_int_equal(v->misoriented_edges, 0);
        assert_int_equal(v->boundary_edges, 0);
        if (l == 0) continue;
        printf("  LOD%zu: %zu triangles, ratio %.3f, silhouette IoU %.3f, sails %zu, open %zu\n", v->lod, v->triangles,
               v->ratio, v->silhouette_iou, v->sails, v->boundary_edges);
        assert_true(v->ratio >= RATIO_MIN && v->ratio <= RATIO_MAX);
        assert_true(v->silhouette_iou >= (l == 1 ? IOU_LOD1 : IOU_ANY));
    }
}

/* Base-ring vertices of the LOD0 bark (default mesh options) pushed onto
 * the parent, along the child's first tangent, as far as the tube's next
 * ring or farther: the tube's first row then folds back over itself
 * (docs/mesh.md, Tubes, "Junctions"). */
static size_t first_row_folds(const sy_skeleton *sk)
{
    sy_error err = {0};
    sy_mesh_options mo = sy_mesh_options_default();
    sy_stems st;
    assert_int_equal(sy_stems_build(sk, &mo, &st, &err), SY_OK);
    uint8_t *keep = malloc(st.n + 1);
    size_t max_samp = 1, folds = 0;
    for (size_t i = 0; i < st.n; i++) {
        keep[i] = 1;
        if (st.s[i].n_samp > max_samp) max_samp = st.s[i].n_samp;
    }
    int32_t *idx = malloc(2 * max_samp * sizeof *idx);
    sy_lod_params lp = {0, 1, keep, 1};
    sy_mesh m;
    assert_int_equal(sy_bark_mesh(&st, &lp, 0, &m, &err), SY_OK);
    size_t vo = 0;
    for (size_t i = 0; i < st.n; i++) {
        const sy_stem *s = &st.s[i];
        size_t nv, ni;
        sy_tube_counts(&st, i, &lp, &nv, &ni);
        if (nv > 0 && s->junction && sy_stem_rings(s, &lp, idx) > 1) {
            const float *c = s->sp + 3 * idx[0], *T = s->st + 3 * idx[0];
            float gap = s->ss[idx[1]] - s->ss[idx[0]];
            for (int j = 0; j < sy_stem_radial(s, &lp); j++) {
                const float *y = m.position + 3 * (vo + (size_t)j); /* glTF Y-up */
                float w[3] = {y[0] - c[0], -y[2] - c[1], y[1] - c[2]};
                folds += sy_dot3(w, T) >= gap;
            }
        }
        vo += nv;
    }
    sy_mesh_free(&m);
    free(idx), free(keep);
    sy_stems_free(&st);
    return folds;
}

static weld_tally library_tally;

static void species_assets_survive_a_close_look(void **state)
{
    const char *name = *state;
    sy_species_params sp;
    sy_error err = {0};
    assert_int_equal(sy_species_params_find(name, &sp, &err), SY_OK);
    for (uint64_t seed = 1; seed <= 2; seed++) {
        sy_skeleton sk;
        sy_leaves lv;
        assert_int_equal(sy_grow_tree(&sp, seed, &sk, &lv, &err), SY_OK);
        size_t folds = first_row_folds(&sk);
        printf("%s seed %d: %zu base-ring vertices pushed as far as their next ring\n", name, (int)seed, folds);
        assert_true(folds <= FIRST_ROW_FOLDS_MAX);
        sy_tree_asset_options o = sy_tree_asset_options_default();
        o.impostor = 0; /* not checked; its CPU render is a third of the build */
        o.texture_size = 64;
        o.seed = seed;
        o.check = 1;
        sy_asset a;
        sy_tree_asset_report rep;
        if (sy_tree_asset_build(&sk, &lv, &sp, &o, &a, &rep, &err) != SY_OK) fail_msg("%s: %s", name, err.msg);
        check_asset(name, &rep, &library_tally);
        sy_asset_free(&a);
        sy_skeleton_free(&sk);
        sy_leaves_free(&lv);
    }
    sy_species_params_free(&sp);
}

/* A limb drooping under the ground: the mesher lifts its samples onto it
 * (sample_curve), drawing the limb down to the ground and along it, and
 * the check's capsules follow it there. Lifting a segment's lower end
 * alone drew it as one slant above the drawn limb: its quads came out as
 * sails (the grown Norway spruce's skirt, 123 at LOD0, all within 0.3 m of
 * the ground). */
static void limb_along_the_ground_is_no_sail(void **state)
{
    (void)state;
    sy_skeleton sk;
    sy_leaves lv;
    sy_error err = {0};
    memset(&lv, 0, sizeof lv);
    assert_int_equal(sy_skeleton_init(&sk, 0, &err), SY_OK);
    static const float trunk[4][4] = {{0, 0, 0, 0.12f}, {0, 0, 1, 0.1f}, {0, 0, 2, 0.08f}, {0, 0, 3, 0.05f}};
    static const float limb[4][4] = {{1, 0, 0.8f, 0.03f}, {2, 0, 0.3f, 0.025f}, {3, 0, -0.9f, 0.02f}, {4, 0, -1, 0.015f}};
    int32_t p = -1;
    for (int i = 0; i < 4; i++) p = sy_skeleton_add(&sk, trunk[i], trunk[i][3], p, 0, 0, &err);
    p = 1;
    for (int i = 0; i < 4; i++) p = sy_skeleton_add(&sk, limb[i], limb[i][3], p, 1, 1, &err);
    assert_true(p >= 0);
    sy_tree_asset_options o = sy_tree_asset_options_default();
    o.impostor = 0, o.texture_size = 64, o.check = 1;
    sy_asset a;
    sy_tree_asset_report rep;
    assert_int_equal(sy_tree_asset_build(&sk, &lv, NULL, &o, &a, &rep, &err), SY_OK);
    for (size_t l = 0; l < rep.check.n_levels; l++) {
        const sy_mesh_check_level *v = &rep.check.level[l];
        printf("LOD%zu: %zu sails of %zu bark triangles, %.2f radii off at most, %zu vertices below the ground\n", v->lod,
               v->sails, v->bark_triangles, v->max_off_surface, v->below_ground);
        assert_int_equal(v->below_ground, 0);
        assert_int_equal(v->sails, 0);
        assert_true(v->max_off_surface < 2);
    }
    sy_asset_free(&a);
    sy_skeleton_free(&sk);
}

/* Runs after every species (cmocka keeps the order). */
static void library_welds(void **state)
{
    (void)state;
    const weld_tally *t = &library_tally;
    assert_true(t->junctions[0] > 0 && t->junctions[1] > 0);
    double lod0 = (double)t->welded[0] / (double)t->junctions[0], any = (double)t->welded[1] / (double)t->junctions[1];
    printf("library: LOD0 %zu of %zu junctions welded (%.1f %%), coarser levels %zu of %zu (%.1f %%)\n", t->welded[0],
           t->junctions[0], 100 * lod0, t->welded[1], t->junctions[1], 100 * any);
    assert_true(lod0 >= WELDED_LIBRARY_LOD0);
    assert_true(any >= WELDED_LIBRARY_ANY);
}

int main(void)
{
    /* Every species of the library manifest. */
    static sy_library lib;
    sy_error err = {0};
    if (sy_library_load(NULL, &lib, &err) != SY_OK) return fprintf(stderr, "%s\n", err.msg), 1;
    size_t n = lib.n < 64 ? lib.n : 64;
    struct CMUnitTest tests[66];
    for (size_t i = 0; i < n; i++)
        tests[i] = (struct CMUnitTest){lib.entries[i].name, species_assets_survive_a_close_look, NULL, NULL,
                                       (void *)lib.entries[i].name};
    tests[n++] = (struct CMUnitTest){"library_welds", library_welds, NULL, NULL, NULL};
    tests[n++] = (struct CMUnitTest){"limb_along_the_ground_is_no_sail", limb_along_the_ground_is_no_sail, NULL, NULL, NULL};
    int rc = _cmocka_run_group_tests("mesh_quality", tests, n, NULL, NULL);
    sy_library_free(&lib);
    return rc;
}
