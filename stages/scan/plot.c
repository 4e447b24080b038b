/* Scenes: generated trees turned into labelled primitives (a truncated cone per
 * skeleton edge, a card per leaf), terrain, understory shrubs, Poisson-disk
 * plots, and the truth file describing what was placed. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "scan.h"
#include "species/library.h"
#include "stages/core/json.h"
#include "stages/grow/grow.h"
#include "stages/core/rng.h"

#define PI 3.14159265358979323846

static uint64_t mix64(uint64_t z) { return sy_mix64(z); }

/* A small sequential generator for scene layout (placement is serial). */
typedef struct {
    uint64_t s;
} rng;
static double rng_u01(rng *r)
{
    r->s += SY_GOLDEN_GAMMA;
    return sy_unit53(mix64(r->s));
}
static double rng_range(rng *r, double lo, double hi) { return lo + (hi - lo) * rng_u01(r); }

void sy_scene_init(sy_scene *s)
{
    memset(s, 0, sizeof *s);
    for (int k = 0; k < 3; k++) {
        s->veg_lo[k] = INFINITY;
        s->veg_hi[k] = -INFINITY;
    }
}

void sy_scene_free(sy_scene *s)
{
    sy_prims_free(&s->prims);
    for (size_t i = 0; i < s->n_trees; i++) sy_skeleton_free(&s->trees[i].skel);
    free(s->trees);
    sy_bvh_free(&s->bvh);
    sy_scene_init(s);
}

static void grow_veg(sy_scene *s, const sy_box *b)
{
    for (int k = 0; k < 3; k++) {
        if (b->lo[k] < s->veg_lo[k]) s->veg_lo[k] = b->lo[k];
        if (b->hi[k] > s->veg_hi[k]) s->veg_hi[k] = b->hi[k];
    }
}

static sy_code push_labelled(sy_scene *s, sy_prim *p, sy_error *err)
{
    sy_box b;
    sy_prim_bounds(p, &b);
    grow_veg(s, &b);
    return sy_prims_push(&s->prims, p, err);
}

/* Rotation by the unit quaternion q (x, y, z, w). */
static void quat_rotate(const float q[4], const double v[3], double out[3])
{
    double u[3] = {q[0], q[1], q[2]}, w = q[3];
    double t[3] = {2 * (u[1] * v[2] - u[2] * v[1]), 2 * (u[2] * v[0] - u[0] * v[2]), 2 * (u[0] * v[1] - u[1] * v[0])};
    out[0] = v[0] + w * t[0] + (u[1] * t[2] - u[2] * t[1]);
    out[1] = v[1] + w * t[1] + (u[2] * t[0] - u[0] * t[2]);
    out[2] = v[2] + w * t[2] + (u[0] * t[1] - u[1] * t[0]);
}

typedef struct {
    double c, s, pos[3];
} placement;

static void place_point(const placement *pl, const double v[3], double out[3])
{
    out[0] = pl->pos[0] + pl->c * v[0] - pl->s * v[1];
    out[1] = pl->pos[1] + pl->s * v[0] + pl->c * v[1];
    out[2] = pl->pos[2] + v[2];
}

static void place_dir(const placement *pl, const double v[3], float out[3])
{
    out[0] = (float)(pl->c * v[0] - pl->s * v[1]);
    out[1] = (float)(pl->s * v[0] + pl->c * v[1]);
    out[2] = (float)v[2];
}

