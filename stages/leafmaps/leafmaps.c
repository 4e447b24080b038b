/* Leaf maps from captures (leafmaps.h): segmentation, orientation,
 * registration, albedo, translucency, thickness, normals, horizon map and
 * the directional-translucency precompute of Habel, Kusternig & Wimmer,
 * "Physically Based Real-Time Translucency for Leaves" (EGSR 2007, §3.3).
 *
 * The precompute uses linearity: the thesis convolves the irradiance of each
 * of N_L light directions and projects the N_L results into the HL2 basis;
 * since the projection h = W L is linear and so is the convolution, the same
 * coefficients come from convolving the three projected irradiances
 * E_i = sum_m W_im E(., w_m). Three FFT convolutions per lit side replace 128
 * and give identical coefficients. */
#include "stages/leafmaps/leafmaps.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "stages/core/color.h"
#include "stages/core/parallel.h"
#include "stages/core/sort.h"
#include "stages/leafmaps/leafmaps_cv.h"
#include "stages/leafmaps/leafmaps_internal.h"

#define MIN_SIDE 8
#define MAX_KERNEL_RADIUS 128
#define HORIZON_STEPS 12

/* ---------------------------------------------------------------- images */

sy_code sy_fimage_alloc(sy_fimage *im, int w, int h, int c, sy_error *err)
{
    im->w = w, im->h = h, im->c = c;
    im->px = sy_calloc((size_t)w * (size_t)h * (size_t)c, sizeof(float), err, "image");
    return im->px ? SY_OK : SY_EINTERNAL;
}

void sy_fimage_free(sy_fimage *im)
{
    free(im->px);
    im->px = NULL;
}

void sy_leaf_maps_free(sy_leaf_maps *m)
{
    free(m->alpha);
    free(m->thickness);
    for (int s = 0; s < 2; s++) {
        free(m->albedo[s]);
        free(m->translucency[s]);
        free(m->height[s]);
        free(m->normal[s]);
        free(m->hl2[s]);
        free(m->hl2_scale[s]);
    }
    memset(m, 0, sizeof *m);
}

/* --------------------------------------------------------------- options */

sy_leafmaps_options sy_leafmaps_options_default(void)
{
    sy_leafmaps_options o;
    memset(&o, 0, sizeof o);
    o.texel_mm = 0;
    o.leaf_length_mm = 80;
    o.thickness_mm = 0.2;
    o.sigma_a = 0.4; /* thesis Table 3.1, 510 nm */
    o.sigma_s = 10.2;
    o.g = 0.07;
    o.multipoles = 3;
    o.directions = 128;
    o.sectors = 16;
    o.thickness_bins = 8;
    o.inversion_iterations = 4;
    o.size = 1024;
    o.orient = 1;
    o.highlight_ratio = 1.3;
    o.relief_mm = 0.03;
    o.tint[0] = o.tint[1] = o.tint[2] = -1;
    o.seed = 0;
    return o;
}

sy_code sy_leafmaps_options_check(const sy_leafmaps_options *o, sy_error *err)
{
    if (!(o->texel_mm >= 0 && o->texel_mm <= 10))
        return sy_fail(err, SY_EUSAGE, "leafmaps: texel_mm %g is outside [0, 10] mm", o->texel_mm);
    if (!(o->leaf_length_mm > 1 && o->leaf_length_mm <= 2000))
        return sy_fail(err, SY_EUSAGE, "leafmaps: leaf_length_mm %g is outside (1, 2000] mm", o->leaf_length_mm);
    sy_dipole m = sy_dipole_make(o->sigma_a, o->sigma_s, o->g, 0, 1);
    if (!(o->sigma_a > 0 && o->sigma_a < 100 && o->sigma_s > 0 && o->sigma_s < 1000 && o->g > -1 && o->g < 1))
        return sy_fail(err, SY_EUSAGE, "leafmaps: sigma_a %g, sigma_s %g or g %g is out of range", o->sigma_a, o->sigma_s,
                       o->g);
    if (!(o->thickness_mm >= 1.2 * m.l && o->thickness_mm <= 5))
        return sy_fail(err, SY_EUSAGE,
                       "leafmaps: thickness_mm %g is outside [%.3f, 5] mm (the diffusion model needs d > 1.2/sigma_t')",
                       o->thickness_mm, 1.2 * m.l);
    if (o->multipoles < 0 || o->multipoles > 50) return sy_fail(err, SY_EUSAGE, "leafmaps: multipoles %d is outside 0..50", o->multipoles);
    if (o->directions < 3 || o->directions > 4096)
        return sy_fail(err, SY_EUSAGE, "leafmaps: directions %d is outside 3..4096", o->directions);
    if (o->sectors < 4 || o->sectors > 64) return sy_fail(err, SY_EUSAGE, "leafmaps: sectors %d is outside 4..64", o->sectors);
    if (o->thickness_bins < 1 || o->thickness_bins > 64)
        return sy_fail(err, SY_EUSAGE, "leafmaps: thickness_bins %d is outside 1..64", o->thickness_bins);
    if (o->inversion_iterations < 0 || o->inversion_iterations > 50)
        return sy_fail(err, SY_EUSAGE, "leafmaps: inversion_iterations %d is outside 0..50", o->inversion_iterations);
    if (o->size < 16 || o->size > 8192 || (o->size & (o->size - 1)))
        return sy_fail(err, SY_EUSAGE, "leafmaps: size %d is not a power of two in 16..8192", o->size);
    if (!(o->highlight_ratio > 1 && o->highlight_ratio < 10))
        return sy_fail(err, SY_EUSAGE, "leafmaps: highlight_ratio %g is outside (1, 10)", o->highlight_ratio);
    if (!(o->relief_mm >= 0 && o->relief_mm <= 5)) return sy_fail(err, SY_EUSAGE, "leafmaps: relief_mm %g is outside [0, 5]", o->relief_mm);
    if (o->tint[0] >= 0 || o->tint[1] >= 0 || o->tint[2] >= 0)
        for (int c = 0; c < 3; c++)
            if (!(o->tint[c] >= 0 && o->tint[c] <= 255))
                return sy_fail(err, SY_EUSAGE, "leafmaps: tint %g,%g,%g is not an sRGB colour in 0..255", o->tint[0],
                               o->tint[1], o->tint[2]);
    return SY_OK;
}

/* ----------------------------------------------------------- small tools */

static double cpu_now(void)
{
    return (double)clock() / CLOCKS_PER_SEC;
}

static double wall_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void say(const sy_leafmaps_options *o, const char *what)
{
    if (o->progress) fprintf(stderr, "leaf: %s\n", what);
}

/* Median of v over mask (alpha >= 0.5); 0 if empty. */
static double masked_median(const float *v, const float *alpha, size_t n, float *scratch)
{
    size_t k = 0;
    for (size_t i = 0; i < n; i++)
        if (alpha[i] >= 0.5f) scratch[k++] = v[i];
    if (!k) return 0;
    qsort(scratch, k, sizeof *scratch, sy_cmp_float);
    return k % 2 ? scratch[k / 2] : 0.5 * (scratch[k / 2 - 1] + scratch[k / 2]);
}

/* 2x3 affine maps: p_src = M p_dst. */
static void affine_compose(const double A[6], const double B[6], double out[6]) /* out = A after B: x -> A(B x) */
{
    double r[6];
    r[0] = A[0] * B[0] + A[1] * B[3];
    r[1] = A[0] * B[1] + A[1] * B[4];
    r[2] = A[0] * B[2] + A[1] * B[5] + A[2];
    r[3] = A[3] * B[0] + A[4] * B[3];
    r[4] = A[3] * B[1] + A[4] * B[4];
    r[5] = A[3] * B[2] + A[4] * B[5] + A[5];
    memcpy(out, r, sizeof r);
}

/* Recolours the albedo (linear RGB, n texels) to the mean colour tint (sRGB
 * 0..255) over the leaf (alpha >= 0.5): each texel is the tint times its
 * luminance over the leaf's mean luminance, so veins, shading and the
 * petiole keep their contrast (species/materials.c's bark_color, in linear
 * light). Texels outside the leaf are left as they are. */
