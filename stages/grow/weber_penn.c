/* Weber & Penn (1995) tree generation, following the GPU-trees thesis digest
 * (docs/species.md says where we depart from it). Each stem is a polyline
 * of CurveRes straight segments whose frames turn by Curve/CurveBack/CurveV
 * at the joints; split clones continue the remaining segments as stems of
 * their own; children and leaves are spread along every stem piece. */
#include "grow.h"
#include "stages/core/rng.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define PI_F 3.14159265358979f
#define DEG (PI_F / 180.0f)
#define MIN_RADIUS 1e-4f  /* skeleton radii must stay positive at stem tips */
#define MIN_LENGTH 1e-3f  /* shorter stems are not grown */
#define MAX_NODES 2000000 /* a runaway parameter file fails instead of eating memory */
#define MAX_LEAVES 2000000
#define MAX_SEGS 64
#define MAX_PIECE_NODES (MAX_SEGS + 8) /* segment ends plus flare nodes */
#define MAX_CLONES 17                  /* BaseSplits <= 16, SegSplits <= 5 */

/* ---------------------------------------------------------------- shapes */

float sy_shape_ratio(const sy_species_params *sp, int shape, float ratio)
{
    float r = ratio < 0 ? 0 : ratio > 1 ? 1 : ratio;
    switch (shape) {
    case 0: return 0.2f + 0.8f * r;
    case 1: return 0.2f + 0.8f * sinf(PI_F * r);
    case 2: return 0.2f + 0.8f * sinf(0.5f * PI_F * r);
    case 3: return 1.0f;
    case 4: return 0.5f + 0.5f * r;
    case 5: return r <= 0.7f ? r / 0.7f : (1.0f - r) / 0.3f;
    case 6: return 1.0f - 0.8f * r;
    case 7: return r <= 0.7f ? 0.5f + 0.5f * r / 0.7f : 0.5f + 0.5f * (1.0f - r) / 0.3f;
    case 8: {
        /* The pruning envelope: rises to 1 at 1 - PruneWidthPeak, then falls
         * to 0 at the crown base; the divisors keep it continuous. */
        float peak = sp ? sp->prune_width_peak : 0.5f;
        float lo = sp ? sp->prune_power_low : 0.5f, hi = sp ? sp->prune_power_high : 0.5f;
        if (r < 1.0f - peak) return powf(r / (1.0f - peak), hi);
        if (peak <= 0) return 0.0f;
        return powf((1.0f - r) / peak, lo);
    }
    default: return 1.0f;
    }
}

float sy_stem_radius_z(float z, float taper, float radius, float length)
{
    float unit_taper = taper < 1 ? taper : taper < 2 ? 2 - taper : 0;
    float taper_z = radius * (1 - unit_taper * z);
    if (taper < 1) return taper_z;
    if (taper > 3 || taper_z <= 0) return 0;
    float z2 = (1 - z) * length; /* metres from the tip */
    float depth = (taper < 2 || z2 < taper_z) ? 1 : taper - 2;
    float z3 = taper < 2 ? z2 : fabsf(z2 - 2 * taper_z * floorf(z2 / (2 * taper_z) + 0.5f));
    if (taper < 2 && z3 > taper_z) return taper_z;
    float arg = taper_z * taper_z - (z3 - taper_z) * (z3 - taper_z);
    return (1 - depth) * taper_z + depth * sqrtf(arg > 0 ? arg : 0);
}

float sy_flare_z(float z, float flare)
{
    float y = 1 - 8 * z;
    if (y < 0) y = 0;
    return flare * (powf(100.0f, y) - 1) / 100.0f + 1;
}

/* ------------------------------------------------------------------ RNG */

typedef struct {
    uint64_t s;
} rng;

static uint64_t rng_next(rng *r) { return sy_splitmix64(&r->s); }

static float rng_unit(rng *r) { return (float)(rng_next(r) >> 40) * (1.0f / 16777216.0f); }

/* Uniform in [-v, v]: Weber-Penn's "X ± XV". */
static float vary(rng *r, float v) { return (2 * rng_unit(r) - 1) * fabsf(v); }

/* --------------------------------------------------------- 3x3 frames */

/* Column-major: x = m[0..2], y = m[3..5], z = m[6..8]; z is the stem heading. */
typedef struct {
    float m[9];
} frame;

