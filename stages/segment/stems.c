/* Stems: circles in the band around breast height. The band's points are
 * clustered on a fine 2-D grid; in each cluster circles are fitted one after
 * another (the skeleton stage's RANSAC + geometric least-squares fit) and
 * kept when they look like a trunk cross-section: a radius in range, inliers
 * spread around enough of the circle, and an empty inside (a clump of leaves
 * fits a circle too, but is full). This is the slice-and-fit detector of
 * most TLS inventory tools (e.g. Liang et al. 2012, "Automatic stem mapping
 * using single-scan terrestrial laser scanning", IEEE TGRS 50:661-670). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "segment_internal.h"
#include "stages/core/geometry.h"
#include "stages/core/voxel.h"
#include "stages/skeleton/skeleton.h"

#define PI 3.14159265358979323846
#define ARC_BINS 16
/* Bark is a thin sheet at the scale the normals are taken on: its spread
 * across the surface at most this fraction of the spread along it. */
#define BARK_THIN 0.5
/* Two stems closer than this bark to bark are one tree forking (metres). */
#define FORK_GAP 0.6


static uint32_t uf_find(uint32_t *p, uint32_t a)
{
    while (p[a] != a) a = p[a] = p[p[a]];
    return a;
}

static void uf_union(uint32_t *p, uint32_t a, uint32_t b)
{
    a = uf_find(p, a), b = uf_find(p, b);
    if (a == b) return;
    if (a < b) p[b] = a;
    else p[a] = b;
}

static int cmp_stem(const void *a, const void *b)
{
    const seg_stem *x = a, *y = b;
    if (x->x != y->x) return x->x < y->x ? -1 : 1;
    return (x->y > y->y) - (x->y < y->y);
}

static int cmp_by_inliers(const void *a, const void *b)
{
    const seg_stem *x = a, *y = b;
    if (x->inliers != y->inliers) return x->inliers > y->inliers ? -1 : 1;
    return cmp_stem(a, b);
}

typedef struct {
    seg_stem *v;
    size_t n, cap;
} stem_list;

static sy_code stem_push(stem_list *l, const seg_stem *s, sy_error *err)
{
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 64;
        seg_stem *v = realloc(l->v, cap * sizeof *v);
        if (!v) return sy_fail(err, SY_EINTERNAL, "segment: out of memory for stems");
        l->v = v;
        l->cap = cap;
    }
    l->v[l->n++] = *s;
    return SY_OK;
}

/* Share of a circle's inliers that look like bark: the local surface (the
 * principal axes of the cluster's points within `reach` in 3-D, x, y and
 * height) is a thin sheet whose normal, the least-spread axis, points away
 * from the circle's centre. A trunk's section is such a surface; the
 * outside of a column of hanging leaves is opaque too and fits a circle
 * just as well, but its leaves face every way and lie several deep. Up to
 * 64 inliers, evenly spread, are asked; those with fewer than 6 neighbours
 * cannot answer. Returns 1 when fewer than 8 can (a sparse scan: no
 * evidence either way). */
static double bark_share(const double *xy, const double *hz, size_t m, const double c[2], double r, double tol,
                             double reach)
{
    size_t inl = 0;
    for (size_t i = 0; i < m; i++) inl += fabs(hypot(xy[2 * i] - c[0], xy[2 * i + 1] - c[1]) - r) <= tol;
    size_t step = inl > 64 ? inl / 64 : 1, seen = 0, asked = 0, facing = 0;
    for (size_t i = 0; i < m; i++) {
        double rx = xy[2 * i] - c[0], ry = xy[2 * i + 1] - c[1], d = hypot(rx, ry);
        if (fabs(d - r) > tol || seen++ % step || d <= 0) continue;
        double mean[3] = {0, 0, 0}, cov[6] = {0};
        size_t k = 0;
        for (size_t j = 0; j < m; j++) {
            double q[3] = {xy[2 * j] - xy[2 * i], xy[2 * j + 1] - xy[2 * i + 1], hz[j] - hz[i]};
            if (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] > reach * reach) continue;
            for (int a = 0; a < 3; a++) mean[a] += q[a];
            cov[0] += q[0] * q[0], cov[1] += q[0] * q[1], cov[2] += q[0] * q[2];
            cov[3] += q[1] * q[1], cov[4] += q[1] * q[2], cov[5] += q[2] * q[2];
            k++;
        }
        if (k < 6) continue;
        for (int a = 0; a < 3; a++) mean[a] /= (double)k;
        cov[0] = cov[0] / (double)k - mean[0] * mean[0], cov[1] = cov[1] / (double)k - mean[0] * mean[1];
        cov[2] = cov[2] / (double)k - mean[0] * mean[2], cov[3] = cov[3] / (double)k - mean[1] * mean[1];
        cov[4] = cov[4] / (double)k - mean[1] * mean[2], cov[5] = cov[5] / (double)k - mean[2] * mean[2];
        double l[3], v[9];
        sy_sym3_eigen(cov, l, v);
        /* The normal: the eigenvector of the smallest eigenvalue (column 2). */
        asked++;
        facing += fabs(v[2] * rx + v[5] * ry) / d >= 0.8 && sqrt(l[2]) <= BARK_THIN * sqrt(l[1]);
    }
    return asked < 8 ? 1.0 : (double)facing / (double)asked;
}

