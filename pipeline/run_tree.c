/* The run driver (pipeline/run_tree.h): the order of the steps and the
 * hand-over between them; every step is a stage call. */
#include "pipeline/run_tree.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "pipeline/tree_synth.h"
#include "species/library.h"
#include "stages/core/fileio.h"
#include "stages/core/parallel.h"
#include "stages/core/progress.h"
#include "stages/core/sort.h"
#include "stages/encode/encode.h"
#include "stages/eval/eval.h"
#include "stages/grow/grow.h"
#include "stages/ingest/ingest.h"
#include "stages/preprocess/preprocess.h"

sy_run_tree_options sy_run_tree_options_default(void)
{
    sy_run_tree_options o;
    memset(&o, 0, sizeof o);
    o.beta = o.gamma = o.fair_sigma = o.return_cap = NAN;
    o.fs = 1;
    o.seed = 1;
    o.lobe_size = -1;
    o.roof = -1;
    o.classify = 1;
    o.max_points = SY_POINT_BUDGET;
    o.asset = sy_tree_asset_options_default();
    return o;
}

sy_code sy_run_tree_options_check(const sy_run_tree_options *o, sy_error *err)
{
    if (!isnan(o->beta) && !(o->beta > 0 && isfinite(o->beta)))
        return sy_fail(err, SY_EUSAGE, "run: beta %g must be > 0", o->beta);
    if (!isnan(o->gamma) && !(o->gamma > 0 && isfinite(o->gamma)))
        return sy_fail(err, SY_EUSAGE, "run: gamma %g must be > 0", o->gamma);
    if (!(o->fs > 0 && o->fs <= 1)) return sy_fail(err, SY_EUSAGE, "run: fs %g outside (0, 1]", o->fs);
    if (!(o->wood_share >= 0 && o->wood_share < 1))
        return sy_fail(err, SY_EUSAGE, "run: wood_share %g outside [0, 1)", o->wood_share);
    if (o->roof < -1 || o->roof > 1) return sy_fail(err, SY_EUSAGE, "run: roof %d must be -1, 0 or 1", o->roof);
    if (!(o->lobe_size == -1 || (o->lobe_size >= 0 && o->lobe_size <= 1)))
        return sy_fail(err, SY_EUSAGE, "run: lobe_size %g outside [0, 1] (or -1: the species')", o->lobe_size);
    if (o->leaf_off < -1 || o->leaf_off > 1) return sy_fail(err, SY_EUSAGE, "run: leaf_off %d is not -1, 0 or 1", o->leaf_off);
    if (!(o->voxel >= 0) || !isfinite(o->voxel))
        return sy_fail(err, SY_EUSAGE, "run: voxel %g must be >= 0 metres", o->voxel);
    if (!isnan(o->fair_sigma) && !(o->fair_sigma >= 0 && isfinite(o->fair_sigma)))
        return sy_fail(err, SY_EUSAGE, "run: fair_sigma %g must be >= 0", o->fair_sigma);
    if (!isnan(o->return_cap) && !(o->return_cap >= 0 && isfinite(o->return_cap)))
        return sy_fail(err, SY_EUSAGE, "run: return_cap %g must be >= 0", o->return_cap);
    return sy_tree_asset_options_check(&o->asset, err);
}

void sy_run_tree_result_free(sy_run_tree_result *r)
{
    free(r->glb);
    free(r->sylva);
    if (r->classified) sy_species_guess_free(&r->guess);
    r->classified = 0;
    r->glb = r->sylva = NULL;
    r->glb_size = r->sylva_size = 0;
}

static void step(const sy_run_tree_options *o, const char *what, double seconds, const char *detail)
{
    if (o->on_step) o->on_step(o->step_ctx, what, seconds, detail);
}

/* The stage's message with the input's name in front when it lacks it. */
static sy_code name_input(sy_code rc, const char *name, sy_error *err)
{
    if (rc == SY_EINPUT && err && !strstr(err->msg, name)) {
        sy_error e2 = *err;
        sy_fail(err, rc, "%s: %s", name, e2.msg);
    }
    return rc;
}

/* Each cut again takes lobes this much larger, at most this many times
 * (1.25^9 = 7.5 times the size asked: a tenth of the cloud's extent up to
 * three quarters), and never past the whole extent. */
#define LOBE_GROW 1.25
#define LOBE_GROW_STEPS 9

/* The cut's share of the reconstruction options. */
static sy_cut_options cut_options(const sy_skeleton_options *o)
{
    sy_cut_options c = sy_cut_options_default();
    c.clusters = o->clusters;
    c.fs = o->fs;
    c.min_points = o->min_cluster_points;
    c.spread_around = o->spread_around;
    c.lobe_size = o->lobe_size;
    return c;
}

sy_code sy_reconstruct_check(const sy_skeleton_options *o, sy_error *err)
{
    sy_cut_options co = cut_options(o);
    sy_code rc = sy_skeleton_options_check(o, err);
    return rc ? rc : sy_cut_options_check(&co, err);
}