static frame mul(const frame *a, const frame *b)
{
    frame c;
    for (int col = 0; col < 3; col++)
        for (int row = 0; row < 3; row++)
            c.m[3 * col + row] = a->m[row] * b->m[3 * col] + a->m[3 + row] * b->m[3 * col + 1] +
                                 a->m[6 + row] * b->m[3 * col + 2];
    return c;
}

static frame rot_x(float a)
{
    float c = cosf(a), s = sinf(a);
    frame f = {{1, 0, 0, 0, c, s, 0, -s, c}};
    return f;
}

static frame rot_z(float a)
{
    float c = cosf(a), s = sinf(a);
    frame f = {{c, s, 0, -s, c, 0, 0, 0, 1}};
    return f;
}

/* Rotation by angle a about the unit axis u (Rodrigues). */
static frame rot_axis(const float u[3], float a)
{
    float c = cosf(a), s = sinf(a), t = 1 - c;
    frame f = {{t * u[0] * u[0] + c, t * u[0] * u[1] + s * u[2], t * u[0] * u[2] - s * u[1],
                t * u[0] * u[1] - s * u[2], t * u[1] * u[1] + c, t * u[1] * u[2] + s * u[0],
                t * u[0] * u[2] + s * u[1], t * u[1] * u[2] - s * u[0], t * u[2] * u[2] + c}};
    return f;
}

/* Child or split frame: turn about the parent axis by az, tilt by down. */
static frame turn(const frame *f, float az, float down)
{
    frame a = rot_z(az), b = rot_x(down);
    frame t = mul(&a, &b);
    return mul(f, &t);
}

/* Rotates heading f.z toward +Z (angle > 0) or -Z (< 0), never past it. */
static void attract(frame *f, float strength)
{
    const float *h = f->m + 6;
    float decl = acosf(h[2] > 1 ? 1 : h[2] < -1 ? -1 : h[2]);
    float axis[3] = {h[1], -h[0], 0}; /* h x Z */
    float len = sqrtf(axis[0] * axis[0] + axis[1] * axis[1]);
    if (len < 1e-6f) return;
    axis[0] /= len;
    axis[1] /= len;
    float a = strength * decl;
    if (a > decl) a = decl;
    if (a < -(PI_F - decl)) a = -(PI_F - decl);
    frame r = rot_axis(axis, a);
    *f = mul(&r, f);
}

/* ------------------------------------------------------------- grower */

typedef struct {
    const sy_species_params *sp;
    rng r;
    sy_skeleton *sk;
    sy_leaves *lv;
    int32_t next_branch;
    float split_error[SY_WP_LEVELS];
    float scale_tree, length_base;
    sy_error *err;
} grower;

/* What a stem knows about itself and its place on the parent. */
typedef struct {
    int level;
    float length, radius;   /* stem length, base radius */
    float offset;           /* metres from the parent's base to the attachment */
    float parent_length;
    float parent_base;      /* bare length on the parent (BaseSize on the trunk) */
    float length_max;       /* the drawn nLength ± nLengthV */
} stem;

typedef struct {
    int point; /* split at this point (start of segment `point`) */
    int n;     /* clones */
    frame f[MAX_CLONES];
} split_event;

/* One traced piece of a stem: segments k0..res-1 and the splits on them. */
typedef struct {
    int k0, res;
    float seg_len;
    float pos[3 * (MAX_SEGS + 1)]; /* indexed by point 0..res; valid from k0 */
    frame seg[MAX_SEGS];
    int n_events;
    split_event events[MAX_SEGS];
    /* emitted nodes in order along the piece */
    int n_nodes;
    int32_t node[MAX_PIECE_NODES];
    float node_off[MAX_PIECE_NODES];
    int32_t point_node[MAX_SEGS + 1]; /* node emitted at each segment end */
} piece;

static const sy_wp_level *lvl(const grower *g, int level)
{
    return &g->sp->level[level < SY_WP_LEVELS ? level : SY_WP_LEVELS - 1];
}