/* Tries circles in one cluster's points (xy pairs, z-ground below) until
 * none fits; accepted ones are appended. */
static sy_code fit_cluster(double *xy, double *gz, double *hz, size_t m, double centre, const sy_segment_options *o,
                           uint64_t seed, stem_list *out, sy_error *err)
{
    const double tol = o->circle_tolerance;
    for (int attempt = 0; attempt < 4 && m >= 12; attempt++) {
        double c[2], r, rms;
        if (sy_fit_circle(xy, m, tol, seed + 7919ULL * (uint64_t)attempt, c, &r, &rms) != 0) break;
        size_t inl = 0, inside = 0;
        int bins[ARC_BINS] = {0};
        double gsum = 0, half[2][3] = {{0}};
        for (size_t i = 0; i < m; i++) {
            double dx = xy[2 * i] - c[0], dy = xy[2 * i + 1] - c[1], d = sqrt(dx * dx + dy * dy);
            if (fabs(d - r) <= tol) {
                inl++;
                gsum += gz[i];
                int up = hz[i] >= centre;
                half[up][0] += xy[2 * i], half[up][1] += xy[2 * i + 1], half[up][2] += 1;
                int b = (int)((atan2(dy, dx) + PI) / (2 * PI) * ARC_BINS);
                bins[b < 0 ? 0 : b >= ARC_BINS ? ARC_BINS - 1 : b] = 1;
            } else if (d < r - tol) {
                inside++;
            }
        }
        int arc = 0;
        for (int b = 0; b < ARC_BINS; b++) arc += bins[b];
        /* Upright: the ring's lower and upper halves share their centre (a
         * branch crossing the band slants, its section walks sideways). */
        double drift = INFINITY;
        if (half[0][2] >= 5 && half[1][2] >= 5)
            drift = hypot(half[1][0] / half[1][2] - half[0][0] / half[0][2], half[1][1] / half[1][2] - half[0][1] / half[0][2]);
        int ok = r >= o->stem_min_radius && r <= o->stem_max_radius && inl >= o->stem_min_points &&
                 (double)arc / ARC_BINS >= o->min_arc && (double)inside <= 0.25 * (double)inl &&
                 drift <= 0.05 + 0.5 * r;
        if (ok) ok = bark_share(xy, hz, m, c, r, tol, fmin(fmax(0.7 * r, 0.03), 0.08)) >= o->min_facing;
        if (ok) {
            seg_stem s = {.x = c[0], .y = c[1], .r = r, .inliers = inl, .band = 0, .dbh = 2 * r,
                          .ground_z = gsum / (double)inl, .arc = (double)arc / ARC_BINS};
            sy_code rc = stem_push(out, &s, err);
            if (rc) return rc;
        }
        /* Remove this circle's points (and what it encloses) and look again:
         * two trunks can share a cluster where their bark nearly touches. */
        size_t k = 0;
        double reach = ok ? r + 2 * tol : r + tol;
        for (size_t i = 0; i < m; i++) {
            double dx = xy[2 * i] - c[0], dy = xy[2 * i + 1] - c[1];
            int drop = ok ? dx * dx + dy * dy <= reach * reach : fabs(sqrt(dx * dx + dy * dy) - r) <= tol;
            if (drop) continue;
            xy[2 * k] = xy[2 * i], xy[2 * k + 1] = xy[2 * i + 1], gz[k] = gz[i], hz[k] = hz[i];
            k++;
        }
        if (k == m) break;
        m = k;
    }
    return SY_OK;
}

