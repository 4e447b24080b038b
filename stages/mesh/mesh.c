/* sy_mesh_tree: skeleton + leaves -> Asset with a LOD chain (docs/mesh.md). */
#include "mesh.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_internal.h"
#include "stages/core/parallel.h"
#include "stages/core/rng.h"

sy_mesh_options sy_mesh_options_default(void)
{
    sy_mesh_options o;
    memset(&o, 0, sizeof o);
    o.radial_segments = 16;
    o.segment_length = 0;
    o.n_lods = 4;
    o.lod0_max_triangles = 54000;
    o.lod0_max_leaves = 30000;
    o.impostor = 1;
    o.impostor_size = 512;
    o.min_radius = 0.0015f;
    o.leaf_aspect = 0.6f;
    o.leaf_shape = 0;
    o.seed = 1;
    o.bark_material = -1;
    o.leaf_material = -1;
    return o;
}

sy_code sy_mesh_options_check(const sy_mesh_options *o, sy_error *err)
{
    if (o->radial_segments < 3 || o->radial_segments > 256)
        return sy_fail(err, SY_EUSAGE, "mesh: radial_segments %d outside [3, 256]", o->radial_segments);
    if (!(o->segment_length >= 0) || !isfinite(o->segment_length))
        return sy_fail(err, SY_EUSAGE, "mesh: segment_length %g is not >= 0", o->segment_length);
    if (o->n_lods < 1 || o->n_lods > 7)
        return sy_fail(err, SY_EUSAGE, "mesh: n_lods %d outside [1, 7]", o->n_lods);
    if (o->lod0_max_leaves < 0) return sy_fail(err, SY_EUSAGE, "mesh: lod0_max_leaves %d is negative", o->lod0_max_leaves);
    if (o->impostor && (o->impostor_size < 16 || o->impostor_size > 4096))
        return sy_fail(err, SY_EUSAGE, "mesh: impostor_size %d outside [16, 4096]", o->impostor_size);
    if (!(o->min_radius >= 0) || !isfinite(o->min_radius))
        return sy_fail(err, SY_EUSAGE, "mesh: min_radius %g is not >= 0", o->min_radius);
    if (!(o->lean_radius >= 0 && o->lean_radius <= 1))
        return sy_fail(err, SY_EUSAGE, "mesh: lean_radius %g is not in [0, 1] m", o->lean_radius);
    if (!(o->leaf_aspect > 0) || !isfinite(o->leaf_aspect))
        return sy_fail(err, SY_EUSAGE, "mesh: leaf_aspect %g is not positive", o->leaf_aspect);
    return SY_OK;
}

static sy_code check_options(const sy_mesh_options *o, const sy_asset *a, sy_error *err)
{
    sy_code rc = sy_mesh_options_check(o, err);
    if (rc) return rc;
    if (o->bark_material >= (int)a->n_materials || o->leaf_material >= (int)a->n_materials)
        return sy_fail(err, SY_EUSAGE, "mesh: material index beyond the asset's %zu materials", a->n_materials);
    return SY_OK;
}

static sy_code check_leaves(const sy_leaves *lv, const sy_skeleton *sk, sy_error *err)
{
    for (size_t i = 0; i < lv->n; i++) {
        if (lv->node[i] < 0 || (size_t)lv->node[i] >= sk->n)
            return sy_fail(err, SY_EINPUT, "mesh: leaf %zu hangs on node %d of %zu", i, lv->node[i], sk->n);
        for (int k = 0; k < 3; k++)
            if (!isfinite(lv->pos[3 * i + k])) return sy_fail(err, SY_EINPUT, "mesh: leaf %zu position is not finite", i);
        for (int k = 0; k < 4; k++)
            if (!isfinite(lv->rot[4 * i + k])) return sy_fail(err, SY_EINPUT, "mesh: leaf %zu rotation is not finite", i);
        if (!(lv->scale[i] > 0) || !isfinite(lv->scale[i]))
            return sy_fail(err, SY_EINPUT, "mesh: leaf %zu size %g is not positive", i, lv->scale[i]);
    }
    return SY_OK;
}