double sy_trunk_radius_at(const sy_skeleton *s, double above)
{
    int32_t root = -1;
    for (size_t i = 0; i < s->n; i++)
        if (s->parent[i] < 0) root = (int32_t)i;
    if (root < 0) return NAN;
    int32_t trunk = s->branch[root];
    double z0 = s->pos[3 * root + 2], best_low = INFINITY, r = NAN;
    for (size_t i = 0; i < s->n; i++) {
        int32_t p = s->parent[i];
        if (p < 0 || s->branch[i] != trunk || s->branch[p] != trunk) continue;
        double za = s->pos[3 * p + 2] - z0, zb = s->pos[3 * i + 2] - z0;
        double lo = za < zb ? za : zb, hi = za < zb ? zb : za;
        if (above < lo || above > hi || lo >= best_low) continue;
        double f = hi > lo ? (above - za) / (zb - za) : 0;
        r = s->radius[p] + f * ((double)s->radius[i] - s->radius[p]);
        best_low = lo;
    }
    return r;
}

/* Height, crown width over the placed wood and leaves. */
typedef struct {
    double top, lo[2], hi[2];
} extent;

static void extent_add(extent *e, const double x[3])
{
    if (x[2] > e->top) e->top = x[2];
    for (int k = 0; k < 2; k++) {
        if (x[k] < e->lo[k]) e->lo[k] = x[k];
        if (x[k] > e->hi[k]) e->hi[k] = x[k];
    }
}


static sy_code add_wood(sy_scene *s, const sy_skeleton *world, int tree_id, int species_id, extent *ext,
                        sy_error *err)
{
    for (size_t i = 0; i < world->n; i++) {
        int32_t p = world->parent[i];
        if (p < 0) continue;
        const float *a = world->pos + 3 * p, *b = world->pos + 3 * i;
        if (a[0] == b[0] && a[1] == b[1] && a[2] == b[2]) continue;
        /* A branch's first edge runs along its parent stem's axis: give it the
         * branch's own radius so it stays inside the parent's wood. */
        float ra = world->branch[p] == world->branch[i] ? world->radius[p] : world->radius[i];
        sy_prim c = sy_prim_cone(a, ra, b, world->radius[i]);
        c.tree_id = tree_id;
        c.species_id = species_id;
        c.branch_id = world->branch[i];
        /* The cone's box is its exact extent (end discs), give or take 10 um. */
        sy_box box;
        sy_prim_bounds(&c, &box);
        extent_add(ext, box.lo);
        extent_add(ext, box.hi);
        if (push_labelled(s, &c, err)) return err->code;
    }
    return SY_OK;
}

/* How far under the terrain's surface wood may reach: the stem base sits
 * 2 cm down, and the triangulated ground departs from the height function
 * by about the roughness. */
#define SY_BELOW_GROUND 0.05

/* Weber & Penn's model knows no ground: a low limb that curves down (black
 * oak's do, by up to 3 m) runs on under the terrain, where no scanner sees it
 * and where, in a plot, it hides the ground and passes for stems at breast
 * height. A limb ends where it meets the ground: the nodes under the surface
 * go, with everything they carry. world is compacted in place; map gets each
 * old node's new index (-1: gone). Returns how many nodes went. */
static size_t prune_below_ground(const sy_scene *s, sy_skeleton *world, int32_t *map)
{
    size_t n = world->n, gone = 0;
    /* map: -2 not judged yet, -1 gone, 1 kept (new indices below). */
    for (size_t i = 0; i < n; i++) map[i] = -2;
    for (size_t i = 0; i < n; i++) {
        /* Judge i's unjudged ancestors from the top down, then i. */
        for (;;) {
            size_t k = i;
            /* the highest unjudged node on the way up (its parent judged, or none) */
            while (map[k] == -2) {
                int32_t p = world->parent[k];
                if (p < 0 || map[p] != -2) break;
                k = (size_t)p;
            }
            if (map[k] != -2) break;
            int32_t p = world->parent[k];
            const float *x = world->pos + 3 * k;
            int keep = p < 0 || (map[p] == 1 &&
                                 x[2] >= sy_terrain_height(&s->terrain, x[0], x[1]) - SY_BELOW_GROUND);
            map[k] = keep ? 1 : -1;
        }
    }
    size_t j = 0;
    for (size_t i = 0; i < n; i++) {
        if (map[i] < 0) {
            gone++;
            continue;
        }
        map[i] = (int32_t)j++;
    }
    for (size_t i = 0; i < n; i++) {
        int32_t m = map[i];
        if (m < 0) continue;
        int32_t p = world->parent[i];
        memmove(world->pos + 3 * m, world->pos + 3 * i, 3 * sizeof *world->pos);
        world->radius[m] = world->radius[i];
        world->order[m] = world->order[i];
        world->branch[m] = world->branch[i];
        world->parent[m] = p < 0 ? -1 : map[p];
    }
    world->n = j;
    return gone;
}

