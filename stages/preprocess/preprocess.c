#include "preprocess.h"

#include <math.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../core/parallel.h"
#include "../core/progress.h"
#include "../core/voxel.h"
#include "pcl_filters.h"
#include "stages/core/geometry.h"
#include "stages/core/sort.h"

/* ---------------------------------------------------------------- options */

sy_preprocess_options sy_preprocess_options_default(void)
{
    sy_preprocess_options value_, *o = &value_;
    memset(o, 0, sizeof *o);
    o->up = SY_UP_AUTO;
    o->sor = 1;
    o->sor_k = 16;
    o->sor_std = 2.0;
    o->keep_top = 1;
    o->ground = 1;
    o->ground_cell = 0.5;
    o->ground_slope = 0.3;
    o->ground_max_window = 16.0;
    o->ground_threshold = 0.15;
    o->normals = 1;
    o->normal_k = 16;
    return value_;
}

sy_code sy_preprocess_options_check(const sy_preprocess_options *o, sy_error *err)
{
    if (o->up < -3 || o->up > 3) return sy_fail(err, SY_EUSAGE, "--up: unknown axis code %d", o->up);
    if (o->crop)
        for (int k = 0; k < 3; k++)
            if (!(o->crop_box[k] <= o->crop_box[k + 3]))
                return sy_fail(err, SY_EUSAGE, "--crop: minimum %g exceeds maximum %g on axis %c", o->crop_box[k],
                               o->crop_box[k + 3], 'x' + k);
    if (!(o->voxel >= 0) || !isfinite(o->voxel))
        return sy_fail(err, SY_EUSAGE, "--voxel: size must be 0 (off) or a positive number of metres");
    if (o->sor && (o->sor_k < 1 || o->sor_k > 1000))
        return sy_fail(err, SY_EUSAGE, "--sor-k: %d is outside 1..1000", o->sor_k);
    if (o->sor && !(o->sor_std > 0 && isfinite(o->sor_std)))
        return sy_fail(err, SY_EUSAGE, "--sor-std: must be a positive number");
    if (o->ground) {
        if (!(o->ground_cell > 0 && isfinite(o->ground_cell)))
            return sy_fail(err, SY_EUSAGE, "--ground-cell: must be a positive number of metres");
        if (!(o->ground_slope > 0 && isfinite(o->ground_slope)))
            return sy_fail(err, SY_EUSAGE, "--ground-slope: must be a positive rise over run");
        if (!(o->ground_max_window >= o->ground_cell && isfinite(o->ground_max_window)))
            return sy_fail(err, SY_EUSAGE, "--ground-max-window: must be at least --ground-cell");
        if (!(o->ground_threshold > 0 && isfinite(o->ground_threshold)))
            return sy_fail(err, SY_EUSAGE, "--ground-threshold: must be a positive number of metres");
    }
    if (o->normals && (o->normal_k < 3 || o->normal_k > 1000))
        return sy_fail(err, SY_EUSAGE, "--normal-k: %d is outside 3..1000", o->normal_k);
    return SY_OK;
}

int sy_up_parse(const char *text, int *up)
{
    if (strcmp(text, "auto") == 0) {
        *up = SY_UP_AUTO;
        return 0;
    }
    int sign = 1;
    if (*text == '+' || *text == '-') sign = *text++ == '-' ? -1 : 1;
    if (text[0] < 'x' || text[0] > 'z' || text[1] != '\0') return -1;
    *up = sign * (text[0] - 'x' + 1);
    return 0;
}

const char *sy_up_name(int up)
{
    static const char *names[] = {"-z", "-y", "-x", "auto", "+x", "+y", "+z"};
    return up >= -3 && up <= 3 ? names[up + 3] : "?";
}

/* ----------------------------------------------------------- up detection */

/* Cues, each measured as a fraction of the analysed points (see
 * docs/preprocess.md): cos 20 degrees marks a normal along an axis, sin 10
 * degrees a normal across it. */
#define ALONG 0.94
#define ACROSS 0.17
#define UP_SAMPLE 20000
#define UP_K 16
#define END_QUANTILE 0.03

/* RMS distance, across axis a, of the points with normalised height in
 * [lo, hi] from their own centroid. */
static double slab_spread(const float *p, size_t n, const double *h, int a, double lo, double hi)
{
    int u = (a + 1) % 3, v = (a + 2) % 3;
    double su = 0, sv = 0, suu = 0, svv = 0;
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (h[i] >= lo && h[i] <= hi) {
            double x = p[3 * i + u], y = p[3 * i + v];
            su += x, sv += y, suu += x * x, svv += y * y;
            m++;
        }
    if (m < 3) return 0;
    double var = suu / m - (su / m) * (su / m) + svv / m - (sv / m) * (sv / m);
    return var > 0 ? sqrt(var) : 0;
}

static double normalise(double v, double lo, double hi)
{
    v = (v - lo) / (hi - lo);
    return v < 0 ? 0 : v > 1 ? 1 : v;
}

/* Heights of the sample along axis a, normalised so that the 1st and 99th
 * percentiles map to 0 and 1 (far outliers must not set the scale) and
 * clamped to [0, 1]; sorted receives them in ascending order. Returns 0 when
 * the sample is flat along a. */
static int heights(const float *p, size_t n, int a, double *h, double *sorted)
{
    for (size_t i = 0; i < n; i++) sorted[i] = p[3 * i + a];
    qsort(sorted, n, sizeof *sorted, sy_cmp_double);
    double lo = sorted[n / 100], hi = sorted[n - 1 - n / 100];
    if (!(hi - lo > 1e-6)) return 0;
    for (size_t i = 0; i < n; i++) {
        h[i] = normalise(p[3 * i + a], lo, hi);
        sorted[i] = normalise(sorted[i], lo, hi); /* monotonic: stays sorted */
    }
    return 1;
}

/* Axis and sign evidence for axis a from the local PCA of the sample. */
static void axis_evidence(const float *p, size_t n, const float *dir, const float *nrm, const float *eig, int a,
                          double *h, double *sorted, double *axis_score, double *sign_score)
{
    *axis_score = *sign_score = 0;
    if (!heights(p, n, a, h, sorted)) return;
    double mean = 0;
    for (size_t i = 0; i < n; i++) mean += h[i];
    mean /= n;
    double floor_low = 0, floor_high = 0, stems = 0, stem_below = 0, lines = 0;
    for (size_t i = 0; i < n; i++) {
        double l1 = eig[3 * i], l2 = eig[3 * i + 1], l3 = eig[3 * i + 2];
        if (!(l1 > 0)) continue;
        int planar = (l2 - l3) / l1 > 0.5, linear = (l1 - l2) / l1 > 0.6;
        int along = -1;
        for (int b = 0; b < 3; b++)
            if (fabsf(nrm[3 * i + b]) > ALONG) along = b;
        if (planar && along == a) {
            /* A horizontal surface at one end: ground under the scene. */
            if (h[i] < 0.25) floor_low++;
            if (h[i] > 0.75) floor_high++;
        }
        if (planar && along < 0 && fabsf(nrm[3 * i + a]) < ACROSS) {
            /* A vertical surface not facing a coordinate axis: stems seen
             * from the side (ground never lands here for any axis). */
            stems++;
            stem_below += mean - h[i];
        }
        if (linear && fabsf(dir[3 * i + a]) > ALONG) lines++;
    }
    size_t q = (size_t)(END_QUANTILE * n);
    double bottom = slab_spread(p, n, h, a, 0.0, sorted[q]);
    double top = slab_spread(p, n, h, a, sorted[n - 1 - q], 1.0);
    double narrow_base = top + bottom > 0 ? (top - bottom) / (top + bottom) : 0;
    *axis_score = (floor_low + floor_high + stems + lines) / n;
    *sign_score = (floor_low - floor_high + stem_below) / n + 0.01 * narrow_base;
}

