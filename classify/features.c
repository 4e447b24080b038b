/* Tree features for species classification (Pirk 2013 §3.5.1: "over 200
 * features" from the points and from a first reconstruction; the families the
 * thesis found most effective are trunk and crown dimensions and their ratios,
 * the distribution of normal directions, the vertical density distribution, the
 * inhomogeneity of the point set and the number of main stems). The concrete
 * list is ours and documented in docs/classify.md.
 *
 * Invariance: every feature is measured relative to the trunk base and axis
 * (position) and from radial distances, eigenvalues or angles to the vertical
 * (heading). Density: the cloud is first reduced to voxel centroids, at most
 * max_points of them, so a dense terrestrial scan and a sparser mobile scan of
 * the same tree give similar numbers; airborne scans stay sparser than the voxel
 * and are learnt as such. Eigen-features (linearity, planarity, scattering) follow
 * Demantké et al. 2011, "Dimensionality based scale selection in 3D lidar point
 * clouds", at fixed radii. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "classify/classify.h"
#include "stages/clusters/clusters.h"
#include "stages/core/geometry.h"
#include "stages/core/grid.h"
#include "stages/core/progress.h"
#include "stages/core/sort.h"
#include "stages/core/voxel.h"
#include "stages/skeleton/skeleton.h"

#define N_ELEV 18     /* normal-elevation bins over 0..90 degrees */
#define N_QUART 4     /* height slabs (quarters of the height) */
#define N_SCALES 3
#define N_VPROF 32
#define N_RPROF 16
#define N_ENV 10
#define N_ANG 9
#define N_LEN 8
#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif
static const double scale_radius[N_SCALES] = {0.15, 0.3, 0.6};

/* ------------------------------------------------------------ the names */

enum {
    F_HEIGHT,
    F_TRUNK_WIDTH,
    F_TRUNK_WIDTH_REL,
    F_CROWN_BASE_M,
    F_CROWN_BASE_REL,
    F_CROWN_HEIGHT_M,
    F_CROWN_WIDTH_M,
    F_CROWN_WIDTH_REL,
    F_CROWN_W_OVER_CH,
    F_PCA_MAJOR_M,
    F_PCA_MINOR_M,
    F_PCA_MINOR_OVER_MAJOR,
    F_WIDEST_AT_REL,
    F_H_MEAN,
    F_H_STD,
    F_H_SKEW,
    F_H_KURT,
    F_R_MEAN_REL,
    F_R_STD_REL,
    F_HULL_VOLUME_M3,
    F_HULL_VOLUME_REL,    /* / H^3 */
    F_HULL_FILL_CYLINDER, /* / (pi (W/2)^2 crown height) */
    F_VOXEL_FILL_HULL,    /* occupied 0.25 m voxels / hull volume */
    F_HULL_Q0,            /* hull volume share per height quarter (4) */
    F_CROWN_ASYM = F_HULL_Q0 + N_QUART,
    F_NORMAL_GLOBAL,
    F_NORMAL_SLAB = F_NORMAL_GLOBAL + N_ELEV,
    F_EIGEN = F_NORMAL_SLAB + N_ELEV * N_QUART,        /* scale x (global + 4 slabs) x (L, P, S) */
    F_VPROF = F_EIGEN + N_SCALES * (1 + N_QUART) * 3,
    F_RPROF = F_VPROF + N_VPROF,
    F_ENV_R = F_RPROF + N_RPROF, /* p90 radius / H per tenth of the height */
    F_ENV_AREA = F_ENV_R + N_ENV, /* slab hull area / the largest */
    F_INHOM_VOX = F_ENV_AREA + N_ENV, /* CV of points per 0.25 m voxel: global + 4 slabs */
    F_INHOM_LOCAL = F_INHOM_VOX + 1 + N_QUART, /* CV of the neighbour count at 0.3 m: global + 4 */
    F_MAIN_STEMS = F_INHOM_LOCAL + 1 + N_QUART,
    F_CROSS_Q1,  /* skeleton edges crossing 0.25 H, 0.5 H, 0.75 H */
    F_CROSS_Q2,
    F_CROSS_Q3,
    F_SK_BRANCHES,
    F_SK_LENGTH_REL,
    F_SK_MAX_ORDER,
    F_SK_MEAN_BRANCH_LEN_REL,
    F_SK_TRUNK_SHARE,
    F_SK_TRUNK_STRAIGHT,
    F_SK_TRUNK_LEAN,
    F_SK_BRANCHES_PER_M,
    F_SK_DBH_M,
    F_SK_ANGLE_O1,
    F_SK_ANGLE_O2,
    F_SK_ORDER_SHARE,                       /* length share of order 0, 1, 2, 3+ */
    F_SK_ANGLE_HIST = F_SK_ORDER_SHARE + 4, /* branching angle to the parent */
    F_SK_ELEV_HIST = F_SK_ANGLE_HIST + N_ANG, /* branch chord elevation */
    F_SK_LEN_HIST = F_SK_ELEV_HIST + N_ANG,   /* branch length / H, log bins */
    F_COUNT = F_SK_LEN_HIST + N_LEN
};

static const char *const scalar_names[] = {
    "height_m", "trunk_width_m", "trunk_width_rel", "crown_base_m", "crown_base_rel", "crown_height_m",
    "crown_width_m", "crown_width_rel", "crown_width_over_crown_height", "crown_pca_major_m", "crown_pca_minor_m",
    "crown_pca_minor_over_major", "widest_at_rel", "height_mean_rel", "height_std_rel", "height_skewness",
    "height_kurtosis", "radius_mean_rel", "radius_std_rel", "hull_volume_m3", "hull_volume_rel",
    "hull_fill_of_cylinder", "voxel_fill_of_hull"};

