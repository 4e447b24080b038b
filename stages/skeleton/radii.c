/* Radii: the trunk diameter at breast height from a robust circle fit, every
 * other radius from the pipe-model allometry of Pirk 2013 eq. 3.1. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "skeleton_internal.h"
#include "stages/core/bvh.h"
#include "stages/core/geometry.h"
#include "stages/core/parallel.h"
#include "stages/core/rng.h"
#include "stages/core/sort.h"

/* ---- Circle fit ---- */

/* splitmix64: good enough to pick RANSAC triples. */
static uint64_t rng_next(uint64_t *s) { return sy_splitmix64(s); }

/* Circle through three points; 0 when they are (nearly) collinear. */
static int circle3(const double *a, const double *b, const double *c, double ctr[2], double *r)
{
    double bx = b[0] - a[0], by = b[1] - a[1], cx = c[0] - a[0], cy = c[1] - a[1];
    double d = 2 * (bx * cy - by * cx);
    if (fabs(d) < 1e-12) return 0;
    double b2 = bx * bx + by * by, c2 = cx * cx + cy * cy;
    double ux = (cy * b2 - by * c2) / d, uy = (bx * c2 - cx * b2) / d;
    ctr[0] = a[0] + ux;
    ctr[1] = a[1] + uy;
    *r = sqrt(ux * ux + uy * uy);
    return 1;
}

/* Geometric least squares (Gauss-Newton on |p - c| - r) over the points
 * within tol of the current circle. Returns the number of inliers used. */
static size_t refine(const double *xy, size_t n, double tol, double c[2], double *r, double *rms)
{
    size_t used = 0;
    for (int it = 0; it < 20; it++) {
        double A[3][3] = {{0}}, g[3] = {0}, ss = 0;
        used = 0;
        for (size_t i = 0; i < n; i++) {
            double dx = xy[2 * i] - c[0], dy = xy[2 * i + 1] - c[1], d = sqrt(dx * dx + dy * dy);
            double res = d - *r;
            if (fabs(res) > tol || d < 1e-12) continue;
            double J[3] = {-dx / d, -dy / d, -1};
            for (int a = 0; a < 3; a++) {
                g[a] += J[a] * res;
                for (int b = 0; b < 3; b++) A[a][b] += J[a] * J[b];
            }
            ss += res * res;
            used++;
        }
        if (used < 3) return used;
        *rms = sqrt(ss / (double)used);
        /* Solve A * delta = -g by Cramer's rule (3x3). */
        double det = A[0][0] * (A[1][1] * A[2][2] - A[1][2] * A[2][1]) -
                     A[0][1] * (A[1][0] * A[2][2] - A[1][2] * A[2][0]) +
                     A[0][2] * (A[1][0] * A[2][1] - A[1][1] * A[2][0]);
        if (fabs(det) < 1e-18) return used;
        double delta[3];
        for (int col = 0; col < 3; col++) {
            double M[3][3];
            memcpy(M, A, sizeof M);
            for (int row = 0; row < 3; row++) M[row][col] = -g[row];
            delta[col] = (M[0][0] * (M[1][1] * M[2][2] - M[1][2] * M[2][1]) -
                          M[0][1] * (M[1][0] * M[2][2] - M[1][2] * M[2][0]) +
                          M[0][2] * (M[1][0] * M[2][1] - M[1][1] * M[2][0])) /
                         det;
        }
        c[0] += delta[0];
        c[1] += delta[1];
        *r += delta[2];
        if (fabs(delta[0]) + fabs(delta[1]) + fabs(delta[2]) < 1e-9) break;
    }
    return used;
}

int sy_fit_circle(const double *xy, size_t n, double tol, unsigned long long seed, double centre[2], double *radius,
                  double *rms)
{
    if (n < 5 || !(tol > 0)) return -1;
    uint64_t st = seed ^ 0x5eed;
    size_t best_in = 0;
    double bc[2] = {0, 0}, br = 0;
    for (int it = 0; it < 300; it++) {
        size_t i = rng_next(&st) % n, j = rng_next(&st) % n, k = rng_next(&st) % n;
        if (i == j || j == k || i == k) continue;
        double c[2], r;
        if (!circle3(xy + 2 * i, xy + 2 * j, xy + 2 * k, c, &r)) continue;
        size_t in = 0;
        for (size_t t = 0; t < n; t++) {
            double dx = xy[2 * t] - c[0], dy = xy[2 * t + 1] - c[1];
            if (fabs(sqrt(dx * dx + dy * dy) - r) <= tol) in++;
        }
        if (in > best_in) {
            best_in = in;
            bc[0] = c[0];
            bc[1] = c[1];
            br = r;
        }
    }
    if (best_in < 5) return -1;
    double r = br, e = 0;
    size_t used = refine(xy, n, tol, bc, &r, &e);
    if (used < 5 || !(r > 0) || !isfinite(r)) return -1;
    centre[0] = bc[0];
    centre[1] = bc[1];
    *radius = r;
    *rms = e;
    return 0;
}

/* ---- Radii ---- */

