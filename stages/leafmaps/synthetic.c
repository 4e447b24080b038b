/* Synthetic leaf captures with known truth (leafmaps.h, sy_leaf_synthesize):
 * a veined, bent, slightly bumpy ovate leaf with an insect hole, photographed
 * as the thesis's fixing frame would (front-lit over a white reference,
 * back-lit over a diffuser, the abaxial side turned over), rendered with the
 * stage's own reflection and multi-dipole transmission model. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "stages/leafmaps/leafmaps.h"
#include "stages/leafmaps/leafmaps_cv.h"
#include "stages/leafmaps/leafmaps_internal.h"

#define LEAF_LENGTH_MM 80.0

static uint32_t hash3(int x, int y, uint64_t seed)
{
    uint64_t h = (uint64_t)(uint32_t)x * 0x9E3779B97F4A7C15ull ^ (uint64_t)(uint32_t)y * 0xC2B2AE3D27D4EB4Full ^
                 seed * 0x165667B19E3779F9ull;
    h ^= h >> 29;
    h *= 0xBF58476D1CE4E5B9ull;
    h ^= h >> 32;
    return (uint32_t)h;
}

/* Smooth value noise in [-1, 1]. */
static double noise(double x, double y, uint64_t seed)
{
    int x0 = (int)floor(x), y0 = (int)floor(y);
    double fx = x - x0, fy = y - y0;
    fx = fx * fx * (3 - 2 * fx), fy = fy * fy * (3 - 2 * fy);
    double v[4];
    for (int k = 0; k < 4; k++) v[k] = (hash3(x0 + (k & 1), y0 + (k >> 1), seed) & 0xFFFF) / 32767.5 - 1;
    return (v[0] * (1 - fx) + v[1] * fx) * (1 - fy) + (v[2] * (1 - fx) + v[3] * fx) * fy;
}

void sy_leaf_synthetic_free(sy_leaf_synthetic *s)
{
    for (int k = 0; k < 2; k++) {
        sy_fimage_free(&s->reflected[k]);
        sy_fimage_free(&s->transmitted[k]);
        sy_fimage_free(&s->height[k]);
        sy_fimage_free(&s->albedo[k]);
        sy_fimage_free(&s->normal[k]);
    }
    sy_fimage_free(&s->flat_field);
    sy_fimage_free(&s->thickness);
    sy_fimage_free(&s->alpha);
}

/* Leaf coordinates of photo pixel (x, y): a along the axis (0 petiole base,
 * 1 tip), c across (units of the length, + to the photo's right at rot 0). */
static void leaf_coords(int n, double rot, double x, double y, double *a, double *c)
{
    double L = 0.75 * n;
    double ux = sin(rot), uy = -cos(rot); /* tip direction */
    double rx = -uy, ry = ux;
    double bx = n / 2.0 - ux * L / 2, by = n / 2.0 - uy * L / 2;
    *a = ((x - bx) * ux + (y - by) * uy) / L;
    *c = ((x - bx) * rx + (y - by) * ry) / L;
}