/* Every feature's name, from constants only (no table kept between calls). */
static void build_names(char g_names[F_COUNT][SY_FEATURE_NAME_MAX])
{
    for (int i = 0; i < F_COUNT; i++) snprintf(g_names[i], sizeof g_names[i], "f%d", i);
    for (int i = 0; i < (int)(sizeof scalar_names / sizeof *scalar_names); i++)
        snprintf(g_names[i], sizeof g_names[i], "%s", scalar_names[i]);
    for (int q = 0; q < N_QUART; q++) snprintf(g_names[F_HULL_Q0 + q], 40, "hull_share_q%d", q);
    snprintf(g_names[F_CROWN_ASYM], 40, "crown_asymmetry");
    for (int b = 0; b < N_ELEV; b++) snprintf(g_names[F_NORMAL_GLOBAL + b], 40, "normal_elev_b%02d", b);
    for (int q = 0; q < N_QUART; q++)
        for (int b = 0; b < N_ELEV; b++)
            snprintf(g_names[F_NORMAL_SLAB + q * N_ELEV + b], 40, "normal_elev_q%d_b%02d", q, b);
    static const char lps[3] = {'L', 'P', 'S'};
    for (int s = 0; s < N_SCALES; s++)
        for (int q = 0; q <= N_QUART; q++)
            for (int e = 0; e < 3; e++) {
                int i = F_EIGEN + (s * (1 + N_QUART) + q) * 3 + e;
                if (q == 0) snprintf(g_names[i], 40, "eigen_%c_r%d", lps[e], (int)lround(scale_radius[s] * 100));
                else snprintf(g_names[i], 40, "eigen_%c_r%d_q%d", lps[e], (int)lround(scale_radius[s] * 100), q - 1);
            }
    for (int b = 0; b < N_VPROF; b++) snprintf(g_names[F_VPROF + b], 40, "vertical_density_b%02d", b);
    for (int b = 0; b < N_RPROF; b++) snprintf(g_names[F_RPROF + b], 40, "radial_density_b%02d", b);
    for (int b = 0; b < N_ENV; b++) snprintf(g_names[F_ENV_R + b], 40, "envelope_radius_rel_t%d", b);
    for (int b = 0; b < N_ENV; b++) snprintf(g_names[F_ENV_AREA + b], 40, "envelope_area_t%d", b);
    snprintf(g_names[F_INHOM_VOX], 40, "inhomogeneity_voxel");
    snprintf(g_names[F_INHOM_LOCAL], 40, "inhomogeneity_local");
    for (int q = 0; q < N_QUART; q++) {
        snprintf(g_names[F_INHOM_VOX + 1 + q], 40, "inhomogeneity_voxel_q%d", q);
        snprintf(g_names[F_INHOM_LOCAL + 1 + q], 40, "inhomogeneity_local_q%d", q);
    }
    static const char *const sk[] = {"main_stems", "crossings_q1", "crossings_q2", "crossings_q3",
                                     "skeleton_branches", "skeleton_length_rel", "skeleton_max_order",
                                     "branch_length_mean_rel", "trunk_length_share", "trunk_straightness",
                                     "trunk_lean_deg", "branches_per_trunk_m", "skeleton_dbh_m",
                                     "branch_angle_o1_deg", "branch_angle_o2_deg"};
    for (int i = 0; i < (int)(sizeof sk / sizeof *sk); i++) snprintf(g_names[F_MAIN_STEMS + i], 40, "%s", sk[i]);
    for (int o = 0; o < 4; o++) snprintf(g_names[F_SK_ORDER_SHARE + o], 40, "length_share_order%d", o);
    for (int b = 0; b < N_ANG; b++) snprintf(g_names[F_SK_ANGLE_HIST + b], 40, "branch_angle_b%d", b);
    for (int b = 0; b < N_ANG; b++) snprintf(g_names[F_SK_ELEV_HIST + b], 40, "branch_elevation_b%d", b);
    for (int b = 0; b < N_LEN; b++) snprintf(g_names[F_SK_LEN_HIST + b], 40, "branch_length_b%d", b);
}

size_t sy_feature_count(void) { return F_COUNT; }

const char *sy_feature_name(size_t i, char name[SY_FEATURE_NAME_MAX])
{
    if (i >= F_COUNT) return NULL;
    char (*all)[SY_FEATURE_NAME_MAX] = malloc(F_COUNT * sizeof *all);
    if (!all) return NULL;
    build_names(all);
    memcpy(name, all[i], SY_FEATURE_NAME_MAX);
    free(all);
    return name;
}

sy_features_options sy_features_options_default(void)
{
    sy_features_options o = {0.04, 8000, 1, 20000};
    return o;
}

sy_code sy_features_options_check(const sy_features_options *o, sy_error *err)
{
    if (!(o->voxel > 0 && o->voxel < 10)) return sy_fail(err, SY_EUSAGE, "features: voxel must be in (0, 10) m");
    if (o->max_points < 256 || o->max_points > 2000000)
        return sy_fail(err, SY_EUSAGE, "features: max_points must be in [256, 2000000]");
    if (o->skeleton && (o->skeleton_points < 256 || o->skeleton_points > 2000000))
        return sy_fail(err, SY_EUSAGE, "features: skeleton_points must be in [256, 2000000]");
    return SY_OK;
}

/* ------------------------------------------------------------ helpers */

/* q-quantile of v (n > 0) by sorting a scratch copy. */
static double quantile(const float *v, size_t n, double q, float *scratch)
{
    if (n == 0) return NAN;
    memcpy(scratch, v, n * sizeof *v);
    qsort(scratch, n, sizeof *scratch, sy_cmp_float);
    double pos = q * (double)(n - 1);
    size_t i = (size_t)pos;
    if (i + 1 >= n) return scratch[n - 1];
    double t = pos - (double)i;
    return scratch[i] * (1 - t) + scratch[i + 1] * t;
}

