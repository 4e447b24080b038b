/* Preetham sky and its SH projection (see sky.h). */
#include "viewer/sky.h"

#include <math.h>
#ifndef M_PI
#define M_PI 3.14159265358979323846 /* POSIX C11 does not define it */
#endif
#include <string.h>

static double perez_f(const double c[5], double cos_theta, double gamma)
{
    double ct = cos_theta < 0.01 ? 0.01 : cos_theta, cg = cos(gamma);
    return (1 + c[0] * exp(c[1] / ct)) * (1 + c[2] * exp(c[3] * gamma) + c[4] * cg * cg);
}

void sy_sky_make(sy_sky *s, double az_deg, double el_deg, double T)
{
    memset(s, 0, sizeof *s);
    if (T < 1.7) T = 1.7;
    if (T > 10) T = 10;
    if (el_deg < 0.5) el_deg = 0.5; /* the model is defined for a sun above the horizon */
    if (el_deg > 90) el_deg = 90;
    double az = az_deg * M_PI / 180, el = el_deg * M_PI / 180;
    s->sun_dir[0] = (float)(cos(el) * cos(az));
    s->sun_dir[1] = (float)sin(el);
    s->sun_dir[2] = (float)(cos(el) * sin(az));
    double ts = M_PI / 2 - el; /* solar zenith angle */
    double c[3][5] = {
        {0.1787 * T - 1.4630, -0.3554 * T + 0.4275, -0.0227 * T + 5.3251, 0.1206 * T - 2.5771, -0.0670 * T + 0.3703},
        {-0.0193 * T - 0.2592, -0.0665 * T + 0.0008, -0.0004 * T + 0.2125, -0.0641 * T - 0.8989, -0.0033 * T + 0.0452},
        {-0.0167 * T - 0.2608, -0.0950 * T + 0.0092, -0.0079 * T + 0.2102, -0.0441 * T - 1.6537, -0.0109 * T + 0.0529}};
    double chi = (4.0 / 9.0 - T / 120.0) * (M_PI - 2 * ts);
    double Yz = (4.0453 * T - 4.9710) * tan(chi) - 0.2155 * T + 2.4192;
    double t2 = ts * ts, t3 = t2 * ts;
    double xz = T * T * (0.00166 * t3 - 0.00375 * t2 + 0.00209 * ts) + T * (-0.02903 * t3 + 0.06377 * t2 - 0.03202 * ts + 0.00394) +
                (0.11693 * t3 - 0.21196 * t2 + 0.06052 * ts + 0.25886);
    double yz = T * T * (0.00275 * t3 - 0.00610 * t2 + 0.00317 * ts) + T * (-0.04214 * t3 + 0.08970 * t2 - 0.04153 * ts + 0.00516) +
                (0.15346 * t3 - 0.26756 * t2 + 0.06670 * ts + 0.26688);
    s->zenith[0] = (float)Yz, s->zenith[1] = (float)xz, s->zenith[2] = (float)yz;
    for (int k = 0; k < 5; k++)
        for (int ch = 0; ch < 3; ch++) s->perez[k][ch] = (float)c[ch][k];
    for (int ch = 0; ch < 3; ch++) s->perez_sun[ch] = (float)perez_f(c[ch], 1.0, ts);
    /* Zenith luminance to ~0.35 render units: a clear sky reads as a sky under the Reinhard
     * curve whatever the turbidity. */
    s->scale = (float)(0.35 / (Yz > 0.1 ? Yz : 0.1));
    /* Sun: white attenuated along the air mass (Kasten & Young 1989), reddened at low sun. */
    double cz = cos(ts), m = 1.0 / (cz + 0.50572 * pow(96.07995 - ts * 180 / M_PI, -1.6364));
    const double beta[3] = {0.060, 0.095, 0.180}; /* per-channel optical depth, turbidity-scaled */
    for (int ch = 0; ch < 3; ch++) s->sun_color[ch] = (float)(3.0 * exp(-beta[ch] * m * T / 2.0));

    /* Project the sky (upper hemisphere) and a grey ground bounce (lower) into SH. */
    double L[9][3] = {{0}};
    const int NT = 48, NP = 96;
    double ground[3] = {0, 0, 0}, wsum = 0;
    double up_rad[48 * 96][3];
    for (int i = 0; i < NT / 2; i++)
        for (int j = 0; j < NP; j++) {
            double th = (i + 0.5) * M_PI / NT, ph = (j + 0.5) * 2 * M_PI / NP;
            double d[3] = {sin(th) * cos(ph), cos(th), sin(th) * sin(ph)}, rgb[3];
            sy_sky_radiance(s, d, rgb);
            double w = sin(th) * cos(th);
            for (int ch = 0; ch < 3; ch++) ground[ch] += rgb[ch] * w;
            wsum += w;
            memcpy(up_rad[i * NP + j], rgb, sizeof rgb);
        }
    /* Ground: albedo 0.2 times the sky irradiance plus the sun on it, Lambertian. */
    for (int ch = 0; ch < 3; ch++) ground[ch] = 0.2 * (ground[ch] / wsum + s->sun_color[ch] * s->sun_dir[1] / M_PI);
    for (int i = 0; i < NT; i++)
        for (int j = 0; j < NP; j++) {
            double th = (i + 0.5) * M_PI / NT, ph = (j + 0.5) * 2 * M_PI / NP;
            double x = sin(th) * cos(ph), y = cos(th), z = sin(th) * sin(ph);
            double dw = sin(th) * (M_PI / NT) * (2 * M_PI / NP);
            const double *rgb = i < NT / 2 ? up_rad[i * NP + j] : ground;
            /* Real SH basis in the shader's variable order, with world x, y, z as they are. */
            double Y[9] = {0.282095, 0.488603 * y, 0.488603 * z, 0.488603 * x, 1.092548 * x * y, 1.092548 * y * z,
                           0.315392 * (3 * z * z - 1), 1.092548 * x * z, 0.546274 * (x * x - y * y)};
            for (int k = 0; k < 9; k++)
                for (int ch = 0; ch < 3; ch++) L[k][ch] += rgb[ch] * Y[k] * dw;
        }
    /* Irradiance (Ramamoorthi & Hanrahan 2001): E = sum A_l L_lm Y_lm; divided by pi so that
     * albedo * value is the diffuse radiance. The basis constants are folded in. */
    const double A[9] = {M_PI, 2 * M_PI / 3, 2 * M_PI / 3, 2 * M_PI / 3, M_PI / 4, M_PI / 4, M_PI / 4, M_PI / 4, M_PI / 4};
    const double K[9] = {0.282095, 0.488603, 0.488603, 0.488603, 1.092548, 1.092548, 0.315392, 1.092548, 0.546274};
    for (int k = 0; k < 9; k++)
        for (int ch = 0; ch < 3; ch++) s->sh[k][ch] = (float)(A[k] * L[k][ch] * K[k] / M_PI);
}

