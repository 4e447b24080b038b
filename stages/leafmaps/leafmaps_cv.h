/* The OpenCV parts of the leaf-maps stage behind a C interface: image files,
 * masks, warps, ECC registration, blurs and FFT convolution. Float images
 * are row-major with interleaved channels; masks are one byte per pixel (0 or
 * 255). Every function returns SY_OK, or a code with a one-line reason in
 * err that names the operation (the caller puts its file or step in front
 * with sy_error_prefix); none throws. OpenCV failures (out of memory, no
 * convergence) are SY_EINTERNAL. */
#ifndef SYLVA_LEAFMAPS_CV_H
#define SYLVA_LEAFMAPS_CV_H

#include <stddef.h>

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* (image_io.c, stb_image and zlib, no OpenCV:) Decodes an image file (PNG
 * 8/16-bit, JPEG, BMP, TGA, PNM) into floats in [0,1] without
 * any colour conversion, channels in R,G,B(,A) order; grey images have c = 1.
 * *depth is 8 or 16 (bits per sample of the file). *px is malloc'ed.
 * SY_EINPUT when the file cannot be read or decoded (err names path). */
sy_code sy_lcv_read(const char *path, float **px, int *w, int *h, int *c, int *depth, sy_error *err);

/* Encodes [0,1] floats as PNG with 8 or 16 bits per sample (c = 1, 3 or 4,
 * R,G,B(,A) order). *png is malloc'ed. */
sy_code sy_lcv_encode_png(const float *px, int w, int h, int c, int bits, unsigned char **png, size_t *size,
                          sy_error *err);

/* Binary mask cleanup: opening then closing with a disc of radius r px,
 * components smaller than min_frac of the largest removed, holes (background
 * components not touching the border) smaller than max_hole px filled. */
sy_code sy_lcv_mask_clean(unsigned char *mask, int w, int h, int r, double min_frac, int max_hole, sy_error *err);

/* Otsu threshold of v (n values, any range) over the pixels where use != 0
 * (use may be NULL); returns the threshold in v's units through *t.
 * SY_EINPUT when the selected values are all equal (nothing to split). */
sy_code sy_lcv_otsu(const float *v, const unsigned char *use, int w, int h, double *t, sy_error *err);

/* Warps src (c channels) with the 2x3 affine M mapping destination pixel
 * coordinates to source coordinates (bilinear; border: replicate if
 * replicate else constant 0) into dst of dw x dh. */
sy_code sy_lcv_warp(const float *src, int w, int h, int c, const double M[6], float *dst, int dw, int dh,
                    int replicate, sy_error *err);

/* Euclidean ECC (Evangelidis & Psarakis 2008): finds M (2x3, destination ->
 * source as sy_lcv_warp takes it) so that mov warped by M matches ref. Both
 * single channel, same size. M holds the initial guess on entry.
 * SY_EINTERNAL also when ECC does not converge. */
sy_code sy_lcv_register(const float *ref, const float *mov, int w, int h, double M[6], sy_error *err);

/* Gaussian blur (sigma px) of each channel, replicated borders. */
sy_code sy_lcv_blur(const float *src, int w, int h, int c, double sigma, float *dst, sy_error *err);

/* Area resize (c channels). */
sy_code sy_lcv_resize(const float *src, int w, int h, int c, float *dst, int dw, int dh, sy_error *err);

/* out[i] = sum_k conv(in[i*n_k + k], kernel[k]) for i < n_out, with zero
 * padding, 'same' size (w x h); kernels are (2r+1)^2, centred. FFTs run on
 * `threads` threads over the outputs; results do not depend on it. */
sy_code sy_lcv_convolve_sum(const float *const *in, int n_out, int n_k, const float *const *kernel, int r, int w,
                            int h, float *const *out, int threads, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