static sy_code add_leaves(sy_scene *s, const sy_leaves *lv, const sy_skeleton *world, const int32_t *map,
                          const placement *pl, const sy_card_form *form, int tree_id, int species_id, extent *ext,
                          size_t *added, sy_error *err)
{
    *added = 0;
    for (size_t i = 0; i < lv->n; i++) {
        int32_t node = lv->node[i];
        if (map && node >= 0 && map[node] < 0) continue; /* its twig went with a limb under the ground */
        if (map && node >= 0) node = map[node];
        const float *q = lv->rot + 4 * i;
        double ex[3] = {1, 0, 0}, ey[3] = {0, 1, 0}, lx[3], ly[3], base[3];
        quat_rotate(q, ex, lx);
        quat_rotate(q, ey, ly);
        double lp[3] = {lv->pos[3 * i], lv->pos[3 * i + 1], lv->pos[3 * i + 2]};
        place_point(pl, lp, base);
        if (s->has_terrain && base[2] < sy_terrain_height(&s->terrain, base[0], base[1]) - SY_BELOW_GROUND) continue;
        float fx[3], fy[3], fb[3] = {(float)base[0], (float)base[1], (float)base[2]};
        place_dir(pl, lx, fx);
        place_dir(pl, ly, fy);
        float len = lv->scale[i], width = len * form->width;
        sy_prim c = sy_prim_quad(fb, fx, fy, len, width, form->elliptic);
        sy_prim_quad_gaps(&c, form->fill);
        c.tree_id = tree_id;
        c.species_id = species_id;
        c.branch_id = node >= 0 && (size_t)node < world->n ? world->branch[node] : -1;
        for (int sx = -1; sx <= 1; sx += 2)
            for (int ty = 0; ty <= 1; ty++) {
                double corner[3];
                for (int k = 0; k < 3; k++) corner[k] = fb[k] + sx * (double)c.v[3 + k] + ty * (double)c.v[6 + k];
                extent_add(ext, corner);
            }
        if (push_labelled(s, &c, err)) return err->code;
        ++*added;
    }
    return SY_OK;
}

