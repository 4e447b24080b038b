/* A synthetic tree with known geometry for the skeleton tests and benchmark:
 * tapered cylinders (trunk, primary and optional secondary branches) sampled
 * on their surfaces with Gaussian noise, and optional foliage blobs (points
 * filling ellipsoids at branch tips). Header-only, seeded, deterministic. */
#ifndef SYLVA_SYNTHETIC_TREE_H
#define SYLVA_SYNTHETIC_TREE_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "stages/core/cloud.h"

typedef struct {
    double a[3], b[3]; /* axis from base a to tip b */
    double ra, rb;     /* radius at a and at b */
    int parent;        /* segment it grows from, -1 for the trunk */
} syn_seg;

typedef struct {
    syn_seg seg[128];
    int n;
    double blob[128][4]; /* centre xyz, radius */
    int n_blobs;
} syn_tree;

static uint64_t syn_next(uint64_t *s)
{
    uint64_t z = (*s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static double syn_uniform(uint64_t *s) { return (double)(syn_next(s) >> 11) * (1.0 / 9007199254740992.0); }

static double syn_normal(uint64_t *s)
{
    double u = syn_uniform(s), v = syn_uniform(s);
    return sqrt(-2 * log(u + 1e-300)) * cos(2 * 3.14159265358979323846 * v);
}

static double syn_trunk_radius(double z) { return 0.15 - 0.019 * z; }

/* Trunk 7 m; four primary branches at 40 degrees elevation; with
 * secondary != 0, two secondary branches on each primary; with blobs != 0, a
 * foliage ellipsoid at every branch tip. */
static void syn_tree_make(syn_tree *t, int secondary, int blobs)
{
    memset(t, 0, sizeof *t);
    syn_seg trunk = {{0, 0, 0}, {0, 0, 7}, syn_trunk_radius(0), syn_trunk_radius(7), -1};
    t->seg[t->n++] = trunk;
    const double pi = 3.14159265358979323846;
    for (int i = 0; i < 4; i++) {
        double z = 2.2 + 1.0 * i, az = i * pi / 2 + 0.3, el = 40 * pi / 180, len = 2.0 - 0.2 * i;
        syn_seg s = {{0, 0, z}, {0, 0, 0}, 0.055 - 0.005 * i, 0.012, 0};
        double d[3] = {cos(el) * cos(az), cos(el) * sin(az), sin(el)};
        for (int k = 0; k < 3; k++) s.b[k] = s.a[k] + len * d[k];
        int pi_ = t->n;
        t->seg[t->n++] = s;
        if (secondary)
            for (int j = 0; j < 2; j++) {
                double f = 0.45 + 0.25 * j, az2 = az + (j ? 0.9 : -0.9), el2 = 55 * pi / 180;
                syn_seg c = {{0}, {0}, 0.03, 0.01, pi_};
                for (int k = 0; k < 3; k++) c.a[k] = s.a[k] + f * (s.b[k] - s.a[k]);
                double d2[3] = {cos(el2) * cos(az2), cos(el2) * sin(az2), sin(el2)};
                for (int k = 0; k < 3; k++) c.b[k] = c.a[k] + 0.8 * d2[k];
                t->seg[t->n++] = c;
            }
    }
    if (blobs)
        for (int i = 1; i < t->n; i++) {
            for (int k = 0; k < 3; k++) t->blob[t->n_blobs][k] = t->seg[i].b[k];
            t->blob[t->n_blobs][3] = t->seg[i].parent == 0 ? 0.45 : 0.3;
            t->n_blobs++;
        }
}

/* Distance from p to the axis segment of s, and the axis parameter. */
static double syn_axis_dist(const syn_seg *s, const double p[3], double *u)
{
    double ab[3], ap[3], L = 0, t = 0;
    for (int k = 0; k < 3; k++) {
        ab[k] = s->b[k] - s->a[k];
        ap[k] = p[k] - s->a[k];
        L += ab[k] * ab[k];
        t += ab[k] * ap[k];
    }
    t = fmin(1, fmax(0, t / L));
    double d2 = 0;
    for (int k = 0; k < 3; k++) d2 += (ap[k] - t * ab[k]) * (ap[k] - t * ab[k]);
    if (u) *u = t;
    return sqrt(d2);
}

/* Samples n points: (1 - blob_frac) on the branch surfaces (uniform by
 * area), blob_frac inside the foliage blobs; noise = sigma of the radial
 * noise in metres. Points of one segment that fall inside another are
 * dropped and redrawn (a scanner never sees them). */
static sy_code syn_sample(const syn_tree *t, size_t n, double blob_frac, double noise, uint64_t seed, sy_cloud *c,
                          sy_error *err)
{
    sy_code rc = sy_cloud_init(c, n, err);
    if (rc) return rc;
    uint64_t st = seed;
    double area[128], total = 0;
    for (int i = 0; i < t->n; i++) {
        double L = 0;
        for (int k = 0; k < 3; k++) L += (t->seg[i].b[k] - t->seg[i].a[k]) * (t->seg[i].b[k] - t->seg[i].a[k]);
        area[i] = 3.14159265358979323846 * (t->seg[i].ra + t->seg[i].rb) * sqrt(L);
        total += area[i];
    }
    size_t n_blob = t->n_blobs ? (size_t)(blob_frac * (double)n) : 0;
    for (size_t i = 0; i < n; i++) {
        double p[3];
        if (i < n - n_blob) {
            for (;;) {
                double r = syn_uniform(&st) * total;
                int s = 0;
                while (s < t->n - 1 && r > area[s]) r -= area[s++];
                const syn_seg *g = &t->seg[s];
                double ax[3], L = 0;
                for (int k = 0; k < 3; k++) {
                    ax[k] = g->b[k] - g->a[k];
                    L += ax[k] * ax[k];
                }
                L = sqrt(L);
                for (int k = 0; k < 3; k++) ax[k] /= L;
                /* Frame around the axis. */
                double up[3] = {fabs(ax[2]) < 0.9 ? 0 : 1, 0, fabs(ax[2]) < 0.9 ? 1 : 0};
                double e1[3] = {ax[1] * up[2] - ax[2] * up[1], ax[2] * up[0] - ax[0] * up[2], ax[0] * up[1] - ax[1] * up[0]};
                double l1 = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
                for (int k = 0; k < 3; k++) e1[k] /= l1;
                double e2[3] = {ax[1] * e1[2] - ax[2] * e1[1], ax[2] * e1[0] - ax[0] * e1[2], ax[0] * e1[1] - ax[1] * e1[0]};
                double u = syn_uniform(&st), phi = 2 * 3.14159265358979323846 * syn_uniform(&st);
                double rad = g->ra + u * (g->rb - g->ra) + noise * syn_normal(&st);
                for (int k = 0; k < 3; k++)
                    p[k] = g->a[k] + u * L * ax[k] + rad * (cos(phi) * e1[k] + sin(phi) * e2[k]);
                int hidden = 0;
                for (int o = 0; o < t->n && !hidden; o++) {
                    if (o == s) continue;
                    double v, d = syn_axis_dist(&t->seg[o], p, &v);
                    hidden = d < t->seg[o].ra + v * (t->seg[o].rb - t->seg[o].ra) - 2 * noise;
                }
                if (!hidden) break;
            }
        } else {
            const double *b = t->blob[(i - (n - n_blob)) % (size_t)t->n_blobs];
            for (;;) {
                for (int k = 0; k < 3; k++) p[k] = (2 * syn_uniform(&st) - 1) * b[3];
                if (p[0] * p[0] + p[1] * p[1] + p[2] * p[2] <= b[3] * b[3]) break;
            }
            p[2] *= 0.7; /* flattened crowns */
            for (int k = 0; k < 3; k++) p[k] += b[k];
        }
        for (int k = 0; k < 3; k++) c->xyz[3 * i + k] = (float)p[k];
    }
    return SY_OK;
}

#endif
