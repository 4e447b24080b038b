/* A uniform grid over points, hashed by cell: the points sorted by their
 * voxel key (stages/core/voxel.h, 21 bits per axis), in index order within a
 * cell, each occupied cell's range, key and coordinates, and an open-addressing
 * table from a cell's coordinates to it. Sparse: memory follows the points,
 * never the extent. The skeleton graph's kNN and radius joins and the
 * classifier's neighbourhood covariances query it. */
#ifndef SYLVA_CORE_GRID_H
#define SYLVA_CORE_GRID_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    double h, lo[3];     /* cell edge; the points' low corner */
    size_t n_cells;      /* occupied cells */
    uint32_t *order;     /* point indices sorted by cell */
    float *pts;          /* their coordinates in that order (3 each), for locality */
    size_t *cell_start;  /* n_cells + 1 into order */
    uint64_t *cell_key;  /* n_cells */
    int32_t *cell_coord; /* 3 * n_cells */
    uint32_t *table;     /* open addressing: cell index + 1, 0 = empty */
    size_t mask;
} sy_grid;

/* Buckets the n points of xyz into cells of edge h from their low corner; h
 * grows where the extent would need more than 2^21 - 2 cells a side, and
 * becomes 1 when it is not positive. */
sy_code sy_grid_build(sy_grid *g, const float *xyz, size_t n, double h, sy_error *err);
void sy_grid_free(sy_grid *g);
/* p's cell: per axis floor((p - lo) / h) in double, clamped to the key range. */
void sy_grid_cell_of(const sy_grid *g, const float *p, int32_t c[3]);
/* The occupied cell at (x, y, z), or -1 when it is empty or out of range. */
long sy_grid_find(const sy_grid *g, int32_t x, int32_t y, int32_t z);

#ifdef __cplusplus
}
#endif

#endif
