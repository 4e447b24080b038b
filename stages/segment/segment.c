/* Segment: options, the normalised-height frame, the method choice, and the
 * per-tree table every method ends in. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "segment_internal.h"
#include "stages/core/progress.h"
#include "stages/preprocess/preprocess.h"

int sy_segment_method_parse(const char *text, sy_segment_method *m)
{
    if (!text) return -1;
    if (!strcmp(text, "auto")) *m = SY_SEGMENT_AUTO;
    else if (!strcmp(text, "terrestrial") || !strcmp(text, "tls")) *m = SY_SEGMENT_TERRESTRIAL;
    else if (!strcmp(text, "airborne") || !strcmp(text, "als")) *m = SY_SEGMENT_AIRBORNE;
    else return -1;
    return 0;
}

const char *sy_segment_method_name(sy_segment_method m)
{
    switch (m) {
    case SY_SEGMENT_TERRESTRIAL: return "terrestrial";
    case SY_SEGMENT_AIRBORNE: return "airborne";
    default: return "auto";
    }
}

sy_segment_options sy_segment_options_default(void)
{
    sy_segment_options o;
    memset(&o, 0, sizeof o);
    o.method = SY_SEGMENT_AUTO;
    o.auto_density = 10;
    o.ground_cell = 0.5;
    o.ground_threshold = 0.15;
    o.ground_max_window = 16;
    o.breast_height = 1.3;
    o.slice = 0.6;
    o.stem_min_radius = 0.025;
    o.stem_max_radius = 1.0;
    o.circle_tolerance = 0.025;
    o.stem_min_points = 30;
    o.stem_cluster_gap = 0.1;
    o.min_arc = 0.35;
    o.single_band_arc = 0.5;
    o.min_facing = 0.5;
    o.voxel = 0.15;
    o.graph_reach = 2;
    o.gap_penalty = 1.0;
    o.chm_cell = 0.5;
    o.min_height = 2.0;
    o.window_base = 3.0;
    o.window_slope = 0.15;
    o.window_max = 10;
    o.seed_ratio = 0.45;
    o.crown_ratio = 0.55;
    o.max_crown_radius = 8;
    o.min_points = 20;
    o.seed = 1;
    return o;
}

static int positive(double v) { return v > 0 && isfinite(v); }

sy_code sy_segment_options_check(const sy_segment_options *o, sy_error *err)
{
    const char *bad = NULL;
    if (o->method != SY_SEGMENT_AUTO && o->method != SY_SEGMENT_TERRESTRIAL && o->method != SY_SEGMENT_AIRBORNE)
        bad = "method: expected auto, terrestrial or airborne";
    else if (!(o->auto_density >= 0 && isfinite(o->auto_density))) bad = "auto_density: must be >= 0 points per m^2";
    else if (!positive(o->ground_cell)) bad = "ground_cell: must be a positive number of metres";
    else if (!positive(o->ground_threshold)) bad = "ground_threshold: must be a positive number of metres";
    else if (!(o->ground_max_window >= o->ground_cell && isfinite(o->ground_max_window)))
        bad = "ground_max_window: must be at least ground_cell";
    else if (!positive(o->breast_height) || o->breast_height > 10) bad = "breast_height: must be in (0, 10] metres";
    else if (!positive(o->slice) || o->slice > 2 * o->breast_height)
        bad = "slice: must be positive and at most twice breast_height";
    else if (!positive(o->stem_min_radius) || !positive(o->stem_max_radius) || o->stem_min_radius >= o->stem_max_radius ||
             o->stem_max_radius > 5)
        bad = "stem_min_radius/stem_max_radius: need 0 < min < max <= 5 metres";
    else if (!positive(o->circle_tolerance) || o->circle_tolerance > 0.5) bad = "circle_tolerance: must be in (0, 0.5] metres";
    else if (o->stem_min_points < 5 || o->stem_min_points > 100000) bad = "stem_min_points: must be 5..100000";
    else if (!positive(o->stem_cluster_gap) || o->stem_cluster_gap > 2) bad = "stem_cluster_gap: must be in (0, 2] metres";
    else if (!(o->min_arc >= 0 && o->min_arc <= 1)) bad = "min_arc: must be in [0, 1]";
    else if (!(o->single_band_arc >= 0 && o->single_band_arc <= 1)) bad = "single_band_arc: must be in [0, 1]";
    else if (!(o->min_facing >= 0 && o->min_facing <= 1)) bad = "min_facing: must be in [0, 1]";
    else if (!(o->voxel >= 0.01 && o->voxel <= 5)) bad = "voxel: must be in [0.01, 5] metres";
    else if (o->graph_reach < 1 || o->graph_reach > 4) bad = "graph_reach: must be 1..4 voxels";
    else if (!(o->gap_penalty >= 0 && o->gap_penalty <= 8)) bad = "gap_penalty: must be in [0, 8]";
    else if (!(o->chm_cell >= 0.05 && o->chm_cell <= 10)) bad = "chm_cell: must be in [0.05, 10] metres";
    else if (!(o->min_height >= 0 && o->min_height < 100)) bad = "min_height: must be in [0, 100) metres";
    else if (!positive(o->window_base) || !(o->window_slope >= 0 && o->window_slope < 10) ||
             !(o->window_max >= o->window_base && o->window_max <= 100))
        bad = "window_base/window_slope/window_max: need base > 0, slope >= 0, base <= max <= 100 metres";
    else if (!(o->seed_ratio >= 0 && o->seed_ratio <= 1) || !(o->crown_ratio >= 0 && o->crown_ratio <= 1))
        bad = "seed_ratio/crown_ratio: must be in [0, 1]";
    else if (!positive(o->max_crown_radius) || o->max_crown_radius > 100) bad = "max_crown_radius: must be in (0, 100] metres";
    if (bad) return sy_fail(err, SY_EUSAGE, "segment: %s", bad);
    return SY_OK;
}

/* ------------------------------------------------------------ the frame */