/* The trunk node (branch 0) nearest height z. */
static size_t trunk_node_near(const sy_skeleton *s, double z)
{
    size_t best = 0;
    double bd = INFINITY;
    for (size_t i = 0; i < s->n; i++)
        if (s->branch[i] == 0 && fabs(s->pos[3 * i + 2] - z) < bd) {
            bd = fabs(s->pos[3 * i + 2] - z);
            best = i;
        }
    return best;
}

typedef struct {
    const sy_skeleton *s;
    const float *xyz;
    const int32_t *node_of;
    size_t n;
    double slab, tol, reach;
    double centre[2]; /* the trunk axis' x y near the slab */
} trunk_slab;

/* The extent of n points (xy pairs, mean mx, my) along their principal axis. */
static double slab_span(const double *xy, size_t n, double mx, double my)
{
    double c[6] = {0}, l[3], v[9];
    for (size_t i = 0; i < n; i++) {
        double x = xy[2 * i] - mx, y = xy[2 * i + 1] - my;
        c[0] += x * x, c[1] += x * y, c[3] += y * y;
    }
    sy_sym3_eigen(c, l, v);
    double ux = v[0], uy = v[3], lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < n; i++) {
        double t = (xy[2 * i] - mx) * ux + (xy[2 * i + 1] - my) * uy;
        lo = fmin(lo, t), hi = fmax(hi, t);
    }
    return hi - lo;
}

/* Circle fit to the trunk points of a horizontal slab at height z; 1 when a
 * circle was fitted. xy (2 n doubles) and *k keep the slab's points of the
 * last pass for the caller's fallback. */
static int fit_trunk_slab(const trunk_slab *q, double z, double *xy, size_t *k, double c[2], double *r, double *rms)
{
    const float *xyz = q->xyz;
    /* Sparse scans leave few points in a 10 cm slab: widen it (trunks are
     * near vertical, so a taller slab still cuts one circle). */
    for (int pass = 0; pass < 8; pass++) {
        int widen = 1 << (pass % 4), near_axis = pass >= 4;
        double sx = 0, sy = 0;
        *k = 0;
        for (size_t i = 0; i < q->n; i++) {
            if (fabs(xyz[3 * i + 2] - z) > widen * q->slab / 2) continue;
            /* Trunk points: on a trunk node, or (for sparse scans whose level
             * sets mix heights) within half a metre of the trunk's axis. */
            int32_t v = q->node_of[i];
            double axis_d = hypot(xyz[3 * i] - q->centre[0], xyz[3 * i + 1] - q->centre[1]);
            if (axis_d > q->reach || (!(v >= 0 && q->s->branch[v] == 0) && (!near_axis || axis_d > 0.5))) continue;
            xy[2 * *k] = xyz[3 * i];
            xy[2 * *k + 1] = xyz[3 * i + 1];
            sx += xy[2 * *k];
            sy += xy[2 * *k + 1];
            (*k)++;
        }
        if (*k >= 10 && sy_fit_circle(xy, *k, q->tol, 1, c, r, rms) == 0 && *r < q->reach) {
            /* A fitted centre far outside the slab's points, or points
             * spanning less than the radius (an arc under 60 degrees), mean
             * the arc was too short to define the circle; the fallback is
             * safer then. AdTree's tree13: a 21 cm arc of its stem base fitted 27 cm. */
            double mx = sx / (double)*k, my = sy / (double)*k;
            if (hypot(c[0] - mx, c[1] - my) <= 1.5 * *r && slab_span(xy, *k, mx, my) >= *r) return 1;
        }
    }
    return 0;
}

/* The butt of a trunk is at most this many times its breast-height radius. */
#define BUTT_FLARE 2.0