static void tint_albedo(float *rgb, const float *alpha, size_t n, const double tint[3])
{
    double sum = 0;
    size_t k = 0;
    for (size_t i = 0; i < n; i++)
        if (alpha[i] >= 0.5f) sum += sy_leaf_luma(rgb + 3 * i), k++;
    if (k == 0 || !(sum > 0)) return;
    double mean = sum / (double)k, lin[3];
    for (int c = 0; c < 3; c++) lin[c] = sy_srgb_to_linear(tint[c] / 255);
    for (size_t i = 0; i < n; i++) {
        if (alpha[i] < 0.5f) continue;
        double l = sy_leaf_luma(rgb + 3 * i) / mean;
        for (int c = 0; c < 3; c++) {
            double v = lin[c] * l;
            rgb[3 * i + c] = (float)(v > 0.98 ? 0.98 : v);
        }
    }
}

/* ---------------------------------------------------------- segmentation */

/* Perceptual-ish coordinates for colour distances: linear -> gamma 1/2.2. */
static float gamma_enc(float v)
{
    return v > 0 ? powf(v, 1.0f / 2.2f) : 0.0f;
}

/* Leaf mask of a photo: its alpha when it has one that is not all opaque,
 * else the pixels whose colour differs from the background (the median of
 * the border) by more than Otsu's threshold of the colour distance. */
static sy_code photo_mask(const sy_fimage *im, unsigned char *mask, const char *what, sy_error *err)
{
    size_t n = (size_t)im->w * (size_t)im->h;
    int w = im->w, h = im->h;
    int alpha_used = 0;
    if (im->c == 4)
        for (size_t i = 0; i < n && !alpha_used; i++) alpha_used = im->px[4 * i + 3] < 0.99f;
    if (alpha_used) {
        for (size_t i = 0; i < n; i++) mask[i] = im->px[4 * i + 3] >= 0.5f ? 255 : 0;
    } else {
        size_t nb = 2 * (size_t)w + 2 * (size_t)h;
        double *border = malloc(nb * sizeof *border);
        float *dist = malloc(n * sizeof *dist);
        if (!border || !dist) {
            free(border), free(dist);
            return sy_fail(err, SY_EINTERNAL, "%s: out of memory", what);
        }
        float bg[3];
        for (int c = 0; c < 3; c++) {
            size_t k = 0;
            for (int x = 0; x < w; x++) {
                border[k++] = gamma_enc(im->px[(size_t)x * im->c + c]);
                border[k++] = gamma_enc(im->px[((size_t)(h - 1) * w + x) * im->c + c]);
            }
            for (int y = 0; y < h; y++) {
                border[k++] = gamma_enc(im->px[((size_t)y * w) * im->c + c]);
                border[k++] = gamma_enc(im->px[((size_t)y * w + w - 1) * im->c + c]);
            }
            qsort(border, k, sizeof *border, sy_cmp_double);
            bg[c] = (float)border[k / 2];
        }
        for (size_t i = 0; i < n; i++) {
            float d2 = 0;
            for (int c = 0; c < 3; c++) {
                float d = gamma_enc(im->px[i * im->c + c]) - bg[c];
                d2 += d * d;
            }
            dist[i] = sqrtf(d2);
        }
        double t;
        sy_code rc = sy_lcv_otsu(dist, NULL, w, h, &t, err);
        if (rc) {
            free(border), free(dist);
            /* One colour everywhere: no leaf stands out of the background. */
            if (rc == SY_EINPUT) return sy_fail(err, SY_EINPUT, "%s: no leaf found (the image is all background)", what);
            return sy_error_prefix(err, what);
        }
        if (t < 0.04) t = 0.04; /* noise alone never makes a leaf */
        for (size_t i = 0; i < n; i++) mask[i] = dist[i] > t ? 255 : 0;
        free(border), free(dist);
    }
    /* An alpha channel is exact: only specks and pinholes go. A colour
     * threshold also needs an opening (noise) and a closing (dark veins). */
    int r = alpha_used ? 0 : 1;
    int max_hole = alpha_used ? 2 : (int)(n / 2000) + 4; /* glints look like background */
    if (sy_lcv_mask_clean(mask, w, h, r, alpha_used ? 0.0005 : 0.002, max_hole, err)) return sy_error_prefix(err, what);
    size_t count = 0;
    for (size_t i = 0; i < n; i++) count += mask[i] != 0;
    if (count < 16) return sy_fail(err, SY_EINPUT, "%s: no leaf found (the image is all background)", what);
    return SY_OK;
}

/* Mask of a back-lit photo: the leaf is darker than the back light. */
static sy_code transmit_mask(const sy_fimage *ratio, unsigned char *mask, const char *what, sy_error *err)
{
    size_t n = (size_t)ratio->w * (size_t)ratio->h;
    float *lum = calloc(n, sizeof *lum);
    if (!lum) return sy_fail(err, SY_EINTERNAL, "%s: out of memory", what);
    for (size_t i = 0; i < n; i++) lum[i] = sy_leaf_luma(ratio->px + 3 * i);
    double t;
    sy_code rc = sy_lcv_otsu(lum, NULL, ratio->w, ratio->h, &t, err);
    if (!rc)
        for (size_t i = 0; i < n; i++) mask[i] = lum[i] < t ? 255 : 0;
    free(lum);
    if (rc == SY_EINPUT) return sy_fail(err, SY_EINPUT, "%s: no leaf found in the back-lit photo", what);
    if (rc) return sy_error_prefix(err, what);
    int r = (ratio->w < ratio->h ? ratio->w : ratio->h) / 300;
    if (sy_lcv_mask_clean(mask, ratio->w, ratio->h, r, 0.02, (int)(n / 4000) + 4, err)) return sy_error_prefix(err, what);
    return SY_OK;
}

/* The white reference is no part of the leaf (2 px margin). */
static void clear_rect(unsigned char *mask, int w, int h, const int r[4])
{
    if (r[2] <= 0) return;
    for (int y = r[1] - 2; y < r[1] + r[3] + 2; y++)
        for (int x = r[0] - 2; x < r[0] + r[2] + 2; x++)
            if (x >= 0 && y >= 0 && x < w && y < h) mask[(size_t)y * w + x] = 0;
}

/* ------------------------------------------------------------ orientation */

/* The output frame: M maps output texel centres (u, v) to photo pixels. The
 * leaf's main axis (largest principal direction of the mask) becomes
 * vertical, the thinner end (the petiole) goes down and to the bottom
 * centre, and the leaf fills size x size with a 3 % margin. *scale is output
 * texels per photo pixel. */
