/* Skeleton -> stems: one chain of nodes per branch id, the smooth curve
 * through it (Catmull-Rom style Hermite segments with Bessel tangents and a
 * monotone cubic radius), adaptive ring sampling, rotation-minimising frames,
 * and the trim that starts a child's tube where it leaves its parent. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_internal.h"

#define SY_PI 3.14159265358979323846f
/* Points closer than this are one point: a zero-length segment has no
 * direction and would give NaN tangents. */
#define DEDUPE_EPS 1e-5f
/* Adaptive sampling bounds per ring step. */
#define MAX_TURN (10.0f * SY_PI / 180.0f)
#define MAX_RADIUS_STEP 0.15f
#define RINGS_PER_STEM 6
#define TWIG_RINGS 2
#define MAX_SUBDIV 64
/* A lean branch's rings (sy_stem_lean): one per 45 degrees of turn. Traced
 * twigs step cell to cell with turns of 60-90 degrees; at 30 (before stop 39)
 * their rings took the triangles the four-sided lean parents need
 * (LEAN_PARENT_MIN_RADIAL), and the LOD0 budget dropped a fifth of a
 * willow's twigs. */
#define LEAN_MAX_TURN (45.0f * SY_PI / 180.0f)
/* Ring vertices of a lobed trunk at most (Lobes goes up to 64). */
#define LOBED_MAX_RADIAL 64

void sy_stems_free(sy_stems *st)
{
    for (size_t i = 0; i < st->n; i++) {
        sy_stem *s = &st->s[i];
        free(s->nodes);
        free(s->pts);
        free(s->rad);
        free(s->pt_s);
        free(s->sp);
        free(s->st);
        free(s->sn);
        free(s->sr);
        free(s->ss);
        free(s->sdr);
    }
    free(st->s);
    free(st->by_depth);
    free(st->node_stem);
    free(st->node_s);
    free(st->reach);
    memset(st, 0, sizeof *st);
}

/* Point p raises the reach of stem k and of each of its ancestors to its
 * distance from that stem's base. */
static void reach_point(sy_stems *st, int32_t k, const float p[3])
{
    for (; k >= 0; k = st->s[k].parent) {
        const float *b = st->s[k].pts;
        if (!b) continue;
        float d = sqrtf((p[0] - b[0]) * (p[0] - b[0]) + (p[1] - b[1]) * (p[1] - b[1]) + (p[2] - b[2]) * (p[2] - b[2]));
        if (d > st->reach[k]) st->reach[k] = d;
    }
}

sy_code sy_stems_reach(sy_stems *st, const sy_leaves *lv, sy_error *err)
{
    free(st->reach);
    st->reach = sy_calloc(st->n + 1, sizeof *st->reach, err, "mesh");
    if (!st->reach) return SY_EINTERNAL;
    for (size_t i = 0; i < st->n; i++)
        for (size_t j = 0; j < st->s[i].n_pts; j++) reach_point(st, (int32_t)i, st->s[i].pts + 3 * j);
    for (size_t l = 0; lv && l < lv->n; l++) reach_point(st, st->node_stem[lv->node[l]], lv->pos + 3 * l);
    return SY_OK;
}

/* ---- chains ---- */

typedef struct {
    int32_t branch, start;
} stem_key;

static int cmp_key(const void *a, const void *b)
{
    const stem_key *x = a, *y = b;
    if (x->branch != y->branch) return x->branch < y->branch ? -1 : 1;
    return (x->start > y->start) - (x->start < y->start);
}

/* Splits the nodes into chains. A chain starts at the root, at a node whose
 * parent carries another branch id, or at a second same-branch child of a
 * node (a malformed fork: it becomes a stem of its own). It continues through
 * the lowest-index same-branch child. Every node lies in exactly one chain. */
static sy_code build_chains(const sy_skeleton *sk, sy_stems *st, sy_error *err)
{
    size_t n = sk->n;
    int32_t *cont = malloc(n * sizeof *cont);
    stem_key *keys = malloc(n * sizeof *keys);
    st->node_stem = malloc(n * sizeof *st->node_stem);
    st->node_s = calloc(n, sizeof *st->node_s);
    if (!cont || !keys || !st->node_stem || !st->node_s) {
        free(cont);
        free(keys);
        return sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
    }
    sy_skeleton_continuations(sk, cont);
    size_t ns = 0;
    for (size_t i = 0; i < n; i++) {
        int32_t p = sk->parent[i];
        if (p < 0 || cont[p] != (int32_t)i) keys[ns++] = (stem_key){sk->branch[i], (int32_t)i};
    }
    qsort(keys, ns, sizeof *keys, cmp_key);
    st->s = calloc(ns, sizeof *st->s);
    if (!st->s) {
        free(cont);
        free(keys);
        return sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
    }
    st->n = ns;
    for (size_t k = 0; k < ns; k++) {
        sy_stem *s = &st->s[k];
        s->branch_id = keys[k].branch;
        size_t len = 0;
        for (int32_t v = keys[k].start; v >= 0; v = cont[v]) len++;
        s->nodes = malloc(len * sizeof *s->nodes);
        if (!s->nodes) {
            free(cont);
            free(keys);
            return sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
        }
        len = 0;
        for (int32_t v = keys[k].start; v >= 0; v = cont[v]) {
            s->nodes[len++] = v;
            st->node_stem[v] = (int32_t)k;
        }
        s->n_nodes = len;
    }
    free(cont);
    free(keys);
    for (size_t k = 0; k < ns; k++) {
        sy_stem *s = &st->s[k];
        s->attach_node = sk->parent[s->nodes[0]];
        s->parent = s->attach_node >= 0 ? st->node_stem[s->attach_node] : -1;
        if (s->parent < 0) st->root = (int32_t)k;
        else st->s[s->parent].has_children = 1;
    }
    return SY_OK;
}

int sy_stem_by_radius_cmp(const void *x, const void *y)
{
    const sy_stem_by_radius *a = x, *b = y;
    if (a->r_base != b->r_base) return a->r_base > b->r_base ? -1 : 1;
    return (a->stem > b->stem) - (a->stem < b->stem);
}

/* Depth of every stem and the parents-first order, thickest first within a
 * depth (fit_on_parent): the thinner child slides past the thicker one, not
 * the other way round. By index, a twig listed before the limb beside it
 * kept its place and the limb, unable to slide past it, crossed its ring. */