sy_code sy_detect_up(const sy_cloud *c, int *up, sy_up_evidence *ev, sy_error *err)
{
    sy_up_evidence local;
    if (!ev) ev = &local;
    memset(ev, 0, sizeof *ev);
    *up = SY_UP_Z;
    if (c->n < UP_K) return SY_OK; /* too few points to say anything */
    size_t stride = (c->n + UP_SAMPLE - 1) / UP_SAMPLE, n = (c->n + stride - 1) / stride;
    float *buf = sy_calloc(n, 12 * sizeof(float), err, "up-axis analysis");
    double *h = sy_calloc(2 * n, sizeof(double), err, "up-axis analysis");
    if (!buf || !h) {
        free(buf);
        free(h);
        return SY_EINTERNAL;
    }
    float *p = buf, *dir = buf + 3 * n, *nrm = buf + 6 * n, *eig = buf + 9 * n;
    for (size_t i = 0; i < n; i++) memcpy(p + 3 * i, c->xyz + 3 * i * stride, 3 * sizeof(float));
    if (sy_pcl_local_pca(p, n, UP_K, dir, nrm, eig, err)) {
        free(buf);
        free(h);
        return SY_EINTERNAL;
    }
    ev->sample = n;
    for (int a = 0; a < 3; a++)
        axis_evidence(p, n, dir, nrm, eig, a, h, h + n, &ev->axis_score[a], &ev->sign_score[a]);
    int best = 2; /* ties keep z */
    for (int a = 1; a >= 0; a--)
        if (ev->axis_score[a] > ev->axis_score[best]) best = a;
    *up = (ev->sign_score[best] >= 0 ? 1 : -1) * (best + 1);
    free(buf);
    free(h);
    return SY_OK;
}

/* Maps a vector so that the signed axis up becomes +z; every mapping is a
 * proper rotation (determinant +1). */
static void rotate3(int up, const double in[3], double out[3])
{
    double x = in[0], y = in[1], z = in[2];
    switch (up) {
    case -3: out[0] = x, out[1] = -y, out[2] = -z; break;
    case 2: out[0] = x, out[1] = -z, out[2] = y; break;
    case -2: out[0] = x, out[1] = z, out[2] = -y; break;
    case 1: out[0] = y, out[1] = z, out[2] = x; break;
    case -1: out[0] = y, out[1] = -z, out[2] = -x; break;
    default: out[0] = x, out[1] = y, out[2] = z; break;
    }
}

static void rotate_floats(int up, float *v, size_t n)
{
    for (size_t i = 0; i < n; i++) {
        double in[3] = {v[3 * i], v[3 * i + 1], v[3 * i + 2]}, out[3];
        rotate3(up, in, out);
        for (int k = 0; k < 3; k++) v[3 * i + k] = (float)out[k];
    }
}

void sy_rotate_to_z_up(sy_cloud *c, int up)
{
    if (up == SY_UP_Z || up == SY_UP_AUTO) return;
    double o[3];
    rotate3(up, c->origin, o);
    memcpy(c->origin, o, sizeof o);
    rotate_floats(up, c->xyz, c->n);
    if (c->normal) rotate_floats(up, c->normal, c->n);
}

/* ------------------------------------------------------------ crop, voxel */

sy_code sy_crop(sy_cloud *c, const double box[6], sy_error *err)
{
    uint8_t *keep = sy_calloc(c->n ? c->n : 1, 1, err, "crop mask");
    if (!keep) return SY_EINTERNAL;
    for (size_t i = 0; i < c->n; i++) {
        int in = 1;
        for (int k = 0; k < 3; k++) {
            double w = c->origin[k] + c->xyz[3 * i + k];
            in &= w >= box[k] && w <= box[k + 3];
        }
        keep[i] = (uint8_t)in;
    }
    sy_code rc = sy_cloud_filter(c, keep, err);
    free(keep);
    return rc;
}

/* The box of c's first `axes` coordinates, in its float frame; c->n > 0. */
static void local_bounds(const sy_cloud *c, int axes, float *lo, float *hi)
{
    for (int k = 0; k < axes; k++) lo[k] = hi[k] = c->xyz[k];
    for (size_t i = 1; i < c->n; i++)
        for (int k = 0; k < axes; k++) {
            float v = c->xyz[3 * i + k];
            if (v < lo[k]) lo[k] = v;
            if (v > hi[k]) hi[k] = v;
        }
}

sy_code sy_voxel_downsample(sy_cloud *c, double size, sy_error *err)
{
    if (c->n == 0 || size <= 0) return SY_OK;
    float lo[3], hi[3];
    local_bounds(c, 3, lo, hi);
    for (int k = 0; k < 3; k++)
        if ((hi[k] - lo[k]) / size >= (double)SY_VOXEL_AXIS_CELLS - 1)
            return sy_fail(err, SY_EUSAGE, "--voxel: %g m is too small for a cloud %.0f m wide (at most %u voxels per axis)",
                           size, (double)(hi[k] - lo[k]), SY_VOXEL_AXIS_CELLS);
    sy_voxel_entry *e = sy_calloc(c->n, sizeof *e, err, "voxel keys");
    uint8_t *keep = sy_calloc(c->n, 1, err, "voxel mask");
    if (!e || !keep) {
        free(e);
        free(keep);
        return SY_EINTERNAL;
    }
    sy_voxel_sort(c->xyz, c->n, lo, size, e);
    for (size_t b = 0; b < c->n;) {
        size_t end = b;
        double cen[3] = {0, 0, 0};
        while (end < c->n && e[end].key == e[b].key) {
            for (int k = 0; k < 3; k++) cen[k] += c->xyz[3 * e[end].index + k];
            end++;
        }
        for (int k = 0; k < 3; k++) cen[k] /= (double)(end - b);
        size_t best = e[b].index;
        double best_d = INFINITY;
        for (size_t j = b; j < end; j++) { /* ascending index: ties keep the first */
            const float *q = c->xyz + 3 * e[j].index;
            double d = 0;
            for (int k = 0; k < 3; k++) d += (q[k] - cen[k]) * (q[k] - cen[k]);
            if (d < best_d) best_d = d, best = e[j].index;
        }
        keep[best] = 1;
        b = end;
    }
    free(e);
    sy_code rc = sy_cloud_filter(c, keep, err);
    free(keep);
    return rc;
}

/* Distinct voxels of edge `size` among the points, counted up to a little
 * past `limit`: the points are split among the threads, which insert their
 * keys into one open-addressing table by compare-and-swap (an insert that
 * wins an empty slot is a new voxel; one that finds its key there is not),
 * so the count is exact whatever the split and the search below ends on the
 * same size for any thread count. Each thread publishes its count every
 * VOXEL_COUNT_BATCH new voxels and stops once the published total passes
 * the limit, which keeps the table (twice the limit) from filling. */
