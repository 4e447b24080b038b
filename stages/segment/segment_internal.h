/* The segment stage's parts, shared by its files only. */
#ifndef SYLVA_SEGMENT_INTERNAL_H
#define SYLVA_SEGMENT_INTERNAL_H

#include "segment.h"

/* What every method starts from: heights above the ground surface. */
typedef struct {
    size_t n;
    const float *xyz;  /* the plot's positions (local frame, plot->origin) */
    double origin[3];  /* plot->origin */
    double *hag;       /* n heights above ground, metres */
    uint8_t *ground;   /* n flags: 1 = a ground return */
    double lo[3], hi[3]; /* local bounds */
    double area;       /* occupied ground area, m^2 (1 m cells holding a point) */
} seg_frame;

sy_code seg_frame_build(const sy_cloud *plot, const sy_segment_options *o, seg_frame *f, sy_error *err);
void seg_frame_free(seg_frame *f);

/* A stem found at breast height (local frame). */
typedef struct {
    double x, y, r;    /* circle centre and radius (the lowest band it shows in) */
    size_t inliers;
    int band;          /* 0: the band under breast height, 1: breast height */
    double dbh;        /* diameter of the breast-height circle, else of this one */
    double ground_z;   /* local z of the ground under it */
    double arc;        /* fraction of the circle its inliers surround */
    int both_bands;    /* a circle of the other band agrees with it */
} seg_stem;

/* Stems as circles in the breast-height band; *stems malloc'd, sorted by
 * x then y. *candidates: slice clusters tried. */
sy_code seg_find_stems(const seg_frame *f, const sy_segment_options *o, seg_stem **stems, size_t *n_stems,
                       size_t *candidates, sy_error *err);


/* A tree top of the canopy height model (local frame). */
typedef struct {
    double x, y, h;
} seg_top;

/* Airborne: CHM, tops and the watershed; label as seg_grow_crowns (1..n
 * tops), *tops malloc'd. tops_only: stop after the tops (label untouched,
 * may be NULL). */
sy_code seg_chm_watershed(const seg_frame *f, const sy_segment_options *o, int tops_only, seg_top **tops,
                          size_t *n_tops, int32_t *label, sy_error *err);

/* Labels every non-ground point with the stem (1..n_stems) its shortest
 * voxel-graph path reaches first (from its lower trunk, and up the column
 * over it), -1 where no path leads; ground gets 0. */
sy_code seg_grow_crowns(const seg_frame *f, const sy_segment_options *o, const seg_stem *stems, size_t n_stems,
                        int32_t *label, sy_error *err);

/* Open-addressing map from 63-bit voxel or cell keys to indices. */
typedef struct {
    uint64_t *keys; /* UINT64_MAX: empty */
    uint32_t *vals;
    size_t mask;
} seg_map;

sy_code seg_map_init(seg_map *m, size_t n, sy_error *err);
void seg_map_put(seg_map *m, uint64_t key, uint32_t val);
/* The value or UINT32_MAX. */
uint32_t seg_map_get(const seg_map *m, uint64_t key);
void seg_map_free(seg_map *m);

/* (ix, iy, iz) with 21 bits each into one key. */
static inline uint64_t seg_key3(uint32_t ix, uint32_t iy, uint32_t iz)
{
    return ((uint64_t)ix << 42) | ((uint64_t)iy << 21) | (uint64_t)iz;
}

/* A binary min-heap of (cost, index), ties broken by index so the order is
 * fixed. */
typedef struct {
    double *cost;
    uint32_t *idx;
    size_t n, cap;
} seg_heap;

sy_code seg_heap_push(seg_heap *h, double cost, uint32_t idx, sy_error *err);
/* Pops the smallest; 0 when empty. */
int seg_heap_pop(seg_heap *h, double *cost, uint32_t *idx);
void seg_heap_free(seg_heap *h);

#endif
