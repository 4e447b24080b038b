/* Checks of a tree asset that a validator cannot make and an artist sees:
 * triangles that leave the branch surface (sails), triangles too thin to
 * see (slivers), bark that is not one closed, consistently oriented,
 * welded surface, leaves that float away from their twigs, anything below
 * the ground, and the triangle ratios of the LOD chain (docs/mesh.md,
 * "Quality checks"). The reference surface is the skeleton's union of
 * capsules (each edge a truncated cone) with the radii the mesher draws. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "eval.h"
#include "geometry.h"
#include "stages/core/bvh.h"
#include "stages/core/vec3.h"
#include "stages/mesh/mesh.h"

/* Glitches: SY_MESH_SLIVER_AREA and SY_MESH_NEEDLE_ASPECT (mesh.h). */
#define SLIVER_AREA SY_MESH_SLIVER_AREA
#define SLIVER_ASPECT SY_MESH_NEEDLE_ASPECT
/* Off-surface allowance per metre of skeleton segment (spline vs polyline). */
#define SPLINE_SLACK 0.05
/* Silhouette masks: pixels on a side (the LOD test of a tree, like a 256 px
 * impostor view). */
#define SILHOUETTE_PX 256

typedef struct {
    double a[3], b[3];
    double ra, rb;
    double len; /* |b - a|; 0 for a child's first capsule when it starts on its parent's axis */
} capsule;

typedef struct {
    const capsule *caps;
    int with_axis; /* only capsules with a direction (not a child's zero-length first one) */
    int in_slack;  /* the gap in units of the capsule's room: its radius or 5 % of its length */
} cap_ctx;

static int has_axis(const capsule *c) { return c->len > 1e-6; }

/* Distance from q to the capsule's surface, 0 inside (the BVH prunes with
 * box distances, which this never undercuts). */
static double capsule_gap(const capsule *c, const double q[3], double *t)
{
    double d = sy_point_segment_distance(q, c->a, c->b, t);
    double r = c->ra + *t * (c->rb - c->ra);
    return d - r;
}

static double cap_distance(const void *ctx, uint32_t prim, const double q[3])
{
    const cap_ctx *c = ctx;
    const capsule *cp = &c->caps[prim];
    if (c->with_axis && !has_axis(cp)) return INFINITY;
    double t, g = capsule_gap(cp, q, &t);
    if (g <= 0) return 0;
    /* Never below the box distance the BVH prunes with: a room of at most
     * a metre only scales the gap up. */
    if (c->in_slack) g /= fmin(1.0, fmax(fmax(cp->ra, cp->rb), SPLINE_SLACK * cp->len));
    return g;
}

typedef struct {
    const double *tri; /* 9 per triangle */
} tri_ctx;

static double tri_distance(const void *ctx, uint32_t prim, const double q[3])
{
    const double *t = ((const tri_ctx *)ctx)->tri + 9 * (size_t)prim;
    return sy_point_triangle_distance(q, t, t + 3, t + 6, NULL);
}

/* glTF Y-up -> Sylva Z-up: (x, y, z) -> (x, -z, y). */
static void to_zup(const float *v, double out[3])
{
    out[0] = v[0];
    out[1] = -(double)v[2];
    out[2] = v[1];
}

typedef struct {
    uint64_t key;
    uint32_t id;
} weld_slot;

static uint64_t hash_pos(const float *p)
{
    uint32_t u[3];
    memcpy(u, p, sizeof u);
    uint64_t h = 1469598103934665603ull;
    for (int k = 0; k < 3; k++) h = (h ^ (u[k] + 0x9e3779b9u)) * 1099511628211ull;
    return h;
}

typedef struct {
    uint32_t lo, hi; /* welded vertex ids, lo < hi */
    int dir;         /* +1 when the triangle runs lo -> hi */
} edge_rec;

static int cmp_edge(const void *x, const void *y)
{
    const edge_rec *a = x, *b = y;
    if (a->lo != b->lo) return a->lo < b->lo ? -1 : 1;
    if (a->hi != b->hi) return a->hi < b->hi ? -1 : 1;
    return (a->dir > b->dir) - (a->dir < b->dir);
}

static uint32_t uf_find(uint32_t *p, uint32_t x)
{
    while (p[x] != x) x = p[x] = p[p[x]];
    return x;
}

