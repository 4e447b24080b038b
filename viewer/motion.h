/* Wind motion for the preview (Habel 2009 ch. 4.5): per-level 2-D motion textures made by
 * spectral synthesis of the wind spectrum filtered by a damped oscillator, and per-branch
 * trajectories through them whose speed sets the branch's natural frequency. Pure C, no GL. */
#ifndef SYLVA_VIEWER_MOTION_H
#define SYLVA_VIEWER_MOTION_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SY_MOTION_LEVELS 4

typedef struct {
    int size;                       /* texels per side (power of two) */
    float *texels;                  /* SY_MOTION_LEVELS layers of size^2 RG pairs, unit RMS per channel */
    double peak_cycles_per_texel;   /* where the oscillator resonates in every layer */
    double damping[SY_MOTION_LEVELS]; /* damping ratio zeta per level */
} sy_motion;

/* Builds the textures (size a power of two >= 16) from a seed; same seed, same bytes.
 * Layer l: a complex Gaussian field shaped by sqrt(P_w(f)) (Simiu & Scanlan, eq. 4.15) times
 * the textbook damped-oscillator magnitude 1 / sqrt((4 pi^2 (f_h^2 - f^2))^2 + (2 pi f gamma)^2)
 * (eq. 4.16 corrected), radially symmetric, cut at f_max = 2 f_h, which lies at 8 texels per
 * cycle (the thesis's 4x zero padding); the inverse 2-D FFT's real and imaginary parts are two
 * independent tileable fields, one per bending axis. Returns 0, or -1 when out of memory. */
int sy_motion_make(sy_motion *m, int size, double mean_wind, uint64_t seed);
void sy_motion_free(sy_motion *m);

/* Trajectory of one branch: a direction whose slope is far from small rationals (the
 * thesis's aperiodicity rule; here: |p/q - slope| > 0.02 for q <= 16), scaled so that the
 * resonance peak of the texture passes at the branch's natural frequency f_h:
 * speed = f_h / peak (texels per second). offset: a random start. */
void sy_motion_trajectory(const sy_motion *m, double f_h, uint64_t seed, uint32_t branch, float vel[2], float offset[2]);

/* In-place radix-2 complex FFT of n (power of two) values, inverse when inverse != 0 (unscaled). */
void sy_fft(double *re, double *im, int n, int inverse);

/* Grass slice textures for the ray-traced grass: `layers` RGBA8 images of w x h, blades
 * grown from a seed (non-premultiplied alpha). Returns malloc'd bytes or NULL. */
unsigned char *sy_grass_slices(int w, int h, int layers, uint64_t seed);

#ifdef __cplusplus
}
#endif

#endif