sy_code sy_reconstruct_tree(const sy_cloud *c, const sy_skeleton_options *o, double alpha_scale, sy_skeleton *out,
                            sy_clusters *clusters, sy_skeleton_report *report, sy_hull_report *hulls, sy_error *err)
{
    memset(out, 0, sizeof *out);
    if (clusters) memset(clusters, 0, sizeof *clusters);
    sy_skeleton_report local;
    if (!report) report = &local;
    sy_hull_options ho = sy_hull_options_default();
    if (alpha_scale > 0) ho.alpha_scale = alpha_scale;
    sy_cut_options co = cut_options(o);
    sy_code rc = sy_hull_options_check(&ho, err);
    if (!rc) rc = sy_cut_options_check(&co, err);
    if (rc) return rc;
    /* The skeleton stage: the full skeleton, every point on a node. */
    sy_full_skeleton full;
    if ((rc = sy_reconstruct_skeleton(c, o, &full, report, err))) return rc;
    /* The clusters stage: cut, lobes, split, then the hulls. */
    sy_cut_report cut;
    rc = sy_clusters_extract(&full, c->xyz, &co, out, clusters, &cut, err);
    /* Lobes the .sylva cannot hold at a useful hull each are cut again,
     * larger: a dense crown (the simulated 250k-point trees) splits into
     * hundreds of small lobes. Not where the skeleton alone fills the file
     * (larger lobes cannot help) or the lobes already span the whole
     * extent. docs/synthesize.md "Lobes that fit". */
    for (int grow = 0; !rc && clusters && co.lobe_size > 0 && co.lobe_size < 1 && grow < LOBE_GROW_STEPS &&
                       clusters->n && sy_sylva_lobes_fit(0, out->n) && !sy_sylva_lobes_fit(clusters->n, out->n);
         grow++) {
        double seconds = cut.seconds;
        sy_clusters_free(clusters);
        sy_skeleton_free(out);
        co.lobe_size = fmin(1, co.lobe_size * LOBE_GROW);
        rc = sy_clusters_extract(&full, c->xyz, &co, out, clusters, &cut, err);
        cut.seconds += seconds;
    }
    sy_full_skeleton_free(&full);
    if (rc) return rc;
    /* Radii the returns bound, on the chains as the skeleton left them (level
     * sets, their ringed nodes moved onto their rings), before the fairing
     * smooths them along each limb; the trunk keeps its DBH fit up to breast
     * height. */
    double breast_z = report->breast_z;
    rc = sy_cap_radii_by_returns(out, c->xyz, o->return_cap, breast_z, &report->radii_capped, err);
    /* Faired after the cut, which judges the chains as the skeleton left
     * them (their points' spread about each edge). */
    if (rc || (rc = sy_skeleton_fair_limbs(out, o->fair_sigma, breast_z, err))) {
        if (clusters) sy_clusters_free(clusters);
        sy_skeleton_free(out);
        return rc;
    }
    report->limb_kinks = sy_skeleton_limb_kinks(out, 0.02, 60, &report->limb_turn_max);
    report->nodes = cut.nodes;
    report->branches = cut.branches;
    report->clusters = cut.clusters;
    report->cluster_points = cut.cluster_points;
    report->lobe_size = co.lobe_size;
    report->skeleton_points = cut.skeleton_points;
    report->t_clusters = cut.seconds;
    report->t_total += cut.seconds;
    if (!clusters) return SY_OK;
    /* The twigs the lobes' returns trace, in the room the .sylva has for
     * them (none for an airborne crown: its returns are its top's shell). */
    sy_twig_options to = sy_twig_options_default();
    to.max_nodes = report->stem_unseen || o->no_twigs ? 0 : sy_sylva_twig_budget(clusters->n, out->n);
    sy_twig_report twigs;
    if ((rc = sy_clusters_trace_twigs(clusters, out, c->xyz, &to, &twigs, err))) {
        sy_clusters_free(clusters);
        sy_skeleton_free(out);
        return rc;
    }
    ho.triangles = sy_sylva_hull_budget(clusters->n, out->n, twigs.nodes);
    /* An airborne crown, seen from above: the cells under a return are
     * hidden by it, not empty; each lobe's hull reaches in to the node it
     * hangs from and down to the crown's lowest return (what the scanner saw
     * is the crown's top; the foliage goes on under it). docs/skeleton.md
     * 8d: on six simulated airborne species against their true trees, IoU
     * mean 0.461 without the floor, 0.566 with it. */
    ho.seen_from_above = report->stem_unseen;
    float *anchors = NULL;
    if (report->stem_unseen && clusters->n) {
        if (!(anchors = sy_calloc(clusters->n, 3 * sizeof *anchors, err, "hulls"))) rc = SY_EINTERNAL;
        for (size_t k = 0; anchors && k < clusters->n; k++)
            memcpy(anchors + 3 * k, out->pos + 3 * (size_t)clusters->items[k].seed, 3 * sizeof *anchors);
        ho.anchors = anchors;
        double zlo = INFINITY, ztop = -INFINITY, root = out->n ? out->pos[2] : 0;
        for (size_t i = 0; i < c->n; i++) zlo = fmin(zlo, c->xyz[3 * i + 2]), ztop = fmax(ztop, c->xyz[3 * i + 2]);
        ho.floor.z = zlo;
        /* ... and at least to the species' crown base: the lower crown the
         * top hides from above (the airborne aspen's returns start at 8.6 m
         * of 13.6, its crown at 5.4). Seed-2 airborne scans of the 13
         * species against their true trees: IoU mean 0.577 -> 0.601 (birch
         * 0.619 -> 0.748, poplar 0.617 -> 0.721; pine -0.03, beech -0.02). */
        if (o->crown_base_share > 0) ho.floor.z = fmin(zlo, root + o->crown_base_share * (ztop - root));
        /* ... narrowing toward it as the species' crown does (a dome's
         * returns seen from above reach its widest part, and columns from
         * there stood as a box). */
        ho.floor.axis[0] = out->n ? out->pos[0] : 0, ho.floor.axis[1] = out->n ? out->pos[1] : 0;
        ho.floor.top = ztop;
        memcpy(ho.floor.profile, o->crown_profile, sizeof ho.floor.profile);
    }
    /* A terrestrial crown whose top the stations saw through its lower
     * crown: its lobes reach up to the crown's roof where its top stands
     * further under it than its species' own crown does (docs/synthesize.md
     * "Stop 46"). */
    sy_crown_roof roof;
    memset(&roof, 0, sizeof roof);
    if (!rc && !report->stem_unseen && clusters->n && o->crown_roof != 0) {
        rc = sy_crown_roof_build(c->xyz, c->n, SY_ROOF_CELLS, SY_ROOF_LIFT, &roof, err);
        report->roof_gap = rc ? 0 : sy_crown_roof_gap(&roof), report->roof_gap_species = o->crown_roof_gap;
        report->roofed = o->crown_roof == 1 ||
                         (o->crown_roof_gap > 0 && report->roof_gap > SY_ROOF_GAP_RATIO * o->crown_roof_gap &&
                          report->roof_gap > o->crown_roof_gap + SY_ROOF_GAP_MARGIN);
        if (report->roofed) ho.roof = &roof;
    }
    rc = rc ? rc : sy_clusters_build_hulls(clusters, c->xyz, &ho, hulls, err);
    /* Hulls that kept more triangles than their budget leave less room:
     * the twigs are traced again, coarser, to fit beside them. */
    size_t room = rc ? 0 : sy_sylva_twig_room(clusters, out->n);
    if (!rc && twigs.nodes > room) {
        double first = twigs.seconds;
        to.max_nodes = room;
        rc = sy_clusters_trace_twigs(clusters, out, c->xyz, &to, &twigs, err);
        twigs.seconds += first;
        /* None fit even at the coarsest voxel: the tree is one without
         * twigs, whose clusters store occupancy bits, and its hulls take
         * that budget. */
        if (!rc && twigs.nodes == 0) {
            double built = hulls ? hulls->seconds : 0;
            ho.triangles = sy_sylva_hull_budget(clusters->n, out->n, 0);
            rc = sy_clusters_build_hulls(clusters, c->xyz, &ho, hulls, err);
            if (hulls) hulls->seconds += built;
        }
    }
    if (rc) {
        sy_clusters_free(clusters);
        sy_skeleton_free(out);
    } else if (hulls) {
        hulls->twig_nodes = twigs.nodes, hulls->twig_voxel = twigs.voxel;
        hulls->seconds += twigs.seconds;
    }
    free(anchors);
    sy_crown_roof_free(&roof);
    return rc;
}