void sy_sky_radiance(const sy_sky *s, const double d[3], double rgb[3])
{
    double ct = d[1] > 0 ? d[1] : 0;
    double cg = d[0] * s->sun_dir[0] + d[1] * s->sun_dir[1] + d[2] * s->sun_dir[2];
    if (cg > 1) cg = 1;
    if (cg < -1) cg = -1;
    double g = acos(cg), v[3];
    for (int ch = 0; ch < 3; ch++) {
        double c[5] = {s->perez[0][ch], s->perez[1][ch], s->perez[2][ch], s->perez[3][ch], s->perez[4][ch]};
        v[ch] = s->zenith[ch] * perez_f(c, ct, g) / s->perez_sun[ch];
    }
    double Y = v[0] * s->scale, x = v[1], y = v[2] > 1e-4 ? v[2] : 1e-4;
    double X = x / y * Y, Z = (1 - x - y) / y * Y;
    rgb[0] = 3.2406 * X - 1.5372 * Y - 0.4986 * Z;
    rgb[1] = -0.9689 * X + 1.8758 * Y + 0.0415 * Z;
    rgb[2] = 0.0557 * X - 0.2040 * Y + 1.0570 * Z;
    for (int ch = 0; ch < 3; ch++)
        if (rgb[ch] < 0) rgb[ch] = 0;
}
