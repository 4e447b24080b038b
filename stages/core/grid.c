/* The hashed uniform grid (grid.h). */
#include "grid.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "voxel.h"

#define KEY_BITS SY_VOXEL_BITS
#define KEY_MAX ((1 << KEY_BITS) - 1)

static uint64_t pack(int32_t x, int32_t y, int32_t z)
{
    return ((uint64_t)x << (2 * KEY_BITS)) | ((uint64_t)y << KEY_BITS) | (uint64_t)z;
}

static uint64_t mix(uint64_t k)
{
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    return k;
}

void sy_grid_cell_of(const sy_grid *g, const float *p, int32_t c[3])
{
    for (int a = 0; a < 3; a++) {
        double v = floor((p[a] - g->lo[a]) / g->h);
        c[a] = v < 0 ? 0 : v > KEY_MAX ? KEY_MAX : (int32_t)v;
    }
}

long sy_grid_find(const sy_grid *g, int32_t x, int32_t y, int32_t z)
{
    if (x < 0 || y < 0 || z < 0 || x > KEY_MAX || y > KEY_MAX || z > KEY_MAX) return -1;
    uint64_t key = pack(x, y, z);
    for (size_t s = mix(key) & g->mask;; s = (s + 1) & g->mask) {
        uint32_t v = g->table[s];
        if (!v) return -1;
        if (g->cell_key[v - 1] == key) return (long)v - 1;
    }
}

void sy_grid_free(sy_grid *g)
{
    free(g->order);
    free(g->pts);
    free(g->cell_start);
    free(g->cell_key);
    free(g->cell_coord);
    free(g->table);
    memset(g, 0, sizeof *g);
}

sy_code sy_grid_build(sy_grid *g, const float *xyz, size_t n, double h, sy_error *err)
{
    memset(g, 0, sizeof *g);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], xyz[3 * i + a]);
            hi[a] = fmax(hi[a], xyz[3 * i + a]);
        }
    /* Keep every cell coordinate within the packed key's 21 bits. */
    for (int a = 0; a < 3; a++)
        if ((hi[a] - lo[a]) / h > KEY_MAX - 2) h = (hi[a] - lo[a]) / (KEY_MAX - 2);
    if (!(h > 0)) h = 1;
    g->h = h;
    memcpy(g->lo, lo, sizeof lo);
    sy_voxel_entry *k = sy_calloc(n, sizeof *k, err, "grid");
    if (!k) return SY_EINTERNAL;
    for (size_t i = 0; i < n; i++) {
        int32_t c[3];
        sy_grid_cell_of(g, xyz + 3 * i, c);
        k[i].key = pack(c[0], c[1], c[2]);
        k[i].index = i;
    }
    sy_voxel_entries_sort(k, n); /* by cell, points of a cell in index order */
    size_t cells = 0;
    for (size_t i = 0; i < n; i++)
        if (i == 0 || k[i].key != k[i - 1].key) cells++;
    size_t tsize = 16;
    while (tsize < 2 * cells) tsize *= 2;
    g->order = sy_calloc(n, sizeof *g->order, err, "grid");
    g->pts = sy_calloc(n, 3 * sizeof *g->pts, err, "grid");
    g->cell_start = sy_calloc(cells + 1, sizeof *g->cell_start, err, "grid");
    g->cell_key = sy_calloc(cells, sizeof *g->cell_key, err, "grid");
    g->cell_coord = sy_calloc(cells, 3 * sizeof *g->cell_coord, err, "grid");
    g->table = sy_calloc(tsize, sizeof *g->table, err, "grid");
    if (!g->order || !g->pts || !g->cell_start || !g->cell_key || !g->cell_coord || !g->table) {
        free(k);
        sy_grid_free(g);
        return SY_EINTERNAL;
    }
    g->mask = tsize - 1;
    size_t c = 0;
    for (size_t i = 0; i < n; i++) {
        g->order[i] = (uint32_t)k[i].index;
        memcpy(g->pts + 3 * i, xyz + 3 * k[i].index, 3 * sizeof(float));
        if (i == 0 || k[i].key != k[i - 1].key) {
            g->cell_start[c] = i;
            g->cell_key[c] = k[i].key;
            g->cell_coord[3 * c] = (int32_t)(k[i].key >> (2 * KEY_BITS));
            g->cell_coord[3 * c + 1] = (int32_t)((k[i].key >> KEY_BITS) & KEY_MAX);
            g->cell_coord[3 * c + 2] = (int32_t)(k[i].key & KEY_MAX);
            size_t s = mix(k[i].key) & g->mask;
            while (g->table[s]) s = (s + 1) & g->mask;
            g->table[s] = (uint32_t)(c + 1);
            c++;
        }
    }
    g->cell_start[cells] = n;
    g->n_cells = cells;
    free(k);
    return SY_OK;
}