sy_code sy_leaf_synthesize(int n, uint64_t seed, double shift, const sy_leafmaps_options *o, sy_leaf_synthetic *s,
                           sy_error *err)
{
    memset(s, 0, sizeof *s);
    if (n < 32 || n > 8192) return sy_fail(err, SY_EINPUT, "synthetic leaf size %d is outside 32..8192", n);
    size_t np = (size_t)n * n;
    double rot = 0.3; /* the leaf lies tilted in the frame: orientation has work to do */
    s->texel_mm = LEAF_LENGTH_MM / (0.75 * n);
    s->white_rect[0] = n / 40, s->white_rect[1] = n / 40, s->white_rect[2] = n / 10, s->white_rect[3] = n / 10;
    s->white_reflectance = 0.9;
    sy_code rc = SY_OK;
    sy_fimage hl = {0}, leaf_rgb[2] = {{0}}, trans_rgb[2] = {{0}};
    if ((rc = sy_fimage_alloc(&s->alpha, n, n, 1, err)) || (rc = sy_fimage_alloc(&s->thickness, n, n, 1, err)) ||
        (rc = sy_fimage_alloc(&hl, n, n, 1, err)))
        goto done;
    for (int k = 0; k < 2; k++)
        if ((rc = sy_fimage_alloc(&s->albedo[k], n, n, 3, err)) || (rc = sy_fimage_alloc(&s->normal[k], n, n, 3, err)) ||
            (rc = sy_fimage_alloc(&s->height[k], n, n, 1, err)))
            goto done;
    /* Truth in the adaxial photo frame. */
    double bend_mean = 0, dsum = 0, cnt = 0;
    for (int y = 0; y < n; y++)
        for (int x = 0; x < n; x++) {
            size_t i = (size_t)y * n + x;
            double a, c;
            leaf_coords(n, rot, x + 0.5, y + 0.5, &a, &c);
            double half = a > 0.1 && a < 1 ? 0.27 * pow(sin(SY_LEAF_PI * (a - 0.1) / 0.9), 0.8) : 0;
            int petiole = a >= 0 && a <= 0.12 && fabs(c) < 0.012;
            double hx = a - 0.55, hy = c - 0.12; /* an insect hole */
            int hole = hx * hx + hy * hy < 0.03 * 0.03;
            int in = (fabs(c) < half || petiole) && !hole;
            s->alpha.px[i] = in ? 1.0f : 0.0f;
            if (!in) continue;
            /* Veins: a midrib and lateral veins running towards the tip. */
            double mid = exp(-pow(c / 0.012, 2));
            double phase = (a - 1.2 * fabs(c)) * 9;
            double dv = fabs(phase - floor(phase + 0.5)) / 9;
            double lat = a > 0.15 ? exp(-pow(dv / 0.006, 2)) * (1 - fabs(c) / (half + 1e-9)) : 0;
            double vein = fmax(mid, 0.6 * lat);
            double var = noise(a * 6, c * 6, seed);
            double d = 0.19 + 0.03 * var + 0.10 * mid * (1 - 0.6 * a) + 0.03 * lat;
            if (petiole && fabs(c) >= half) d = 0.35;
            s->thickness.px[i] = (float)d;
            dsum += d, cnt++;
            double tint = 1 + 0.12 * noise(a * 14, c * 14, seed + 1);
            static const double ad[3] = {0.060, 0.160, 0.035}, ab[3] = {0.120, 0.240, 0.080};
            for (int ch = 0; ch < 3; ch++) {
                s->albedo[0].px[3 * i + ch] = (float)(ad[ch] * tint * (1 + 0.5 * vein));
                s->albedo[1].px[3 * i + ch] = (float)(ab[ch] * tint * (1 + 0.35 * vein));
            }
            /* Bending (both surfaces move together) and small bumps. */
            double bend = 2.5 * c * c * LEAF_LENGTH_MM * 0.05 + 0.02 * noise(a * 30, c * 30, seed + 2);
            s->height[0].px[i] = (float)bend;
            bend_mean += bend;
        }
    double dbar = cnt ? dsum / cnt : 0.2;
    bend_mean = cnt ? bend_mean / cnt : 0;
    for (size_t i = 0; i < np; i++) {
        if (s->alpha.px[i] < 0.5f) continue;
        double half_var = 0.5 * (s->thickness.px[i] - dbar), b = s->height[0].px[i] - bend_mean;
        s->height[0].px[i] = (float)(half_var + b);
        s->height[1].px[i] = (float)(half_var - b);
    }
    /* Truth normals from the truth heights (photo frame; tangent X = photo right, Y = photo up). */
    for (int k = 0; k < 2; k++)
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++) {
                size_t i = (size_t)y * n + x;
                float *nr = s->normal[k].px + 3 * i;
                int xl = x > 0 && s->alpha.px[i - 1] >= 0.5f ? x - 1 : x;
                int xr = x < n - 1 && s->alpha.px[i + 1] >= 0.5f ? x + 1 : x;
                int yu = y > 0 && s->alpha.px[i - n] >= 0.5f ? y - 1 : y;
                int yd = y < n - 1 && s->alpha.px[i + n] >= 0.5f ? y + 1 : y;
                const float *hh = s->height[k].px;
                double dx = xr > xl ? (hh[(size_t)y * n + xr] - hh[(size_t)y * n + xl]) / ((xr - xl) * s->texel_mm) : 0;
                double dy = yd > yu ? (hh[(size_t)yu * n + x] - hh[(size_t)yd * n + x]) / ((yd - yu) * s->texel_mm) : 0;
                double l = sqrt(dx * dx + dy * dy + 1);
                nr[0] = (float)(-dx / l), nr[1] = (float)(-dy / l), nr[2] = (float)(1 / l);
            }
    /* Transmission under uniform back light, per unit irradiance, by the
     * model: M_seen = (1 - a_seen) A_p sum T(r, d(x_i)) (1 - a_lit(x_i)). */
    float *E[2] = {malloc(np * sizeof(float)), malloc(np * sizeof(float))};
    float *P[2] = {malloc(np * sizeof(float)), malloc(np * sizeof(float))};
    if (!E[0] || !E[1] || !P[0] || !P[1]) rc = sy_fail(err, SY_EINTERNAL, "synthetic leaf: out of memory");
    double rho = 0;
    for (size_t i = 0; i < np; i++)
        if (s->alpha.px[i] >= 0.5f) rho += s->albedo[0].px[3 * i + 1] + s->albedo[1].px[3 * i + 1];
    sy_dipole dp = sy_dipole_make(o->sigma_a, o->sigma_s, o->g, cnt ? rho / (2 * cnt) : 0.1, o->multipoles);
    for (int seen = 0; !rc && seen < 2; seen++)
        for (size_t i = 0; i < np; i++) E[seen][i] = s->alpha.px[i] >= 0.5f ? 1 - s->albedo[1 - seen].px[3 * i + 1] : 0;
    if (!rc)
        rc = sy_leaf_convolve((const float *const *)E, 2, s->thickness.px, s->alpha.px, n, n, s->texel_mm, &dp, 32, P,
                              NULL, err);
    for (int k = 0; !rc && k < 2; k++) {
        if ((rc = sy_fimage_alloc(&leaf_rgb[k], n, n, 4, err)) || (rc = sy_fimage_alloc(&trans_rgb[k], n, n, 4, err)))
            break;
        for (size_t i = 0; i < np; i++) {
            double a_seen = s->albedo[k].px[3 * i + 1];
            double mg = (1 - a_seen) * P[k][i];
            static const double hue[3] = {0.55, 1.0, 0.22};
            for (int ch = 0; ch < 3; ch++) {
                double lim = 1 - s->albedo[1 - k].px[3 * i + ch];
                double v = mg * hue[ch];
                trans_rgb[k].px[4 * i + ch] = (float)(v < lim ? v : lim);
                leaf_rgb[k].px[4 * i + ch] = s->albedo[k].px[3 * i + ch];
            }
            trans_rgb[k].px[4 * i + 3] = leaf_rgb[k].px[4 * i + 3] = s->alpha.px[i];
        }
    }
    free(E[0]), free(E[1]), free(P[0]), free(P[1]);
    if (rc) goto done;
    /* Highlights on the adaxial photo (not in the truth). */
    for (int k = 0; k < 3; k++) {
        double a = 0.35 + 0.2 * k, c = 0.06 * (k - 1);
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++) {
                double aa, cc;
                leaf_coords(n, rot, x + 0.5, y + 0.5, &aa, &cc);
                double r2 = ((aa - a) * (aa - a) + (cc - c) * (cc - c)) / (0.006 * 0.006);
                if (r2 < 4) hl.px[(size_t)y * n + x] += (float)(0.25 * exp(-r2));
            }
    }
    /* The captures: capture frame -> adaxial frame affines (sy_lcv_warp's
     * destination-to-source form). Abaxial captures are mirrored; back-lit
     * photos moved by `shift` px and 0.3 degrees. */
    static const double white_level[3] = {0.85, 0.9, 0.8}, bg[3] = {0.35, 0.33, 0.30};
    static const double flat_tint[3] = {0.95, 1.0, 0.9};
    double ang = 0.3 * SY_LEAF_PI / 180, ca = cos(ang), sa = sin(ang);
    for (int k = 0; k < 4 && !rc; k++) {
        int side = k / 2, transmitted = k & 1;
        double A[6] = {1, 0, 0, 0, 1, 0};
        if (transmitted) {
            double cx = n / 2.0, cy = n / 2.0;
            A[0] = ca, A[1] = -sa, A[3] = sa, A[4] = ca;
            A[2] = cx - ca * cx + sa * cy - 0.5 * shift;
            A[5] = cy - sa * cx - ca * cy + shift;
        }
        if (side) {
            /* x_adaxial = n - 1 - x_abaxial after the abaxial's own shift. */
            double B[6] = {-A[0], -A[1], n - 1 - (A[2] + A[0] * shift), A[3], A[4], A[5] + 0.5 * shift};
            memcpy(A, B, sizeof A);
        }
        sy_fimage *src = transmitted ? &trans_rgb[side] : &leaf_rgb[side];
        sy_fimage warped = {0};
        if ((rc = sy_fimage_alloc(&warped, n, n, 4, err))) break;
        if ((rc = sy_lcv_warp(src->px, n, n, 4, A, warped.px, n, n, 0, err))) {
            sy_fimage_free(&warped);
            sy_error_prefix(err, "synthetic leaf");
            break;
        }
        float *hlw = NULL;
        if (!transmitted && side == 0) hlw = hl.px;
        sy_fimage *out = transmitted ? &s->transmitted[side] : &s->reflected[side];
        if ((rc = sy_fimage_alloc(out, n, n, 3, err))) {
            sy_fimage_free(&warped);
            break;
        }
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++) {
                size_t i = (size_t)y * n + x;
                double al = warped.px[4 * i + 3];
                double rx = (x - n / 2.0) / n, ry = (y - n / 2.0) / n;
                double flat = 0.9 * (1 - 0.25 * (rx * rx + ry * ry) * 4);
                for (int ch = 0; ch < 3; ch++) {
                    double leaf = al > 1e-6 ? warped.px[4 * i + ch] / al : 0, v;
                    if (transmitted) v = flat * flat_tint[ch] * (al * leaf + (1 - al));
                    else v = white_level[ch] * (al * leaf + (1 - al) * bg[ch]) + (hlw ? white_level[ch] * hlw[i] * al : 0);
                    out->px[3 * i + ch] = (float)v;
                }
            }
        sy_fimage_free(&warped);
        if (!transmitted) {
            const int *r = s->white_rect;
            for (int y = r[1]; y < r[1] + r[3]; y++)
                for (int x = r[0]; x < r[0] + r[2]; x++)
                    for (int ch = 0; ch < 3; ch++)
                        out->px[3 * ((size_t)y * n + x) + ch] = (float)(white_level[ch] * s->white_reflectance);
        }
        if (!transmitted && side == 1) {
            /* The abaxial scan lives in the abaxial photo's frame. */
            sy_fimage hw = {0};
            if ((rc = sy_fimage_alloc(&hw, n, n, 1, err))) break;
            if ((rc = sy_lcv_warp(s->height[1].px, n, n, 1, A, hw.px, n, n, 1, err))) sy_error_prefix(err, "synthetic leaf");
            sy_fimage_free(&s->height[1]);
            s->height[1] = hw;
        }
    }
    if (!rc) rc = sy_fimage_alloc(&s->flat_field, n, n, 3, err);
    for (int y = 0; !rc && y < n; y++)
        for (int x = 0; x < n; x++) {
            double rx = (x - n / 2.0) / n, ry = (y - n / 2.0) / n;
            double flat = 0.9 * (1 - 0.25 * (rx * rx + ry * ry) * 4);
            for (int ch = 0; ch < 3; ch++) s->flat_field.px[3 * ((size_t)y * n + x) + ch] = (float)(flat * flat_tint[ch]);
        }
done:
    sy_fimage_free(&hl);
    for (int k = 0; k < 2; k++) sy_fimage_free(&leaf_rgb[k]), sy_fimage_free(&trans_rgb[k]);
    if (rc) sy_leaf_synthetic_free(s);
    return rc;
}
