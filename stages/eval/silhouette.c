/* How an asset looks against its scan: silhouette IoU over six orthographic
 * views, the vertical profile's correlation, height and crown-width errors
 * (docs/eval.md). Both sets become points (the model's surface sampled
 * finer than a pixel), each splatted as a disk of the scan's median
 * spacing into 256 x 256 masks over the union's extent in that view. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/eval/eval.h"
#include "stages/eval/eval_internal.h"
#include "stages/core/fileio.h"
#include "stages/core/png.h"
#include "stages/core/sort.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define VIEWS SY_SILHOUETTE_VIEWS
#define RES SY_SILHOUETTE_RES
#define BINS SY_SILHOUETTE_BINS
/* Splats up to this radius (pixels) are drawn point by point, exactly; wider
 * ones (sparse scans) at once from the points' pixels (splat_seeds), within
 * 0.7 px of the same disks. */
#define SPLAT_EXACT_PX 3.0

/* Median nearest-neighbour distance over up to 2000 evenly picked points, by
 * brute force over a hashed grid of cell ~ the bounding box / 64. */
static double median_spacing(const double *p, size_t n)
{
    if (n < 2) return 0.01;
    double lo[3], hi[3];
    for (int k = 0; k < 3; k++) lo[k] = hi[k] = p[k];
    for (size_t i = 1; i < n; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], p[3 * i + k]), hi[k] = fmax(hi[k], p[3 * i + k]);
    double ext = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    double cell = ext / 64 > 1e-6 ? ext / 64 : 1e-3;
    size_t dims[3], nc = 1;
    for (int k = 0; k < 3; k++) dims[k] = (size_t)((hi[k] - lo[k]) / cell) + 1, nc *= dims[k];
    size_t *start = calloc(nc + 1, sizeof *start), *idx = malloc(n * sizeof *idx), *cellof = malloc(n * sizeof *cellof);
    size_t m = n < 2000 ? n : 2000;
    double *best = malloc(m * sizeof *best);
    if (!start || !idx || !cellof || !best) {
        free(start), free(idx), free(cellof), free(best);
        return 0.01;
    }
    for (size_t i = 0; i < n; i++) {
        size_t c[3];
        for (int k = 0; k < 3; k++) {
            c[k] = (size_t)((p[3 * i + k] - lo[k]) / cell);
            if (c[k] >= dims[k]) c[k] = dims[k] - 1;
        }
        cellof[i] = c[0] + dims[0] * (c[1] + dims[1] * c[2]);
        start[cellof[i] + 1]++;
    }
    for (size_t c = 0; c < nc; c++) start[c + 1] += start[c];
    size_t *fill = calloc(nc, sizeof *fill);
    if (!fill) {
        free(start), free(idx), free(cellof), free(best);
        return 0.01;
    }
    for (size_t i = 0; i < n; i++) idx[start[cellof[i]] + fill[cellof[i]]++] = i;
    free(fill);
    for (size_t s = 0; s < m; s++) {
        size_t i = s * (n / m);
        const double *q = p + 3 * i;
        double bd = INFINITY;
        long c[3];
        for (int k = 0; k < 3; k++) c[k] = (long)((q[k] - lo[k]) / cell);
        for (long r = 1; r <= 8 && !(bd <= (r - 1) * cell); r++) /* grow the shell until the best is settled */
            for (long dz = -r; dz <= r; dz++)
                for (long dy = -r; dy <= r; dy++)
                    for (long dx = -r; dx <= r; dx++) {
                        if (labs(dx) != r && labs(dy) != r && labs(dz) != r && r > 1) continue;
                        long X = c[0] + dx, Y = c[1] + dy, Z = c[2] + dz;
                        if (X < 0 || Y < 0 || Z < 0 || X >= (long)dims[0] || Y >= (long)dims[1] || Z >= (long)dims[2]) continue;
                        size_t cc = (size_t)X + dims[0] * ((size_t)Y + dims[1] * (size_t)Z);
                        for (size_t t = start[cc]; t < start[cc + 1]; t++) {
                            size_t j = idx[t];
                            if (j == i) continue;
                            double a = p[3 * j] - q[0], b = p[3 * j + 1] - q[1], d = p[3 * j + 2] - q[2];
                            double dd = sqrt(a * a + b * b + d * d);
                            if (dd > 0 && dd < bd) bd = dd;
                        }
                    }
        best[s] = isfinite(bd) ? bd : cell;
    }
    qsort(best, m, sizeof *best, sy_cmp_double);
    double med = best[m / 2];
    free(start), free(idx), free(cellof), free(best);
    return med > 0 ? med : 0.01;
}