sy_code sy_assign_radii(sy_skeleton *s, const float *xyz, const int32_t *node_of, size_t n, double gamma,
                        double spacing, double ground_z, double dbh_height, double slab, double dbh_per_height,
                        sy_radii_info *info, sy_error *err)
{
    memset(info, 0, sizeof *info);
    /* The allometry needs the tree's height: only a base on the ground gives it. */
    if (!isfinite(ground_z)) dbh_per_height = 0;
    size_t m = s->n;
    double *l = sy_calloc(m ? m : 1, sizeof *l, err, "radii");
    double *xy = sy_calloc(n ? n : 1, 2 * sizeof *xy, err, "radii");
    if (!l || !xy) {
        free(l);
        free(xy);
        return SY_EINTERNAL;
    }
    sy_skeleton_subtree_lengths(s, l);
    double z0 = isfinite(ground_z) ? ground_z : s->pos[2], zmax = z0;
    for (size_t i = 0; i < n; i++) zmax = fmax(zmax, xyz[3 * i + 2]);
    info->height = zmax - z0;
    /* Short trees (saplings, test scenes) are measured a quarter up instead. */
    double zb = z0 + fmin(dbh_height, 0.25 * info->height);
    info->dbh_z = zb - z0;
    /* The trunk node nearest breast height carries the DBH exactly. */
    size_t ub = trunk_node_near(s, zb);
    /* The trunk's neighbourhood: no trunk is wider than a tenth of the tree's
     * height (nor, for small trees, than a metre). Foliage hanging down to
     * breast height around the trunk otherwise joins the slab and RANSAC can
     * prefer a metres-wide circle through it (black oak: 9 m). */
    trunk_slab q = {s, xyz, node_of, n, slab, fmax(0.01, spacing), fmax(0.5, 0.05 * info->height),
                    {s->pos[3 * ub], s->pos[3 * ub + 1]}};
    double c[2], r = 0, rms = 0;
    size_t k = 0;
    info->fitted = fit_trunk_slab(&q, zb, xy, &k, c, &r, &rms);
    info->centre[0] = c[0], info->centre[1] = c[1], info->inliers = k;
    if (info->fitted) {
        /* Trunks taper: a breast-height circle much wider than the trunk
         * halfway down went through limbs that leave the trunk there (black
         * oak: 16 trunk returns against 30 limb returns in the slab). Refit
         * close around the lower circle. */
        double zl = z0 + 0.5 * (zb - z0), cl[2], rl, rmsl;
        size_t kl;
        trunk_slab low = q;
        size_t ul = trunk_node_near(s, zl);
        low.centre[0] = s->pos[3 * ul];
        low.centre[1] = s->pos[3 * ul + 1];
        if (fit_trunk_slab(&low, zl, xy, &kl, cl, &rl, &rmsl) && r > 1.2 * rl) {
            trunk_slab near = q;
            near.centre[0] = cl[0];
            near.centre[1] = cl[1];
            near.reach = 1.3 * rl;
            double cn[2], rn, rmsn;
            size_t kn;
            /* Between the two heights a trunk tapers little: a circle much
             * narrower than the lower one is a limb beside it. */
            if (fit_trunk_slab(&near, zb, xy, &kn, cn, &rn, &rmsn) && rn <= 1.2 * rl && rn >= 0.7 * rl) {
                r = rn;
                rms = rmsn;
            } else if (kl < 20 && dbh_per_height > 0) {
                /* Neither circle is the trunk, and the lower one rests on a
                 * few returns (balsam fir: 11, 37% under the truth; weeping
                 * willow: 13, 45% under): the species' allometry, below. */
                info->fitted = 0;
            } else {
                r = rl; /* the lower trunk's radius: tapering makes it an upper bound */
                rms = rmsl;
            }
        }
    }
    /* With the species' allometry to fall back on, a fit must be a clean
     * trunk section: a circle over twice the species' norm at this height is
     * a conifer's whorl of branches around the trunk (balsam fir, 1M points:
     * 1.06 m for 0.38 m), and one whose residual exceeds a tenth of its
     * radius runs through the bases of branches (the same fir preprocessed: 0.21 m,
     * residual 16 mm on 0.11 m). Stems thinner than the norm are otherwise
     * left alone: trees grown in a stand are slender. */
    info->allometric_dbh = dbh_per_height * info->height;
    if (info->fitted && dbh_per_height > 0 && (2 * r > 2 * info->allometric_dbh || rms > 0.1 * r)) info->fitted = 0;
    if (!info->fitted && dbh_per_height > 0) {
        /* No trunk circle (a conifer's needles or a leafy crown hide it):
         * the species' nominal tree, scaled to this one's height. */
        r = 0.5 * info->allometric_dbh;
        rms = 0;
    } else if (!info->fitted && k >= 3) {
        /* Fallback (AdTree's): half the wider of the x and y extents of the
         * slab, between the 5th and 95th percentiles to shed strays. A
         * distance-from-centroid estimate would shrink on one-sided scans. */
        double half = 0;
        for (int a = 0; a < 2; a++) {
            double *v = malloc(k * sizeof *v);
            if (!v) break;
            for (size_t i = 0; i < k; i++) v[i] = xy[2 * i + a];
            qsort(v, k, sizeof *v, sy_cmp_double);
            half = fmax(half, 0.5 * (v[k - 1 - k / 20] - v[k / 20]));
            free(v);
        }
        r = half;
        rms = 0;
    }
    if (!(r > 0)) r = fmax(spacing, 0.01);
    info->dbh = 2 * r;
    info->rms = rms;
    /* Eq. 3.1 anchored at the breast-height node: r_i = r_ub (l_i / l_ub)^(1/gamma).
     * Below it the pipe model alone can run away: limbs or hanging foliage
     * that the graph joins to the trunk near the ground put most of the
     * tree's length below ub (a leafy black oak: 0.4% above it, a 2.2 m
     * root radius for a 0.34 m DBH). So the butt swells to at most
     * BUTT_FLARE times the breast-height radius (Weber & Penn's flare:
     * 1 + Flare at the ground, Flare 0.3-1.2 in the library), and a limb that
     * leaves below breast height is no thicker than the stem there. */
    double inv = 1.0 / gamma, r_ub = 0.5 * info->dbh;
    double l_ub = l[ub] > 0 ? l[ub] : l[0];
    double rmin = fmax(0.25 * spacing, 0.001);
    for (size_t i = 0; i < m; i++) {
        double f = l_ub > 0 ? l[i] / l_ub : 1;
        double ri = r_ub * pow(f, inv);
        if (s->branch[i] == 0) ri = fmin(ri, BUTT_FLARE * r_ub);
        else if (ri > r_ub) ri = r_ub;
        s->radius[i] = (float)fmax(ri, rmin);
    }
    info->d_root = 2.0 * s->radius[0];
    /* Float rounding must not let a child exceed its parent. */
    for (size_t i = 1; i < m; i++)
        if (s->parent[i] >= 0 && s->radius[i] > s->radius[s->parent[i]]) s->radius[i] = s->radius[s->parent[i]];
    free(l);
    free(xy);
    return SY_OK;
}

