/* A reconstructed tree from its compact file: .sylva image -> decode -> root
 * moved to the origin -> species branchlets -> cluster texturing. `sylva run`
 * goes through its own in-memory .sylva image and `sylva mesh tree.sylva`
 * through the file, so both synthesise the same tree from the same bytes. */
#ifndef SYLVA_TREE_SYNTH_H
#define SYLVA_TREE_SYNTH_H

#include <stddef.h>

#include "stages/clusters/clusters.h"
#include "stages/core/skeleton.h"
#include "species/params.h"
#include "stages/encode/encode.h"
#include "stages/synthesize/synthesize.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    sy_skeleton skel;     /* decoded main skeleton, root at (0,0,0), origin = its world position */
    sy_clusters lobes;    /* decoded hulls, same frame */
    sy_sylva_meta meta;
    sy_skeleton grown;    /* skel plus the placed patches' stems */
    sy_leaves leaves;     /* in stochastic-pruning order */
    sy_synth_report synth;
    size_t branchlets, patches; /* the species library used */
    char lsys[512];       /* its file */
    int leaf_off;         /* 1: no leaf cards: asked for, or the file marks a leaf-off tree (SY_SYLVA_LEAF_OFF) */
    float lean_radius;    /* the mesher's (sy_tree_asset_options.lean_radius): SY_MESH_LEAN_RADIUS where
                             the lobes' traced twigs were drawn, else 0 */
    double seconds_decode, seconds_library;
} sy_decoded_tree;

/* species (may be NULL): its branchlets (NAME.lsys in the species library's
 * folder, beside its .ini) and leaf size; NULL or a species without an
 * .lsys: the library's default.lsys. leaf_off, or the file's
 * SY_SYLVA_LEAF_OFF flag (t->leaf_off says which holds): a leaf-off tree,
 * whose lobes' traced twigs are their wood (sy_synth_options.bare); the
 * leaves made for the other lobes are the caller's to drop. name names the
 * image in messages. */
sy_code sy_decoded_tree_build(const char *name, const unsigned char *data, size_t size, const sy_species_params *species,
                              int leaf_off, sy_decoded_tree *t, sy_error *err);
void sy_decoded_tree_free(sy_decoded_tree *t);

/* One line per bare lobe ("lobe 3 (node 12): no room inside its hull ...") to stderr. */
void sy_decoded_tree_report_bare(const char *command, const sy_decoded_tree *t);

#ifdef __cplusplus
}
#endif

#endif