/* View v's projection: u, w (screen axes) of a point. Views: azimuth 0,
 * 45, 90, 135 degrees from the side, the top, and 30 degrees above the
 * horizon at azimuth 0. The sines are taken once per view, not per point
 * (the same values, so the same pixels). */
typedef struct {
    int v;
    double sn, cs;
} view;

static view view_of(int v)
{
    view vw = {v, 0, 1};
    if (v < 4) vw.sn = sin(v * M_PI / 4), vw.cs = cos(v * M_PI / 4);
    else if (v == 5) vw.sn = sin(M_PI / 6), vw.cs = cos(M_PI / 6); /* looking down along (-cos e, 0, -sin e) */
    return vw;
}

static void project(const view *vw, const double *p, double *u, double *w)
{
    if (vw->v < 4) {
        *u = -vw->sn * p[0] + vw->cs * p[1];
        *w = p[2];
    } else if (vw->v == 4) {
        *u = p[0], *w = p[1];
    } else {
        *u = p[1];
        *w = -vw->sn * p[0] + vw->cs * p[2];
    }
}

/* floor() of a pixel coordinate (well inside a long), without the call. */
static long floor_px(double x)
{
    long t = (long)x;
    return t - (t > x);
}

static void splat(unsigned char *mask, double u, double w, const double lo[2], double px, double rad)
{
    double cu = (u - lo[0]) / px, cw = (w - lo[1]) / px, r = rad / px, r2 = r * r + 0.5;
    long i0 = floor_px(cu - r), i1 = floor_px(cu + r), j0 = floor_px(cw - r), j1 = floor_px(cw + r);
    if (i0 < 0) i0 = 0;
    if (j0 < 0) j0 = 0;
    if (i1 > RES - 1) i1 = RES - 1;
    if (j1 > RES - 1) j1 = RES - 1;
    for (long j = j0; j <= j1; j++)
        for (long i = i0; i <= i1; i++) {
            double du = (i + 0.5) - cu, dw = (j + 0.5) - cw;
            /* The disk, or at least the pixel holding the point. */
            if (du * du + dw * dw <= r2) mask[j * RES + i] = 1;
        }
}

/* Squared distance transform of one line (Felzenszwalb & Huttenlocher 2012,
 * "Distance Transforms of Sampled Functions"): d[q] = min_p f[p] + (q - p)^2,
 * the lower envelope of parabolas, in O(n). v, z: n and n + 1 scratch. */
static void distance_line(const double *f, int n, double *d, int *v, double *z)
{
    int k = 0;
    v[0] = 0, z[0] = -1e30, z[1] = 1e30;
    for (int q = 1; q < n; q++) {
        double s;
        for (;;) {
            int p = v[k];
            s = ((f[q] + (double)q * q) - (f[p] + (double)p * p)) / (2.0 * (q - p));
            if (s > z[k]) break;
            k--;
        }
        k++;
        v[k] = q, z[k] = s, z[k + 1] = 1e30;
    }
    k = 0;
    for (int q = 0; q < n; q++) {
        while (z[k + 1] < q) k++;
        double dq = q - v[k];
        d[q] = dq * dq + f[v[k]];
    }
}

/* Splats of radius r pixels around every seed pixel of mask at once: a pixel
 * is set when its centre lies within r^2 + 0.5 (squared) of a seed's centre,
 * as splat() sets them but with each point moved to its pixel's centre. The
 * cost is the mask's, not points x r^2: a model surface sampled finer than a
 * pixel and splatted with an airborne scan's spacing (1 m = 50 pixels) took
 * 11 s for one small tree. */