sy_code sy_scene_add_tree(sy_scene *s, const sy_skeleton *local, const sy_leaves *leaves, const sy_card_form *cards,
                          const char *species, int species_id, uint64_t seed, const double pos[3],
                          double yaw_deg, sy_error *err)
{
    sy_scan_tree *grown = realloc(s->trees, (s->n_trees + 1) * sizeof *grown);
    if (!grown) return sy_fail(err, SY_EINTERNAL, "out of memory for scene trees");
    s->trees = grown;
    sy_scan_tree *t = &s->trees[s->n_trees];
    memset(t, 0, sizeof *t);
    if (sy_skeleton_init(&t->skel, local->n, err)) return err->code;
    s->n_trees++;
    t->tree_id = (int)s->n_trees;
    snprintf(t->species, sizeof t->species, "%s", species ? species : "");
    t->species_id = species_id;
    t->seed = seed;
    memcpy(t->pos, pos, sizeof t->pos);
    t->yaw_deg = yaw_deg;
    placement pl = {cos(yaw_deg * PI / 180), sin(yaw_deg * PI / 180), {pos[0], pos[1], pos[2]}};
    int32_t root = 0;
    for (size_t i = 0; i < local->n; i++)
        if (local->parent[i] < 0) root = (int32_t)i;
    /* The trunk base lands on pos whatever the grown frame's origin. */
    double shift[3] = {(double)local->pos[3 * root] + local->origin[0], (double)local->pos[3 * root + 1] + local->origin[1],
                       (double)local->pos[3 * root + 2] + local->origin[2]};
    extent ext = {-INFINITY, {INFINITY, INFINITY}, {-INFINITY, -INFINITY}};
    for (size_t i = 0; i < local->n; i++) {
        double lp[3], w[3];
        for (int k = 0; k < 3; k++) lp[k] = (double)local->pos[3 * i + k] + local->origin[k] - shift[k];
        place_point(&pl, lp, w);
        for (int k = 0; k < 3; k++) t->skel.pos[3 * i + k] = (float)w[k];
        t->skel.radius[i] = local->radius[i];
        t->skel.parent[i] = local->parent[i];
        t->skel.order[i] = local->order[i];
        t->skel.branch[i] = local->branch[i];
    }
    int32_t *map = NULL;
    if (s->has_terrain) {
        if (!(map = sy_calloc(local->n ? local->n : 1, sizeof *map, err, "node map"))) return err->code;
        t->pruned_nodes = prune_below_ground(s, &t->skel, map);
    }
    sy_code rc = add_wood(s, &t->skel, t->tree_id, species_id, &ext, err);
    if (!rc && leaves) {
        sy_leaves moved = *leaves;
        float *lp = sy_calloc(leaves->n ? 3 * leaves->n : 1, sizeof(float), err, "leaf positions");
        if (!lp) rc = err->code;
        for (size_t i = 0; lp && i < leaves->n; i++)
            for (int k = 0; k < 3; k++) lp[3 * i + k] = (float)((double)leaves->pos[3 * i + k] + local->origin[k] - shift[k]);
        moved.pos = lp;
        if (lp) rc = add_leaves(s, &moved, &t->skel, map, &pl, cards, t->tree_id, species_id, &ext,
                                &t->leaf_count, err);
        free(lp);
    }
    free(map);
    if (rc) return rc;
    t->height = ext.top - pos[2];
    t->crown_width = 0.5 * ((ext.hi[0] - ext.lo[0]) + (ext.hi[1] - ext.lo[1]));
    t->dbh = 2 * sy_trunk_radius_at(&t->skel, 1.3);
    return SY_OK;
}

sy_code sy_scene_add_terrain(sy_scene *s, const sy_terrain *t, sy_error *err)
{
    s->terrain = *t;
    s->has_terrain = 1;
    return sy_terrain_triangulate(t, &s->prims, err);
}

static double ground_z(const sy_scene *s, double x, double y)
{
    return s->has_terrain ? sy_terrain_height(&s->terrain, x, y) : 0.0;
}