/* Bend at joint j (between segments j-1 and j) of a stem with res segments. */
static void bend_joint(grower *g, const stem *st, int j, frame *f)
{
    const sy_wp_level *L = lvl(g, st->level);
    int joints = L->curve_res - 1;
    float a;
    if (L->curve_back == 0) {
        a = L->curve / (float)joints;
    } else {
        int first = joints / 2 > 0 ? joints / 2 : 1;
        int second = joints - first > 0 ? joints - first : 1;
        a = j <= first ? L->curve / (float)first : L->curve_back / (float)second;
    }
    if (L->curve_v >= 0) {
        a += vary(&g->r, L->curve_v / (float)L->curve_res);
    } else {
        /* Negative CurveV: the bend plane turns once around the stem: a helix. */
        frame t = rot_z(2 * PI_F / (float)joints);
        *f = mul(f, &t);
        a += -L->curve_v / (float)L->curve_res;
    }
    frame b = rot_x(a * DEG);
    *f = mul(f, &b);
    if (st->level >= 2 && g->sp->attraction_up != 0) attract(f, g->sp->attraction_up / (float)L->curve_res);
}

/* Clone count at point j with Weber-Penn's per-level error diffusion. */
static int split_count(grower *g, const stem *st, int j)
{
    const sy_wp_level *L = lvl(g, st->level);
    if (st->level == 0 && j == 1 && g->sp->level[0].base_splits > 0)
        return (int)floorf(g->sp->level[0].base_splits + 0.5f);
    if (L->seg_splits <= 0) return 0;
    float want = L->seg_splits + g->split_error[st->level];
    int n = (int)floorf(want + 0.5f);
    if (n < 0) n = 0;
    if (n > MAX_CLONES - 1) n = MAX_CLONES - 1;
    g->split_error[st->level] -= (float)n - L->seg_splits;
    return n;
}

/* Splits the heading at a joint into n+1 stems spread evenly around it; the
 * first replaces the piece's own frame, the others become clones. */
static void split_frames(grower *g, const stem *st, const frame *heading, int n, frame *own, split_event *ev)
{
    const sy_wp_level *L = lvl(g, st->level);
    const frame base = *heading; /* own may alias heading */
    const frame *f = &base;
    float phase = 2 * PI_F * rng_unit(&g->r);
    for (int i = 0; i <= n; i++) {
        float angle = (L->split_angle + vary(&g->r, L->split_angle_v)) * DEG;
        if (angle < 0) angle = 0;
        float az = phase + 2 * PI_F * (float)i / (float)(n + 1);
        frame t = turn(f, az, angle);
        frame back = rot_z(-az); /* keep the curvature plane where it was */
        t = mul(&t, &back);
        if (i == 0)
            *own = t;
        else
            ev->f[i - 1] = t;
    }
    ev->n = n;
}

/* Traces segments k0..res-1 from p0 with frame f0, recording splits. */
static void trace(grower *g, const stem *st, int k0, const float p0[3], const frame *f0, piece *pc)
{
    const sy_wp_level *L = lvl(g, st->level);
    pc->k0 = k0;
    pc->res = L->curve_res;
    pc->seg_len = st->length / (float)pc->res;
    pc->n_events = 0;
    memcpy(pc->pos + 3 * k0, p0, 3 * sizeof(float));
    frame f = *f0;
    for (int j = k0; j < pc->res; j++) {
        if (j > k0) { /* a clone's first frame already holds its joint's bend */
            bend_joint(g, st, j, &f);
            int n = split_count(g, st, j);
            if (n > 0) {
                split_event *ev = &pc->events[pc->n_events++];
                ev->point = j;
                split_frames(g, st, &f, n, &f, ev);
            }
        }
        pc->seg[j] = f;
        for (int k = 0; k < 3; k++) pc->pos[3 * (j + 1) + k] = pc->pos[3 * j + k] + f.m[6 + k] * pc->seg_len;
    }
}

/* Weber-Penn's pruning envelope test for a point (tree base at the origin). */
static int inside_envelope(const grower *g, const float p[3])
{
    const sy_species_params *sp = g->sp;
    float r = sqrtf(p[0] * p[0] + p[1] * p[1]);
    float ratio = (g->scale_tree - p[2]) / (g->scale_tree * (1 - sp->base_size));
    if (ratio < 0 || ratio > 1) return 0;
    return r / g->scale_tree < sp->prune_width * sy_shape_ratio(sp, 8, ratio);
}

static int piece_inside(const grower *g, const piece *pc)
{
    for (int j = pc->k0 + 1; j <= pc->res; j++)
        if (!inside_envelope(g, pc->pos + 3 * j)) return 0;
    return 1;
}

/* Shortens a stem until it fits the envelope, then blends by PruneRatio;
 * the random draws replay identically for every trial length. */