#define TWO_PI 6.28318530717958647692

/* ---- Measured radii: a circle fit per node where the scan shows the branch ---- */

/* Largest gap, in radians, between the angles of the points around centre c:
 * 2 pi minus it is the arc the points cover. */
static double largest_angle_gap(const double *xy, size_t n, const double c[2], double r, double tol, double *ang)
{
    size_t k = 0;
    for (size_t i = 0; i < n; i++) {
        double dx = xy[2 * i] - c[0], dy = xy[2 * i + 1] - c[1];
        if (fabs(sqrt(dx * dx + dy * dy) - r) <= tol) ang[k++] = atan2(dy, dx);
    }
    if (k < 2) return TWO_PI;
    qsort(ang, k, sizeof *ang, sy_cmp_double);
    double gap = ang[0] + TWO_PI - ang[k - 1];
    for (size_t i = 1; i < k; i++) gap = fmax(gap, ang[i] - ang[i - 1]);
    return gap;
}

/* Node i's continuation along its branch (the child with the same branch id), or -1. */
static int32_t continuation(const sy_skeleton *s, const int32_t *first_child, const int32_t *next_sibling, size_t i)
{
    for (int32_t c = first_child[i]; c >= 0; c = next_sibling[c])
        if (s->branch[c] == s->branch[i]) return c;
    return -1;
}

typedef struct {
    const sy_skeleton *s;
    const float *xyz;
    const int32_t *first_child, *next_sibling;
    size_t most;
    double tol;
    float *fit;
    float *shift; /* 3 per node, or NULL */
    uint8_t *failed; /* per chunk: it ran out of memory */
} ring_job;

/* The ring fits of nodes [begin, end): each node's fit reads only the
 * skeleton and the points and seeds its RANSAC with its own id, so chunks
 * run on any thread and give the same radii. */
static void ring_chunk(void *ctx, size_t begin, size_t end, size_t chunk)
{
    ring_job *J = ctx;
    const sy_skeleton *s = J->s;
    const float *xyz = J->xyz;
    const int32_t *first_child = J->first_child, *next_sibling = J->next_sibling;
    double tol = J->tol;
    float *fit = J->fit;
    double *xy = malloc((3 * J->most + 1) * 2 * sizeof *xy);
    double *ang = malloc((3 * J->most + 1) * sizeof *ang);
    if (!xy || !ang) {
        free(xy);
        free(ang);
        J->failed[chunk] = 1;
        return;
    }
    for (size_t i = begin < 1 ? 1 : begin; i < end; i++) {
        int32_t p = s->parent[i], c = continuation(s, first_child, next_sibling, i);
        int32_t prev = s->branch[p] == s->branch[i] ? p : -1;
        /* The local axis: from the previous node along the branch to the next. */
        const float *a = s->pos + 3 * (size_t)p, *b = s->pos + 3 * (size_t)(c >= 0 ? c : (int32_t)i);
        double ax[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double L = sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2]);
        if (!(L > 0)) continue;
        for (int k = 0; k < 3; k++) ax[k] /= L;
        /* An orthonormal basis (u, v) of the plane across the axis. */
        double h[3] = {fabs(ax[0]) < 0.9 ? 1 : 0, fabs(ax[0]) < 0.9 ? 0 : 1, 0};
        double u[3] = {ax[1] * h[2] - ax[2] * h[1], ax[2] * h[0] - ax[0] * h[2], ax[0] * h[1] - ax[1] * h[0]};
        double ul = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
        for (int k = 0; k < 3; k++) u[k] /= ul;
        double v[3] = {ax[1] * u[2] - ax[2] * u[1], ax[2] * u[0] - ax[0] * u[2], ax[0] * u[1] - ax[1] * u[0]};
        /* This node's points and those of its neighbours on the branch: one
         * level set alone holds too few points on a thin limb. */
        int32_t near[3] = {(int32_t)i, prev, c};
        size_t k = 0, total = 0;
        for (int q = 0; q < 3; q++)
            if (near[q] >= 0) total += s->support_start[near[q] + 1] - s->support_start[near[q]];
        /* A few hundred points define a circle as well as thousands: a dense
         * scan's level sets hold 1000+ and RANSAC's cost grows with them. */
        size_t stride = total > 384 ? total / 256 : 1;
        double cx = 0, cy = 0;
        const float *o = s->pos + 3 * i;
        for (int q = 0; q < 3; q++) {
            if (near[q] < 0) continue;
            for (uint32_t j = s->support_start[near[q]]; j < s->support_start[near[q] + 1]; j += (uint32_t)stride) {
                const float *P = xyz + 3 * (size_t)s->support[j];
                double d[3] = {P[0] - o[0], P[1] - o[1], P[2] - o[2]};
                xy[2 * k] = d[0] * u[0] + d[1] * u[1] + d[2] * u[2];
                xy[2 * k + 1] = d[0] * v[0] + d[1] * v[1] + d[2] * v[2];
                cx += xy[2 * k];
                cy += xy[2 * k + 1];
                k++;
            }
        }
        if (k < 12) continue;
        cx /= (double)k;
        cy /= (double)k;
        double spread = 0;
        for (size_t j = 0; j < k; j++) spread = fmax(spread, hypot(xy[2 * j] - cx, xy[2 * j + 1] - cy));
        double ctr[2], r, rms;
        if (sy_fit_circle(xy, k, tol, i, ctr, &r, &rms) != 0) continue;
        /* A branch, not a leaf mass: most points on the circle, the circle
         * no wider than the points (a flat arc fits any large circle), and the
         * points round at least half of it (a one-sided scan shows about
         * half, several stations more). */
        size_t in = 0;
        for (size_t j = 0; j < k; j++)
            if (fabs(hypot(xy[2 * j] - ctr[0], xy[2 * j + 1] - ctr[1]) - r) <= tol) in++;
        if ((double)in < 0.7 * (double)k || r > spread || r < tol) continue;
        if (largest_angle_gap(xy, k, ctr, r, tol, ang) > 0.5 * TWO_PI) continue;
        fit[i] = (float)r;
        if (J->shift)
            for (int q = 0; q < 3; q++) J->shift[3 * i + (size_t)q] = (float)(ctr[0] * u[q] + ctr[1] * v[q]);
        }
    free(xy);
    free(ang);
}

