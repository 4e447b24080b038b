/* The OpenCV filtering behind species materials, behind a C interface.
 * Images are 8-bit, row-major, tightly packed; RGBA has 4 channels. Every
 * function returns SY_OK, or SY_EINTERNAL with OpenCV's reason in err (out of
 * memory). */
#ifndef SYLVA_IMAGE_CV_H
#define SYLVA_IMAGE_CV_H

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Area-averaged resize of an RGBA image; colour is averaged with alpha
 * weights so transparent background colours do not bleed into edges. */
sy_code sy_cv_resize_rgba(const unsigned char *src, int w, int h, unsigned char *dst, int dw, int dh,
                          sy_error *err);

/* Tangent-space normal map (RGB, glTF convention: +X right, +Y up, +Z out)
 * from the luminance of an RGBA image read as a height field in [0,1]:
 * n = normalize(-s dh/dx, -s dh/dy_up, 1) with Sobel derivatives per pixel.
 * wrap: 1 for tiling textures (bark), 0 to replicate the edges (cards). */
sy_code sy_cv_normal_map(const unsigned char *rgba, int w, int h, float strength, int wrap, unsigned char *rgb,
                         sy_error *err);

/* Sets alpha for an image without one: pixels whose colour differs from the
 * background (the median of the border pixels) by more than threshold
 * (0..255, Euclidean in RGB) become opaque, the rest transparent. */
sy_code sy_cv_alpha_from_background(unsigned char *rgba, int w, int h, float threshold, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