static void prune(grower *g, stem *st, const float p0[3], const frame *f0, piece *pc)
{
    rng saved = g->r;
    float saved_err[SY_WP_LEVELS];
    memcpy(saved_err, g->split_error, sizeof saved_err);
    float full = st->length;
    for (int tries = 0; tries < 40; tries++) {
        g->r = saved;
        memcpy(g->split_error, saved_err, sizeof saved_err);
        trace(g, st, 0, p0, f0, pc);
        if (piece_inside(g, pc)) break;
        st->length *= 0.9f;
    }
    st->length = full * (1 - g->sp->prune_ratio) + st->length * g->sp->prune_ratio;
    g->r = saved;
    memcpy(g->split_error, saved_err, sizeof saved_err);
}

static float node_radius(const grower *g, const stem *st, float offset)
{
    float z = st->length > 0 ? offset / st->length : 0;
    if (z > 1) z = 1;
    float r = sy_stem_radius_z(z, lvl(g, st->level)->taper, st->radius, st->length);
    if (st->level == 0) r *= sy_flare_z(z, g->sp->flare);
    return r > MIN_RADIUS ? r : MIN_RADIUS;
}

static sy_code add_node(grower *g, piece *pc, const stem *st, const float p[3], float off, int32_t parent,
                        int32_t branch)
{
    if (g->sk->n >= MAX_NODES)
        return sy_fail(g->err, SY_EINPUT, "species %s: tree exceeds %d nodes; lower Branches or Levels",
                       g->sp->name ? g->sp->name : "?", MAX_NODES);
    int32_t id = sy_skeleton_add(g->sk, p, node_radius(g, st, off), parent, st->level, branch, g->err);
    if (id < 0) return SY_EINTERNAL;
    pc->node[pc->n_nodes] = id;
    pc->node_off[pc->n_nodes++] = off;
    return SY_OK;
}

/* Emits the traced piece as nodes; the first is at p0, its parent `parent`. */
static sy_code emit(grower *g, piece *pc, const stem *st, int32_t parent)
{
    int32_t branch = g->next_branch++;
    pc->n_nodes = 0;
    sy_code rc = add_node(g, pc, st, pc->pos + 3 * pc->k0, (float)pc->k0 * pc->seg_len, parent, branch);
    pc->point_node[pc->k0] = pc->node[0];
    for (int j = pc->k0; j < pc->res && rc == SY_OK; j++) {
        /* The flare only lives in the lowest eighth of the trunk: sample it. */
        if (st->level == 0 && j == 0 && g->sp->flare > 0) {
            static const float flare_z[] = {1.0f / 32, 1.0f / 16, 1.0f / 8};
            for (int k = 0; k < 3 && rc == SY_OK; k++) {
                float off = flare_z[k] * st->length;
                if (off >= pc->seg_len * 0.999f) break;
                float p[3];
                for (int c = 0; c < 3; c++) p[c] = pc->pos[c] + pc->seg[0].m[6 + c] * off;
                rc = add_node(g, pc, st, p, off, pc->node[pc->n_nodes - 1], branch);
            }
        }
        if (rc == SY_OK)
            rc = add_node(g, pc, st, pc->pos + 3 * (j + 1), (float)(j + 1) * pc->seg_len, pc->node[pc->n_nodes - 1],
                          branch);
        if (rc == SY_OK) pc->point_node[j + 1] = pc->node[pc->n_nodes - 1];
    }
    return rc;
}

/* Where offset `off` lies on the piece: position, segment frame, nearest node
 * and the smaller radius of the two bracketing nodes. */
static void locate(const grower *g, const piece *pc, float off, float p[3], frame *f, int32_t *nearest,
                   float *r_min)
{
    int a = 0;
    while (a + 2 < pc->n_nodes && pc->node_off[a + 1] <= off) a++;
    int b = a + 1 < pc->n_nodes ? a + 1 : a;
    float span = pc->node_off[b] - pc->node_off[a];
    float t = span > 0 ? (off - pc->node_off[a]) / span : 0;
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    const float *pa = g->sk->pos + 3 * pc->node[a], *pb = g->sk->pos + 3 * pc->node[b];
    for (int c = 0; c < 3; c++) p[c] = pa[c] + t * (pb[c] - pa[c]);
    int s = (int)(off / pc->seg_len);
    if (s >= pc->res) s = pc->res - 1;
    if (s < pc->k0) s = pc->k0;
    *f = pc->seg[s];
    *nearest = t < 0.5f ? pc->node[a] : pc->node[b];
    float ra = g->sk->radius[pc->node[a]], rb = g->sk->radius[pc->node[b]];
    *r_min = ra < rb ? ra : rb;
}

