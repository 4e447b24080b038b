/* Space colonisation (Runions, Lane & Prusinkiewicz 2007, "Modeling trees
 * with a space colonization algorithm"), the loop both of its users share:
 * the skeleton's limbs for a crown the scan never saw inside
 * (stages/skeleton/colonize.c) and synthesis' hidden limbs inside each lobe
 * (stages/synthesize, the scaffold). Each live attraction point pulls its
 * nearest node; a node with pull grows one step along the mean of its unit
 * pulls; a point within the kill distance of a node is reached. The
 * influence radius is unbounded (the open variant of the paper). */
#ifndef SYLVA_COLONIZE_H
#define SYLVA_COLONIZE_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/status.h"

/* The grown tree: node positions, parents (-1 for the seeds) and child
 * lists (each node's children from the last grown to the first). */
typedef struct {
    float *pos;
    int32_t *parent, *first, *next;
    size_t n, cap;
} sy_colony;

/* May node v grow a child along unit dir (which it may turn; the child
 * would stand at pos[v] + step dir)? Called before the child is added, at
 * index c->n. NULL: always. */
typedef int (*sy_colony_steer)(void *ctx, const sy_colony *c, size_t v, double dir[3]);

typedef struct {
    double step, kill;  /* metres */
    double min_pull;    /* a node whose mean unit pull is shorter (pulls nearly cancel) does not grow */
    double same_cos;    /* no child within this cosine of an existing child's direction (the paper's
                           duplicate-node check) */
    size_t max_nodes;   /* seeds included */
    int max_rounds;     /* 0: until no node grows or every point is reached */
    sy_colony_steer steer;
    void *ctx;
} sy_colony_options;

/* Grows from the n_seed seeds (3 floats each) toward the n_att attraction
 * points att. c is initialised here; sy_colony_free releases it. */
sy_code sy_colony_grow(sy_colony *c, const float *seed, size_t n_seed, const float *att, size_t n_att,
                       const sy_colony_options *o, sy_error *err);
void sy_colony_free(sy_colony *c);

#endif