static sy_code add_shrub(sy_scene *s, rng *r, double x, double y, sy_error *err)
{
    double z = ground_z(s, x, y) - 0.02; /* stems start just below the surface */
    double h = rng_range(r, 0.3, 1.2);
    int stems = 3 + (int)(rng_u01(r) * 3);
    for (int st = 0; st < stems; st++) {
        double az = rng_range(r, 0, 2 * PI), tilt = rng_range(r, 0.15, 0.7);
        double p[3] = {x, y, z};
        for (int seg = 0; seg < 3; seg++) {
            double len = h / 3 * rng_range(r, 0.8, 1.2);
            double a = az + rng_range(r, -0.4, 0.4), tl = tilt + 0.15 * seg;
            double q[3] = {p[0] + len * sin(tl) * cos(a), p[1] + len * sin(tl) * sin(a), p[2] + len * cos(tl)};
            float fa[3] = {(float)p[0], (float)p[1], (float)p[2]}, fb[3] = {(float)q[0], (float)q[1], (float)q[2]};
            sy_prim c = sy_prim_cone(fa, (float)(0.012 - 0.003 * seg), fb, (float)(0.009 - 0.003 * seg));
            c.understory = 1;
            if (push_labelled(s, &c, err)) return err->code;
            memcpy(p, q, sizeof p);
        }
    }
    /* The leafy blob: small cards scattered in an ellipsoid around the crown. */
    int n_leaves = 20 + (int)(rng_u01(r) * 40);
    for (int i = 0; i < n_leaves; i++) {
        double u = rng_range(r, -1, 1), v = rng_range(r, -1, 1), w = rng_range(r, -1, 1);
        float base[3] = {(float)(x + 0.35 * h * u), (float)(y + 0.35 * h * v), (float)(z + h * (0.65 + 0.3 * w))};
        double a = rng_range(r, 0, 2 * PI), b = rng_range(r, -1, 1);
        double sb = sqrt(1 - b * b);
        float fy[3] = {(float)(sb * cos(a)), (float)(sb * sin(a)), (float)b};
        /* Any unit vector orthogonal to fy. */
        double ref[3] = {fabs(fy[2]) < 0.9 ? 0 : 1, 0, fabs(fy[2]) < 0.9 ? 1 : 0};
        double fx[3] = {fy[1] * ref[2] - fy[2] * ref[1], fy[2] * ref[0] - fy[0] * ref[2], fy[0] * ref[1] - fy[1] * ref[0]};
        double fl = sqrt(fx[0] * fx[0] + fx[1] * fx[1] + fx[2] * fx[2]);
        float ffx[3] = {(float)(fx[0] / fl), (float)(fx[1] / fl), (float)(fx[2] / fl)};
        float len = (float)rng_range(r, 0.04, 0.09);
        sy_prim c = sy_prim_quad(base, ffx, fy, len, len * 0.6f, 1);
        c.understory = 1;
        if (push_labelled(s, &c, err)) return err->code;
    }
    return SY_OK;
}

sy_code sy_scene_add_understory(sy_scene *s, double density, uint64_t seed, sy_error *err)
{
    double w = s->area_hi[0] - s->area_lo[0], d = s->area_hi[1] - s->area_lo[1];
    if (!(density > 0) || !(w > 0) || !(d > 0)) return SY_OK;
    double expected = density * w * d;
    if (expected > 1e6) return sy_fail(err, SY_EINPUT, "understory: %.0f shrubs is too many", expected);
    size_t n = (size_t)llround(expected);
    rng r = {mix64(seed ^ 0x5348525542ull)};
    for (size_t i = 0; i < n; i++) {
        double x = rng_range(&r, s->area_lo[0], s->area_hi[0]), y = rng_range(&r, s->area_lo[1], s->area_hi[1]);
        int clear = 1;
        for (size_t t = 0; t < s->n_trees && clear; t++)
            clear = hypot(x - s->trees[t].pos[0], y - s->trees[t].pos[1]) > 1.0;
        if (clear && add_shrub(s, &r, x, y, err)) return err->code;
    }
    return SY_OK;
}

sy_code sy_scene_finish(sy_scene *s, sy_error *err)
{
    sy_bvh_free(&s->bvh);
    return sy_prims_index(&s->prims, &s->bvh, err);
}

sy_scene_options sy_scene_options_default(void)
{
    sy_scene_options value_, *o = &value_;
    memset(o, 0, sizeof *o);
    o->trees = 5;
    o->understory = -1; /* resolved by sy_scene_build */
    o->roughness = 0.05;
    o->terrain = 1;
    o->leaves = 1;
    o->elliptic = 1;
    o->seed = 1;
    return value_;
}

typedef struct {
    sy_skeleton skel;
    sy_leaves leaves;
    float leaf_width, leaf_fill;
    char name[64];
    int species_id;
    uint64_t seed;
    double x, y, yaw, half_crown;
} grown_tree;

static void free_grown(grown_tree *g, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        sy_skeleton_free(&g[i].skel);
        sy_leaves_free(&g[i].leaves);
    }
    free(g);
}