/* The voxel that thins a scan beyond the point budget (0 when within it or
 * when --voxel is given): applied in the preprocess voxel step, before the
 * outlier filter (k-nearest statistics on 1 M raw points cost more than all
 * the rest of the run). */
static sy_code budget_voxel(const sy_cloud *c, const sy_run_tree_options *o, double *voxel, sy_error *err)
{
    *voxel = 0;
    if (o->voxel > 0 || !o->max_points || c->n <= o->max_points) return SY_OK;
    return sy_voxel_size_for_count(c, o->max_points, voxel, err);
}

/* Preprocess: a clean, Z-up cloud of the tree alone. */
static sy_code clean(sy_cloud *c, const char *name, const sy_run_tree_options *o, double budget_voxel,
                     sy_run_tree_result *r, sy_error *err)
{
    double t = sy_now();
    sy_preprocess_options po = sy_preprocess_options_default();
    po.voxel = budget_voxel > 0 ? budget_voxel : o->voxel;
    po.remove_ground = 1; /* one tree: the ground would become a skeleton of its own */
    po.normals = 0;       /* the skeleton does not use them */
    po.keep_top = 0;      /* a crown's sparse top makes no skeleton; the height is taken to top_z */
    sy_preprocess_result pr;
    sy_code rc = sy_preprocess(c, &po, &pr, err);
    if (rc) return rc;
    r->t_preprocess = sy_now() - t;
    r->points_clean = c->n;
    r->top_z = pr.top_z;
    r->clean_top_z = -INFINITY;
    for (size_t i = 0; i < c->n; i++) r->clean_top_z = fmax(r->clean_top_z, c->origin[2] + c->xyz[3 * i + 2]);
    char line[160];
    snprintf(line, sizeof line, "%zu points left (up %s, %zu ground removed%s)", c->n, sy_up_name(pr.up_axis),
             pr.ground_points, budget_voxel > 0 ? ", thinned to the point budget first" : "");
    step(o, "preprocess", r->t_preprocess, line);
    if (c->n == 0) return sy_fail(err, SY_EINPUT, "%s: no points left after preprocessing", name);
    return SY_OK;
}

typedef struct nominal_tree nominal_tree;
static sy_code reconstruct_with(sy_cloud *c, const char *name, const sy_run_tree_options *o,
                                const sy_species_params *sp, const nominal_tree *nt, sy_run_tree_result *r,
                                sy_error *err);

/* Step lines for the thinning and any retry the checks made. */
static void report_checks(const sy_run_tree_options *o, const sy_tree_checks *k)
{
    char line[320];
    if (k->thinning_voxel > 0) {
        snprintf(line, sizeof line, "%zu -> %zu points (%.4f m voxels, point budget %zu)", k->points_before_thinning,
                 k->points_after_thinning, k->thinning_voxel, o->max_points);
        step(o, "thin", 0, line);
    }
    if (k->attempts > 1) {
        snprintf(line, sizeof line, "first skeleton failed the checks; passed after retrying with %s", k->retried);
        step(o, "checks", 0, line);
    }
}

/* The classifier sees the tree as its training scans were seen
 * (sy_classify_preprocess: 2 cm voxels, ground removed, no outlier filter),
 * from the points as read, not from the run's cleaned cloud: the outlier
 * filter strips the sparse crown edge and twigs the features measure (the
 * TreeLS pine is european_pine p 1.00 from its file, and was sugar_maple p
 * 0.89 from the run's cloud). It works on a copy of the positions and the
 * format (the up axis), made before the run cleans its cloud. A scan beyond
 * the point budget is thinned with the budget's voxel instead, when coarser
 * (the features' own sample is 4 cm voxels and up; the ground filter on 1 M
 * points cost 0.5 s), and a cloud too wide for 2 cm voxels (two trees 100 km
 * apart) with the finest voxel its extent allows. */