/* Azimuth of the next child or leaf around its parent (Weber-Penn nRotate). */
static float next_azimuth(grower *g, const sy_wp_level *L, float *state, int *side)
{
    if (L->rotate >= 0) {
        *state += L->rotate + vary(&g->r, L->rotate_v);
        return *state * DEG;
    }
    /* Negative: children alternate to either side, two rows. */
    *side = -*side;
    return (float)*side * (180.0f + L->rotate + vary(&g->r, L->rotate_v)) * DEG + *state * DEG;
}

static float down_angle(grower *g, const sy_wp_level *L, const stem *parent, float off)
{
    if (L->down_angle_v >= 0) return (L->down_angle + vary(&g->r, L->down_angle_v)) * DEG;
    /* Negative V: a gradient from the parent's base to its tip. */
    float span = parent->length - parent->parent_base;
    float ratio = span > 0 ? (parent->length - off) / span : 0;
    float d = L->down_angle + L->down_angle_v * (1 - 2 * sy_shape_ratio(g->sp, 0, ratio));
    return d * DEG;
}

/* Children of stem st (a level-(n+1) count as a float, before rounding). */
static float child_count(const grower *g, const stem *st)
{
    const sy_wp_level *L = lvl(g, st->level + 1);
    if (st->level == 0) return L->branches;
    if (st->level == 1)
        return L->branches * (0.2f + 0.8f * (st->length / st->parent_length) / st->length_max);
    return L->branches * (1.0f - 0.5f * st->offset / st->parent_length);
}

static sy_code grow_stem(grower *g, stem *st, const float p0[3], const frame *f0, int32_t parent);

static sy_code grow_children(grower *g, const stem *st, const piece *pc, float count)
{
    float lo = st->level == 0 ? g->length_base : 0;
    float start = (float)pc->k0 * pc->seg_len;
    if (start < lo) start = lo;
    float span = st->length - lo;
    if (span <= 0 || start >= st->length) return SY_OK;
    int n = (int)floorf(count * (st->length - start) / span + 0.5f);
    const sy_wp_level *C = lvl(g, st->level + 1);
    float az = 360.0f * rng_unit(&g->r);
    int side = 1;
    for (int i = 0; i < n; i++) {
        float off = start + (st->length - start) * ((float)i + 0.5f) / (float)n;
        float p[3], r_min;
        frame f;
        int32_t near;
        locate(g, pc, off, p, &f, &near, &r_min);
        stem ch = {.level = st->level + 1, .offset = off, .parent_length = st->length, .parent_base = lo};
        ch.length_max = C->length + vary(&g->r, C->length_v);
        if (st->level == 0)
            ch.length = st->length * ch.length_max *
                        sy_shape_ratio(g->sp, g->sp->shape, (st->length - off) / (st->length - g->length_base));
        else
            ch.length = ch.length_max * (st->length - 0.6f * off);
        float azimuth = next_azimuth(g, C, &az, &side);
        float down = down_angle(g, C, st, off);
        if (ch.length < MIN_LENGTH) continue;
        ch.radius = st->radius * powf(ch.length / st->length, g->sp->ratio_power);
        if (ch.radius > r_min) ch.radius = r_min; /* never thicker than the parent there */
        frame cf = turn(&f, azimuth, down);
        sy_code rc = grow_stem(g, &ch, p, &cf, near);
        if (rc) return rc;
    }
    return SY_OK;
}

/* Quaternion (x, y, z, w) of the rotation whose columns are x, y, z. */
static void quat_from_axes(const float x[3], const float y[3], const float z[3], float q[4])
{
    float tr = x[0] + y[1] + z[2];
    if (tr > 0) {
        float s = sqrtf(tr + 1) * 2;
        q[3] = 0.25f * s;
        q[0] = (y[2] - z[1]) / s;
        q[1] = (z[0] - x[2]) / s;
        q[2] = (x[1] - y[0]) / s;
    } else if (x[0] > y[1] && x[0] > z[2]) {
        float s = sqrtf(1 + x[0] - y[1] - z[2]) * 2;
        q[3] = (y[2] - z[1]) / s;
        q[0] = 0.25f * s;
        q[1] = (y[0] + x[1]) / s;
        q[2] = (z[0] + x[2]) / s;
    } else if (y[1] > z[2]) {
        float s = sqrtf(1 + y[1] - x[0] - z[2]) * 2;
        q[3] = (z[0] - x[2]) / s;
        q[0] = (y[0] + x[1]) / s;
        q[1] = 0.25f * s;
        q[2] = (z[1] + y[2]) / s;
    } else {
        float s = sqrtf(1 + z[2] - x[0] - y[1]) * 2;
        q[3] = (x[1] - y[0]) / s;
        q[0] = (z[0] + x[2]) / s;
        q[1] = (z[1] + y[2]) / s;
        q[2] = 0.25f * s;
    }
    float n = sqrtf(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int k = 0; k < 4; k++) q[k] /= n;
}