static void orient_frame(const unsigned char *mask, int w, int h, int size, int orient, double M[6], double *scale)
{
    double sx = 0, sy = 0, sxx = 0, syy = 0, sxy = 0, cnt = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            if (mask[(size_t)y * w + x]) {
                sx += x, sy += y, cnt++;
            }
    double cx = sx / cnt, cy = sy / cnt;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            if (mask[(size_t)y * w + x]) {
                double dx = x - cx, dy = y - cy;
                sxx += dx * dx, syy += dy * dy, sxy += dx * dy;
            }
    /* Axis direction a (unit, photo coordinates, y down) of the leaf's length. */
    double ax = 0, ay = -1; /* photo up */
    if (orient) {
        double theta = 0.5 * atan2(2 * sxy, sxx - syy);
        ax = cos(theta), ay = sin(theta);
        /* Keep the axis within 45 degrees of the photo's vertical when the
         * leaf is round (no clear main axis): a nearly isotropic mask. */
        double tr = sxx + syy, det = sxx * syy - sxy * sxy;
        double l1 = 0.5 * tr + sqrt(fmax(0, 0.25 * tr * tr - det)), l2 = tr - l1;
        if (l1 < 1.1 * l2) ax = 0, ay = -1;
    }
    /* Extent along the axis; the end with less mass in its last 10 % is the
     * petiole. The leaf's "up" (tip) direction is u = -petiole direction. */
    double tmin = DBL_MAX, tmax = -DBL_MAX;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            if (mask[(size_t)y * w + x]) {
                double t = (x - cx) * ax + (y - cy) * ay;
                if (t < tmin) tmin = t;
                if (t > tmax) tmax = t;
            }
    double len = tmax - tmin;
    double m_lo = 0, m_hi = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            if (mask[(size_t)y * w + x]) {
                double t = (x - cx) * ax + (y - cy) * ay;
                if (t < tmin + 0.1 * len) m_lo++;
                if (t > tmax - 0.1 * len) m_hi++;
            }
    /* up = direction from petiole to tip, photo coordinates. */
    double ux, uy;
    if (!orient) ux = 0, uy = -1;
    else if (m_lo < m_hi) ux = ax, uy = ay; /* petiole at tmin: up is +a */
    else ux = -ax, uy = -ay;
    /* right = up rotated so that (right, up) keeps the photo's handedness
     * (photo right (1,0), up (0,-1)): right = (-uy, ux). */
    double rx = -uy, ry = ux;
    /* Leaf coordinates: along = (p - c).up, across = (p - c).right. */
    double amin = DBL_MAX, amax = -DBL_MAX;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            if (mask[(size_t)y * w + x]) {
                double a = (x - cx) * ux + (y - cy) * uy;
                if (a < amin) amin = a;
                if (a > amax) amax = a;
            }
    /* Petiole position across: mean of the bottom 3 % of the leaf. */
    double pc = 0, pn = 0, half = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            if (mask[(size_t)y * w + x]) {
                double a = (x - cx) * ux + (y - cy) * uy, c = (x - cx) * rx + (y - cy) * ry;
                if (a < amin + 0.03 * (amax - amin) + 1) pc += c, pn++;
            }
    pc = pn ? pc / pn : 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            if (mask[(size_t)y * w + x]) {
                double c = fabs((x - cx) * rx + (y - cy) * ry - pc);
                if (c > half) half = c;
            }
    double extent = fmax(amax - amin + 1, 2 * half + 2);
    double s = 0.94 * size / extent; /* output texels per photo pixel */
    double margin = 0.03 * size;
    /* Output (u, v), v down: across = (u + 0.5 - size/2)/s + pc,
     * along = amin + (size - margin - (v + 0.5))/s. p = c + across r + along up. */
    double k = 1 / s;
    M[0] = k * rx;
    M[1] = -k * ux;
    M[2] = cx + rx * ((0.5 - size / 2.0) * k + pc) + ux * (amin + (size - margin - 0.5) * k);
    M[3] = k * ry;
    M[4] = -k * uy;
    M[5] = cy + ry * ((0.5 - size / 2.0) * k + pc) + uy * (amin + (size - margin - 0.5) * k);
    *scale = s;
}

/* --------------------------------------------------------------- capture */

static sy_code check_image(const sy_fimage *im, const sy_fimage *ref, int want_c, const char *what, sy_error *err)
{
    if (!im) return SY_OK;
    if (!im->px || im->w < MIN_SIDE || im->h < MIN_SIDE)
        return sy_fail(err, SY_EINPUT, "%s: image is %dx%d, smaller than %dx%d", what, im->w, im->h, MIN_SIDE,
                       MIN_SIDE);
    if (want_c == 1 && im->c != 1) return sy_fail(err, SY_EINPUT, "%s: a height map needs one channel, not %d", what, im->c);
    if (want_c == 3 && im->c != 3 && im->c != 4)
        return sy_fail(err, SY_EINPUT, "%s: a photo needs RGB or RGBA, not %d channel(s)", what, im->c);
    if (ref && (im->w != ref->w || im->h != ref->h))
        return sy_fail(err, SY_EINPUT, "%s: size %dx%d does not match the adaxial photo's %dx%d", what, im->w, im->h,
                       ref->w, ref->h);
    for (size_t i = 0; i < (size_t)im->w * im->h * im->c; i++)
        if (!isfinite(im->px[i])) return sy_fail(err, SY_EINPUT, "%s: pixel values are not finite", what);
    return SY_OK;
}

/* Mirror about the vertical axis (the leaf was turned over for side 1). */
static void mirror_affine(int w, double M[6])
{
    double F[6] = {-1, 0, w - 1, 0, 1, 0};
    affine_compose(F, M, M);
}

/* Warp of an image through M into the output frame, first c_out channels. */
static sy_code warp_into(const sy_fimage *src, int c_out, const double M[6], int size, int replicate, float **dst,
                         sy_error *err)
{
    float *full = sy_calloc((size_t)size * size, (size_t)src->c * sizeof(float), err, "warp");
    if (!full) return SY_EINTERNAL;
    if (sy_lcv_warp(src->px, src->w, src->h, src->c, M, full, size, size, replicate, err)) {
        free(full);
        return err->code;
    }
    if (c_out == src->c) {
        *dst = full;
        return SY_OK;
    }
    float *out = sy_calloc((size_t)size * size, (size_t)c_out * sizeof(float), err, "warp");
    if (!out) {
        free(full);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < (size_t)size * size; i++)
        for (int c = 0; c < c_out; c++) out[i * c_out + c] = full[i * src->c + (c < src->c ? c : 0)];
    free(full);
    *dst = out;
    return SY_OK;
}

/* Refines M so that the mask of the moving image, warped, lies on ref (the
 * adaxial mask in the output frame): ECC on blurred silhouettes at a quarter
 * of the output size, the common signal of reflected and back-lit photos of
 * either side. *moved gets the correction's shift in output texels. */
static sy_code register_mask(const float *ref_small, int small, const unsigned char *mov_mask, int w, int h,
                             int size, double M[6], double *moved, sy_error *err)
{
    size_t n = (size_t)w * h;
    float *m = malloc(n * sizeof *m);
    float *ws = malloc((size_t)size * size * sizeof *ws);
    float *mv = malloc((size_t)small * small * sizeof *mv);
    sy_code rc = SY_OK;
    if (!m || !ws || !mv) rc = sy_fail(err, SY_EINTERNAL, "registration: out of memory");
    if (!rc) {
        for (size_t i = 0; i < n; i++) m[i] = mov_mask[i] ? 1.0f : 0.0f;
        if (sy_lcv_warp(m, w, h, 1, M, ws, size, size, 0, err) ||
            sy_lcv_resize(ws, size, size, 1, mv, small, small, err) || sy_lcv_blur(mv, small, small, 1, 2.0, mv, err))
            rc = sy_error_prefix(err, "registration");
    }
    double R[6] = {1, 0, 0, 0, 1, 0};
    sy_error no_fit; /* a failed fit is no error of the stage: see below */
    if (!rc && sy_lcv_register(ref_small, mv, small, small, R, &no_fit)) {
        /* No convergence: the captures are taken as aligned (thesis setup). */
        R[0] = 1, R[1] = 0, R[2] = 0, R[3] = 0, R[4] = 1, R[5] = 0;
    }
    if (!rc) {
        /* R acts on small-image coordinates; to output texel coordinates. */
        double k = (double)size / small;
        double S[6] = {R[0], R[1], R[2] * k + (R[0] - 1) * 0.5 * (k - 1) + R[1] * 0.5 * (k - 1),
                       R[3], R[4], R[5] * k + R[3] * 0.5 * (k - 1) + (R[4] - 1) * 0.5 * (k - 1)};
        /* Pixel centre convention: small (i + 0.5) k = big (j + 0.5). */
        S[2] = k * (R[2] + 0.5 * (R[0] + R[1] - 1)) - 0.5 * (R[0] + R[1] - 1);
        S[5] = k * (R[5] + 0.5 * (R[3] + R[4] - 1)) - 0.5 * (R[3] + R[4] - 1);
        *moved = hypot(S[2], S[5]) + size * fabs(asin(fmax(-1, fmin(1, S[3]))));
        affine_compose(M, S, M);
    }
    free(m), free(ws), free(mv);
    return rc;
}

/* -------------------------------------------------------------- the maps */

/* Highlight removal: texels brighter than highlight_ratio times the local
 * (masked, Gaussian) mean luminance are specular glints; they are filled by
 * normalised convolution of the remaining texels. */