/* The forest-grown habit (sy_scene_options.forest): self-pruning of shaded
 * lower limbs raises the crown base (towards half the height), crowding shortens the limbs, and a stand
 * tree is slender (its height over diameter is about twice an open-grown
 * one's: the trunk radius ratio halves at forest = 1). */
static void forest_habit(sy_species_params *sp, double forest)
{
    if (!(forest > 0)) return;
    if (sp->base_size < 0.5f) sp->base_size += (float)(forest * (0.5 - sp->base_size));
    sp->level[1].length *= (float)(1 - 0.7 * forest);
    sp->ratio *= (float)(1 - 0.5 * forest);
    /* Shade sheds the inner foliage: a stand crown is a thin live shell the
     * scanner sees into (the open-grown files' foliage is opaque). */
    sp->leaves *= (float)(1 - 0.7 * forest);
}

static sy_code grow_one(grown_tree *g, const char *species, uint64_t seed, int leaves, double forest, sy_error *err)
{
    sy_species_params sp;
    if (sy_species_params_find(species, &sp, err)) return err->code;
    forest_habit(&sp, forest);
    sy_code rc = sy_grow_tree(&sp, seed, &g->skel, leaves ? &g->leaves : NULL, err);
    g->leaf_width = sp.leaf_scale_x;
    g->leaf_fill = sp.leaf_fill;
    snprintf(g->name, sizeof g->name, "%s", sp.name ? sp.name : species);
    g->species_id = sy_library_id(g->name);
    g->seed = seed;
    sy_species_params_free(&sp);
    if (rc) return rc;
    for (size_t i = 0; i < g->skel.n; i++) {
        double r = hypot(g->skel.pos[3 * i] - g->skel.pos[0], g->skel.pos[3 * i + 1] - g->skel.pos[1]);
        if (r > g->half_crown) g->half_crown = r;
    }
    return SY_OK;
}

/* Dart throwing with a shrinking radius: every tree gets a spot, as evenly
 * spread as the plot allows. */
static void poisson_disk(grown_tree *g, int n, double size, rng *r)
{
    double half = size / 2 - (size > 4 ? 1.0 : 0.0);
    double radius = 0.8 * size / sqrt((double)n);
    int placed = 0, misses = 0;
    while (placed < n) {
        double x = rng_range(r, -half, half), y = rng_range(r, -half, half);
        int ok = 1;
        for (int i = 0; i < placed && ok; i++) ok = hypot(x - g[i].x, y - g[i].y) >= radius;
        if (ok) {
            g[placed].x = x;
            g[placed].y = y;
            placed++;
            misses = 0;
        } else if (++misses > 200) {
            radius *= 0.9;
            misses = 0;
        }
    }
}

sy_code sy_scene_options_check(const sy_scene_options *o, sy_error *err)
{
    int max_species = (int)(sizeof o->species / sizeof *o->species);
    if (o->n_species < 1 || o->n_species > max_species)
        return sy_fail(err, SY_EUSAGE, "scan: n_species %d outside [1, %d]", o->n_species, max_species);
    for (int i = 0; i < o->n_species; i++)
        if (!o->species[i] || !o->species[i][0]) return sy_fail(err, SY_EUSAGE, "scan: species[%d] is empty", i);
    if (!(o->plot_size >= 0) || !isfinite(o->plot_size))
        return sy_fail(err, SY_EUSAGE, "scan: plot_size %g must be >= 0", o->plot_size);
    int plot = o->plot_size > 0;
    if (plot && (o->trees < 0 || o->trees > 10000))
        return sy_fail(err, SY_EUSAGE, "scan: trees %d outside [0, 10000]", o->trees);
    if (o->neighbours < 0 || o->neighbours > 12)
        return sy_fail(err, SY_EUSAGE, "scan: neighbours %d outside [0, 12]", o->neighbours);
    if (plot && o->neighbours > 0)
        return sy_fail(err, SY_EUSAGE, "scan: neighbours is for a single tree (plot_size 0), not a plot");
    if (!(o->forest >= 0 && o->forest <= 1)) return sy_fail(err, SY_EUSAGE, "scan: forest %g outside [0, 1]", o->forest);
    /* Negative understory is the default (resolved by sy_scene_build); NaN is none. */
    if (isnan(o->understory)) return sy_fail(err, SY_EUSAGE, "scan: understory is not a number");
    /* tan(slope) lifts the ground: a vertical one has no height. */
    if (!(fabs(o->slope_deg) < 90)) return sy_fail(err, SY_EUSAGE, "scan: slope_deg %g outside (-90, 90)", o->slope_deg);
    if (!isfinite(o->aspect_deg)) return sy_fail(err, SY_EUSAGE, "scan: aspect_deg %g is not finite", o->aspect_deg);
    if (!(o->roughness >= 0) || !isfinite(o->roughness))
        return sy_fail(err, SY_EUSAGE, "scan: roughness %g must be >= 0", o->roughness);
    return SY_OK;
}

