/* Leaves for a skeleton that has none (a QSM, a reconstruction): leaf cards
 * along the finest branches from a species' leaf parameters, so
 * `sylva mesh QSM --species NAME` makes a leafy asset. Same frame as the
 * skeleton (positions relative to its origin, Z up); deterministic per seed. */
#ifndef SYLVA_LEAF_PLACEMENT_H
#define SYLVA_LEAF_PLACEMENT_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/skeleton.h"
#include "stages/grow/grow.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double per_metre;      /* leaves per metre of twig */
    float size;            /* leaf length, metres */
    int max_reverse_order; /* edges of reverse branch order <= this are twigs (default 2) */
    uint64_t seed;
} sy_leaf_placement;

/* From the species: size = LeafScale / sqrt(LeafQuality) (as sy_grow_tree);
 * per_metre = |Leaves| * LeafQuality spread over the nominal length of a
 * last-level Weber-Penn stem, Scale * 0Length * ... * (Levels-1)Length. */
sy_leaf_placement sy_leaf_placement_from_species(const sy_species_params *sp, uint64_t seed);

/* A species' leaf cards are sized for the grown tree (its Scale: a 13 m
 * aspen's 0.55 m cards). On a smaller tree (a 3.8 m sapling) they would be
 * oversized: the cards shrink by k = tree_height / Scale (k in [0.25, 1];
 * trees as tall as the species or taller keep them) and their count per
 * metre of twig grows by 1/k^2, so the leaf area along a twig stays. */
void sy_leaf_placement_fit_tree(sy_leaf_placement *p, const sy_species_params *sp, double tree_height);

/* Twigs are the edges parent -> child whose reverse branch order
 * (sy_skeleton_reverse_order: 1 from a tip down to the first fork, +1 per
 * fork level) is at most max_reverse_order. Each twig gets per_metre x its
 * length leaves (fractions carried from edge to edge), spread along it: base
 * on the bark at a random azimuth, axis leaning 30..60 degrees forward from
 * the radial direction, blade normal turned toward the sky. leaves is
 * initialised here; twig_length (may be NULL) gets the metres of twig. */
sy_code sy_place_leaves(const sy_skeleton *s, const sy_leaf_placement *p, sy_leaves *leaves, double *twig_length,
                        sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