typedef struct {
    sy_cloud copy;
    const char *name;
    const sy_run_tree_options *o;
    double voxel;
    sy_species_guess *guess;
    sy_code rc;
    sy_error err;
} classify_job;

static sy_code classify_job_init(classify_job *J, const sy_cloud *raw, const char *name, const sy_run_tree_options *o,
                                 double voxel, sy_species_guess *guess, sy_error *err)
{
    memset(J, 0, sizeof *J);
    sy_code rc = sy_cloud_init(&J->copy, raw->n, err);
    if (rc) return rc;
    sy_cloud *t = &J->copy;
    memcpy(t->xyz, raw->xyz, raw->n * 3 * sizeof *t->xyz);
    memcpy(t->origin, raw->origin, sizeof t->origin);
    memcpy(t->meta.format, raw->meta.format, sizeof t->meta.format);
    memcpy(t->meta.version, raw->meta.version, sizeof t->meta.version);
    t->meta.point_format = raw->meta.point_format;
    J->voxel = fmax(SY_CLASSIFY_VOXEL, fmax(voxel, sy_voxel_finest(t)));
    J->name = name, J->o = o, J->guess = guess;
    return SY_OK;
}

static void classify_job_run(classify_job *J)
{
    double t0 = sy_now();
    J->rc = sy_classify_preprocess(&J->copy, J->name, J->voxel, &J->err);
    if (J->rc == SY_EINPUT && J->copy.n < SY_FEATURES_MIN_POINTS) {
        J->err = (sy_error){0};
        J->rc = SY_OK; /* a handful of returns: sy_classify_cloud reports it too few, unknown */
    }
    if (!J->rc) J->rc = sy_classify_cloud(&J->copy, J->o->model, J->guess, &J->err);
    if (!J->rc) J->guess->seconds = sy_now() - t0;
    sy_cloud_free(&J->copy);
}

/* The classification of the copy and the run's own cleaning are
 * independent; each spends much of its time on one thread (PCL's ground
 * filter, the voxel sort), so they run side by side. */
typedef struct {
    classify_job *classify;
    sy_cloud *c;
    const char *name;
    const sy_run_tree_options *o;
    double voxel;
    sy_run_tree_result *r;
    sy_code rc;
    sy_error err;
} prepare_job;

static void prepare_part(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)end, (void)chunk;
    prepare_job *P = ctx;
    if (begin == 1) classify_job_run(P->classify);
    else P->rc = clean(P->c, P->name, P->o, P->voxel, P->r, &P->err);
}

/* The scan's crown base over its height: the lowest of CROWN_SLABS_SCAN
 * height slabs whose returns spread wider than a tenth of the height (the
 * 90th percentile of their horizontal distance from the slab's mean),
 * above a lowest slab (of 10 returns or more) narrower than that: a stem
 * in view. -1 when the lowest slab is already wide (no stem seen: an airborne crown, a bush) or
 * no slab is (a pole). */
#define CROWN_SLABS_SCAN 20
#define CROWN_SPREAD_SHARE 0.1
static double scan_crown_base_share(const sy_cloud *c)
{
    if (c->n < 100) return -1;
    float zlo = c->xyz[2], zhi = c->xyz[2];
    for (size_t i = 1; i < c->n; i++) zlo = fminf(zlo, c->xyz[3 * i + 2]), zhi = fmaxf(zhi, c->xyz[3 * i + 2]);
    double h = (double)zhi - zlo;
    if (!(h > 0)) return -1;
    double sum[CROWN_SLABS_SCAN][3] = {{0}};
    size_t start[CROWN_SLABS_SCAN + 1] = {0};
    int *slab = malloc(c->n * sizeof *slab);
    double *d = malloc(c->n * sizeof *d);
    if (!slab || !d) {
        free(slab), free(d);
        return -1;
    }
    for (size_t i = 0; i < c->n; i++) {
        int k = (int)((c->xyz[3 * i + 2] - zlo) / h * CROWN_SLABS_SCAN);
        slab[i] = k >= CROWN_SLABS_SCAN ? CROWN_SLABS_SCAN - 1 : k;
        sum[slab[i]][0] += c->xyz[3 * i], sum[slab[i]][1] += c->xyz[3 * i + 1], sum[slab[i]][2] += 1;
        start[slab[i] + 1]++;
    }
    for (int k = 0; k < CROWN_SLABS_SCAN; k++) start[k + 1] += start[k];
    size_t fill[CROWN_SLABS_SCAN];
    memcpy(fill, start, sizeof fill);
    for (size_t i = 0; i < c->n; i++) {
        const double *m = sum[slab[i]];
        d[fill[slab[i]]++] = hypot(c->xyz[3 * i] - m[0] / m[2], c->xyz[3 * i + 1] - m[1] / m[2]);
    }
    double share = -1;
    for (int k = 0, first = 1; k < CROWN_SLABS_SCAN; k++) {
        size_t m = start[k + 1] - start[k];
        if (m < 10) continue;
        if (sy_select_double(d + start[k], m, (size_t)(0.9 * (double)(m - 1))) > CROWN_SPREAD_SHARE * h) {
            if (!first) share = (double)k / CROWN_SLABS_SCAN;
            break;
        }
        first = 0;
    }
    free(slab), free(d);
    return share;
}