sy_code sy_scene_build(sy_scene *s, const sy_scene_options *o, double reach, sy_error *err)
{
    sy_scene_init(s);
    sy_code checked = sy_scene_options_check(o, err);
    if (checked) return checked;
    int plot = o->plot_size > 0;
    int n = plot ? o->trees : 1 + o->neighbours;
    grown_tree *g = sy_calloc(n ? (size_t)n : 1, sizeof *g, err, "trees");
    if (!g) return err->code;
    rng r = {mix64(o->seed ^ 0x504C4F54ull)};
    for (int i = 0; i < n; i++) {
        const char *species = o->species[plot ? (int)(rng_u01(&r) * o->n_species) % o->n_species : 0];
        uint64_t seed = plot || i > 0 ? mix64(o->seed * 1000003ull + (uint64_t)i) & 0xFFFFFFFFull : o->seed;
        if (grow_one(&g[i], species, seed, o->leaves, o->forest, err)) {
            free_grown(g, (size_t)n);
            return err->code;
        }
        g[i].yaw = plot ? rng_range(&r, 0, 360) : 0;
    }
    double crown = 0;
    for (int i = 0; i < n; i++) crown = fmax(crown, g[i].half_crown);
    if (plot) {
        poisson_disk(g, n, o->plot_size, &r);
        s->area_lo[0] = s->area_lo[1] = -o->plot_size / 2;
        s->area_hi[0] = s->area_hi[1] = o->plot_size / 2;
    } else {
        /* Neighbours on a ring, crowns about touching: their own generator,
         * so a lone tree's scene is what it always was. */
        rng ring = {mix64(o->seed ^ 0x4E45494748ull)};
        double extent = crown;
        for (int i = 1; i < n; i++) {
            double a = 2 * PI * (i - 1 + rng_range(&ring, -0.3, 0.3)) / (n - 1);
            double d = (g[0].half_crown + g[i].half_crown) * rng_range(&ring, 0.8, 1.1);
            d = fmax(d, 1.0);
            g[i].x = d * cos(a);
            g[i].y = d * sin(a);
            g[i].yaw = rng_range(&ring, 0, 360);
            extent = fmax(extent, d + g[i].half_crown);
        }
        s->area_lo[0] = s->area_lo[1] = -(extent + 5);
        s->area_hi[0] = s->area_hi[1] = extent + 5;
    }
    if (o->terrain) {
        sy_terrain t = {o->slope_deg, o->aspect_deg, o->roughness, 6.0, 0.0, mix64(o->seed ^ 0x47524F554E44ull),
                        {0, 0}, {0, 0}, 0.5};
        double ext = fmax(reach, 0) + 2;
        for (int k = 0; k < 2; k++) {
            t.lo[k] = fmin(s->area_lo[k], -ext) - 2;
            t.hi[k] = fmax(s->area_hi[k], ext) + 2;
        }
        /* Keep the ground to about a million triangles. */
        double cells = (t.hi[0] - t.lo[0]) * (t.hi[1] - t.lo[1]) / (t.step * t.step);
        if (cells > 5e5) t.step *= sqrt(cells / 5e5);
        if (sy_scene_add_terrain(s, &t, err)) {
            free_grown(g, (size_t)n);
            return err->code;
        }
    }
    sy_code rc = SY_OK;
    for (int i = 0; i < n && !rc; i++) {
        double pos[3] = {g[i].x, g[i].y, ground_z(s, g[i].x, g[i].y)};
        sy_card_form cards = {g[i].leaf_width, g[i].leaf_fill, o->elliptic};
        rc = sy_scene_add_tree(s, &g[i].skel, o->leaves ? &g[i].leaves : NULL, &cards, g[i].name,
                               g[i].species_id, g[i].seed, pos, g[i].yaw, err);
    }
    free_grown(g, (size_t)n);
    double shrubs = o->understory >= 0 ? o->understory : plot ? 0.05 : 0.0;
    if (!rc && o->terrain) rc = sy_scene_add_understory(s, shrubs, o->seed, err);
    if (!rc) rc = sy_scene_finish(s, err);
    return rc;
}

