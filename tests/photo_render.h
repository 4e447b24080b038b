/* A small CPU renderer for the photogrammetry tests: photographs the
 * synthetic tree of synthetic_tree.h (tapered cylinders) standing on a
 * ground disc ringed by boulders and a far backdrop of textured "forest"
 * (features for the views to match on, as real surroundings give), from
 * pinhole cameras with known poses. Surfaces carry a
 * solid value-noise texture (bark and ground) and Lambert shading, which
 * gives SIFT the blobs it needs; the sky is flat. The tree is sphere-traced
 * (the distance to a tapered segment is its axis distance minus the local
 * radius, near-exact for gentle taper); the ground is a plane. Header-only,
 * deterministic. */
#ifndef SYLVA_PHOTO_RENDER_H
#define SYLVA_PHOTO_RENDER_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#include "synthetic_tree.h"

typedef struct {
    double centre[3], right[3], down[3], forward[3]; /* world axes of the image x, y and the view */
    double f;                                        /* focal length, pixels */
    int width, height;
} pr_camera;

static void pr_normalise(double v[3])
{
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int k = 0; k < 3; k++) v[k] /= n;
}

static void pr_cross(const double a[3], const double b[3], double o[3])
{
    o[0] = a[1] * b[2] - a[2] * b[1];
    o[1] = a[2] * b[0] - a[0] * b[2];
    o[2] = a[0] * b[1] - a[1] * b[0];
}

/* A camera at c looking at target with +Z up. */
static pr_camera pr_look_at(const double c[3], const double target[3], double f, int w, int h)
{
    pr_camera cam;
    memcpy(cam.centre, c, sizeof cam.centre);
    for (int k = 0; k < 3; k++) cam.forward[k] = target[k] - c[k];
    pr_normalise(cam.forward);
    double z[3] = {0, 0, 1}, up[3];
    pr_cross(cam.forward, z, cam.right);
    pr_normalise(cam.right);
    pr_cross(cam.right, cam.forward, up);
    for (int k = 0; k < 3; k++) cam.down[k] = -up[k];
    cam.f = f;
    cam.width = w;
    cam.height = h;
    return cam;
}

static double pr_hash(int x, int y, int z)
{
    uint32_t h = (uint32_t)x * 374761393u + (uint32_t)y * 668265263u + (uint32_t)z * 2147483647u;
    h = (h ^ (h >> 13)) * 1274126177u;
    return (double)((h ^ (h >> 16)) & 0xFFFFFF) / 16777215.0;
}

/* Trilinear value noise in [0, 1]. */
static double pr_noise(double x, double y, double z)
{
    int ix = (int)floor(x), iy = (int)floor(y), iz = (int)floor(z);
    double fx = x - ix, fy = y - iy, fz = z - iz;
    fx = fx * fx * (3 - 2 * fx), fy = fy * fy * (3 - 2 * fy), fz = fz * fz * (3 - 2 * fz);
    double v = 0;
    for (int c = 0; c < 8; c++) {
        int dx = c & 1, dy = (c >> 1) & 1, dz = c >> 2;
        double w = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) * (dz ? fz : 1 - fz);
        v += w * pr_hash(ix + dx, iy + dy, iz + dz);
    }
    return v;
}

/* Three octaves, contrast stretched: blobs of ~10 and ~5 cm at freq 10. */
static double pr_texture(const double p[3], double freq)
{
    double v = 0.55 * pr_noise(p[0] * freq, p[1] * freq, p[2] * freq) +
               0.3 * pr_noise(p[0] * 2 * freq + 17, p[1] * 2 * freq, p[2] * 2 * freq) +
               0.15 * pr_noise(p[0] * 4 * freq, p[1] * 4 * freq + 5, p[2] * 4 * freq);
    v = (v - 0.5) * 2.2 + 0.5;
    return v < 0 ? 0 : v > 1 ? 1 : v;
}

/* Distance from p to the tree's surface (negative inside) and the segment hit. */
static double pr_tree_sdf(const syn_tree *t, const double p[3], int *seg)
{
    double best = 1e30;
    for (int i = 0; i < t->n; i++) {
        double u, d = syn_axis_dist(&t->seg[i], p, &u) - (t->seg[i].ra + u * (t->seg[i].rb - t->seg[i].ra));
        if (d < best) {
            best = d;
            if (seg) *seg = i;
        }
    }
    return best;
}