static int splat_seeds(unsigned char *mask, double r)
{
    double *g = malloc(RES * RES * sizeof *g), *f = malloc(RES * sizeof *f), *d = malloc(RES * sizeof *d);
    double *z = malloc((RES + 1) * sizeof *z);
    int *v = malloc(RES * sizeof *v);
    if (!g || !f || !d || !z || !v) {
        free(g), free(f), free(d), free(z), free(v);
        return -1;
    }
    for (int j = 0; j < RES; j++) {
        for (int i = 0; i < RES; i++) f[i] = mask[j * RES + i] ? 0 : 1e20;
        distance_line(f, RES, d, v, z);
        for (int i = 0; i < RES; i++) g[j * RES + i] = d[i];
    }
    for (int i = 0; i < RES; i++) {
        for (int j = 0; j < RES; j++) f[j] = g[j * RES + i];
        distance_line(f, RES, d, v, z);
        for (int j = 0; j < RES; j++) mask[j * RES + i] = d[j] <= r * r + 0.5;
    }
    free(g), free(f), free(d), free(z), free(v);
    return 0;
}

/* The pixel holding a point, as a seed of splat_seeds. */
static void seed(unsigned char *mask, double u, double w, const double lo[2], double px)
{
    long i = (long)floor((u - lo[0]) / px), j = (long)floor((w - lo[1]) / px);
    if (i >= 0 && j >= 0 && i < RES && j < RES) mask[j * RES + i] = 1;
}

/* Points on the triangles no more than `step` metres apart (so disks of the
 * splat radius, never below the step, cover each triangle without gaps):
 * rows parallel to the longest edge, `step` apart, each sampled every `step`
 * along its length; areas per sample for the profile. The count follows the
 * area plus the perimeter: a barycentric m x m grid by the longest edge gave
 * a twig's long, thin triangle m^2 / 2 samples for a few square
 * centimetres (8.5 million for a 97k-triangle tree). */
static double *sample_triangles(const double *tri, size_t n_tri, const sy_gltf_cutout *cut, double step, size_t *n_out,
                                double **area_out)
{
    size_t cap = 4 * n_tri + 1024, n = 0;
    double *s = malloc(3 * cap * sizeof *s), *ar = malloc(cap * sizeof *ar);
    if (!s || !ar) {
        free(s), free(ar);
        return NULL;
    }
    for (size_t t = 0; t < n_tri; t++) {
        const double *q = tri + 9 * t;
        double len[3];
        for (int k = 0; k < 3; k++) {
            const double *a = q + 3 * k, *b = q + 3 * ((k + 1) % 3);
            len[k] = sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) + (b[2] - a[2]) * (b[2] - a[2]));
        }
        int e = len[0] >= len[1] && len[0] >= len[2] ? 0 : len[1] >= len[2] ? 1 : 2;
        const double *a = q + 3 * e, *b = q + 3 * ((e + 1) % 3), *c = q + 3 * ((e + 2) % 3);
        double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double cr[3] = {ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2], ab[0] * ac[1] - ab[1] * ac[0]};
        double area = 0.5 * sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]);
        double height = len[e] > 0 ? 2 * area / len[e] : 0;
        long rows = (long)ceil(height / step), per = (long)ceil(len[e] / step);
        if (rows > 200) rows = 200;
        if (per > 200) per = 200;
        size_t need = (size_t)((rows + 1) * (per + 2));
        if (n + need > cap) {
            while (n + need > cap) cap *= 2;
            double *s2 = realloc(s, 3 * cap * sizeof *s), *a2 = realloc(ar, cap * sizeof *ar);
            if (!s2 || !a2) {
                free(s2 ? s2 : s), free(a2 ? a2 : ar);
                return NULL;
            }
            s = s2, ar = a2;
        }
        size_t first = n, all = 0;
        int tested = cut && cut->map && cut->map[t] >= 0;
        for (long r = 0; r <= rows; r++) {
            /* Row r from a + f (c - a) to b + f (c - b); the last is c. */
            double f = rows ? (double)r / (double)rows : 0, p0[3], p1[3];
            for (int k = 0; k < 3; k++) p0[k] = a[k] + f * (c[k] - a[k]), p1[k] = b[k] + f * (c[k] - b[k]);
            long m = (long)ceil((1 - f) * len[e] / step);
            if (m > per) m = per;
            if (m < 1) m = 1;
            if (r == rows && rows > 0) m = 0;
            for (long i = 0; i <= m; i++) {
                double g = m ? (double)i / (double)m : 0;
                all++;
                if (tested) {
                    /* The sample's weights on the triangle's own corners. */
                    double w[3];
                    w[e] = (1 - f) * (1 - g), w[(e + 1) % 3] = (1 - f) * g, w[(e + 2) % 3] = f;
                    if (!sy_gltf_cutout_drawn(cut, t, w)) continue;
                }
                for (int k = 0; k < 3; k++) s[3 * n + k] = p0[k] + g * (p1[k] - p0[k]);
                n++;
            }
        }
        /* A cut-out triangle's drawn share of its area. */
        for (size_t i = first; i < n; i++) ar[i] = area / (double)all;
    }
    *n_out = n;
    *area_out = ar;
    return s;
}