/* The species' nominal tree (Weber-Penn, seed 1; a few milliseconds): its
 * DBH over its height, the allometry (height-diameter curves by species are
 * how inventories fill in a stem the survey could not measure), and its
 * crown base over its height; each 0 when it cannot be grown or measured. */
_Static_assert(sizeof(((sy_skeleton_options *)0)->crown_profile) == SY_CROWN_SLABS * sizeof(float),
               "the skeleton options carry the clusters stage's crown profile");

struct nominal_tree {
    double dbh_per_height, crown_base_share, roof_gap;
    float profile[SY_CROWN_SLABS];
};

static void species_nominal(const sy_species_params *sp, nominal_tree *nt)
{
    sy_skeleton t;
    sy_error err = {0};
    memset(nt, 0, sizeof *nt);
    if (sy_grow_tree(sp, 1, &t, NULL, &err)) return;
    double h = sy_skeleton_height(&t), d = sy_skeleton_dbh(&t);
    /* The crown base: the lowest node off the trunk (Weber-Penn's BaseSize
     * of the stem bare of branches). */
    double zb = INFINITY, zt = -INFINITY;
    for (size_t i = 0; i < t.n; i++) {
        if (t.order[i] >= 1) zb = fmin(zb, t.pos[3 * i + 2]);
        zt = fmax(zt, t.pos[3 * i + 2]);
    }
    if (t.n && h > 0 && isfinite(zb)) nt->crown_base_share = fmin(fmax((zb - t.pos[2]) / h, 0), 1);
    /* The crown's profile: per slab from its base to its top, the farthest
     * branch node from the trunk's foot (the species' own crown shape, as
     * Weber & Penn's Shape and the branch angles draw it). */
    if (t.n && isfinite(zb) && zt > zb)
        for (size_t i = 0; i < t.n; i++) {
            if (t.order[i] < 1) continue;
            int k = (int)((t.pos[3 * i + 2] - zb) / (zt - zb) * SY_CROWN_SLABS);
            k = k < 0 ? 0 : k >= SY_CROWN_SLABS ? SY_CROWN_SLABS - 1 : k;
            float r = hypotf(t.pos[3 * i] - t.pos[0], t.pos[3 * i + 1] - t.pos[1]);
            if (r > nt->profile[k]) nt->profile[k] = r;
        }
    /* How far its crown's top stands under its roof, from its branch nodes
     * (as a scan's from its returns). */
    float *crown = t.n ? malloc(3 * t.n * sizeof *crown) : NULL;
    if (crown) {
        size_t m = 0;
        for (size_t i = 0; i < t.n; i++)
            if (t.order[i] >= 1) memcpy(crown + 3 * m++, t.pos + 3 * i, 3 * sizeof *crown);
        sy_crown_roof roof;
        memset(&roof, 0, sizeof roof);
        if (m && !sy_crown_roof_build(crown, m, SY_ROOF_CELLS, SY_ROOF_LIFT, &roof, &err))
            nt->roof_gap = sy_crown_roof_gap(&roof);
        sy_crown_roof_free(&roof);
        free(crown);
    }
    sy_skeleton_free(&t);
    if (h > 1.3 && d > 0 && d / h < 1) nt->dbh_per_height = d / h;
}

/* The classifier learnt its species from simulated scans, and a real scan
 * unlike all of them can still take one with confidence: rTwig's leaf-off
 * sapling, branched from 0.45 of its height, came out a palm (p 0.97). A
 * species grown with a bare bole over more than BARE_BOLE_SHARE of its
 * height (the library's palm: 0.78; the next, the pine, 0.46) is ruled out
 * for a scan whose crown starts more than BOLE_MARGIN of its height lower
 * (drooping fronds bring the simulated palm's scan to 0.65), and the most
 * probable species left is taken. The guess keeps its probabilities and
 * names what was ruled out. *sp and *nt hold the guess's parameters and
 * nominal tree on entry, the species taken's on return; *none: no species
 * is left (unknown). */
#define BARE_BOLE_SHARE 0.5
#define BOLE_MARGIN 0.3
static sy_code rule_out_by_crown_base(const sy_cloud *c, sy_species_guess *g, sy_species_params *sp,
                                      nominal_tree *nt, int *none, sy_error *err)
{
    *none = 0;
    double nominal = nt->crown_base_share;
    if (nominal <= BARE_BOLE_SHARE) return SY_OK;
    double scan = scan_crown_base_share(c);
    if (scan < 0 || scan >= nominal - BOLE_MARGIN) return SY_OK;
    snprintf(g->ruled_out, sizeof g->ruled_out, "%s", g->name);
    g->crown_base_scan = scan, g->crown_base_species = nominal;
    sy_library lib;
    sy_code rc = sy_library_load(NULL, &lib, err);
    if (rc) return rc;
    /* A species ruled out gets probability 0, so batch's report, which
     * decides again from the probabilities, cannot bring it back; one whose
     * file does not load is skipped. Each turn removes a candidate. */
    uint8_t *skip = sy_calloc(g->species.n_classes + 1, 1, err, "species");
    if (!skip) {
        sy_library_free(&lib);
        return SY_EINTERNAL;
    }
    float *p = g->species.probabilities;
    p[g->species.id] = 0;
    int taken = -1;
    for (;;) {
        int best = -1;
        for (size_t k = 0; k < g->species.n_classes; k++)
            if (!skip[k] && p[k] > 0 && (best < 0 || p[k] > p[best])) best = (int)k;
        if (best < 0) break;
        const sy_library_entry *e = sy_library_by_id(&lib, best);
        sy_species_params cand;
        sy_error e2 = {0};
        if (!e || sy_library_params(&lib, e, &cand, &e2)) {
            skip[best] = 1;
            continue;
        }
        nominal_tree cand_nt;
        species_nominal(&cand, &cand_nt);
        double base = cand_nt.crown_base_share;
        if (base > BARE_BOLE_SHARE && scan < base - BOLE_MARGIN) {
            sy_species_params_free(&cand); /* ruled out as well: the next */
            p[best] = 0;
            continue;
        }
        sy_species_params_free(sp);
        *sp = cand, *nt = cand_nt;
        taken = best;
        break;
    }
    const sy_library_entry *e = taken >= 0 ? sy_library_by_id(&lib, taken) : NULL;
    snprintf(g->name, sizeof g->name, "%s", e ? e->name : "unknown");
    snprintf(g->species.name, sizeof g->species.name, "%s", e ? e->name : "");
    g->species.id = taken;
    g->taken_probability = taken >= 0 ? p[taken] : 0;
    *none = taken < 0;
    free(skip);
    sy_library_free(&lib);
    return SY_OK;
}