/* Circles in the band of thickness o->slice centred `centre` metres above
 * the ground, appended to list with the band's index. */
static sy_code detect_band(const seg_frame *f, const sy_segment_options *o, double centre, int band, stem_list *out,
                           size_t *candidates, sy_error *err)
{
    /* The band the circles are fitted in, and the taller one that tests
     * vertical continuity: a trunk fills most heights of its 5 cm columns,
     * leaves and twigs crossing the slice fill few. */
    double lo = centre - 0.5 * o->slice, hi = centre + 0.5 * o->slice, g = o->stem_cluster_gap;
    double vlo = fmax(centre - o->slice, 0.25), vhi = centre + o->slice;
    double col = fmax(4 * o->circle_tolerance, 0.04), bin_h = (vhi - vlo) / 16;
    if ((f->hi[0] - f->lo[0]) / fmin(g, col) > 2e9 || (f->hi[1] - f->lo[1]) / fmin(g, col) > 2e9)
        return sy_fail(err, SY_EINPUT, "segment: the plot is %.0f m wide, too wide for %.3g m stem clusters",
                       fmax(f->hi[0] - f->lo[0], f->hi[1] - f->lo[1]), fmin(g, col));
    size_t nb = 0;
    for (size_t i = 0; i < f->n; i++) nb += !f->ground[i] && f->hag[i] >= vlo && f->hag[i] <= vhi;
    if (nb == 0) return SY_OK;
    seg_map cols = {0};
    uint16_t *mask = sy_calloc(nb, sizeof *mask, err, "stem columns");
    sy_code crc = mask ? seg_map_init(&cols, nb, err) : SY_EINTERNAL;
    if (crc) {
        free(mask);
        return crc;
    }
    uint32_t n_cols = 0;
    for (size_t i = 0; i < f->n; i++) {
        if (f->ground[i] || f->hag[i] < vlo || f->hag[i] > vhi) continue;
        uint64_t key = ((uint64_t)(uint32_t)((f->xyz[3 * i] - f->lo[0]) / col) << 32) |
                       (uint32_t)((f->xyz[3 * i + 1] - f->lo[1]) / col);
        uint32_t c = seg_map_get(&cols, key);
        if (c == UINT32_MAX) seg_map_put(&cols, key, c = n_cols++);
        int b = (int)((f->hag[i] - vlo) / bin_h);
        mask[c] |= (uint16_t)(1u << (b < 0 ? 0 : b > 15 ? 15 : b));
    }
    size_t m = 0;
    sy_voxel_entry *pts = sy_calloc(nb, sizeof *pts, err, "stem slice");
    if (!pts) {
        free(mask);
        seg_map_free(&cols);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < f->n; i++) {
        if (f->ground[i] || f->hag[i] < lo || f->hag[i] > hi) continue;
        uint64_t key = ((uint64_t)(uint32_t)((f->xyz[3 * i] - f->lo[0]) / col) << 32) |
                       (uint32_t)((f->xyz[3 * i + 1] - f->lo[1]) / col);
        uint32_t c = seg_map_get(&cols, key);
        int filled = 0;
        for (int b = 0; b < 16; b++) filled += (mask[c] >> b) & 1;
        if (filled < 6) continue;
        uint32_t ix = (uint32_t)((f->xyz[3 * i] - f->lo[0]) / g), iy = (uint32_t)((f->xyz[3 * i + 1] - f->lo[1]) / g);
        pts[m].key = ((uint64_t)ix << 32) | iy;
        pts[m++].index = i;
    }
    free(mask);
    seg_map_free(&cols);
    if (m == 0) {
        free(pts);
        return SY_OK;
    }
    sy_voxel_entries_sort(pts, m); /* by cell, then point */
    /* Occupied cells and their connected components (8-neighbourhood). */
    size_t nc = 0;
    uint32_t *cell_start = sy_calloc(m + 1, sizeof *cell_start, err, "stem cells");
    uint32_t *parent = sy_calloc(m, sizeof *parent, err, "stem cells");
    seg_map map = {0};
    sy_code rc = cell_start && parent ? seg_map_init(&map, m, err) : SY_EINTERNAL;
    if (rc == SY_OK) {
        for (size_t i = 0; i < m; i++)
            if (i == 0 || pts[i].key != pts[i - 1].key) {
                cell_start[nc] = (uint32_t)i;
                seg_map_put(&map, pts[i].key, (uint32_t)nc);
                parent[nc] = (uint32_t)nc;
                nc++;
            }
        cell_start[nc] = (uint32_t)m;
        for (size_t c = 0; c < nc; c++) {
            uint64_t key = pts[cell_start[c]].key;
            uint32_t ix = (uint32_t)(key >> 32), iy = (uint32_t)key;
            for (int dx = -1; dx <= 1; dx++)
                for (int dy = -1; dy <= 1; dy++) {
                    if ((dx < 0 && ix == 0) || (dy < 0 && iy == 0) || (dx == 0 && dy == 0)) continue;
                    uint32_t nb = seg_map_get(&map, ((uint64_t)(ix + dx) << 32) | (uint32_t)(iy + dy));
                    if (nb != UINT32_MAX) uf_union(parent, (uint32_t)c, nb);
                }
        }
    }
    /* Points grouped by component (components in order of their first cell). */
    uint32_t *order = NULL, *comp_of = NULL;
    double *xy = NULL, *gz = NULL, *hz = NULL;
    stem_list list = *out;
    size_t first = list.n;
    if (rc == SY_OK) {
        order = sy_calloc(m, sizeof *order, err, "stem clusters");
        comp_of = sy_calloc(nc, sizeof *comp_of, err, "stem clusters");
        xy = sy_calloc(2 * m, sizeof *xy, err, "stem clusters");
        gz = sy_calloc(m, sizeof *gz, err, "stem clusters");
        hz = sy_calloc(m, sizeof *hz, err, "stem clusters");
        if (!order || !comp_of || !xy || !gz || !hz) rc = SY_EINTERNAL;
    }
    if (rc == SY_OK) {
        for (size_t c = 0; c < nc; c++) comp_of[c] = uf_find(parent, (uint32_t)c);
        /* Walk components by root: gather each root's cells' points. */
        uint32_t *count = sy_calloc(nc + 1, sizeof *count, err, "stem clusters");
        if (!count) rc = SY_EINTERNAL;
        else {
            for (size_t c = 0; c < nc; c++) count[comp_of[c] + 1] += cell_start[c + 1] - cell_start[c];
            for (size_t c = 0; c < nc; c++) count[c + 1] += count[c];
            uint32_t *fill = sy_calloc(nc + 1, sizeof *fill, err, "stem clusters");
            if (!fill) rc = SY_EINTERNAL;
            else {
                memcpy(fill, count, (nc + 1) * sizeof *fill);
                for (size_t c = 0; c < nc; c++)
                    for (uint32_t j = cell_start[c]; j < cell_start[c + 1]; j++) order[fill[comp_of[c]]++] = (uint32_t)pts[j].index;
                free(fill);
            }
            for (size_t c = 0; c < nc && rc == SY_OK; c++) {
                size_t begin = count[c], end = count[c + 1], k = end - begin;
                if (k < 12) continue;
                (*candidates)++;
                for (size_t j = 0; j < k; j++) {
                    uint32_t p = order[begin + j];
                    xy[2 * j] = f->xyz[3 * p];
                    xy[2 * j + 1] = f->xyz[3 * p + 1];
                    gz[j] = f->xyz[3 * p + 2] - f->hag[p];
                    hz[j] = f->hag[p];
                }
                rc = fit_cluster(xy, gz, hz, k, centre, o, o->seed * 1000003ULL + 2 * c + (uint64_t)band, &list, err);
            }
            free(count);
        }
    }
    free(pts), free(cell_start), free(parent), free(order), free(comp_of), free(xy), free(gz), free(hz);
    seg_map_free(&map);
    for (size_t i = first; i < list.n; i++) list.v[i].band = band, list.v[i].dbh = 2 * list.v[i].r;
    *out = list; /* the caller frees it, also on failure */
    return rc;
}