static sy_code remove_highlights(float *rgb, const float *alpha, int size, double ratio, sy_error *err)
{
    size_t n = (size_t)size * size;
    float *a = malloc(n * 2 * sizeof(float)), *b = malloc(n * 4 * sizeof(float));
    if (!a || !b) {
        free(a), free(b);
        return sy_fail(err, SY_EINTERNAL, "highlights: out of memory");
    }
    for (size_t i = 0; i < n; i++) {
        float m = alpha[i] >= 0.5f ? 1.0f : 0.0f;
        a[2 * i] = sy_leaf_luma(rgb + 3 * i) * m;
        a[2 * i + 1] = m;
    }
    sy_code rc = SY_OK;
    if (sy_lcv_blur(a, size, size, 2, size / 96.0, a, err)) rc = sy_error_prefix(err, "highlights");
    size_t hits = 0;
    for (size_t i = 0; !rc && i < n; i++) {
        float local = a[2 * i + 1] > 1e-6f ? a[2 * i] / a[2 * i + 1] : 0;
        int glint = alpha[i] >= 0.5f && sy_leaf_luma(rgb + 3 * i) > ratio * local;
        hits += glint;
        float keep = alpha[i] >= 0.5f && !glint ? 1.0f : 0.0f;
        for (int c = 0; c < 3; c++) b[4 * i + c] = rgb[3 * i + c] * keep;
        b[4 * i + 3] = keep;
    }
    if (!rc && hits) {
        if (sy_lcv_blur(b, size, size, 4, size / 256.0 + 1, b, err)) rc = sy_error_prefix(err, "highlights");
        for (size_t i = 0; !rc && i < n; i++) {
            float local = a[2 * i + 1] > 1e-6f ? a[2 * i] / a[2 * i + 1] : 0;
            int glint = alpha[i] >= 0.5f && sy_leaf_luma(rgb + 3 * i) > ratio * local;
            if (glint && b[4 * i + 3] > 1e-4f)
                for (int c = 0; c < 3; c++) rgb[3 * i + c] = b[4 * i + c] / b[4 * i + 3];
        }
    }
    free(a), free(b);
    return rc;
}

/* Masked Gaussian smoothing of a one-channel map (values outside the mask
 * neither contribute nor change). */
static sy_code masked_smooth(float *v, const float *alpha, int size, double sigma, sy_error *err)
{
    size_t n = (size_t)size * size;
    float *a = calloc(2 * n, sizeof *a);
    if (!a) return sy_fail(err, SY_EINTERNAL, "smoothing: out of memory");
    for (size_t i = 0; i < n; i++) {
        float m = alpha[i] >= 0.5f ? 1.0f : 0.0f;
        a[2 * i] = v[i] * m, a[2 * i + 1] = m;
    }
    if (sy_lcv_blur(a, size, size, 2, sigma, a, err)) {
        free(a);
        return sy_error_prefix(err, "smoothing");
    }
    for (size_t i = 0; i < n; i++)
        if (alpha[i] >= 0.5f && a[2 * i + 1] > 1e-6f) v[i] = a[2 * i] / a[2 * i + 1];
    free(a);
    return SY_OK;
}

/* Tangent-space normals of side s from its height field (mm): central
 * differences inside the leaf, one-sided at its border. */
static void normals_from_height(const float *hgt, const float *alpha, int size, double texel, float *nrm)
{
    for (int y = 0; y < size; y++)
        for (int x = 0; x < size; x++) {
            size_t i = (size_t)y * size + x;
            float *n = nrm + 3 * i;
            if (alpha[i] < 0.5f) {
                n[0] = 0, n[1] = 0, n[2] = 1;
                continue;
            }
#define IN(xx, yy) ((xx) >= 0 && (xx) < size && (yy) >= 0 && (yy) < size && alpha[(size_t)(yy) * size + (xx)] >= 0.5f)
            int xl = IN(x - 1, y) ? x - 1 : x, xr = IN(x + 1, y) ? x + 1 : x;
            int yu = IN(x, y - 1) ? y - 1 : y, yd = IN(x, y + 1) ? y + 1 : y;
#undef IN
            double dx = xr > xl ? (hgt[(size_t)y * size + xr] - hgt[(size_t)y * size + xl]) / ((xr - xl) * texel) : 0;
            /* +Y is image up: rows grow downwards. */
            double dy = yd > yu ? (hgt[(size_t)yu * size + x] - hgt[(size_t)yd * size + x]) / ((yd - yu) * texel) : 0;
            double l = sqrt(dx * dx + dy * dy + 1);
            n[0] = (float)(-dx / l), n[1] = (float)(-dy / l), n[2] = (float)(1 / l);
        }
}

/* ---------------------------------------------------------------- horizon */

typedef struct {
    const float *height, *alpha;
    int w, h, sectors;
    double texel;
    float *hz;
    const int *off;         /* per sector and step: texel offset (dx, dy) */
    double inv_dist[HORIZON_STEPS]; /* 1 / (step * texel) */
} horizon_job;

static void horizon_rows(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    const horizon_job *j = ctx;
    for (size_t y = begin; y < end; y++)
        for (int x = 0; x < j->w; x++) {
            size_t i = y * (size_t)j->w + (size_t)x;
            float *out = j->hz + i * (size_t)j->sectors;
            float h0 = j->height[i];
            for (int k = 0; k < j->sectors; k++) {
                /* The steepest slope along the sector, one atan at the end. */
                double best = -1e30;
                for (int s = 0; s < HORIZON_STEPS; s++) {
                    int px = x + j->off[2 * (k * HORIZON_STEPS + s)], py = (int)y + j->off[2 * (k * HORIZON_STEPS + s) + 1];
                    if (px < 0 || py < 0 || px >= j->w || py >= j->h) break;
                    size_t q = (size_t)py * (size_t)j->w + (size_t)px;
                    if (j->alpha[q] < 0.5f) break; /* beyond the leaf nothing occludes */
                    double slope = (j->height[q] - h0) * j->inv_dist[s];
                    if (slope > best) best = slope;
                }
                out[k] = best > -1e29 ? (float)atan(best) : (float)(-SY_LEAF_PI / 2);
            }
        }
}

sy_code sy_leaf_horizon(const float *height, const float *alpha, int w, int h, double texel_mm, int sectors, float *hz,
                        sy_error *err)
{
    static const int steps[HORIZON_STEPS] = {1, 2, 3, 4, 6, 8, 11, 16, 22, 32, 45, 64};
    int *off = sy_calloc((size_t)sectors * HORIZON_STEPS * 2, sizeof *off, err, "horizon");
    if (!off) return SY_EINTERNAL;
    horizon_job j = {height, alpha, w, h, sectors, texel_mm, hz, off, {0}};
    for (int k = 0; k < sectors; k++) {
        double phi = 2 * SY_LEAF_PI * k / sectors;
        for (int s = 0; s < HORIZON_STEPS; s++) {
            off[2 * (k * HORIZON_STEPS + s)] = (int)lround(cos(phi) * steps[s]);
            off[2 * (k * HORIZON_STEPS + s) + 1] = (int)lround(-sin(phi) * steps[s]); /* +Y up is -row */
        }
    }
    for (int s = 0; s < HORIZON_STEPS; s++) j.inv_dist[s] = 1 / (steps[s] * texel_mm);
    sy_parallel_for((size_t)h, 16, horizon_rows, &j);
    free(off);
    return SY_OK;
}

/* Where direction w falls among the horizon sectors: its elevation, the two
 * sectors around its azimuth and the interpolation weight of the second. */
typedef struct {
    float elevation, t;
    int k0, k1;
} sector_pos;

static sector_pos sector_of(int sectors, const double w[3])
{
    sector_pos p;
    p.elevation = (float)asin(fmax(-1, fmin(1, w[2])));
    double az = atan2(w[1], w[0]);
    if (az < 0) az += 2 * SY_LEAF_PI;
    double f = az / (2 * SY_LEAF_PI) * sectors;
    p.k0 = (int)floor(f) % sectors;
    p.k1 = (p.k0 + 1) % sectors;
    p.t = (float)(f - floor(f));
    return p;
}

static int visible_at(const float *hz, const sector_pos *p)
{
    return p->elevation > hz[p->k0] * (1 - p->t) + hz[p->k1] * p->t;
}

int sy_leaf_visible(const float *hz, int sectors, const double w[3])
{
    sector_pos p = sector_of(sectors, w);
    return visible_at(hz, &p);
}

/* ------------------------------------------------------------ convolution */