/* A coordinate with the surface area it stands for. */
typedef struct {
    double v, w;
} weighted_value;

static int cmp_weighted_value(const void *a, const void *b)
{
    double x = ((const weighted_value *)a)->v, y = ((const weighted_value *)b)->v;
    return (x > y) - (x < y);
}

/* The value below which a share q of the total weight lies (v sorted). */
static double weighted_quantile(const weighted_value *v, size_t n, double total, double q)
{
    double acc = 0;
    for (size_t i = 0; i < n; i++)
        if ((acc += v[i].w) >= q * total) return v[i].v;
    return v[n - 1].v;
}

/* Crown width: the 5-95% extent along x and along y, averaged. Points with
 * weights w (the surface area each sample of a mesh stands for) are counted
 * by them: the mesh sampler puts a few samples on every triangle however
 * small, so counted one each, a twig of millimetre triangles outweighed a
 * stem (rTwig's sapling: 1.46 m counted per sample, 1.11 m by area, its
 * scan 1.25 m, rTwig's own structure model 1.28 m by area). */
static double crown_width(const double *p, const double *w, size_t n, double *tmp, weighted_value *wv)
{
    double width = 0;
    for (int k = 0; k < 2; k++) {
        if (!w) {
            for (size_t i = 0; i < n; i++) tmp[i] = p[3 * i + k];
            width += sy_quantile_double(tmp, n, 0.95) - sy_quantile_double(tmp, n, 0.05);
            continue;
        }
        double total = 0;
        for (size_t i = 0; i < n; i++) wv[i] = (weighted_value){p[3 * i + k], w[i]}, total += w[i];
        qsort(wv, n, sizeof *wv, cmp_weighted_value);
        width += weighted_quantile(wv, n, total, 0.95) - weighted_quantile(wv, n, total, 0.05);
    }
    return width / 2;
}

double *sy_drawn_surface_points(const double *tri, size_t n_tri, const sy_gltf_cutout *cut, double step, size_t *n,
                                double **area_out, sy_error *err)
{
    double *area = NULL, *p = sample_triangles(tri, n_tri, cut, step, n, &area);
    if (p && area_out) *area_out = area;
    else free(area);
    if (!p) sy_fail(err, SY_EINTERNAL, "surface points: out of memory");
    return p;
}

