/* The .sylva file: one reconstructed tree in a few kilobytes (Pirk 2013
 * Table 3.2: < 40 kB per scanned tree). It holds the main skeleton as spline
 * control points with radii and branch orders, the cluster hulls with their seed nodes, the
 * species id and the synthesis seed. Layout: docs/sylva-format.md.
 *
 * Quantisation: positions are 16-bit multiples of a power-of-two step, the
 * smallest at or above extent / 65535 (0.49 mm for a 30 m tree, 0.12 mm for
 * 8 m), so a decoded position is within half a step of the original. Radii
 * are 16-bit on a log2 scale between the smallest and largest radius
 * (relative error below (log2(rmax / rmin) / 65535) * ln 2 / 2, 5e-5 for a
 * 1000:1 range). Decoding then re-encoding with the file's own quantisation
 * reproduces the file byte for byte. */
#ifndef SYLVA_ENCODE_H
#define SYLVA_ENCODE_H

#include <stddef.h>
#include <stdint.h>

#include "stages/clusters/clusters.h"
#include "stages/core/skeleton.h"
#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Written version; the decoder reads 1 (orders derived from branch starts)
 * and 2 (orders stored per branch); 3 adds each cluster's occupancy grid; 4
 * its traced twigs, and no grid where it has them (derived from them). */
#define SY_SYLVA_VERSION 4

/* The quantisation grid of one file. */
typedef struct {
    int32_t step_log2;  /* position step = 2^step_log2 metres */
    int32_t box_min[3]; /* lower corner of the grid, in steps (relative to origin) */
    float log2_rmin, log2_rmax;
} sy_sylva_quant;

/* Header flags (byte 5). A leaf-off tree: its scan's returns lie on its
 * wood, so its lobes' traced twigs are their wood and it carries no leaf
 * cards (docs/sylva-format.md). Readers refuse bits they do not know. */
#define SY_SYLVA_LEAF_OFF 0x01u
#define SY_SYLVA_KNOWN_FLAGS SY_SYLVA_LEAF_OFF

/* What a file holds besides the skeleton and clusters. */
typedef struct {
    uint16_t species_id;
    uint8_t flags; /* SY_SYLVA_LEAF_OFF */
    uint64_t seed;
    sy_sylva_quant quant;
} sy_sylva_meta;

/* Encodes to memory (*out malloc'd). The skeleton is written in
 * breadth-first order from its root (children by index), branch ids
 * renumbered in that order; cluster points are not stored. quant NULL picks
 * the grid from the data; a given quant must cover the data (SY_EINPUT). */
sy_code sy_encode_mem(const sy_skeleton *skel, const sy_clusters *clusters, uint16_t species_id, uint64_t seed,
                      const sy_sylva_quant *quant, unsigned char **out, size_t *size, sy_error *err);

/* Sets the header flags of an encoded image and rewrites its checksum
 * (SY_EINPUT: not a .sylva image, or a flag readers would refuse). */
sy_code sy_sylva_set_flags(unsigned char *data, size_t size, uint8_t flags, sy_error *err);

/* Writes the file atomically. */
sy_code sy_encode_write(const char *path, const sy_skeleton *skel, const sy_clusters *clusters, uint16_t species_id,
                        uint64_t seed, sy_error *err);

/* Triangles per cluster hull that keep a .sylva file of n_nodes skeleton
 * nodes, n_clusters hulls and n_twigs traced twig nodes (all clusters with
 * twigs, or none) under its 40 kB target (Pirk 2013 Table 3.2), in
 * [16, 160]; the hull step (sy_hull_options.triangles) takes it. */
int sy_sylva_hull_budget(size_t n_clusters, size_t n_nodes, size_t n_twigs);
/* 1 when n_clusters hulls of 24 triangles, with their occupancy grids,
 * fit beside n_nodes skeleton nodes under the 36 kB the file aims at
 * (below that the hull budget's floor of 16 triangles a hull takes the
 * file past 40 kB: simulated 250k-point crowns split into 300-500 lobes
 * came to 50-110 kB). */
int sy_sylva_lobes_fit(size_t n_clusters, size_t n_nodes);
/* Traced twig nodes (sy_twig_options.max_nodes) such a file has room for
 * beside hulls of 24 triangles, at most about 16 kB of them; 0: none. */
size_t sy_sylva_twig_budget(size_t n_clusters, size_t n_nodes);
/* The room beside the hulls as built, under the 40 kB bound itself (with
 * a 1 kB margin): a hull the simplifier cannot bring down to its budget
 * without leaving returns out keeps more triangles (the TreeLS pine's 103
 * hulls averaged 32 of the 24 asked, and its file came to 40.95 kB). */
size_t sy_sylva_twig_room(const sy_clusters *clusters, size_t n_nodes);

/* Decodes a file image; path names it in messages. Every malformed,
 * truncated or corrupted input fails with one SY_EINPUT line naming path. */
sy_code sy_decode_mem(const char *path, const unsigned char *data, size_t size, sy_skeleton *skel,
                      sy_clusters *clusters, sy_sylva_meta *meta, sy_error *err);

sy_code sy_decode_read(const char *path, sy_skeleton *skel, sy_clusters *clusters, sy_sylva_meta *meta,
                       sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