static sy_code reconstruct(sy_cloud *c, const char *name, const sy_run_tree_options *o,
                           const sy_species_params *sp, sy_run_tree_result *r, sy_error *err)
{
    /* No species given: the classifier names one, and a confident answer
     * brings its parameters and materials. */
    int classify = !sp && !o->species && o->classify;
    double voxel;
    sy_code rc = budget_voxel(c, o, &voxel, err);
    classify_job cj = {.rc = SY_OK};
    if (!rc && classify) rc = classify_job_init(&cj, c, name, o, voxel, &r->guess, err);
    if (rc) return rc;
    prepare_job P = {&cj, c, name, o, voxel, r, SY_OK, {0}};
    sy_parallel_for(classify ? 2 : 1, 1, prepare_part, &P);
    r->classified = classify && cj.rc == SY_OK; /* the guess is freed with the result */
    /* The classification's error first, as when it ran before the cleaning. */
    if (classify && cj.rc) {
        *err = cj.err;
        return cj.rc;
    }
    if (P.rc) {
        *err = P.err;
        return P.rc;
    }
    sy_species_params guessed;
    int have_guess = 0;
    nominal_tree nt;
    if (sp) species_nominal(sp, &nt);
    if (classify) {
        if (r->guess.species.id >= 0) {
            if ((rc = sy_species_params_find(r->guess.name, &guessed, err))) return rc;
            species_nominal(&guessed, &nt);
            int none;
            if ((rc = rule_out_by_crown_base(c, &r->guess, &guessed, &nt, &none, err))) {
                sy_species_params_free(&guessed);
                return rc;
            }
            if (none) sy_species_params_free(&guessed);
            else sp = &guessed, have_guess = 1, r->species_id = r->guess.species.id;
        }
        char line[320], ruled[160] = "";
        if (r->guess.ruled_out[0])
            snprintf(ruled, sizeof ruled, "; %s ruled out: crown from %.2f of the height, the species' from %.2f",
                     r->guess.ruled_out, r->guess.crown_base_scan, r->guess.crown_base_species);
        if (r->guess.too_few)
            snprintf(line, sizeof line, "unknown (%zu points: too few to classify, at least %d)", r->guess.too_few,
                     SY_FEATURES_MIN_POINTS);
        else
            snprintf(line, sizeof line, "%s (%s; best %s p %.2f%s)", r->guess.name,
                     r->guess.confident ? "confident" : r->guess.novel ? "unlike the training trees" : "not confident",
                     r->guess.best, r->guess.probability, ruled);
        step(o, "species", r->guess.seconds, line);
    }
    rc = reconstruct_with(c, name, o, sp, sp ? &nt : NULL, r, err);
    if (have_guess) sy_species_params_free(&guessed);
    return rc;
}

/* The share of the cloud's returns within spacing of the surface of wood
 * (each edge a truncated cone): how much of the scan the leaf-off tree
 * draws as it stands. NaN without returns, a spacing or an edge of wood. */
static sy_code returns_on_wood(const sy_cloud *c, const sy_skeleton *wood, double spacing, double *share,
                               sy_error *err)
{
    *share = NAN;
    if (!c->n || !(spacing > 0) || wood->n < 2) return SY_OK; /* nothing to measure: the cards stay */
    double *pts = sy_cloud_world_points(c, err), *dist = pts ? sy_calloc(c->n, sizeof *dist, err, "run") : NULL;
    if (!dist) {
        free(pts);
        return SY_EINTERNAL;
    }
    /* The model borrows the skeleton: nothing of it is freed here. */
    sy_eval_tree tree = {.tree_id = -1, .species_id = -1, .skel = *wood};
    sy_eval_model m = {0};
    m.skeletons.n_trees = 1, m.skeletons.trees = &tree;
    sy_code rc = sy_model_distances(&m, pts, c->n, dist, err);
    if (!rc) *share = sy_coverage(dist, c->n, spacing);
    free(pts), free(dist);
    return rc;
}

/* The tree from r->sylva: leaf-off when asked (o->leaf_off > 0) or, left to
 * the scan (0), when its returns lie on the leaf-off tree's wood: decoded
 * leaf-off first, kept at SY_LEAF_OFF_RETURNS, else decoded again with its
 * cards. Only lobes with traced twigs can draw their returns as wood (without
 * any, the lobes' returns, most of a crown's, lie off it), and twigs traced at
 * voxels finer than SY_LEAF_OFF_MIN_VOXEL spacings run through nearly every
 * return, leaves or not, and tell nothing. A leaf-off tree's .sylva is
 * flagged. *spacing gets the scan's own spacing where it was judged (a
 * retried reconstruction's, sr->spacing, is doubled). On failure dt holds
 * nothing to free. */