/* The caller's materials, or plain defaults: brown bark; green, two-sided,
 * alpha-masked, light-transmitting leaves. */
static sy_code add_materials(sy_asset *a, const sy_mesh_options *o, int want_leaf, int *bark, int *leaf,
                             sy_error *err)
{
    *bark = o->bark_material;
    *leaf = o->leaf_material;
    if (*bark < 0) {
        sy_material m = sy_material_default("bark");
        m.base_color[0] = 0.36f, m.base_color[1] = 0.25f, m.base_color[2] = 0.16f;
        m.roughness = 0.9f;
        if ((*bark = sy_asset_add_material(a, &m, err)) < 0) return SY_EINTERNAL;
    }
    if (*leaf < 0 && want_leaf) {
        sy_material m = sy_material_default("leaf");
        m.base_color[0] = 0.22f, m.base_color[1] = 0.45f, m.base_color[2] = 0.12f;
        m.roughness = 0.6f;
        m.alpha_mode = SY_ALPHA_MASK;
        m.alpha_cutoff = 0.5f;
        m.double_sided = 1;
        m.diffuse_transmission = 0.4f;
        m.diffuse_transmission_color[0] = 0.55f, m.diffuse_transmission_color[1] = 0.75f;
        m.diffuse_transmission_color[2] = 0.2f;
        if ((*leaf = sy_asset_add_material(a, &m, err)) < 0) return SY_EINTERNAL;
    }
    return SY_OK;
}

typedef struct {
    uint32_t *list; /* leaves this level keeps, a subsequence of the previous level's */
    size_t n;
} leaf_level;

/* Growth for cards that must carry `area` times their own area. LOD0 keeps
 * the leaf's shape. A coarser level, seen from farther away, first widens a
 * narrow card up to a square and only then lengthens it: a long leaflet
 * grown in length alone hangs into a shaggy curtain (a palm's metre-long
 * leaflets stood 2.8 times as long at LOD3), while widening fills the gaps
 * its pruned neighbours left beside it. */
static sy_card_growth card_growth(double area, float aspect, int level)
{
    double across = 1;
    if (level > 0 && aspect < 1) across = fmin(area, 1 / (double)aspect);
    double along = sqrt(area / across);
    return (sy_card_growth){(float)(across * along), (float)along};
}

/* Grows the cards of list so that their total area matches all of level 0's
 * (at most 16x), keeping the crown's coverage roughly constant as leaves are
 * pruned; cards that would then reach below the ground are left out.
 * Returns the growth. */
static sy_card_growth grow_to_full_area(const sy_leaves *lv, const leaf_level *all, float aspect, int level,
                                        float ground, leaf_level *list)
{
    double ref = 0, kept = 0;
    for (size_t i = 0; i < all->n; i++) ref += (double)lv->scale[all->list[i]] * lv->scale[all->list[i]];
    for (size_t i = 0; i < list->n; i++) kept += (double)lv->scale[list->list[i]] * lv->scale[list->list[i]];
    double area = kept > 0 ? ref / kept : 1;
    sy_card_growth g = card_growth(area < 1 ? 1 : area > 16 ? 16 : area, aspect, level);
    size_t n = 0;
    for (size_t i = 0; i < list->n; i++) {
        uint32_t l = list->list[i];
        if (sy_card_lowest(lv, l, aspect, g, lv->pos[3 * l + 2]) >= ground) list->list[n++] = l;
    }
    list->n = n;
    return g;
}

/* The next level keeps the first n_keep of the previous level's leaves (a
 * prefix of the stored seeded order), grown to level 0's leaf area. Leaves
 * of twigs the level drops stay: at a distance they stand in for the twig's
 * foliage, and they keep swaying with it because every wind entry survives.
 * Dropping them instead left the coarse levels bare (LOD3 of a 20k-leaf tree
 * kept none). Returns the growth. */
static sy_card_growth next_leaf_level(const sy_leaves *lv, const leaf_level *prev, size_t n_keep,
                                      const leaf_level *all, float aspect, int level, float ground, leaf_level *next)
{
    next->n = 0;
    for (size_t i = 0; i < n_keep && i < prev->n; i++) next->list[next->n++] = prev->list[i];
    return grow_to_full_area(lv, all, aspect, level, ground, next);
}