/* Voxel centroids of xyz at voxel size v; returns the count written to out (3m floats). */
static size_t voxel_centroids(const float *xyz, size_t n, const float lo[3], double v, sy_voxel_entry *tmp,
                              float *out)
{
    sy_voxel_sort(xyz, n, lo, v, tmp);
    size_t m = 0;
    for (size_t i = 0; i < n;) {
        size_t j = i;
        double s[3] = {0, 0, 0};
        while (j < n && tmp[j].key == tmp[i].key) {
            for (int a = 0; a < 3; a++) s[a] += xyz[3 * tmp[j].index + a];
            j++;
        }
        for (int a = 0; a < 3; a++) out[3 * m + a] = (float)(s[a] / (double)(j - i));
        m++;
        i = j;
    }
    return m;
}

/* Voxel centroids at *voxel or coarser, at most max_points of them, from
 * `first`, the m0 centroids of the input at *voxel (computed once and shared
 * by the statistics' and the skeleton's samples). A crown sampled like a
 * surface loses points as voxel^-2, so each retry jumps by the square root of
 * the excess (plus 3%): two or three passes, not dozens. Coarser passes run
 * over the first pass's centroids: far fewer points. */
static size_t subsample(const float *first, size_t m0, const float lo[3], size_t max_points, sy_voxel_entry *tmp,
                        float *out, double *voxel)
{
    size_t m = m0;
    memcpy(out, first, 3 * m0 * sizeof *out);
    for (int it = 0; it < 40 && m > max_points; it++) {
        *voxel *= fmax(1.05, 1.03 * sqrt((double)m / (double)max_points));
        m = voxel_centroids(first, m0, lo, *voxel, tmp, out);
    }
    return m;
}

/* The neighbourhood grid (stages/core/grid.h) with cells of edge cell, grown
 * by half until the extent spans at most 4 M cells: the cell order is the
 * order local_cov sums in, so the edge is kept as it was for a dense grid. */
static sy_code grid_build(sy_grid *g, const float *xyz, size_t n, const float lo[3], const float hi[3], double cell,
                          sy_error *err)
{
    for (;;) {
        size_t cells = 1;
        for (int a = 0; a < 3; a++) cells *= (size_t)(floor((hi[a] - lo[a]) / cell) + 1);
        if (cells <= (size_t)4 << 20) break;
        cell *= 1.5; /* a query radius below the cell only costs time, never answers */
    }
    return sy_grid_build(g, xyz, n, cell, err);
}

/* Covariance of the points within r of point i; returns the neighbour count. */
static size_t local_cov(const sy_grid *g, const float *xyz, size_t i, double r, double cov[6])
{
    const float *p = xyz + 3 * i;
    int32_t c[3];
    sy_grid_cell_of(g, p, c);
    int reach = (int)ceil(r / g->h);
    double s[3] = {0, 0, 0}, ss[6] = {0, 0, 0, 0, 0, 0}, r2 = r * r;
    size_t m = 0;
    for (int32_t z = c[2] - reach; z <= c[2] + reach; z++) {
        for (int32_t y = c[1] - reach; y <= c[1] + reach; y++) {
            for (int32_t x = c[0] - reach; x <= c[0] + reach; x++) {
                long cell = sy_grid_find(g, x, y, z);
                if (cell < 0) continue;
                for (size_t k = g->cell_start[cell]; k < g->cell_start[cell + 1]; k++) {
                    const float *q = g->pts + 3 * k;
                    double d[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
                    if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] > r2) continue;
                    for (int a = 0; a < 3; a++) s[a] += d[a];
                    ss[0] += d[0] * d[0], ss[1] += d[0] * d[1], ss[2] += d[0] * d[2];
                    ss[3] += d[1] * d[1], ss[4] += d[1] * d[2], ss[5] += d[2] * d[2];
                    m++;
                }
            }
        }
    }
    if (m == 0) return 0;
    double inv = 1.0 / (double)m;
    cov[0] = ss[0] * inv - s[0] * s[0] * inv * inv;
    cov[1] = ss[1] * inv - s[0] * s[1] * inv * inv;
    cov[2] = ss[2] * inv - s[0] * s[2] * inv * inv;
    cov[3] = ss[3] * inv - s[1] * s[1] * inv * inv;
    cov[4] = ss[4] * inv - s[1] * s[2] * inv * inv;
    cov[5] = ss[5] * inv - s[2] * s[2] * inv * inv;
    return m;
}

/* Area of the 2-D convex hull of pts (2m doubles; reordered) by Andrew's monotone chain. */
static int cmp_xy(const void *a, const void *b)
{
    const double *p = a, *q = b;
    if (p[0] != q[0]) return p[0] < q[0] ? -1 : 1;
    return (p[1] > q[1]) - (p[1] < q[1]);
}

static double cross2(const double *o, const double *a, const double *b)
{
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
}

static double hull_area(double *pts, size_t m, double *hull /* 2(m+1) */)
{
    if (m < 3) return 0;
    qsort(pts, m, 2 * sizeof *pts, cmp_xy);
    size_t k = 0;
    for (size_t i = 0; i < m; i++) {
        while (k >= 2 && cross2(hull + 2 * (k - 2), hull + 2 * (k - 1), pts + 2 * i) <= 0) k--;
        hull[2 * k] = pts[2 * i], hull[2 * k + 1] = pts[2 * i + 1], k++;
    }
    for (size_t i = m - 1, t = k + 1; i-- > 0;) {
        while (k >= t && cross2(hull + 2 * (k - 2), hull + 2 * (k - 1), pts + 2 * i) <= 0) k--;
        hull[2 * k] = pts[2 * i], hull[2 * k + 1] = pts[2 * i + 1], k++;
    }
    double a = 0;
    for (size_t i = 0; i + 1 < k; i++) a += hull[2 * i] * hull[2 * i + 3] - hull[2 * i + 2] * hull[2 * i + 1];
    return fabs(a) / 2;
}