#define VOXEL_COUNT_BATCH 1024
typedef struct {
    const sy_cloud *c;
    const float *lo;
    double size;
    size_t limit, mask;
    _Atomic uint64_t *table;
    _Atomic size_t published;
    size_t chunk, chunks; /* points per chunk (fixed by n), and their count */
    size_t *counts;       /* per chunk */
} voxel_count_job;

static void clear_chunk(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    voxel_count_job *J = ctx;
    for (size_t i = begin; i < end; i++) atomic_store_explicit(&J->table[i], 0, memory_order_relaxed);
}

static void count_chunk(void *ctx, size_t begin, size_t end, size_t chunk)
{
    voxel_count_job *J = ctx;
    size_t count = 0, pending = 0;
    for (size_t i = begin; i < end; i++) {
        if (pending == VOXEL_COUNT_BATCH) {
            if (atomic_fetch_add_explicit(&J->published, pending, memory_order_relaxed) + pending > J->limit) break;
            pending = 0;
        }
        /* The core key uses 63 bits; a leading 1 keeps 0 free as the empty slot. */
        uint64_t key = 1ull << 63 | sy_voxel_key(J->c->xyz + 3 * i, J->lo, J->size);
        uint64_t h = key * 0x9E3779B97F4A7C15ull;
        for (size_t slot = (size_t)(h >> 20) & J->mask;; slot = (slot + 1) & J->mask) {
            uint64_t seen = atomic_load_explicit(&J->table[slot], memory_order_relaxed);
            if (seen == key) break;
            if (!seen) {
                if (atomic_compare_exchange_strong_explicit(&J->table[slot], &seen, key, memory_order_relaxed,
                                                            memory_order_relaxed)) {
                    count++;
                    pending++;
                    break;
                }
                if (seen == key) break; /* another thread put this key there first */
            }
        }
    }
    atomic_fetch_add_explicit(&J->published, pending, memory_order_relaxed);
    J->counts[chunk] = count;
}

static size_t occupied_voxels(voxel_count_job *J, double size)
{
    J->size = size;
    atomic_store(&J->published, 0);
    sy_parallel_for(J->mask + 1, 1 << 16, clear_chunk, J);
    sy_parallel_for(J->c->n, J->chunk, count_chunk, J);
    size_t count = 0;
    for (size_t k = 0; k < J->chunks; k++) count += J->counts[k];
    return count;
}

/* The finest voxel edge over a span of `wide` metres: keys of
 * SY_VOXEL_AXIS_CELLS cells per axis, two kept spare for rounding. */
static double finest_for_width(double wide) { return wide / ((double)SY_VOXEL_AXIS_CELLS - 2); }

double sy_voxel_finest(const sy_cloud *c)
{
    if (c->n == 0) return 0;
    float lo[3], hi[3];
    local_bounds(c, 3, lo, hi);
    double wide = 0;
    for (int k = 0; k < 3; k++) wide = fmax(wide, hi[k] - lo[k]);
    return finest_for_width(wide);
}

sy_code sy_voxel_size_for_count(const sy_cloud *c, size_t target, double *size, sy_error *err)
{
    *size = 0;
    if (c->n <= target || target == 0) return SY_OK;
    float lo[3], hi[3];
    local_bounds(c, 3, lo, hi);
    double vol = 1, wide = 0;
    for (int k = 0; k < 3; k++) {
        vol *= fmax(hi[k] - lo[k], 1e-3);
        wide = fmax(wide, hi[k] - lo[k]);
    }
    /* With edge cbrt(volume / target) the box holds at most target voxels. */
    double big = cbrt(vol / (double)target), small = fmax(big / 64, finest_for_width(wide));
    size_t tsize = 16;
    while (tsize < 2 * (target + 1)) tsize *= 2;
    /* Chunks of points: as many as the threads could use, fixed by n. */
    size_t chunk = c->n / 64 + 1;
    voxel_count_job J = {c, lo, 0, target, tsize - 1, NULL, 0, chunk, (c->n + chunk - 1) / chunk, NULL};
    J.table = sy_calloc(tsize, sizeof *J.table, err, "voxel count");
    J.counts = sy_calloc(J.chunks, sizeof *J.counts, err, "voxel count");
    if (!J.table || !J.counts) {
        free((void *)J.table);
        free(J.counts);
        return SY_EINTERNAL;
    }
    if (occupied_voxels(&J, small) <= target) big = small;
    else
        /* Bisection in log size: the count falls as the edge grows. */
        for (int it = 0; it < 10; it++) {
            double mid = sqrt(small * big);
            if (occupied_voxels(&J, mid) <= target) big = mid;
            else small = mid;
        }
    free((void *)J.table);
    free(J.counts);
    *size = big;
    return SY_OK;
}

/* ---------------------------------------------------------------- outliers */

typedef struct {
    float z, x, y;
    size_t i; /* index in the cloud */
} z_point;

static int cmp_z_down(const void *a, const void *b)
{
    const z_point *p = a, *q = b;
    int by_z = (p->z < q->z) - (p->z > q->z);
    return by_z ? by_z : (p->i > q->i) - (p->i < q->i);
}

static double z_dist(const z_point *a, const z_point *b) { return hypot(hypot(a->x - b->x, a->y - b->y), a->z - b->z); }

/* Has p[i] (sorted by z, highest first) `company` others within `reach`?
 * With mark (flags by cloud index), every one of them is marked. */
static int has_company(const z_point *p, size_t n, size_t i, double reach, size_t company, uint8_t *mark)
{
    size_t k = 0, all = mark ? n : company;
    for (size_t j = i; j-- > 0 && p[j].z - p[i].z <= reach && k < all;)
        if (z_dist(&p[j], &p[i]) <= reach && ++k && mark) mark[p[j].i] = 1;
    for (size_t j = i + 1; j < n && p[i].z - p[j].z <= reach && k < all; j++)
        if (z_dist(&p[j], &p[i]) <= reach && ++k && mark) mark[p[j].i] = 1;
    return k >= company;
}

/* The crown's top, world z (NaN when none): the highest point with
 * `company` others within `reach` (a stray has no company; a crown top
 * has), then on up through returns each within `link` of one below it that
 * is the tree's. The statistical filter judges a point by how far its
 * neighbours are against the whole cloud's spread, so on a terrestrial scan
 * it strips the sparse top of a crown with the strays (a 100k-point beech
 * lost 2.3 m of its 26 m). And a scanner on the ground sees a crown's top
 * in tufts up to a metre apart: on the bench's simulated sugar maple (100k
 * points) the highest supported return is 7.3 % under the true top, the
 * highest chained at 1 m 3.1 %, the highest of all 3.1 %; on the beech a
 * gap of more than 1.5 m leaves its highest returns (-5.8 %) apart from
 * the tree (-13.5 % supported and chained), and they stay out. chained
 * (c->n flags, by cloud index; may be NULL) marks the points that make
 * that top. */