/* How many of the previous level's leaves the next keeps, and how many
 * triangles the level's bark lends its cards for them (*lent). The level
 * has as many triangles as halving the cards and taking SY_LOD_SHARE of
 * the bark (prev_bark, before welding) would give; the cards take up to
 * CARD_SHARE of them, at least half the previous level's leaves, and the
 * bark pays for those past half. A scanned tree's crown of a few thousand
 * cards halved at every level lost its silhouette (AdTree's tree1, 2,000
 * leaves: LOD3 0.571 against LOD0) while the cards were a tenth of its
 * triangles: the kept cards grow to the same area and fill as many pixels,
 * so pruning them bought few triangles at a large cost in shape. */
#define CARD_SHARE 0.5
static size_t leaves_to_keep(size_t prev_leaves, size_t prev_bark, size_t card_tris, size_t *lent)
{
    size_t half = prev_leaves / 2;
    *lent = 0;
    if (card_tris == 0) return half;
    double level = SY_LOD_SHARE * (double)prev_bark + (double)(card_tris * half);
    double fit = floor(CARD_SHARE * level / (double)card_tris);
    size_t keep = fit <= (double)half ? half : fit >= (double)prev_leaves ? prev_leaves : (size_t)fit;
    *lent = (keep - half) * card_tris;
    return keep;
}

/* One level of the chain: chosen in order (each level's stems and leaves
 * follow from the previous level's), then meshed on its own (the levels in
 * parallel), then appended to the asset in order, so the asset is the same
 * for any thread count. */
typedef struct {
    sy_lod_params lp; /* lp.keep: this level's own copy */
    leaf_level leaves;
    sy_card_growth grow;
    float coverage;
    sy_mesh bark;
    sy_instances cards;
    int built, has_cards;
    size_t junctions, welded;
    sy_code rc;
    sy_error err;
} level_job;

typedef struct {
    level_job *jobs;
    const sy_stems *st;
    const sy_leaves *lv;
    int bark, card;
    float aspect;
} level_build;

static void build_levels(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    const level_build *b = ctx;
    for (size_t l = begin; l < end; l++) {
        level_job *j = &b->jobs[l];
        j->rc = sy_bark_mesh_welds(b->st, &j->lp, b->bark, &j->bark, &j->junctions, &j->welded, &j->err);
        if (j->rc != SY_OK) continue;
        j->built = 1;
        snprintf(j->bark.name, sizeof j->bark.name, "bark_lod%d", j->lp.level);
        if (b->card >= 0 && j->leaves.n > 0) {
            j->rc = sy_leaf_instances(b->lv, b->st, j->lp.level == 0 ? j->lp.keep : NULL, b->aspect, j->leaves.list,
                                      j->leaves.n, j->grow, b->card, &j->cards, &j->err);
            j->has_cards = j->rc == SY_OK;
        }
    }
}

/* Appends a built level to the asset; its mesh and cards move there. */
static sy_code append_level(sy_asset *a, level_job *j, sy_mesh_weld_stats *ws, sy_error *err)
{
    sy_lod lod;
    memset(&lod, 0, sizeof lod);
    lod.screen_coverage = j->coverage;
    if (ws && ws->levels < SY_MESH_MAX_LEVELS) {
        ws->junctions[ws->levels] = j->junctions, ws->welded[ws->levels] = j->welded;
        ws->levels++;
    }
    j->built = 0;
    if (j->bark.n_vertices > 0) {
        int mi = sy_asset_add_mesh(a, &j->bark, err);
        if (mi < 0) {
            sy_mesh_free(&j->bark);
            return SY_EINTERNAL;
        }
        lod.meshes[lod.n_meshes++] = mi;
    } else {
        sy_mesh_free(&j->bark);
    }
    if (j->has_cards) {
        lod.instances[0] = j->cards;
        lod.n_instances = 1;
        j->has_cards = 0;
    }
    if (sy_asset_add_lod(a, &lod, err) < 0) {
        for (int k = 0; k < lod.n_instances; k++) sy_instances_free(&lod.instances[k]);
        return SY_EINTERNAL;
    }
    return SY_OK;
}

