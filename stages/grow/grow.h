/* Procedural species trees after Weber & Penn (1995), as digested from seed
 * 004 (docs/species.md): a species' parameters (species/params.h) grow a
 * skeleton and leaf placements.
 *
 * Output frame: Z up, metres, the trunk base at the origin. Every stem (the
 * trunk, each branch, each split clone) gets its own branch id; a stem's first
 * node lies at its attachment point on the parent stem's axis and its parent
 * is the parent-stem node nearest that point. Leaves: pos is the leaf base
 * (where it meets the twig), local +Y runs base->tip, +Z is the blade normal,
 * scale is the leaf length; the width is scale * leaf_scale_x. */
#ifndef SYLVA_GROW_H
#define SYLVA_GROW_H

#include <stddef.h>
#include <stdint.h>

#include "species/params.h"
#include "stages/core/skeleton.h"
#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Weber-Penn ShapeRatio; shape 8 is the pruning envelope of sp (may be NULL
 * for shapes 0..7). Ratios outside [0,1] are clamped. */
float sy_shape_ratio(const sy_species_params *sp, int shape, float ratio);
/* Stem radius at normalized position z in [0,1] (thesis getRadiusZ, NaN-safe). */
float sy_stem_radius_z(float z, float taper, float radius, float length);
/* Trunk flare multiplier at z: 1 + 0.99 flare at the base, 1 from z = 1/8. */
float sy_flare_z(float z, float flare);

/* Grows one tree. The same species and seed give byte-identical output;
 * out and leaves_out (may be NULL) are initialised here and owned by the
 * caller. */
sy_code sy_grow_tree(const sy_species_params *sp, uint64_t seed, sy_skeleton *out, sy_leaves *leaves_out,
                     sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