static double crown_top(const sy_cloud *c, double reach, size_t company, double link, uint8_t *chained)
{
    if (c->n == 0) return NAN;
    z_point *p = malloc(c->n * sizeof *p);
    uint8_t *tree = calloc(c->n, 1);
    if (!p || !tree) {
        free(p), free(tree);
        return NAN;
    }
    for (size_t i = 0; i < c->n; i++) p[i] = (z_point){c->xyz[3 * i + 2], c->xyz[3 * i], c->xyz[3 * i + 1], i};
    qsort(p, c->n, sizeof *p, cmp_z_down);
    size_t top = c->n;
    for (size_t i = 0; i < c->n && top == c->n; i++)
        if (has_company(p, c->n, i, reach, company, NULL)) top = i;
    /* Upward from the supported top: everything at or below it counts as
     * the tree's. */
    for (size_t i = top; i < c->n; i++) tree[i] = 1;
    /* chained: the supported top with its company, each point the chain
     * takes and the point it links to, so that the same top stands in
     * the output for a second pass to find (`run` on a preprocessed file). */
    if (chained && top < c->n) chained[p[top].i] = 1, has_company(p, c->n, top, reach, company, chained);
    size_t highest = top;
    for (size_t j = top < c->n ? top : 0; j-- > 0;)
        for (size_t k = j + 1; k < c->n && p[j].z - p[k].z <= link; k++)
            if (tree[k] && z_dist(&p[j], &p[k]) <= link) {
                tree[j] = 1, highest = j;
                if (chained) chained[p[j].i] = chained[p[k].i] = 1;
                break;
            }
    double z = highest < c->n ? c->origin[2] + (double)p[highest].z : NAN;
    free(p), free(tree);
    return z;
}

/* The statistical filter's keep mask, with the crown's top given back: a
 * point it dropped above every point it kept, up to top_z (world;
 * crown_top), is kept when it has `company` others within `reach`, and so
 * is every point of the chain to that top. A sparse top is the tree; a
 * stray stays dropped. `sylva preprocess` wrote files 0.8-2.3 m short of their tops
 * (simulated black oak, London plane, beech at 100k points: -9.9, -10.1 and
 * -14.7 % of their true heights, against -5.0, -5.0 and -5.8 % for the
 * highest return of all), so a tree measured from a preprocessed file came
 * out short. Returns the points given back. */
static size_t keep_crown_top(const sy_cloud *c, uint8_t *keep, double top_z, const uint8_t *chained, double reach,
                             size_t company)
{
    if (!isfinite(top_z) || c->n == 0) return 0;
    size_t given = 0;
    float kept_max = -INFINITY, top = (float)(top_z - c->origin[2]);
    for (size_t i = 0; i < c->n; i++)
        if (keep[i]) kept_max = fmaxf(kept_max, c->xyz[3 * i + 2]);
    /* The chain whole, its stepping stones below the kept top too: without
     * them a second pass (`run` on a preprocessed file) found no chain. */
    for (size_t i = 0; chained && i < c->n; i++)
        if (chained[i] && !keep[i]) keep[i] = 1, given++;
    if (!(top > kept_max)) return given;
    /* Company of a point above kept_max lies above kept_max - reach. */
    size_t n = 0;
    for (size_t i = 0; i < c->n; i++) n += c->xyz[3 * i + 2] >= kept_max - (float)reach;
    z_point *p = malloc((n ? n : 1) * sizeof *p);
    n = 0; /* without memory, only the chain is given back */
    for (size_t i = 0; p && i < c->n; i++)
        if (c->xyz[3 * i + 2] >= kept_max - (float)reach)
            p[n++] = (z_point){c->xyz[3 * i + 2], c->xyz[3 * i], c->xyz[3 * i + 1], i};
    if (n) qsort(p, n, sizeof *p, cmp_z_down);
    for (size_t a = 0; a < n; a++) {
        size_t i = p[a].i;
        if (keep[i] || !(p[a].z > kept_max) || p[a].z > top + 1e-3f) continue;
        if (has_company(p, n, a, reach, company, NULL)) keep[i] = 1, given++;
    }
    free(p);
    return given;
}

sy_code sy_remove_outliers(sy_cloud *c, int k, double std_mul, sy_error *err)
{
    size_t given;
    return sy_remove_outliers_keeping_top(c, k, std_mul, NAN, NULL, &given, err);
}

sy_code sy_remove_outliers_keeping_top(sy_cloud *c, int k, double std_mul, double top_z, const uint8_t *chained,
                                       size_t *given, sy_error *err)
{
    uint8_t *keep = sy_calloc(c->n ? c->n : 1, 1, err, "outlier mask");
    if (!keep) return SY_EINTERNAL;
    sy_code rc = sy_pcl_outliers(c->xyz, c->n, k, std_mul, sy_threads(), keep, err);
    *given = rc == SY_OK ? keep_crown_top(c, keep, top_z, chained, 0.5, 3) : 0;
    if (rc == SY_OK) rc = sy_cloud_filter(c, keep, err);
    free(keep);
    return rc;
}

/* ------------------------------------------------------------------ ground */

/* The ground surface lives on the occupied cells only, never on a raster over
 * the bounds: two trees 100 km apart have the cells of two trees, and every
 * step below is bounded by the point count, not by the extent. A cell is
 * (column, row) packed into 64 bits; the bounds in cells are kept only to
 * clamp bilinear sampling at the edges. */
typedef struct {
    double x0, y0, cell;
    uint32_t nx, ny;    /* cells spanned by the bounds (never allocated) */
    size_t n_occupied;
    uint64_t *occupied; /* sorted keys of the cells holding points */
    uint32_t *cell_of;  /* per point: its cell's index in occupied */
    uint32_t *lowest;   /* per occupied cell: its lowest point (ties: lowest index) */
} ground_grid;

/* Heights on a sorted subset of cells. */
typedef struct {
    size_t n;
    uint64_t *key;
    double *z;
} cell_heights;

#define CELL_KEY(ix, iy) ((uint64_t)(iy) << 32 | (uint64_t)(ix))
#define CELL_X(k) ((uint32_t)((k) & 0xffffffffu))
#define CELL_Y(k) ((uint32_t)((k) >> 32))

static void grid_free(ground_grid *g)
{
    free(g->occupied);
    free(g->cell_of);
    free(g->lowest);
    memset(g, 0, sizeof *g);
}

static uint32_t cell_coord(double v, double lo, double cell, uint32_t n)
{
    double f = floor((v - lo) / cell);
    return f < 0 ? 0 : f >= n ? n - 1 : (uint32_t)f;
}

typedef struct {
    uint64_t key;
    float z;
    uint32_t index;
} point_cell;

static int cmp_point_cell(const void *a, const void *b)
{
    const point_cell *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    if (x->z != y->z) return x->z < y->z ? -1 : 1;
    return (x->index > y->index) - (x->index < y->index);
}

/* Finds key in the sorted keys; -1 when absent. */
static long find_key(const uint64_t *keys, size_t n, uint64_t key)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (keys[mid] < key) lo = mid + 1;
        else hi = mid;
    }
    return lo < n && keys[lo] == key ? (long)lo : -1;
}