sy_code seg_frame_build(const sy_cloud *plot, const sy_segment_options *o, seg_frame *f, sy_error *err)
{
    memset(f, 0, sizeof *f);
    f->n = plot->n;
    f->xyz = plot->xyz;
    memcpy(f->origin, plot->origin, sizeof f->origin);
    /* The ground filter classifies in place: give it a positions-only copy. */
    sy_cloud tmp;
    sy_code rc = sy_cloud_init(&tmp, plot->n, err);
    if (rc) return rc;
    memcpy(tmp.xyz, plot->xyz, plot->n * 3 * sizeof(float));
    memcpy(tmp.origin, plot->origin, sizeof tmp.origin);
    sy_preprocess_options po = sy_preprocess_options_default();
    po.ground_cell = o->ground_cell;
    po.ground_threshold = o->ground_threshold;
    po.ground_max_window = o->ground_max_window;
    size_t n_ground = 0;
    rc = sy_classify_ground(&tmp, &po, &n_ground, err);
    if (rc == SY_OK) {
        f->ground = sy_calloc(plot->n ? plot->n : 1, 1, err, "ground flags");
        for (size_t a = 0; a < tmp.n_attrs; a++)
            if (!strcmp(tmp.attrs[a].name, "height_above_ground")) {
                f->hag = tmp.attrs[a].values; /* taken over */
                tmp.attrs[a].values = NULL;
            }
        if (!f->ground || !f->hag || !tmp.classification) rc = sy_fail(err, SY_EINTERNAL, "segment: ground heights missing");
    }
    if (rc == SY_OK) {
        for (size_t i = 0; i < plot->n; i++) f->ground[i] = tmp.classification[i] == 2;
        /* Bounds of the float positions themselves, so (x - lo) / cell is never negative. */
        for (int k = 0; k < 3; k++) f->lo[k] = INFINITY, f->hi[k] = -INFINITY;
        for (size_t i = 0; i < plot->n; i++)
            for (int k = 0; k < 3; k++) {
                double v = plot->xyz[3 * i + k];
                if (v < f->lo[k]) f->lo[k] = v;
                if (v > f->hi[k]) f->hi[k] = v;
            }
        /* Occupied area on a 1 m grid: the density auto-detection reads. */
        double w = floor(f->hi[0] - f->lo[0]) + 1, h = floor(f->hi[1] - f->lo[1]) + 1;
        if (w * h <= 4e7) {
            size_t nx = (size_t)w, ny = (size_t)h;
            uint8_t *occ = sy_calloc(nx * ny, 1, err, "occupancy");
            if (!occ) rc = SY_EINTERNAL;
            else {
                size_t cells = 0;
                for (size_t i = 0; i < plot->n; i++) {
                    size_t ix = (size_t)(plot->xyz[3 * i] - f->lo[0]), iy = (size_t)(plot->xyz[3 * i + 1] - f->lo[1]);
                    if (ix >= nx) ix = nx - 1;
                    if (iy >= ny) iy = ny - 1;
                    cells += !occ[iy * nx + ix];
                    occ[iy * nx + ix] = 1;
                }
                f->area = (double)cells;
                free(occ);
            }
        } else {
            f->area = w * h;
        }
    }
    sy_cloud_free(&tmp);
    if (rc) seg_frame_free(f);
    return rc;
}