sy_code sy_measure_node_radii(const sy_skeleton *s, const float *xyz, double spacing, float *fit, float *shift,
                              size_t *fitted_out, sy_error *err)
{
    *fitted_out = 0;
    size_t m = s->n, fitted = 0;
    for (size_t i = 0; i < m; i++) fit[i] = 0;
    if (shift) memset(shift, 0, 3 * m * sizeof *shift);
    if (!s->support_start || m < 2) return SY_OK;
    size_t most = 0;
    for (size_t i = 0; i < m; i++)
        if (s->support_start[i + 1] - s->support_start[i] > most) most = s->support_start[i + 1] - s->support_start[i];
    int32_t *first_child = sy_calloc(m, sizeof *first_child, err, "radii");
    int32_t *next_sibling = sy_calloc(m, sizeof *next_sibling, err, "radii");
    if (!first_child || !next_sibling) {
        free(first_child);
        free(next_sibling);
        return SY_EINTERNAL;
    }
    sy_skeleton_children(s, first_child, next_sibling);
    /* The inlier band: the scan's own roughness, a few millimetres at least. */
    uint8_t *failed = sy_calloc(m / 32 + 1, 1, err, "radii");
    if (!failed) {
        free(first_child);
        free(next_sibling);
        return SY_EINTERNAL;
    }
    ring_job J = {s, xyz, first_child, next_sibling, most, fmax(0.5 * spacing, 0.006), fit, shift, failed};
    sy_parallel_for(m, 32, ring_chunk, &J);
    free(first_child);
    free(next_sibling);
    int out_of_memory = 0;
    for (size_t c = 0; c <= m / 32; c++) out_of_memory |= failed[c];
    free(failed);
    if (out_of_memory) return sy_fail(err, SY_EINTERNAL, "radii: out of memory");
    for (size_t i = 0; i < m; i++) fitted += fit[i] > 0;
    *fitted_out = fitted;
    return SY_OK;
}

/* The trunk above breast height where its rings show it thinner. The
 * allometry anchored at breast height sums the length a node carries,
 * which hardly changes up a bare bole, so it draws the bole as a cylinder
 * of the DBH: PyTLidar's tree_1 at 0.17 m from the ground to 4.5 m, where
 * its rings measure 0.169 m at 1.3 m and 0.128 m at 4.5 m. Above breast
 * height, where at least TRUNK_RINGS_MIN trunk nodes have a ring (the
 * median within two nodes along the trunk), the trunk follows the rings'
 * taper from the lowest of them, which keeps its allometric radius: the
 * DBH's circle sets the scale, the rings only the shape (a node's rings
 * read up to a tenth under the DBH fit on the simulated scans' trunks,
 * whose DBH errors rose from under 1 cm to 2.6-3.8 cm when the rings were
 * taken as they are). A node's ratio to its allometric radius is at most
 * 1, interpolated by index between ringed nodes, 1 below the lowest and
 * kept beyond the highest. Rings only thin it: inside a leafy crown they
 * hold foliage too (let them swell it up to the lowest ring's radius, and
 * the simulated Lombardy poplar's trunk was a 0.34 m cylinder up to 17 m,
 * where its true one thins to 0.08 m); and a ring within two trunk radii
 * of where a limb leaves holds the limb's base too (twelve low limbs round
 * a 0.15 m trunk measured 0.25 m) and is skipped. Below breast height the
 * butt is the DBH's (sy_assign_radii), and the fairing keeps the radius at
 * breast height (sy_skeleton_fair_limbs). Trunk nodes are taken in index
 * order: breadth-first along one chain. */