static sy_code grid_init(ground_grid *g, const sy_cloud *c, double cell, sy_error *err)
{
    memset(g, 0, sizeof *g);
    if (c->n >= UINT32_MAX) return sy_fail(err, SY_EINPUT, "ground: %zu points exceed the 2^32 a cloud may hold", c->n);
    float lo[2], hi[2];
    local_bounds(c, 2, lo, hi);
    g->x0 = lo[0], g->y0 = lo[1], g->cell = cell;
    double nx = floor(((double)hi[0] - lo[0]) / cell) + 1, ny = floor(((double)hi[1] - lo[1]) / cell) + 1;
    /* Only the key width limits the span; no memory depends on it. */
    if (!(nx < 4e9 && ny < 4e9))
        return sy_fail(err, SY_EUSAGE, "--ground-cell: %g m is too small for a cloud %.0f m wide (at most 4e9 cells a side)",
                       cell, fmax((double)hi[0] - lo[0], (double)hi[1] - lo[1]));
    g->nx = (uint32_t)nx, g->ny = (uint32_t)ny;
    point_cell *e = sy_calloc(c->n, sizeof *e, err, "ground cells");
    g->cell_of = sy_calloc(c->n, sizeof *g->cell_of, err, "ground cells");
    if (!e || !g->cell_of) {
        free(e);
        grid_free(g);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < c->n; i++) {
        const float *p = c->xyz + 3 * i;
        e[i].key = CELL_KEY(cell_coord(p[0], g->x0, cell, g->nx), cell_coord(p[1], g->y0, cell, g->ny));
        e[i].z = p[2];
        e[i].index = (uint32_t)i;
    }
    qsort(e, c->n, sizeof *e, cmp_point_cell);
    size_t m = 0;
    for (size_t i = 0; i < c->n; i++) m += i == 0 || e[i].key != e[i - 1].key;
    g->occupied = sy_calloc(m, sizeof *g->occupied, err, "ground cells");
    g->lowest = sy_calloc(m, sizeof *g->lowest, err, "ground cells");
    if (!g->occupied || !g->lowest) {
        free(e);
        grid_free(g);
        return SY_EINTERNAL;
    }
    size_t j = 0;
    for (size_t i = 0; i < c->n; i++) {
        if (i == 0 || e[i].key != e[i - 1].key) {
            g->occupied[j] = e[i].key;
            g->lowest[j++] = e[i].index; /* sorted by z then index within the cell */
        }
        g->cell_of[e[i].index] = (uint32_t)(j - 1);
    }
    g->n_occupied = m;
    free(e);
    return SY_OK;
}

/* ---- gap filling: Shepard's inverse-distance weighting ----
 * A cell without ground takes the inverse-square-distance weighted mean of
 * the FILL_K nearest ground cells (Shepard 1968, "A two-dimensional
 * interpolation function for irregularly-spaced data"), found in a 2-d tree;
 * next to ground this is the mean of the filled neighbours, and across any
 * gap the cost stays a tree query. */

enum { FILL_K = 8 };

typedef struct {
    double x, y, z; /* cell centre in cell units, height */
} kd_item;

static int cmp_kd_x(const void *a, const void *b)
{
    const kd_item *p = a, *q = b;
    if (p->x != q->x) return p->x < q->x ? -1 : 1;
    return (p->y > q->y) - (p->y < q->y);
}

static int cmp_kd_y(const void *a, const void *b)
{
    const kd_item *p = a, *q = b;
    if (p->y != q->y) return p->y < q->y ? -1 : 1;
    return (p->x > q->x) - (p->x < q->x);
}

/* Balanced implicit tree: the median of each range splits it on x, then y. */
static void kd_build(kd_item *a, size_t n, int axis)
{
    if (n < 2) return;
    qsort(a, n, sizeof *a, axis ? cmp_kd_y : cmp_kd_x);
    size_t mid = n / 2;
    kd_build(a, mid, !axis);
    kd_build(a + mid + 1, n - mid - 1, !axis);
}

typedef struct {
    double d2;
    const kd_item *item;
} kd_hit;

/* Keeps the k nearest sorted by distance, ties by position (so the answer
 * does not depend on the tree's visiting order). */
static void kd_offer(kd_hit *best, int *len, int k, double d2, const kd_item *it)
{
    int i = *len;
    if (i == k) {
        const kd_hit *w = &best[k - 1];
        if (d2 > w->d2 || (d2 == w->d2 && cmp_kd_x(it, w->item) >= 0)) return;
        i = k - 1;
    } else
        (*len)++;
    while (i > 0 && (best[i - 1].d2 > d2 || (best[i - 1].d2 == d2 && cmp_kd_x(best[i - 1].item, it) > 0))) {
        best[i] = best[i - 1];
        i--;
    }
    best[i].d2 = d2;
    best[i].item = it;
}

static void kd_nearest(const kd_item *a, size_t n, int axis, double qx, double qy, kd_hit *best, int *len, int k)
{
    while (n > 0) {
        size_t mid = n / 2;
        const kd_item *p = a + mid;
        double dx = p->x - qx, dy = p->y - qy;
        kd_offer(best, len, k, dx * dx + dy * dy, p);
        double diff = axis ? qy - p->y : qx - p->x;
        const kd_item *near = diff < 0 ? a : p + 1, *far = diff < 0 ? p + 1 : a;
        size_t n_near = diff < 0 ? mid : n - mid - 1, n_far = diff < 0 ? n - mid - 1 : mid;
        kd_nearest(near, n_near, !axis, qx, qy, best, len, k);
        if (*len == k && diff * diff > best[k - 1].d2) return;
        a = far, n = n_far, axis = !axis; /* the far side, iteratively */
    }
}

/* Heights at every cell a point's bilinear sample touches: the occupied
 * cells and their 8 neighbours, each from h or filled. */
static sy_code fill_cells(const ground_grid *g, const cell_heights *h, cell_heights *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    size_t cap = 9 * g->n_occupied;
    out->key = sy_calloc(cap, sizeof *out->key, err, "ground surface");
    kd_item *tree = sy_calloc(h->n ? h->n : 1, sizeof *tree, err, "ground surface");
    if (!out->key || !tree) {
        free(out->key);
        free(tree);
        out->key = NULL;
        return SY_EINTERNAL;
    }
    size_t n = 0;
    for (size_t j = 0; j < g->n_occupied; j++) {
        uint32_t cx = CELL_X(g->occupied[j]), cy = CELL_Y(g->occupied[j]);
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                int64_t x = (int64_t)cx + dx, y = (int64_t)cy + dy;
                if (x < 0 || y < 0 || x >= g->nx || y >= g->ny) continue;
                out->key[n++] = CELL_KEY(x, y);
            }
    }
    qsort(out->key, n, sizeof *out->key, sy_cmp_u64);
    size_t u = 0;
    for (size_t i = 0; i < n; i++)
        if (u == 0 || out->key[i] != out->key[u - 1]) out->key[u++] = out->key[i];
    out->n = u;
    out->z = sy_calloc(u, sizeof *out->z, err, "ground surface");
    if (!out->z) {
        free(tree);
        free(out->key);
        out->key = NULL;
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < h->n; i++) {
        tree[i].x = CELL_X(h->key[i]) + 0.5;
        tree[i].y = CELL_Y(h->key[i]) + 0.5;
        tree[i].z = h->z[i];
    }
    kd_build(tree, h->n, 0);
    for (size_t i = 0; i < u; i++) {
        long at = find_key(h->key, h->n, out->key[i]);
        if (at >= 0) {
            out->z[i] = h->z[at];
            continue;
        }
        kd_hit best[FILL_K];
        int len = 0;
        kd_nearest(tree, h->n, 0, CELL_X(out->key[i]) + 0.5, CELL_Y(out->key[i]) + 0.5, best, &len, FILL_K);
        double sw = 0, sz = 0;
        for (int k = 0; k < len; k++) {
            double w = 1 / best[k].d2; /* d2 >= 1: the cell itself has no height */
            sw += w, sz += w * best[k].item->z;
        }
        out->z[i] = sz / sw;
    }
    free(tree);
    return SY_OK;
}