sy_code sy_leaf_convolve(const float *const *in, int n_out, const float *d, const float *alpha, int w, int h,
                         double texel, const sy_dipole *m, int bins, float *const *out, double *radius_mm,
                         sy_error *err)
{
    size_t n = (size_t)w * h;
    double dmin = DBL_MAX, dmax = 0;
    for (size_t i = 0; i < n; i++)
        if (alpha[i] >= 0.5f) {
            if (d[i] < dmin) dmin = d[i];
            if (d[i] > dmax) dmax = d[i];
        }
    if (dmax <= 0) {
        for (int i = 0; i < n_out; i++) memset(out[i], 0, n * sizeof(float));
        return SY_OK;
    }
    if (dmax - dmin < 1e-4) bins = 1;
    double rmm = 0;
    double *dk = malloc((size_t)bins * sizeof *dk);
    if (!dk) return sy_fail(err, SY_EINTERNAL, "convolution: out of memory");
    for (int k = 0; k < bins; k++) {
        dk[k] = bins == 1 ? 0.5 * (dmin + dmax) : dmin + (dmax - dmin) * k / (bins - 1);
        double r = sy_dipole_radius(m, dk[k]);
        if (r > rmm) rmm = r;
    }
    int R = (int)ceil(rmm / texel);
    if (R < 1) R = 1;
    if (R > MAX_KERNEL_RADIUS) R = MAX_KERNEL_RADIUS;
    if (radius_mm) *radius_mm = rmm;
    size_t ks = (size_t)(2 * R + 1) * (size_t)(2 * R + 1);
    float **kern = calloc((size_t)bins, sizeof *kern);
    float **split = calloc((size_t)bins * (size_t)n_out, sizeof *split);
    sy_code rc = kern && split ? SY_OK : sy_fail(err, SY_EINTERNAL, "convolution: out of memory");
    for (int k = 0; !rc && k < bins; k++) {
        kern[k] = malloc(ks * sizeof(float));
        if (!kern[k]) rc = sy_fail(err, SY_EINTERNAL, "convolution: out of memory");
        else sy_dipole_kernel(m, dk[k], texel, R, kern[k]);
    }
    for (int i = 0; !rc && i < n_out; i++)
        for (int k = 0; !rc && k < bins; k++) {
            float *s = split[(size_t)i * bins + k] = calloc(n, sizeof(float));
            if (!s) {
                rc = sy_fail(err, SY_EINTERNAL, "convolution: out of memory");
                break;
            }
            for (size_t p = 0; p < n; p++) {
                if (alpha[p] < 0.5f) continue;
                double wgt = 1;
                if (bins > 1) {
                    double f = (d[p] - dmin) / (dmax - dmin) * (bins - 1);
                    double dist = fabs(f - k);
                    wgt = dist < 1 ? 1 - dist : 0;
                }
                if (wgt > 0) s[p] = (float)(in[i][p] * wgt);
            }
        }
    if (!rc)
        rc = sy_lcv_convolve_sum((const float *const *)split, n_out, bins, (const float *const *)kern, R, w, h, out,
                                 sy_threads(), err);
    if (kern)
        for (int k = 0; k < bins; k++) free(kern[k]);
    if (split)
        for (int k = 0; k < bins * n_out; k++) free(split[k]);
    free(kern), free(split), free(dk);
    return rc;
}

/* ----------------------------------------------------- the HL2 precompute */

typedef struct {
    const float *alpha, *albedo, *normal, *hz;
    int size, sectors, n_dirs;
    const double *dirs, *W; /* 3 x n_dirs */
    const sector_pos *pos;  /* per direction */
    float *E[3];
} irradiance_job;

/* E_i(x) = sum_m W_im (1 - rho_d(x)) V(x, w_m) max(0, n(x).w_m): the three
 * HL2-projected irradiances of eq (3.13). */
static void irradiance_rows(void *ctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    const irradiance_job *j = ctx;
    for (size_t y = begin; y < end; y++)
        for (int x = 0; x < j->size; x++) {
            size_t i = y * (size_t)j->size + (size_t)x;
            double e[3] = {0, 0, 0};
            if (j->alpha[i] >= 0.5f) {
                const float *n = j->normal + 3 * i;
                const float *hz = j->hz + i * (size_t)j->sectors;
                for (int m = 0; m < j->n_dirs; m++) {
                    const double *w = j->dirs + 3 * m;
                    double c = n[0] * w[0] + n[1] * w[1] + n[2] * w[2];
                    if (c <= 0 || !visible_at(hz, &j->pos[m])) continue;
                    for (int k = 0; k < 3; k++) e[k] += j->W[(size_t)k * j->n_dirs + m] * c;
                }
                double entry = 1 - j->albedo[3 * i + 1]; /* 510 nm: the green channel */
                for (int k = 0; k < 3; k++) e[k] *= entry;
            }
            for (int k = 0; k < 3; k++) j->E[k][i] = (float)e[k];
        }
}

static sy_dipole leaf_dipole(const sy_leaf_maps *m, const sy_leafmaps_options *o)
{
    /* One boundary condition for the slab: the mean green albedo of both
     * sides stands in for the average diffuse reflectance rho_d (eq 3.4). */
    size_t n = (size_t)m->w * m->h, k = 0;
    double sum = 0;
    for (size_t i = 0; i < n; i++)
        if (m->alpha[i] >= 0.5f) sum += m->albedo[0][3 * i + 1] + m->albedo[1][3 * i + 1], k += 2;
    return sy_dipole_make(o->sigma_a, o->sigma_s, o->g, k ? sum / k : 0.1, o->multipoles);
}

sy_code sy_leaf_transmit_direction(const sy_leaf_maps *m, const sy_leafmaps_options *o, int lit, const double w[3],
                                   float *out, sy_error *err)
{
    size_t n = (size_t)m->w * m->h;
    float *E = malloc(n * sizeof *E), *hz = malloc(n * (size_t)o->sectors * sizeof *hz);
    if (!E || !hz) {
        free(E), free(hz);
        return sy_fail(err, SY_EINTERNAL, "transmission: out of memory");
    }
    sy_code rc = sy_leaf_horizon(m->height[lit], m->alpha, m->w, m->h, m->texel_mm, o->sectors, hz, err);
    for (size_t i = 0; !rc && i < n; i++) {
        const float *nr = m->normal[lit] + 3 * i;
        double c = nr[0] * w[0] + nr[1] * w[1] + nr[2] * w[2];
        int vis = m->alpha[i] >= 0.5f && c > 0 && sy_leaf_visible(hz + i * (size_t)o->sectors, o->sectors, w);
        E[i] = vis ? (float)((1 - m->albedo[lit][3 * i + 1]) * c) : 0.0f;
    }
    sy_dipole dp = leaf_dipole(m, o);
    const float *in[1] = {E};
    float *outs[1] = {out};
    if (!rc) rc = sy_leaf_convolve(in, 1, m->thickness, m->alpha, m->w, m->h, m->texel_mm, &dp, o->thickness_bins, outs, NULL, err);
    free(E), free(hz);
    return rc;
}