static void normalise(float *h, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++) s += h[i];
    for (int i = 0; i < n; i++) h[i] = s > 0 ? (float)(h[i] / s) : 0;
}

static double cv_of(const double *v, size_t n)
{
    if (n < 2) return -1;
    double s = 0, ss = 0;
    for (size_t i = 0; i < n; i++) s += v[i], ss += v[i] * v[i];
    double m = s / (double)n, var = ss / (double)n - m * m;
    return m > 0 ? sqrt(var > 0 ? var : 0) / m : -1;
}

static int quarter_of(double h)
{
    int q = (int)(h * N_QUART);
    return q < 0 ? 0 : q >= N_QUART ? N_QUART - 1 : q;
}

/* ------------------------------------------------------------ skeleton part */

static void skeleton_features(const float *P, size_t m, double z0, double H, double trunk_r, double crown_base,
                              float *f, sy_error *err)
{
    for (int i = F_MAIN_STEMS; i < F_COUNT; i++) f[i] = -1;
    sy_cloud c;
    memset(&c, 0, sizeof c);
    c.n = m;
    c.xyz = (float *)P; /* read only: the stage takes a const cloud */
    sy_skeleton_options so = sy_skeleton_options_default();
    /* The features of SY_FEATURES_VERSION 2, on which the shipped model was
     * trained, come from skeletons with their hairpins left as they are and
     * occluded stems rebuilt to the crown's top, crowns regrown at a trunk
     * meander of 1.8 above a base measured from the root, and no stem drawn
     * for a scan that shows none. */
    so.unfold_hairpins = 0;
    so.fork_domed_stems = 0;
    so.crown_meander = 1.8;
    so.crown_base_above_root = 0;
    so.unseen_stems = 0;
    sy_cut_options co = sy_cut_options_default();
    co.clusters = 0; /* the skeleton alone, every point on it */
    sy_full_skeleton full;
    sy_skeleton s;
    sy_skeleton_report r;
    sy_error e2 = {0};
    if (sy_reconstruct_skeleton(&c, &so, &full, &r, &e2)) {
        (void)err; /* a tree too odd for a skeleton still has its point features */
        return;
    }
    sy_code cut = sy_clusters_extract(&full, c.xyz, &co, &s, NULL, NULL, &e2);
    sy_full_skeleton_free(&full);
    if (cut) return;
    size_t n = s.n;
    int32_t nb = sy_skeleton_branch_count(&s);
    double total = 0, by_order[4] = {0, 0, 0, 0};
    int max_order = 0;
    int crossings[3] = {0, 0, 0};
    for (size_t i = 0; i < n; i++) {
        if (s.order[i] > max_order) max_order = s.order[i];
        int p = s.parent[i];
        if (p < 0) continue;
        const float *a = s.pos + 3 * p, *b = s.pos + 3 * i;
        double len = sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]));
        total += len;
        by_order[s.order[i] < 3 ? s.order[i] : 3] += len;
        for (int q = 0; q < 3; q++) {
            double lvl = z0 + H * (q + 1) / 4.0;
            if ((a[2] - lvl) * (b[2] - lvl) < 0) crossings[q]++;
        }
    }
    /* Per branch: first node, last node, path length, parent direction at the base. */
    double *blen = calloc((size_t)nb + 1, sizeof *blen);
    int32_t *bfirst = malloc(((size_t)nb + 1) * sizeof *bfirst), *blast = malloc(((size_t)nb + 1) * sizeof *blast);
    if (!blen || !bfirst || !blast) {
        free(blen), free(bfirst), free(blast);
        sy_skeleton_free(&s);
        return;
    }
    for (int32_t b = 0; b <= nb; b++) bfirst[b] = blast[b] = -1;
    for (size_t i = 0; i < n; i++) {
        int32_t b = s.branch[i];
        if (b < 0 || b > nb) continue;
        /* Nodes are breadth-first from the root: the first seen is the base. */
        if (bfirst[b] < 0) bfirst[b] = (int32_t)i;
        blast[b] = (int32_t)i;
        int p = s.parent[i];
        if (p >= 0 && s.branch[p] == b) {
            const float *a = s.pos + 3 * p, *q = s.pos + 3 * i;
            blen[b] += sqrt((a[0] - q[0]) * (a[0] - q[0]) + (a[1] - q[1]) * (a[1] - q[1]) + (a[2] - q[2]) * (a[2] - q[2]));
        }
    }
    float angle_hist[N_ANG] = {0}, elev_hist[N_ANG] = {0}, len_hist[N_LEN] = {0};
    double ang_sum[3] = {0, 0, 0};
    int ang_n[3] = {0, 0, 0}, main_stems = 1, branches = 0, trunk_branches = 0;
    double len_sum = 0;
    for (int32_t b = 0; b <= nb; b++) {
        int32_t i0 = bfirst[b], i1 = blast[b];
        if (i0 < 0 || i1 == i0) continue;
        const float *A = s.pos + 3 * i0, *B = s.pos + 3 * i1;
        double d[3] = {B[0] - A[0], B[1] - A[1], B[2] - A[2]};
        double dl = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (dl <= 0) continue;
        int ord = s.order[i0];
        branches++;
        len_sum += blen[b];
        double elev = asin(fmax(-1, fmin(1, d[2] / dl))) * 180 / M_PI; /* -90..90 */
        int eb = (int)((elev + 90) / 180 * N_ANG);
        elev_hist[eb < 0 ? 0 : eb >= N_ANG ? N_ANG - 1 : eb] += 1;
        double lr = blen[b] / H; /* log bins from 1/256 H to H */
        int lb = lr > 0 ? (int)floor((log2(lr) + 8) / 8 * N_LEN) : 0;
        len_hist[lb < 0 ? 0 : lb >= N_LEN ? N_LEN - 1 : lb] += 1;
        if (ord == 0) continue;
        int p = s.parent[i0];
        if (p < 0) continue;
        if (s.order[p] == 0) trunk_branches++;
        int pp = s.parent[p];
        const float *P0 = s.pos + 3 * (pp >= 0 ? pp : p), *P1 = s.pos + 3 * p;
        double pd[3] = {P1[0] - P0[0], P1[1] - P0[1], P1[2] - P0[2]};
        if (pp < 0) pd[0] = 0, pd[1] = 0, pd[2] = 1;
        double pl = sqrt(pd[0] * pd[0] + pd[1] * pd[1] + pd[2] * pd[2]);
        if (pl <= 0) continue;
        double cs = (pd[0] * d[0] + pd[1] * d[1] + pd[2] * d[2]) / (pl * dl);
        double ang = acos(fmax(-1, fmin(1, cs))) * 180 / M_PI; /* 0..180 */
        int ab = (int)(ang / 180 * N_ANG);
        angle_hist[ab < 0 ? 0 : ab >= N_ANG ? N_ANG - 1 : ab] += 1;
        int oi = ord < 2 ? 1 : 2;
        ang_sum[oi] += ang, ang_n[oi]++;
        /* A main stem: an order-1 branch leaving the trunk below the crown
         * base, at least half as thick as the trunk. */
        if (s.order[p] == 0 && s.pos[3 * i0 + 2] < z0 + crown_base + 0.1 * H && trunk_r > 0 &&
            s.radius[i0] >= 0.5 * trunk_r)
            main_stems++;
    }
    /* Trunk: branch of the root. */
    double trunk_len = bfirst[s.branch[0]] >= 0 ? blen[s.branch[0]] : 0;
    const float *T0 = s.pos, *T1 = s.pos + 3 * blast[s.branch[0]];
    double td[3] = {T1[0] - T0[0], T1[1] - T0[1], T1[2] - T0[2]};
    double tchord = sqrt(td[0] * td[0] + td[1] * td[1] + td[2] * td[2]);
    normalise(angle_hist, N_ANG);
    normalise(elev_hist, N_ANG);
    normalise(len_hist, N_LEN);
    f[F_MAIN_STEMS] = (float)main_stems;
    for (int q = 0; q < 3; q++) f[F_CROSS_Q1 + q] = (float)crossings[q];
    f[F_SK_BRANCHES] = (float)branches;
    f[F_SK_LENGTH_REL] = (float)(total / H);
    f[F_SK_MAX_ORDER] = (float)max_order;
    f[F_SK_MEAN_BRANCH_LEN_REL] = branches ? (float)(len_sum / branches / H) : -1;
    f[F_SK_TRUNK_SHARE] = total > 0 ? (float)(trunk_len / total) : -1;
    f[F_SK_TRUNK_STRAIGHT] = trunk_len > 0 ? (float)(tchord / trunk_len) : -1;
    f[F_SK_TRUNK_LEAN] = tchord > 0 ? (float)(acos(fmax(-1, fmin(1, td[2] / tchord))) * 180 / M_PI) : -1;
    f[F_SK_BRANCHES_PER_M] = trunk_len > 0 ? (float)(trunk_branches / trunk_len) : -1;
    f[F_SK_DBH_M] = (float)r.dbh;
    f[F_SK_ANGLE_O1] = ang_n[1] ? (float)(ang_sum[1] / ang_n[1]) : -1;
    f[F_SK_ANGLE_O2] = ang_n[2] ? (float)(ang_sum[2] / ang_n[2]) : -1;
    for (int o = 0; o < 4; o++) f[F_SK_ORDER_SHARE + o] = total > 0 ? (float)(by_order[o] / total) : -1;
    memcpy(f + F_SK_ANGLE_HIST, angle_hist, sizeof angle_hist);
    memcpy(f + F_SK_ELEV_HIST, elev_hist, sizeof elev_hist);
    memcpy(f + F_SK_LEN_HIST, len_hist, sizeof len_hist);
    free(blen), free(bfirst), free(blast);
    sy_skeleton_free(&s);
}

