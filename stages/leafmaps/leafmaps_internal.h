/* Shared inside stages/leafmaps only. */
#ifndef SYLVA_LEAFMAPS_INTERNAL_H
#define SYLVA_LEAFMAPS_INTERNAL_H

#include "stages/leafmaps/leafmaps.h"

#ifdef __cplusplus
extern "C" {
#endif

/* out[i](x_o) = A_p sum_{x_i} T(|x_o - x_i|, d(x_i)) in[i](x_i) for i < n_out
 * (eq 3.16 with the non-stationary kernel), by FFT: the kernel is tabulated
 * at `bins` thicknesses over the range of d inside the mask and each input is
 * split between the two nearest bins (hat weights). Texels with alpha < 0.5
 * carry no light. *radius_mm (may be NULL) gets the kernel radius used. */
sy_code sy_leaf_convolve(const float *const *in, int n_out, const float *d, const float *alpha, int w, int h,
                         double texel_mm, const sy_dipole *m, int bins, float *const *out, double *radius_mm,
                         sy_error *err);

#define SY_LEAF_PI 3.14159265358979323846

static inline float sy_leaf_luma(const float *rgb)
{
    return 0.2126f * rgb[0] + 0.7152f * rgb[1] + 0.0722f * rgb[2];
}

#ifdef __cplusplus
}
#endif

#endif