#define TRUNK_RINGS_MIN 3
static sy_code trunk_on_rings(sy_skeleton *s, const float *fit, double breast_z, sy_error *err)
{
    size_t nt = 0;
    for (size_t i = 0; i < s->n; i++) nt += s->branch[i] == 0 && s->pos[3 * i + 2] >= breast_z;
    if (nt < TRUNK_RINGS_MIN) return SY_OK;
    size_t *t = sy_calloc(nt, sizeof *t, err, "radii");
    double *q = sy_calloc(nt, sizeof *q, err, "radii");
    if (!t || !q) {
        free(t), free(q);
        return SY_EINTERNAL;
    }
    nt = 0;
    for (size_t i = 0; i < s->n; i++)
        if (s->branch[i] == 0 && s->pos[3 * i + 2] >= breast_z) t[nt++] = i;
    /* q < 0: a ring beside a limb's base, not the trunk's. */
    for (size_t i = 0; i < s->n; i++) {
        int32_t p = s->parent[i];
        if (p < 0 || s->branch[i] == 0 || s->branch[p] != 0) continue;
        const float *a = s->pos + 3 * (size_t)p;
        for (size_t k = 0; k < nt; k++) {
            const float *b = s->pos + 3 * t[k];
            double d2 = 0, reach = 2 * s->radius[t[k]];
            for (int c = 0; c < 3; c++) d2 += ((double)b[c] - a[c]) * ((double)b[c] - a[c]);
            if (d2 <= reach * reach) q[k] = -1;
        }
    }
    size_t rings = 0, first = nt;
    double ring_first = 0;
    for (size_t k = 0; k < nt; k++) {
        if (!(fit[t[k]] > 0) || q[k] < 0) continue;
        double v[5];
        size_t n = 0;
        for (size_t j = k >= 2 ? k - 2 : 0; j <= k + 2 && j < nt; j++)
            if (fit[t[j]] > 0 && q[j] >= 0) v[n++] = fit[t[j]];
        double ring = sy_quantile_double(v, n, 0.5);
        if (first == nt) first = k, ring_first = ring;
        /* The rings' taper from the lowest, at the allometry's radius
         * there; only ever thinner than the allometry. */
        q[k] = fmin(1, s->radius[t[first]] * ring / (ring_first * s->radius[t[k]])); /* in (0, 1] */
        rings++;
    }
    if (rings >= TRUNK_RINGS_MIN) {
        /* The ratios, from 1 at breast height: nodes without one between. */
        double prev_q = 1;
        size_t prev = 0;
        if (!(q[0] > 0)) q[0] = 1;
        for (size_t k = 0; k < nt; k++) {
            if (q[k] > 0) {
                prev_q = q[k], prev = k;
                continue;
            }
            size_t next = k + 1;
            while (next < nt && !(q[next] > 0)) next++;
            q[k] = next < nt ? prev_q + (q[next] - prev_q) * (double)(k - prev) / (double)(next - prev) : prev_q;
        }
        for (size_t k = 0; k < nt; k++) s->radius[t[k]] = (float)(s->radius[t[k]] * q[k]);
    }
    free(t), free(q);
    return SY_OK;
}

sy_code sy_calibrate_radii(sy_skeleton *s, const float *fit, double breast_z, sy_error *err)
{
    size_t m = s->n;
    int32_t nb = 0;
    for (size_t i = 0; i < m; i++)
        if (s->branch[i] >= nb) nb = s->branch[i] + 1;
    /* The trunk's own scale: its rings (the branches' is below). */
    sy_code rc = trunk_on_rings(s, fit, breast_z, err);
    if (rc || m == 0) return rc;
    size_t *count = sy_calloc((size_t)nb, sizeof *count, err, "radii");
    size_t *start = sy_calloc((size_t)nb + 1, sizeof *start, err, "radii");
    double *ratio = sy_calloc(m, sizeof *ratio, err, "radii");
    double *scale = sy_calloc((size_t)nb, sizeof *scale, err, "radii");
    if (!count || !start || !ratio || !scale) {
        free(count);
        free(start);
        free(ratio);
        free(scale);
        return SY_EINTERNAL;
    }
    /* Group the measured-to-allometric ratios by branch. */
    for (size_t i = 0; i < m; i++)
        if (fit[i] > 0 && s->radius[i] > 0) count[s->branch[i]]++;
    for (int32_t b = 0; b < nb; b++) start[b + 1] = start[b] + count[b];
    for (int32_t b = 0; b < nb; b++) count[b] = 0;
    for (size_t i = 0; i < m; i++)
        if (fit[i] > 0 && s->radius[i] > 0) {
            int32_t b = s->branch[i];
            ratio[start[b] + count[b]++] = fit[i] / s->radius[i];
        }
    /* A branch's scale: the median ratio of its measured nodes. A branch the
     * scan does not resolve keeps the allometry: inheriting the parent's scale
     * swelled unmeasured limbs inside leafy crowns past the low-confidence rule
     * (london plane: precision 0.64 -> 0.75 without it). The trunk keeps 1:
     * the DBH fit calibrated it, and its rings above breast height. */
    for (int32_t b = 0; b < nb; b++) scale[b] = -1;
    scale[0] = 1;
    for (size_t i = 0; i < m; i++) {
        int32_t b = s->branch[i];
        if (scale[b] >= 0) continue;
        size_t k = count[b];
        if (k >= 2) {
            double *v = ratio + start[b];
            qsort(v, k, sizeof *v, sy_cmp_double);
            scale[b] = k % 2 ? v[k / 2] : 0.5 * (v[k / 2 - 1] + v[k / 2]);
        } else {
            scale[b] = 1;
        }
    }
    for (size_t i = 0; i < m; i++) s->radius[i] = (float)(s->radius[i] * scale[s->branch[i]]);
    /* Radii never grow toward the tips (breadth-first order: parents first). */
    for (size_t i = 1; i < m; i++)
        if (s->parent[i] >= 0 && s->radius[i] > s->radius[s->parent[i]]) s->radius[i] = s->radius[s->parent[i]];
    free(count);
    free(start);
    free(ratio);
    free(scale);
    return SY_OK;
}