static sy_code order_by_depth(const sy_skeleton *sk, sy_stems *st, sy_error *err)
{
    st->by_depth = malloc((st->n ? st->n : 1) * sizeof *st->by_depth);
    size_t *count = calloc(st->n + 1, sizeof *count);
    if (!st->by_depth || !count) {
        free(count);
        return sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
    }
    int max_depth = 0;
    for (size_t k = 0; k < st->n; k++) {
        int d = 0;
        for (int32_t p = st->s[k].parent; p >= 0; p = st->s[p].parent) d++;
        st->s[k].depth = d;
        if (d > max_depth) max_depth = d;
        count[d + 1]++;
    }
    for (int d = 1; d <= max_depth; d++) count[d] += count[d - 1];
    for (size_t k = 0; k < st->n; k++) st->by_depth[count[st->s[k].depth]++] = (int32_t)k;
    free(count);
    sy_stem_by_radius *key = malloc((st->n ? st->n : 1) * sizeof *key);
    if (!key) return sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
    for (size_t a = 0; a < st->n;) {
        size_t b = a;
        while (b < st->n && st->s[st->by_depth[b]].depth == st->s[st->by_depth[a]].depth) b++;
        for (size_t k = a; k < b; k++)
            key[k] = (sy_stem_by_radius){st->by_depth[k], sk->radius[st->s[st->by_depth[k]].nodes[0]]};
        qsort(key + a, b - a, sizeof *key, sy_stem_by_radius_cmp);
        for (size_t k = a; k < b; k++) st->by_depth[k] = key[k].stem;
        a = b;
    }
    free(key);
    return SY_OK;
}

/* ---- curve ---- */

/* Polyline through the attachment node and the chain; records for each
 * chain node the polyline point it collapsed into (node_pt). */
static int build_polyline(const sy_skeleton *sk, sy_stem *s, int32_t *node_pt, float min_radius)
{
    size_t cap = s->n_nodes + 2; /* the attachment, the chain and a tip stretch (extend_tip) */
    s->pts = malloc(cap * 3 * sizeof(float));
    s->rad = malloc(cap * sizeof(float));
    s->pt_s = malloc(cap * sizeof(float));
    if (!s->pts || !s->rad || !s->pt_s) return 0;
    size_t m = 0;
    if (s->attach_node >= 0) {
        memcpy(s->pts, sk->pos + 3 * s->attach_node, 3 * sizeof(float));
        /* The tube starts with the child's own radius, not the parent's. */
        s->rad[0] = fmaxf(sk->radius[s->nodes[0]], min_radius);
        m = 1;
    }
    for (size_t i = 0; i < s->n_nodes; i++) {
        const float *p = sk->pos + 3 * s->nodes[i];
        if (m > 0) {
            const float *q = s->pts + 3 * (m - 1);
            float d[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]};
            if (sy_dot3(d, d) < DEDUPE_EPS * DEDUPE_EPS) {
                node_pt[i] = (int32_t)(m - 1);
                continue;
            }
        }
        memcpy(s->pts + 3 * m, p, 3 * sizeof(float));
        s->rad[m] = fmaxf(sk->radius[s->nodes[i]], min_radius);
        node_pt[i] = (int32_t)m;
        m++;
    }
    s->n_pts = m;
    return 1;
}

/* A stem with children at its last node, none of them going on as it (each
 * turning more than the 60 degrees sy_skeleton_continuations allows), ended
 * in its tip cap there: their rings stood on the cap, off the tube's quads,
 * and were capped instead of welded (61 of the 84 such rings on rTwig's
 * sapling, whose LOD0 welded 68 % of its junctions). The tube goes on past
 * that node by SY_MESH_TIP_EXTENSION radii along `dir`, the stem's last
 * chord as built (tip_stretch), at its tip radius (extend_tip, after the
 * base has moved: the single-node guards of reattach_buried and
 * attach_on_parent count the stem's own points). The mesh check draws the
 * same stretch (stages/eval/mesh_check.c). */
static int tip_stretch(const sy_stem *s, float tip_child, float dir[3], float *ext)
{
    size_t m = s->n_pts;
    if (!(tip_child > 0) || m < 2) return 0;
    const float *a = s->pts + 3 * (m - 2), *b = s->pts + 3 * (m - 1);
    for (int k = 0; k < 3; k++) dir[k] = b[k] - a[k];
    float len = sqrtf(sy_dot3(dir, dir));
    if (!(len > 0)) return 0;
    for (int k = 0; k < 3; k++) dir[k] /= len;
    *ext = SY_MESH_TIP_EXTENSION * fmaxf(tip_child, s->rad[m - 1]);
    return 1;
}

static void extend_tip(sy_stem *s, const float dir[3], float ext)
{
    size_t m = s->n_pts;
    for (int k = 0; k < 3; k++) s->pts[3 * m + k] = s->pts[3 * (m - 1) + k] + dir[k] * ext;
    s->rad[m] = s->rad[m - 1];
    s->n_pts = m + 1;
}

/* Unit Bessel tangent at polyline point i (chord-weighted average of the
 * adjacent chord directions; the chord itself at the ends). */
static void bessel_tangent(const sy_stem *s, size_t i, float out[3])
{
    size_t n = s->n_pts;
    const float *p = s->pts;
    if (i == 0 || i == n - 1) {
        size_t a = i == 0 ? 0 : n - 2;
        for (int k = 0; k < 3; k++) out[k] = p[3 * (a + 1) + k] - p[3 * a + k];
        sy_normalize3(out);
        return;
    }
    float a[3], b[3];
    for (int k = 0; k < 3; k++) {
        a[k] = p[3 * i + k] - p[3 * (i - 1) + k];
        b[k] = p[3 * (i + 1) + k] - p[3 * i + k];
    }
    float da = sy_normalize3(a), db = sy_normalize3(b);
    for (int k = 0; k < 3; k++) out[k] = (db * a[k] + da * b[k]) / (da + db);
    if (sy_normalize3(out) < 1e-6f) {
        /* A hairpin: the chords cancel; follow the incoming one. */
        for (int k = 0; k < 3; k++) out[k] = a[k];
    }
}

/* Fritsch-Carlson slopes dr/ds at the polyline points: a monotone cubic, so
 * the radius never overshoots between nodes (no bulges, never negative). */
static void radius_slopes(const sy_stem *s, const float *chord, float *slope)
{
    size_t n = s->n_pts;
    for (size_t i = 0; i < n; i++) {
        float dl = i > 0 ? (s->rad[i] - s->rad[i - 1]) / chord[i - 1] : 0;
        float dr = i + 1 < n ? (s->rad[i + 1] - s->rad[i]) / chord[i] : 0;
        if (i == 0) slope[i] = dr;
        else if (i + 1 == n) slope[i] = dl;
        else slope[i] = dl * dr > 0 ? 0.5f * (dl + dr) : 0;
    }
    for (size_t i = 0; i + 1 < n; i++) {
        float d = (s->rad[i + 1] - s->rad[i]) / chord[i];
        if (d == 0) {
            slope[i] = slope[i + 1] = 0;
            continue;
        }
        float a = slope[i] / d, b = slope[i + 1] / d;
        if (a * a + b * b > 9) {
            float t = 3 / sqrtf(a * a + b * b);
            slope[i] = t * a * d;
            slope[i + 1] = t * b * d;
        }
    }
}