static void heights_free(cell_heights *h)
{
    free(h->key);
    free(h->z);
    memset(h, 0, sizeof *h);
}

/* hag[i] = height of point i above the surface through h's cells, bilinear
 * between cell centres (clamped at the bounds). */
static sy_code heights_above(const sy_cloud *c, const ground_grid *g, const cell_heights *h, double *hag,
                             sy_error *err)
{
    cell_heights s;
    if (fill_cells(g, h, &s, err)) return SY_EINTERNAL;
    long mx = (long)g->nx - 1, my = (long)g->ny - 1;
    for (size_t i = 0; i < c->n; i++) {
        const float *p = c->xyz + 3 * i;
        double fx = (p[0] - g->x0) / g->cell - 0.5, fy = (p[1] - g->y0) / g->cell - 0.5;
        double bx = floor(fx), by = floor(fy);
        double tx = fx - bx, ty = fy - by;
        long x0 = bx < 0 ? -1 : bx > mx ? mx : (long)bx, y0 = by < 0 ? -1 : by > my ? my : (long)by;
        long x1 = x0 + 1, y1 = y0 + 1;
        if (x0 < 0) x0 = 0, tx = 0;
        if (y0 < 0) y0 = 0, ty = 0;
        if (x1 > mx) x1 = mx;
        if (y1 > my) y1 = my;
        double z[4];
        long xs[2] = {x0, x1}, ys[2] = {y0, y1};
        for (int k = 0; k < 4; k++) {
            long at = find_key(s.key, s.n, CELL_KEY(xs[k & 1], ys[k >> 1]));
            z[k] = at >= 0 ? s.z[at] : p[2]; /* unreachable: every corner neighbours the point's cell */
        }
        hag[i] = p[2] - ((1 - ty) * ((1 - tx) * z[0] + tx * z[1]) + ty * ((1 - tx) * z[2] + tx * z[3]));
    }
    heights_free(&s);
    return SY_OK;
}

/* The lowest point of every occupied cell, run through PMF; the surviving
 * cells get their lowest point's height. */
static sy_code pmf_surface(const sy_cloud *c, const sy_preprocess_options *o, const ground_grid *g, cell_heights *h,
                           sy_error *err)
{
    memset(h, 0, sizeof *h);
    size_t m = g->n_occupied;
    float *copy = sy_calloc(m, 3 * sizeof(float), err, "ground candidates");
    uint8_t *is_ground = sy_calloc(m, 1, err, "ground candidates");
    h->key = sy_calloc(m, sizeof *h->key, err, "ground candidates");
    h->z = sy_calloc(m, sizeof *h->z, err, "ground candidates");
    sy_code rc = SY_OK;
    if (!copy || !is_ground || !h->key || !h->z) rc = SY_EINTERNAL;
    if (rc == SY_OK) {
        for (size_t j = 0; j < m; j++) memcpy(copy + 3 * j, c->xyz + 3 * (size_t)g->lowest[j], 3 * sizeof(float));
        rc = sy_pcl_ground_pmf(copy, m, o->ground_cell, o->ground_slope, o->ground_max_window, o->ground_threshold,
                               3.0 + o->ground_slope * o->ground_max_window, is_ground, err);
    }
    for (size_t j = 0; rc == SY_OK && j < m; j++)
        if (is_ground[j]) h->key[h->n] = g->occupied[j], h->z[h->n++] = copy[3 * j + 2];
    free(copy);
    free(is_ground);
    if (rc) heights_free(h);
    return rc;
}

/* Replaces each cell's height by the mean height of the ground points in it,
 * which centres the surface in the ground's noise band instead of under it. */
static sy_code refine_surface(const sy_cloud *c, const ground_grid *g, const double *hag, double threshold,
                              cell_heights *h, sy_error *err)
{
    size_t m = g->n_occupied;
    double *sum = sy_calloc(m, sizeof(double), err, "ground surface");
    size_t *count = sy_calloc(m, sizeof(size_t), err, "ground surface");
    if (!sum || !count) {
        free(sum);
        free(count);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < c->n; i++)
        if (hag[i] < threshold) {
            sum[g->cell_of[i]] += c->xyz[3 * i + 2];
            count[g->cell_of[i]]++;
        }
    h->n = 0;
    for (size_t j = 0; j < m; j++)
        if (count[j]) h->key[h->n] = g->occupied[j], h->z[h->n++] = sum[j] / count[j];
    free(sum);
    free(count);
    return SY_OK;
}

sy_code sy_classify_ground(sy_cloud *c, const sy_preprocess_options *o, size_t *n_ground, sy_error *err)
{
    *n_ground = 0;
    double *hag = sy_cloud_add_attr(c, "height_above_ground", err);
    if (!hag) return SY_EINTERNAL;
    int had_classes = c->classification != NULL;
    if (sy_cloud_add_classification(c, err)) return SY_EINTERNAL;
    if (c->n == 0) return SY_OK;
    ground_grid g;
    cell_heights h = {0};
    sy_code rc = grid_init(&g, c, o->ground_cell, err);
    if (rc == SY_OK) rc = pmf_surface(c, o, &g, &h, err);
    int filled = rc == SY_OK && h.n > 0;
    if (filled) {
        rc = heights_above(c, &g, &h, hag, err);
        /* refine keeps a subset of the occupied cells: h's arrays suffice */
        if (rc == SY_OK) rc = refine_surface(c, &g, hag, o->ground_threshold, &h, err);
        if (rc == SY_OK && h.n > 0) rc = heights_above(c, &g, &h, hag, err);
    } else if (rc == SY_OK) { /* PMF kept nothing: heights from the lowest point */
        float zmin = c->xyz[2];
        for (size_t i = 1; i < c->n; i++)
            if (c->xyz[3 * i + 2] < zmin) zmin = c->xyz[3 * i + 2];
        for (size_t i = 0; i < c->n; i++) hag[i] = c->xyz[3 * i + 2] - zmin;
    }
    for (size_t i = 0; rc == SY_OK && i < c->n; i++) {
        int ground = filled && hag[i] < o->ground_threshold;
        if (ground) c->classification[i] = 2, (*n_ground)++;
        else if (!had_classes || c->classification[i] == 2) c->classification[i] = 1; /* unclassified */
    }
    heights_free(&h);
    grid_free(&g);
    return rc;
}

/* ----------------------------------------------------------------- normals */

/* Median x and median y of the cloud. */
static sy_code median_xy(const sy_cloud *c, float centre[2], sy_error *err)
{
    float *v = sy_calloc(c->n, sizeof(float), err, "normal orientation");
    if (!v) return SY_EINTERNAL;
    for (int k = 0; k < 2; k++) {
        for (size_t i = 0; i < c->n; i++) v[i] = c->xyz[3 * i + k];
        qsort(v, c->n, sizeof(float), sy_cmp_float);
        centre[k] = v[c->n / 2];
    }
    free(v);
    return SY_OK;
}

static void normals_progress(void *ctx, size_t done) { sy_progress_update(ctx, done); }