/* ---- Radii the returns bound ---- */

/* Each edge of the main skeleton is at most return_cap (2) times as thick
 * as the median distance of its returns from it (those nearest to it of all
 * the edges, pooled along its branch over four of its radii either way),
 * when they are RETURN_MIN or more. Twice leaves a one-sided scan its room:
 * a level set's node sits at the centroid of the half ring the scanner saw,
 * from which a limb's returns lie 0.55-0.7 of its radius on the median (the
 * side facing the scanner is sampled densest).
 * What it cuts is the allometry's and the pipe model's guess where the
 * returns deny it: AdTree's tree7 forks a metre up into a vase of thin
 * stems, and the trunk chain running up its middle took 0.09 m from the
 * pipe model where its own returns lie 0.02-0.03 m from it (docs/skeleton.md
 * step 11d). Nearest edges, not level sets: a fork's level sets hold both
 * limbs' rings. */
#define RETURN_MIN 20

/* The main skeleton's edges as BVH primitives: edge k ends at node[k]. */
typedef struct {
    const sy_skeleton *s;
    const int32_t *node;
} edge_set;

static double edge_distance(const void *ctx, uint32_t k, const double q[3])
{
    const edge_set *E = ctx;
    const float *a = E->s->pos + 3 * (size_t)E->s->parent[E->node[k]], *b = E->s->pos + 3 * (size_t)E->node[k];
    const double ad[3] = {a[0], a[1], a[2]}, bd[3] = {b[0], b[1], b[2]};
    return sy_point_segment_distance(q, ad, bd, NULL);
}

typedef struct {
    const edge_set *E;
    const sy_bvh *bvh;
    const float *xyz;
    double reach;  /* a return farther than this from every edge is none's */
    int32_t *edge; /* per support entry: the nearest edge's child node, -1 none */
    float *dist;   /* ... and the distance to it */
} nearest_job;

static void nearest_edges(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    nearest_job *J = ctx;
    const sy_skeleton *s = J->E->s;
    uint32_t hint = UINT32_MAX;
    for (size_t k = begin; k < end; k++) {
        const float *p = J->xyz + 3 * (size_t)s->support[k];
        const double q[3] = {p[0], p[1], p[2]};
        double best;
        /* Ties go to the lower edge, so the answer is the same on any thread. */
        uint32_t e = sy_bvh_nearest(J->bvh, q, J->reach, edge_distance, J->E, hint, &best);
        int32_t node = e == UINT32_MAX ? -1 : J->E->node[e];
        if (e != UINT32_MAX) hint = e;
        /* A return on the parent's tube where a branch leaves it is left out:
         * the branch's first segment runs through the parent's tube there, so
         * it would count for the branch (and the parent has its own returns
         * all along its tube). */
        if (node >= 0) {
            int32_t par = s->parent[node];
            const float *o = s->pos + 3 * (size_t)par;
            double dx = q[0] - o[0], dy = q[1] - o[1], dz = q[2] - o[2];
            if (s->branch[par] != s->branch[node] && sqrt(dx * dx + dy * dy + dz * dz) < 1.2 * s->radius[par]) node = -1;
        }
        J->edge[k] = node;
        J->dist[k] = (float)best;
    }
}