static int alloc_samples(sy_stem *s, size_t n)
{
    s->sp = malloc(n * 3 * sizeof(float));
    s->st = malloc(n * 3 * sizeof(float));
    s->sn = malloc(n * 3 * sizeof(float));
    s->sr = malloc(n * sizeof(float));
    s->ss = malloc(n * sizeof(float));
    s->sdr = malloc(n * sizeof(float));
    return s->sp && s->st && s->sn && s->sr && s->ss && s->sdr;
}

/* Segment i of stem s as sample_curve draws it: the Hermite slopes m0, m1
 * (shortened at sharp polyline corners, below) and the radius at t. */
static void segment_slopes(const sy_stem *s, size_t i, const float *chord, const float *tan, float m0[3], float m1[3])
{
    /* Hermite slopes of the chord's length overshoot where the tangent
     * leaves the chord at a sharp polyline corner (a noisy reconstructed
     * twig bulged up to 10 radii off its skeleton, the run outputs'
     * "sails"): each is shortened by the cosine of its angle to the chord
     * (at least 0.3), which keeps its direction, so the curve stays G1, and
     * keeps straight runs as they were. */
    const float *p0 = s->pts + 3 * i, *p1 = p0 + 3;
    float cd[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
    float inv = chord[i] > 0 ? 1.0f / chord[i] : 0;
    float k0 = fmaxf(0.3f, sy_dot3(tan + 3 * i, cd) * inv), k1 = fmaxf(0.3f, sy_dot3(tan + 3 * i + 3, cd) * inv);
    for (int k = 0; k < 3; k++) {
        m0[k] = k0 * chord[i] * tan[3 * i + k];
        m1[k] = k1 * chord[i] * tan[3 * i + 3 + k];
    }
}

/* Radius of segment i at t (cubic Hermite with slopes scaled to the
 * segment) and its derivative in t. */
static float segment_radius(const sy_stem *s, size_t i, const float *chord, const float *slope, float t, float *drdt)
{
    float t2 = t * t, t3 = t2 * t;
    float ra = s->rad[i], rb = s->rad[i + 1], ma = slope[i] * chord[i], mb = slope[i + 1] * chord[i];
    *drdt = (6 * t2 - 6 * t) * ra + (3 * t2 - 4 * t + 1) * ma + (-6 * t2 + 6 * t) * rb + (3 * t2 - 2 * t) * mb;
    return (2 * t3 - 3 * t2 + 1) * ra + (t3 - 2 * t2 + t) * ma + (-2 * t3 + 3 * t2) * rb + (t3 - t2) * mb;
}

/* Where segment i's axis meets the ground (its height less the radius
 * there crosses `ground`), at most GROUND_CROSSINGS of them in (0, 1), in
 * order, none within a tenth of a step of the segment's sub even steps
 * (that step's ring draws it): found on GROUND_SCAN steps and bisected. A
 * branch that droops under the ground is drawn resting on it (sample_curve
 * lifts its rings); a ring at each contact draws the bend there, where the
 * rings either side of it cut across it (a limb's quads 10 cm above its
 * path on the ground, the mesh check's sails). */
#define GROUND_CROSSINGS 2
#define GROUND_SCAN 16
/* Height of segment i's axis at t above `ground` plus its radius there. */
static float ground_gap(const sy_stem *s, size_t i, const float *chord, const float *slope, const float m0[3],
                        const float m1[3], float ground, float t)
{
    float x[3], der[3], dr;
    sy_hermite(s->pts + 3 * i, m0, s->pts + 3 * i + 3, m1, t, x, der);
    return x[2] - ground - segment_radius(s, i, chord, slope, t, &dr);
}

static int ground_crossings(const sy_stem *s, size_t i, const float *chord, const float *tan, const float *slope,
                            float ground, int sub, float cross[GROUND_CROSSINGS])
{
    float m0[3], m1[3];
    segment_slopes(s, i, chord, tan, m0, m1);
    const float *p0 = s->pts + 3 * i, *p1 = p0 + 3;
    /* Clear of the ground throughout: the curve's Bezier heights (p0,
     * p0 + m0 / 3, p1 - m1 / 3, p1) bound it below, the radius's above. */
    float ra = s->rad[i], rb = s->rad[i + 1], ma = slope[i] * chord[i], mb = slope[i + 1] * chord[i];
    float zlo = fminf(fminf(p0[2], p0[2] + m0[2] / 3), fminf(p1[2] - m1[2] / 3, p1[2]));
    float rhi = fmaxf(fmaxf(ra, ra + ma / 3), fmaxf(rb - mb / 3, rb));
    if (zlo - rhi > ground) return 0;
    int n = 0;
    float prev = ground_gap(s, i, chord, slope, m0, m1, ground, 0);
    for (int k = 1; k <= GROUND_SCAN && n < GROUND_CROSSINGS; k++) {
        float lo = (float)(k - 1) / GROUND_SCAN, hi = (float)k / GROUND_SCAN;
        float g = ground_gap(s, i, chord, slope, m0, m1, ground, hi);
        if ((prev < 0) != (g < 0)) {
            int below = prev < 0;
            for (int it = 0; it < 20; it++) {
                float mid = 0.5f * (lo + hi);
                if ((ground_gap(s, i, chord, slope, m0, m1, ground, mid) < 0) == below) lo = mid;
                else hi = mid;
            }
            float t = 0.5f * (lo + hi), f = t * (float)sub;
            if (fabsf(f - roundf(f)) >= 0.1f) cross[n++] = t;
        }
        prev = g;
    }
    return n;
}

/* Samples the curve: every segment is split so that no ring step turns more
 * than MAX_TURN, changes the radius by more than MAX_RADIUS_STEP of itself, or
 * exceeds the target spacing (segment_length, or a sixth of the stem so that
 * wind bending has joints to bend at). */
static int sample_curve(sy_stem *s, const sy_mesh_options *opt, float ground)
{
    size_t n = s->n_pts;
    float *chord = malloc(n * sizeof(float)), *tan = malloc(n * 3 * sizeof(float));
    float *slope = malloc(n * sizeof(float));
    int *sub = malloc(n * sizeof(int));
    if (!chord || !tan || !slope || !sub) {
        free(chord), free(tan), free(slope), free(sub);
        return 0;
    }
    float total = 0;
    for (size_t i = 0; i + 1 < n; i++) {
        float d[3] = {s->pts[3 * i + 3] - s->pts[3 * i], s->pts[3 * i + 4] - s->pts[3 * i + 1],
                      s->pts[3 * i + 5] - s->pts[3 * i + 2]};
        chord[i] = sqrtf(sy_dot3(d, d));
        total += chord[i];
    }
    for (size_t i = 0; i < n; i++) bessel_tangent(s, i, tan + 3 * i);
    radius_slopes(s, chord, slope);
    /* A leaf-bearing twig bends as one piece: two steps give wind its joint
     * and keep the thousands of twigs of a crown inside the LOD0 budget. */
    int lean = sy_stem_lean(s);
    int rings = (s->has_children || s->parent < 0) && !lean ? RINGS_PER_STEM : TWIG_RINGS;
    float spacing = opt->segment_length > 0 ? opt->segment_length : total / (float)rings;
    size_t count = 1;
    float *cross = malloc(n * GROUND_CROSSINGS * sizeof *cross);
    int *n_cross = calloc(n, sizeof *n_cross);
    if (!cross || !n_cross) {
        free(chord), free(tan), free(slope), free(sub), free(cross), free(n_cross);
        return 0;
    }
    for (size_t i = 0; i + 1 < n; i++) {
        float c = sy_dot3(tan + 3 * i, tan + 3 * i + 3);
        float turn = acosf(c > 1 ? 1 : c < -1 ? -1 : c);
        float r0 = s->rad[i], r1 = s->rad[i + 1];
        float k = fmaxf(ceilf(chord[i] / spacing), ceilf(turn / (lean ? LEAN_MAX_TURN : MAX_TURN)));
        if (!lean) k = fmaxf(k, ceilf(fabsf(r1 - r0) / (MAX_RADIUS_STEP * fmaxf(r0, r1))));
        sub[i] = k < 1 ? 1 : k > MAX_SUBDIV ? MAX_SUBDIV : (int)k;
        count += (size_t)sub[i];
        if (s->parent >= 0) n_cross[i] = ground_crossings(s, i, chord, tan, slope, ground, sub[i], cross + GROUND_CROSSINGS * i);
        count += (size_t)n_cross[i];
    }
    if (!alloc_samples(s, count)) {
        free(chord), free(tan), free(slope), free(sub), free(cross), free(n_cross);
        return 0;
    }
    size_t j = 0;
    for (size_t i = 0; i + 1 < n; i++) {
        const float *p0 = s->pts + 3 * i, *p1 = p0 + 3;
        float m0[3], m1[3];
        segment_slopes(s, i, chord, tan, m0, m1);
        /* The even steps, and the ground contacts among them, in order. */
        int last = i + 2 == n, steps = sub[i] + last + n_cross[i];
        const float *ci = cross + GROUND_CROSSINGS * i;
        for (int k = 0, even = 0, c = 0; k < steps; k++) {
            float te = (float)even / (float)sub[i], der[3];
            int contact = c < n_cross[i] && (even > sub[i] - 1 + last || ci[c] < te);
            float t = contact ? ci[c++] : te;
            even += !contact;
            sy_hermite(p0, m0, p1, m1, t, s->sp + 3 * j, der);
            float speed = sy_normalize3(der);
            if (speed < 1e-9f) {
                for (int q = 0; q < 3; q++) der[q] = p1[q] - p0[q];
                sy_normalize3(der);
                speed = chord[i];
            }
            memcpy(s->st + 3 * j, der, sizeof der);
            float drdt, r = segment_radius(s, i, chord, slope, t, &drdt);
            s->sr[j] = fmaxf(r, 1e-5f);
            /* A branch that droops to the ground rests on it instead of
             * passing below (the trunk's base ring sits on it already). */
            if (s->parent >= 0 && s->sp[3 * j + 2] < ground + s->sr[j]) s->sp[3 * j + 2] = ground + s->sr[j];
            s->sdr[j] = drdt / speed;
            if (j == 0) {
                s->ss[j] = 0;
            } else {
                const float *a = s->sp + 3 * (j - 1), *b = s->sp + 3 * j;
                float d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
                s->ss[j] = s->ss[j - 1] + sqrtf(sy_dot3(d, d));
            }
            if (k == 0) s->pt_s[i] = s->ss[j];
            j++;
        }
    }
    s->n_samp = j;
    s->pt_s[n - 1] = s->ss[j - 1];
    s->length = s->ss[j - 1];
    free(chord), free(tan), free(slope), free(sub), free(cross), free(n_cross);
    return 1;
}

/* A grown child leaves its parent between two parent nodes, while its chain
 * starts from the node before: the first segment would run inside the
 * parent and come out as a flap. The attachment moves to the point of the
 * parent's curve nearest the child's first own point (ring samples, within
 * the parent segments next to the attachment node). */
static int attach_on_parent(const sy_stem *p, sy_stem *s)
{
    const float *q = s->pts + 3;
    float best = INFINITY, at[3] = {s->pts[0], s->pts[1], s->pts[2]}, as = s->attach_s;
    /* It cannot leave the parent farther along than its first point lies
     * from the attachment node. */
    float d0[3] = {q[0] - at[0], q[1] - at[1], q[2] - at[2]}, reach = sqrtf(sy_dot3(d0, d0));
    for (size_t k = 0; k + 1 < p->n_samp; k++) {
        if (p->ss[k + 1] < s->attach_s - reach || p->ss[k] > s->attach_s + reach) continue;
        const float *a = p->sp + 3 * k, *b = a + 3;
        float ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, aq[3] = {q[0] - a[0], q[1] - a[1], q[2] - a[2]};
        float l2 = sy_dot3(ab, ab), t = l2 > 0 ? sy_dot3(aq, ab) / l2 : 0;
        t = t < 0 ? 0 : t > 1 ? 1 : t;
        float c[3] = {a[0] + t * ab[0], a[1] + t * ab[1], a[2] + t * ab[2]};
        float d[3] = {q[0] - c[0], q[1] - c[1], q[2] - c[2]}, dd = sy_dot3(d, d);
        if (dd < best) best = dd, memcpy(at, c, sizeof at), as = p->ss[k] + t * (p->ss[k + 1] - p->ss[k]);
    }
    /* Keep the attachment node when the nearest point would collapse onto
     * the child's first point (a child starting on the parent's axis). */
    if (best < DEDUPE_EPS * DEDUPE_EPS) return 0;
    s->attach_s = as;
    if (best < s->rad[0] * s->rad[0] && s->n_pts > 2) {
        /* The child starts on its parent's axis: that first point is the
         * attachment, and a millimetre-long first segment would only give
         * its base a random direction. */
        memmove(s->pts, s->pts + 3, 3 * (s->n_pts - 1) * sizeof(float));
        memmove(s->rad + 1, s->rad + 2, (s->n_pts - 2) * sizeof(float));
        s->n_pts--;
        return 1;
    }
    memcpy(s->pts, at, sizeof at);
    return 0;
}

/* Slack kept between a child's footprint and its parent's first or last
 * ring, in footprint half-lengths; gaps kept between siblings' footprints,
 * along the parent (in the child's radii) and around it (radians). */
#define FOOTPRINT_SLACK 1.25f
#define FOOTPRINT_GAP 0.25f
#define FOOTPRINT_GAP_AZ 0.15f
/* A child slides past a sibling by at most this many half-lengths of its
 * own footprint or of the sibling's, whichever is longer: a twig beside a
 * limb that leaves the same node must clear the limb's footprint. Bounded
 * by its own alone, the grown beech kept 12 of its 15 capped LOD0 rings
 * crossing a sibling's (seed 1; 354 of 355 junctions welded now, 340
 * before; docs/mesh.md "Stop 40"). */
#define FOOTPRINT_MAX_SLIDE 3.0f
/* A slide turns the child's first segment by less than 30 degrees. */
#define SLIDE_MIN_COS 0.866f
/* A parent with more placed children than this fits the next ones to its
 * tube alone, past no sibling. */
#define FOOTPRINT_MAX_SIBLINGS 64

/* Does a footprint at arc lengths lo..hi, azimuth az +- hw, clear every
 * sibling of stem `self` placed before it (first / next: their lists, by
 * parent)? */
static int footprint_clear(const sy_stems *st, int32_t self, const int32_t *first, const int32_t *next, float lo,
                           float hi, float az, float hw, float gap)
{
    /* A slot built against a sibling's edge may round a hair into it. */
    const float tol = 1e-5f;
    for (int32_t k = first[st->s[self].parent]; k >= 0; k = next[k]) {
        const sy_stem *o = &st->s[k];
        if (o->fp_hi + gap <= lo + tol || o->fp_lo - gap >= hi - tol) continue;
        float dz = fabsf(remainderf(o->fp_az - az, 2 * SY_PI));
        if (dz < o->fp_hw + hw + FOOTPRINT_GAP_AZ) return 0;
    }
    return 1;
}

typedef struct {
    float centre, half, az, hw; /* footprint about attachment arc length as */
    float lo, hi;               /* the arc lengths where it fits on the tube */
    float d[3];                 /* the first segment's direction from there */
} footprint;

/* The footprint of s's base ring if s left parent p at arc length as,
 * its first segment running from there to its first own point. 0 when
 * that segment has no direction; FOOTPRINT_ALONG when it runs within 25
 * degrees of the parent's axis (a continuation, carried through by
 * sy_skeleton_continuations), the footprint then drawn as if at 25 degrees;
 * else 1. */
#define FOOTPRINT_ALONG 2
static int footprint_at(const sy_stem *p, const sy_stem *s, float as, footprint *f)
{
    float c[3], T[3], N[3], B[3], R;
    sy_stem_frame_at(p, NULL, 0, as, c, T, N, &R);
    for (int k = 0; k < 3; k++) f->d[k] = s->pts[3 + k] - c[k];
    if (sy_normalize3(f->d) < DEDUPE_EPS || R <= 0) return 0;
    float ct = sy_dot3(f->d, T), st2 = 1 - ct * ct;
    int along = st2 < 0.1786f; /* sin^2 25 degrees */
    if (along) st2 = 0.1786f, ct = ct < 0 ? -sqrtf(1 - st2) : sqrtf(1 - st2);
    float sn = sqrtf(st2), r = s->rad[0];
    f->centre = R * ct / sn, f->half = FOOTPRINT_SLACK * r / sn;
    f->lo = p->ss[0] + f->half - f->centre, f->hi = p->ss[p->n_samp - 1] - f->half - f->centre;
    sy_cross3(T, N, B);
    f->az = atan2f(sy_dot3(f->d, B), sy_dot3(f->d, N)), f->hw = asinf(fminf(1.0f, r / R));
    return along ? FOOTPRINT_ALONG : 1;
}

/* Records child self's footprint f, leaving its parent at arc length as,
 * and lists it among the parent's placed children. */
static void list_footprint(sy_stems *st, int32_t self, int32_t *first, int32_t *next, int32_t *placed, float as,
                           const footprint *f)
{
    sy_stem *s = &st->s[self];
    s->fp_lo = as + f->centre - f->half, s->fp_hi = as + f->centre + f->half;
    s->fp_az = f->az, s->fp_hw = f->hw;
    next[self] = first[s->parent], first[s->parent] = self;
    placed[s->parent]++;
}

/* A junction welds only where the child's base ring lands on the parent's
 * tube, clear of its siblings' rings (tube.c). A child leaving its parent's
 * last node (a stem ending in a fork that turns back, a branchlet patch
 * docked at a twig's end) or its first ring (a twig off the node where the
 * parent leaves the grandparent) had part of its ring off the tube's end,
 * and children leaving one node side by side had rings crossing: both were
 * capped, most of the capped junctions of a `run` asset (tree1: 110 and 20
 * of 131 at LOD0). Such a child slides along its parent, as little as it
 * can, until its footprint fits on the tube and clears the siblings placed
 * before it: its axis leaves a parent of radius R, at angle th to it, R cot
 * th farther along, and the ring of radius r lands within r / sin th of
 * there (1.25 times that kept clear) and asin(r / R) of its azimuth.
 * Children within 25 degrees of the parent's axis (continuations, carried
 * through by sy_skeleton_continuations), parents too short for the
 * footprint, and
 * slides that would turn the child's first segment by more than 30 degrees
 * keep their place. Moving the start turns the first segment, which moves
 * the footprint: the fit is repeated, four rounds at most. Records the
 * footprint either way and lists the child among its parent's placed
 * children. */
static void fit_on_parent(sy_stems *st, int32_t self, int32_t *first, int32_t *next, int32_t *placed)
{
    sy_stem *s = &st->s[self];
    const sy_stem *p = &st->s[s->parent];
    footprint f0, f, fg;
    if (p->n_samp < 2 || s->n_pts < 2) return;
    int fit = footprint_at(p, s, s->attach_s, &f0);
    if (fit != 1) {
        /* A child running within 25 degrees of its parent keeps its place,
         * but the siblings placed after it must clear the long ring it lays
         * along the parent: its footprint is listed as if it left at 25
         * degrees (a bound its ring exceeds). Unlisted, the siblings beside
         * it kept their places and their rings crossed its own (a fifth of
         * the grown trees' capped LOD0 junctions). */
        if (fit == FOOTPRINT_ALONG) list_footprint(st, self, first, next, placed, s->attach_s, &f0);
        return;
    }
    fg = f0;
    float gap = FOOTPRINT_GAP * s->rad[0], as = s->attach_s, good = NAN;
    /* Past this many placed siblings a slot is rarely found and the search
     * costs their number squared (4,000 twigs off one node: minutes). */
    int crowd = placed[s->parent] > FOOTPRINT_MAX_SIBLINGS;
    /* Moving the start turns the first segment, which moves the footprint:
     * a few rounds settle it, and the last place found clear on the tube
     * (judged by its own footprint) is kept. */
    for (int round = 0; round <= 4; round++) {
        if (footprint_at(p, s, as, &f) != 1 || f.lo > f.hi) break;
        int on_tube = as >= f.lo - 0.1f * f.half && as <= f.hi + 0.1f * f.half;
        if (on_tube && (crowd || footprint_clear(st, self, first, next, as + f.centre - f.half,
                                                 as + f.centre + f.half, f.az, f.hw, gap)))
            good = as, fg = f;
        if (round == 4) break;
        /* The nearest clear place: the end-fitted one, or just before or
         * after a sibling's footprint. */
        float fitted = s->attach_s < f.lo ? f.lo : s->attach_s > f.hi ? f.hi : s->attach_s, to = fitted;
        if (!crowd &&
            !footprint_clear(st, self, first, next, to + f.centre - f.half, to + f.centre + f.half, f.az, f.hw, gap)) {
            float best = INFINITY;
            for (int32_t k = first[s->parent]; k >= 0; k = next[k]) {
                const sy_stem *o = &st->s[k];
                float cand[2] = {o->fp_lo - gap - f.centre - f.half, o->fp_hi + gap - f.centre + f.half};
                for (int e = 0; e < 2; e++) {
                    float a = cand[e], move = fabsf(a - fitted);
                    if (a < f.lo || a > f.hi || move >= best ||
                        move > FOOTPRINT_MAX_SLIDE * fmaxf(f.half, 0.5f * (o->fp_hi - o->fp_lo)) ||
                        !footprint_clear(st, self, first, next, a + f.centre - f.half, a + f.centre + f.half, f.az,
                                         f.hw, gap))
                        continue;
                    /* A place where the child would run along its parent
                     * (no footprint) or turn more than the slide allows is
                     * no place: the other side of the sibling may be. */
                    footprint fa;
                    if (footprint_at(p, s, a, &fa) != 1 || sy_dot3(fa.d, f0.d) < SLIDE_MIN_COS) continue;
                    best = move, to = a;
                }
            }
        }
        if (fabsf(to - as) <= 1e-3f * f.half) break;
        as = to;
    }
    /* Where no place was judged clear, the last one tried still welds
     * more often than not (the footprint is a bound, not the ring). */
    if (isnan(good)) {
        if (footprint_at(p, s, as, &fg) == 1) good = as;
        else good = s->attach_s, fg = f0;
    }
    if (good != s->attach_s) {
        float c[3], T[3], N[3], R, w[3];
        sy_stem_frame_at(p, NULL, 0, good, c, T, N, &R);
        for (int k = 0; k < 3; k++) w[k] = s->pts[3 + k] - c[k];
        float r = s->rad[0];
        if (sy_dot3(fg.d, f0.d) >= SLIDE_MIN_COS && sy_dot3(w, w) >= 4 * r * r) {
            memcpy(s->pts, c, sizeof c);
            s->attach_s = good;
        } else {
            good = s->attach_s, fg = f0;
        }
    }
    list_footprint(st, self, first, next, placed, good, &fg);
}

/* A child of a lean parent (a traced twig off a traced twig) starts no
 * thicker than CHILD_BASE_SHARE of its parent's radius where it leaves it.
 * Both are often at the reconstruction's floor, and a base ring as wide as
 * the parent laid across a whole face of its four-sided tube, where no strip
 * welds it without a fold (a grown tree's child is never thicker than its
 * parent there, stages/grow). 0.6 of the radius fits within the face
 * (half-width 0.71 R): the welded LOD0 junctions of the nine real scans went
 * from 96.5 % to 97.6 % (docs/mesh.md, "Stop 39"). Only the attachment
 * point's radius changes: the tube widens back to the child's own over its
 * first segment. Other parents keep their children's radii: the bundled
 * palms' and airborne trees' sails rose by 7-21 % with the rule on them. */
#define CHILD_BASE_SHARE 0.6f

static void narrow_base(const sy_stem *p, sy_stem *s)
{
    float c[3], T[3], N[3], R;
    sy_stem_frame_at(p, NULL, 0, s->attach_s, c, T, N, &R);
    if (R > 0 && s->rad[0] > CHILD_BASE_SHARE * R) s->rad[0] = CHILD_BASE_SHARE * R;
}

/* A child whose first point lies within the start its parent lost inside
 * the grandparent (trim_junction; a twig off the first centimetres of a twig
 * that leaves the trunk with it) has no parent surface to leave there: its
 * tube started at the parent's first ring, half a metre along on a twig
 * leaving the trunk at a glancing angle, and ran back across to its own path
 * (a 0.6 m chord on the aspen). It leaves the grandparent instead, from
 * where the parent does, straight towards its second point: that first
 * point sits on the parent's buried axis, and a tube through it would share
 * the parent's base (kept when it is the child's only point after the
 * attachment). Returns whether that first point was dropped. */
static int reattach_buried(sy_stems *st, sy_stem *s)
{
    int moved = 0;
    while (s->parent >= 0 && s->n_pts >= 2) {
        const sy_stem *p = &st->s[s->parent];
        if (!p->junction || p->parent < 0) break;
        const float *q = s->pts + 3;
        float d0[3] = {q[0] - s->pts[0], q[1] - s->pts[1], q[2] - s->pts[2]};
        if (s->attach_s + sqrtf(sy_dot3(d0, d0)) >= p->ss[0]) break;
        if (!s->reattached) s->reattached = 1, s->tree_parent = s->parent, s->tree_attach_s = s->attach_s;
        memcpy(s->pts, p->pts, 3 * sizeof(float));
        s->parent = p->parent;
        s->attach_s = p->attach_s;
        moved = 1;
    }
    if (!moved || s->n_pts <= 2) return 0;
    memmove(s->pts + 3, s->pts + 6, 3 * (s->n_pts - 2) * sizeof(float));
    memmove(s->rad + 1, s->rad + 2, (s->n_pts - 2) * sizeof(float));
    s->n_pts--;
    return 1;
}

/* Seam placement: u = 0 faces down on branches (under the branch) and away
 * from a glTF viewer's default camera on a vertical trunk. */
static void initial_normal(const sy_stem *s, float r0[3])
{
    const float *t0 = s->st;
    /* x_axis lives as long as ref: a compound literal in the if's body
     * would end with that body (C11 6.8.4), and ref would dangle. */
    float down[3] = {0, 0, -1}, back[3] = {0, 1, 0}, x_axis[3] = {1, 0, 0};
    const float *ref = (s->parent >= 0 && fabsf(sy_dot3(t0, down)) < 0.95f) ? down : back;
    if (fabsf(sy_dot3(t0, ref)) > 0.95f) ref = fabsf(t0[0]) < 0.9f ? x_axis : back;
    float d = sy_dot3(ref, t0);
    for (int k = 0; k < 3; k++) r0[k] = ref[k] - d * t0[k];
    sy_normalize3(r0);
}

/* ---- frame queries ---- */

void sy_stem_frame_at(const sy_stem *s, const int32_t *idx, size_t n_idx, float q, float c[3], float T[3],
                      float N[3], float *R)
{
    if (!idx) n_idx = s->n_samp;
#define IDX(k) (idx ? (size_t)idx[k] : (size_t)(k))
    size_t lo = 0, hi = n_idx - 1;
    float f = 0;
    if (n_idx == 1 || q <= s->ss[IDX(0)]) {
        hi = lo;
    } else if (q >= s->ss[IDX(n_idx - 1)]) {
        lo = hi;
    } else {
        while (hi - lo > 1) {
            size_t mid = (lo + hi) / 2;
            if (s->ss[IDX(mid)] <= q) lo = mid;
            else hi = mid;
        }
        float a = s->ss[IDX(lo)], b = s->ss[IDX(hi)];
        f = b > a ? (q - a) / (b - a) : 0;
    }
    size_t a = IDX(lo), b = IDX(hi);
#undef IDX
    for (int k = 0; k < 3; k++) {
        c[k] = s->sp[3 * a + k] + f * (s->sp[3 * b + k] - s->sp[3 * a + k]);
        T[k] = s->st[3 * a + k] + f * (s->st[3 * b + k] - s->st[3 * a + k]);
        N[k] = s->sn[3 * a + k] + f * (s->sn[3 * b + k] - s->sn[3 * a + k]);
    }
    if (sy_normalize3(T) < 1e-6f) memcpy(T, s->st + 3 * a, 3 * sizeof(float));
    float d = sy_dot3(N, T);
    for (int k = 0; k < 3; k++) N[k] -= d * T[k];
    if (sy_normalize3(N) < 1e-6f) memcpy(N, s->sn + 3 * a, 3 * sizeof(float));
    *R = s->sr[a] + f * (s->sr[b] - s->sr[a]);
}

float sy_stem_closest_on_axis(const sy_stem *s, const int32_t *idx, size_t n_idx, const float x[3], float s_hint,
                              int iters, float c[3], float T[3], float N[3], float *R)
{
    float q = s_hint;
    for (int it = 0; it < iters; it++) {
        sy_stem_frame_at(s, idx, n_idx, q, c, T, N, R);
        float w[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]}, dq = sy_dot3(w, T);
        q += dq;
        if (fabsf(dq) < 1e-6f) break;
    }
    sy_stem_frame_at(s, idx, n_idx, q, c, T, N, R);
    return q;
}

