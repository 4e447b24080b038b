/* The sRGB transfer function (IEC 61966-2-1), shared by every stage that
 * reads photos or writes colour textures: images on disk are sRGB, Sylva's
 * arithmetic is linear. Inputs are clamped to [0, 1]. */
#ifndef SYLVA_COLOR_H
#define SYLVA_COLOR_H

#include <math.h>

#ifdef __cplusplus
extern "C" {
#endif

static inline double sy_srgb_to_linear(double c)
{
    c = c < 0 ? 0 : c > 1 ? 1 : c;
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

static inline double sy_linear_to_srgb(double v)
{
    v = v < 0 ? 0 : v > 1 ? 1 : v;
    return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
}

#ifdef __cplusplus
}
#endif

#endif
