/* Leaf maps from photographs: albedo, translucency, thickness, normals and the
 * precomputed directional translucency in the Half-Life 2 basis, following
 * Habel, Kusternig & Wimmer, "Physically Based Real-Time Translucency for
 * Leaves" (EGSR 2007), with the corrections listed in docs/leafmaps.md.
 *
 * Frames and units. Every map lives in the texel grid of the adaxial (front)
 * photo after cropping and orienting: row 0 is the top of the image (the leaf
 * tip), the petiole sits at the bottom centre. Tangent space is OpenGL style:
 * +X = image right (+U), +Y = image up (+V), +Z out of the side the map belongs
 * to. The abaxial (back) side uses the same +X and +Y with +Z pointing out of
 * the back (so its frame is (T, B, -N) of the front frame). Lengths are mm,
 * colours linear (sRGB only in files). Side 0 is adaxial, side 1 abaxial.
 *
 * Pipeline (sy_leafmaps_build): segment -> orient/crop -> register the other
 * captures to the adaxial reflected photo -> albedo (white reference,
 * highlight removal) -> translucency (back-lit / flat field) -> thickness
 * (scans, else the inverted multi-dipole model) -> heights and normals ->
 * horizon map (16 sectors) -> the HL2 precompute per lit side. */
#ifndef SYLVA_LEAFMAPS_H
#define SYLVA_LEAFMAPS_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A float image, row-major, c interleaved channels, row 0 at the top. */
typedef struct {
    int w, h, c;
    float *px;
} sy_fimage;

sy_code sy_fimage_alloc(sy_fimage *im, int w, int h, int c, sy_error *err);
void sy_fimage_free(sy_fimage *im);

/* The photographs and scans of one side. Colour images are linear RGB (3
 * channels) or RGBA (4: alpha is the leaf mask, 1 = leaf); heights are one
 * channel in mm (larger = closer to the camera that photographed the side).
 * Abaxial captures are taken after turning the leaf over about its vertical
 * axis, i.e. as mirror images; the stage mirrors them back. */
typedef struct {
    const sy_fimage *reflected;   /* front-lit photo; required for side 0, optional for side 1 */
    const sy_fimage *transmitted; /* back-lit photo (light behind the leaf), or NULL */
    const sy_fimage *flat_field;  /* the back light alone, same exposure, or NULL */
    const sy_fimage *height;      /* displacement scan of this side (mm), or NULL */
} sy_leaf_side_capture;

typedef struct {
    sy_leaf_side_capture side[2];
    /* Grey/white reference in the adaxial reflected photo: pixel rectangle
     * x, y, w, h (w = 0: none) and its known reflectance. */
    int white_rect[4];
    double white_reflectance;
} sy_leaf_capture;

typedef struct {
    /* Physical size. texel_mm > 0 fixes the size of one output texel; else
     * the leaf's length along its axis is leaf_length_mm. */
    double texel_mm;
    double leaf_length_mm;
    /* Measured (calliper) thickness, the anchor of the thickness map. */
    double thickness_mm;
    /* Optical parameters at 510 nm (thesis Table 3.1): mm^-1, mean cosine. */
    double sigma_a, sigma_s, g;
    int multipoles;     /* dipole pairs each side of the slab, n in eq (3.8) */
    int directions;     /* light directions of the HL2 projection, N_L */
    int sectors;        /* horizon map azimuth sectors */
    int thickness_bins; /* kernels tabulated over the thickness range */
    int inversion_iterations; /* fixed-point steps inverting the transmission */
    int size;           /* output maps are size x size texels (power of two) */
    int orient;         /* 1: main axis vertical, petiole down */
    double highlight_ratio; /* luminance over the local median that marks a highlight */
    double relief_mm;   /* amplitude of the luminance detail in derived heights */
    /* The leaf's mean colour (sRGB 0..255) the front-lit photos are
     * recoloured to, each texel keeping its luminance over the mean: an
     * autumn photo of a summer leaf. tint[0] < 0: as photographed. */
    double tint[3];
    uint64_t seed;      /* jitter of the HL2 light directions */
    int progress;       /* 1: print progress lines on stderr */
} sy_leafmaps_options;

sy_leafmaps_options sy_leafmaps_options_default(void);
sy_code sy_leafmaps_options_check(const sy_leafmaps_options *o, sy_error *err);

/* What each map was made from (for reports and the material file). */
typedef enum {
    SY_LEAF_SRC_NONE = 0,
    SY_LEAF_SRC_MEASURED, /* from the capture of this side */
    SY_LEAF_SRC_MODEL,    /* from the diffusion model / derived heights */
    SY_LEAF_SRC_COPY      /* the other side's map, this side was not captured */
} sy_leaf_source;

typedef struct {
    int w, h;
    double texel_mm;
    float *alpha;           /* wh, 0..1 */
    float *albedo[2];       /* 3wh, linear diffuse reflectance (the front-lit photo over white) */
    float *translucency[2]; /* 3wh, linear diffuse transmittance seen on side s, lit from the other side */
    float *height[2];       /* wh, mm, outward from side s */
    float *normal[2];       /* 3wh, unit, tangent space of side s */
    float *thickness;       /* wh, mm (0 outside the leaf) */
    /* HL2 coefficients for light arriving on side s, in side s's tangent
     * frame, normalised so the reconstruction at normal incidence is 1
     * (docs/leafmaps.md "HL2 maps"): L = L_D translucency(x)/pi sum_i h_i H_i(w). */
    float *hl2[2];          /* 3wh */
    float *hl2_scale[2];    /* wh: L_t^D at normal incidence (physical, per unit irradiance) */
    double photo_from_map[6]; /* 2x3 affine: output texel (u, v) -> adaxial photo pixel */
    /* Physical scale: mean L_t^D (eq 3.16) at normal incidence per lit side. */
    double transmit_normal[2];
    double thickness_min, thickness_max, thickness_median;
    double sigma_tr, extrapolation_mm, kernel_radius_mm;
    double anchor_scale;      /* transmission model scale that met the measured thickness */
    size_t energy_clamped;    /* texels whose albedo + translucency was clamped to 1 */
    double registration_shift[4]; /* px moved by registration: side0 transmitted, side1 reflected, side1 transmitted, - */
    sy_leaf_source src_albedo[2], src_translucency[2], src_height[2], src_thickness;
    double seconds[6];        /* segment, register, maps, horizon, precompute, total */
    double cpu_seconds;
} sy_leaf_maps;