/* Where the ray from w (relative to a point on the axis) along d leaves the
 * infinite cylinder of radius R around unit axis a; 0 when it misses. */
static int cylinder_exit(const float w[3], const float d[3], const float a[3], float R, float *lam)
{
    float wa = sy_dot3(w, a), da = sy_dot3(d, a), wp[3], dp[3];
    for (int k = 0; k < 3; k++) {
        wp[k] = w[k] - wa * a[k];
        dp[k] = d[k] - da * a[k];
    }
    float A = sy_dot3(dp, dp), B = sy_dot3(wp, dp), C = sy_dot3(wp, wp) - R * R;
    if (A < 1e-8f) return 0;
    float disc = B * B - A * C;
    if (disc < 0) return 0;
    *lam = (-B + sqrtf(disc)) / A;
    return 1;
}

/* Whether child s's ring j lies wholly outside parent p's tube: its centre
 * is at least the two radii from the parent's axis at the axis point
 * nearest it (found from arc length *q, which is left there for the next
 * ring), the parent's radius grown by its lobes' depth on a lobed trunk. */
static int ring_clears(const sy_stem *p, const sy_stem *s, size_t j, float *q)
{
    const float *x = s->sp + 3 * j;
    float c[3], T[3], N[3], R;
    *q = sy_stem_closest_on_axis(p, NULL, 0, x, *q, 4, c, T, N, &R);
    float w[3] = {x[0] - c[0], x[1] - c[1], x[2] - c[2]}, along = sy_dot3(w, T), d2 = sy_dot3(w, w) - along * along;
    float need = R * (1 + (p->lobes > 0 ? p->lobe_depth : 0)) + s->sr[j];
    return d2 >= need * need;
}