sy_code sy_estimate_normals(sy_cloud *c, int k, sy_error *err)
{
    if (sy_cloud_add_normals(c, err)) return SY_EINTERNAL;
    if (c->n == 0) return SY_OK;
    sy_progress p;
    sy_progress_begin(&p, "normals", c->n);
    if (sy_pcl_normals(c->xyz, c->n, k, sy_threads(), c->normal, normals_progress, &p, err)) return SY_EINTERNAL;
    sy_progress_end(&p);
    float centre[2];
    if (median_xy(c, centre, err)) return SY_EINTERNAL;
    /* Reference direction: up plus the unit vector away from the vertical
     * line through the median point. Ground (slopes under 45 degrees) then
     * faces up and stems around that line face outwards; a far viewpoint
     * would leave near-horizontal stem normals to noise. */
    for (size_t i = 0; i < c->n; i++) {
        float *nv = c->normal + 3 * i;
        double len = sqrt((double)nv[0] * nv[0] + (double)nv[1] * nv[1] + (double)nv[2] * nv[2]);
        if (!(len > 0)) {
            nv[0] = 0, nv[1] = 0, nv[2] = 1;
            continue;
        }
        double rx = c->xyz[3 * i] - centre[0], ry = c->xyz[3 * i + 1] - centre[1], r = sqrt(rx * rx + ry * ry);
        double dot = nv[2] + (r > 0 ? (nv[0] * rx + nv[1] * ry) / r : 0);
        double s = (dot < 0 ? -1 : 1) / len;
        for (int k = 0; k < 3; k++) nv[k] = (float)(nv[k] * s);
    }
    return SY_OK;
}

/* ---------------------------------------------------------------- pipeline */

static sy_preprocess_step *step_begin(sy_preprocess_result *r, int i, const char *name, int ran, size_t n)
{
    sy_preprocess_step *s = &r->steps[i];
    memset(s, 0, sizeof *s);
    s->name = name;
    s->ran = ran;
    s->before = s->after = n;
    s->seconds = sy_now();
    return s;
}

static void step_end(sy_preprocess_step *s, size_t n)
{
    s->after = n;
    s->seconds = s->ran ? sy_now() - s->seconds : 0;
}

static sy_code step_up(sy_cloud *c, const sy_preprocess_options *o, sy_preprocess_result *r, sy_preprocess_step *s,
                       sy_error *err)
{
    int up = o->up;
    if (up == SY_UP_AUTO && strcmp(c->meta.format, "LAS") == 0) {
        up = SY_UP_Z;
        snprintf(s->detail, sizeof s->detail, "LAS is Z-up by specification; kept");
    } else if (up == SY_UP_AUTO) {
        sy_up_evidence ev;
        sy_code rc = sy_detect_up(c, &up, &ev, err);
        if (rc) return rc;
        r->up_detected = 1;
        int a = abs(up) - 1;
        /* The file's own +z is the convention of survey and scanner exports
         * (every AdTree, TreeLS, rTwig and PyTLidar file): leave it only on
         * decisive evidence. Near-ties are what a sparse airborne crown gives
         * (ahn3_delft: y 0.039 vs z 0.031, and a 2-node tree lying down). */
        int weak_axis = a != 2 && ev.axis_score[a] < SY_UP_AXIS_MARGIN * ev.axis_score[2];
        int weak_sign = up == -SY_UP_Z && -ev.sign_score[2] < SY_UP_SIGN_MARGIN;
        if (weak_axis || weak_sign) {
            snprintf(s->detail, sizeof s->detail,
                     "geometry leans %s (axis scores x %.3f y %.3f z %.3f, sign %+.4f) but not decisively; kept the "
                     "file's +z",
                     sy_up_name(up), ev.axis_score[0], ev.axis_score[1], ev.axis_score[2], ev.sign_score[a]);
            up = SY_UP_Z;
        } else {
            snprintf(s->detail, sizeof s->detail, "detected %s (axis scores x %.3f y %.3f z %.3f, sign %+.4f)%s",
                     sy_up_name(up), ev.axis_score[0], ev.axis_score[1], ev.axis_score[2], ev.sign_score[a],
                     up == SY_UP_Z ? "; kept" : "; rotated to +z");
        }
    } else {
        snprintf(s->detail, sizeof s->detail, "given %s%s", sy_up_name(up), up == SY_UP_Z ? "; kept" : "; rotated to +z");
    }
    r->up_axis = up;
    sy_rotate_to_z_up(c, up);
    return SY_OK;
}

/* Whether the points classified ground are terrain: enough of them, lying
 * on one surface (a least-squares plane z = a x + b y + c leaves a median
 * absolute residual of at most GROUND_PLANE_RESIDUAL metres; measured 0.01-0.05
 * on TLS and ALS ground, 0.16 on ahn3_delft's street, 0.34 on a scan with no
 * ground at all: terrain under one tree is near planar, while
 * on a scan without ground the filter takes the lowest points of each cell,
 * the stem's foot and the underside of the crown, metres apart), covering
 * at least GROUND_COVER of the cloud's footprint cells, and spread wider than
 * it is thick: the standard deviation of its x, y along their narrower
 * principal axis at least GROUND_SPREAD times the 90th percentile of the
 * plane's residuals. Terrain is a sheet (measured 3.6 on ahn3_delft's street,
 * 4.2 under the TreeLS pine, 27 on its plot); a scan that stops
 * at the stem's foot gives the filter a slab of stem as tall as it is wide
 * (0.33 on rTwig's sapling, 0.44 on AdTree's tree7) or the base of a stem with the
 * crown's underside (1.2 on tree13), whose removal shortened the stem. */
#define GROUND_MIN_POINTS 50
#define GROUND_PLANE_RESIDUAL 0.25
#define GROUND_COVER 0.05
#define GROUND_SPREAD 2.0

static size_t distinct_cells(uint64_t *k, size_t m)
{
    qsort(k, m, sizeof *k, sy_cmp_u64);
    size_t d = 0;
    for (size_t i = 0; i < m; i++) d += i == 0 || k[i] != k[i - 1];
    return d;
}

