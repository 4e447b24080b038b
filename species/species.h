/* A classifier's answer for one tree: which species of the library it is,
 * with the probability of every library species and whether the answer is
 * confident enough to use (below the threshold the pipeline treats the tree
 * as unknown). The Weber-Penn parameters of a library species are
 * sy_species_params (species/params.h); the library itself is
 * species/library.h. */
#ifndef SYLVA_SPECIES_H
#define SYLVA_SPECIES_H

#include <stddef.h>

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    int id;               /* stable library id (species/library.tsv); -1: unknown */
    char name[64];        /* the library name of id; "" when unknown */
    size_t n_classes;     /* entries of probabilities */
    float *probabilities; /* probabilities[k]: P(species with library id k), summing to 1;
                             malloc'd, owned by this struct (NULL when n_classes is 0) */
    int confident;        /* 1: the top probability passed the classifier's confidence threshold */
} sy_species;

/* An unknown species with room for n_classes probabilities, all 0 (n_classes
 * 0: none). Fails only when out of memory. */
sy_code sy_species_init(sy_species *s, size_t n_classes, sy_error *err);
void sy_species_free(sy_species *s);

#ifdef __cplusplus
}
#endif

#endif