/* Starts a child's tube where its axis leaves the parent's cylinder and drops
 * the rings its projected base ring would pass (those lie inside the parent),
 * but none past the first ring that already stands clear of the parent's
 * tube, once past the base ring's push: the base ring of a child that turns
 * along its parent runs nearly parallel to the parent's axis, and its exit
 * from the infinite cylinder came metres on (AdTree's tree7: a 0.48 m twig
 * cut to one straight segment, its own three twigs then crowded into its
 * one quad row and capped, not welded). A child whose tip stays inside the
 * parent is buried and draws nothing. */
static void trim_junction(sy_stems *st, sy_stem *s)
{
    const sy_stem *p = &st->s[s->parent];
    float c[3], a[3], pn[3], R;
    sy_stem_frame_at(p, NULL, 0, s->attach_s, c, a, pn, &R);
    float w[3] = {s->sp[0] - c[0], s->sp[1] - c[1], s->sp[2] - c[2]}, lam;
    if (!cylinder_exit(w, s->st, a, R, &lam) || lam > 0.5f * s->length) return; /* runs along the parent */
    float s0 = lam > 0 ? lam : 0;
    float c0[3], t0[3], n0[3], r0, b0[3];
    sy_stem_frame_at(s, NULL, 0, s0, c0, t0, n0, &r0);
    sy_cross3(t0, n0, b0);
    float adv = 0;
    for (int j = 0; j < 32; j++) {
        float th = 2 * SY_PI * (float)j / 32, q[3];
        for (int k = 0; k < 3; k++) q[k] = c0[k] + r0 * (cosf(th) * n0[k] + sinf(th) * b0[k]) - c[k];
        if (cylinder_exit(q, t0, a, R, &lam) && lam > adv) adv = lam;
    }
    float cut = s0 + 1.15f * adv + 1e-4f, q = s->attach_s;
    /* Never a ring the base ring's vertices may be pushed past (tube.c
     * pushes them along the child's tangent by up to 2 (r + R)): the
     * first row would fold back. */
    float floor_cut = fminf(cut, s0 + 2 * (s->r_base + p->r_base) + 1e-4f);
    for (size_t j = 1; j < s->n_samp && s->ss[j] <= cut; j++)
        if (s->ss[j] > floor_cut && ring_clears(p, s, j, &q)) {
            cut = fmaxf(s->ss[j] - 1e-4f, floor_cut);
            break;
        }
    /* Buried: the tip centre is inside the parent's cylinder. */
    const float *tip = s->sp + 3 * (s->n_samp - 1);
    float wt[3] = {tip[0] - c[0], tip[1] - c[1], tip[2] - c[2]}, ta = sy_dot3(wt, a);
    for (int k = 0; k < 3; k++) wt[k] -= ta * a[k];
    if (sy_dot3(wt, wt) < R * R || s->ss[s->n_samp - 1] <= s0 + 1e-4f) {
        s->has_geometry = 0;
        return;
    }
    /* Interpolated values for ring 0 before the arrays are compacted. */
    size_t lo = 0;
    while (lo + 2 < s->n_samp && s->ss[lo + 1] <= s0) lo++;
    float f = s->ss[lo + 1] > s->ss[lo] ? (s0 - s->ss[lo]) / (s->ss[lo + 1] - s->ss[lo]) : 0;
    float dr0 = s->sdr[lo] + f * (s->sdr[lo + 1] - s->sdr[lo]);
    size_t out = 1;
    for (size_t j = 1; j < s->n_samp; j++) {
        if (s->ss[j] <= cut && j + 1 < s->n_samp) continue;
        memmove(s->sp + 3 * out, s->sp + 3 * j, 3 * sizeof(float));
        memmove(s->st + 3 * out, s->st + 3 * j, 3 * sizeof(float));
        memmove(s->sn + 3 * out, s->sn + 3 * j, 3 * sizeof(float));
        s->sr[out] = s->sr[j];
        s->ss[out] = s->ss[j];
        s->sdr[out] = s->sdr[j];
        out++;
    }
    memcpy(s->sp, c0, sizeof c0);
    memcpy(s->st, t0, sizeof t0);
    memcpy(s->sn, n0, sizeof n0);
    s->sr[0] = r0;
    s->ss[0] = s0;
    s->sdr[0] = dr0;
    s->n_samp = out;
    s->junction = 1;
}