void sy_leaf_maps_free(sy_leaf_maps *m);

/* Runs the whole stage. On failure nothing is left in *out. */
sy_code sy_leafmaps_build(const sy_leaf_capture *cap, const sy_leafmaps_options *o, sy_leaf_maps *out,
                          sy_error *err);

/* ------------------------------------------------------------------ model */

/* The multi-dipole slab (thesis §3.3.5, Donner & Jensen's form of eq 3.8). */
typedef struct {
    double sigma_tr;  /* sqrt(3 sigma_a sigma_t'), mm^-1 */
    double sigma_tp;  /* reduced extinction sigma_t', mm^-1 */
    double alpha_p;   /* reduced albedo sigma_s'/sigma_t' */
    double D;         /* diffusion constant 1/(3 sigma_t'), mm */
    double zb;        /* extrapolation distance 2AD, mm */
    double l;         /* depth of the real source 1/sigma_t', mm */
    int n;            /* multipoles each side */
} sy_dipole;

/* A from the average diffuse reflectance rho_d of the rough surfaces, eq (3.4). */
sy_dipole sy_dipole_make(double sigma_a, double sigma_s, double g, double rho_d, int n);
/* Diffuse transmittance T(r, d) per mm^2 (eq 3.8 with (1 + s d) e^{-s d}). */
double sy_dipole_T(const sy_dipole *m, double r_mm, double d_mm);
/* Closed form of the integral of T over the plane (digest D1). */
double sy_dipole_total(const sy_dipole *m, double d_mm);
/* Thickness whose total transmittance is t, clamped to [dmin, dmax]. */
double sy_dipole_invert(const sy_dipole *m, double t, double dmin, double dmax);

/* Footprint-integrated kernel weights (4x4 sub-samples per texel, times the
 * texel area A_p), size (2R+1)^2, clamped at 0. */
void sy_dipole_kernel(const sy_dipole *m, double d_mm, double texel_mm, int radius, float *w);
/* Radius (mm) where T falls below 1e-6 mm^-2, the thesis's cut-off. */
double sy_dipole_radius(const sy_dipole *m, double d_mm);

/* ----------------------------------------------------------- HL2 basis */

/* H_i of §3.3.8: unit, pairwise orthogonal, 1/sqrt(3) elevation. */
void sy_hl2_vectors(double H[3][3]);
/* sqrt(3/(2 pi)) H_i . w for i = 0..2. */
void sy_hl2_eval(const double w[3], double out[3]);
/* n stratified, jittered directions on the upper hemisphere, uniform in solid
 * angle via Shirley & Chiu's concentric map. dirs: 3n. */
void sy_hl2_directions(int n, uint64_t seed, double *dirs);
/* Least-squares projection weights W (3 x n, row-major): h = W L projects the
 * samples L(w_m) onto the basis exactly for linear L. Returns 0, -1 if the
 * sampled Gram matrix is singular. */
int sy_hl2_projection(const double *dirs, int n, double *W);

/* -------------------------------------------------------- precompute parts */

/* Horizon elevation angles (radians) of a height field (mm) in `sectors`
 * azimuths per texel (hz: w*h*sectors); azimuth k = 2 pi k / sectors from +X
 * towards +Y (image up). Outside the mask heights are taken as the edge's. */
sy_code sy_leaf_horizon(const float *height, const float *alpha, int w, int h, double texel_mm, int sectors,
                        float *hz, sy_error *err);
/* Visibility of direction w (tangent space, z > 0) from a texel's horizon. */
int sy_leaf_visible(const float *hz_texel, int sectors, const double w[3]);

/* L_t^D(x, w) of eq (3.16) for one light direction w arriving on side lit
 * (tangent frame of that side), out: wh. Uses the built maps. */
sy_code sy_leaf_transmit_direction(const sy_leaf_maps *m, const sy_leafmaps_options *o, int lit,
                                   const double w[3], float *out, sy_error *err);

/* --------------------------------------------------------------- captures */

/* A synthetic leaf with known albedo, thickness and heights, and the photos
 * the thesis's capture setup would take of it, rendered with the stage's
 * model (reflection: albedo times the white level; transmission: the
 * multi-dipole convolution of eq 3.16 under uniform back light). The abaxial
 * captures are mirror images as a real capture would be; `shift_px` moves
 * and rotates the transmitted photos to exercise registration. */
typedef struct {
    sy_fimage reflected[2], transmitted[2], flat_field, height[2];
    /* Truth in the adaxial photo's pixel grid: */
    sy_fimage albedo[2], thickness, normal[2], alpha;
    double texel_mm;
    int white_rect[4];
    double white_reflectance;
} sy_leaf_synthetic;

sy_code sy_leaf_synthesize(int size, uint64_t seed, double shift_px, const sy_leafmaps_options *o,
                           sy_leaf_synthetic *out, sy_error *err);
void sy_leaf_synthetic_free(sy_leaf_synthetic *s);

#ifdef __cplusplus
}
#endif

#endif