/* ------------------------------------------------------------ main */

typedef struct {
    float *P;         /* 3m subsampled points */
    float *first;     /* 3m0: the centroids at the first voxel */
    float *h, *r;     /* m: relative height, radial distance */
    float *scratch;   /* max(m, n) */
    sy_voxel_entry *keys; /* n */
    double *pts2, *hull2;
    double *tmp;
} work;

static void work_free(work *w)
{
    free(w->P), free(w->first), free(w->h), free(w->r), free(w->scratch), free(w->keys), free(w->pts2), free(w->hull2), free(w->tmp);
}

sy_code sy_features_compute(const sy_cloud *tree, const sy_features_options *o, float *f, sy_features_info *info,
                            sy_error *err)
{
    double t_start = sy_now();
    sy_code rc = sy_features_options_check(o, err);
    if (rc) return rc;
    if (tree->n < SY_FEATURES_MIN_POINTS)
        return sy_fail(err, SY_EINPUT, "features: %zu points, at least %d are needed", tree->n, SY_FEATURES_MIN_POINTS);
    size_t n = tree->n;
    work w;
    memset(&w, 0, sizeof w);
    w.P = sy_calloc(3 * n, sizeof *w.P, err, "features");
    w.keys = sy_calloc(n, sizeof *w.keys, err, "features");
    w.scratch = sy_calloc(n, sizeof *w.scratch, err, "features");
    if (!w.P || !w.keys || !w.scratch) {
        work_free(&w);
        return err->code;
    }
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            float v = tree->xyz[3 * i + a];
            if (!isfinite(v)) {
                work_free(&w);
                return sy_fail(err, SY_EINPUT, "features: point %zu is not finite", i);
            }
            if (v < lo[a]) lo[a] = v;
            if (v > hi[a]) hi[a] = v;
        }
    /* Subsample to at most max_points voxel centroids. */
    w.first = sy_calloc(3 * n, sizeof *w.first, err, "features");
    if (!w.first) {
        work_free(&w);
        return err->code;
    }
    double voxel = o->voxel;
    size_t m0 = voxel_centroids(tree->xyz, n, lo, o->voxel, w.keys, w.first);
    size_t m = subsample(w.first, m0, lo, o->max_points, w.keys, w.P, &voxel);
    double spacing = sy_estimate_spacing(tree->xyz, n);
    w.h = sy_calloc(m, sizeof *w.h, err, "features");
    w.r = sy_calloc(m, sizeof *w.r, err, "features");
    w.pts2 = sy_calloc(2 * m + 2, sizeof *w.pts2, err, "features");
    w.hull2 = sy_calloc(2 * m + 4, sizeof *w.hull2, err, "features");
    w.tmp = sy_calloc(m + 1, sizeof *w.tmp, err, "features");
    if (!w.h || !w.r || !w.pts2 || !w.hull2 || !w.tmp) {
        work_free(&w);
        return err->code;
    }
    const float *P = w.P;
    /* Frame: base height, height, trunk axis from the lowest slab. */
    for (size_t i = 0; i < m; i++) w.h[i] = P[3 * i + 2];
    double z0 = quantile(w.h, m, 0.005, w.scratch), ztop = quantile(w.h, m, 0.995, w.scratch);
    double H = ztop - z0;
    if (!(H > 0.05)) H = 0.05;
    double slab = fmax(0.3, 0.05 * H);
    size_t ns = 0;
    for (size_t i = 0; i < m; i++)
        if (P[3 * i + 2] <= z0 + slab) w.h[ns++] = P[3 * i];
    double cx = quantile(w.h, ns, 0.5, w.scratch);
    ns = 0;
    for (size_t i = 0; i < m; i++)
        if (P[3 * i + 2] <= z0 + slab) w.h[ns++] = P[3 * i + 1];
    double cy = quantile(w.h, ns, 0.5, w.scratch);
    for (size_t i = 0; i < m; i++) {
        w.h[i] = (float)((P[3 * i + 2] - z0) / H);
        w.r[i] = (float)hypot(P[3 * i] - cx, P[3 * i + 1] - cy);
    }
    for (int i = 0; i < F_COUNT; i++) f[i] = 0;
    f[F_HEIGHT] = (float)H;

    /* Trunk width: radial distances of points near the axis at breast height. */
    ns = 0;
    for (size_t i = 0; i < m; i++) {
        double zabs = w.h[i] * H;
        if (zabs >= 1.0 && zabs <= 1.6 && w.r[i] < 0.6) w.scratch[ns++] = w.r[i];
    }
    double trunk_r = -1;
    if (ns >= 8 && H > 3) {
        float *tmpf = malloc(ns * sizeof *tmpf);
        if (tmpf) {
            memcpy(tmpf, w.scratch, ns * sizeof *tmpf);
            trunk_r = quantile(tmpf, ns, 0.5, w.scratch);
            free(tmpf);
        }
    }
    f[F_TRUNK_WIDTH] = trunk_r > 0 ? (float)(2 * trunk_r) : -1;
    f[F_TRUNK_WIDTH_REL] = trunk_r > 0 ? (float)(2 * trunk_r / H) : -1;

    /* Envelope per tenth of the height and per 40th for the crown base. */
    double env[40], area[N_ENV];
    double crown_r = 0;
    {
        float *tmpf = malloc(m * sizeof *tmpf);
        if (!tmpf) {
            work_free(&w);
            return sy_fail(err, SY_EINTERNAL, "features: out of memory");
        }
        for (int k = 0; k < 40; k++) {
            size_t c = 0;
            for (size_t i = 0; i < m; i++)
                if ((int)fmin(39, fmax(0, floor(w.h[i] * 40))) == k) tmpf[c++] = w.r[i];
            env[k] = c ? quantile(tmpf, c, 0.9, w.scratch) : 0;
        }
        crown_r = quantile(w.r, m, 0.95, w.scratch);
        for (int k = 0; k < N_ENV; k++) {
            size_t c = 0, c2 = 0;
            for (size_t i = 0; i < m; i++) {
                int t = (int)fmin(N_ENV - 1, fmax(0, floor(w.h[i] * N_ENV)));
                if (t != k) continue;
                tmpf[c++] = w.r[i];
                w.pts2[2 * c2] = P[3 * i], w.pts2[2 * c2 + 1] = P[3 * i + 1], c2++;
            }
            f[F_ENV_R + k] = c ? (float)(quantile(tmpf, c, 0.9, w.scratch) / H) : 0;
            area[k] = hull_area(w.pts2, c2, w.hull2);
        }
        free(tmpf);
    }
    double env_max = 0, area_max = 0;
    int widest = 0;
    for (int k = 0; k < 40; k++)
        if (env[k] > env_max) env_max = env[k], widest = k;
    /* The crown starts where the envelope leaves the trunk: a quarter of the
     * widest slab, but for a narrow crown (a forest-grown pine) at least
     * three trunk radii plus 20 cm, else the trunk itself counts as crown. */
    double crown_thr = 0.25 * env_max;
    if (trunk_r > 0) crown_thr = fmax(crown_thr, fmin(0.5 * env_max, 3 * trunk_r + 0.2));
    /* Down from the widest slab while the envelope stays above the threshold:
     * a flared base or shrubs at the foot do not pull the crown to the ground. */
    int cb = widest;
    while (cb > 0 && env[cb - 1] >= crown_thr) cb--;
    double crown_base = cb / 40.0 * H;
    for (int k = 0; k < N_ENV; k++) area_max = fmax(area_max, area[k]);
    for (int k = 0; k < N_ENV; k++) f[F_ENV_AREA + k] = area_max > 0 ? (float)(area[k] / area_max) : 0;
    double crown_h = H - crown_base;
    double W = 2 * crown_r;
    f[F_CROWN_BASE_M] = (float)crown_base;
    f[F_CROWN_BASE_REL] = (float)(crown_base / H);
    f[F_CROWN_HEIGHT_M] = (float)crown_h;
    f[F_CROWN_WIDTH_M] = (float)W;
    f[F_CROWN_WIDTH_REL] = (float)(W / H);
    f[F_CROWN_W_OVER_CH] = crown_h > 0 ? (float)(W / crown_h) : -1;
    f[F_WIDEST_AT_REL] = (float)((widest + 0.5) / 40.0);

    /* Crown PCA in the horizontal plane and asymmetry (points above the crown base). */
    {
        double sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0;
        size_t c = 0;
        for (size_t i = 0; i < m; i++) {
            if (w.h[i] * H < crown_base) continue;
            double x = P[3 * i] - cx, y = P[3 * i + 1] - cy;
            sx += x, sy += y, sxx += x * x, sxy += x * y, syy += y * y, c++;
        }
        if (c >= 3) {
            double mx = sx / c, my = sy / c;
            double a = sxx / c - mx * mx, b = sxy / c - mx * my, d = syy / c - my * my;
            double tr = a + d, det = a * d - b * b, disc = sqrt(fmax(0, tr * tr / 4 - det));
            double l1 = tr / 2 + disc, l2 = fmax(0, tr / 2 - disc);
            f[F_PCA_MAJOR_M] = (float)(4 * sqrt(l1));
            f[F_PCA_MINOR_M] = (float)(4 * sqrt(l2));
            f[F_PCA_MINOR_OVER_MAJOR] = l1 > 0 ? (float)sqrt(l2 / l1) : 1;
            f[F_CROWN_ASYM] = crown_r > 0 ? (float)(hypot(mx, my) / crown_r) : 0;
        }
    }
    /* Height and radius moments. */
    {
        double s1 = 0, s2 = 0;
        for (size_t i = 0; i < m; i++) s1 += w.h[i];
        double mu = s1 / m;
        double m2 = 0, m3 = 0, m4 = 0;
        for (size_t i = 0; i < m; i++) {
            double d = w.h[i] - mu;
            m2 += d * d, m3 += d * d * d, m4 += d * d * d * d;
        }
        m2 /= m, m3 /= m, m4 /= m;
        f[F_H_MEAN] = (float)mu;
        f[F_H_STD] = (float)sqrt(m2);
        f[F_H_SKEW] = m2 > 0 ? (float)(m3 / pow(m2, 1.5)) : 0;
        f[F_H_KURT] = m2 > 0 ? (float)(m4 / (m2 * m2)) : 0;
        s1 = 0;
        for (size_t i = 0; i < m; i++) s1 += w.r[i], s2 += (double)w.r[i] * w.r[i];
        double rm = s1 / m;
        f[F_R_MEAN_REL] = (float)(rm / H);
        f[F_R_STD_REL] = (float)(sqrt(fmax(0, s2 / m - rm * rm)) / H);
    }
    /* Hull volumes: stacked slab hulls. */
    {
        double vol = 0, vq[N_QUART] = {0};
        for (int k = 0; k < N_ENV; k++) {
            double v = area[k] * H / N_ENV;
            vol += v;
            vq[quarter_of((k + 0.5) / N_ENV)] += v;
        }
        f[F_HULL_VOLUME_M3] = (float)vol;
        f[F_HULL_VOLUME_REL] = (float)(vol / (H * H * H));
        f[F_HULL_FILL_CYLINDER] = crown_r > 0 && crown_h > 0 ? (float)(vol / (M_PI * crown_r * crown_r * H)) : -1;
        for (int q = 0; q < N_QUART; q++) f[F_HULL_Q0 + q] = vol > 0 ? (float)(vq[q] / vol) : 0;
        /* Occupied 0.25 m voxels and their counts. */
        float *cent = malloc(3 * m * sizeof *cent);
        if (cent) {
            size_t mv = voxel_centroids(P, m, lo, 0.25, w.keys, cent);
            f[F_VOXEL_FILL_HULL] = vol > 0 ? (float)(mv * 0.015625 / vol) : -1;
            /* counts per voxel: the keys are sorted, runs are voxels */
            size_t runs = 0, qruns[N_QUART] = {0};
            double *cnt = w.tmp;
            double *qcnt[N_QUART];
            double *qbuf = malloc(m * sizeof *qbuf * N_QUART);
            for (int q = 0; q < N_QUART; q++) qcnt[q] = qbuf ? qbuf + (size_t)q * m : NULL;
            for (size_t i = 0; i < m;) {
                size_t j = i;
                while (j < m && w.keys[j].key == w.keys[i].key) j++;
                cnt[runs++] = (double)(j - i);
                int q = quarter_of(w.h[w.keys[i].index]);
                if (qbuf) qcnt[q][qruns[q]++] = (double)(j - i);
                i = j;
            }
            f[F_INHOM_VOX] = (float)cv_of(cnt, runs);
            for (int q = 0; q < N_QUART; q++) f[F_INHOM_VOX + 1 + q] = qbuf ? (float)cv_of(qcnt[q], qruns[q]) : -1;
            free(qbuf);
            free(cent);
        }
    }
    /* Vertical and radial density profiles. */
    for (size_t i = 0; i < m; i++) {
        int b = (int)floor(w.h[i] * N_VPROF);
        f[F_VPROF + (b < 0 ? 0 : b >= N_VPROF ? N_VPROF - 1 : b)] += 1;
        int rb = crown_r > 0 ? (int)floor(w.r[i] / (1.25 * crown_r) * N_RPROF) : 0;
        f[F_RPROF + (rb < 0 ? 0 : rb >= N_RPROF ? N_RPROF - 1 : rb)] += 1;
    }
    normalise(f + F_VPROF, N_VPROF);
    normalise(f + F_RPROF, N_RPROF);

    /* Local PCA at three radii: normals (smallest axis) from the first,
     * linearity / planarity / scattering from all; the neighbour count at
     * 0.3 m measures local inhomogeneity. */
    {
        double eig_sum[N_SCALES][1 + N_QUART][3];
        size_t eig_n[N_SCALES][1 + N_QUART];
        memset(eig_sum, 0, sizeof eig_sum);
        memset(eig_n, 0, sizeof eig_n);
        double *qloc = malloc(m * sizeof *qloc * N_QUART);
        size_t qn[N_QUART] = {0};
        for (int s = 0; s < N_SCALES; s++) {
            sy_grid g;
            float plo[3] = {INFINITY, INFINITY, INFINITY}, phi[3] = {-INFINITY, -INFINITY, -INFINITY};
            for (size_t i = 0; i < m; i++)
                for (int a = 0; a < 3; a++) plo[a] = fminf(plo[a], P[3 * i + a]), phi[a] = fmaxf(phi[a], P[3 * i + a]);
            /* At least 2.5, 5 and 10 voxels: the coarser the sample, the wider the
             * neighbourhood must be to hold a plane's worth of points. */
            double rad = fmax(scale_radius[s], 2.5 * (1 << s) * voxel);
            if (grid_build(&g, P, m, plo, phi, rad, err)) {
                free(qloc);
                work_free(&w);
                return err->code;
            }
            /* Large radii in dense crowns: every 2nd/4th point is enough for the means. */
            size_t stride = s == 0 ? 1 : (size_t)(s == 1 ? 2 : 4);
            for (size_t i = 0; i < m; i += stride) {
                double cov[6], l[3], v[9];
                size_t k = local_cov(&g, P, i, rad, cov);
                int q = quarter_of(w.h[i]);
                if (s == 1) {
                    w.tmp[i / stride] = (double)k;
                    if (qloc) qloc[(size_t)q * m + qn[q]++] = (double)k;
                }
                if (k < 4) continue;
                sy_sym3_eigen(cov, l, v);
                if (!(l[0] > 0)) continue;
                double L = (sqrt(l[0]) - sqrt(l[1])) / sqrt(l[0]), Pl = (sqrt(l[1]) - sqrt(l[2])) / sqrt(l[0]),
                       S = sqrt(l[2]) / sqrt(l[0]);
                double vals[3] = {L, Pl, S};
                for (int e = 0; e < 3; e++) eig_sum[s][0][e] += vals[e], eig_sum[s][1 + q][e] += vals[e];
                eig_n[s][0]++, eig_n[s][1 + q]++;
                if (s == 0) {
                    /* Normal elevation: the angle of the smallest axis above the horizontal. */
                    double nz = fabs(v[2 * 3 + 2]);
                    double el = asin(fmin(1, nz)) * 180 / M_PI;
                    int b = (int)(el / 90 * N_ELEV);
                    b = b < 0 ? 0 : b >= N_ELEV ? N_ELEV - 1 : b;
                    f[F_NORMAL_GLOBAL + b] += 1;
                    f[F_NORMAL_SLAB + q * N_ELEV + b] += 1;
                }
            }
            if (s == 1) {
                f[F_INHOM_LOCAL] = (float)cv_of(w.tmp, (m + stride - 1) / stride);
                for (int q = 0; q < N_QUART; q++)
                    f[F_INHOM_LOCAL + 1 + q] = qloc ? (float)cv_of(qloc + (size_t)q * m, qn[q]) : -1;
            }
            sy_grid_free(&g);
        }
        free(qloc);
        normalise(f + F_NORMAL_GLOBAL, N_ELEV);
        for (int q = 0; q < N_QUART; q++) normalise(f + F_NORMAL_SLAB + q * N_ELEV, N_ELEV);
        for (int s = 0; s < N_SCALES; s++)
            for (int q = 0; q <= N_QUART; q++)
                for (int e = 0; e < 3; e++)
                    f[F_EIGEN + (s * (1 + N_QUART) + q) * 3 + e] =
                        eig_n[s][q] ? (float)(eig_sum[s][q][e] / (double)eig_n[s][q]) : -1;
    }
    if (o->skeleton) {
        /* The skeleton needs a finer sample than the statistics: at 20 cm
         * spacing its level sets merge every branch into the trunk. */
        float *Q = malloc(3 * n * sizeof *Q);
        if (!Q) {
            work_free(&w);
            return sy_fail(err, SY_EINTERNAL, "features: out of memory");
        }
        double sv = o->voxel;
        size_t mq = subsample(w.first, m0, lo, o->skeleton_points, w.keys, Q, &sv);
        skeleton_features(Q, mq, z0, H, trunk_r, crown_base, f, err);
        free(Q);
    }
    else
        for (int i = F_MAIN_STEMS; i < F_COUNT; i++) f[i] = -1;
    for (int i = 0; i < F_COUNT; i++)
        if (!isfinite(f[i])) f[i] = -1;
    if (info) {
        info->points_in = n;
        info->points_used = m;
        info->voxel = voxel;
        info->spacing = spacing;
        info->base[0] = tree->origin[0] + cx;
        info->base[1] = tree->origin[1] + cy;
        info->base[2] = tree->origin[2] + z0;
        info->height = H;
        info->seconds = sy_now() - t_start;
    }
    work_free(&w);
    return SY_OK;
}