/* Welds by exact position (the mesher copies shared vertices bit for bit),
 * then counts edges by their number of faces and orientation, and the
 * connected parts. */
static sy_code topology(const float *pos, size_t nv, const uint32_t *idx, size_t nt, sy_mesh_check_level *out,
                        sy_error *err)
{
    size_t cap = 16;
    while (cap < 2 * nv) cap <<= 1;
    weld_slot *tab = malloc(cap * sizeof *tab);
    uint32_t *id = malloc((nv + 1) * sizeof *id), *uf = malloc((nv + 1) * sizeof *uf);
    edge_rec *e = malloc((3 * nt + 1) * sizeof *e);
    if (!tab || !id || !uf || !e) {
        free(tab), free(id), free(uf), free(e);
        return sy_fail(err, SY_EINTERNAL, "mesh check: out of memory");
    }
    for (size_t i = 0; i < cap; i++) tab[i].id = UINT32_MAX;
    uint32_t n_ids = 0;
    for (size_t v = 0; v < nv; v++) {
        const float *p = pos + 3 * v;
        uint64_t h = hash_pos(p);
        size_t s = (size_t)h & (cap - 1);
        for (;;) {
            if (tab[s].id == UINT32_MAX) {
                tab[s].key = h;
                tab[s].id = (uint32_t)v;
                id[v] = n_ids++;
                uf[id[v]] = id[v];
                break;
            }
            const float *q = pos + 3 * tab[s].id;
            if (tab[s].key == h && memcmp(p, q, 3 * sizeof(float)) == 0) {
                id[v] = id[tab[s].id];
                break;
            }
            s = (s + 1) & (cap - 1);
        }
    }
    size_t ne = 0, used_tris = 0;
    for (size_t t = 0; t < nt; t++) {
        uint32_t w[3] = {id[idx[3 * t]], id[idx[3 * t + 1]], id[idx[3 * t + 2]]};
        if (w[0] == w[1] || w[1] == w[2] || w[0] == w[2]) {
            out->collapsed++;
            continue;
        }
        used_tris++;
        for (int k = 0; k < 3; k++) {
            uint32_t a = w[k], b = w[(k + 1) % 3];
            e[ne++] = a < b ? (edge_rec){a, b, 1} : (edge_rec){b, a, -1};
            uint32_t ra = uf_find(uf, a), rb = uf_find(uf, b);
            if (ra != rb) uf[ra < rb ? rb : ra] = ra < rb ? ra : rb;
        }
    }
    qsort(e, ne, sizeof *e, cmp_edge);
    for (size_t i = 0; i < ne;) {
        size_t j = i;
        int sum = 0;
        while (j < ne && e[j].lo == e[i].lo && e[j].hi == e[i].hi) sum += e[j++].dir;
        size_t k = j - i;
        if (k == 1) out->boundary_edges++;
        else if (k > 2) out->nonmanifold_edges++;
        else if (sum != 0) out->misoriented_edges++;
        i = j;
    }
    /* Parts: roots among the welded vertices that some triangle uses. */
    uint8_t *used = calloc(n_ids + 1, 1);
    if (!used) {
        free(tab), free(id), free(uf), free(e);
        return sy_fail(err, SY_EINTERNAL, "mesh check: out of memory");
    }
    for (size_t i = 0; i < ne; i++) used[e[i].lo] = 1;
    for (uint32_t v = 0; v < n_ids; v++)
        if (used[v] && uf_find(uf, v) == v) out->components++;
    free(used), free(tab), free(id), free(uf), free(e);
    (void)used_tris;
    return SY_OK;
}

sy_mesh_check_options sy_mesh_check_options_default(void)
{
    sy_mesh_check_options o;
    memset(&o, 0, sizeof o);
    o.min_radius = 0;
    o.ground = 0;
    o.ground_tolerance = 0.005;
    o.sail_radii = 3.0;
    o.across_radii = 4.0;
    return o;
}

sy_code sy_mesh_check_options_check(const sy_mesh_check_options *o, sy_error *err)
{
    if (!(o->min_radius >= 0) || !isfinite(o->min_radius))
        return sy_fail(err, SY_EUSAGE, "mesh check: min_radius %g is not >= 0", o->min_radius);
    if (!isfinite(o->ground) || !(o->ground_tolerance >= 0))
        return sy_fail(err, SY_EUSAGE, "mesh check: ground %g / ground_tolerance %g invalid", o->ground,
                       o->ground_tolerance);
    if (!(o->sail_radii > 0) || !(o->across_radii > 0))
        return sy_fail(err, SY_EUSAGE, "mesh check: sail_radii and across_radii must be positive");
    return SY_OK;
}