void seg_frame_free(seg_frame *f)
{
    free(f->hag);
    free(f->ground);
    memset(f, 0, sizeof *f);
}

/* ------------------------------------------------------- map and heap */

static uint64_t hash64(uint64_t z)
{
    z += 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

sy_code seg_map_init(seg_map *m, size_t n, sy_error *err)
{
    size_t cap = 16;
    while (cap < 2 * n + 16) cap <<= 1;
    m->mask = cap - 1;
    m->keys = malloc(cap * sizeof *m->keys);
    m->vals = malloc(cap * sizeof *m->vals);
    if (!m->keys || !m->vals) {
        seg_map_free(m);
        return sy_fail(err, SY_EINTERNAL, "segment: out of memory for a %zu-entry map", n);
    }
    memset(m->keys, 0xff, cap * sizeof *m->keys);
    return SY_OK;
}

void seg_map_put(seg_map *m, uint64_t key, uint32_t val)
{
    size_t i = (size_t)hash64(key) & m->mask;
    while (m->keys[i] != UINT64_MAX && m->keys[i] != key) i = (i + 1) & m->mask;
    m->keys[i] = key;
    m->vals[i] = val;
}

uint32_t seg_map_get(const seg_map *m, uint64_t key)
{
    size_t i = (size_t)hash64(key) & m->mask;
    while (m->keys[i] != UINT64_MAX) {
        if (m->keys[i] == key) return m->vals[i];
        i = (i + 1) & m->mask;
    }
    return UINT32_MAX;
}

void seg_map_free(seg_map *m)
{
    free(m->keys);
    free(m->vals);
    memset(m, 0, sizeof *m);
}

static int heap_less(const seg_heap *h, size_t a, size_t b)
{
    return h->cost[a] < h->cost[b] || (h->cost[a] == h->cost[b] && h->idx[a] < h->idx[b]);
}

static void heap_swap(seg_heap *h, size_t a, size_t b)
{
    double c = h->cost[a];
    h->cost[a] = h->cost[b];
    h->cost[b] = c;
    uint32_t i = h->idx[a];
    h->idx[a] = h->idx[b];
    h->idx[b] = i;
}

sy_code seg_heap_push(seg_heap *h, double cost, uint32_t idx, sy_error *err)
{
    if (h->n == h->cap) {
        size_t cap = h->cap ? 2 * h->cap : 1024;
        double *c = realloc(h->cost, cap * sizeof *c);
        if (c) h->cost = c;
        uint32_t *i = c ? realloc(h->idx, cap * sizeof *i) : NULL;
        if (!c || !i) return sy_fail(err, SY_EINTERNAL, "segment: out of memory for the path queue");
        h->idx = i;
        h->cap = cap;
    }
    size_t k = h->n++;
    h->cost[k] = cost;
    h->idx[k] = idx;
    while (k > 0 && heap_less(h, k, (k - 1) / 2)) {
        heap_swap(h, k, (k - 1) / 2);
        k = (k - 1) / 2;
    }
    return SY_OK;
}

int seg_heap_pop(seg_heap *h, double *cost, uint32_t *idx)
{
    if (h->n == 0) return 0;
    *cost = h->cost[0];
    *idx = h->idx[0];
    h->n--;
    if (h->n) {
        h->cost[0] = h->cost[h->n];
        h->idx[0] = h->idx[h->n];
        size_t k = 0;
        for (;;) {
            size_t l = 2 * k + 1, r = l + 1, m = k;
            if (l < h->n && heap_less(h, l, m)) m = l;
            if (r < h->n && heap_less(h, r, m)) m = r;
            if (m == k) break;
            heap_swap(h, k, m);
            k = m;
        }
    }
    return 1;
}

void seg_heap_free(seg_heap *h)
{
    free(h->cost);
    free(h->idx);
    memset(h, 0, sizeof *h);
}

/* ------------------------------------------------------------- segment */

/* Which method runs: the option, or for auto the plot's density. */
static int wants_airborne(const sy_segment_options *o, const seg_frame *f)
{
    if (o->method == SY_SEGMENT_AIRBORNE) return 1;
    if (o->method == SY_SEGMENT_TERRESTRIAL) return 0;
    double density = f->area > 0 ? (double)f->n / f->area : 0;
    return density < o->auto_density;
}

/* Trees from the per-point labels (1..k): small ones dissolved, ids
 * renumbered in label order, the table filled. */
static sy_code build_trees(const sy_cloud *plot, const seg_frame *f, const sy_segment_options *o, size_t k,
                           const seg_stem *stems, const seg_top *tops, sy_segmentation *s, sy_error *err)
{
    size_t *count = sy_calloc(k + 1, sizeof *count, err, "tree counts");
    int32_t *renum = sy_calloc(k + 1, sizeof *renum, err, "tree ids");
    if (!count || !renum) {
        free(count), free(renum);
        return SY_EINTERNAL;
    }
    int32_t *lab = s->tree_of;
    for (size_t i = 0; i < f->n; i++)
        if (lab[i] > 0) count[lab[i]]++;
    size_t m = 0;
    for (size_t t = 1; t <= k; t++) renum[t] = count[t] >= o->min_points && count[t] > 0 ? (int32_t)++m : -1;
    s->trees = sy_calloc(m ? m : 1, sizeof *s->trees, err, "trees");
    if (!s->trees) {
        free(count), free(renum);
        return SY_EINTERNAL;
    }
    s->n_trees = m;
    double (*ext)[5] = sy_calloc(m ? m : 1, sizeof *ext, err, "tree extents"); /* xlo, xhi, ylo, yhi, top */
    if (!ext) {
        free(count), free(renum);
        return SY_EINTERNAL;
    }
    for (size_t t = 0; t < m; t++) ext[t][0] = ext[t][2] = INFINITY, ext[t][1] = ext[t][3] = ext[t][4] = -INFINITY;
    size_t *top_point = sy_calloc(m ? m : 1, sizeof *top_point, err, "tree tops");
    if (!top_point) {
        free(count), free(renum), free(ext);
        return SY_EINTERNAL;
    }
    s->n_ground = s->n_unassigned = 0;
    for (size_t i = 0; i < f->n; i++) {
        if (lab[i] > 0) lab[i] = renum[lab[i]];
        if (lab[i] == 0) s->n_ground++;
        else if (lab[i] < 0) s->n_unassigned++;
        else {
            size_t t = (size_t)lab[i] - 1;
            double x = f->xyz[3 * i], y = f->xyz[3 * i + 1];
            s->trees[t].n_points++;
            if (x < ext[t][0]) ext[t][0] = x;
            if (x > ext[t][1]) ext[t][1] = x;
            if (y < ext[t][2]) ext[t][2] = y;
            if (y > ext[t][3]) ext[t][3] = y;
            if (f->hag[i] > ext[t][4]) ext[t][4] = f->hag[i], top_point[t] = i;
        }
    }
    for (size_t t = 1; t <= k; t++) {
        if (renum[t] < 0) continue;
        sy_segment_tree *tr = &s->trees[renum[t] - 1];
        size_t ti = (size_t)renum[t] - 1, tp = top_point[ti];
        tr->id = renum[t];
        tr->height = ext[ti][4];
        tr->crown_width = 0.5 * ((ext[ti][1] - ext[ti][0]) + (ext[ti][3] - ext[ti][2]));
        if (stems) {
            tr->stem[0] = plot->origin[0] + stems[t - 1].x;
            tr->stem[1] = plot->origin[1] + stems[t - 1].y;
            tr->stem[2] = plot->origin[2] + stems[t - 1].ground_z;
            tr->dbh = stems[t - 1].dbh;
        } else {
            (void)tops;
            tr->stem[0] = plot->origin[0] + f->xyz[3 * tp];
            tr->stem[1] = plot->origin[1] + f->xyz[3 * tp + 1];
            tr->stem[2] = plot->origin[2] + f->xyz[3 * tp + 2] - f->hag[tp];
            tr->dbh = NAN;
        }
    }
    free(count), free(renum), free(ext), free(top_point);
    return SY_OK;
}

sy_code sy_segment(const sy_cloud *plot, const sy_segment_options *o, sy_segmentation *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    sy_code rc = sy_segment_options_check(o, err);
    if (rc) return rc;
    if (plot->n == 0) return sy_fail(err, SY_EINPUT, "segment: the plot has no points");
    if (plot->n >= INT32_MAX) return sy_fail(err, SY_EINPUT, "segment: %zu points exceed the 2^31 a plot may hold", plot->n);
    double t0 = sy_now();
    seg_frame f;
    if ((rc = seg_frame_build(plot, o, &f, err))) return rc;
    out->n_points = plot->n;
    out->density = f.area > 0 ? (double)plot->n / f.area : 0;
    out->tree_of = sy_calloc(plot->n, sizeof *out->tree_of, err, "tree labels");
    if (!out->tree_of) {
        seg_frame_free(&f);
        return SY_EINTERNAL;
    }
    int airborne = wants_airborne(o, &f);
    seg_stem *stems = NULL;
    size_t n_stems = 0;
    if (!airborne) {
        rc = seg_find_stems(&f, o, &stems, &n_stems, &out->n_stem_candidates, err);
        /* Auto: a dense cloud in which no stem shows is a canopy seen from above. */
        if (rc == SY_OK && n_stems == 0 && o->method == SY_SEGMENT_AUTO) airborne = 1;
        else if (rc == SY_OK) rc = seg_grow_crowns(&f, o, stems, n_stems, out->tree_of, err);
        if (rc == SY_OK && !airborne) rc = build_trees(plot, &f, o, n_stems, stems, NULL, out, err);
    }
    if (rc == SY_OK && airborne) {
        seg_top *tops = NULL;
        size_t n_tops = 0;
        rc = seg_chm_watershed(&f, o, 0, &tops, &n_tops, out->tree_of, err);
        if (rc == SY_OK) rc = build_trees(plot, &f, o, n_tops, NULL, tops, out, err);
        free(tops);
    }
    out->airborne = airborne;
    free(stems);
    seg_frame_free(&f);
    out->seconds = sy_now() - t0;
    if (rc) sy_segmentation_free(out);
    return rc;
}

void sy_segmentation_free(sy_segmentation *s)
{
    free(s->tree_of);
    free(s->trees);
    memset(s, 0, sizeof *s);
}

sy_code sy_segmentation_tree_cloud(const sy_cloud *plot, const sy_segmentation *s, size_t index, sy_cloud *out,
                                   sy_error *err)
{
    memset(out, 0, sizeof *out);
    if (index >= s->n_trees) return sy_fail(err, SY_EUSAGE, "segment: tree index %zu of %zu trees", index, s->n_trees);
    if (plot->n != s->n_points) return sy_fail(err, SY_EUSAGE, "segment: the plot has %zu points, the segmentation %zu", plot->n, s->n_points);
    uint8_t *keep = sy_calloc(plot->n, 1, err, "tree mask");
    if (!keep) return SY_EINTERNAL;
    int32_t id = s->trees[index].id;
    for (size_t i = 0; i < plot->n; i++) keep[i] = s->tree_of[i] == id;
    sy_code rc = sy_cloud_subset(out, plot, keep, err);
    free(keep);
    return rc;
}

sy_code sy_segmentation_label(sy_cloud *c, const sy_segmentation *s, sy_error *err)
{
    if (c->n != s->n_points) return sy_fail(err, SY_EUSAGE, "segment: the cloud has %zu points, the segmentation %zu", c->n, s->n_points);
    double *v = sy_cloud_add_attr(c, "treeID", err);
    if (!v) return err->code ? err->code : SY_EINTERNAL;
    for (size_t i = 0; i < c->n; i++) v[i] = s->tree_of[i] > 0 ? (double)s->tree_of[i] : 0;
    return SY_OK;
}

int sy_segment_is_plot(const sy_cloud *c, const sy_segment_options *o)
{
    sy_error err = {0};
    if (!c || c->n < 10 || sy_segment_options_check(o, &err)) return 0;
    seg_frame f;
    if (seg_frame_build(c, o, &f, &err)) return 0;
    int plot = 0;
    if (!wants_airborne(o, &f)) {
        seg_stem *stems = NULL;
        size_t n = 0, cand = 0;
        if (seg_find_stems(&f, o, &stems, &n, &cand, &err) == SY_OK) {
            if (n >= 2) plot = 1;
            else if (n == 1 || o->method == SY_SEGMENT_TERRESTRIAL) plot = 0;
            else plot = -1; /* no stem at all: look at the canopy */
        }
        free(stems);
    } else {
        plot = -1;
    }
    if (plot < 0) {
        seg_top *tops = NULL;
        size_t n = 0;
        plot = seg_chm_watershed(&f, o, 1, &tops, &n, NULL, &err) == SY_OK && n >= 2;
        free(tops);
    }
    seg_frame_free(&f);
    return plot;
}
