/* The multi-dipole diffusion model of a leaf slab: Donner & Jensen, "Light
 * Diffusion in Multi-Layered Translucent Materials" (SIGGRAPH 2005), as
 * Habel, Kusternig & Wimmer use it for leaves (EGSR 2007, eqs 3.3-3.8). The
 * printed eq (3.8) puts the exponential inside (1 + s d); the kernel here
 * uses the correct (1 + s d) e^{-s d}. */
#include "stages/leafmaps/leafmaps.h"

#include <math.h>

#define PI 3.14159265358979323846
#define CUTOFF 1e-6 /* mm^-2, the thesis's kernel truncation */

sy_dipole sy_dipole_make(double sigma_a, double sigma_s, double g, double rho_d, int n)
{
    sy_dipole m;
    double sigma_sp = (1 - g) * sigma_s;
    m.sigma_tp = sigma_a + sigma_sp;
    m.alpha_p = sigma_sp / m.sigma_tp;
    m.D = 1 / (3 * m.sigma_tp);
    m.l = 1 / m.sigma_tp;
    m.sigma_tr = sqrt(3 * sigma_a * m.sigma_tp);
    /* Rough surfaces: A from the average diffuse reflectance, eq (3.4), in
     * place of the Fresnel diffuse reflectance. */
    if (rho_d < 0) rho_d = 0;
    if (rho_d > 0.95) rho_d = 0.95;
    double A = (1 + rho_d) / (1 - rho_d);
    m.zb = 2 * A * m.D;
    m.n = n;
    return m;
}

/* Source depths of pair j, eq (3.5). */
static void depths(const sy_dipole *m, double d, int j, double *zr, double *zv)
{
    double period = 2.0 * j * (d + 2 * m->zb);
    *zr = period + m->l;
    *zv = period - m->l - 2 * m->zb;
}

static double pole(double s, double h, double r)
{
    double dist = sqrt(r * r + h * h);
    if (dist < 1e-12) return 0;
    return h * (1 + s * dist) * exp(-s * dist) / (dist * dist * dist);
}

double sy_dipole_T(const sy_dipole *m, double r, double d)
{
    double sum = 0;
    for (int j = -m->n; j <= m->n; j++) {
        double zr, zv;
        depths(m, d, j, &zr, &zv);
        sum += pole(m->sigma_tr, d - zr, r) - pole(m->sigma_tr, d - zv, r);
    }
    return m->alpha_p / (4 * PI) * sum;
}

static double signed_decay(double s, double h)
{
    return h > 0 ? exp(-s * h) : h < 0 ? -exp(s * h) : 0;
}

double sy_dipole_total(const sy_dipole *m, double d)
{
    double sum = 0;
    for (int j = -m->n; j <= m->n; j++) {
        double zr, zv;
        depths(m, d, j, &zr, &zv);
        sum += signed_decay(m->sigma_tr, d - zr) - signed_decay(m->sigma_tr, d - zv);
    }
    return m->alpha_p / 2 * sum;
}

double sy_dipole_invert(const sy_dipole *m, double t, double dmin, double dmax)
{
    /* T_tot decreases monotonically for d > l (digest property 6). */
    if (t >= sy_dipole_total(m, dmin)) return dmin;
    if (t <= sy_dipole_total(m, dmax)) return dmax;
    double lo = dmin, hi = dmax;
    for (int it = 0; it < 60; it++) {
        double mid = 0.5 * (lo + hi);
        if (sy_dipole_total(m, mid) > t) lo = mid;
        else hi = mid;
    }
    return 0.5 * (lo + hi);
}

void sy_dipole_kernel(const sy_dipole *m, double d, double texel, int radius, float *w)
{
    /* The peak is as narrow as a texel (half-max radius 0.04 mm at d = 0.15
     * mm): point samples over-count it by up to 27 %, so each weight
     * integrates T over its texel's footprint. */
    const int sub = 4;
    int size = 2 * radius + 1;
    double area = texel * texel / (sub * sub);
    for (int dy = -radius; dy <= radius; dy++)
        for (int dx = -radius; dx <= radius; dx++) {
            double s = 0;
            for (int sy = 0; sy < sub; sy++)
                for (int sx = 0; sx < sub; sx++) {
                    double x = (dx + (sx + 0.5) / sub - 0.5) * texel, y = (dy + (sy + 0.5) / sub - 0.5) * texel;
                    s += sy_dipole_T(m, sqrt(x * x + y * y), d);
                }
            s *= area;
            w[(size_t)(dy + radius) * (size_t)size + (size_t)(dx + radius)] = s > 0 ? (float)s : 0.0f;
        }
}

double sy_dipole_radius(const sy_dipole *m, double d)
{
    double last = 0;
    for (double r = 0.005; r < 20; r += 0.005)
        if (sy_dipole_T(m, r, d) >= CUTOFF) last = r;
    return last;
}