/* Weber-Penn LeafBend: turn the blade normal toward the outside of the tree
 * (about Z), then toward the sky, each by the fraction LeafBend. */
static void bend_leaf(const grower *g, const float p[3], frame *leaf)
{
    float bend = g->sp->leaf_bend;
    if (bend <= 0) return;
    const float *n = leaf->m + 6;
    if (fabsf(n[0]) + fabsf(n[1]) > 1e-6f && fabsf(p[0]) + fabsf(p[1]) > 1e-6f) {
        float d = atan2f(p[1], p[0]) - atan2f(n[1], n[0]);
        while (d > PI_F) d -= 2 * PI_F;
        while (d < -PI_F) d += 2 * PI_F;
        frame r = rot_z(bend * d);
        *leaf = mul(&r, leaf);
    }
    float axis[3] = {n[1], -n[0], 0}; /* n x Z */
    float len = sqrtf(axis[0] * axis[0] + axis[1] * axis[1]);
    if (len < 1e-6f) return;
    axis[0] /= len;
    axis[1] /= len;
    float a = acosf(n[2] > 1 ? 1 : n[2] < -1 ? -1 : n[2]);
    frame r = rot_axis(axis, bend * a);
    *leaf = mul(&r, leaf);
}

static sy_code add_leaf(grower *g, const float p[3], const frame *f, int32_t node)
{
    if (g->lv->n >= MAX_LEAVES)
        return sy_fail(g->err, SY_EINPUT, "species %s: tree exceeds %d leaves; lower Leaves or LeafQuality",
                       g->sp->name ? g->sp->name : "?", MAX_LEAVES);
    /* Leaf axes: +Y along the child heading, +Z (normal) in the plane of the
     * twig and the leaf, +X completing a right-handed frame. */
    frame leaf;
    for (int k = 0; k < 3; k++) {
        leaf.m[k] = -f->m[k];
        leaf.m[3 + k] = f->m[6 + k];
        leaf.m[6 + k] = f->m[3 + k];
    }
    bend_leaf(g, p, &leaf);
    float q[4];
    quat_from_axes(leaf.m, leaf.m + 3, leaf.m + 6, q);
    float scale = g->sp->leaf_scale / sqrtf(g->sp->leaf_quality);
    return sy_leaves_add(g->lv, p, q, scale, node, g->err);
}

static sy_code grow_leaves(grower *g, const stem *st, const piece *pc)
{
    const sy_species_params *sp = g->sp;
    float ratio = st->parent_length > 0 ? st->offset / st->parent_length : 0;
    float count = fabsf(sp->leaves) * sy_shape_ratio(sp, 4, ratio) * sp->leaf_quality;
    float start = (float)pc->k0 * pc->seg_len;
    int n = (int)floorf(count * (st->length - start) / st->length + 0.5f);
    const sy_wp_level *L = lvl(g, sp->levels);
    float az = 360.0f * rng_unit(&g->r);
    int side = 1;
    for (int i = 0; i < n; i++) {
        float off = sp->leaves < 0 ? st->length : start + (st->length - start) * ((float)i + 0.5f) / (float)n;
        float p[3], r_min;
        frame f;
        int32_t near;
        locate(g, pc, off, p, &f, &near, &r_min);
        float azimuth = sp->leaves < 0 ? (az + 360.0f * (float)i / (float)n) * DEG : next_azimuth(g, L, &az, &side);
        frame lf = turn(&f, azimuth, (L->down_angle + vary(&g->r, L->down_angle_v)) * DEG);
        sy_code rc = add_leaf(g, p, &lf, near);
        if (rc) return rc;
    }
    return SY_OK;
}