/* The ground points and those under the stem bands on a 0.5 m grid, to ask whether a circle
 * stands on the ground: a trunk's surface continues down to its base, a
 * branch hanging through the band or a clump of leaves does not. */
typedef struct {
    seg_map map;
    sy_voxel_entry *pts; /* sorted by cell */
    uint32_t *start;     /* per cell index: first point, cells in map order */
    size_t n_cells;
    double cell;
} low_index;

static sy_code low_index_build(const seg_frame *f, double top, low_index *ix, sy_error *err)
{
    memset(ix, 0, sizeof *ix);
    ix->cell = 0.5;
    size_t m = 0;
    for (size_t i = 0; i < f->n; i++) m += f->ground[i] || f->hag[i] < top;
    ix->pts = sy_calloc(m ? m : 1, sizeof *ix->pts, err, "stem bases");
    ix->start = sy_calloc(m + 1, sizeof *ix->start, err, "stem bases");
    sy_code rc = ix->pts && ix->start ? seg_map_init(&ix->map, m, err) : SY_EINTERNAL;
    if (rc) return rc;
    m = 0;
    for (size_t i = 0; i < f->n; i++) {
        if (!f->ground[i] && f->hag[i] >= top) continue;
        uint32_t cx = (uint32_t)((f->xyz[3 * i] - f->lo[0]) / ix->cell), cy = (uint32_t)((f->xyz[3 * i + 1] - f->lo[1]) / ix->cell);
        ix->pts[m].key = ((uint64_t)cx << 32) | cy;
        ix->pts[m++].index = i;
    }
    sy_voxel_entries_sort(ix->pts, m); /* by cell, then point */
    for (size_t i = 0; i < m; i++)
        if (i == 0 || ix->pts[i].key != ix->pts[i - 1].key) {
            ix->start[ix->n_cells] = (uint32_t)i;
            seg_map_put(&ix->map, ix->pts[i].key, (uint32_t)ix->n_cells++);
        }
    ix->start[ix->n_cells] = (uint32_t)m;
    return SY_OK;
}