enum { PR_GROUND_RADIUS = 22, PR_BOULDERS = 12, PR_BACKDROP = 22 };

/* Boulders around the tree, beyond the camera ring: centre xyz, radius. */
static void pr_boulder(int i, double b[4])
{
    double a = 2 * 3.14159265358979323846 * (i + 0.37 * pr_hash(i, 1, 2)) / PR_BOULDERS;
    double r = 8.5 + 2.0 * pr_hash(i, 3, 4);
    b[3] = 0.5 + 0.5 * pr_hash(i, 5, 6);
    b[0] = r * cos(a), b[1] = r * sin(a), b[2] = 0.4 * b[3];
}

/* Distance to the nearest boulder, and which. */
static double pr_boulder_sdf(const double p[3], int *which)
{
    double best = 1e30;
    for (int i = 0; i < PR_BOULDERS; i++) {
        double b[4];
        pr_boulder(i, b);
        double d = sqrt(pow(p[0] - b[0], 2) + pow(p[1] - b[1], 2) + pow(p[2] - b[2], 2)) - b[3];
        if (d < best) best = d, *which = i;
    }
    return best;
}

/* Renders one view into rgb (width * height * 3 bytes). */
static void pr_render(const syn_tree *t, const pr_camera *cam, unsigned char *rgb)
{
    const double light[3] = {0.45, 0.35, 0.82};
    for (int y = 0; y < cam->height; y++)
        for (int x = 0; x < cam->width; x++) {
            double dir[3];
            double u = (x + 0.5 - cam->width / 2.0) / cam->f, v = (y + 0.5 - cam->height / 2.0) / cam->f;
            for (int k = 0; k < 3; k++) dir[k] = cam->forward[k] + u * cam->right[k] + v * cam->down[k];
            pr_normalise(dir);
            /* ground plane z = 0 */
            double t_ground = dir[2] < -1e-9 ? -cam->centre[2] / dir[2] : 1e30;
            double gp[3];
            for (int k = 0; k < 3; k++) gp[k] = cam->centre[k] + t_ground * dir[k];
            if (t_ground < 1e30 && gp[0] * gp[0] + gp[1] * gp[1] > PR_GROUND_RADIUS * PR_GROUND_RADIUS) t_ground = 1e30;
            /* boulders: ray-sphere */
            double limit = t_ground < 60 ? t_ground : 60;
            int boulder = -1;
            for (int i = 0; i < PR_BOULDERS; i++) {
                double b[4], oc[3];
                pr_boulder(i, b);
                for (int k = 0; k < 3; k++) oc[k] = cam->centre[k] - b[k];
                double hb = oc[0] * dir[0] + oc[1] * dir[1] + oc[2] * dir[2];
                double cc = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - b[3] * b[3], disc = hb * hb - cc;
                if (disc < 0) continue;
                double tb = -hb - sqrt(disc);
                if (tb > 0 && tb < limit) limit = tb, boulder = i;
            }
            /* tree: sphere tracing over the segments the ray passes near */
            syn_tree near_t;
            near_t.n = 0;
            for (int i = 0; i < t->n; i++) {
                const syn_seg *g = &t->seg[i];
                double best = 1e30;
                for (int q = 0; q <= 16; q++) { /* coarse closest approach of ray and axis */
                    double pa[3], w = q / 16.0, tt = 0;
                    for (int k = 0; k < 3; k++) pa[k] = g->a[k] + w * (g->b[k] - g->a[k]);
                    for (int k = 0; k < 3; k++) tt += (pa[k] - cam->centre[k]) * dir[k];
                    double d2 = 0;
                    for (int k = 0; k < 3; k++) d2 += pow(cam->centre[k] + tt * dir[k] - pa[k], 2);
                    best = fmin(best, sqrt(d2));
                }
                double len = sqrt(pow(g->b[0] - g->a[0], 2) + pow(g->b[1] - g->a[1], 2) + pow(g->b[2] - g->a[2], 2));
                if (best < fmax(g->ra, g->rb) + len / 16 + 1e-3) near_t.seg[near_t.n++] = *g;
            }
            double s = 0;
            int seg = -1, hit = 0;
            double p[3];
            for (int it = 0; near_t.n && it < 256 && s < limit; it++) {
                for (int k = 0; k < 3; k++) p[k] = cam->centre[k] + s * dir[k];
                double d = pr_tree_sdf(&near_t, p, &seg);
                if (d < 5e-4) {
                    hit = 1;
                    boulder = -1;
                    break;
                }
                s += d * 0.9;
            }
            if (!hit && boulder >= 0) {
                hit = 1;
                for (int k = 0; k < 3; k++) p[k] = cam->centre[k] + limit * dir[k];
            }
            double colour[3];
            if (hit && boulder >= 0) {
                double b[4], n[3];
                pr_boulder(boulder, b);
                for (int k = 0; k < 3; k++) n[k] = p[k] - b[k];
                pr_normalise(n);
                double lam = fmax(0, n[0] * light[0] + n[1] * light[1] + n[2] * light[2]);
                double tex = pr_texture(p, 5.0), shade = (0.35 + 0.65 * lam) * (0.15 + 0.85 * tex);
                colour[0] = 0.62 * shade, colour[1] = 0.6 * shade, colour[2] = 0.56 * shade;
            } else if (hit) {
                /* normal: from the axis to the point */
                const syn_seg *g = &near_t.seg[seg];
                double uu;
                syn_axis_dist(g, p, &uu);
                double n[3];
                for (int k = 0; k < 3; k++) n[k] = p[k] - (g->a[k] + uu * (g->b[k] - g->a[k]));
                pr_normalise(n);
                double lam = fmax(0, n[0] * light[0] + n[1] * light[1] + n[2] * light[2]);
                double tex = pr_texture(p, 12.0);
                double shade = (0.5 + 0.5 * lam) * (0.08 + 0.92 * tex) * 1.5;
                colour[0] = 0.55 * shade, colour[1] = 0.40 * shade, colour[2] = 0.28 * shade;
            } else if (t_ground < 1e30 && t_ground <= limit) {
                double tex = pr_texture(gp, 2.5), tex2 = pr_noise(gp[0] * 0.7, gp[1] * 0.7, 3.3);
                double shade = light[2] * (0.15 + 0.85 * tex);
                colour[0] = (0.35 + 0.25 * tex2) * shade, colour[1] = (0.45 + 0.1 * tex2) * shade;
                colour[2] = 0.2 * shade;
            } else {
                /* the backdrop: a textured cylinder of radius PR_BACKDROP, 0-14 m high */
                double b = cam->centre[0] * dir[0] + cam->centre[1] * dir[1];
                double a2 = dir[0] * dir[0] + dir[1] * dir[1];
                double cc = cam->centre[0] * cam->centre[0] + cam->centre[1] * cam->centre[1] - PR_BACKDROP * PR_BACKDROP;
                double tb = a2 > 1e-12 ? (-b + sqrt(fmax(0, b * b - a2 * cc))) / a2 : -1;
                double q[3];
                for (int k = 0; k < 3; k++) q[k] = cam->centre[k] + tb * dir[k];
                if (tb > 0 && q[2] >= 0 && q[2] <= 14) {
                    double tex = pr_texture(q, 1.2), stripe = pr_noise(atan2(q[1], q[0]) * 40, 0.5, 7.1);
                    double shade = 0.3 + 0.25 * tex * (0.5 + 0.5 * stripe); /* dim: features for registration, not the bulk */
                    colour[0] = 0.5 * shade, colour[1] = 0.65 * shade, colour[2] = 0.45 * shade;
                } else {
                    colour[0] = 0.62, colour[1] = 0.74, colour[2] = 0.9;
                }
            }
            for (int k = 0; k < 3; k++) {
                double c = colour[k] * 255.0 + 0.5;
                rgb[3 * ((size_t)y * cam->width + x) + k] = (unsigned char)(c < 0 ? 0 : c > 255 ? 255 : c);
            }
        }
}

/* Distance from p to the true surface: the tree's cylinders, the ground or a boulder. */
static double pr_surface_distance(const syn_tree *t, const double p[3])
{
    int which;
    return fmin(fmin(fabs(pr_tree_sdf(t, p, NULL)), fabs(p[2])), fabs(pr_boulder_sdf(p, &which)));
}

#endif