/* A traced piece becomes nodes, then its clones, children and leaves. */
static sy_code finish_piece(grower *g, const stem *st, piece *pc, int32_t parent)
{
    sy_code rc = emit(g, pc, st, parent);
    for (int e = 0; e < pc->n_events && rc == SY_OK; e++) {
        const split_event *ev = &pc->events[e];
        int32_t at = pc->point_node[ev->point];
        for (int c = 0; c < ev->n && rc == SY_OK; c++) {
            piece *clone = malloc(sizeof *clone);
            if (!clone) return sy_fail(g->err, SY_EINTERNAL, "grow: out of memory");
            trace(g, st, ev->point, pc->pos + 3 * ev->point, &ev->f[c], clone);
            rc = finish_piece(g, st, clone, at);
            free(clone);
        }
    }
    if (rc) return rc;
    if (st->level + 1 < g->sp->levels) {
        float count = child_count(g, st) + vary(&g->r, lvl(g, st->level + 1)->branches_v);
        if (count > 0) rc = grow_children(g, st, pc, count);
    } else if (g->sp->leaves != 0) {
        rc = grow_leaves(g, st, pc);
    }
    return rc;
}

static sy_code grow_stem(grower *g, stem *st, const float p0[3], const frame *f0, int32_t parent)
{
    piece *pc = malloc(sizeof *pc);
    if (!pc) return sy_fail(g->err, SY_EINTERNAL, "grow: out of memory");
    if (st->level >= 1 && g->sp->prune_ratio > 0) prune(g, st, p0, f0, pc);
    trace(g, st, 0, p0, f0, pc);
    sy_code rc = finish_piece(g, st, pc, parent);
    free(pc);
    return rc;
}

sy_code sy_grow_tree(const sy_species_params *sp, uint64_t seed, sy_skeleton *out, sy_leaves *leaves_out, sy_error *err)
{
    sy_leaves scratch;
    memset(&scratch, 0, sizeof scratch);
    sy_leaves *lv = leaves_out ? leaves_out : &scratch;
    memset(lv, 0, sizeof *lv);
    sy_code rc = sy_skeleton_init(out, 0, err);
    if (rc) return rc;
    for (int k = 0; k < SY_WP_LEVELS; k++)
        if (sp->level[k].curve_res < 1 || sp->level[k].curve_res > MAX_SEGS)
            return sy_fail(err, SY_EINPUT, "species %s: %dCurveRes must be in [1, %d]", sp->name ? sp->name : "?",
                           k, MAX_SEGS);
    grower g = {.sp = sp, .sk = out, .lv = lv, .err = err};
    g.r.s = seed ^ 0x5EED5A1FA5EEDull;
    g.scale_tree = sp->scale + vary(&g.r, sp->scale_v);
    float zscale = sp->zscale + vary(&g.r, sp->zscale_v);
    /* Node radii stay the circular Weber-Penn radius; the mesher ripples the
     * trunk's cross-section around it. */
    out->lobes = sp->lobe_depth > 0 ? sp->lobes : 0;
    out->lobe_depth = out->lobes > 0 ? sp->lobe_depth : 0;
    stem trunk = {.level = 0};
    trunk.length_max = sp->level[0].length + vary(&g.r, sp->level[0].length_v);
    trunk.length = trunk.length_max * g.scale_tree;
    trunk.parent_length = trunk.length;
    trunk.radius = trunk.length * sp->ratio * (sp->scale0 + vary(&g.r, sp->scale0_v));
    g.length_base = sp->base_size * trunk.length;
    if (trunk.length < MIN_LENGTH || trunk.radius <= 0) {
        return sy_fail(err, SY_EINPUT, "species %s: trunk length %g m / radius %g m is not positive",
                       sp->name ? sp->name : "?", trunk.length, trunk.radius);
    }
    frame f0 = rot_z(2 * PI_F * rng_unit(&g.r));
    const float origin[3] = {0, 0, 0};
    rc = grow_stem(&g, &trunk, origin, &f0, -1);
    if (rc == SY_OK && zscale != 1) {
        for (size_t i = 0; i < out->n; i++) out->pos[3 * i + 2] *= zscale;
        for (size_t i = 0; i < lv->n; i++) lv->pos[3 * i + 2] *= zscale;
    }
    if (rc) {
        sy_skeleton_free(out);
        sy_leaves_free(lv);
    } else if (!leaves_out) {
        sy_leaves_free(&scratch);
    }
    return rc;
}