/* The bark of a level: its meshes that are not leaf cards or the impostor
 * (those are instanced or named "impostor"), i.e. every mesh whose name
 * starts with "bark". */
static int is_bark(const sy_mesh *m) { return strncmp(m->name, "bark", 4) == 0; }

static sy_code check_level(const sy_asset *a, size_t level, const sy_bvh *cap_bvh, const capsule *caps,
                           const sy_mesh_check_options *o, sy_mesh_check_level *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    out->bark_top = -INFINITY;
    out->leaf_top = -INFINITY;
    const sy_lod *lod = &a->lods[level];
    size_t nt = 0;
    for (int k = 0; k < lod->n_meshes; k++) {
        const sy_mesh *m = &a->meshes[lod->meshes[k]];
        if (is_bark(m)) nt += m->n_indices / 3;
    }
    double *tri = malloc((9 * nt + 1) * sizeof *tri);
    sy_box *boxes = malloc((nt + 1) * sizeof *boxes);
    if (!tri || !boxes) {
        free(tri), free(boxes);
        return sy_fail(err, SY_EINTERNAL, "mesh check: out of memory");
    }
    size_t t = 0;
    cap_ctx cc = {caps, 0, 0}, axis_cc = {caps, 1, 0}, room_cc = {caps, 1, 1};
    uint32_t hint = UINT32_MAX;
    for (int k = 0; k < lod->n_meshes; k++) {
        const sy_mesh *m = &a->meshes[lod->meshes[k]];
        if (!is_bark(m)) continue;
        sy_code rc = topology(m->position, m->n_vertices, m->indices, m->n_indices / 3, out, err);
        if (rc != SY_OK) {
            free(tri), free(boxes);
            return rc;
        }
        for (size_t v = 0; v < m->n_vertices; v++) {
            double p[3];
            to_zup(m->position + 3 * v, p);
            if (p[2] < o->ground - o->ground_tolerance) out->below_ground++;
            if (p[2] > out->bark_top) out->bark_top = p[2];
        }
        for (size_t f = 0; f < m->n_indices / 3; f++, t++) {
            double *q = tri + 9 * t;
            for (int c = 0; c < 3; c++) to_zup(m->position + 3 * m->indices[3 * f + c], q + 3 * c);
            sy_box_empty(&boxes[t]);
            for (int c = 0; c < 3; c++) sy_box_add_point(&boxes[t], q + 3 * c);
            double e1[3], e2[3], n[3], lmax = 0;
            int sail = 0;
            for (int k2 = 0; k2 < 3; k2++) e1[k2] = q[3 + k2] - q[k2], e2[k2] = q[6 + k2] - q[k2];
            n[0] = e1[1] * e2[2] - e1[2] * e2[1];
            n[1] = e1[2] * e2[0] - e1[0] * e2[2];
            n[2] = e1[0] * e2[1] - e1[1] * e2[0];
            double area = 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
            /* Local radius: the largest of the radii of the capsules
             * nearest each corner (corners lie on the surface they belong to). */
            double rloc = 0;
            uint32_t corner_cap[3] = {UINT32_MAX, UINT32_MAX, UINT32_MAX}, corner_room[3];
            for (int c = 0; c < 3; c++) {
                double g, tt;
                corner_room[c] = sy_bvh_nearest(cap_bvh, q + 3 * c, INFINITY, cap_distance, &room_cc, hint, &g);
                uint32_t ci = sy_bvh_nearest(cap_bvh, q + 3 * c, INFINITY, cap_distance, &cc, hint, &g);
                if (ci == UINT32_MAX) continue;
                hint = ci;
                corner_cap[c] = ci;
                capsule_gap(&caps[ci], q + 3 * c, &tt);
                double r = caps[ci].ra + tt * (caps[ci].rb - caps[ci].ra);
                if (r > rloc) rloc = r;
            }
            for (int c = 0; c < 3 && rloc > 0; c++) {
                const double *u = q + 3 * c, *w = q + 3 * ((c + 1) % 3);
                double d[3] = {w[0] - u[0], w[1] - u[1], w[2] - u[2]};
                double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
                if (len > lmax) lmax = len;
                /* Across: the edge's extent perpendicular to the branch axis
                 * nearest its midpoint; off: the midpoint's distance outside
                 * the skeleton's surface. Both in local radii. */
                double mid[3] = {0.5 * (u[0] + w[0]), 0.5 * (u[1] + w[1]), 0.5 * (u[2] + w[2])}, gap;
                uint32_t ci = sy_bvh_nearest(cap_bvh, mid, INFINITY, cap_distance, &cc, hint, &gap);
                if (ci == UINT32_MAX) continue;
                /* Across: the edge's extent perpendicular to a branch axis,
                 * the least over the branches nearest its two ends and its
                 * midpoint, each found both by distance and by distance in
                 * units of the branch's room (a twig's spline may bow 5 % of
                 * a long segment towards a neighbouring twig, which is then
                 * nearer). An edge running along its own twig near a
                 * junction has its midpoint nearest the parent, across
                 * which it runs; an edge spanning two branches (a sail) is
                 * across all of them. A child starting on its parent's axis
                 * has a zero-length first capsule: the nearest branch with
                 * a direction stands in for it. */
                const capsule *cp = &caps[ci];
                double g3;
                uint32_t cand[6] = {ci, corner_cap[c], corner_cap[(c + 1) % 3],
                                    sy_bvh_nearest(cap_bvh, mid, INFINITY, cap_distance, &room_cc, ci, &g3),
                                    corner_room[c], corner_room[(c + 1) % 3]};
                double across = INFINITY;
                for (int h = 0; h < 6; h++) {
                    if (cand[h] == UINT32_MAX) continue;
                    const capsule *axis = &caps[cand[h]];
                    if (!has_axis(axis)) {
                        const double *at = h % 3 == 0 ? mid : h % 3 == 1 ? u : w;
                        double g2;
                        uint32_t c2 = sy_bvh_nearest(cap_bvh, at, INFINITY, cap_distance, &axis_cc, UINT32_MAX, &g2);
                        if (c2 == UINT32_MAX) continue;
                        axis = &caps[c2];
                    }
                    double ax[3];
                    sy_v3_sub(ax, axis->b, axis->a);
                    double along = sy_v3_dot(d, ax) / axis->len;
                    across = fmin(across, sqrt(fmax(0, len * len - along * along)) / fmax(rloc, SPLINE_SLACK * axis->len));
                }
                if (across == INFINITY) across = 0;
                /* The mesh follows a smooth curve through the nodes, the
                 * capsules the polyline: allow 5 % of the segment's length. */
                double off = gap / fmax(rloc, SPLINE_SLACK * cp->len);
                if (across > out->max_across) out->max_across = across;
                if (len / rloc > out->max_edge_radii) out->max_edge_radii = len / rloc;
                if (off > out->max_off_surface) out->max_off_surface = off;
                if (off > o->sail_radii) sail = 1;
            }
            out->sails += (size_t)sail;
            if (area < SLIVER_AREA) out->degenerate++;
            if (area < SLIVER_AREA || 2 * area < SLIVER_ASPECT * lmax * lmax) out->slivers++;
            if (lmax > out->max_edge) out->max_edge = lmax;
        }
        out->bark_triangles += m->n_indices / 3;
    }
    /* Leaves: each card's petiole (its local origin) against this level's
     * bark, and every card vertex against the ground. */
    sy_bvh tb;
    memset(&tb, 0, sizeof tb);
    sy_code rc = nt ? sy_bvh_build(&tb, boxes, nt, err) : SY_OK;
    free(boxes);
    if (rc != SY_OK) {
        free(tri);
        return rc;
    }
    tri_ctx tc = {tri};
    if (nt) sy_bvh_reorder(&tb, tri, 9 * sizeof(double), err);
    double gap_sum = 0;
    for (int k = 0; k < lod->n_instances; k++) {
        const sy_instances *in = &lod->instances[k];
        const sy_mesh *card = &a->meshes[in->mesh];
        hint = UINT32_MAX;
        for (size_t i = 0; i < in->n; i++) {
            double p[3];
            to_zup(in->translation + 3 * i, p);
            double s = in->scale[3 * i + 1], d = INFINITY;
            if (nt) hint = sy_bvh_nearest(&tb, p, INFINITY, tri_distance, &tc, hint, &d);
            double rel = d / s;
            out->leaves++;
            gap_sum += rel;
            if (rel > 1) out->leaves_far++;
            if (rel > out->max_leaf_gap) out->max_leaf_gap = rel;
            if (p[2] > out->leaf_top) out->leaf_top = p[2];
            const float *r = in->rotation + 4 * i;
            for (size_t v = 0; v < card->n_vertices; v++) {
                /* q v q* for unit q = (x, y, z, w), then scale and move. */
                const float *c = card->position + 3 * v;
                double x = r[0], y = r[1], z = r[2], w = r[3];
                double vx = c[0] * in->scale[3 * i], vy = c[1] * in->scale[3 * i + 1], vz = c[2] * in->scale[3 * i + 2];
                double tx = 2 * (y * vz - z * vy), ty = 2 * (z * vx - x * vz), tz = 2 * (x * vy - y * vx);
                double wy = vy + w * ty + (z * tx - x * tz);
                double yup_y = in->translation[3 * i + 1] + wy;
                if (yup_y < o->ground - o->ground_tolerance) {
                    out->leaves_below_ground++;
                    break;
                }
            }
        }
    }
    out->mean_leaf_gap = out->leaves ? gap_sum / (double)out->leaves : 0;
    sy_bvh_free(&tb);
    free(tri);
    return SY_OK;
}