static sy_code precompute(sy_leaf_maps *m, const sy_leafmaps_options *o, sy_error *err)
{
    int size = m->w;
    size_t n = (size_t)size * size;
    int nd = o->directions;
    double *dirs = malloc((size_t)nd * 3 * sizeof *dirs), *W = malloc((size_t)nd * 3 * sizeof *W);
    float *hz = malloc(n * (size_t)o->sectors * sizeof *hz);
    float *E[6] = {0}, *h[6] = {0};
    sy_code rc = dirs && W && hz ? SY_OK : sy_fail(err, SY_EINTERNAL, "precompute: out of memory");
    for (int k = 0; !rc && k < 6; k++) {
        E[k] = malloc(n * sizeof(float));
        h[k] = malloc(n * sizeof(float));
        if (!E[k] || !h[k]) rc = sy_fail(err, SY_EINTERNAL, "precompute: out of memory");
    }
    sector_pos *pos = rc ? NULL : malloc((size_t)nd * sizeof *pos);
    if (!rc && !pos) rc = sy_fail(err, SY_EINTERNAL, "precompute: out of memory");
    if (!rc) {
        sy_hl2_directions(nd, o->seed, dirs);
        if (sy_hl2_projection(dirs, nd, W)) rc = sy_fail(err, SY_EINPUT, "directions %d give a singular HL2 projection", nd);
        for (int k = 0; !rc && k < nd; k++) pos[k] = sector_of(o->sectors, dirs + 3 * k);
    }
    double t0 = wall_now();
    for (int s = 0; !rc && s < 2; s++) {
        say(o, s ? "horizon and irradiance, abaxial side lit" : "horizon and irradiance, adaxial side lit");
        rc = sy_leaf_horizon(m->height[s], m->alpha, size, size, m->texel_mm, o->sectors, hz, err);
        if (rc) break;
        irradiance_job j = {m->alpha, m->albedo[s], m->normal[s], hz, size, o->sectors, nd, dirs, W, pos,
                            {E[3 * s], E[3 * s + 1], E[3 * s + 2]}};
        sy_parallel_for((size_t)size, 8, irradiance_rows, &j);
    }
    m->seconds[3] = wall_now() - t0;
    t0 = wall_now();
    sy_dipole dp = leaf_dipole(m, o);
    if (!rc) {
        say(o, "multi-dipole convolution (FFT), both sides");
        rc = sy_leaf_convolve((const float *const *)E, 6, m->thickness, m->alpha, size, size, m->texel_mm, &dp,
                              o->thickness_bins, h, &m->kernel_radius_mm, err);
    }
    for (int s = 0; !rc && s < 2; s++) {
        m->hl2[s] = sy_calloc(n, 3 * sizeof(float), err, "hl2");
        m->hl2_scale[s] = sy_calloc(n, sizeof(float), err, "hl2");
        if (!m->hl2[s] || !m->hl2_scale[s]) {
            rc = SY_EINTERNAL;
            break;
        }
        double sum = 0;
        size_t cnt = 0;
        const double iso = sqrt(2 * SY_LEAF_PI) / 3, root = sqrt(2 * SY_LEAF_PI);
        for (size_t i = 0; i < n; i++) {
            double c[3] = {h[3 * s][i], h[3 * s + 1][i], h[3 * s + 2][i]};
            double tot = c[0] + c[1] + c[2];
            /* Reconstruction at normal incidence: sum_i h_i / sqrt(2 pi). */
            double normal_incidence = tot / root;
            m->hl2_scale[s][i] = (float)(normal_incidence > 0 ? normal_incidence : 0);
            for (int k = 0; k < 3; k++)
                m->hl2[s][3 * i + k] = (float)(m->alpha[i] >= 0.5f && tot > 1e-9 ? c[k] * root / tot : iso);
            if (m->alpha[i] >= 0.5f) sum += normal_incidence, cnt++;
        }
        m->transmit_normal[s] = cnt ? sum / cnt : 0;
    }
    m->seconds[4] = wall_now() - t0;
    for (int k = 0; k < 6; k++) free(E[k]), free(h[k]);
    free(dirs), free(W), free(hz), free(pos);
    return rc;
}

/* ------------------------------------------------------------- thickness */

/* Median thickness from the local inversion of t scaled by k. */
static double median_inverted(const sy_dipole *dp, const float *t, const float *alpha, size_t n, double k, double dmin,
                              double dmax, float *tmp, float *scratch)
{
    for (size_t i = 0; i < n; i++) tmp[i] = alpha[i] >= 0.5f ? (float)sy_dipole_invert(dp, k * t[i], dmin, dmax) : 0;
    return masked_median(tmp, alpha, n, scratch);
}

/* Thickness from the measured transmittance M (green, seen on side `seen`,
 * lit from the other side) by inverting the multi-dipole model:
 *   M(x) = (1 - a_seen(x)) A_p sum T(r, d(x_i)) (1 - a_lit(x_i)).
 * Start from the local closed form (digest D1) anchored so the median
 * thickness equals the measured one, then fixed-point steps with the full
 * non-local convolution correct the blur and the leaf's border. */
static sy_code thickness_from_transmission(sy_leaf_maps *m, const sy_leafmaps_options *o, int seen, sy_error *err)
{
    int size = m->w;
    size_t n = (size_t)size * size;
    int lit = 1 - seen;
    sy_dipole dp = leaf_dipole(m, o);
    double dmin = 1.2 * dp.l, dmax = 3.0;
    float *t = malloc(n * sizeof *t), *tmp = malloc(n * sizeof *tmp), *scratch = malloc(n * sizeof *scratch);
    float *E = malloc(n * sizeof *E), *P = malloc(n * sizeof *P);
    if (!t || !tmp || !scratch || !E || !P) {
        free(t), free(tmp), free(scratch), free(E), free(P);
        return sy_fail(err, SY_EINTERNAL, "thickness: out of memory");
    }
    for (size_t i = 0; i < n; i++) {
        double den = (1 - m->albedo[seen][3 * i + 1]) * (1 - m->albedo[lit][3 * i + 1]);
        t[i] = m->alpha[i] >= 0.5f && den > 1e-6 ? (float)(m->translucency[seen][3 * i + 1] / den) : 0;
    }
    /* Anchor: bisection on log k for median(d) = thickness_mm. */
    double lo = log(1e-4), hi = log(1e4);
    for (int it = 0; it < 50; it++) {
        double mid = 0.5 * (lo + hi);
        double med = median_inverted(&dp, t, m->alpha, n, exp(mid), dmin, dmax, tmp, scratch);
        if (med > o->thickness_mm) lo = mid; /* too thick: more transmission */
        else hi = mid;
    }
    double k = exp(0.5 * (lo + hi));
    for (size_t i = 0; i < n; i++) m->thickness[i] = m->alpha[i] >= 0.5f ? (float)sy_dipole_invert(&dp, k * t[i], dmin, dmax) : 0;
    sy_code rc = SY_OK;
    for (size_t i = 0; i < n; i++) E[i] = m->alpha[i] >= 0.5f ? (float)(1 - m->albedo[lit][3 * i + 1]) : 0;
    for (int it = 0; !rc && it < o->inversion_iterations; it++) {
        const float *in[1] = {E};
        float *outs[1] = {P};
        rc = sy_leaf_convolve(in, 1, m->thickness, m->alpha, size, size, m->texel_mm, &dp, o->thickness_bins, outs, NULL,
                              err);
        if (rc) break;
        /* P / (1 - a_lit) is the model's transmittance per unit entering
         * light at x; correct the local total so the model meets k t. */
        for (size_t i = 0; i < n; i++) {
            if (m->alpha[i] < 0.5f) continue;
            double pred = P[i] / (1 - m->albedo[lit][3 * i + 1]);
            double cur = sy_dipole_total(&dp, m->thickness[i]);
            if (pred <= 1e-9) continue;
            m->thickness[i] = (float)sy_dipole_invert(&dp, cur * k * t[i] / pred, dmin, dmax);
        }
        /* Re-anchor: keep the median at the measured thickness. */
        double med = masked_median(m->thickness, m->alpha, n, scratch);
        k *= sy_dipole_total(&dp, o->thickness_mm) / sy_dipole_total(&dp, med);
    }
    m->anchor_scale = k;
    free(t), free(tmp), free(scratch), free(E), free(P);
    return rc;
}

/* ------------------------------------------------------------------ build */