sy_code sy_stems_build(const sy_skeleton *sk, const sy_mesh_options *opt, sy_stems *st, sy_error *err)
{
    memset(st, 0, sizeof *st);
    st->root = -1;
    sy_code rc = build_chains(sk, st, err);
    if (rc == SY_OK) rc = order_by_depth(sk, st, err);
    if (rc != SY_OK) {
        sy_stems_free(st);
        return rc;
    }
    float zmin = INFINITY, zmax = -INFINITY;
    for (size_t i = 0; i < sk->n; i++) {
        zmin = fminf(zmin, sk->pos[3 * i + 2]);
        zmax = fmaxf(zmax, sk->pos[3 * i + 2]);
    }
    st->height = zmax - zmin;
    st->trunk_radius = sk->radius[st->s[st->root].nodes[0]];
    st->ground = sk->pos[3 * st->s[st->root].nodes[0] + 2];
    /* Each stem's children placed so far (fit_on_parent). */
    int32_t *first_child = malloc(3 * (st->n ? st->n : 1) * sizeof *first_child), *next_sib = first_child + st->n;
    int32_t *placed = next_sib + st->n;
    if (!first_child) {
        sy_stems_free(st);
        return sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
    }
    for (size_t i = 0; i < st->n; i++) first_child[i] = -1, placed[i] = 0;
    /* The thickest child leaving each stem's last node (tip_stretch). */
    float *tip_child = calloc(st->n ? st->n : 1, sizeof *tip_child);
    if (!tip_child) {
        free(first_child);
        sy_stems_free(st);
        return sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
    }
    for (size_t k = 0; k < st->n; k++) {
        const sy_stem *c = &st->s[k];
        if (c->parent < 0) continue;
        const sy_stem *p = &st->s[c->parent];
        if (p->n_nodes && c->attach_node == p->nodes[p->n_nodes - 1])
            tip_child[c->parent] = fmaxf(tip_child[c->parent], sk->radius[c->nodes[0]]);
    }
    for (size_t o = 0; o < st->n; o++) {
        sy_stem *s = &st->s[st->by_depth[o]];
        int32_t *node_pt = malloc(s->n_nodes * sizeof *node_pt);
        if (!node_pt || !build_polyline(sk, s, node_pt, opt->min_radius)) {
            free(node_pt), free(first_child), free(tip_child);
            sy_stems_free(st);
            return sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
        }
        float tip_dir[3], tip_ext = 0;
        int stretch = tip_stretch(s, tip_child[st->by_depth[o]], tip_dir, &tip_ext);
        s->r_base = s->rad[0];
        s->r_tip = s->rad[s->n_pts - 1];
        s->lean = s->parent < 0 || !(s->r_base < opt->lean_radius) ? 0 : s->r_base < 0.5f * opt->lean_radius ? 2 : 1;
        if (s->parent >= 0) {
            s->attach_s = st->node_s[s->attach_node];
            if (reattach_buried(st, s))
                for (size_t i = 0; i < s->n_nodes; i++) node_pt[i] = node_pt[i] > 0 ? node_pt[i] - 1 : 0;
        }
        /* (Only when the first node is a point of its own: a child whose first
         * node sits on the attachment node starts exactly there.) */
        if (s->parent >= 0 && st->s[s->parent].has_geometry && s->n_pts >= 2 && node_pt[0] == 1 &&
            attach_on_parent(&st->s[s->parent], s))
            for (size_t i = 0; i < s->n_nodes; i++) node_pt[i] = node_pt[i] > 0 ? node_pt[i] - 1 : 0;
        if (s->parent >= 0 && st->s[s->parent].has_geometry)
            fit_on_parent(st, st->by_depth[o], first_child, next_sib, placed);
        if (s->parent >= 0 && st->s[s->parent].has_geometry && sy_stem_lean(&st->s[s->parent]) && s->n_pts >= 2) narrow_base(&st->s[s->parent], s);
        if (stretch && s->n_pts >= 2) extend_tip(s, tip_dir, tip_ext);
        if (s->n_pts >= 2) {
            if (!sample_curve(s, opt, st->ground)) {
                free(node_pt), free(first_child), free(tip_child);
                sy_stems_free(st);
                return sy_fail(err, SY_EINTERNAL, "mesh: out of memory");
            }
            s->has_geometry = 1;
        } else {
            s->length = 0;
        }
        for (size_t i = 0; i < s->n_nodes; i++)
            st->node_s[s->nodes[i]] = s->has_geometry ? s->pt_s[node_pt[i]] : 0;
        free(node_pt);
        if (!s->has_geometry) continue;
        float r0[3];
        initial_normal(s, r0);
        sy_rmf(s->n_samp, s->sp, s->st, r0, s->sn);
        int radial = (int)lroundf((float)opt->radial_segments * sqrtf(s->r_base / st->trunk_radius));
        s->radial = radial < 3 ? 3 : radial > opt->radial_segments ? opt->radial_segments : radial;
        if (s->radial < 3) s->radial = 3;
        if (sk->lobes > 0 && sk->order[s->nodes[0]] == 0) {
            s->lobes = sk->lobes;
            s->lobe_depth = sk->lobe_depth;
            /* Four ring vertices per lobe draw the ripple; fewer alias it. */
            int want = 4 * s->lobes > LOBED_MAX_RADIAL ? LOBED_MAX_RADIAL : 4 * s->lobes;
            if (s->radial < want) s->radial = want;
        }
        if (s->parent >= 0 && st->s[s->parent].has_geometry) trim_junction(st, s);
    }
    free(first_child), free(tip_child);
    return SY_OK;
}
