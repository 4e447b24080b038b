#include "pipeline/tree_synth.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "pipeline/tree_asset.h"
#include "species/library.h"
#include "stages/core/progress.h"

/* The share of a tree's height a scan is sure to show (sy_species_leaf_fit). */
#define SCAN_HEIGHT_SEEN 0.8

void sy_decoded_tree_free(sy_decoded_tree *t)
{
    sy_skeleton_free(&t->skel);
    sy_clusters_free(&t->lobes);
    sy_skeleton_free(&t->grown);
    sy_leaves_free(&t->leaves);
    memset(t, 0, sizeof *t);
}

sy_code sy_decoded_tree_build(const char *name, const unsigned char *data, size_t size, const sy_species_params *species,
                              int leaf_off, sy_decoded_tree *t, sy_error *err)
{
    memset(t, 0, sizeof *t);
    double t0 = sy_now();
    sy_code rc = sy_decode_mem(name, data, size, &t->skel, &t->lobes, &t->meta, err);
    if (rc) return rc;
    sy_tree_asset_root_to_origin(&t->skel, &t->lobes);
    t->leaf_off = leaf_off || (t->meta.flags & SY_SYLVA_LEAF_OFF);
    t->seconds_decode = sy_now() - t0;
    t0 = sy_now();
    char dir[4096];
    if ((rc = sy_library_locate(dir, sizeof dir, err))) {
        sy_decoded_tree_free(t);
        return rc;
    }
    snprintf(t->lsys, sizeof t->lsys, "%.200s/default.lsys", dir);
    if (species && species->name) {
        char p[500];
        snprintf(p, sizeof p, "%.200s/%.200s.lsys", dir, species->name);
        if (access(p, R_OK) == 0) snprintf(t->lsys, sizeof t->lsys, "%s", p);
    }
    sy_lsystem ls;
    sy_branchlets lib;
    if ((rc = sy_lsystem_load(t->lsys, &ls, err)) || (rc = sy_branchlets_generate(&ls, t->meta.seed, &lib, err))) {
        sy_decoded_tree_free(t);
        return rc;
    }
    t->branchlets = lib.n_branchlets;
    t->patches = lib.n_patches;
    t->seconds_library = sy_now() - t0;
    sy_synth_options so = sy_synth_options_default();
    so.seed = t->meta.seed;
    so.leaf_size = ls.leaf_size;
    if (species && species->leaf_scale > 0) {
        /* The species' cards fit its grown tree; a shorter tree takes them
         * shrunk. Synthesis places a patch's leaves as its branchlet carries
         * them, so the leaf area falls with the square of the shrink (QSM
         * twigs get more leaves instead; patches have no such knob). The
         * height: the highest node or hull vertex above the root, now at the
         * origin. A scan can miss a tall tree's top (the simulated beech at 100k
         * points: 14% of its height), so only trees under SCAN_HEIGHT_SEEN
         * of the species' size count as smaller. */
        double top = sy_skeleton_height(&t->skel);
        for (size_t c = 0; c < t->lobes.n; c++)
            for (size_t i = 0; i < t->lobes.items[c].n_verts; i++) top = fmax(top, t->lobes.items[c].verts[3 * i + 2]);
        so.leaf_size = (float)(species->leaf_scale / sqrt(species->leaf_quality > 0 ? species->leaf_quality : 1) *
                               sy_species_leaf_fit(species, top, SCAN_HEIGHT_SEEN));
    }
    so.leaf_density = ls.leaf_density;
    so.bare = t->leaf_off;
    /* A crown of fronds: as many as the species' stem carries (Weber &
     * Penn's 1Branches; the palm's 24). */
    if (species && !species->twigs) so.fronds = species->level[1].branches >= 1 ? (int)lround(species->level[1].branches) : 1;
    so.max_depth = ls.max_depth;
    if (species && species->ratio_power > 0) so.ratio_power = species->ratio_power;
    if (species) {
        so.levels = species->levels;
        _Static_assert(SY_SYNTH_WP_LEVELS == SY_WP_LEVELS, "synthesis takes every Weber & Penn level's length");
        for (int l = 0; l < SY_WP_LEVELS; l++) so.level_length[l] = species->level[l].length;
        for (int l = 0; l < 2; l++)
            so.down_angle[l] = species->level[l + 1].down_angle, so.down_angle_v[l] = species->level[l + 1].down_angle_v;
    }
    for (size_t c = 0; c < t->lobes.n && !so.fronds && !t->lean_radius; c++)
        if (t->lobes.items[c].n_twigs) t->lean_radius = SY_MESH_LEAN_RADIUS;
    rc = sy_synthesize(&t->skel, &t->lobes, &lib, &so, &t->grown, &t->leaves, &t->synth, err);
    sy_branchlets_free(&lib);
    if (rc) sy_decoded_tree_free(t);
    return rc;
}

void sy_decoded_tree_report_bare(const char *command, const sy_decoded_tree *t)
{
    const sy_synth_report *r = &t->synth;
    for (size_t i = 0; i < r->lobes_bare && i < 8; i++) {
        int32_t c = r->bare_lobe[i];
        fprintf(stderr, "sylva %s: lobe %d (node %d): %s\n", command, (int)c,
                c >= 0 && (size_t)c < t->lobes.n ? (int)t->lobes.items[c].seed : -1, sy_synth_bare_reason(r->bare_reason[i]));
    }
    if (r->lobes_bare > 8) fprintf(stderr, "sylva %s: ... and %zu more bare lobes\n", command, r->lobes_bare - 8);
}