/* Seven significant digits (10 um at 100 m): the truth file stays a third
 * the size of a full float round trip. */
static double short_float(float f)
{
    char buf[32];
    snprintf(buf, sizeof buf, "%.7g", (double)f);
    return strtod(buf, NULL);
}

void sy_write_truth(FILE *fp, const sy_scene *s, const sy_scan_options *sc, int stations)
{
    sy_json j;
    sy_json_begin(&j, fp, 0);
    sy_json_object(&j, NULL);
    sy_json_string(&j, "format", "sylva-truth");
    sy_json_int(&j, "version", 1);
    sy_json_object(&j, "scanner");
    sy_json_string(&j, "kind", sy_scanner_kind_name(sc->kind));
    sy_json_int(&j, "positions", stations);
    sy_json_int(&j, "seed", (long long)sc->seed);
    sy_json_end(&j);
    sy_json_array(&j, "trees");
    for (size_t i = 0; i < s->n_trees; i++) {
        const sy_scan_tree *t = &s->trees[i];
        sy_json_object(&j, NULL);
        sy_json_int(&j, "tree_id", t->tree_id);
        sy_json_string(&j, "species", t->species);
        sy_json_int(&j, "species_id", t->species_id);
        sy_json_int(&j, "seed", (long long)t->seed);
        sy_json_numbers(&j, "position", t->pos, 3);
        sy_json_number(&j, "height", t->height);
        sy_json_number(&j, "dbh", t->dbh);
        sy_json_number(&j, "crown_width", t->crown_width);
        sy_json_int(&j, "leaf_count", (long long)t->leaf_count);
        sy_json_int(&j, "nodes_below_ground", (long long)t->pruned_nodes);
        sy_json_array(&j, "nodes");
        for (size_t k = 0; k < t->skel.n; k++) {
            sy_json_object(&j, NULL);
            sy_json_int(&j, "id", (long long)k);
            sy_json_int(&j, "parent", t->skel.parent[k]);
            sy_json_number(&j, "x", short_float(t->skel.pos[3 * k]));
            sy_json_number(&j, "y", short_float(t->skel.pos[3 * k + 1]));
            sy_json_number(&j, "z", short_float(t->skel.pos[3 * k + 2]));
            sy_json_number(&j, "radius", short_float(t->skel.radius[k]));
            sy_json_int(&j, "order", t->skel.order[k]);
            sy_json_int(&j, "branch", t->skel.branch[k]);
            sy_json_end(&j);
        }
        sy_json_end(&j);
        sy_json_end(&j);
    }
    sy_json_end(&j);
    sy_json_end(&j);
    sy_json_finish(&j);
}
