/* Texture helpers shared by the stages that write alpha-tested textures. */
#ifndef SYLVA_TEXTURE_H
#define SYLVA_TEXTURE_H

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Colour bleeding for alpha-tested textures: every texel that covered[] marks
 * 0 takes the colour of the covered texels around it, by push-pull (a pyramid
 * of covered-weighted box averages, pulled down to 1 x 1, then pushed back up
 * into the uncovered texels; Gortler et al. 1996, "The Lumigraph"). Covered
 * texels keep their values, so the cut-out shape is the same; the clear
 * texels that a GPU's filtering and mip levels mix in carry the surface's own
 * colours instead of whatever a photo's background or a cleared buffer left
 * there (a leaf atlas that is 86 % clear averaged to its background's
 * blue-grey at a distance). px: w x h texels of `stride` floats, of which
 * the first c bleed (the rest, e.g. alpha, stay as they are); with no texel
 * covered nothing changes. SY_EINTERNAL when memory runs out. */
sy_code sy_texture_bleed(float *px, int w, int h, int stride, int c, const unsigned char *covered, sy_error *err);

/* The same for 8-bit texels (values 0-255). */
sy_code sy_texture_bleed_u8(unsigned char *px, int w, int h, int stride, int c, const unsigned char *covered,
                            sy_error *err);

#ifdef __cplusplus
}
#endif
#endif