static sy_code build(const sy_leaf_capture *cap, const sy_leafmaps_options *o, sy_leaf_maps *m, sy_error *err)
{
    static const char *side_name[2] = {"adaxial", "abaxial"};
    const sy_fimage *ref = cap->side[0].reflected;
    double wall0 = wall_now(), cpu0 = cpu_now();
    if (!ref) return sy_fail(err, SY_EINPUT, "no adaxial (front-lit) photo given");
    char what[96];
    sy_code rc;
    for (int s = 0; s < 2; s++) {
        const sy_leaf_side_capture *c = &cap->side[s];
        snprintf(what, sizeof what, "%s reflected photo", side_name[s]);
        if ((rc = check_image(c->reflected, s ? ref : NULL, 3, what, err))) return rc;
        snprintf(what, sizeof what, "%s back-lit photo", side_name[s]);
        if ((rc = check_image(c->transmitted, ref, 3, what, err))) return rc;
        snprintf(what, sizeof what, "%s flat field", side_name[s]);
        if ((rc = check_image(c->flat_field, ref, 3, what, err))) return rc;
        snprintf(what, sizeof what, "%s height scan", side_name[s]);
        if ((rc = check_image(c->height, ref, 1, what, err))) return rc;
        if (c->flat_field && !c->transmitted)
            return sy_fail(err, SY_EINPUT, "%s: a flat field without a back-lit photo", side_name[s]);
    }
    if (cap->white_rect[2] > 0) {
        const int *r = cap->white_rect;
        if (r[0] < 0 || r[1] < 0 || r[3] <= 0 || r[0] + r[2] > ref->w || r[1] + r[3] > ref->h)
            return sy_fail(err, SY_EINPUT, "white reference %d,%d,%d,%d lies outside the %dx%d photo", r[0], r[1], r[2],
                           r[3], ref->w, ref->h);
        if (!(cap->white_reflectance > 0 && cap->white_reflectance <= 1))
            return sy_fail(err, SY_EINPUT, "white reference reflectance %g is outside (0, 1]", cap->white_reflectance);
    }
    int W = ref->w, H = ref->h, size = o->size;
    size_t np = (size_t)W * H, n = (size_t)size * size;

    /* Ratio images (back-lit over flat field), in the photo frame. */
    sy_fimage ratio[2] = {{0}, {0}};
    unsigned char *mask[4] = {0}; /* side0 reflected, side0 transmitted, side1 reflected, side1 transmitted */
    for (int k = 0; k < 4; k++)
        if (!(mask[k] = malloc(np))) rc = sy_fail(err, SY_EINTERNAL, "masks: out of memory");
    for (int s = 0; s < 2; s++) {
        const sy_leaf_side_capture *c = &cap->side[s];
        if (rc || !c->transmitted) continue;
        if ((rc = sy_fimage_alloc(&ratio[s], W, H, 3, err))) break;
        /* No flat field: the back light's level is the median of the
         * background of the back-lit photo (its brightest mode). */
        float level[3] = {1, 1, 1};
        const sy_fimage *fl = c->flat_field ? c->flat_field : cap->side[0].flat_field;
        if (!fl) {
            float *tmp = malloc(np * sizeof *tmp);
            if (!tmp) {
                rc = sy_fail(err, SY_EINTERNAL, "flat field: out of memory");
                break;
            }
            for (int ch = 0; ch < 3; ch++) {
                for (size_t i = 0; i < np; i++) tmp[i] = c->transmitted->px[i * c->transmitted->c + ch];
                qsort(tmp, np, sizeof *tmp, sy_cmp_float);
                level[ch] = tmp[(size_t)(0.95 * (double)(np - 1))];
                if (level[ch] < 1e-4f) level[ch] = 1e-4f;
            }
            free(tmp);
        }
        for (size_t i = 0; i < np; i++)
            for (int ch = 0; ch < 3; ch++) {
                double f = fl ? fl->px[i * fl->c + ch] : level[ch];
                double v = f > 1e-4 ? c->transmitted->px[i * c->transmitted->c + ch] / f : 0;
                ratio[s].px[3 * i + ch] = (float)(v < 0 ? 0 : v > 1 ? 1 : v);
            }
    }
    double t0 = wall_now();
    say(o, "segmentation");
    /* The adaxial reflected photo is the reference frame of every map. */
    if (!rc) rc = photo_mask(ref, mask[0], "adaxial reflected photo", err);
    if (!rc) clear_rect(mask[0], W, H, cap->white_rect);
    if (!rc && ratio[0].px) rc = transmit_mask(&ratio[0], mask[1], "adaxial back-lit photo", err);
    if (!rc && cap->side[1].reflected) rc = photo_mask(cap->side[1].reflected, mask[2], "abaxial reflected photo", err);
    if (!rc && cap->side[1].reflected) clear_rect(mask[2], W, H, cap->white_rect);
    if (!rc && ratio[1].px) rc = transmit_mask(&ratio[1], mask[3], "abaxial back-lit photo", err);
    double M0[6], scale = 1;
    if (!rc) orient_frame(mask[0], W, H, size, o->orient, M0, &scale);
    m->seconds[0] = wall_now() - t0;
    t0 = wall_now();

    /* Registration of every other capture to the adaxial silhouette. */
    double Mi[4][6];
    for (int k = 0; k < 4; k++) memcpy(Mi[k], M0, sizeof M0);
    int small = size / 4 < 64 ? size : size / 4;
    float *ref_small = NULL;
    if (!rc) {
        float *mf = malloc(np * sizeof *mf), *big = malloc(n * sizeof *big);
        ref_small = malloc((size_t)small * small * sizeof *ref_small);
        if (!mf || !big || !ref_small) rc = sy_fail(err, SY_EINTERNAL, "registration: out of memory");
        if (!rc) {
            for (size_t i = 0; i < np; i++) mf[i] = mask[0][i] ? 1.0f : 0.0f;
            if (sy_lcv_warp(mf, W, H, 1, M0, big, size, size, 0, err) ||
                sy_lcv_resize(big, size, size, 1, ref_small, small, small, err) ||
                sy_lcv_blur(ref_small, small, small, 1, 2.0, ref_small, err))
                rc = sy_error_prefix(err, "registration");
        }
        free(mf), free(big);
    }
    say(o, "registration (ECC on silhouettes)");
    for (int k = 1; !rc && k < 4; k++) {
        int s = k / 2;
        int present = (k & 1) ? ratio[s].px != NULL : cap->side[s].reflected != NULL;
        if (!present) continue;
        if (s == 1) mirror_affine(W, Mi[k]);
        rc = register_mask(ref_small, small, mask[k], W, H, size, Mi[k], &m->registration_shift[k - 1], err);
    }
    free(ref_small);
    m->seconds[1] = wall_now() - t0;
    t0 = wall_now();

    /* The maps in the output frame. */
    m->w = m->h = size;
    if (!rc) {
        m->alpha = sy_calloc(n, sizeof(float), err, "alpha");
        m->thickness = sy_calloc(n, sizeof(float), err, "thickness");
        for (int s = 0; s < 2; s++) {
            m->height[s] = sy_calloc(n, sizeof(float), err, "height");
            m->normal[s] = sy_calloc(n, 3 * sizeof(float), err, "normal");
        }
        if (!m->alpha || !m->thickness || !m->height[0] || !m->height[1] || !m->normal[0] || !m->normal[1])
            rc = SY_EINTERNAL;
    }
    if (!rc) {
        float *mf = malloc(np * sizeof *mf);
        if (!mf) rc = sy_fail(err, SY_EINTERNAL, "alpha: out of memory");
        else {
            for (size_t i = 0; i < np; i++) mf[i] = mask[0][i] ? 1.0f : 0.0f;
            if (sy_lcv_warp(mf, W, H, 1, M0, m->alpha, size, size, 0, err)) rc = sy_error_prefix(err, "alpha");
            free(mf);
        }
    }
    memcpy(m->photo_from_map, M0, sizeof M0);
    /* Photo pixel size: given, or from the leaf's length along its axis. */
    if (!rc) {
        double photo_mm;
        if (o->texel_mm > 0) photo_mm = o->texel_mm;
        else {
            int top = size, bottom = -1;
            for (int y = 0; y < size; y++)
                for (int x = 0; x < size; x++)
                    if (m->alpha[(size_t)y * size + x] >= 0.5f) {
                        if (y < top) top = y;
                        bottom = y;
                    }
            photo_mm = o->leaf_length_mm / ((bottom - top + 1) / scale);
        }
        m->texel_mm = photo_mm / scale;
    }
    /* White level (fixed exposure: one level for both sides). */
    double white[3] = {1, 1, 1};
    if (!rc && cap->white_rect[2] > 0) {
        const int *r = cap->white_rect;
        for (int ch = 0; ch < 3; ch++) {
            double s = 0;
            for (int y = r[1]; y < r[1] + r[3]; y++)
                for (int x = r[0]; x < r[0] + r[2]; x++) s += ref->px[((size_t)y * W + x) * ref->c + ch];
            s /= (double)r[2] * r[3];
            white[ch] = s / cap->white_reflectance;
            if (white[ch] < 1e-4) rc = sy_fail(err, SY_EINPUT, "white reference %d,%d,%d,%d is black", r[0], r[1], r[2], r[3]);
        }
    }
    say(o, "albedo, translucency");
    for (int s = 0; !rc && s < 2; s++) {
        const sy_fimage *im = cap->side[s].reflected;
        if (!im) {
            m->src_albedo[s] = SY_LEAF_SRC_COPY;
            m->albedo[s] = malloc(n * 3 * sizeof(float));
            if (!m->albedo[s]) rc = sy_fail(err, SY_EINTERNAL, "albedo: out of memory");
            else memcpy(m->albedo[s], m->albedo[0], n * 3 * sizeof(float));
            continue;
        }
        m->src_albedo[s] = SY_LEAF_SRC_MEASURED;
        if ((rc = warp_into(im, 3, Mi[2 * s], size, 1, &m->albedo[s], err))) break;
        for (size_t i = 0; i < n; i++)
            for (int ch = 0; ch < 3; ch++) {
                double v = m->albedo[s][3 * i + ch] / white[ch];
                m->albedo[s][3 * i + ch] = (float)(v < 0 ? 0 : v > 0.98 ? 0.98 : v);
            }
        rc = remove_highlights(m->albedo[s], m->alpha, size, o->highlight_ratio, err);
        if (!rc && o->tint[0] >= 0) tint_albedo(m->albedo[s], m->alpha, n, o->tint);
    }
    for (int s = 0; !rc && s < 2; s++) {
        if (!ratio[s].px) continue;
        m->src_translucency[s] = SY_LEAF_SRC_MEASURED;
        rc = warp_into(&ratio[s], 3, Mi[2 * s + 1], size, 1, &m->translucency[s], err);
    }
    m->seconds[2] = wall_now() - t0;

    /* Heights from the scans (side 1's scan sits in its reflected photo's frame). */
    for (int s = 0; !rc && s < 2; s++) {
        if (!cap->side[s].height) continue;
        float *hgt = NULL;
        if ((rc = warp_into(cap->side[s].height, 1, Mi[2 * s], size, 1, &hgt, err))) break;
        memcpy(m->height[s], hgt, n * sizeof(float));
        free(hgt);
        m->src_height[s] = SY_LEAF_SRC_MEASURED;
    }
    float *scratch = rc ? NULL : malloc(n * sizeof *scratch);
    if (!rc && !scratch) rc = sy_fail(err, SY_EINTERNAL, "thickness: out of memory");
    /* Thickness. */
    sy_dipole dp = rc ? sy_dipole_make(o->sigma_a, o->sigma_s, o->g, 0, o->multipoles) : leaf_dipole(m, o);
    if (!rc) {
        say(o, "thickness");
        if (m->src_height[0] && m->src_height[1]) {
            /* Thesis: the difference of the two displacement maps; the
             * unknown offset between the scans is set by the calliper. */
            for (size_t i = 0; i < n; i++) m->thickness[i] = m->height[0][i] + m->height[1][i];
            double med = masked_median(m->thickness, m->alpha, n, scratch);
            for (size_t i = 0; i < n; i++)
                m->thickness[i] = m->alpha[i] >= 0.5f ? (float)fmax(1.2 * dp.l, m->thickness[i] - med + o->thickness_mm) : 0;
            m->src_thickness = SY_LEAF_SRC_MEASURED;
        } else if (m->translucency[0] || m->translucency[1]) {
            rc = thickness_from_transmission(m, o, m->translucency[0] ? 0 : 1, err);
            if (!rc) rc = masked_smooth(m->thickness, m->alpha, size, 0.75, err);
            m->src_thickness = SY_LEAF_SRC_MODEL;
        } else {
            for (size_t i = 0; i < n; i++) m->thickness[i] = m->alpha[i] >= 0.5f ? (float)o->thickness_mm : 0;
            m->src_thickness = SY_LEAF_SRC_NONE;
        }
    }
    /* Translucency the capture lacks: copy the other side (transmission is
     * reciprocal), else the model's transmittance with the albedo's hue
     * (leaf reflectance and transmittance spectra have nearly the same
     * shape: Jacquemoud & Baret, PROSPECT, 1990). */
    for (int s = 0; !rc && s < 2; s++) {
        if (m->translucency[s]) continue;
        m->translucency[s] = malloc(n * 3 * sizeof(float));
        if (!m->translucency[s]) {
            rc = sy_fail(err, SY_EINTERNAL, "translucency: out of memory");
            break;
        }
        if (m->translucency[1 - s] && m->src_translucency[1 - s] == SY_LEAF_SRC_MEASURED) {
            memcpy(m->translucency[s], m->translucency[1 - s], n * 3 * sizeof(float));
            m->src_translucency[s] = SY_LEAF_SRC_COPY;
            continue;
        }
        m->src_translucency[s] = SY_LEAF_SRC_MODEL;
        for (size_t i = 0; i < n; i++) {
            const float *a = m->albedo[s] + 3 * i, *b = m->albedo[1 - s] + 3 * i;
            double tg = m->alpha[i] >= 0.5f ? (1 - a[1]) * (1 - b[1]) * sy_dipole_total(&dp, m->thickness[i]) : 0;
            for (int ch = 0; ch < 3; ch++) {
                double v = a[1] > 1e-4 ? tg * a[ch] / a[1] : tg;
                m->translucency[s][3 * i + ch] = (float)(v > 1 ? 1 : v);
            }
        }
    }
    /* Energy: what a texel reflects plus what it transmits never exceeds
     * what falls on it (per channel, light from the lit side). */
    for (int s = 0; !rc && s < 2; s++)
        for (size_t i = 0; i < n; i++)
            for (int ch = 0; ch < 3; ch++) {
                float *t = &m->translucency[s][3 * i + ch];
                float lim = 1.0f - m->albedo[1 - s][3 * i + ch];
                if (m->alpha[i] < 0.5f) *t = 0; /* no leaf: nothing to transmit */
                else if (*t > lim) *t = lim, m->energy_clamped++;
            }
    /* Heights without scans: half the thickness variation each side plus the
     * albedo's luminance detail (veins) as relief. */
    if (!rc && (!m->src_height[0] || !m->src_height[1])) {
        float *detail = malloc(n * sizeof *detail), *blur = malloc(n * sizeof *blur);
        if (!detail || !blur) rc = sy_fail(err, SY_EINTERNAL, "heights: out of memory");
        double med = rc ? 0 : masked_median(m->thickness, m->alpha, n, scratch);
        for (int s = 0; !rc && s < 2; s++) {
            if (m->src_height[s]) continue;
            for (size_t i = 0; i < n; i++) detail[i] = logf(sy_leaf_luma(m->albedo[s] + 3 * i) + 1e-3f);
            memcpy(blur, detail, n * sizeof *blur);
            if ((rc = masked_smooth(blur, m->alpha, size, size / 64.0, err))) break;
            double var = 0;
            size_t cnt = 0;
            for (size_t i = 0; i < n; i++)
                if (m->alpha[i] >= 0.5f) {
                    detail[i] -= blur[i];
                    var += detail[i] * detail[i], cnt++;
                }
            double sd = cnt && var > 0 ? sqrt(var / cnt) : 1;
            for (size_t i = 0; i < n; i++)
                m->height[s][i] = m->alpha[i] >= 0.5f
                                      ? (float)(0.5 * (m->thickness[i] - med) + o->relief_mm * detail[i] / sd)
                                      : 0;
            if ((rc = masked_smooth(m->height[s], m->alpha, size, 0.7, err))) break;
            m->src_height[s] = SY_LEAF_SRC_MODEL;
        }
        free(detail), free(blur);
    }
    for (int s = 0; !rc && s < 2; s++) normals_from_height(m->height[s], m->alpha, size, m->texel_mm, m->normal[s]);
    /* Thickness statistics and the model's constants. */
    if (!rc) {
        double lo = DBL_MAX, hi = 0;
        for (size_t i = 0; i < n; i++)
            if (m->alpha[i] >= 0.5f) {
                if (m->thickness[i] < lo) lo = m->thickness[i];
                if (m->thickness[i] > hi) hi = m->thickness[i];
            }
        m->thickness_min = lo, m->thickness_max = hi;
        m->thickness_median = masked_median(m->thickness, m->alpha, n, scratch);
        m->sigma_tr = dp.sigma_tr;
        m->extrapolation_mm = dp.zb;
    }
    free(scratch);
    if (!rc) rc = precompute(m, o, err);
    for (int k = 0; k < 4; k++) free(mask[k]);
    sy_fimage_free(&ratio[0]);
    sy_fimage_free(&ratio[1]);
    m->seconds[5] = wall_now() - wall0;
    m->cpu_seconds = cpu_now() - cpu0;
    return rc;
}

sy_code sy_leafmaps_build(const sy_leaf_capture *cap, const sy_leafmaps_options *o, sy_leaf_maps *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    sy_code rc = sy_leafmaps_options_check(o, err);
    if (!rc) rc = build(cap, o, out, err);
    if (rc) sy_leaf_maps_free(out);
    return rc;
}