sy_code sy_silhouette_metrics_compute(const double *tri, size_t n_tri, const sy_gltf_cutout *cut, const double *pts,
                                      const double *pts_w, size_t n_pts, sy_silhouette_metrics *out, unsigned char *masks,
                                      sy_error *err)
{
    memset(out, 0, sizeof *out);
    if (n_pts < 2) return sy_fail(err, SY_EINPUT, "silhouette: the scan has %zu points above the ground", n_pts);
    if (n_tri == 0) return sy_fail(err, SY_EINPUT, "silhouette: the asset has no triangles outside its proxy");
    double s = median_spacing(pts, n_pts);
    out->splat_radius = s;
    /* Extent of the union in 3-D sizes the sampling step. */
    double lo[3], hi[3];
    for (int k = 0; k < 3; k++) lo[k] = hi[k] = pts[k];
    for (size_t i = 0; i < n_pts; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], pts[3 * i + k]), hi[k] = fmax(hi[k], pts[3 * i + k]);
    for (size_t i = 0; i < 3 * n_tri; i++)
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], tri[3 * i + k]), hi[k] = fmax(hi[k], tri[3 * i + k]);
    double ext = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    double step = fmin(ext / RES / 2, s);
    if (!(step > 1e-5)) step = 1e-5;
    size_t n_smp = 0;
    double *area = NULL;
    double *smp = sample_triangles(tri, n_tri, cut, step, &n_smp, &area);
    unsigned char *ma = malloc(RES * RES), *mb = malloc(RES * RES);
    double *tmp = malloc(n_pts * sizeof *tmp); /* the scan's unweighted quantiles (the model's are by area) */
    weighted_value *wv = malloc((n_smp > n_pts ? n_smp : n_pts) * sizeof *wv);
    if (!smp || !ma || !mb || !tmp || !wv) {
        free(smp), free(area), free(ma), free(mb), free(tmp), free(wv);
        return sy_fail(err, SY_EINTERNAL, "silhouette: out of memory");
    }
    out->iou_min = INFINITY;
    for (int v = 0; v < VIEWS; v++) {
        const view vw = view_of(v);
        double plo[2] = {INFINITY, INFINITY}, phi[2] = {-INFINITY, -INFINITY}, u, w;
        for (size_t i = 0; i < n_pts; i++) {
            project(&vw, pts + 3 * i, &u, &w);
            plo[0] = fmin(plo[0], u), plo[1] = fmin(plo[1], w), phi[0] = fmax(phi[0], u), phi[1] = fmax(phi[1], w);
        }
        for (size_t i = 0; i < n_smp; i++) {
            project(&vw, smp + 3 * i, &u, &w);
            plo[0] = fmin(plo[0], u), plo[1] = fmin(plo[1], w), phi[0] = fmax(phi[0], u), phi[1] = fmax(phi[1], w);
        }
        double px = fmax(phi[0] - plo[0], phi[1] - plo[1]) / (RES - 1);
        if (!(px > 0)) px = 1e-3;
        memset(ma, 0, RES * RES), memset(mb, 0, RES * RES);
        if (s / px <= SPLAT_EXACT_PX) {
            for (size_t i = 0; i < n_pts; i++) project(&vw, pts + 3 * i, &u, &w), splat(ma, u, w, plo, px, s);
            for (size_t i = 0; i < n_smp; i++) project(&vw, smp + 3 * i, &u, &w), splat(mb, u, w, plo, px, s);
        } else {
            for (size_t i = 0; i < n_pts; i++) project(&vw, pts + 3 * i, &u, &w), seed(ma, u, w, plo, px);
            for (size_t i = 0; i < n_smp; i++) project(&vw, smp + 3 * i, &u, &w), seed(mb, u, w, plo, px);
            if (splat_seeds(ma, s / px) || splat_seeds(mb, s / px)) {
                free(smp), free(area), free(ma), free(mb), free(tmp), free(wv);
                return sy_fail(err, SY_EINTERNAL, "silhouette: out of memory");
            }
        }
        size_t inter = 0, uni = 0, in_a = 0, in_b = 0;
        for (size_t i = 0; i < RES * RES; i++)
            inter += ma[i] && mb[i], uni += ma[i] || mb[i], in_a += ma[i] != 0, in_b += mb[i] != 0;
        out->precision += (in_b ? (double)inter / (double)in_b : 0) / VIEWS;
        out->recall += (in_a ? (double)inter / (double)in_a : 0) / VIEWS;
        if (masks)
            for (size_t i = 0; i < RES * RES; i++)
                masks[(size_t)v * RES * RES + i] = (unsigned char)((ma[i] ? SY_MASK_SCAN : 0) | (mb[i] ? SY_MASK_MODEL : 0));
        out->iou[v] = uni ? (double)inter / (double)uni : 0;
        out->iou_mean += out->iou[v] / VIEWS;
        out->iou_min = fmin(out->iou_min, out->iou[v]);
    }
    /* Vertical profiles over the union's height. */
    double hp[BINS] = {0}, hm[BINS] = {0}, z0 = lo[2], dz = (hi[2] - lo[2]) / BINS;
    if (!(dz > 0)) dz = 1;
    for (size_t i = 0; i < n_pts; i++) {
        long b = (long)((pts[3 * i + 2] - z0) / dz);
        hp[b < 0 ? 0 : b >= BINS ? BINS - 1 : b] += pts_w ? pts_w[i] : 1;
    }
    for (size_t i = 0; i < n_smp; i++) {
        long b = (long)((smp[3 * i + 2] - z0) / dz);
        hm[b < 0 ? 0 : b >= BINS ? BINS - 1 : b] += area[i];
    }
    double mp = 0, mm = 0, sxy = 0, sxx = 0, syy = 0;
    for (int b = 0; b < BINS; b++) mp += hp[b] / BINS, mm += hm[b] / BINS;
    for (int b = 0; b < BINS; b++)
        sxy += (hp[b] - mp) * (hm[b] - mm), sxx += (hp[b] - mp) * (hp[b] - mp), syy += (hm[b] - mm) * (hm[b] - mm);
    out->profile_correlation = sxx > 0 && syy > 0 ? sxy / sqrt(sxx * syy) : 0;
    out->profile_z0 = z0, out->profile_dz = dz;
    memcpy(out->profile_scan, hp, sizeof hp);
    memcpy(out->profile_model, hm, sizeof hm);
    /* Height (base to top) and crown width of each. */
    double pz0 = INFINITY, pz1 = -INFINITY, mz0 = INFINITY, mz1 = -INFINITY;
    for (size_t i = 0; i < n_pts; i++) pz0 = fmin(pz0, pts[3 * i + 2]), pz1 = fmax(pz1, pts[3 * i + 2]);
    for (size_t i = 0; i < n_smp; i++) mz0 = fmin(mz0, smp[3 * i + 2]), mz1 = fmax(mz1, smp[3 * i + 2]);
    out->scan_height = pz1 - pz0;
    out->model_height = mz1 - mz0;
    out->height_error = out->scan_height > 0 ? (out->model_height - out->scan_height) / out->scan_height : NAN;
    out->scan_width = crown_width(pts, pts_w, n_pts, tmp, wv);
    out->model_width = crown_width(smp, area, n_smp, tmp, wv);
    out->width_error = out->scan_width > 0 ? (out->model_width - out->scan_width) / out->scan_width : NAN;
    free(smp), free(area), free(ma), free(mb), free(tmp), free(wv);
    return SY_OK;
}