static void node_pos(const sy_skeleton *sk, int32_t i, double out[3])
{
    for (int k = 0; k < 3; k++) out[k] = sk->pos[3 * (size_t)i + k];
}

/* The point of the stem through node p nearest q, searched along the
 * stem from p both ways over the arc length |q - p| (backwards onto the
 * segment that joins it to its own parent); near starts at p's position. */
static void nearest_on_branch(const sy_skeleton *sk, const int32_t *cont, int32_t p, const double q[3],
                              double near[3])
{
    double d[3], best = INFINITY;
    node_pos(sk, p, d);
    sy_v3_sub(d, q, d);
    double reach = sy_v3_len(d);
    for (int dir = 0; dir < 2; dir++) {
        double walked = 0;
        for (int32_t x = p; walked < reach;) {
            int32_t ia = dir ? x : sk->parent[x], ib = dir ? cont[x] : x;
            if (ia < 0 || ib < 0) break;
            double a[3], b[3], t;
            node_pos(sk, ia, a), node_pos(sk, ib, b);
            double dd = sy_point_segment_distance(q, a, b, &t);
            if (dd < best)
                for (int k = 0; k < 3; k++) best = dd, near[k] = a[k] + t * (b[k] - a[k]);
            sy_v3_sub(d, b, a);
            walked += sy_v3_len(d);
            if (!dir && cont[ia] != ib) break; /* ib starts its stem */
            x = dir ? ib : ia;
        }
    }
}