static void low_index_free(low_index *ix)
{
    seg_map_free(&ix->map);
    free(ix->pts);
    free(ix->start);
}

/* The points of the cells that the square of half-side reach around (x, y)
 * touches, cell by cell (x outer, y inner), each cell's in index order. */
typedef struct {
    const low_index *ix;
    long x1, y0, y1, cx, cy;
    uint32_t j, end;
} square_walk;

static void square_begin(square_walk *w, const seg_frame *f, const low_index *ix, double x, double y, double reach)
{
    long x0 = (long)floor((x - reach - f->lo[0]) / ix->cell), y0 = (long)floor((y - reach - f->lo[1]) / ix->cell);
    w->ix = ix;
    w->x1 = (long)floor((x + reach - f->lo[0]) / ix->cell);
    w->y1 = (long)floor((y + reach - f->lo[1]) / ix->cell);
    w->y0 = y0 < 0 ? 0 : y0;
    w->cx = x0 < 0 ? 0 : x0;
    w->cy = w->y0 - 1; /* square_next steps to the first cell */
    if (w->y0 > w->y1) w->cx = w->x1 + 1; /* no row: nothing to walk */
    w->j = w->end = 0;
}

/* The next point of the walk into *p; 0 when it is over. */
static int square_next(square_walk *w, uint32_t *p)
{
    while (w->j == w->end) {
        if (++w->cy > w->y1) w->cx++, w->cy = w->y0;
        if (w->cx > w->x1) return 0;
        uint32_t c = seg_map_get(&w->ix->map, ((uint64_t)w->cx << 32) | (uint64_t)w->cy);
        if (c == UINT32_MAX) continue;
        w->j = w->ix->start[c], w->end = w->ix->start[c + 1];
    }
    *p = (uint32_t)w->ix->pts[w->j++].index;
    return 1;
}

/* Fraction of the 10 cm height bins in [zlo, zhi) holding a point of the
 * disc of radius 1.5 r + 2 tolerances around (x, y). */
static double base_support(const seg_frame *f, const low_index *ix, double x, double y, double r, double tol, double zlo,
                           double zhi)
{
    int nbins = (int)ceil((zhi - zlo) / 0.1 - 1e-9);
    if (nbins <= 0) return 1;
    if (nbins > 64) nbins = 64;
    uint64_t seen = 0;
    double reach = 1.5 * r + 2 * tol; /* trunks flare towards their base */
    square_walk w;
    square_begin(&w, f, ix, x, y, reach);
    for (uint32_t p; square_next(&w, &p);) {
        double h = f->hag[p];
        if (f->ground[p] || h < zlo || h >= zhi) continue;
        double dx = f->xyz[3 * p] - x, dy = f->xyz[3 * p + 1] - y;
        if (dx * dx + dy * dy > reach * reach) continue;
        int b = (int)((h - zlo) / 0.1);
        if (b >= 0 && b < nbins) seen |= 1ULL << b;
    }
    int k = 0;
    for (int b = 0; b < nbins; b++) k += (int)((seen >> b) & 1);
    return (double)k / nbins;
}

/* Ground returns within radius of (x, y): where the ground filter saw none,
 * its surface is extrapolated and heights above it mean little. */