static int ground_is_terrain(const sy_cloud *c, double cell, double *rms_out, double *cover_out, double *spread_out)
{
    *rms_out = *cover_out = *spread_out = 0;
    size_t m = 0;
    double lo[2] = {INFINITY, INFINITY};
    for (size_t i = 0; i < c->n; i++) {
        m += c->classification[i] == 2;
        for (int k = 0; k < 2; k++) lo[k] = fmin(lo[k], c->xyz[3 * i + k]);
    }
    if (m < GROUND_MIN_POINTS) return 0;
    /* Normal equations of the plane, centred for conditioning. */
    double mean[3] = {0, 0, 0};
    for (size_t i = 0; i < c->n; i++)
        if (c->classification[i] == 2)
            for (int k = 0; k < 3; k++) mean[k] += c->xyz[3 * i + k] / (double)m;
    double sxx = 0, sxy = 0, syy = 0, sxz = 0, syz = 0;
    for (size_t i = 0; i < c->n; i++) {
        if (c->classification[i] != 2) continue;
        double x = c->xyz[3 * i] - mean[0], y = c->xyz[3 * i + 1] - mean[1], z = c->xyz[3 * i + 2] - mean[2];
        sxx += x * x, sxy += x * y, syy += y * y, sxz += x * z, syz += y * z;
    }
    double det = sxx * syy - sxy * sxy, a = 0, b = 0;
    if (fabs(det) > 1e-12) {
        a = (sxz * syy - syz * sxy) / det;
        b = (syz * sxx - sxz * sxy) / det;
    }
    /* The median absolute residual: a few stray returns (a kerb, a low
     * shrub) must not decide it. */
    double *res = malloc(m * sizeof *res);
    uint64_t *k = malloc(c->n * sizeof *k);
    if (!k || !res) {
        free(k);
        free(res);
        return 1; /* no evidence either way: keep the classification */
    }
    size_t t = 0;
    for (size_t i = 0; i < c->n; i++) {
        if (c->classification[i] != 2) continue;
        double x = c->xyz[3 * i] - mean[0], y = c->xyz[3 * i + 1] - mean[1], z = c->xyz[3 * i + 2] - mean[2];
        res[t++] = fabs(z - a * x - b * y);
    }
    qsort(res, m, sizeof *res, sy_cmp_double);
    *rms_out = res[m / 2];
    double thickness = res[(size_t)(0.9 * (double)(m - 1))];
    free(res);
    /* The narrower principal spread of the ground's footprint: the smaller
     * eigenvalue of its x, y covariance (z left out, so the third is 0). */
    double cov[6] = {sxx / (double)m, sxy / (double)m, 0, syy / (double)m, 0, 0}, l[3], v[9];
    sy_sym3_eigen(cov, l, v);
    double narrow = sqrt(l[1]);
    size_t g = 0;
    for (size_t i = 0; i < c->n; i++)
        if (c->classification[i] == 2)
            k[g++] = (uint64_t)floor((c->xyz[3 * i] - lo[0]) / cell) << 32 | (uint64_t)floor((c->xyz[3 * i + 1] - lo[1]) / cell);
    size_t ground_cells = distinct_cells(k, g);
    for (size_t i = 0; i < c->n; i++)
        k[i] = (uint64_t)floor((c->xyz[3 * i] - lo[0]) / cell) << 32 | (uint64_t)floor((c->xyz[3 * i + 1] - lo[1]) / cell);
    size_t all_cells = distinct_cells(k, c->n);
    free(k);
    *cover_out = all_cells ? (double)ground_cells / (double)all_cells : 0;
    *spread_out = thickness > 0 ? narrow / thickness : INFINITY;
    return *rms_out <= GROUND_PLANE_RESIDUAL && *cover_out >= GROUND_COVER && *spread_out >= GROUND_SPREAD;
}

sy_code sy_preprocess(sy_cloud *c, const sy_preprocess_options *o, sy_preprocess_result *r, sy_error *err)
{
    memset(r, 0, sizeof *r);
    r->point_count_in = c->n;
    sy_code rc = sy_preprocess_options_check(o, err);
    if (rc) return rc;
    sy_progress p;

    sy_preprocess_step *s = step_begin(r, 0, "up", 1, c->n);
    rc = step_up(c, o, r, s, err);
    step_end(s, c->n);

    s = step_begin(r, 1, "crop", o->crop, c->n);
    if (rc == SY_OK && o->crop) rc = sy_crop(c, o->crop_box, err);
    step_end(s, c->n);

    s = step_begin(r, 2, "voxel", o->voxel > 0, c->n);
    if (rc == SY_OK && o->voxel > 0) {
        rc = sy_voxel_downsample(c, o->voxel, err);
        snprintf(s->detail, sizeof s->detail, "%g m voxels, nearest point to each voxel centroid kept", o->voxel);
    }
    step_end(s, c->n);

    /* Only the outlier filter strips a top: without it the output's highest point is the top. */
    /* The chain to it is kept only with keep_top. */
    uint8_t *chained = rc == SY_OK && o->sor && o->keep_top ? calloc(c->n ? c->n : 1, 1) : NULL;
    if (rc == SY_OK && o->sor && o->keep_top && !chained) rc = sy_fail(err, SY_EINTERNAL, "preprocess: out of memory");
    r->top_z = rc == SY_OK && o->sor ? crown_top(c, 0.5, 3, 1.0, chained) : NAN;
    s = step_begin(r, 3, "outliers", o->sor, c->n);
    if (rc == SY_OK && o->sor) {
        sy_progress_begin(&p, "outliers", c->n);
        size_t given = 0;
        rc = sy_remove_outliers_keeping_top(c, o->sor_k, o->sor_std, o->keep_top ? r->top_z : NAN, chained, &given,
                                            err);
        if (rc == SY_OK) sy_progress_end(&p);
        snprintf(s->detail, sizeof s->detail, "k %d, %g standard deviations; %zu points of the crown's top kept",
                 o->sor_k, o->sor_std, given);
    }
    free(chained);
    step_end(s, c->n);

    s = step_begin(r, 4, "ground", o->ground, c->n);
    if (rc == SY_OK && o->ground) {
        sy_progress_begin(&p, "ground", c->n);
        rc = sy_classify_ground(c, o, &r->ground_points, err);
        if (rc == SY_OK) sy_progress_end(&p);
        double rms = 0, cover = 0, spread = 0;
        int terrain = rc == SY_OK && ground_is_terrain(c, o->ground_cell, &rms, &cover, &spread);
        if (rc == SY_OK && !terrain && r->ground_points) {
            /* No ground in this scan: the "ground" was the tree's own lowest
             * points. They stay, unclassified, with no height above ground. */
            double *hag = sy_cloud_attr(c, "height_above_ground");
            for (size_t i = 0; i < c->n; i++) {
                if (c->classification[i] == 2) c->classification[i] = 1;
                if (hag) hag[i] = NAN;
            }
            snprintf(s->detail, sizeof s->detail,
                     "no ground: the %zu lowest points fit no terrain (median plane residual %.2f m, %.0f%% of the footprint, "
                     "width/thickness %.1f); kept",
                     r->ground_points, rms, 100 * cover, spread);
            r->ground_points = 0;
        }
        if (rc == SY_OK && !terrain) {
        } else if (rc == SY_OK && o->remove_ground) {
            uint8_t *keep = sy_calloc(c->n ? c->n : 1, 1, err, "ground mask");
            if (!keep) rc = SY_EINTERNAL;
            for (size_t i = 0; keep && i < c->n; i++) keep[i] = c->classification[i] != 2;
            if (keep) rc = sy_cloud_filter(c, keep, err);
            free(keep);
        }
        if (terrain)
            snprintf(s->detail, sizeof s->detail,
                     "%zu ground points (class 2)%s, cell %g m, slope %g, window %g m; median plane residual %.2f m, %.0f%% of the "
                     "footprint, width/thickness %.1f",
                     r->ground_points, o->remove_ground ? " removed" : "", o->ground_cell, o->ground_slope,
                     o->ground_max_window, rms, 100 * cover, spread);
    }
    step_end(s, c->n);

    s = step_begin(r, 5, "normals", o->normals, c->n);
    if (rc == SY_OK && o->normals) {
        rc = sy_estimate_normals(c, o->normal_k, err);
        snprintf(s->detail, sizeof s->detail, "k %d on %d threads, oriented up and outwards", o->normal_k, sy_threads());
    }
    step_end(s, c->n);

    r->point_count_out = c->n;
    return rc;
}