sy_code sy_cap_radii_by_returns(sy_skeleton *s, const float *xyz, double cap_factor, double keep_below_z, size_t *capped,
                                sy_error *err)
{
    *capped = 0;
    size_t m = s->n;
    if (!(cap_factor > 0) || m < 2 || !s->support_start || !s->support_start[m]) return SY_OK;
    size_t n_sup = s->support_start[m], n_edges = 0;
    double rmax = 0;
    for (size_t i = 0; i < m; i++) rmax = fmax(rmax, s->radius[i]), n_edges += s->parent[i] >= 0;
    int32_t *node = sy_calloc(n_edges + 1, sizeof *node, err, "radii");
    sy_box *boxes = sy_calloc(n_edges + 1, sizeof *boxes, err, "radii");
    int32_t *edge = sy_calloc(n_sup, sizeof *edge, err, "radii");
    float *dist = sy_calloc(n_sup, sizeof *dist, err, "radii");
    size_t *start = sy_calloc(m + 1, sizeof *start, err, "radii");
    double *d = sy_calloc(n_sup, sizeof *d, err, "radii");
    int32_t *next = sy_calloc(m, sizeof *next, err, "radii");
    int32_t *first_child = sy_calloc(m, sizeof *first_child, err, "radii");
    int32_t *next_sibling = sy_calloc(m, sizeof *next_sibling, err, "radii");
    int32_t *order = sy_calloc(m, sizeof *order, err, "radii");
    double *pool = sy_calloc(n_sup, sizeof *pool, err, "radii"), *cap = sy_calloc(m, sizeof *cap, err, "radii");
    sy_bvh bvh = {0};
    sy_code rc = node && boxes && edge && dist && start && d && next && first_child && next_sibling && order && pool && cap
                     ? SY_OK
                     : SY_EINTERNAL;
    for (size_t i = 0, k = 0; !rc && i < m; i++) {
        if (s->parent[i] < 0) continue;
        const float *a = s->pos + 3 * (size_t)s->parent[i], *b = s->pos + 3 * i;
        for (int c = 0; c < 3; c++) boxes[k].lo[c] = fmin(a[c], b[c]), boxes[k].hi[c] = fmax(a[c], b[c]);
        node[k++] = (int32_t)i;
    }
    if (!rc) rc = sy_bvh_build(&bvh, boxes, n_edges, err);
    if (!rc) {
        /* Each return's nearest edge within 1.5 of the thickest radius (a
         * surface return of any limb is that near its own chain), 1.5 cm at least. */
        edge_set E = {s, node};
        nearest_job J = {&E, &bvh, xyz, fmax(1.5 * rmax, 0.015), edge, dist};
        sy_parallel_for(n_sup, 4096, nearest_edges, &J);
        /* Each edge's distances, then their median. */
        for (size_t q = 0; q < n_sup; q++)
            if (edge[q] >= 0) start[edge[q] + 1]++;
        for (size_t i = 0; i < m; i++) start[i + 1] += start[i];
        for (size_t q = 0; q < n_sup; q++)
            if (edge[q] >= 0) d[start[edge[q]]++] = dist[q];
        /* The scatter moved each start[i] to the end of edge i's run: shift
         * them back so edge i's run is start[i] .. start[i + 1]. */
        for (size_t i = m; i > 0; i--) start[i] = start[i - 1];
        start[0] = 0;
        /* Each node's cap from the returns of its edge and of the edges along
         * its branch within four of its radii either way: a single short edge
         * holds a sliver of returns, and at a fork a biased one (the
         * synthetic tree's trunk: 21 returns at 2.8 cm for a 12 cm radius). */
        sy_skeleton_branch_next(s, next);
        for (size_t i = 0; i < m; i++) {
            cap[i] = INFINITY;
            if (s->parent[i] < 0 || (s->branch[i] == 0 && s->pos[3 * i + 2] < keep_below_z)) continue;
            double reach = 4 * s->radius[i];
            size_t cnt = 0;
            for (int dir = 0; dir < 2; dir++) {
                int32_t v = (int32_t)i;
                double walked = 0;
                while (v >= 0 && walked <= reach) {
                    if (dir == 0 || v != (int32_t)i)
                        for (size_t q = start[v]; q < start[v + 1]; q++) pool[cnt++] = d[q];
                    int32_t w = dir ? next[v] : s->parent[v];
                    if (w < 0 || s->parent[w] < 0 || s->branch[w] != s->branch[i]) break;
                    walked += sy_skeleton_edge_length(s, (size_t)(dir ? w : v));
                    v = w;
                }
            }
            /* A millimetre at least: returns on the chain itself (duplicates,
             * a level set of one point) must not make a radius of 0. */
            if (cnt >= RETURN_MIN) cap[i] = fmax(cap_factor * sy_quantile_double(pool, cnt, 0.5), 0.001);
        }
        for (size_t i = 0; i < m; i++)
            if (s->radius[i] > cap[i]) {
                s->radius[i] = (float)cap[i];
                (*capped)++;
            }
        /* No radius grows toward the tips: parents before children. */
        sy_skeleton_children(s, first_child, next_sibling);
        size_t n_order = sy_skeleton_breadth_first(s, first_child, next_sibling, order);
        for (size_t h = 0; h < n_order; h++) {
            int32_t v = order[h], p = s->parent[v];
            if (p >= 0 && s->radius[v] > s->radius[p]) s->radius[v] = s->radius[p];
        }
    }
    sy_bvh_free(&bvh);
    free(node), free(boxes), free(edge), free(dist), free(start), free(d), free(next);
    free(first_child), free(next_sibling), free(order), free(pool), free(cap);
    return rc;
}