sy_code sy_silhouette_png(const unsigned char *masks, const char *path, sy_error *err)
{
    /* 3 x 2 views, a 4-pixel white gutter round each with a light grey
     * frame, so an empty view still shows where it is. */
    enum { GAP = 4, BAND = 12, COLS = 3, ROWS = 2 };
    enum { W = COLS * RES + (COLS + 1) * GAP, H = ROWS * (RES + BAND) + (ROWS + 1) * GAP };
    static const unsigned char colour[4][3] = {{255, 255, 255}, {230, 40, 40}, {40, 80, 230}, {60, 60, 60}};
    unsigned char *px = sy_calloc((size_t)W * H, 3, err, "silhouette image");
    if (!px) return SY_EINTERNAL;
    memset(px, 255, (size_t)W * H * 3);
    static const char *name[VIEWS] = {"azimuth 0", "azimuth 45", "azimuth 90", "azimuth 135", "top", "oblique 30"};
    sy_canvas cv = {px, W, H};
    for (int v = 0; v < VIEWS; v++) {
        int x0 = GAP + (v % COLS) * (RES + GAP), y0 = GAP + BAND + (v / COLS) * (RES + BAND + GAP);
        size_t both = 0, any = 0;
        for (size_t i = 0; i < RES * RES; i++) {
            unsigned char b = masks[(size_t)v * RES * RES + i] & 3;
            both += b == 3, any += b != 0;
        }
        for (int y = -1; y <= RES; y++)
            for (int x = -1; x <= RES; x++) {
                unsigned char *o = px + 3 * ((size_t)(y0 + y) * W + (size_t)(x0 + x));
                if (x < 0 || y < 0 || x == RES || y == RES) {
                    o[0] = o[1] = o[2] = 200;
                    continue;
                }
                /* Image rows run down, mask rows up. */
                memcpy(o, colour[masks[(size_t)v * RES * RES + (size_t)(RES - 1 - y) * RES + (size_t)x] & 3], 3);
            }
        /* Each view's name and IoU in the band above it. */
        char label[48];
        snprintf(label, sizeof label, "%s IoU %.3f", name[v], any ? (double)both / (double)any : 0.0);
        static const unsigned char ink[3] = {20, 20, 20};
        sy_canvas_text(&cv, x0, y0 - BAND + 1, label, 0, ink);
    }
    unsigned char *png = NULL;
    size_t size = 0;
    int bad = sy_png_encode(px, W, H, 3, 8, &png, &size);
    free(px);
    sy_code rc = bad ? sy_fail(err, SY_EINTERNAL, "%s: PNG encoding failed", path) : sy_write_file_atomic(path, png, size, err);
    free(png);
    return rc;
}
