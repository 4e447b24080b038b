#include "preprocess.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../core/parallel.h"
#include "../core/progress.h"
#include "pcl_filters.h"

/* ---------------------------------------------------------------- options */

sy_preprocess_options sy_preprocess_options_default(void)
{
    sy_preprocess_options value_, *o = &value_;
    memset(o, 0, sizeof *o);
    o->up = SY_UP_AUTO;
    o->sor = 1;
    o->sor_k = 16;
    o->sor_std = 2.0;
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

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

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
    qsort(sorted, n, sizeof *sorted, cmp_double);
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
    char msg[256];
    if (sy_pcl_local_pca(p, n, UP_K, dir, nrm, eig, msg, sizeof msg)) {
        free(buf);
        free(h);
        return sy_fail(err, SY_EINTERNAL, "%s", msg);
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

typedef struct {
    uint64_t key;
    size_t index;
} voxel_entry;

static int cmp_voxel(const void *a, const void *b)
{
    const voxel_entry *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return (x->index > y->index) - (x->index < y->index);
}

#define VOXEL_BITS 21

sy_code sy_voxel_downsample(sy_cloud *c, double size, sy_error *err)
{
    if (c->n == 0 || size <= 0) return SY_OK;
    float lo[3] = {c->xyz[0], c->xyz[1], c->xyz[2]}, hi[3] = {lo[0], lo[1], lo[2]};
    for (size_t i = 1; i < c->n; i++)
        for (int k = 0; k < 3; k++) {
            float v = c->xyz[3 * i + k];
            if (v < lo[k]) lo[k] = v;
            if (v > hi[k]) hi[k] = v;
        }
    for (int k = 0; k < 3; k++)
        if ((hi[k] - lo[k]) / size >= (double)(1u << VOXEL_BITS) - 1)
            return sy_fail(err, SY_EUSAGE, "--voxel: %g m is too small for a cloud %.0f m wide (at most %u voxels per axis)",
                           size, (double)(hi[k] - lo[k]), 1u << VOXEL_BITS);
    voxel_entry *e = sy_calloc(c->n, sizeof *e, err, "voxel keys");
    uint8_t *keep = sy_calloc(c->n, 1, err, "voxel mask");
    if (!e || !keep) {
        free(e);
        free(keep);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < c->n; i++) {
        uint64_t key = 0;
        for (int k = 0; k < 3; k++) {
            uint64_t cell = (uint64_t)floor((c->xyz[3 * i + k] - lo[k]) / size);
            key = key << VOXEL_BITS | cell;
        }
        e[i].key = key;
        e[i].index = i;
    }
    qsort(e, c->n, sizeof *e, cmp_voxel);
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

/* ---------------------------------------------------------------- outliers */

sy_code sy_remove_outliers(sy_cloud *c, int k, double std_mul, sy_error *err)
{
    uint8_t *keep = sy_calloc(c->n ? c->n : 1, 1, err, "outlier mask");
    if (!keep) return SY_EINTERNAL;
    char msg[256];
    sy_code rc = SY_OK;
    if (sy_pcl_outliers(c->xyz, c->n, k, std_mul, keep, msg, sizeof msg)) rc = sy_fail(err, SY_EINTERNAL, "%s", msg);
    else rc = sy_cloud_filter(c, keep, err);
    free(keep);
    return rc;
}

/* ------------------------------------------------------------------ ground */

/* A raster over the cloud's xy bounds; cells hold a surface height or NaN. */
typedef struct {
    double x0, y0, cell;
    size_t nx, ny;
    double *z;
} grid;

#define GRID_MAX_CELLS ((size_t)1 << 25)

static sy_code grid_init(grid *g, const sy_cloud *c, double cell, sy_error *err)
{
    float lo[2] = {c->xyz[0], c->xyz[1]}, hi[2] = {lo[0], lo[1]};
    for (size_t i = 1; i < c->n; i++)
        for (int k = 0; k < 2; k++) {
            float v = c->xyz[3 * i + k];
            if (v < lo[k]) lo[k] = v;
            if (v > hi[k]) hi[k] = v;
        }
    g->x0 = lo[0], g->y0 = lo[1], g->cell = cell;
    double nx = floor((hi[0] - lo[0]) / cell) + 1, ny = floor((hi[1] - lo[1]) / cell) + 1;
    if (nx * ny > (double)GRID_MAX_CELLS)
        return sy_fail(err, SY_EUSAGE, "--ground-cell: %g m gives %.0f x %.0f cells over this cloud; use a larger cell",
                       cell, nx, ny);
    g->nx = (size_t)nx, g->ny = (size_t)ny;
    g->z = sy_calloc(g->nx * g->ny, sizeof(double), err, "ground grid");
    if (!g->z) return SY_EINTERNAL;
    for (size_t i = 0; i < g->nx * g->ny; i++) g->z[i] = NAN;
    return SY_OK;
}

static size_t grid_index(const grid *g, const float *p)
{
    size_t ix = (size_t)((p[0] - g->x0) / g->cell), iy = (size_t)((p[1] - g->y0) / g->cell);
    if (ix >= g->nx) ix = g->nx - 1;
    if (iy >= g->ny) iy = g->ny - 1;
    return iy * g->nx + ix;
}

/* Fills empty cells ring by ring from the filled ones, each with the mean of
 * its already-filled 8-neighbours; returns 0 when no cell was filled. */
static int grid_fill(grid *g, sy_error *err)
{
    size_t total = g->nx * g->ny, filled = 0;
    for (size_t i = 0; i < total; i++) filled += !isnan(g->z[i]);
    if (filled == 0) return 0;
    double *next = sy_calloc(total, sizeof(double), err, "ground grid");
    if (!next) return -1;
    while (filled < total) {
        memcpy(next, g->z, total * sizeof(double));
        for (size_t iy = 0; iy < g->ny; iy++)
            for (size_t ix = 0; ix < g->nx; ix++) {
                if (!isnan(g->z[iy * g->nx + ix])) continue;
                double sum = 0;
                int m = 0;
                for (int dy = -1; dy <= 1; dy++)
                    for (int dx = -1; dx <= 1; dx++) {
                        long x = (long)ix + dx, y = (long)iy + dy;
                        if (x < 0 || y < 0 || x >= (long)g->nx || y >= (long)g->ny) continue;
                        double v = g->z[(size_t)y * g->nx + (size_t)x];
                        if (!isnan(v)) sum += v, m++;
                    }
                if (m) next[iy * g->nx + ix] = sum / m, filled++;
            }
        memcpy(g->z, next, total * sizeof(double));
    }
    free(next);
    return 1;
}

/* Surface height at p, bilinear between cell centres. */
static double grid_sample(const grid *g, const float *p)
{
    double fx = (p[0] - g->x0) / g->cell - 0.5, fy = (p[1] - g->y0) / g->cell - 0.5;
    double bx = floor(fx), by = floor(fy);
    double tx = fx - bx, ty = fy - by;
    long x0 = (long)bx, y0 = (long)by;
    long x1 = x0 + 1, y1 = y0 + 1;
    long mx = (long)g->nx - 1, my = (long)g->ny - 1;
    if (x0 < 0) x0 = 0, tx = 0;
    if (y0 < 0) y0 = 0, ty = 0;
    if (x1 > mx) x1 = mx;
    if (y1 > my) y1 = my;
    if (x0 > mx) x0 = mx;
    if (y0 > my) y0 = my;
    double z00 = g->z[y0 * g->nx + x0], z10 = g->z[y0 * g->nx + x1];
    double z01 = g->z[y1 * g->nx + x0], z11 = g->z[y1 * g->nx + x1];
    return (1 - ty) * ((1 - tx) * z00 + tx * z10) + ty * ((1 - tx) * z01 + tx * z11);
}

/* The lowest point of every occupied cell, run through PMF; the surviving
 * cells get their lowest point's height. Returns the ground cell count. */
static sy_code pmf_surface(const sy_cloud *c, const sy_preprocess_options *o, grid *g, size_t *n_cells, sy_error *err)
{
    size_t total = g->nx * g->ny;
    size_t *lowest = sy_calloc(total, sizeof(size_t), err, "ground grid");
    if (!lowest) return SY_EINTERNAL;
    for (size_t i = 0; i < total; i++) lowest[i] = SIZE_MAX;
    for (size_t i = 0; i < c->n; i++) {
        size_t k = grid_index(g, c->xyz + 3 * i);
        if (lowest[k] == SIZE_MAX || c->xyz[3 * i + 2] < c->xyz[3 * lowest[k] + 2]) lowest[k] = i;
    }
    size_t m = 0;
    for (size_t k = 0; k < total; k++) m += lowest[k] != SIZE_MAX;
    float *copy = sy_calloc(m, 3 * sizeof(float), err, "ground candidates");
    size_t *cell_of = sy_calloc(m, sizeof(size_t), err, "ground candidates");
    uint8_t *is_ground = sy_calloc(m, 1, err, "ground candidates");
    sy_code rc = SY_OK;
    if (!copy || !cell_of || !is_ground) rc = SY_EINTERNAL;
    char msg[256];
    if (rc == SY_OK) {
        size_t j = 0;
        for (size_t k = 0; k < total; k++)
            if (lowest[k] != SIZE_MAX) {
                memcpy(copy + 3 * j, c->xyz + 3 * lowest[k], 3 * sizeof(float));
                cell_of[j++] = k;
            }
        if (sy_pcl_ground_pmf(copy, m, o->ground_cell, o->ground_slope, o->ground_max_window, o->ground_threshold,
                              3.0 + o->ground_slope * o->ground_max_window, is_ground, msg, sizeof msg))
            rc = sy_fail(err, SY_EINTERNAL, "%s", msg);
    }
    *n_cells = 0;
    for (size_t j = 0; rc == SY_OK && j < m; j++)
        if (is_ground[j]) g->z[cell_of[j]] = copy[3 * j + 2], (*n_cells)++;
    free(lowest);
    free(copy);
    free(cell_of);
    free(is_ground);
    return rc;
}

/* hag[i] = height of point i above the surface in g. */
static void heights_above(const sy_cloud *c, const grid *g, double *hag)
{
    for (size_t i = 0; i < c->n; i++) hag[i] = c->xyz[3 * i + 2] - grid_sample(g, c->xyz + 3 * i);
}

/* Replaces each cell's height by the mean height of the ground points in it,
 * which centres the surface in the ground's noise band instead of under it. */
static sy_code refine_surface(const sy_cloud *c, grid *g, const double *hag, double threshold, sy_error *err)
{
    size_t total = g->nx * g->ny;
    double *sum = sy_calloc(total, sizeof(double), err, "ground grid");
    size_t *count = sy_calloc(total, sizeof(size_t), err, "ground grid");
    if (!sum || !count) {
        free(sum);
        free(count);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < c->n; i++)
        if (hag[i] < threshold) {
            size_t k = grid_index(g, c->xyz + 3 * i);
            sum[k] += c->xyz[3 * i + 2];
            count[k]++;
        }
    for (size_t k = 0; k < total; k++) g->z[k] = count[k] ? sum[k] / count[k] : NAN;
    free(sum);
    free(count);
    return grid_fill(g, err) < 0 ? SY_EINTERNAL : SY_OK;
}

sy_code sy_classify_ground(sy_cloud *c, const sy_preprocess_options *o, size_t *n_ground, sy_error *err)
{
    *n_ground = 0;
    double *hag = sy_cloud_add_attr(c, "height_above_ground", err);
    if (!hag) return SY_EINTERNAL;
    int had_classes = c->classification != NULL;
    if (sy_cloud_add_classification(c, err)) return SY_EINTERNAL;
    if (c->n == 0) return SY_OK;
    grid g = {0};
    size_t cells = 0;
    sy_code rc = grid_init(&g, c, o->ground_cell, err);
    if (rc == SY_OK) rc = pmf_surface(c, o, &g, &cells, err);
    int filled = 0;
    if (rc == SY_OK) {
        filled = grid_fill(&g, err);
        if (filled < 0) rc = SY_EINTERNAL;
    }
    if (rc == SY_OK && filled) {
        heights_above(c, &g, hag);
        rc = refine_surface(c, &g, hag, o->ground_threshold, err);
        if (rc == SY_OK) heights_above(c, &g, hag);
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
    free(g.z);
    return rc;
}

/* ----------------------------------------------------------------- normals */

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* Median x and median y of the cloud. */
static sy_code median_xy(const sy_cloud *c, float centre[2], sy_error *err)
{
    float *v = sy_calloc(c->n, sizeof(float), err, "normal orientation");
    if (!v) return SY_EINTERNAL;
    for (int k = 0; k < 2; k++) {
        for (size_t i = 0; i < c->n; i++) v[i] = c->xyz[3 * i + k];
        qsort(v, c->n, sizeof(float), cmp_float);
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
    char msg[256];
    if (sy_pcl_normals(c->xyz, c->n, k, sy_threads(), c->normal, normals_progress, &p, msg, sizeof msg))
        return sy_fail(err, SY_EINTERNAL, "%s", msg);
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
        snprintf(s->detail, sizeof s->detail, "detected %s (axis scores x %.3f y %.3f z %.3f, sign %+.4f)%s",
                 sy_up_name(up), ev.axis_score[0], ev.axis_score[1], ev.axis_score[2],
                 ev.sign_score[abs(up) - 1], up == SY_UP_Z ? "; kept" : "; rotated to +z");
    } else {
        snprintf(s->detail, sizeof s->detail, "given %s%s", sy_up_name(up), up == SY_UP_Z ? "; kept" : "; rotated to +z");
    }
    r->up_axis = up;
    sy_rotate_to_z_up(c, up);
    return SY_OK;
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

    s = step_begin(r, 3, "outliers", o->sor, c->n);
    if (rc == SY_OK && o->sor) {
        sy_progress_begin(&p, "outliers", c->n);
        rc = sy_remove_outliers(c, o->sor_k, o->sor_std, err);
        if (rc == SY_OK) sy_progress_end(&p);
        snprintf(s->detail, sizeof s->detail, "k %d, %g standard deviations", o->sor_k, o->sor_std);
    }
    step_end(s, c->n);

    s = step_begin(r, 4, "ground", o->ground, c->n);
    if (rc == SY_OK && o->ground) {
        sy_progress_begin(&p, "ground", c->n);
        rc = sy_classify_ground(c, o, &r->ground_points, err);
        if (rc == SY_OK) sy_progress_end(&p);
        if (rc == SY_OK && o->remove_ground) {
            uint8_t *keep = sy_calloc(c->n ? c->n : 1, 1, err, "ground mask");
            if (!keep) rc = SY_EINTERNAL;
            for (size_t i = 0; keep && i < c->n; i++) keep[i] = c->classification[i] != 2;
            if (keep) rc = sy_cloud_filter(c, keep, err);
            free(keep);
        }
        snprintf(s->detail, sizeof s->detail, "%zu ground points (class 2)%s, cell %g m, slope %g, window %g m",
                 r->ground_points, o->remove_ground ? " removed" : "", o->ground_cell, o->ground_slope,
                 o->ground_max_window);
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
