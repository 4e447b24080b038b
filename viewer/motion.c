/* Spectral wind motion and grass slices (see motion.h). */
#include "viewer/motion.h"

#include <math.h>
#ifndef M_PI
#define M_PI 3.14159265358979323846 /* POSIX C11 does not define it */
#endif
#include <stdlib.h>
#include <string.h>

/* splitmix64: a seedable, platform-independent generator. */
static uint64_t next_u64(uint64_t *s)
{
    uint64_t z = (*s += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}
static double uniform01(uint64_t *s) { return ((next_u64(s) >> 11) + 0.5) * (1.0 / 9007199254740992.0); }
static double gauss(uint64_t *s)
{
    double u = uniform01(s), v = uniform01(s);
    return sqrt(-2 * log(u)) * cos(2 * M_PI * v);
}

void sy_fft(double *re, double *im, int n, int inverse)
{
    for (int i = 1, j = 0; i < n; i++) {
        int bit = n >> 1;
        for (; j & bit; bit >>= 1) j ^= bit;
        j ^= bit;
        if (i < j) {
            double t = re[i]; re[i] = re[j]; re[j] = t;
            t = im[i]; im[i] = im[j]; im[j] = t;
        }
    }
    for (int len = 2; len <= n; len <<= 1) {
        double ang = 2 * M_PI / len * (inverse ? 1 : -1);
        double wr = cos(ang), wi = sin(ang);
        for (int i = 0; i < n; i += len) {
            double cr = 1, ci = 0;
            for (int k = 0; k < len / 2; k++) {
                int a = i + k, b = i + k + len / 2;
                double xr = re[b] * cr - im[b] * ci, xi = re[b] * ci + im[b] * cr;
                re[b] = re[a] - xr, im[b] = im[a] - xi;
                re[a] += xr, im[a] += xi;
                double t = cr * wr - ci * wi;
                ci = cr * wi + ci * wr;
                cr = t;
            }
        }
    }
}

int sy_motion_make(sy_motion *m, int size, double v_m, uint64_t seed)
{
    memset(m, 0, sizeof *m);
    if (size < 16 || (size & (size - 1))) return -1;
    m->size = size;
    /* f_max = 2 f_h at 8 texels per cycle => f_h at 1/16 cycle per texel. */
    m->peak_cycles_per_texel = 1.0 / 16.0;
    /* Slightly under-damped small branches, near critical damping for the trunk (§4.5.3, [65]). */
    const double zeta[SY_MOTION_LEVELS] = {0.9, 0.6, 0.4, 0.3};
    size_t n = (size_t)size * size;
    m->texels = malloc(n * 2 * SY_MOTION_LEVELS * sizeof(float));
    double *re = malloc(n * sizeof(double)), *im = malloc(n * sizeof(double)), *row = malloc(2 * (size_t)size * sizeof(double));
    if (!m->texels || !re || !im || !row) {
        free(re), free(im), free(row), sy_motion_free(m);
        return -1;
    }
    uint64_t rng = seed ^ 0x5f1a5f1a5f1a5f1aull;
    for (int l = 0; l < SY_MOTION_LEVELS; l++) {
        m->damping[l] = zeta[l];
        /* Frequencies in units of f_h: texel frequency k maps to f = k / peak (f_h = 1). */
        double fh = 1.0, gamma = 2 * zeta[l] * 2 * M_PI * fh;
        for (int y = 0; y < size; y++)
            for (int x = 0; x < size; x++) {
                int kx = x <= size / 2 ? x : x - size, ky = y <= size / 2 ? y : y - size;
                double k = sqrt((double)kx * kx + (double)ky * ky) / size; /* cycles per texel */
                double f = k / m->peak_cycles_per_texel;                /* in units of f_h */
                double amp = 0;
                if (k > 0 && f <= 2.0 * fh) {
                    /* Wind speed spectrum in the same scaled units: v_m sets its roll-off. */
                    double pw = v_m / pow(1 + f / v_m, 5.0 / 3.0);
                    double osc = 1.0 / sqrt(pow(4 * M_PI * M_PI * (fh * fh - f * f), 2) + pow(2 * M_PI * f * gamma, 2));
                    amp = sqrt(pw) * osc;
                }
                size_t i = (size_t)y * size + x;
                re[i] = amp * gauss(&rng);
                im[i] = amp * gauss(&rng);
            }
        /* Inverse 2-D FFT: rows then columns. */
        for (int y = 0; y < size; y++) sy_fft(re + (size_t)y * size, im + (size_t)y * size, size, 1);
        for (int x = 0; x < size; x++) {
            for (int y = 0; y < size; y++) row[y] = re[(size_t)y * size + x], row[size + y] = im[(size_t)y * size + x];
            sy_fft(row, row + size, size, 1);
            for (int y = 0; y < size; y++) re[(size_t)y * size + x] = row[y], im[(size_t)y * size + x] = row[size + y];
        }
        double s_re = 0, s_im = 0;
        for (size_t i = 0; i < n; i++) s_re += re[i] * re[i], s_im += im[i] * im[i];
        s_re = sqrt(s_re / n), s_im = sqrt(s_im / n);
        float *dst = m->texels + (size_t)l * n * 2;
        for (size_t i = 0; i < n; i++) {
            dst[2 * i] = (float)(s_re > 0 ? re[i] / s_re : 0);
            dst[2 * i + 1] = (float)(s_im > 0 ? im[i] / s_im : 0);
        }
    }
    free(re), free(im), free(row);
    return 0;
}

void sy_motion_free(sy_motion *m)
{
    free(m->texels);
    m->texels = NULL;
}

void sy_motion_trajectory(const sy_motion *m, double f_h, uint64_t seed, uint32_t branch, float vel[2], float offset[2])
{
    uint64_t s = seed * 0x2545f4914f6cdd1dull + branch * 0x9e3779b97f4a7c15ull + 1;
    double ang = 0;
    for (int tries = 0; tries < 64; tries++) {
        ang = uniform01(&s) * 2 * M_PI;
        double c = cos(ang), sn = sin(ang);
        double slope = fabs(c) > fabs(sn) ? fabs(sn / c) : fabs(c / sn); /* in [0, 1] */
        int ok = 1;
        for (int q = 1; q <= 16 && ok; q++)
            for (int p = 0; p <= q; p++)
                if (fabs(slope - (double)p / q) < 0.02 / q) { ok = 0; break; }
        if (ok) break;
    }
    double speed = f_h / m->peak_cycles_per_texel;
    vel[0] = (float)(cos(ang) * speed);
    vel[1] = (float)(sin(ang) * speed);
    offset[0] = (float)(uniform01(&s) * m->size);
    offset[1] = (float)(uniform01(&s) * m->size);
}

unsigned char *sy_grass_slices(int w, int h, int layers, uint64_t seed)
{
    unsigned char *px = calloc((size_t)w * h * layers * 4, 1);
    if (!px) return NULL;
    uint64_t s = seed ^ 0x67a55ull;
    for (int l = 0; l < layers; l++) {
        unsigned char *img = px + (size_t)l * w * h * 4;
        int blades = w / 5;
        for (int b = 0; b < blades; b++) {
            double x0 = uniform01(&s) * w, height = (0.45 + 0.55 * uniform01(&s)) * h, width = 1.5 + 2.5 * uniform01(&s);
            double lean = (uniform01(&s) - 0.5) * 0.6 * w / 8;
            double g = 0.35 + 0.3 * uniform01(&s), r = 0.15 + 0.2 * uniform01(&s);
            for (int y = 0; y < (int)height; y++) {
                double t = y / height; /* 0 at the soil */
                double cx = x0 + lean * t * t, half = width * (1 - t) * 0.5 + 0.3;
                int row = h - 1 - y;
                for (int x = (int)floor(cx - half - 1); x <= (int)ceil(cx + half + 1); x++) {
                    double cov = half + 0.5 - fabs(x + 0.5 - cx);
                    if (cov <= 0) continue;
                    if (cov > 1) cov = 1;
                    int xx = ((x % w) + w) % w;
                    unsigned char *p = img + ((size_t)row * w + xx) * 4;
                    double shade = 0.55 + 0.45 * t;
                    p[0] = (unsigned char)(255 * r * shade), p[1] = (unsigned char)(255 * g * shade);
                    p[2] = (unsigned char)(255 * 0.08 * shade);
                    double a = p[3] / 255.0 + cov * (1 - p[3] / 255.0);
                    p[3] = (unsigned char)(255 * a + 0.5);
                }
            }
        }
    }
    return px;
}