/* A capsule's length and its box (ends grown by the larger radius). */
static void capsule_close(capsule *c, sy_box *box)
{
    c->len = sy_v3_dist(c->a, c->b);
    double rm = fmax(c->ra, c->rb), lo[3], hi[3];
    for (int k = 0; k < 3; k++) lo[k] = fmin(c->a[k], c->b[k]) - rm, hi[k] = fmax(c->a[k], c->b[k]) + rm;
    sy_box_empty(box);
    sy_box_add_point(box, lo);
    sy_box_add_point(box, hi);
}

sy_code sy_mesh_check(const sy_asset *a, const sy_skeleton *sk, const sy_mesh_check_options *o,
                      sy_mesh_check_report *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    sy_code rc = sy_mesh_check_options_check(o, err);
    if (rc != SY_OK) return rc;
    size_t nc = 0;
    for (size_t i = 0; i < sk->n; i++)
        if (sk->parent[i] >= 0) nc++;
    /* Room for a split at the ground and a tip stretch at every node
     * besides (SY_MESH_TIP_EXTENSION). */
    capsule *caps = malloc((3 * nc + 1) * sizeof *caps);
    sy_box *boxes = malloc((3 * nc + 1) * sizeof *boxes);
    if (!caps || !boxes) {
        free(caps), free(boxes);
        return sy_fail(err, SY_EINTERNAL, "mesh check: out of memory");
    }
    /* Each node's continuation in its stem as the mesher chains them, to
     * find where a child really leaves its parent. */
    int32_t *cont = malloc((sk->n + 1) * sizeof *cont);
    if (!cont) {
        free(caps), free(boxes);
        return sy_fail(err, SY_EINTERNAL, "mesh check: out of memory");
    }
    sy_skeleton_continuations(sk, cont);
    /* The trunk: the root's chain of continuations. */
    uint8_t *trunk = calloc(sk->n + 1, 1);
    if (!trunk) {
        free(caps), free(boxes), free(cont);
        return sy_fail(err, SY_EINTERNAL, "mesh check: out of memory");
    }
    double mesh_ground = INFINITY; /* the mesher's: the root's height (sy_stems_build) */
    for (size_t i = 0; i < sk->n; i++)
        if (sk->parent[i] < 0) {
            if (mesh_ground == INFINITY) mesh_ground = sk->pos[3 * i + 2];
            for (int32_t x = (int32_t)i; x >= 0 && !trunk[x]; x = cont[x]) trunk[x] = 1;
        }
    nc = 0;
    for (size_t i = 0; i < sk->n; i++) {
        int32_t p = sk->parent[i];
        if (p < 0) continue;
        capsule *c = &caps[nc];
        for (int k = 0; k < 3; k++) c->a[k] = sk->pos[3 * p + k], c->b[k] = sk->pos[3 * i + k];
        if (cont[p] != (int32_t)i) {
            /* A child starts where its parent's axis passes nearest its first
             * node, not at the node before: the mesher attaches it there,
             * searching the parent's curve as far either way from the node
             * as the child's first node lies from it (attach_on_parent in
             * stages/mesh/stems.c). Searching only the two segments at the
             * node measured a synthesised whorl's twigs, attached 20 cm
             * down a fir's shoot, as sails across that gap. */
            const double q[3] = {c->b[0], c->b[1], c->b[2]};
            double near[3] = {c->a[0], c->a[1], c->a[2]};
            nearest_on_branch(sk, cont, p, q, near);
            memcpy(c->a, near, sizeof near);
        }
        /* A stem's first segment carries its own radius at the attachment. */
        c->ra = fmax(cont[p] == (int32_t)i ? sk->radius[p] : sk->radius[i], o->min_radius);
        c->rb = fmax(sk->radius[i], o->min_radius);
        /* The mesher lifts a drooping twig's samples above the ground
         * (sample_curve in stages/mesh/stems.c): so do its capsules. A
         * segment that goes under it (or comes up out of it) is split where
         * its axis meets it: the mesher draws it down to there and along
         * the ground after (a ring at the contact). Lifting the lower end
         * alone drew the segment as one slant above the drawn twig (the
         * grown Norway spruce's skirt: 123 sails, all within 0.3 m of the
         * ground). */
        if (!trunk[i]) {
            double za = c->a[2] - (mesh_ground + c->ra), zb = c->b[2] - (mesh_ground + c->rb);
            if ((za < 0) != (zb < 0) && sy_v3_dist(c->a, c->b) > 1e-6) {
                double t = za / (za - zb);
                capsule *d = &caps[nc + 1];
                *d = *c;
                for (int k = 0; k < 3; k++) c->b[k] = d->a[k] = c->a[k] + t * (d->b[k] - c->a[k]);
                c->rb = d->ra = c->ra + t * (d->rb - c->ra);
                d->a[2] = mesh_ground + d->ra;
                d->b[2] = fmax(d->b[2], mesh_ground + d->rb);
                c->a[2] = fmax(c->a[2], mesh_ground + c->ra), c->b[2] = d->a[2];
                capsule_close(c, &boxes[nc]);
                c = d, nc++;
            } else {
                c->a[2] = fmax(c->a[2], mesh_ground + c->ra);
                c->b[2] = fmax(c->b[2], mesh_ground + c->rb);
            }
        }
        capsule_close(c, &boxes[nc]);
        nc++;
    }
    /* A chain that ends where children leave goes on past its last node
     * as the mesher draws it (tip_stretch in stages/mesh/stems.c): along its
     * last segment, by SY_MESH_TIP_EXTENSION radii of the thicker of its
     * tip and its thickest child there, at its tip radius. */
    float *tip_child = calloc(sk->n + 1, sizeof *tip_child);
    if (!tip_child) {
        free(caps), free(boxes), free(cont), free(trunk);
        return sy_fail(err, SY_EINTERNAL, "mesh check: out of memory");
    }
    for (size_t i = 0; i < sk->n; i++) {
        int32_t p = sk->parent[i];
        if (p >= 0 && cont[p] < 0) tip_child[p] = fmaxf(tip_child[p], sk->radius[i]);
    }
    for (size_t i = 0; i < sk->n; i++) {
        int32_t p = sk->parent[i];
        if (p < 0 || !(tip_child[i] > 0)) continue;
        double r = fmax(sk->radius[i], o->min_radius), d[3];
        for (int k = 0; k < 3; k++) d[k] = (double)sk->pos[3 * i + k] - sk->pos[3 * (size_t)p + k];
        double len = sqrt(sy_v3_dot(d, d));
        if (!(len > 0)) continue;
        double ext = SY_MESH_TIP_EXTENSION * fmax(tip_child[i], r);
        capsule *c = &caps[nc];
        for (int k = 0; k < 3; k++) c->a[k] = sk->pos[3 * i + k], c->b[k] = c->a[k] + d[k] / len * ext;
        if (!trunk[i]) c->a[2] = fmax(c->a[2], mesh_ground + r), c->b[2] = fmax(c->b[2], mesh_ground + r);
        c->ra = c->rb = r;
        capsule_close(c, &boxes[nc]);
        nc++;
    }
    free(tip_child);
    free(cont), free(trunk);
    sy_bvh cb;
    rc = sy_bvh_build(&cb, boxes, nc, err);
    free(boxes);
    if (rc == SY_OK) rc = sy_bvh_reorder(&cb, caps, sizeof *caps, err);
    size_t levels = 0;
    for (size_t l = 0; l < a->n_lods && rc == SY_OK; l++) {
        int meshy = 0;
        for (int k = 0; k < a->lods[l].n_meshes; k++) meshy |= is_bark(&a->meshes[a->lods[l].meshes[k]]);
        if (!meshy || levels >= SY_MESH_CHECK_MAX_LEVELS) continue;
        rc = check_level(a, l, &cb, caps, o, &out->level[levels], err);
        out->level[levels].lod = l;
        size_t tris = out->level[levels].bark_triangles;
        const sy_lod *lod = &a->lods[l];
        for (int k = 0; k < lod->n_instances; k++)
            tris += lod->instances[k].n * (a->meshes[lod->instances[k].mesh].n_indices / 3);
        out->level[levels].triangles = tris;
        levels++;
    }
    out->n_levels = levels;
    /* Silhouettes: intersection over union of each level's coverage with
     * LOD0's, front and side averaged, on LOD0's box. */
    if (rc == SY_OK && levels > 0) {
        int S = SILHOUETTE_PX;
        uint8_t *m0 = malloc(2 * (size_t)S * (size_t)S), *mk = malloc(2 * (size_t)S * (size_t)S);
        float lo[3], hi[3];
        if (!m0 || !mk) rc = sy_fail(err, SY_EINTERNAL, "mesh check: out of memory");
        if (rc == SY_OK) {
            sy_mesh_lod_bounds(a, out->level[0].lod, lo, hi);
            rc = sy_mesh_silhouettes(a, out->level[0].lod, lo, hi, S, m0, m0 + (size_t)S * (size_t)S, err);
        }
        for (size_t l = 0; l < levels && rc == SY_OK; l++) {
            rc = sy_mesh_silhouettes(a, out->level[l].lod, lo, hi, S, mk, mk + (size_t)S * (size_t)S, err);
            double iou = 0;
            for (int v = 0; v < 2 && rc == SY_OK; v++) {
                size_t in = 0, un = 0;
                for (size_t i = 0; i < (size_t)S * (size_t)S; i++) {
                    uint8_t a0 = m0[(size_t)v * (size_t)S * (size_t)S + i], ak = mk[(size_t)v * (size_t)S * (size_t)S + i];
                    in += a0 & ak, un += a0 | ak;
                }
                iou += 0.5 * (un ? (double)in / (double)un : 1);
            }
            out->level[l].silhouette_iou = iou;
        }
        free(m0), free(mk);
    }
    for (size_t l = 1; l < levels; l++) {
        double r = (double)out->level[l].triangles / (double)(out->level[l - 1].triangles ? out->level[l - 1].triangles : 1);
        out->level[l].ratio = r;
    }
    sy_bvh_free(&cb);
    free(caps);
    return rc;
}