sy_code sy_mesh_add_impostor(sy_asset *a, size_t lod0, int size, sy_error *err)
{
    if (lod0 >= a->n_lods) return sy_fail(err, SY_EINTERNAL, "mesh: impostor of a missing level %zu", lod0);
    int mi = sy_impostor_build(a, &a->lods[lod0], size, err);
    if (mi < 0) return err ? err->code : SY_EINTERNAL;
    sy_lod lod;
    memset(&lod, 0, sizeof lod);
    /* Half the coverage of the coarsest mesh level before it. */
    lod.screen_coverage = a->lods[a->n_lods - 1].screen_coverage * 0.5f;
    lod.n_meshes = 1;
    lod.meshes[0] = mi;
    return sy_asset_add_lod(a, &lod, err) < 0 ? SY_EINTERNAL : SY_OK;
}

sy_code sy_mesh_tree(const sy_skeleton *skel, const sy_leaves *leaves, const sy_mesh_options *opt, sy_asset *out,
                     sy_error *err)
{
    static const sy_leaves none;
    const sy_leaves *lv = leaves ? leaves : &none;
    sy_code rc = check_options(opt, out, err);
    if (rc != SY_OK) return rc;
    if (skel->n == 0) return sy_fail(err, SY_EINPUT, "mesh: the skeleton has no nodes");
    if ((rc = sy_skeleton_validate(skel, err)) != SY_OK) return rc;
    if ((rc = check_leaves(lv, skel, err)) != SY_OK) return rc;
    if (lv->n > UINT32_MAX) return sy_fail(err, SY_EINPUT, "mesh: %zu leaves are too many", lv->n);

    if (opt->weld_stats) memset(opt->weld_stats, 0, sizeof *opt->weld_stats);
    sy_stems st;
    if ((rc = sy_stems_build(skel, opt, &st, err)) != SY_OK) return rc;
    if ((rc = sy_stems_reach(&st, lv, err)) != SY_OK) {
        sy_stems_free(&st);
        return rc;
    }
    /* The chain's levels; level 0's stems and leaves are filled below. */
    level_job *jobs = calloc((size_t)opt->n_lods, sizeof *jobs);
    int n_levels = 0;
    leaf_level all = {malloc((lv->n + 1) * sizeof(uint32_t)), lv->n};
    if (jobs) {
        jobs[0].lp = (sy_lod_params){0, 1, malloc(st.n + 1), 1};
        jobs[0].leaves.list = malloc((lv->n + 1) * sizeof(uint32_t));
        n_levels = 1;
    }
    if (!jobs || !all.list || !jobs[0].lp.keep || !jobs[0].leaves.list) {
        rc = sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
        goto done;
    }
    if ((rc = sy_wind_build(&st, out, err)) != SY_OK) goto done;
    int bark, leaf, card = -1;
    if ((rc = add_materials(out, opt, lv->n > 0, &bark, &leaf, err)) != SY_OK) goto done;
    if (lv->n > 0) {
        sy_mesh cm;
        if ((rc = sy_leaf_card(opt->leaf_shape, opt->leaf_aspect, leaf, &cm, err)) != SY_OK) goto done;
        if ((card = sy_asset_add_mesh(out, &cm, err)) < 0) {
            sy_mesh_free(&cm);
            rc = SY_EINTERNAL;
            goto done;
        }
    }
    /* Level 0: everything; the leaf order is the seeded permutation, so
     * every coarser level's leaves are a filtered prefix of it. */
    if (opt->keep_leaf_order)
        for (size_t i = 0; i < lv->n; i++) all.list[i] = (uint32_t)i;
    else {
        uint64_t state = opt->seed;
        sy_permutation(all.list, lv->n, &state);
    }
    /* Nothing below the ground: a card that would dip under it is left out. */
    size_t kept = 0;
    for (size_t i = 0; i < lv->n; i++)
        if (sy_card_lowest(lv, all.list[i], opt->leaf_aspect, (sy_card_growth){1, 1}, lv->pos[3 * all.list[i] + 2]) >=
            st.ground)
            all.list[kept++] = all.list[i];
    all.n = kept;
    level_job *l0 = &jobs[0];
    memcpy(l0->leaves.list, all.list, kept * sizeof(uint32_t));
    l0->leaves.n = kept;
    /* Over the leaf budget LOD0 keeps a prefix of the seeded order (stochastic
     * pruning, Cook et al. 2007), grown to the total area of all leaves. */
    l0->grow = (sy_card_growth){1, 1}, l0->coverage = 0.5f;
    if (opt->lod0_max_leaves > 0 && l0->leaves.n > (size_t)opt->lod0_max_leaves) {
        l0->leaves.n = (size_t)opt->lod0_max_leaves;
        l0->grow = grow_to_full_area(lv, &all, opt->leaf_aspect, 0, st.ground, &l0->leaves);
    }
    memset(l0->lp.keep, 1, st.n);
    size_t tris = sy_lod_bark_triangles(&st, &l0->lp);
    if (opt->lod0_max_triangles > 0 && tris > (size_t)opt->lod0_max_triangles &&
        !sy_lod_fit_budget(&st, &l0->lp, &tris, (size_t)opt->lod0_max_triangles)) {
        rc = sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
        goto done;
    }
    /* The chain, level by level: each keeps a subset of the previous one's
     * stems and at least half its leaves. */
    size_t card_tris = card >= 0 ? out->meshes[card].n_indices / 3 : 0;
    for (int level = 1; level < opt->n_lods; level++) {
        const level_job *prev = &jobs[level - 1];
        level_job *jb = &jobs[level];
        jb->lp = (sy_lod_params){level, 1 << level, malloc(st.n + 1), 0};
        jb->leaves.list = malloc((prev->leaves.n + 1) * sizeof(uint32_t));
        if (!jb->lp.keep || !jb->leaves.list) {
            free(jb->lp.keep), free(jb->leaves.list);
            rc = sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
            goto done;
        }
        size_t next_tris, lent;
        size_t n_keep = leaves_to_keep(prev->leaves.n, tris, card_tris, &lent);
        /* A trunk too thick for the bark left after lending keeps the chain
         * going with half the cards, as it would have without them. */
        int selected = sy_lod_select(&st, prev->lp.keep, tris, lent, &jb->lp, &next_tris);
        if (!selected && lent > 0) {
            n_keep = prev->leaves.n / 2;
            selected = sy_lod_select(&st, prev->lp.keep, tris, 0, &jb->lp, &next_tris);
        }
        if (!selected) {
            free(jb->lp.keep), free(jb->leaves.list);
            break; /* no coarser level can halve the triangles: the chain ends */
        }
        jb->grow = next_leaf_level(lv, &prev->leaves, n_keep, &all, opt->leaf_aspect, level, st.ground, &jb->leaves);
        jb->coverage = 0.5f * prev->coverage;
        n_levels++;
        tris = next_tris;
    }
    level_build lb = {jobs, &st, lv, bark, card, opt->leaf_aspect};
    sy_parallel_for((size_t)n_levels, 1, build_levels, &lb);
    size_t first_lod = out->n_lods;
    for (int l = 0; l < n_levels; l++) {
        if (jobs[l].rc != SY_OK) {
            if (err) *err = jobs[l].err;
            rc = jobs[l].rc;
            goto done;
        }
        if ((rc = append_level(out, &jobs[l], opt->weld_stats, err)) != SY_OK) goto done;
    }
    if (opt->impostor) rc = sy_mesh_add_impostor(out, first_lod, opt->impostor_size, err);
done:
    for (int l = 0; jobs && l < n_levels; l++) {
        if (jobs[l].built) sy_mesh_free(&jobs[l].bark);
        if (jobs[l].has_cards) sy_instances_free(&jobs[l].cards);
        free(jobs[l].lp.keep), free(jobs[l].leaves.list);
    }
    free(jobs);
    free(all.list);
    sy_stems_free(&st);
    return rc;
}