static sy_code decode_tree(const sy_cloud *c, const sy_clusters *cl, const char *name, const sy_run_tree_options *o,
                           const sy_species_params *sp, sy_run_tree_result *r, sy_decoded_tree *dt, double *spacing,
                           sy_error *err)
{
    r->returns_on_wood = NAN;
    int twigs = 0;
    for (size_t k = 0; k < cl->n && !twigs; k++) twigs = cl->items[k].n_twigs > 0;
    int test = 0;
    if (o->leaf_off == 0 && twigs) {
        *spacing = sy_estimate_spacing(c->xyz, c->n);
        test = r->hulls.twig_voxel >= SY_LEAF_OFF_MIN_VOXEL * *spacing;
    }
    sy_code rc = sy_decoded_tree_build(name, r->sylva, r->sylva_size, sp, o->leaf_off > 0 || test, dt, err);
    if (rc) return rc;
    if (test) {
        rc = returns_on_wood(c, &dt->grown, *spacing, &r->returns_on_wood, err);
        if (!rc && !(r->returns_on_wood >= SY_LEAF_OFF_RETURNS)) {
            sy_decoded_tree_free(dt);
            if ((rc = sy_decoded_tree_build(name, r->sylva, r->sylva_size, sp, 0, dt, err))) return rc;
        }
    }
    if (!rc && dt->leaf_off) rc = sy_sylva_set_flags(r->sylva, r->sylva_size, SY_SYLVA_LEAF_OFF, err);
    if (rc) sy_decoded_tree_free(dt);
    return rc;
}

static sy_code reconstruct_with(sy_cloud *c, const char *name, const sy_run_tree_options *o,
                                const sy_species_params *sp, const nominal_tree *nt, sy_run_tree_result *r,
                                sy_error *err)
{
    sy_code rc;
    sy_skeleton_options so = sy_skeleton_options_default();
    if (sp) {
        so.beta = sp->beta, so.gamma = sp->gamma;
        so.dbh_per_height = nt->dbh_per_height, so.crown_base_share = nt->crown_base_share;
        memcpy(so.crown_profile, nt->profile, sizeof so.crown_profile);
        so.crown_roof_gap = nt->roof_gap;
        so.no_twigs = !sp->twigs;
        so.stem_taper = sp->level[0].taper < 1 ? sp->level[0].taper : 1;
    }
    if (!isnan(o->beta)) so.beta = o->beta;
    if (!isnan(o->gamma)) so.gamma = o->gamma;
    so.fs = o->fs;
    so.wood_share = o->wood_share;
    so.spread_around = o->spread_around;
    so.unfold_hairpins = !o->keep_hairpins;
    if (!isnan(o->fair_sigma)) so.fair_sigma = o->fair_sigma;
    if (!isnan(o->return_cap)) so.return_cap = o->return_cap;
    /* A crown of fronds is one rosette on the stem's top: one lobe, whose
     * fronds all leave the stem's top metre (sy_synth_options.fronds). Cut
     * into lobes of a tenth of the tree, fronds from there drew a frond per
     * few returns: 1,211 rachises on the bundled palm, a broom. */
    so.lobe_size = o->lobe_size >= 0 ? o->lobe_size : so.no_twigs ? 1 : SY_RUN_LOBE_SIZE;
    so.crown_roof = o->roof;
    sy_skeleton s;
    sy_clusters cl;
    sy_skeleton_report *sr = &r->skeleton;
    rc = sy_reconstruct_tree_checked(c, name, &so, 0, o->max_points, &s, &cl, sr, &r->hulls, &r->checks, err);
    if (rc) return name_input(rc, name, err);
    /* Height to the crown's top as scanned, not as the outlier filter left it. */
    if (isfinite(r->top_z) && isfinite(r->clean_top_z) && r->top_z > r->clean_top_z)
        sr->height += r->top_z - r->clean_top_z;
    char line[512];
    report_checks(o, &r->checks);
    snprintf(line, sizeof line, "%zu nodes, %zu branches, DBH %.3f m, height %.2f m", sr->nodes, sr->branches,
             sr->dbh, sr->height);
    step(o, "skeleton", sr->t_total - sr->t_clusters, line);
    snprintf(line, sizeof line, "%zu clusters (%zu alpha, %zu convex, %zu box), %zu points, %zu twig nodes (%.3f m voxels)",
             sr->clusters, r->hulls.alpha, r->hulls.convex, r->hulls.box, sr->cluster_points, r->hulls.twig_nodes,
             r->hulls.twig_voxel);
    step(o, "clusters", sr->t_clusters + r->hulls.seconds, line);

    /* Everything after the reconstruction reads the .sylva image (the scan's
     * own frame), as `sylva mesh OUT.sylva` does: the same bytes give the
     * same tree. */
    int id = r->species_id;
    uint16_t sid = (uint16_t)(id >= 0 && id < 65535 ? id + 1 : 0);
    rc = sy_encode_mem(&s, &cl, sid, o->seed, NULL, &r->sylva, &r->sylva_size, err);
    sy_decoded_tree dt;
    double spacing = 0;
    if (!rc) {
        double t = sy_now();
        rc = decode_tree(c, &cl, name, o, sp, r, &dt, &spacing, err);
        r->t_synth = sy_now() - t;
    }
    int have_tree = !rc;
    sy_cloud_free(c);
    if (!rc) {
        r->synth = dt.synth;
        r->leaf_off = dt.leaf_off;
        if (dt.leaf_off) r->synth.leaves = r->synth.leaves_in_hull = 0;
        if (!isnan(r->returns_on_wood)) {
            snprintf(line, sizeof line, "%s: %.0f %% of the returns lie within %.3f m of the traced wood (leaf-off from %.0f %%)",
                     dt.leaf_off ? "leaf-off" : "leaves", 100 * r->returns_on_wood, spacing, 100 * SY_LEAF_OFF_RETURNS);
            step(o, "leaves", 0, line);
        }
        const char *lsys = strrchr(dt.lsys, '/') ? strrchr(dt.lsys, '/') + 1 : dt.lsys;
        snprintf(line, sizeof line, "%zu patches (%.60s: %zu branchlets, %zu patches), %zu leaves, %zu lobes bare",
                 dt.synth.patches, lsys, dt.branchlets, dt.patches, dt.synth.leaves, dt.synth.lobes_bare);
        step(o, "synthesize", r->t_synth, line);
        for (size_t i = 0; i < dt.synth.lobes_bare && i < 8; i++) {
            int32_t c = dt.synth.bare_lobe[i];
            snprintf(line, sizeof line, "lobe %d (node %d): %s", (int)c,
                     c >= 0 && (size_t)c < dt.lobes.n ? (int)dt.lobes.items[c].seed : -1,
                     sy_synth_bare_reason(dt.synth.bare_reason[i]));
            step(o, "synthesize", 0, line);
        }
        sy_tree_asset_options ao = o->asset;
        ao.seed = o->seed;
        ao.keep_leaf_order = 1;
        ao.hulls = o->proxy ? &dt.lobes : NULL;
        ao.lean_radius = dt.lean_radius;
        ao.source = name;
        ao.source_format = "scan";
        /* A leaf-off scan: its traced twigs and branches without cards. */
        rc = sy_tree_asset_glb(&dt.grown, dt.leaf_off ? NULL : &dt.leaves, sp, &ao, name, &r->glb, &r->glb_size,
                               &r->asset, err);
    }
    if (have_tree) sy_decoded_tree_free(&dt);
    if (!o->sylva) {
        free(r->sylva);
        r->sylva = NULL;
        r->sylva_size = 0;
    }
    if (!rc) {
        const sy_tree_asset_report *a = &r->asset;
        snprintf(line, sizeof line, "%zu levels, LOD0 %zu triangles (%zu leaf cards, %zu of them hulls)", a->lods,
                 a->triangles[0], a->leaf_cards[0], a->hull_triangles);
        step(o, "mesh", a->seconds_mesh, line);
        snprintf(line, sizeof line, "%zu bytes", a->bytes);
        step(o, "export", a->seconds_export, line);
    }
    sy_clusters_free(&cl);
    sy_skeleton_free(&s);
    return rc;
}

