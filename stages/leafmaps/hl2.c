/* The Half-Life 2 basis on the hemisphere (McTaggart, "Half-Life 2 / Valve
 * Source Shading", GDC 2004) as Habel et al. use it for directional leaf
 * translucency (eqs 3.17-3.21), with light directions from Shirley & Chiu's
 * concentric map ("A Low Distortion Map Between Disk and Square", 1997) and a
 * least-squares projection so that linear functions project exactly. */
#include "stages/leafmaps/leafmaps.h"

#include <math.h>

#define PI 3.14159265358979323846

void sy_hl2_vectors(double H[3][3])
{
    double a = 1 / sqrt(6.0), b = 1 / sqrt(2.0), c = 1 / sqrt(3.0);
    H[0][0] = -a, H[0][1] = -b, H[0][2] = c;
    H[1][0] = -a, H[1][1] = b, H[1][2] = c;
    H[2][0] = sqrt(2.0 / 3.0), H[2][1] = 0, H[2][2] = c;
}

void sy_hl2_eval(const double w[3], double out[3])
{
    double H[3][3];
    sy_hl2_vectors(H);
    double k = sqrt(3 / (2 * PI));
    for (int i = 0; i < 3; i++) out[i] = k * (H[i][0] * w[0] + H[i][1] * w[1] + H[i][2] * w[2]);
}

static uint64_t splitmix(uint64_t *s)
{
    uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

static double unit(uint64_t *s)
{
    return (double)(splitmix(s) >> 11) * (1.0 / 9007199254740992.0);
}

/* Square [0,1]^2 -> unit disk -> upper hemisphere, uniform in solid angle. */
static void concentric_hemisphere(double u, double v, double *w)
{
    double a = 2 * u - 1, b = 2 * v - 1, r, phi;
    if (a == 0 && b == 0) {
        r = 0, phi = 0;
    } else if (fabs(a) > fabs(b)) {
        r = a, phi = PI / 4 * (b / a);
    } else {
        r = b, phi = PI / 2 - PI / 4 * (a / b);
    }
    double x = r * cos(phi), y = r * sin(phi), r2 = x * x + y * y;
    double s = sqrt(2 - r2);
    w[0] = x * s, w[1] = y * s, w[2] = 1 - r2;
}

void sy_hl2_directions(int n, uint64_t seed, double *dirs)
{
    uint64_t s = seed ^ 0x6C65616648324Cull;
    int gx = (int)sqrt((double)n);
    while (gx > 1 && n % gx) gx--;
    int gy = n / gx;
    for (int i = 0; i < n; i++) {
        double u = ((i % gx) + unit(&s)) / gx, v = ((i / gx) + unit(&s)) / gy;
        concentric_hemisphere(u, v, dirs + 3 * i);
    }
}

int sy_hl2_projection(const double *dirs, int n, double *W)
{
    double G[3][3] = {{0}};
    for (int m = 0; m < n; m++) {
        double b[3];
        sy_hl2_eval(dirs + 3 * m, b);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) G[i][j] += b[i] * b[j];
    }
    double det = G[0][0] * (G[1][1] * G[2][2] - G[1][2] * G[2][1]) - G[0][1] * (G[1][0] * G[2][2] - G[1][2] * G[2][0]) +
                 G[0][2] * (G[1][0] * G[2][1] - G[1][1] * G[2][0]);
    if (!(fabs(det) > 1e-12)) return -1;
    double I[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            int i1 = (j + 1) % 3, i2 = (j + 2) % 3, j1 = (i + 1) % 3, j2 = (i + 2) % 3;
            I[i][j] = (G[i1][j1] * G[i2][j2] - G[i1][j2] * G[i2][j1]) / det;
        }
    for (int m = 0; m < n; m++) {
        double b[3];
        sy_hl2_eval(dirs + 3 * m, b);
        for (int i = 0; i < 3; i++) W[(size_t)i * n + m] = I[i][0] * b[0] + I[i][1] * b[1] + I[i][2] * b[2];
    }
    return 0;
}