static size_t ground_near(const seg_frame *f, const low_index *ix, double x, double y, double radius)
{
    size_t k = 0;
    square_walk w;
    square_begin(&w, f, ix, x, y, radius);
    for (uint32_t p; square_next(&w, &p);) {
        double dx = f->xyz[3 * p] - x, dy = f->xyz[3 * p + 1] - y;
        k += f->ground[p] && dx * dx + dy * dy <= radius * radius;
    }
    return k;
}

sy_code seg_find_stems(const seg_frame *f, const sy_segment_options *o, seg_stem **stems, size_t *n_stems,
                       size_t *candidates, sy_error *err)
{
    *stems = NULL;
    *n_stems = 0;
    *candidates = 0;
    /* Two bands: breast height, and one slice lower, where trees that fork
     * or carry foliage at breast height (oaks, open-grown crowns) still show
     * one clear trunk. */
    stem_list list = {0};
    double low = o->breast_height - o->slice;
    sy_code rc = SY_OK;
    if (low - 0.5 * o->slice >= 0.2) rc = detect_band(f, o, low, 0, &list, candidates, err);
    if (rc == SY_OK) rc = detect_band(f, o, o->breast_height, 1, &list, candidates, err);
    /* A stem stands on the ground: its circle's disc holds points at most
     * heights between the ground filter's band and the circle's own band,
     * and ground returns were seen around it (under a canopy that hides the
     * ground the surface is a guess, and so is every height above it). */
    low_index ix;
    if (rc == SY_OK) rc = low_index_build(f, o->breast_height, &ix, err);
    if (rc) {
        free(list.v);
        return rc;
    }
    size_t grounded = 0;
    double zlo = o->ground_threshold + 0.05;
    for (size_t i = 0; i < list.n; i++) {
        double top = (list.v[i].band ? o->breast_height : low) - 0.5 * o->slice;
        if (base_support(f, &ix, list.v[i].x, list.v[i].y, list.v[i].r, o->circle_tolerance, zlo, top) >= 0.5 &&
            ground_near(f, &ix, list.v[i].x, list.v[i].y, list.v[i].r + 1.0) >= 10)
            list.v[grounded++] = list.v[i];
    }
    list.n = grounded;
    low_index_free(&ix);
    /* One stem per trunk: within a band the best-supported circle wins where
     * two overlap; a breast-height circle over a lower one is the same trunk
     * (it lends its diameter, and forks above the lower circle fold into it). */
    if (list.n) qsort(list.v, list.n, sizeof *list.v, cmp_by_inliers);
    seg_stem *out = sy_calloc(list.n ? list.n : 1, sizeof *out, err, "stems");
    if (!out) {
        free(list.v);
        return SY_EINTERNAL;
    }
    size_t kept = 0;
    for (int band = 0; band < 2; band++)
        for (size_t i = 0; i < list.n; i++) {
            const seg_stem *c = &list.v[i];
            if (c->band != band) continue;
            int dup = 0;
            for (size_t j = 0; j < kept && !dup; j++) {
                double dx = c->x - out[j].x, dy = c->y - out[j].y, d = sqrt(dx * dx + dy * dy);
                if (out[j].band == band) dup = d < c->r + out[j].r + FORK_GAP;
                else if (d < out[j].r + c->r + FORK_GAP) {
                    dup = 1;
                    /* Confirmed when the circles overlap (a fork's stems stand on the trunk). */
                    if (d < out[j].r + c->r) out[j].both_bands = 1;
                    /* The trunk itself (not a fork) when the circles agree. */
                    if (d < 0.5 * out[j].r && c->r < 1.25 * out[j].r) out[j].dbh = 2 * c->r;
                }
            }
            if (!dup) out[kept++] = *c;
        }
    /* A trunk shows in both bands. A circle in one only (a trunk forking or
     * leafy at breast height, or a section of something that is no trunk:
     * a hanging limb, a column of leaves) stays a stem when it is seen well,
     * around at least o->single_band_arc of it. */
    size_t confirmed = 0;
    for (size_t i = 0; i < kept; i++)
        if (out[i].both_bands || out[i].arc >= o->single_band_arc) out[confirmed++] = out[i];
    kept = confirmed;
    free(list.v);
    list.v = out;
    if (kept) qsort(list.v, kept, sizeof *list.v, cmp_stem);
    *stems = list.v;
    *n_stems = kept;
    return SY_OK;
}