/* Checks the options and loads the species (before any input is read, so
 * a bad option or species fails fast). *spp is NULL without a species. */
static sy_code prepare(const sy_run_tree_options *o, sy_species_params *sp, const sy_species_params **spp,
                       sy_run_tree_result *r, sy_error *err)
{
    *spp = NULL;
    r->species_id = -1;
    sy_code rc = sy_run_tree_options_check(o, err);
    if (rc || !o->species) return rc;
    if ((rc = sy_species_params_find(o->species, sp, err))) return rc;
    *spp = sp;
    r->species_id = sy_library_id(o->species);
    return SY_OK;
}

static sy_code finish(sy_code rc, sy_cloud *c, sy_species_params *sp, const sy_species_params *spp,
                      sy_run_tree_result *r)
{
    sy_cloud_free(c); /* reconstruct frees it early on success; freeing twice is safe */
    if (spp) sy_species_params_free(sp);
    if (rc) sy_run_tree_result_free(r);
    return rc;
}

sy_code sy_run_tree_cloud(sy_cloud *c, const char *name, const sy_run_tree_options *o, sy_run_tree_result *r,
                          sy_error *err)
{
    memset(r, 0, sizeof *r);
    r->points_in = c->n;
    sy_species_params sp;
    const sy_species_params *spp;
    sy_code rc = prepare(o, &sp, &spp, r, err);
    if (!rc) rc = reconstruct(c, name, o, spp, r, err);
    return finish(rc, c, &sp, spp, r);
}

sy_code sy_run_tree(const char *path, const sy_run_tree_options *o, sy_run_tree_result *r, sy_error *err)
{
    memset(r, 0, sizeof *r);
    sy_species_params sp;
    const sy_species_params *spp;
    sy_code rc = prepare(o, &sp, &spp, r, err);
    if (rc) return rc;
    double t = sy_now();
    sy_cloud c;
    if ((rc = sy_read_cloud(path, &c, err))) return finish(rc, NULL, &sp, spp, r);
    r->t_ingest = sy_now() - t;
    r->points_in = c.n;
    char line[64];
    snprintf(line, sizeof line, "%zu points", c.n);
    step(o, "ingest", r->t_ingest, line);
    rc = reconstruct(&c, path, o, spp, r, err);
    return finish(rc, &c, &sp, spp, r);
}

sy_code sy_run_tree_write(const sy_run_tree_result *r, const char *glb_path, const char *sylva_path, sy_error *err)
{
    if (sylva_path && !r->sylva) return sy_fail(err, SY_EINTERNAL, "%s: the run made no .sylva file", sylva_path);
    /* Staged and committed together, the glb (what a batch checks for) last:
     * a kill never leaves a glb beside another run's .sylva. */
    sy_staged_output out[2];
    size_t n = 0;
    sy_code rc = SY_OK;
    if (sylva_path && !(rc = sy_stage_output(&out[n], sylva_path, err))) {
        n++;
        rc = sy_write_file_atomic(out[0].staged, r->sylva, r->sylva_size, err);
    }
    if (!rc && !(rc = sy_stage_output(&out[n], glb_path, err))) {
        n++;
        rc = sy_write_file_atomic(out[n - 1].staged, r->glb, r->glb_size, err);
    }
    if (!rc) return sy_stage_commit(out, n, err);
    sy_stage_abort(out, n);
    return rc;
}
