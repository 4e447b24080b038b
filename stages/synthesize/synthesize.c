/* Cluster texturing with species patches (Pirk 2013 §3.4); see synthesize.h
 * and docs/synthesize.md. */
#include "stages/synthesize/synthesize.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/rng.h"
#include "stages/core/geometry.h"
#include "stages/core/parallel.h"
#include "stages/core/progress.h"
#include "stages/core/sort.h"
#include "stages/core/colonize.h"
#include "stages/core/vec3.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

sy_synth_options sy_synth_options_default(void)
{
    sy_synth_options o;
    memset(&o, 0, sizeof o);
    o.seed = 1;
    o.leaf_size = 0.25f;
    o.max_patches = 3000;
    o.candidates = 12;
    o.rolls = 4;
    o.outside_max = 0.2f;
    o.start_outside_max = 0.35f;
    o.grid = 16;
    return o;
}

sy_code sy_synth_options_check(const sy_synth_options *o, sy_error *err)
{
    if (!(o->leaf_size > 0 && o->leaf_size < 10)) return sy_fail(err, SY_EUSAGE, "synthesize: leaf_size must be in (0, 10) m");
    if (!(o->leaf_density >= 0 && o->leaf_density <= 1000))
        return sy_fail(err, SY_EUSAGE, "synthesize: leaf_density must be in [0, 1000]");
    if (o->max_depth < 0 || o->max_depth > 32) return sy_fail(err, SY_EUSAGE, "synthesize: max_depth must be 0..32");
    if (o->max_patches < 1 || o->candidates < 1 || o->candidates > 64 || o->rolls < 1 || o->rolls > 16)
        return sy_fail(err, SY_EUSAGE, "synthesize: max_patches >= 1, candidates 1..64, rolls 1..16");
    if (!(o->outside_max >= 0 && o->outside_max <= 1) || !(o->start_outside_max >= 0 && o->start_outside_max <= 1))
        return sy_fail(err, SY_EUSAGE, "synthesize: outside_max and start_outside_max must be in [0, 1]");
    if (o->grid < 2 || o->grid > 64) return sy_fail(err, SY_EUSAGE, "synthesize: grid must be 2..64");
    /* The species parser's ranges (species/params.c). */
    if (!(o->ratio_power >= 0 && o->ratio_power <= 10))
        return sy_fail(err, SY_EUSAGE, "synthesize: ratio_power must be in [0, 10]");
    if (o->levels < 0 || o->levels > SY_SYNTH_WP_LEVELS)
        return sy_fail(err, SY_EUSAGE, "synthesize: levels must be 0..%d", SY_SYNTH_WP_LEVELS);
    for (int l = 0; l < SY_SYNTH_WP_LEVELS; l++)
        if (!(o->level_length[l] >= 0 && o->level_length[l] <= 10))
            return sy_fail(err, SY_EUSAGE, "synthesize: level_length must be in [0, 10]");
    for (int l = 0; l < 2; l++)
        if (!(fabs(o->down_angle[l]) <= 3600 && fabs(o->down_angle_v[l]) <= 3600))
            return sy_fail(err, SY_EUSAGE, "synthesize: down_angle and down_angle_v must be within 3600 degrees");
    if (o->bare != 0 && o->bare != 1) return sy_fail(err, SY_EUSAGE, "synthesize: bare must be 0 or 1");
    if (o->fronds < 0 || o->fronds > 1000) return sy_fail(err, SY_EUSAGE, "synthesize: fronds must be 0..1000");

    return SY_OK;
}

const char *sy_synth_bare_reason(int reason)
{
    switch (reason) {
    case 0: return "no room inside its hull (flat, tiny or a single point); left bare";
    case 1: return "no branchlet patch fits inside its hull; left bare";
    default: return "no branchlet patch fits inside its hull; twigs grown to its returns, no leaves";
    }
}

double sy_winding_number(const float *verts, const uint32_t *tris, size_t n_tris, const float p[3])
{
    double sum = 0;
    for (size_t t = 0; t < n_tris; t++) {
        double a[3], b[3], c[3];
        for (int k = 0; k < 3; k++) {
            a[k] = verts[3 * tris[3 * t] + k] - p[k];
            b[k] = verts[3 * tris[3 * t + 1] + k] - p[k];
            c[k] = verts[3 * tris[3 * t + 2] + k] - p[k];
        }
        double la = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]), lb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]),
               lc = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        double det = a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0]);
        double den = la * lb * lc + (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) * lc +
                     (b[0] * c[0] + b[1] * c[1] + b[2] * c[2]) * la + (c[0] * a[0] + c[1] * a[1] + c[2] * a[2]) * lb;
        sum += 2 * atan2(det, den);
    }
    return sum / (4 * M_PI);
}

/* ---- Small vector helpers ---- */
static void rot_apply(const double R[9], const float v[3], double o[3])
{
    for (int i = 0; i < 3; i++) o[i] = R[3 * i] * v[0] + R[3 * i + 1] * v[1] + R[3 * i + 2] * v[2];
}

static void mat_mul(const double A[9], const double B[9], double C[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) C[3 * i + j] = A[3 * i] * B[j] + A[3 * i + 1] * B[3 + j] + A[3 * i + 2] * B[6 + j];
}

/* Rotation by ang about the unit axis (Rodrigues). */
static void mat_axis(const double ax[3], double ang, double R[9])
{
    double c = cos(ang), s = sin(ang), t = 1 - c, x = ax[0], y = ax[1], z = ax[2];
    double M[9] = {t * x * x + c, t * x * y - s * z, t * x * z + s * y, t * x * y + s * z, t * y * y + c,
                   t * y * z - s * x, t * x * z - s * y, t * y * z + s * x, t * z * z + c};
    memcpy(R, M, sizeof M);
}

/* The smallest rotation taking unit a onto unit b. */
static void mat_align(const double a[3], const double b[3], double R[9])
{
    double ax[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    double s = sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2]), c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    if (s < 1e-9) {
        if (c > 0) {
            double I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
            memcpy(R, I, sizeof I);
        } else {
            double perp[3] = {fabs(a[0]) < 0.9 ? 1 : 0, fabs(a[0]) < 0.9 ? 0 : 1, 0};
            double q[3] = {a[1] * perp[2] - a[2] * perp[1], a[2] * perp[0] - a[0] * perp[2], a[0] * perp[1] - a[1] * perp[0]};
            double l = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
            for (int k = 0; k < 3; k++) q[k] /= l;
            mat_axis(q, M_PI, R);
        }
        return;
    }
    for (int k = 0; k < 3; k++) ax[k] /= s;
    mat_axis(ax, atan2(s, c), R);
}

/* Unit quaternion (x, y, z, w) of the rotation with columns X, Y, Z. */
static void quat_from_basis(const double X[3], const double Y[3], const double Z[3], float q[4])
{
    double m00 = X[0], m11 = Y[1], m22 = Z[2], tr = m00 + m11 + m22, x, y, z, w;
    if (tr > 0) {
        double s = sqrt(tr + 1) * 2;
        w = 0.25 * s, x = (Y[2] - Z[1]) / s, y = (Z[0] - X[2]) / s, z = (X[1] - Y[0]) / s;
    } else if (m00 > m11 && m00 > m22) {
        double s = sqrt(1 + m00 - m11 - m22) * 2;
        w = (Y[2] - Z[1]) / s, x = 0.25 * s, y = (Y[0] + X[1]) / s, z = (Z[0] + X[2]) / s;
    } else if (m11 > m22) {
        double s = sqrt(1 + m11 - m00 - m22) * 2;
        w = (Z[0] - X[2]) / s, x = (Y[0] + X[1]) / s, y = 0.25 * s, z = (Z[1] + Y[2]) / s;
    } else {
        double s = sqrt(1 + m22 - m00 - m11) * 2;
        w = (X[1] - Y[0]) / s, x = (Z[0] + X[2]) / s, y = (Z[1] + Y[2]) / s, z = 0.25 * s;
    }
    double l = sqrt(x * x + y * y + z * z + w * w);
    q[0] = (float)(x / l), q[1] = (float)(y / l), q[2] = (float)(z / l), q[3] = (float)(w / l);
}

/* ---- The lobe's grid ---- */
/* What patch_fit reads of a cell, side by side. */
typedef struct {
    float dist;   /* distance (metres) to the nearest occupied cell; 0 in a lobe with traced twigs (never read) */
    uint8_t soft; /* inside, or next to an inside cell: the hull as a soft constraint */
    uint8_t room; /* occupied, and its block holds less leaf area than its cap (block_has_room) */
} lobe_cell;

typedef struct {
    float lo[3], hi[3];  /* hull box */
    double h;            /* cell size */
    int d[3];
    size_t n;
    uint8_t *inside;     /* winding number >= 0.5 at the cell centre */
    uint8_t *occupied;   /* inside and holding scan points */
    lobe_cell *cell;     /* what a patch's fit reads, one cache line per sample */
    uint16_t *leaves;    /* leaves placed per cell */
    int bk;              /* a block's edge in cells: about a card's length */
    int bd[3];           /* blocks of bk x bk x bk cells, where fullness is counted */
    float *block;        /* leaf area per block, in whole cards of the species' size */
    uint32_t *cell_block; /* each cell's block */
    float *block_cap;    /* leaf area a block holds, in whole cards, a whole number (0 when it has no
                            occupied cell) */
    int16_t *block_box;  /* per block: the box of its occupied cells in cells, x, y, z first and past-last */
    size_t n_occupied, n_blocks, n_filled; /* occupied cells; blocks with room; blocks holding a leaf */
    size_t n_inside;     /* cells inside the hull */
    double capacity;     /* leaves an occupied block holds on average */
    float centroid[3];   /* of the occupied cells */
    const sy_cluster *hull; /* the lobe's hull itself (leaves' distance to it) */
    float *tri_box;      /* per hull triangle: x, y, z min and max (6 floats) */
} lobe_grid;

static void grid_free(lobe_grid *g)
{
    free(g->inside), free(g->occupied), free(g->cell), free(g->leaves), free(g->block), free(g->block_cap),
        free(g->block_box);
    free(g->cell_block), free(g->tri_box);
}

static size_t block_of(const lobe_grid *g, long c) { return g->cell_block[c]; }

/* Cell c's block holds fewer leaves than the species' leaf area density allows. */
static int block_has_room(const lobe_grid *g, long c)
{
    size_t b = block_of(g, c);
    return g->block[b] < g->block_cap[b];
}

static long grid_cell(const lobe_grid *g, const double p[3])
{
    int q[3];
    for (int k = 0; k < 3; k++) {
        double t = (p[k] - g->lo[k]) / g->h;
        if (!(t >= 0) || t >= g->d[k]) return -1;
        q[k] = (int)t;
    }
    return q[0] + (long)g->d[0] * (q[1] + (long)g->d[1] * q[2]);
}

/* A leaf's stem stands inside its lobe's hull or at most this far out of
 * it (metres): the cell tests alone let a stem sit up to a cell diagonal
 * out (on the TreeLS pine's lobes 7 % of the cards stood more than 5 cm
 * out of their hull). */
#define LEAF_HULL_TOL 0.05

/* Where the vertical line through (px, py) meets triangle t of hull c: 1
 * and its height in *z, or 0. */
static int triangle_vertical_hit(const sy_cluster *c, size_t t, double px, double py, double *z)
{
    const float *a = c->verts + 3 * c->tris[3 * t], *b = c->verts + 3 * c->tris[3 * t + 1],
                *e = c->verts + 3 * c->tris[3 * t + 2];
    double d = (b[0] - a[0]) * (e[1] - a[1]) - (e[0] - a[0]) * (b[1] - a[1]);
    if (fabs(d) < 1e-18) return 0;
    double u = ((px - a[0]) * (e[1] - a[1]) - (e[0] - a[0]) * (py - a[1])) / d;
    double v = ((b[0] - a[0]) * (py - a[1]) - (px - a[0]) * (b[1] - a[1])) / d;
    if (u < 0 || v < 0 || u + v > 1) return 0;
    *z = a[2] + u * (b[2] - a[2]) + v * (e[2] - a[2]);
    return 1;
}

/* The same for the lobe grid's hull, outside the triangle's padded box
 * rejected first. */
static int vertical_hit(const lobe_grid *g, size_t t, double px, double py, double *z)
{
    const float *bx = g->tri_box + 6 * t;
    if (px < bx[0] || px > bx[1] || py < bx[2] || py > bx[3]) return 0;
    return triangle_vertical_hit(g->hull, t, px, py, z);
}

/* Hull c's bounding box. */
static void hull_box(const sy_cluster *c, float lo[3], float hi[3])
{
    for (int k = 0; k < 3; k++) lo[k] = hi[k] = c->verts[k];
    for (size_t i = 1; i < c->n_verts; i++)
        for (int k = 0; k < 3; k++) {
            if (c->verts[3 * i + k] < lo[k]) lo[k] = c->verts[3 * i + k];
            if (c->verts[3 * i + k] > hi[k]) hi[k] = c->verts[3 * i + k];
        }
}

/* 1 when p lies inside the hull or within tol of its surface: the exact
 * test behind the grid's cell-centre one, which lets a leaf sit up to half
 * a cell diagonal outside. Inside by the parity of an upward ray's
 * crossings, as grid_build's columns (the hull is closed and outward, so
 * parity and the winding number agree; a point where they could differ
 * lies on the surface, within tol either way); the triangles whose box
 * misses the ray or the point's tol-neighbourhood are skipped. Before,
 * the generalised winding number cost an atan2 per triangle for every
 * leaf (13 % of ahn3_delft's decode). */
static int near_hull(const lobe_grid *g, const double p[3], double tol)
{
    const sy_cluster *c = g->hull;
    const double px = p[0] + 1.3e-7, py = p[1] + 2.9e-7; /* off the edges and vertices, as the columns */
    size_t crossings = 0;
    double z;
    for (size_t t = 0; t < c->n_tris; t++)
        crossings += p[2] <= g->tri_box[6 * t + 5] && vertical_hit(g, t, px, py, &z) && z > p[2];
    if (crossings & 1) return 1;
    for (size_t t = 0; t < c->n_tris; t++) {
        const float *bx = g->tri_box + 6 * t;
        if (p[0] < bx[0] - tol || p[0] > bx[1] + tol || p[1] < bx[2] - tol || p[1] > bx[3] + tol ||
            p[2] < bx[4] - tol || p[2] > bx[5] + tol)
            continue;
        double v[3][3];
        for (int k = 0; k < 3; k++)
            for (int j = 0; j < 3; j++) v[k][j] = c->verts[3 * c->tris[3 * t + k] + j];
        if (sy_point_triangle_distance(p, v[0], v[1], v[2], NULL) <= tol) return 1;
    }
    return 0;
}

static int occ_bit(const sy_cluster *c, const float lo[3], const float hi[3], const double p[3])
{
    if (!c->occupancy) return 1;
    int q[3];
    for (int k = 0; k < 3; k++) {
        double e = hi[k] - lo[k], t = (p[k] - lo[k]) / (e > 0 ? e : 1) * c->occ_dims[k];
        q[k] = t < 0 ? 0 : t >= c->occ_dims[k] ? c->occ_dims[k] - 1 : (int)t;
    }
    size_t bit = (size_t)q[0] + c->occ_dims[0] * ((size_t)q[1] + c->occ_dims[1] * (size_t)q[2]);
    return (c->occupancy[bit >> 3] >> (bit & 7)) & 1;
}

/* Each cell's chamfer distance to the lobe's occupied cells (two passes,
 * 26 neighbours), on a copy of the grid with a border of unreached cells,
 * so every cell reads its neighbours without bounds tests (a border cell
 * never wins: big plus a step rounds to big). */
static sy_code grid_distances(lobe_grid *g, sy_error *err)
{
    const float big = 1e9f;
    const ptrdiff_t px = 1, py = g->d[0] + 2, pz = (ptrdiff_t)(g->d[0] + 2) * (g->d[1] + 2);
    float *pad = malloc((size_t)pz * (size_t)(g->d[2] + 2) * sizeof *pad);
    if (!pad) return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    for (ptrdiff_t i = 0; i < pz * (g->d[2] + 2); i++) pad[i] = big;
    for (int z = 0, i = 0; z < g->d[2]; z++)
        for (int y = 0; y < g->d[1]; y++)
            for (int x = 0; x < g->d[0]; x++, i++)
                if (g->occupied[i]) pad[(x + 1) * px + (y + 1) * py + (z + 1) * pz] = 0;
    /* The 13 neighbours a forward pass has visited before a cell (the
     * backward pass mirrors them): the index step and the distance to each. */
    int n_nb = 0;
    float nb_w[13];
    ptrdiff_t nb_off[13];
    for (int dz = -1; dz <= 0; dz++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                if (dz == 0 && (dy > 0 || (dy == 0 && dx >= 0))) continue;
                nb_off[n_nb] = dx * px + dy * py + dz * pz;
                nb_w[n_nb++] = (float)(g->h * sqrt((double)(dx * dx + dy * dy + dz * dz)));
            }
    /* Row by row: the 12 neighbours in rows the pass has finished, for the
     * whole row at once (independent, so the compiler vectorises them),
     * then the one before each cell in its own row, in the pass's order.
     * A minimum of the same sums in another order: the same distances. */
    float *row = malloc((size_t)g->d[0] * sizeof *row);
    if (!row) {
        free(pad);
        return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    }
    for (int pass = 0; pass < 2; pass++) {
        int s = pass ? -1 : 1;
        for (int zz = 0; zz < g->d[2]; zz++)
            for (int yy = 0; yy < g->d[1]; yy++) {
                int y = pass ? g->d[1] - 1 - yy : yy, z = pass ? g->d[2] - 1 - zz : zz;
                float *r0 = pad + px + (y + 1) * py + (z + 1) * pz; /* the row's cell x = 0 */
                for (int x = 0; x < g->d[0]; x++) row[x] = r0[x];
                for (int k = 0; k < n_nb; k++) {
                    if (nb_off[k] == -px) continue; /* the cell before, in this row: below */
                    const float *q = r0 + s * nb_off[k], w = nb_w[k];
                    for (int x = 0; x < g->d[0]; x++) {
                        float c = q[x] + w;
                        row[x] = c < row[x] ? c : row[x];
                    }
                }
                const float w = (float)g->h; /* the step to the cell before: one cell */
                for (int xx = 0; xx < g->d[0]; xx++) {
                    int x = pass ? g->d[0] - 1 - xx : xx;
                    float c = r0[x - s] + w;
                    r0[x] = c < row[x] ? c : row[x];
                }
            }
    }
    free(row);
    for (int z = 0, i = 0; z < g->d[2]; z++)
        for (int y = 0; y < g->d[1]; y++)
            for (int x = 0; x < g->d[0]; x++, i++) g->cell[i].dist = pad[(x + 1) * px + (y + 1) * py + (z + 1) * pz];
    free(pad);
    return SY_OK;
}

static sy_code grid_build(const sy_cluster *c, int cells, double density, double leaf_area, uint64_t key,
                          int distances, lobe_grid *g, sy_error *err)
{
    memset(g, 0, sizeof *g);
    g->hull = c;
    hull_box(c, g->lo, g->hi);
    double ext = 0;
    for (int k = 0; k < 3; k++)
        if (g->hi[k] - g->lo[k] > ext) ext = g->hi[k] - g->lo[k];
    g->h = ext / cells;
    if (!(g->h > 1e-4)) return SY_OK; /* a point or a sliver: no room */
    g->n = 1;
    for (int k = 0; k < 3; k++) {
        double d = ceil((g->hi[k] - g->lo[k]) / g->h - 1e-9);
        g->d[k] = d < 1 ? 1 : (int)d;
        g->n *= (size_t)g->d[k];
    }
    g->inside = sy_calloc(g->n, 1, err, "synthesis grid");
    g->occupied = sy_calloc(g->n, 1, err, "synthesis grid");
    g->cell = sy_calloc(g->n, sizeof *g->cell, err, "synthesis grid");
    g->leaves = sy_calloc(g->n, sizeof *g->leaves, err, "synthesis grid");
    g->bk = (int)lround(sqrt(2 * leaf_area) / g->h); /* the card's length */
    if (g->bk < 2) g->bk = 2;
    for (int k = 0; k < 3; k++) g->bd[k] = (g->d[k] + g->bk - 1) / g->bk;
    const size_t n_block = (size_t)g->bd[0] * g->bd[1] * g->bd[2];
    g->block = sy_calloc(n_block, sizeof *g->block, err, "synthesis grid");
    g->block_cap = sy_calloc(n_block, sizeof *g->block_cap, err, "synthesis grid");
    g->cell_block = sy_calloc(g->n, sizeof *g->cell_block, err, "synthesis grid");
    g->block_box = sy_calloc(6 * n_block, sizeof *g->block_box, err, "synthesis grid");
    if (!g->inside || !g->occupied || !g->cell || !g->leaves || !g->block || !g->block_cap || !g->cell_block ||
        !g->block_box)
        return SY_EINTERNAL;
    for (int z = 0, i = 0; z < g->d[2]; z++)
        for (int y = 0; y < g->d[1]; y++) {
            uint32_t row = (uint32_t)(g->bd[0] * (y / g->bk + g->bd[1] * (z / g->bk)));
            for (int x = 0; x < g->d[0]; x += g->bk)
                for (int xx = x; xx < x + g->bk && xx < g->d[0]; xx++, i++) g->cell_block[i] = row + (uint32_t)(x / g->bk);
        }
    /* Inside by parity along vertical rays through the cell centres: one
     * pass over the triangles per column instead of a winding number per
     * cell (the hull is closed and outward, so parity and winding agree). The
     * rays are nudged off the cell centres so they miss edges and vertices. */
    double *hits = malloc((c->n_tris + 1) * sizeof *hits);
    /* Each triangle's box, a little wider than the triangle, so a column (or
     * near_hull's ray) outside it skips the barycentric test (which would
     * reject it too). */
    g->tri_box = malloc((c->n_tris + 1) * 6 * sizeof *g->tri_box);
    if (!hits || !g->tri_box) {
        free(hits);
        return sy_fail(err, SY_EINTERNAL, "synthesis grid: out of memory");
    }
    for (size_t t = 0; t < c->n_tris; t++) {
        float *bx = g->tri_box + 6 * t;
        bx[0] = bx[2] = bx[4] = INFINITY, bx[1] = bx[3] = bx[5] = -INFINITY;
        for (int j = 0; j < 3; j++) {
            const float *v = c->verts + 3 * c->tris[3 * t + j];
            for (int k = 0; k < 3; k++) bx[2 * k] = fminf(bx[2 * k], v[k]), bx[2 * k + 1] = fmaxf(bx[2 * k + 1], v[k]);
        }
        float pad = 1e-4f * (bx[1] - bx[0] + bx[3] - bx[2]) + 1e-6f;
        for (int k = 0; k < 3; k++) bx[2 * k] -= pad, bx[2 * k + 1] += pad;
    }
    /* The triangles whose box may hold each column's ray, in triangle
     * order (a column tests only those; its hits are sorted anyway). */
    size_t n_col = (size_t)g->d[0] * (size_t)g->d[1], *col_start = calloc(n_col + 1, sizeof *col_start), *col_tri = NULL;
    int *col_span = malloc((c->n_tris + 1) * 4 * sizeof *col_span);
    if (!col_start || !col_span) {
        free(hits), free(col_start), free(col_span);
        return sy_fail(err, SY_EINTERNAL, "synthesis grid: out of memory");
    }
    for (int pass = 0; pass < 2; pass++) {
        for (size_t t = 0; t < c->n_tris; t++) {
            int *sp = col_span + 4 * t;
            if (pass == 0) {
                const float *bx = g->tri_box + 6 * t;
                /* Column x's ray is at lo + (x + 0.5) h: a cell of slack each way. */
                for (int k = 0; k < 2; k++) {
                    double a = floor((bx[2 * k] - g->lo[k]) / g->h - 0.5) - 1, b = ceil((bx[2 * k + 1] - g->lo[k]) / g->h - 0.5) + 1;
                    sp[2 * k] = a < 0 ? 0 : a >= g->d[k] ? g->d[k] : (int)a;
                    sp[2 * k + 1] = b < 0 ? -1 : b >= g->d[k] ? g->d[k] - 1 : (int)b;
                }
            }
            for (int y = sp[2]; y <= sp[3]; y++)
                for (int x = sp[0]; x <= sp[1]; x++) {
                    size_t col = (size_t)x + (size_t)g->d[0] * (size_t)y;
                    if (pass == 0) col_start[col + 1]++;
                    else col_tri[col_start[col]++] = t;
                }
        }
        if (pass == 0) {
            for (size_t i = 0; i < n_col; i++) col_start[i + 1] += col_start[i];
            col_tri = malloc((col_start[n_col] + 1) * sizeof *col_tri);
            if (!col_tri) {
                free(hits), free(col_start), free(col_span);
                return sy_fail(err, SY_EINTERNAL, "synthesis grid: out of memory");
            }
        }
    }
    /* The second pass advanced each start to the next column's. */
    for (size_t i = n_col; i > 0; i--) col_start[i] = col_start[i - 1];
    col_start[0] = 0;
    for (int y = 0; y < g->d[1]; y++)
        for (int x = 0; x < g->d[0]; x++) {
            double px = g->lo[0] + (x + 0.5) * g->h + 1.3e-7 * g->h, py = g->lo[1] + (y + 0.5) * g->h + 2.9e-7 * g->h;
            size_t nh = 0, col = (size_t)x + (size_t)g->d[0] * (size_t)y;
            for (size_t j = col_start[col]; j < col_start[col + 1]; j++) nh += vertical_hit(g, col_tri[j], px, py, hits + nh);
            qsort(hits, nh, sizeof *hits, sy_cmp_double);
            for (int z = 0; z < g->d[2]; z++) {
                double pz = g->lo[2] + (z + 0.5) * g->h;
                size_t below = 0;
                while (below < nh && hits[below] < pz) below++;
                g->inside[(size_t)x + (size_t)g->d[0] * ((size_t)y + (size_t)g->d[1] * (size_t)z)] = (uint8_t)(below & 1);
            }
        }
    free(hits), free(col_start), free(col_tri), free(col_span);
    double cs[3] = {0, 0, 0};
    for (int z = 0; z < g->d[2]; z++)
        for (int y = 0; y < g->d[1]; y++)
            for (int x = 0; x < g->d[0]; x++) {
                size_t i = (size_t)x + (size_t)g->d[0] * ((size_t)y + (size_t)g->d[1] * (size_t)z);
                double p[3] = {g->lo[0] + (x + 0.5) * g->h, g->lo[1] + (y + 0.5) * g->h, g->lo[2] + (z + 0.5) * g->h};
                g->occupied[i] = g->inside[i] && occ_bit(c, g->lo, g->hi, p);
                g->n_inside += g->inside[i];
                if (g->occupied[i]) {
                    g->n_occupied++;
                    for (int k = 0; k < 3; k++) cs[k] += p[k];
                }
            }
    if (g->n_occupied)
        for (int k = 0; k < 3; k++) g->centroid[k] = (float)(cs[k] / (double)g->n_occupied);
    /* Only patches read the distances (patch_fit): a lobe whose traced
     * twigs are its wood gets none, and skips them. */
    if (distances) {
        sy_code rc = grid_distances(g, err);
        if (rc) return rc;
    }
    const size_t sx = 1, sy = (size_t)g->d[0], sz = (size_t)g->d[0] * (size_t)g->d[1];
    /* soft: inside dilated by the 3 x 3 x 3 cube, one axis at a time. */
    uint8_t *tmp = malloc(g->n);
    if (!tmp) return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    for (size_t i = 0; i < g->n; i++) g->cell[i].soft = g->inside[i];
    const size_t stride[3] = {sx, sy, sz};
    for (int a = 0; a < 3; a++) {
        for (size_t i = 0; i < g->n; i++) tmp[i] = g->cell[i].soft;
        for (int z = 0, i = 0; z < g->d[2]; z++)
            for (int y = 0; y < g->d[1]; y++)
                for (int x = 0; x < g->d[0]; x++, i++) {
                    int q = a == 0 ? x : a == 1 ? y : z;
                    if (q > 0) g->cell[i].soft |= tmp[(size_t)i - stride[a]];
                    if (q + 1 < g->d[a]) g->cell[i].soft |= tmp[(size_t)i + stride[a]];
                }
    }
    free(tmp);
    /* A block is full when its leaves reach `density` square metres of card
     * per cubic metre of the block. Blocks are about a card long, the scale
     * at which a crown's volume is counted (a block holding a return is
     * crown; a finer count shrinks with the cells round a sparse scan's
     * points), and their share of cards, rarely a whole number, is rounded
     * up or down at random with the odds of its fraction (keyed by the lobe
     * and the block), so the expected leaf area is the density's. Before,
     * 2 x 2 x 2 blocks took a card for any share: the leaf area followed the
     * lobe grid, whatever the density (sassafras 3.6 x its true area). */
    double bh = g->bk * g->h;
    g->capacity = density * bh * bh * bh / (leaf_area > 1e-6 ? leaf_area : 1e-6); /* per occupied block */
    for (size_t b = 0; b < n_block; b++)
        for (int k = 0; k < 3; k++) g->block_box[6 * b + 2 * k] = INT16_MAX, g->block_box[6 * b + 2 * k + 1] = 0;
    for (int z = 0, i = 0; z < g->d[2]; z++)
        for (int y = 0; y < g->d[1]; y++)
            for (int x = 0; x < g->d[0]; x++, i++) {
                if (!g->occupied[i]) continue;
                size_t b = block_of(g, i);
                g->block_cap[b] = (float)g->capacity;
                const int q[3] = {x, y, z};
                int16_t *bb = g->block_box + 6 * b;
                for (int k = 0; k < 3; k++) {
                    if (q[k] < bb[2 * k]) bb[2 * k] = (int16_t)q[k];
                    if (q[k] + 1 > bb[2 * k + 1]) bb[2 * k + 1] = (int16_t)(q[k] + 1);
                }
            }
    for (size_t b = 0; b < n_block; b++) {
        double u = (double)(sy_mix64(key ^ ((uint64_t)b + 1) * 0xD1B54A32D192ED03ull) >> 11) * 0x1p-53;
        g->block_cap[b] = g->block_cap[b] > 0 ? (float)floor(g->block_cap[b] + u) : 0;
        g->n_blocks += g->block_cap[b] > 0;
    }
    for (size_t i = 0; i < g->n; i++) g->cell[i].room = g->occupied[i] && block_has_room(g, (long)i);
    return SY_OK;
}

/* A card of this length's area over a whole card's (leaf_size long). */
static float card_share(float size, double leaf_size)
{
    float q = size / (float)leaf_size;
    return q * q;
}

/* A card of share (its area over a whole card's) counted in cell c's
 * block; once the block is full, none of its cells has room (cleared when
 * it fills: a traced twig's cards go on past its block's capacity, and
 * clearing the block's cells again for each was a tenth of tree13's
 * synthesis). The block holds leaf area, not cards: a card halved to keep
 * its tip in the crown (fit_card) has a quarter of the area, and counted
 * as a whole card the species' density fell short wherever cards were
 * halved (the simulated Lombardy poplar's leaf area 0.762 -> 0.746 of its
 * true tree's when the halving came in). */
static void block_add_leaf(lobe_grid *g, long c, float share)
{
    size_t b = block_of(g, c);
    float before = g->block[b];
    g->block[b] += share;
    if (before == 0) g->n_filled++;
    if (!(before < g->block_cap[b] && g->block[b] >= g->block_cap[b])) return; /* it fills now */
    int bx = (int)(b % (size_t)g->bd[0]), by = (int)(b / (size_t)g->bd[0] % (size_t)g->bd[1]),
        bz = (int)(b / ((size_t)g->bd[0] * (size_t)g->bd[1]));
    for (int z = bz * g->bk; z < (bz + 1) * g->bk && z < g->d[2]; z++)
        for (int y = by * g->bk; y < (by + 1) * g->bk && y < g->d[1]; y++)
            for (int x = bx * g->bk; x < (bx + 1) * g->bk && x < g->d[0]; x++)
                g->cell[(size_t)x + (size_t)g->d[0] * ((size_t)y + (size_t)g->d[1] * (size_t)z)].room = 0;
}

/* Does an occupied cell of a block with room come within r (metres) of p?
 * Only such cells have room (block_add_leaf), so a patch placed at p
 * whose every leaf lies within r of it can gain nothing where none does:
 * a dock in a full region skips all its candidates' fits, and a dock a
 * candidate's reach short of any room skips that candidate's (their fits
 * would all stop on their gain or fall outside; the bytes are the same).
 * Each block's test is against the box of its occupied cells, with a
 * margin for the fit's rounding. On black_oak's
 * simulated scan 86 % of the 1.05 million fits of a decode stopped on
 * their gain when only the dock was tested, against whole blocks; tested
 * here, 0.30 million fits are left (synthesis 243 -> 158 ms). */
static int room_near(const lobe_grid *g, const double p[3], double r)
{
    const double reach = r + 1e-4 * g->h, r2 = reach * reach;
    int b0[3], b1[3];
    for (int k = 0; k < 3; k++) {
        double t0 = floor((p[k] - reach - g->lo[k]) / g->h), t1 = floor((p[k] + reach - g->lo[k]) / g->h);
        if (!(t1 >= 0) || !(t0 < g->d[k])) return 0; /* the box misses the grid (NaN too) */
        int c0 = t0 < 0 ? 0 : (int)t0, c1 = t1 >= g->d[k] ? g->d[k] - 1 : (int)t1;
        b0[k] = c0 / g->bk, b1[k] = c1 / g->bk;
    }
    for (int z = b0[2]; z <= b1[2]; z++)
        for (int y = b0[1]; y <= b1[1]; y++)
            for (int x = b0[0]; x <= b1[0]; x++) {
                size_t b = (size_t)x + (size_t)g->bd[0] * ((size_t)y + (size_t)g->bd[1] * (size_t)z);
                if (!(g->block[b] < g->block_cap[b])) continue;
                const int16_t *bb = g->block_box + 6 * b;
                double d2 = 0;
                for (int k = 0; k < 3; k++) {
                    double a = g->lo[k] + bb[2 * k] * g->h, e = g->lo[k] + bb[2 * k + 1] * g->h;
                    double o = p[k] < a ? a - p[k] : p[k] > e ? p[k] - e : 0;
                    d2 += o * o;
                }
                if (d2 <= r2) return 1;
            }
    return 0;
}

/* ---- Texturing ---- */
typedef struct {
    double pos[3], dir[3];
    double thickness;
    int32_t node;
    int depth;
} dock;

typedef struct {
    dock *q;
    size_t head, n, cap;
} dock_queue;

static int queue_push(dock_queue *Q, const dock *d)
{
    if (Q->n == Q->cap) {
        size_t nc = Q->cap ? 2 * Q->cap : 256;
        dock *t = realloc(Q->q, nc * sizeof *t);
        if (!t) return 0;
        Q->q = t, Q->cap = nc;
    }
    Q->q[Q->n++] = *d;
    return 1;
}

/* The crown: the union of every lobe's hull on one coarse grid, read by all
 * lobes (built before they are textured, read only while they run). A
 * card's tip must stay in its own lobe (below) or in the crown: the lobes
 * tile the crown, and a tip held inside its own lobe alone turned every
 * card near a border between two lobes inward, leaving a card-wide seam of
 * bare bark between them (the bundled aspen's crown drawn as a lattice of
 * leaf blocks once the mesher kept the leaves where synthesis put them). */
#define CROWN_CELLS 64
typedef struct {
    double lo[3], h;
    int d[3];
    uint8_t *inside; /* a cell whose centre lies inside some lobe's hull, gaps of one cell closed */
} crown_grid;

/* Inside cells of the crown grid: a cell whose centre lies inside some
 * lobe's hull by the parity of a vertical ray (as the lobe grids), then a
 * closing by one cell (dilate, then erode) that fills the narrow seams
 * between neighbouring hulls and keeps the crown's outer surface. */
static sy_code crown_build(const sy_clusters *lobes, crown_grid *cg, sy_error *err)
{
    memset(cg, 0, sizeof *cg);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    size_t max_tris = 0;
    for (size_t c = 0; lobes && c < lobes->n; c++) {
        const sy_cluster *C = &lobes->items[c];
        if (C->n_verts == 0) continue;
        float blo[3], bhi[3];
        hull_box(C, blo, bhi);
        for (int k = 0; k < 3; k++) lo[k] = fmin(lo[k], blo[k]), hi[k] = fmax(hi[k], bhi[k]);
        if (C->n_tris > max_tris) max_tris = C->n_tris;
    }
    double ext = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    if (!(ext > 1e-3)) return SY_OK; /* no lobes: every tip test falls back on its own lobe */
    cg->h = ext / CROWN_CELLS;
    size_t n = 1;
    for (int k = 0; k < 3; k++) {
        cg->lo[k] = lo[k] - cg->h; /* a border cell each side for the closing */
        cg->d[k] = (int)ceil((hi[k] - lo[k]) / cg->h - 1e-9) + 2;
        n *= (size_t)cg->d[k];
    }
    uint8_t *in = sy_calloc(n, 1, err, "synthesis crown"), *tmp = sy_calloc(n, 1, err, "synthesis crown");
    double *hits = malloc((max_tris + 1) * sizeof *hits);
    if (!in || !tmp || !hits) {
        free(in), free(tmp), free(hits);
        return sy_fail(err, SY_EINTERNAL, "synthesis crown: out of memory");
    }
    const int dx = cg->d[0], dy = cg->d[1], dz = cg->d[2];
    for (size_t c = 0; c < lobes->n; c++) {
        const sy_cluster *C = &lobes->items[c];
        if (C->n_tris < 4) continue;
        float blo[3], bhi[3];
        hull_box(C, blo, bhi);
        int x0 = (int)floor((blo[0] - cg->lo[0]) / cg->h), x1 = (int)floor((bhi[0] - cg->lo[0]) / cg->h);
        int y0 = (int)floor((blo[1] - cg->lo[1]) / cg->h), y1 = (int)floor((bhi[1] - cg->lo[1]) / cg->h);
        for (int y = y0; y <= y1; y++)
            for (int x = x0; x <= x1; x++) {
                if (x < 0 || y < 0 || x >= dx || y >= dy) continue;
                double px = cg->lo[0] + (x + 0.5) * cg->h + 1.3e-7 * cg->h, py = cg->lo[1] + (y + 0.5) * cg->h + 2.9e-7 * cg->h;
                size_t nh = 0;
                for (size_t t = 0; t < C->n_tris; t++) {
                    const float *a = C->verts + 3 * C->tris[3 * t], *b = C->verts + 3 * C->tris[3 * t + 1],
                                *e = C->verts + 3 * C->tris[3 * t + 2];
                    if ((px < a[0] && px < b[0] && px < e[0]) || (px > a[0] && px > b[0] && px > e[0]) ||
                        (py < a[1] && py < b[1] && py < e[1]) || (py > a[1] && py > b[1] && py > e[1]))
                        continue;
                    nh += triangle_vertical_hit(C, t, px, py, hits + nh);
                }
                if (nh < 2) continue;
                qsort(hits, nh, sizeof *hits, sy_cmp_double);
                /* Centres above an odd number of crossings: between hits 2i and 2i+1. */
                for (size_t i = 0; i + 1 < nh; i += 2) {
                    int z0 = (int)ceil((hits[i] - cg->lo[2]) / cg->h - 0.5), z1 = (int)ceil((hits[i + 1] - cg->lo[2]) / cg->h - 0.5);
                    for (int z = z0 < 0 ? 0 : z0; z < z1 && z < dz; z++)
                        in[(size_t)x + (size_t)dx * ((size_t)y + (size_t)dy * (size_t)z)] = 1;
                }
            }
    }
    free(hits);
    /* Closing by one cell, 6-neighbourhood: dilate into tmp, erode back into
     * in. Only set cells are visited. A cell whose centre lies inside a hull
     * is never on the grid's border (the border cells' centres lie outside
     * the hulls' box), so dilation stays on the grid, and a border cell of
     * the dilation erodes to empty. */
    const size_t sx = 1, sy = (size_t)dx, sz = (size_t)dx * (size_t)dy;
    memcpy(tmp, in, n);
    for (size_t i = 0; i < n; i++)
        if (in[i]) tmp[i - sx] = tmp[i + sx] = tmp[i - sy] = tmp[i + sy] = tmp[i - sz] = tmp[i + sz] = 1;
    memset(in, 0, n);
    for (int z = 1; z + 1 < dz; z++)
        for (int y = 1; y + 1 < dy; y++)
            for (int x = 1; x + 1 < dx; x++) {
                size_t i = (size_t)x + sy * (size_t)y + sz * (size_t)z;
                in[i] = tmp[i] && tmp[i - sx] && tmp[i + sx] && tmp[i - sy] && tmp[i + sy] && tmp[i - sz] && tmp[i + sz];
            }
    free(tmp);
    cg->inside = in;
    return SY_OK;
}

static int crown_holds(const crown_grid *cg, const double p[3])
{
    if (!cg || !cg->inside) return 0;
    int q[3];
    for (int k = 0; k < 3; k++) {
        double t = (p[k] - cg->lo[k]) / cg->h;
        if (!(t >= 0) || t >= cg->d[k]) return 0;
        q[k] = (int)t;
    }
    return cg->inside[(size_t)q[0] + (size_t)cg->d[0] * ((size_t)q[1] + (size_t)cg->d[1] * (size_t)q[2])];
}

typedef struct {
    sy_skeleton *out;
    sy_leaves *leaves;
    float *leaf_key; /* per leaf: share of its patch's stored order before it */
    size_t key_cap;
    int32_t next_branch;
    const crown_grid *crown; /* NULL: tips stay in their own lobe */
    size_t patches_from;     /* nodes from here on are the patches' and their carriers' (merge_lobe prunes them) */
} synth_out;

/* Eq. 3.3 with a cost that falls as the fit improves (digest §2.3):
 * thickness ratio max/min times (1 - cos of the vertical-angle difference + eps).
 * The literal form multiplies the ratio by the dot product. */
static double dock_elevation(const dock *d) { return asin(d->dir[2] > 1 ? 1 : d->dir[2] < -1 ? -1 : d->dir[2]); }

/* ce, se: the cosine and sine of dock_elevation(d), once per dock; the
 * cosine of the difference by its sum formula, so a dock costs no
 * trigonometry per patch. */
static double eq33(const sy_patch *p, const dock *d, double ce, double se, int literal)
{
    double tr = p->thickness, td = d->thickness;
    double ratio = (tr > td ? tr : td) / (tr < td ? tr : td);
    double dot = p->elevation_cos * ce + p->elevation_sin * se;
    return literal ? ratio * dot : ratio * (1 - dot + 0.05);
}

/* Length scale of a patch whose radii are scaled by rs: lengths grow more
 * slowly than radii (a limb twice as thick is about 1.5x as long; McMahon's
 * elastic similarity gives l ~ d^(2/3)), clamped so no patch becomes a giant
 * or a speck. */
static double geom_scale(double rs)
{
    double s = pow(rs, 0.6);
    return s < 0.35 ? 0.35 : s > 2 ? 2 : s;
}

/* An index with the key it is ranked by (ascending, ties by index: a total
 * order, so any sort gives the same result): the dock's candidate patches
 * by cost, the leaves by their pruning key. */
typedef struct {
    size_t idx;
    double key;
} ranked;

static int cmp_ranked(const void *a, const void *b)
{
    const ranked *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return x->idx < y->idx ? -1 : x->idx > y->idx;
}

/* Patch-to-world transform: world = pos + s R p, R = Rr T. T aligns the
 * patch root direction (azimuth 0) with the dock's direction (turned by the
 * dock's azimuth Rz, then the smallest rotation); Rr rolls by phi about the
 * dock's direction. Split so a dock computes Rz once, T once per candidate
 * and Rr once per roll. */
#define SY_SYNTH_MAX_ROLLS 16 /* sy_synth_options_check's bound */

static void placement_turn(const dock *d, double Rz[9])
{
    double az = atan2(d->dir[1], d->dir[0]);
    double zax[3] = {0, 0, 1};
    mat_axis(zax, az, Rz);
}

/* T for a patch whose direction dir (its own frame) is laid on the dock's. */
static void placement_align_dir(const float dir[3], const dock *d, const double Rz[9], double T[9])
{
    double A[9], v[3];
    rot_apply(Rz, dir, v);
    mat_align(v, d->dir, A);
    mat_mul(A, Rz, T);
}

static void placement_align(const sy_patch *p, const dock *d, const double Rz[9], double T[9])
{
    placement_align_dir(p->dir, d, Rz, T);
}

/* A frond's chord: the unit direction from its root to its farthest node
 * (its own frame, azimuth 0), to lay on a dock's direction with
 * placement_align_dir; returns the chord's length. */
static double patch_chord(const sy_patch *p, float chord[3])
{
    double best = 0;
    memcpy(chord, p->dir, 3 * sizeof *chord);
    for (size_t i = 0; i < p->n_nodes; i++) {
        const float *v = p->pos + 3 * i;
        double l = sqrt((double)v[0] * v[0] + (double)v[1] * v[1] + (double)v[2] * v[2]);
        if (l > best)
            best = l, chord[0] = (float)(v[0] / l), chord[1] = (float)(v[1] / l), chord[2] = (float)(v[2] / l);
    }
    return best;
}

/* The best k of n candidates (cmp_ranked order: cost, then index, a total
 * order) moved to the front of c in that order, as sorting all of them
 * would leave them, with k insertions instead of a sort of n. */
static void best_k(ranked *c, size_t n, size_t k)
{
    size_t m = 0; /* c[0..m) holds the best so far, sorted */
    for (size_t i = 0; i < n; i++) {
        ranked x = c[i];
        if (m == k && cmp_ranked(&x, &c[m - 1]) >= 0) continue;
        size_t j = m < k ? m++ : m - 1;
        while (j > 0 && cmp_ranked(&x, &c[j - 1]) < 0) {
            c[j] = c[j - 1];
            j--;
        }
        c[j] = x;
    }
}

/* The library's patches for dock d ranked by eq. 3.3 (only those that dock
 * further ones, terminal 0, or only those that do not, 1; -1 all), the
 * best k of them moved to the front of cands in order. Returns how many
 * are there. */
static size_t rank_candidates(const sy_branchlets *lib, const dock *d, const sy_synth_options *o, int terminal,
                              size_t k, ranked *cands)
{
    double ed = dock_elevation(d), ce = cos(ed), se = sin(ed);
    size_t nc = 0;
    for (size_t i = 0; i < lib->n_patches; i++) {
        const sy_patch *p = &lib->patches[i];
        if (!(p->thickness > 0) || p->n_nodes == 0 || (terminal >= 0 && (p->n_docks == 0) != terminal)) continue;
        cands[nc].idx = i;
        cands[nc].key = eq33(p, d, ce, se, o->literal_eq33);
        nc++;
    }
    if (nc > k) {
        best_k(cands, nc, k);
        return k;
    }
    best_k(cands, nc, nc);
    return nc;
}

typedef struct {
    double outside, dist, gain;
} fit_geo;

/* A patch's placement at a dock in lobe-grid units: the cell coordinates
 * of its point v are t = b + A v (A = s R / h, b = (pos - lo) / h), so a
 * sample costs nine multiply-adds and no division. */
typedef struct {
    double A[9], b[3];
} grid_placement;

static void grid_placement_of(const dock *d, const double R[9], double s, const lobe_grid *g, grid_placement *gp)
{
    double inv_h = 1 / g->h;
    for (int k = 0; k < 9; k++) gp->A[k] = s * R[k] * inv_h;
    for (int k = 0; k < 3; k++) gp->b[k] = (d->pos[k] - g->lo[k]) * inv_h;
}

/* The lobe cell of a patch's point v (its own coordinates) placed by gp;
 * -1 outside the grid. */
static inline long placed_cell(const float v[3], const grid_placement *gp, const lobe_grid *g)
{
    double t0 = gp->b[0] + gp->A[0] * v[0] + gp->A[1] * v[1] + gp->A[2] * v[2];
    double t1 = gp->b[1] + gp->A[3] * v[0] + gp->A[4] * v[1] + gp->A[5] * v[2];
    double t2 = gp->b[2] + gp->A[6] * v[0] + gp->A[7] * v[1] + gp->A[8] * v[2];
    /* One branch for all three axes (NaN fails every comparison). */
    int in = (t0 >= 0) & (t0 < g->d[0]) & (t1 >= 0) & (t1 < g->d[1]) & (t2 >= 0) & (t2 < g->d[2]);
    if (!in) return -1;
    return (long)t0 + (long)g->d[0] * ((long)t1 + (long)g->d[1] * (long)t2);
}

/* How patch p fits placed at d (transform R, scale s): the shares of its
 * samples (up to 24 nodes and 24 leaves) outside the lobe, their mean
 * distance from it, and the share of its leaves landing in occupied cells
 * with room. Returns 1 when it may be taken; 0, stopping early, once it
 * cannot: more than max_out of its samples outside, or, with a patch
 * already in hand (best finite), a score (0.25 key + outside + 2 dist /
 * ext - gain) that cannot fall below best; 2, stopping early, when its
 * gain cannot reach the full-lobe floor of 0.15 (the lobe is full where it
 * would go), whether or not a patch is in hand: the gain is counted as if
 * every leaf still to come had room. Outside and distance only grow as
 * samples are added, so the patches taken, and the bytes, are those of a
 * full fit (on the TreeLS pine a fit reads 15 of its up to 48 samples on
 * average). A dock none of whose candidates fits is counted full when one
 * stopped on its gain, else rejected. */
static int patch_fit(const sy_patch *p, const dock *d, const double R[9], double s, const lobe_grid *g,
                     const crown_grid *crown, double max_out, double key, double ext, double best, fit_geo *out)
{
    double far = g->h * (g->d[0] + g->d[1] + g->d[2]);
    grid_placement gp;
    grid_placement_of(d, R, s, g, &gp);
    size_t step = p->n_nodes > 24 ? p->n_nodes / 24 : 1, lstep = p->n_leaves > 24 ? p->n_leaves / 24 : 1;
    size_t n_nodes = (p->n_nodes + step - 1) / step, nl = (p->n_leaves + lstep - 1) / lstep;
    double n = (double)(n_nodes + nl ? n_nodes + nl : 1);
    /* The fewest samples outside that reject the patch, by the test's own
     * arithmetic (outside / n > max_out). */
    double reject = floor(max_out * n);
    while (reject > 0 && (reject - 1) / n > max_out) reject--;
    while (!(reject / n > max_out)) reject++;
    /* The running check multiplies where the final one divides: it only
     * stops early, and a patch it lets through meets the exact test below. */
    const double inv_n = 1 / n, inv_nl = nl ? 1 / (double)nl : 0, dist_w = 2 / (n * ext);
    double outside = 0, dist = 0, gain = 0;
    for (size_t k = 0; k < n_nodes + nl; k++) {
        const float *v = k < nl ? p->leaf_pos + 3 * (k * lstep) : p->pos + 3 * ((k - nl) * step);
        long c = placed_cell(v, &gp, g);
        int out_of_lobe = c < 0 || !g->cell[c].soft;
        if (out_of_lobe && crown) { /* a frond crossing other lobes on its way from the apex is not outside */
            double w[3];
            rot_apply(R, v, w);
            for (int j = 0; j < 3; j++) w[j] = d->pos[j] + s * w[j];
            if (crown_holds(crown, w)) continue;
        }
        outside += out_of_lobe;
        dist += c < 0 ? far : g->cell[c].dist;
        if (k < nl) gain += c >= 0 && g->cell[c].room;
        if (outside >= reject) return 0;
        if ((k & 3) == 3) {
            /* The most gain the leaves still to come can bring. */
            double left = (double)(k < nl ? nl - 1 - k : 0);
            double gain_max = (gain + left) * inv_nl;
            if (!crown && gain_max < 0.15) return 2; /* a frond is laid whatever the room */
            if (isfinite(best) && 0.25 * key + outside * inv_n + dist * dist_w - gain_max >= best) return 0;
        }
    }
    if (0.25 * key + outside / n + 2 * (dist / n) / ext - gain / (double)(nl ? nl : 1) >= best) return 0;
    out->outside = outside / n;
    out->dist = dist / n;
    out->gain = gain / (double)(nl ? nl : 1);
    return 1;
}

/* Does a node of patch p placed at d (transform R, scale s) stand above
 * height top? */
static int rises_above(const sy_patch *p, const dock *d, const double R[9], double s, double top)
{
    for (size_t i = 0; i < p->n_nodes; i++) {
        const float *v = p->pos + 3 * i;
        if (d->pos[2] + s * (R[6] * v[0] + R[7] * v[1] + R[8] * v[2]) > top) return 1;
    }
    return 0;
}

static int keys_reserve(synth_out *so, size_t need)
{
    if (need <= so->key_cap) return 1;
    size_t nc = so->key_cap ? so->key_cap * 2 : 1024;
    while (nc < need) nc *= 2;
    float *t = realloc(so->leaf_key, nc * sizeof *t);
    if (!t) return 0;
    so->leaf_key = t, so->key_cap = nc;
    return 1;
}

/* How a card may sit at its anchor w, tried in order: its stem at
 * w + s leaf_size Y, reaching d Y (d = -1: turned about its normal) for z
 * card lengths. A patch's leaf (its stem at w): as it grew, else turned to
 * point into the lobe, else slid back by half its length (its stem then
 * stands off its twig by at most that), else halved. Before, the cards on
 * a hull's skin stood out from the crown by a card length (the TreeLS pine
 * +30% wide). A twig node's card (its return at w): its middle there, else
 * from there back into the lobe, else halved the same two ways; it never
 * reaches out past its node by more than half its length (turned about its
 * middle it did: the TreeLS pine's crown width +8.8 % -> +14.5 %). At a
 * twig's tip, the last return the scan saw that way, it reaches back into
 * the lobe only (the pine +10.3 % -> +9.8 %). */
typedef struct {
    float s, d, z;
} card_try;
static const card_try PATCH_CARD[6] = {{0, 1, 1}, {0, -1, 1}, {-0.5f, 1, 1}, {0.5f, -1, 1}, {0, 1, 0.5f}, {0, -1, 0.5f}};
static const card_try TWIG_CARD[4] = {{-0.5f, 1, 1}, {0, -1, 1}, {-0.25f, 1, 0.5f}, {0, -1, 0.5f}};
static const card_try TWIG_TIP_CARD[2] = {{0, -1, 1}, {0, -1, 0.5f}};

/* Fits a leaf card of length leaf_size reaching along Y (X across it) at
 * anchor w by the first of n tries whose stem lies in the lobe (its soft
 * hull, and within LEAF_HULL_TOL of the hull itself) and whose tip lies in
 * the lobe (a cell whose centre is inside the hull) or the crown. A tip in
 * the soft hull's outer ring of cells stood up to a cell and a half out of
 * the crown: a halo of cards round the simulated Lombardy poplar (precision
 * 0.799 against its true tree; 0.836 with the tip inside). Returns the
 * card's length (0: left out); its stem in pos, X and Y turned with it. */
static float fit_card(const lobe_grid *g, const crown_grid *crown, const double w[3], const card_try *tries, int n,
                      double leaf_size, double X[3], double Y[3], float pos[3])
{
    for (int t = 0; t < n; t++) {
        double stem[3], tip[3];
        for (int k = 0; k < 3; k++) {
            stem[k] = w[k] + tries[t].s * leaf_size * Y[k];
            tip[k] = stem[k] + tries[t].d * tries[t].z * leaf_size * Y[k];
        }
        long cs = grid_cell(g, stem), ct = grid_cell(g, tip);
        if (cs < 0 || !g->cell[cs].soft || !((ct >= 0 && g->inside[ct]) || crown_holds(crown, tip)) ||
            !near_hull(g, stem, LEAF_HULL_TOL))
            continue;
        for (int k = 0; k < 3; k++) {
            pos[k] = (float)stem[k];
            if (tries[t].d < 0) X[k] = -X[k], Y[k] = -Y[k];
        }
        return tries[t].z * (float)leaf_size;
    }
    return 0;
}

/* Appends patch p at dock d (transform R, scale s); queues its docks. */
static sy_code place(const sy_patch *p, const dock *d, const double R[9], double s, double leaf_size, int frond,
                     lobe_grid *g, synth_out *so, dock_queue *Q, sy_synth_report *rep, sy_error *err)
{
    sy_skeleton *out = so->out;
    int32_t *ids = malloc((p->n_nodes + 1) * sizeof *ids);
    if (!ids) return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    double cap = d->thickness, rs = d->thickness / p->thickness; /* radii match the dock exactly */
    for (size_t i = 0; i < p->n_nodes; i++) {
        double w[3];
        rot_apply(R, p->pos + 3 * i, w);
        float pos[3];
        for (int k = 0; k < 3; k++) pos[k] = (float)(d->pos[k] + s * w[k]);
        int32_t parent = p->parent[i] < 0 ? d->node : ids[p->parent[i]];
        double r = rs * p->radius[i];
        double pr = out->radius[parent];
        if (r > cap) r = cap;
        if (r > pr) r = pr; /* thickness never grows toward the tips */
        if (r < 1e-4) r = 1e-4;
        int order = out->order[parent], branch = out->branch[parent];
        if (p->starts_branch[i]) {
            order = order < 254 ? order + 1 : 255;
            branch = so->next_branch++;
        }
        ids[i] = sy_skeleton_add(out, pos, (float)r, parent, order, branch, err);
        if (ids[i] < 0) {
            free(ids);
            return SY_EINTERNAL;
        }
    }
    rep->nodes_added += p->n_nodes;
    if (!keys_reserve(so, so->leaves->n + p->n_leaves)) {
        free(ids);
        return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    }
    for (size_t i = 0; i < p->n_leaves; i++) {
        double w[3], Y[3], Z[3], X[3];
        rot_apply(R, p->leaf_pos + 3 * i, w);
        rot_apply(R, p->leaf_dir + 3 * i, Y);
        rot_apply(R, p->leaf_normal + 3 * i, Z);
        X[0] = Y[1] * Z[2] - Y[2] * Z[1], X[1] = Y[2] * Z[0] - Y[0] * Z[2], X[2] = Y[0] * Z[1] - Y[1] * Z[0];
        float pos[3], q[4];
        for (int k = 0; k < 3; k++) w[k] = d->pos[k] + s * w[k], pos[k] = (float)w[k];
        long c = grid_cell(g, w);
        /* Leaves outside the hull (the bark may leave it by a cell, leaves
         * not), or where the lobe is already as dense as the species' leaf
         * area density, are pruned. */
        if (c < 0 || !g->inside[c] || !(frond || block_has_room(g, c))) continue;
        float size = fit_card(g, so->crown, w, PATCH_CARD, 6, leaf_size, X, Y, pos);
        if (!(size > 0)) continue;
        quat_from_basis(X, Y, Z, q);
        rep->leaves_in_hull++; /* its stem passed the exact hull test above */
        if (g->occupied[c]) g->leaves[c]++;
        block_add_leaf(g, c, card_share(size, leaf_size));
        so->leaf_key[so->leaves->n] = (float)((i + 0.5) / (double)p->n_leaves);
        if (sy_leaves_add(so->leaves, pos, q, size, ids[p->leaf_node[i]], err)) {
            free(ids);
            return SY_EINTERNAL;
        }
    }
    for (size_t k = 0; k < p->n_docks; k++) {
        const sy_dock *D = &p->docks[k];
        dock nd;
        double w[3];
        rot_apply(R, D->pos, w);
        for (int j = 0; j < 3; j++) nd.pos[j] = d->pos[j] + s * w[j];
        rot_apply(R, D->dir, nd.dir);
        nd.node = ids[D->node];
        double r = rs * D->thickness, pr = out->radius[nd.node];
        nd.thickness = r < 0.95 * pr ? r : 0.95 * pr; /* strictly thinner than where it docks */
        nd.depth = d->depth + 1;
        if (!queue_push(Q, &nd)) {
            free(ids);
            return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
        }
    }
    free(ids);
    rep->patches++;
    return SY_OK;
}

/* ---- The scaffold: the limbs inside a lobe that the scan does not resolve ---- */

/* A lobe hangs off a seed node, often metres from the leaves it holds, and
 * the limbs between them are hidden by those leaves (the simulated beech:
 * a wood return lies near 10 % of its limb length of 2 cm or more). Before
 * the patches, they are grown by space colonisation (Runions, Lane &
 * Prusinkiewicz 2007): every attractor (the lobe's occupied cells, and its
 * inside cells on a lattice of two cells) pulls its nearest scaffold node,
 * every pulled node grows one step toward the mean direction of its pulls,
 * and an attractor within the kill distance of a node is reached (a patch
 * docked there covers it). Rules that keep the limbs tree-like (without
 * the inside cells limbs ran along the lobe's shell of returns; with free
 * turns they drew arcs and hooks):
 * - one limb enters the lobe from its seed, and continues the seed's limb
 *   where that limb ends at the seed;
 * - a node's first child (its continuation) turns at most 15 degrees a step
 *   and 40 from its limb's first direction; a later one (a lateral) leaves
 *   within the species' down-angle band;
 * - no node leaves the soft hull once the limb has entered it, rises above
 *   the scan's top or comes within a step of the ground.
 * Radii by Weber & Penn's rule, the species' own (as `sylva grow`): a branch
 * of length L off a parent branch of length Lp and base radius rp starts at
 * rp (L / Lp)^RatioPower, at most 0.9 of the parent there, and tapers to the
 * thickest patch's thickness, on which patches then dock as on their own
 * twigs. Before, every start drew a straight rod from the seed as thin as a
 * patch: airborne lobes were columns of leaves on bare rods (the airborne
 * oak's IoU against its true tree 0.618, with the scaffold 0.852).
 * L is the length the species grows a branch of that level at that place,
 * Weber & Penn's nLength (Lp - 0.6 offset), not the part of it one lobe
 * holds: lobes are a few metres across, so laterals measured in them were
 * about a metre long and started far thinner than the species' own branches
 * (the simulated beech's: 0.6-1.6 m, a tenth of their limb's radius), or
 * thicker where the species' are short (the pine's: 39 laterals of 2 cm or
 * more off its limbs, where the grown pine has none). A lobe seeded
 * part-way along a limb hangs from it by its entry limb, and the laterals
 * off that entry are the limb's own next-level branches: level, length and
 * offset are the limb's (the seed's place on it plus the way along the
 * entry); a lateral off a lateral is a level further, its parent's length
 * the one its radius stands for. Past the species' levels (where Weber &
 * Penn hang leaves) and off the trunk, L stays the lateral's length in the
 * lobe: the species' length off the trunk (nLength L ShapeRatio) made every
 * lateral of a trunk's lobe a limb, the pine's and the sassafras' 2 cm
 * branches 2.7 times their trees'. docs/synthesize.md "Stop 44". */
#define SCAFFOLD_MAX_NODES 512
#define SCAFFOLD_MAX_STEPS 64
#define SCAFFOLD_KILL 0.35   /* kill distance, in the longest patch's lengths (at least two cells) */
#define SCAFFOLD_MAX_TURN 15 /* degrees a continuation turns per step at most */
#define SCAFFOLD_MAX_BEND 40 /* degrees a limb bends away from the way it left its parent at most */
#define SCAFFOLD_RATIO_POWER 1.2 /* Weber & Penn's RatioPower without a species (species/params.c's default) */

/* The limb of the main skeleton a lobe's seed lies on. */
typedef struct {
    double length, base_radius; /* of the seed's branch */
    double offset;              /* the seed's distance along its branch from where the branch leaves its parent */
    double dir[3];              /* the way the limb runs at the seed (0 at a root) */
    int ends;                   /* the seed is the limb's last node */
    int on_trunk;               /* the seed's limb is the trunk (order 0) */
    double twig_share;          /* the lobe's traced twigs over all those of the lobes at or beyond its seed */
} seed_limb;

/* The scaffold's own state beside the colony (stages/core/colonize.h):
 * the rules' parameters and per node what they need. */
typedef struct {
    const seed_limb *limb;
    double lateral[2][2]; /* radians: the angle a lateral leaves its limb at, min and max, off the trunk / off a limb */
    const lobe_grid *g;
    double step, ceiling, ground;
    double head_dir[3 * SCAFFOLD_MAX_NODES]; /* the way the node's limb left its parent limb */
    uint8_t entered[SCAFFOLD_MAX_NODES];     /* the node or one below it lies in the lobe's soft hull */
    uint8_t on_seed_limb[SCAFFOLD_MAX_NODES]; /* the node continues the seed's own limb (node 0 too) */
} scaffold;

/* Does node j's next child continue its limb (else it starts a lateral)?
 * The seed's child continues the seed's limb where the limb ends there. */
static int scaffold_continues(const scaffold *s, const sy_colony *c, size_t j)
{
    return j == 0 ? s->limb->ends : c->first[j] < 0;
}

/* The attractors of lobe g: its occupied cell centres occ_c (n_occ) and the
 * centres of its other inside cells with even coordinates. */
static float *scaffold_attractors(const lobe_grid *g, const double *occ_c, size_t n_occ, size_t *n_att)
{
    size_t lattice = (size_t)((g->d[0] + 1) / 2) * (size_t)((g->d[1] + 1) / 2) * (size_t)((g->d[2] + 1) / 2);
    float *att = malloc((n_occ + lattice + 1) * 3 * sizeof *att);
    if (!att) return NULL;
    for (size_t i = 0; i < 3 * n_occ; i++) att[i] = (float)occ_c[i];
    size_t m = n_occ;
    for (int z = 0; z < g->d[2]; z += 2)
        for (int y = 0; y < g->d[1]; y += 2)
            for (int x = 0; x < g->d[0]; x += 2) {
                size_t i = (size_t)x + (size_t)g->d[0] * ((size_t)y + (size_t)g->d[1] * (size_t)z);
                if (!g->inside[i] || g->occupied[i]) continue;
                att[3 * m] = (float)(g->lo[0] + (x + 0.5) * g->h), att[3 * m + 1] = (float)(g->lo[1] + (y + 0.5) * g->h);
                att[3 * m + 2] = (float)(g->lo[2] + (z + 0.5) * g->h);
                m++;
            }
    *n_att = m;
    return att;
}

/* The angles a lateral leaves its limb at, off the trunk (band[0]) and off
 * a limb (band[1]): the species' Weber & Penn DownAngle of levels 1 and 2
 * within its variation and 10 degrees more (25 to 90 without a species).
 * With 25 to 90 for every species, a fir's laterals rose off its trunk and
 * arched over. */
static void scaffold_lateral_bands(const sy_synth_options *o, double band[2][2])
{
    for (int l = 0; l < 2; l++) {
        double a = o->down_angle[l], v = fabs(o->down_angle_v[l]) + 10, lo = 25, hi = 90;
        if (a > 0) lo = fmax(5, a - v), hi = fmin(135, a + v);
        band[l][0] = lo * M_PI / 180, band[l][1] = hi * M_PI / 180;
    }
}

/* Turns unit dir toward unit ref onto the cone of angle lim round it: 1
 * when dir lay within it already (unchanged), 2 when turned, 0 when dir
 * points straight away from ref, with no side to turn by. */
static int within_angle(double dir[3], const double ref[3], double lim)
{
    double c = sy_v3_dot(dir, ref), side[3];
    if (c >= cos(lim)) return 1;
    for (int k = 0; k < 3; k++) side[k] = dir[k] - c * ref[k];
    if (!(sy_v3_normalize(side) > 1e-6)) return 0;
    for (int k = 0; k < 3; k++) dir[k] = cos(lim) * ref[k] + sin(lim) * side[k];
    return 2;
}

/* The direction node j grows a child in, from the unit pull dir, within
 * the rules above: a continuation turns at most SCAFFOLD_MAX_TURN from the
 * way j grew and stays within SCAFFOLD_MAX_BEND of its limb's first
 * direction (15 degrees a step still coiled a fir's limbs round its trunk),
 * the trunk's of the vertical, turning toward it by SCAFFOLD_MAX_TURN a
 * step where its top leans further;
 * a lateral leaves within the species' down-angle band (the seed's child
 * too, off the seed's limb, unless that limb ends at the seed and goes on).
 * 0 when it has no such direction. */
static int scaffold_direction(const scaffold *s, const sy_colony *col, size_t j, double dir[3])
{
    double g0[3], side[3];
    if (j == 0) {
        if (!(sy_v3_len(s->limb->dir) > 0)) return 1; /* the root of the tree: any way */
        memcpy(g0, s->limb->dir, sizeof g0);
    } else {
        for (int k = 0; k < 3; k++) g0[k] = (double)col->pos[3 * j + k] - col->pos[3 * (size_t)col->parent[j] + k];
        sy_v3_normalize(g0);
    }
    int on = scaffold_continues(s, col, j);
    double c = sy_v3_dot(dir, g0), lo = 0, hi = SCAFFOLD_MAX_TURN * M_PI / 180;
    if (!on) {
        const double *band = s->lateral[s->on_seed_limb[j] && s->limb->on_trunk ? 0 : 1];
        lo = band[0], hi = band[1];
    }
    for (int k = 0; k < 3; k++) side[k] = dir[k] - c * g0[k];
    if (!(sy_v3_normalize(side) > 1e-6)) { /* straight on or straight back: no side to turn to */
        memcpy(dir, g0, sizeof g0);
        return on && c > 0; /* a continuation goes straight on, a lateral has no way to leave */
    }
    double ang = acos(c > 1 ? 1 : c < -1 ? -1 : c);
    ang = ang < lo ? lo : ang > hi ? hi : ang;
    for (int k = 0; k < 3; k++) dir[k] = cos(ang) * g0[k] + sin(ang) * side[k];
    if (!on) return 1;
    /* A leader grows up: the trunk's hidden rest keeps within the bend of
     * the vertical, not of the way the level sets left its top (the aspen
     * sample's chain leans 30 degrees in its sparse top, and its rest went
     * on 40 more into a crook over the crown). */
    static const double up[3] = {0, 0, 1};
    const double *h = s->on_seed_limb[j] && s->limb->on_trunk ? up : s->head_dir + 3 * j;
    /* Onto the cone in one turn of SCAFFOLD_MAX_TURN at most: a leader whose
     * top leans past it (g0 outside the vertical's cone) comes round over
     * several steps. */
    int bent = within_angle(dir, h, SCAFFOLD_MAX_BEND * M_PI / 180);
    return bent == 2 ? within_angle(dir, g0, hi) != 0 : bent;
}

/* The colony's steer (sy_colony_steer): one limb from the seed, the turn
 * limits, and no node outside lobe g's soft hull once the limb from the
 * seed has reached it (bare limbs stood out of the airborne aspen's crown),
 * above the ceiling, or within a step of the ground (a fir's lowest lobes
 * reach it: tubes along the ground). Records the child's state, which
 * stays unused when the colony then drops it as a duplicate. */
static int scaffold_steer(void *ctx, const sy_colony *c, size_t j, double dir[3])
{
    scaffold *s = ctx;
    if (j == 0 && c->first[0] >= 0) return 0; /* one limb from the seed */
    if (!scaffold_direction(s, c, j, dir)) return 0;
    double p[3];
    for (int k = 0; k < 3; k++) p[k] = c->pos[3 * j + k] + s->step * dir[k];
    long cell = grid_cell(s->g, p);
    int in = cell >= 0 && s->g->cell[cell].soft;
    /* Outside the hull only on the way in: the seed's limb may reach the lobe from below it. */
    if ((!in && (s->entered[j] || c->first[j] >= 0)) || p[2] > s->ceiling || p[2] < s->ground + s->step) return 0;
    /* A continuation keeps its limb's first direction (a root seed has none:
     * its limb's first step gives it); a lateral starts a limb. */
    size_t m = c->n;
    int on = scaffold_continues(s, c, j);
    memcpy(s->head_dir + 3 * m, on && sy_v3_len(s->head_dir + 3 * j) > 0 ? s->head_dir + 3 * j : dir, 3 * sizeof *dir);
    s->entered[m] = s->entered[j] || in;
    s->on_seed_limb[m] = on && s->on_seed_limb[j];
    return 1;
}

static double colony_dist(const sy_colony *c, size_t a, size_t b)
{
    double d[3];
    for (int k = 0; k < 3; k++) d[k] = (double)c->pos[3 * a + k] - c->pos[3 * b + k];
    return sy_v3_len(d);
}

/* Adds scaffold col (its node 0 is node seed of so->out) to so->out: a node
 * continues its parent's branch through its first-grown child, the one
 * grown under the continuation's turn limits (the child carrying the most
 * tips drew a lateral's first step as a 90-degree elbow of its branch);
 * the limb from the seed starts a branch of its own, unless the seed ends
 * its limb (limb->ends): the lobe then holds that limb's hidden rest, which
 * goes on in the limb's own branch. Radii by Weber & Penn's rule from the
 * seed's branch (its length and base radius), the laterals' lengths the
 * species' own for their level (o->level_length, o->levels: above),
 * tapering to tip_r. */
static sy_code scaffold_to_skeleton(const sy_colony *col, const seed_limb *limb, int32_t seed, double ratio_power,
                                    double tip_r, const sy_synth_options *o, synth_out *so, sy_synth_report *rep, sy_error *err)
{
    sy_skeleton *sk = so->out;
    size_t n = col->n;
    int32_t cont[SCAFFOLD_MAX_NODES], head[SCAFFOLD_MAX_NODES], global[SCAFFOLD_MAX_NODES];
    double along[SCAFFOLD_MAX_NODES], blen[SCAFFOLD_MAX_NODES] = {0}, bbase[SCAFFOLD_MAX_NODES] = {0};
    double wlen[SCAFFOLD_MAX_NODES]; /* per branch head: the length its radius stands for (the species' or its own) */
    int level[SCAFFOLD_MAX_NODES];   /* per branch head: its Weber & Penn level */
    for (size_t j = 0; j < n; j++) {
        cont[j] = -1;
        if (j == 0 && !limb->ends) continue;
        for (int32_t c = col->first[j]; c >= 0; c = col->next[c]) cont[j] = c; /* the first grown, listed last */
    }
    /* Branch heads, the distance along their branch, each branch's length
     * (local branch 0: the seed's, seen up to the seed). */
    head[0] = 0, along[0] = blen[0] = limb->length, bbase[0] = limb->base_radius;
    for (size_t j = 1; j < n; j++) {
        int32_t p = col->parent[j];
        int on = cont[p] == (int32_t)j;
        head[j] = on ? head[p] : (int32_t)j;
        along[j] = (on ? along[p] : 0) + colony_dist(col, j, (size_t)p);
        blen[head[j]] = fmax(blen[head[j]], along[j]);
    }
    global[0] = seed;
    wlen[0] = blen[0], level[0] = sk->order[seed];
    sy_code rc = SY_OK;
    for (size_t j = 1; j < n && !rc; j++) {
        int32_t p = col->parent[j], gp = global[p], h = head[j];
        int on = cont[p] == (int32_t)j;
        if (h == (int32_t)j) { /* j starts a lateral off branch head[p] */
            int32_t hp = head[p];
            int of_limb = hp == 0 || (col->parent[hp] == 0 && !limb->ends);
            int lv = level[j] = (of_limb ? level[0] : level[hp]) + 1;
            double Lp = of_limb ? blen[0] : wlen[hp], rp = bbase[of_limb ? 0 : hp];
            double off = of_limb ? limb->offset + along[p] - (hp == 0 ? limb->length : 0) : along[p];
            if (lv >= 2 && lv < o->levels && o->level_length[lv] > 0 && Lp > 0) {
                wlen[j] = o->level_length[lv] * fmax(0, Lp - 0.6 * off);
                bbase[j] = fmax(tip_r, rp * pow(fmin(1, wlen[j] / Lp), ratio_power));
            } else {
                wlen[j] = blen[j];
                bbase[j] = blen[hp] > 0 ? bbase[hp] * pow(fmin(1, blen[j] / blen[hp]), ratio_power) : tip_r;
            }
        }
        double b = h == 0 ? sk->radius[seed] : bbase[h], e = fmin(b, tip_r);
        double a0 = h == 0 ? limb->length : 0, t = blen[h] > a0 ? (along[j] - a0) / (blen[h] - a0) : 1;
        double r = b + (e - b) * t, cap = (on ? 1.0 : 0.9) * sk->radius[gp];
        int order = on ? sk->order[gp] : sk->order[gp] < 254 ? sk->order[gp] + 1 : 255;
        int32_t branch = on ? sk->branch[gp] : so->next_branch++;
        global[j] = sy_skeleton_add(sk, col->pos + 3 * j, (float)(r < cap ? r : cap), gp, order, branch, err);
        if (global[j] < 0) rc = SY_EINTERNAL;
        else rep->nodes_added++, rep->scaffold_nodes++;
    }
    return rc;
}

/* The scaffold of lobe g (occupied cell centres occ_c), hanging off node
 * seed of so->out; reach: the library's longest patch, tip_r: its thickest.
 * None when every attractor lies within the kill distance of the seed. */
static sy_code grow_scaffold(const lobe_grid *g, const double *occ_c, size_t n_occ, int32_t seed, double reach,
                             double tip_r, const sy_synth_options *o, const seed_limb *limb, double ceiling,
                             double ground, synth_out *so, sy_synth_report *rep, sy_error *err)
{
    const double kill = fmax(SCAFFOLD_KILL * reach, 2 * g->h), step = fmax(0.5 * kill, 1.5 * g->h);
    size_t n_att = 0;
    float *att = scaffold_attractors(g, occ_c, n_occ, &n_att);
    scaffold *s = malloc(sizeof *s);
    if (!att || !s) {
        free(att), free(s);
        return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    }
    s->limb = limb, s->g = g, s->step = step, s->ceiling = ceiling, s->ground = ground;
    scaffold_lateral_bands(o, s->lateral);
    memcpy(s->head_dir, limb->dir, sizeof limb->dir);
    s->entered[0] = 0, s->on_seed_limb[0] = 1;
    const float *sp = so->out->pos + 3 * seed;
    size_t beyond = 0;
    for (size_t i = 0; i < n_att; i++) {
        double d[3] = {(double)att[3 * i] - sp[0], (double)att[3 * i + 1] - sp[1], (double)att[3 * i + 2] - sp[2]};
        beyond += sy_v3_len(d) > kill;
    }
    sy_code rc = SY_OK;
    if (beyond) {
        /* Pulls that nearly cancel (under 0.2 of their count) grow nothing;
         * a child within about 29 degrees of a sibling (half a step apart)
         * is a duplicate. */
        sy_colony_options co = {step, kill, 0.2, 0.875, SCAFFOLD_MAX_NODES, SCAFFOLD_MAX_STEPS, scaffold_steer, s};
        sy_colony col;
        rc = sy_colony_grow(&col, sp, 1, att, n_att, &co, err);
        if (!rc && col.n > 1)
            rc = scaffold_to_skeleton(&col, limb, seed, o->ratio_power > 0 ? o->ratio_power : SCAFFOLD_RATIO_POWER,
                                      tip_r, o, so, rep, err);
        sy_colony_free(&col);
    }
    free(att), free(s);
    return rc;
}

/* A lobe's traced twigs (sy_clusters_trace_twigs: its returns, thinned to
 * a voxel and joined by their spanning tree from the seed) as its limbs:
 * where the file has them they stand for the scaffold, which only guesses
 * the limbs from the occupied cells. Radii by a pipe model (Shinozaki et
 * al. 1964): a node carries the cross-section of the returns it leads to,
 * r = r0 (n / N)^TWIG_LENGTH_EXPONENT for n of the lobe's N nodes at or
 * beyond it, r0 a little under the seed's radius (the seed's own where the
 * lobe continues the seed's limb), at least tip_r. A node goes on in its
 * branch through the child leading to most nodes (ties: the first); the
 * others start branches an order up. */
#define TWIG_SMOOTHING 2
/* n counts length beyond a node, not the tips it feeds, so the square root
 * of the area-preserving rule thins the outer twigs too fast: rTwig's
 * corrected structure model of its sapling has r ~ (length beyond)^0.19
 * over its 1,149 cylinders (r ~ tips^0.30), and the sapling's returns lie
 * at 0.85-0.96 of those radii where the square root drew its twigs at
 * 0.79-0.82 (docs/synthesize.md "Stop 42"). 0.2 put ahn3_delft's thicker
 * twigs over its LOD0 budget (IoU -0.013). */
#define TWIG_LENGTH_EXPONENT 0.3
static sy_code twigs_to_skeleton(const sy_cluster *c, const seed_limb *limb, int32_t seed, double tip_r, synth_out *so,
                                 sy_synth_report *rep, sy_error *err)
{
    sy_skeleton *sk = so->out;
    size_t n = c->n_twigs;
    int32_t *cnt = calloc(n + 1, sizeof *cnt), *cont = malloc((n + 1) * sizeof *cont),
            *global = malloc((n + 1) * sizeof *global);
    if (!cnt || !cont || !global) {
        free(cnt), free(cont), free(global);
        return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    }
    /* Index n stands for the seed; parents come before their children. */
    for (size_t i = n; i-- > 0;) {
        cnt[i] += 1;
        size_t p = c->twig_parent[i] < 0 ? n : (size_t)c->twig_parent[i];
        cnt[p] += cnt[i];
    }
    for (size_t i = 0; i <= n; i++) cont[i] = -1;
    for (size_t i = 0; i < n; i++) {
        size_t p = c->twig_parent[i] < 0 ? n : (size_t)c->twig_parent[i];
        if (cont[p] < 0 || cnt[i] > cnt[cont[p]]) cont[p] = (int32_t)i;
    }
    if (!limb->ends) cont[n] = -1; /* the seed's limb goes on past the seed: every twig is a side branch */
    /* Smoothed along each chain, tips staying: the spanning tree zigzags by
     * up to a voxel from one return to the next, and the mesher spends
     * rings on every turn (two passes: tree1's LOD0 bark before the budget
     * 63k -> 53k triangles, its IoU 0.685 -> 0.696). A fork is smoothed
     * along its continuation (the child leading to most nodes), its side
     * twigs starting where it goes: kept at its return, the chain kinked there by
     * up to 94 degrees between two rings, the parent's tube folded on the
     * inside of the kink, and the side twig it carries could not be welded
     * (AdTree's tree13 welded 954 of its 978 LOD0 junctions, now 1,058 of
     * 1,068: smoother chains take fewer rings, so more twigs fit the budget). */
    float *pos = malloc((n + 1) * 3 * sizeof *pos);
    if (!pos) {
        free(cnt), free(cont), free(global);
        return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    }
    memcpy(pos, c->twig_pos, n * 3 * sizeof *pos);
    memcpy(pos + 3 * n, sk->pos + 3 * (size_t)seed, 3 * sizeof *pos);
    for (int pass = 0; pass < TWIG_SMOOTHING; pass++) {
        float *nx = malloc(n * 3 * sizeof *nx);
        if (!nx) break;
        memcpy(nx, pos, n * 3 * sizeof *nx);
        for (size_t i = 0; i < n; i++) {
            if (cont[i] < 0) continue; /* a tip */
            size_t p = c->twig_parent[i] < 0 ? n : (size_t)c->twig_parent[i], q = (size_t)cont[i];
            for (int k = 0; k < 3; k++) nx[3 * i + k] = 0.5f * pos[3 * i + k] + 0.25f * (pos[3 * p + k] + pos[3 * q + k]);
        }
        memcpy(pos, nx, n * 3 * sizeof *nx);
        free(nx);
    }
    double r0 = (cont[n] >= 0 ? 1.0 : 0.9) * sk->radius[seed] * sqrt(limb->twig_share), total = cnt[n] > 0 ? cnt[n] : 1;
    global[n] = seed;
    sy_code rc = SY_OK;
    for (size_t i = 0; i < n && !rc; i++) {
        size_t p = c->twig_parent[i] < 0 ? n : (size_t)c->twig_parent[i];
        int32_t gp = global[p];
        int on = cont[p] == (int32_t)i;
        double r = r0 * pow(cnt[i] / total, TWIG_LENGTH_EXPONENT);
        if (r < tip_r) r = tip_r;
        if (r > sk->radius[gp]) r = sk->radius[gp];
        int order = on ? sk->order[gp] : sk->order[gp] < 254 ? sk->order[gp] + 1 : 255;
        int32_t branch = on ? sk->branch[gp] : so->next_branch++;
        global[i] = sy_skeleton_add(sk, pos + 3 * i, (float)r, gp, order, branch, err);
        if (global[i] < 0) rc = SY_EINTERNAL;
        else rep->nodes_added++;
    }
    free(cnt), free(cont), free(global), free(pos);
    return rc;
}

/* Leaves on a lobe's traced twigs (its nodes from node0 on): each twig
 * node stands at a return (smoothed along its chain, about a third of
 * a voxel on average), so a card there draws foliage where the scan saw
 * some: its middle on the node or, where that does not fit and at a twig's tip,
 * reaching from it back into the lobe (TWIG_CARD, TWIG_TIP_CARD); its leaf
 * counts in the node's block. The lobe takes the leaves its blocks
 * hold at the species' leaf area density (the patches' budget, grid_build)
 * in rounds: each round visits the nodes in an order keyed by the lobe's
 * stream and gives each one more card, spaced by the golden angle around
 * its twig and leaving it at TWIG_LEAF_ANGLE, up to TWIG_LEAVES_MAX a node.
 * The cards pass the tests a patch's leaves pass (fit_card). On AdTree's
 * tree1, IoU against its scan 0.628 with the species' branchlets docked on
 * the twigs, 0.679 with the cards on them; the bundled aspen against its
 * true tree 0.837 -> 0.841, leaf area 0.56 -> 0.61 of the truth's (each
 * block's own cap instead of the lobe's: 0.44, the nodes' voxels reach
 * fewer blocks than the patches do). */
#define TWIG_LEAVES_MAX 8
#define TWIG_LEAF_ANGLE 0.5 /* radians from the twig's way on */
#define GOLDEN_ANGLE 2.39996322972865332
static sy_code leaves_on_twigs(lobe_grid *g, synth_out *so, size_t node0, double leaf_size, uint64_t rng,
                               sy_synth_report *rep, sy_error *err)
{
    const sy_skeleton *sk = so->out;
    size_t n = sk->n > node0 ? sk->n - node0 : 0;
    double budget = 0;
    for (size_t b = 0; b < (size_t)g->bd[0] * g->bd[1] * g->bd[2]; b++) budget += g->block_cap[b];
    ranked *order = malloc((n + 1) * sizeof *order);
    uint8_t *tip = malloc(n + 1);
    if (!order || !tip) {
        free(order), free(tip);
        return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    }
    memset(tip, 1, n + 1);
    for (size_t j = 0; j < n; j++)
        if (sk->parent[node0 + j] >= (int32_t)node0) tip[(size_t)sk->parent[node0 + j] - node0] = 0;
    for (size_t j = 0; j < n; j++)
        order[j].idx = node0 + j, order[j].key = (double)(sy_mix64(rng ^ ((uint64_t)j + 1) * 0x9E3779B97F4A7C15ull) >> 11);
    qsort(order, n, sizeof *order, cmp_ranked);
    sy_code rc = SY_OK;
    size_t placed = 0;
    double held = 0; /* their area, in whole cards (block_add_leaf) */
    for (int round = 0; round < TWIG_LEAVES_MAX && held < budget && !rc; round++) {
        size_t at_start = placed;
        for (size_t j = 0; j < n && held < budget && !rc; j++) {
            int32_t i = (int32_t)order[j].idx, p = sk->parent[i];
            double w[3] = {sk->pos[3 * i], sk->pos[3 * i + 1], sk->pos[3 * i + 2]}, t[3] = {0, 0, 1};
            long c = grid_cell(g, w);
            if (c < 0 || !g->inside[c]) continue;
            if (p >= 0) {
                for (int k = 0; k < 3; k++) t[k] = w[k] - sk->pos[3 * p + k];
                if (sy_v3_len(t) < 1e-9) t[0] = t[1] = 0, t[2] = 1;
                sy_v3_normalize(t);
            }
            /* A basis across the twig, and this round's way round it. */
            double e1[3], e2[3];
            sy_v3_basis_across(t, e1, e2);
            double az = 2 * M_PI * (double)(sy_mix64(rng ^ (uint64_t)i * 0xD1B54A32D192ED03ull) >> 11) * 0x1p-53 +
                        round * GOLDEN_ANGLE;
            double Y[3], Z[3], X[3];
            for (int k = 0; k < 3; k++)
                Y[k] = cos(TWIG_LEAF_ANGLE) * t[k] + sin(TWIG_LEAF_ANGLE) * (cos(az) * e1[k] + sin(az) * e2[k]);
            sy_v3_normalize(Y);
            sy_v3_card_frame(Y, e1, X, Z); /* the blade faces up as far as it can */
            float pos[3], q[4];
            float size = tip[i - node0] ? fit_card(g, so->crown, w, TWIG_TIP_CARD, 2, leaf_size, X, Y, pos)
                                        : fit_card(g, so->crown, w, TWIG_CARD, 4, leaf_size, X, Y, pos);
            if (!(size > 0)) continue;
            quat_from_basis(X, Y, Z, q);
            if (!keys_reserve(so, so->leaves->n + 1)) {
                rc = sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
                break;
            }
            rep->leaves_in_hull++; /* its stem passed fit_card's hull test */
            if (g->occupied[c]) g->leaves[c]++;
            float share = card_share(size, leaf_size);
            block_add_leaf(g, c, share);
            if (sy_leaves_add(so->leaves, pos, q, size, i, err)) rc = SY_EINTERNAL;
            placed++, held += share;
        }
        if (placed == at_start) break; /* no node takes a card any more */
    }
    /* The pruning order: the cards as placed, spread over (0, 1) as a
     * patch's leaves are (sy_synthesize sorts every lobe's together), so
     * each LOD keeps the same share of every lobe, the first round's cards
     * (one a node) last. */
    for (size_t k = 0; !rc && k < placed; k++) so->leaf_key[so->leaves->n - placed + k] = (float)((k + 0.5) / (double)placed);
    free(order), free(tip);
    return rc;
}

/* A start from bark of radius r: a little thinner, at most the library's
 * thickest patch root. */
static double start_thickness(double r, double max_thick) { return r * 0.9 < max_thick ? r * 0.9 : max_thick; }

/* Where a start of a lobe leaves its bark: point, unit direction, the
 * thickness of what it grows. */
typedef struct {
    float at[3];
    double dir[3], thickness;
} start_leaving;

/* A start's first patch leaves the dock at pos towards target, else
 * (target on the dock) the way from the start's bark sp to its cell near,
 * else straight up: unit dir. */
static void start_direction(const double pos[3], const double target[3], const double near[3], const float sp[3],
                            double dir[3])
{
    sy_v3_sub(dir, target, pos);
    if (sy_v3_len(dir) < 1e-6)
        for (int k = 0; k < 3; k++) dir[k] = near[k] - sp[k];
    if (sy_v3_len(dir) < 1e-9) dir[0] = dir[1] = 0, dir[2] = 1;
    sy_v3_normalize(dir);
}

/* Two starts of a lobe leaving the bark within a few of their radii of each
 * other and within START_SPREAD of one direction drew two limbs along one
 * path, their bark through each other and their base rings crossing on the
 * parent, so that neither welded. The earlier start that start x would be
 * such a pair with, or NULL. */
#define START_SPREAD 0.906 /* cos 25 degrees */
#define START_ROOM 4.0     /* radii of the thicker start */
static const start_leaving *start_crowding(const start_leaving *earlier, int n, const start_leaving *x)
{
    for (int i = 0; i < n; i++) {
        const start_leaving *e = &earlier[i];
        double room = START_ROOM * (e->thickness > x->thickness ? e->thickness : x->thickness), d2 = 0, c = 0;
        for (int k = 0; k < 3; k++) d2 += (double)(e->at[k] - x->at[k]) * (e->at[k] - x->at[k]), c += e->dir[k] * x->dir[k];
        if (d2 < room * room && c > START_SPREAD) return e;
    }
    return NULL;
}

/* Of a lobe's occupied cells (occ, their centres occ_c, in index order),
 * the one with room and not yet tried nearest p, or with farthest the one
 * farthest from it (the first in index order of equals): its cell index
 * (-1: none), its centre in c and its squared distance in *d2. */
static long cell_with_room(const lobe_grid *g, const size_t *occ, const double *occ_c, size_t n_occ,
                           const uint8_t *tried, const double p[3], int farthest, double c[3], double *d2)
{
    long best_i = -1;
    double best = farthest ? -1 : INFINITY;
    for (size_t o = 0; o < n_occ; o++) {
        size_t i = occ[o];
        if (tried[i] || !g->cell[i].room) continue;
        const double *q = occ_c + 3 * o;
        double dd = (q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) + (q[2] - p[2]) * (q[2] - p[2]);
        if (farthest ? dd > best : dd < best) best = dd, best_i = (long)i, memcpy(c, q, 3 * sizeof *c);
    }
    *d2 = best;
    return best_i;
}

/* A crown of fronds' frond, to be laid in lobe `lobe` from the shaft
 * toward `to` (fronds_aim). */
typedef struct {
    float to[3];
    int32_t lobe;
} frond_aim;

/* Lays one frond in lobe g from shaft node `from` (or `down` of the way on
 * to the node below it) toward `to`: the species
 * branchlet (a whole frond) and roll that fit best (eq. 3.3's key, the
 * share outside the crown, the distance from the lobe's returns, the share
 * of its leaflets in cells with room), its chord laid from the shaft to
 * `to`, scaled to reach it, rolled at most FROND_ROLL either way so it
 * arches up. Not laid (*laid 0) where every roll rises above the scan's
 * top or, with min_gain > 0, where the best lands fewer than that share of
 * its leaflets in cells with room. It keeps all its leaflets that fall
 * inside the lobe (place): pruned one by one, its rachis stood bare between
 * them. */
#define FROND_ROLL (M_PI / 9)
static sy_code lay_frond(lobe_grid *g, int32_t from, double down, const double to[3], double min_gain,
                         const sy_branchlets *lib, const sy_synth_options *o, double max_thick, double ceiling,
                         double ext, ranked *cands, synth_out *so, sy_synth_report *rep, int *laid, sy_error *err)
{
    *laid = 0;
    const float *fp = so->out->pos + 3 * from;
    dock d;
    d.node = from, d.depth = 0;
    d.thickness = start_thickness(so->out->radius[from], max_thick);
    for (int k = 0; k < 3; k++) d.pos[k] = fp[k];
    if (from > 0 && down > 0)
        for (int k = 0; k < 3; k++) d.pos[k] += down * (so->out->pos[3 * (from - 1) + k] - fp[k]);
    for (int k = 0; k < 3; k++) d.dir[k] = to[k] - d.pos[k];
    double reach_to = sy_v3_len(d.dir);
    if (!(reach_to > 1e-6)) return SY_OK;
    sy_v3_normalize(d.dir);
    double Rz[9], Rr[3][9];
    placement_turn(&d, Rz);
    for (int r = 0; r < 3; r++) mat_axis(d.dir, (r - 1) * FROND_ROLL, Rr[r]);
    size_t nc = rank_candidates(lib, &d, o, -1, (size_t)o->candidates, cands);
    double best = INFINITY, best_gain = 0, bestR[9] = {0}, best_s = 1;
    size_t best_i = 0;
    for (size_t ci = 0; ci < nc; ci++) {
        const sy_patch *p = &lib->patches[cands[ci].idx];
        float chord[3];
        double len = patch_chord(p, chord), T[9];
        double sc = len > 0 ? reach_to / len : 1;
        sc = sc < 0.35 ? 0.35 : sc > 3 ? 3 : sc;
        placement_align_dir(chord, &d, Rz, T);
        for (int r = 0; r < 3; r++) {
            double R[9];
            mat_mul(Rr[r], T, R);
            if (rises_above(p, &d, R, sc, ceiling)) continue;
            fit_geo f = {0, 0, 0};
            if (patch_fit(p, &d, R, sc, g, so->crown, 1, cands[ci].key, ext, best, &f) != 1) continue;
            double score = 0.25 * cands[ci].key + f.outside + 2 * f.dist / ext - f.gain;
            if (score < best)
                best = score, best_gain = f.gain, best_i = cands[ci].idx, best_s = sc, memcpy(bestR, R, sizeof R);
        }
    }
    if (!isfinite(best) || best_gain < min_gain) return SY_OK;
    dock_queue Q = {0}; /* a frond has no docks */
    sy_code rc = place(&lib->patches[best_i], &d, bestR, best_s, o->leaf_size, 1, g, so, &Q, rep, err);
    free(Q.q);
    *laid = !rc;
    return rc;
}

/* Where the k-th frond leaves a shaft of local nodes 0..top: a round of
 * fronds from its nodes, apex down, then a round from the midpoints of the
 * segments below them, and so on in turn (*node, and *down the share of the
 * way on to the node below). From the nodes alone 72 fronds left 4-5
 * nodes of the bundled palm, and their crowded rings were capped: over the
 * two palm samples and the simulated palm's three seeds 292 of 339 LOD0
 * junctions welded, 304 of 339 now (interleaving nodes and midpoints welded
 * 308 of 343, but the simulated palm's seed 3 fell to IoU 0.795). */
static void frond_base(int32_t top, int k, int32_t *node, double *down)
{
    *node = top - k % (top + 1);
    *down = top > 0 && (k / (top + 1)) % 2 ? 0.5 : 0;
}

/* Lays lobe g's fronds from its shaft, local nodes 0..top (the apex); the
 * k-th leaves where frond_base puts it, from the apex down. First
 * those aimed at it (aims, n_aims of them: every lobe's; fronds_aim), then
 * up to `between` more (fronds_between) where its returns hold room for
 * leaflets that they left: each toward the occupied cell with room
 * farthest from the apex, laid where FROND_GAIN of its leaflets find room. The aimed fronds
 * end at the crown's spikes; the others fill between them (the simulated
 * palm, seeds 1-3: IoU against its true tree 0.748-0.773 with the aimed
 * ones alone, a third of its leaf area; 0.802-0.825 with both;
 * docs/synthesize.md stop 47). */
#define FROND_GAIN 0.3
static sy_code lay_fronds(lobe_grid *g, const size_t *occ, const double *occ_c, size_t n_occ, uint8_t *tried,
                          int32_t lobe_index, const frond_aim *aims, size_t n_aims, int between, int32_t top,
                          const sy_branchlets *lib, const sy_synth_options *o, double max_thick, double ceiling,
                          double ext, ranked *cands, synth_out *so, sy_synth_report *rep, sy_error *err)
{
    sy_code rc = SY_OK;
    int k = 0, laid;
    int32_t node;
    double down;
    for (size_t a = 0; a < n_aims && !rc; a++) {
        if (aims[a].lobe != lobe_index) continue;
        const double to[3] = {aims[a].to[0], aims[a].to[1], aims[a].to[2]};
        frond_base(top, k, &node, &down);
        rc = lay_frond(g, node, down, to, 0, lib, o, max_thick, ceiling, ext, cands, so, rep, &laid, err);
        k++;
    }
    const double ap[3] = {so->out->pos[3 * top], so->out->pos[3 * top + 1], so->out->pos[3 * top + 2]};
    for (int extra = 0, tries = 0; !rc && extra < between && tries < 8 * between; tries++) {
        double far_c[3], far_d;
        long far_i = cell_with_room(g, occ, occ_c, n_occ, tried, ap, 1, far_c, &far_d);
        if (far_i < 0) break;
        tried[far_i] = 1;
        frond_base(top, k, &node, &down);
        rc = lay_frond(g, node, down, far_c, FROND_GAIN, lib, o, max_thick, ceiling, ext, cands, so, rep, &laid, err);
        if (laid) k++, extra++;
    }
    return rc;
}

static sy_code texture_lobe(const sy_cluster *c, int32_t lobe_index, const sy_branchlets *lib, const sy_synth_options *o,
                            const seed_limb *limb, const frond_aim *aims, size_t n_aims, int between, double density,
                            int max_depth,
                            double max_thick, double ceiling, double ground, ranked *cands, synth_out *so,
                            sy_synth_report *rep, size_t *occupied, size_t cells[2], sy_error *err)
{
    double leaf_area = 0.5 * o->leaf_size * o->leaf_size; /* a card about half as wide as long */
    uint64_t rng = o->seed * 0x9E3779B97F4A7C15ull ^ ((uint64_t)lobe_index + 1) * 0xD1B54A32D192ED03ull;
    lobe_grid g;
    int twigs = c->n_twigs && !o->fronds; /* its traced twigs are its wood: no patches */
    sy_code rc = grid_build(c, o->grid, density, leaf_area, sy_mix64(rng ^ 0x5851F42D4C957F2Dull), !twigs, &g, err);
    size_t placed0 = rep->patches;
    int bare_reason = -1;
    if (!rc && g.n_occupied == 0) bare_reason = 0;
    dock_queue Q = {0};
    const sy_skeleton *sk = so->out;
    int32_t seed = c->seed;
    double lobe_ext = g.h * (g.d[0] > g.d[1] ? (g.d[0] > g.d[2] ? g.d[0] : g.d[2]) : (g.d[1] > g.d[2] ? g.d[1] : g.d[2]));
    enum { max_starts = 96 };
    int starts = 0, failed = 0, crowded = 0, n_started = 0;
    start_leaving started[2 * max_starts]; /* each start's carrier and its first patch */
    uint8_t *tried = calloc(g.n + 1, 1); /* cells a start aimed at already */
    /* The occupied cells in index order, with their centres: every start
     * looks only at them. */
    size_t n_occ = 0, *occ = malloc((g.n + 1) * sizeof *occ);
    double *occ_c = malloc((g.n + 1) * 3 * sizeof *occ_c);
    if (occ && occ_c && !rc)
        for (int z = 0; z < g.d[2]; z++)
            for (int y = 0; y < g.d[1]; y++)
                for (int x = 0; x < g.d[0]; x++) {
                    size_t i = (size_t)x + (size_t)g.d[0] * ((size_t)y + (size_t)g.d[1] * (size_t)z);
                    if (!g.occupied[i]) continue;
                    occ_c[3 * n_occ] = g.lo[0] + (x + 0.5) * g.h, occ_c[3 * n_occ + 1] = g.lo[1] + (y + 0.5) * g.h;
                    occ_c[3 * n_occ + 2] = g.lo[2] + (z + 0.5) * g.h;
                    occ[n_occ++] = i;
                }
    double reach = 0, min_thick = INFINITY;
    for (size_t i = 0; i < lib->n_patches; i++) {
        if (lib->patches[i].extent > reach) reach = lib->patches[i].extent;
        if (lib->patches[i].thickness > 0 && lib->patches[i].thickness < min_thick) min_thick = lib->patches[i].thickness;
    }
    if (!isfinite(min_thick)) min_thick = 0.002;
    if (!tried || !occ || !occ_c) rc = sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    size_t lobe_node0 = sk->n; /* nodes from here on are this lobe's bark */
    double min_start = sk->radius[seed] * 0.9 < max_thick ? sk->radius[seed] * 0.9 : max_thick;
    size_t lobe_patches = 0;
    size_t scaffold0 = rep->nodes_added;
    if (!rc && bare_reason < 0 && twigs)
        rc = twigs_to_skeleton(c, limb, seed, min_thick, so, rep, err);
    else if (!rc && bare_reason < 0 && !o->fronds)
        rc = grow_scaffold(&g, occ_c, n_occ, seed, reach, max_thick, o, limb, ceiling, ground, so, rep, err);
    int scaffolded = rep->nodes_added > scaffold0;
    so->patches_from = sk->n;
    /* Traced twigs are the lobe's wood: the species' branchlets would add
     * twigs beside the returns, not on them (AdTree's tree1, IoU against
     * its scan 0.639 with them, 0.692 without). A leaf-off tree keeps them
     * bare, a leafy one carries its leaves on them (leaves_on_twigs). */
    if (twigs || o->fronds) starts = max_starts;
    if (!rc && bare_reason < 0 && o->fronds)
        rc = lay_fronds(&g, occ, occ_c, n_occ, tried, lobe_index, aims, n_aims, between, seed, lib, o, max_thick, ceiling,
                        lobe_ext > 0 ? lobe_ext : 1, cands, so, rep, err);
    if (!rc && bare_reason < 0 && twigs && !o->bare)
        rc = leaves_on_twigs(&g, so, lobe_node0, o->leaf_size, sy_mix64(rng ^ 0x2545F4914F6CDD1Dull), rep, err);
    while (!rc && bare_reason < 0 && starts < max_starts && lobe_patches < (size_t)o->max_patches) {
        /* A new start toward the occupied cell with room nearest the seed,
         * from the nearest bark this lobe has (its scaffold, its patches or
         * the seed): where that lies farther than a cell and a half, a
         * straight carrier limb bridges the gap and the first patch docks
         * at its end. */
        double target[3] = {0, 0, 0}, cnt = 0, near[3] = {0, 0, 0}, near_d;
        const double ss[3] = {sk->pos[3 * seed], sk->pos[3 * seed + 1], sk->pos[3 * seed + 2]};
        long near_i = cell_with_room(&g, occ, occ_c, n_occ, tried, ss, 0, near, &near_d);
        if (near_i < 0) break;
        tried[near_i] = 1;
        /* Aim at the empty occupied cells around it (within a large patch's reach). */
        for (size_t o = 0; o < n_occ; o++) {
            if (g.leaves[occ[o]]) continue;
            const double *c = occ_c + 3 * o;
            double dd = (c[0] - near[0]) * (c[0] - near[0]) + (c[1] - near[1]) * (c[1] - near[1]) +
                        (c[2] - near[2]) * (c[2] - near[2]);
            if (dd > reach * reach) continue;
            for (int k = 0; k < 3; k++) target[k] += c[k];
            cnt++;
        }
        /* (Every cell within reach may hold leaves already: aim at the cell.) */
        for (int k = 0; k < 3; k++) target[k] = cnt > 0 ? target[k] / cnt : near[k];
        /* From the nearest bark this lobe has so far (or its seed). A start
         * that would leave it the way an earlier one did is dropped
         * (start_crowding): its cell stays tried. */
        int32_t from = seed;
        double from_d = INFINITY;
        for (size_t i = lobe_node0; i <= sk->n; i++) {
            int32_t v = i == sk->n ? seed : (int32_t)i;
            const float *q = sk->pos + 3 * v;
            double dd = (q[0] - near[0]) * (q[0] - near[0]) + (q[1] - near[1]) * (q[1] - near[1]) +
                        (q[2] - near[2]) * (q[2] - near[2]);
            if (dd < from_d && sk->radius[v] >= 0.3 * min_start) from_d = dd, from = v;
        }
        const float sp[3] = {sk->pos[3 * from], sk->pos[3 * from + 1], sk->pos[3 * from + 2]};
        /* The way it leaves: its carrier's, else its first patch's. */
        int carrier = from_d > 2.25 * g.h * g.h;
        start_leaving x = {{sp[0], sp[1], sp[2]}, {0, 0, 0}, start_thickness(sk->radius[from], max_thick)};
        const double sp_d[3] = {sp[0], sp[1], sp[2]};
        if (carrier) sy_v3_sub(x.dir, near, sp_d), sy_v3_normalize(x.dir);
        else start_direction(sp_d, target, near, sp, x.dir);
        if (start_crowding(started, n_started, &x)) {
            /* Skipped, not failed: a bound on the work only. */
            if (++crowded >= 4 * max_starts) break;
            continue;
        }
        dock d0;
        d0.thickness = x.thickness;
        d0.node = from;
        d0.depth = 0;
        for (int k = 0; k < 3; k++) d0.pos[k] = sp[k];
        near_d = sqrt(from_d);
        if (carrier) {
            int steps = (int)ceil(near_d / g.h);
            if (steps > 64) steps = 64;
            int32_t parent = from, branch = so->next_branch++;
            int order = sk->order[from] < 254 ? sk->order[from] + 1 : 255;
            for (int k = 1; k <= steps && !rc; k++) {
                float p[3];
                for (int q = 0; q < 3; q++) p[q] = (float)(sp[q] + (near[q] - sp[q]) * k / steps);
                double r = d0.thickness * (1 - 0.2 * k / steps), pr = so->out->radius[parent];
                if (r > pr) r = pr;
                parent = sy_skeleton_add(so->out, p, (float)r, parent, order, branch, err);
                if (parent < 0) rc = SY_EINTERNAL;
                rep->nodes_added++;
            }
            if (rc) break;
            d0.node = parent;
            d0.thickness = 0.95 * sk->radius[parent];
            for (int k = 0; k < 3; k++) d0.pos[k] = near[k];
        }
        if (carrier) start_direction(d0.pos, target, near, sp, d0.dir);
        else memcpy(d0.dir, x.dir, sizeof d0.dir);
        /* Its carrier (if any) leaves `from`, its first patch the dock; a
         * first patch that does not fit leaves no trace (its carrier
         * stays, as its bark does). */
        int started0 = n_started;
        if (carrier) started[n_started++] = x;
        started[n_started++] = (start_leaving){{(float)d0.pos[0], (float)d0.pos[1], (float)d0.pos[2]},
                                               {d0.dir[0], d0.dir[1], d0.dir[2]}, d0.thickness};
        starts++;
        Q.head = Q.n = 0;
        if (!queue_push(&Q, &d0)) {
            rc = sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
            break;
        }
        size_t before = rep->patches;
        while (!rc && Q.head < Q.n && lobe_patches < (size_t)o->max_patches) {
            dock d = Q.q[Q.head++];
            long cell = grid_cell(&g, d.pos);
            if (d.depth >= max_depth) {
                rep->docks_depth++;
                continue;
            }
            if (d.depth > 0 && (cell < 0 || !g.cell[cell].soft)) {
                rep->docks_outside++;
                continue;
            }
            /* Candidates by eq. 3.3, the best half among patches that dock
             * further ones and the best half among terminal ones, so a dock
             * in open space can continue the structure and one in a full
             * region can end it. */
            size_t half = (size_t)(o->candidates + 1) / 2;
            size_t nc = rank_candidates(lib, &d, o, 0, half, cands);
            nc += rank_candidates(lib, &d, o, 1, half, cands + nc);
            double phi0 = 2 * M_PI * sy_synth_uniform(&rng);
            double Rz[9], Rr[SY_SYNTH_MAX_ROLLS][9];
            placement_turn(&d, Rz);
            for (int r = 0; r < o->rolls; r++) mat_axis(d.dir, phi0 + 2 * M_PI * r / o->rolls, Rr[r]);
            double best = INFINITY, bestR[9] = {0}, best_s = 1, ext = lobe_ext > 0 ? lobe_ext : 1;
            int full = 0; /* a candidate fitted the hull but every leaf fell in full or empty cells */
            size_t best_i = 0;
            /* The farthest any candidate's leaves can reach from the dock
             * (geom_scale grows with the ratio: one pow for all of them). */
            double thinnest = INFINITY, widest = 0;
            for (size_t ci = 0; ci < nc; ci++) {
                const sy_patch *p = &lib->patches[cands[ci].idx];
                if (p->thickness < thinnest) thinnest = p->thickness;
                if (p->extent > widest) widest = p->extent;
            }
            if (nc && !room_near(&g, d.pos, geom_scale(d.thickness / thinnest) * widest + g.h)) nc = 0, full = 1;
            for (size_t ci = 0; ci < nc; ci++) {
                const sy_patch *p = &lib->patches[cands[ci].idx];
                double s = geom_scale(d.thickness / p->thickness), T[9];
                if (!room_near(&g, d.pos, s * p->extent)) {
                    full = 1;
                    continue;
                }
                placement_align(p, &d, Rz, T);
                for (int r = 0; r < o->rolls; r++) {
                    double R[9];
                    mat_mul(Rr[r], T, R);
                    fit_geo f;
                    if (d.pos[2] + s * p->extent > ceiling && rises_above(p, &d, R, s, ceiling)) continue;
                    /* A start leaves from a seed that may lie outside the hull, so
                     * more of it may lie out (start_outside_max). */
                    int fit = patch_fit(p, &d, R, s, &g, NULL, d.depth > 0 ? o->outside_max : o->start_outside_max, cands[ci].key,
                                        ext, best, &f);
                    if (fit == 0) continue;
                    if (fit == 2 || f.gain < 0.15) { /* the lobe is full where it would go */
                        full = 1;
                        continue;
                    }
                    double score = 0.25 * cands[ci].key + f.outside + 2 * f.dist / ext - f.gain;
                    if (score < best) best = score, best_i = cands[ci].idx, best_s = s, memcpy(bestR, R, sizeof R);
                }
            }
            if (!isfinite(best)) {
                if (full) rep->docks_full++;
                else rep->docks_rejected++;
                continue;
            }
            rc = place(&lib->patches[best_i], &d, bestR, best_s, o->leaf_size, 0, &g, so, &Q, rep, err);
            if (!rc && d.depth > 0) rep->docks_filled++;
            lobe_patches++;
        }
        if (rep->patches == before) n_started = started0 + carrier;
        if (rep->patches == before && ++failed >= 48) break; /* nothing fits any more */
    }
    if (!rc && bare_reason < 0 && rep->patches == placed0 && o->fronds) bare_reason = 1; /* no frond reached it */
    if (!rc && bare_reason < 0 && rep->patches == placed0 && !scaffolded) {
        /* No patch fits and no hidden limb grew: the lobe is smaller than
         * the species' branchlets (a twig's end on a leaf-off scan: rTwig's
         * sapling has 55 such lobes). Its twigs grow toward its returns at
         * the grid's own scale instead (a kill distance of two cells),
         * without leaves. A second colony beside a first would fork the
         * seed's limb (seed_limbs_build). */
        size_t nodes0 = rep->nodes_added;
        rc = grow_scaffold(&g, occ_c, n_occ, seed, 0, max_thick, o, limb, ceiling, ground, so, rep, err);
        bare_reason = rep->nodes_added > nodes0 ? 2 : 1;
    }
    if (!rc && bare_reason >= 0) {
        if (rep->lobes_bare < 8) {
            rep->bare_lobe[rep->lobes_bare] = lobe_index;
            rep->bare_reason[rep->lobes_bare] = bare_reason;
        }
        rep->lobes_bare++;
    }
    if (getenv("SYLVA_SYNTH_DEBUG"))
        fprintf(stderr, "lobe %d seed %d: cap %.3f grid %dx%dx%d h %.3f occupied %zu filled %zu patches %zu starts %d | out %zu rej %zu full %zu depth %zu\n",
                (int)lobe_index, (int)c->seed, g.capacity, g.d[0], g.d[1], g.d[2], g.h, g.n_occupied, g.n_filled,
                rep->patches - placed0, starts, rep->docks_outside, rep->docks_rejected, rep->docks_full, rep->docks_depth);
    /* Summed over lobes; the caller divides by all occupied cells. */
    if (!rc) rep->coverage += (double)g.n_filled;
    if (!rc) cells[0] += g.n_inside, cells[1] += g.n_occupied;
    *occupied += g.n_blocks;
    free(tried), free(occ), free(occ_c);
    free(Q.q);
    grid_free(&g);
    return rc;
}

static sy_code copy_skeleton(const sy_skeleton *s, sy_skeleton *out, sy_error *err)
{
    sy_code rc = sy_skeleton_init(out, 0, err);
    if (rc) return rc;
    memcpy(out->origin, s->origin, sizeof out->origin);
    out->lobes = s->lobes, out->lobe_depth = s->lobe_depth;
    for (size_t i = 0; i < s->n; i++)
        if (sy_skeleton_add(out, s->pos + 3 * i, s->radius[i], s->parent[i], s->order[i], s->branch[i], err) < 0)
            return SY_EINTERNAL;
    return SY_OK;
}

/* Each lobe's seed limb for the scaffold: the length and base radius of
 * its seed's branch, the branch's direction at the seed, whether it is the
 * trunk, and whether the lobe continues it: only where the branch ends at
 * the seed, and only the first lobe on that seed (two would each continue
 * it, forking the limb in two). height: the scan's; the trunk's seen length
 * understates the limb its laterals hang from where its top is hidden, so
 * it counts as the scan's height. */
static sy_code seed_limbs_build(const sy_skeleton *skel, const sy_clusters *lobes, double height, seed_limb *out,
                                sy_error *err)
{
    size_t n_lobes = lobes ? lobes->n : 0;
    int32_t nb = sy_skeleton_branch_count(skel);
    double *len = calloc((size_t)nb + 1, sizeof *len), *base = calloc((size_t)nb + 1, sizeof *base);
    int32_t *taker = malloc((skel->n + 1) * sizeof *taker); /* per node: the lobe continuing its limb, or -1 */
    if (!len || !base || !taker) {
        free(len), free(base), free(taker);
        return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    }
    for (size_t i = 0; i < skel->n; i++) taker[i] = -2; /* -2: a limb ends here, no lobe yet */
    for (size_t i = 0; i < skel->n; i++) {
        int32_t p = skel->parent[i], b = skel->branch[i];
        if (p >= 0 && skel->branch[p] == b) taker[p] = -1; /* the limb goes on past p */
        if (b < 0) continue;
        if (p < 0 || skel->branch[p] != b) base[b] = skel->radius[i];
    }
    /* Traced twigs at or beyond each node: each lobe's count at its seed,
     * summed children before parents (the skeleton's breadth-first order
     * read backwards; parent[i] < i is not given). */
    double *beyond = calloc(skel->n + 1, sizeof *beyond), *arc = calloc(skel->n + 1, sizeof *arc);
    int32_t *first = malloc((skel->n + 1) * sizeof *first), *sib = malloc((skel->n + 1) * sizeof *sib),
            *bfs = malloc((skel->n + 1) * sizeof *bfs);
    if (!beyond || !arc || !first || !sib || !bfs) {
        free(len), free(base), free(taker), free(beyond), free(arc), free(first), free(sib), free(bfs);
        return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    }
    sy_skeleton_children(skel, first, sib);
    size_t reached = sy_skeleton_breadth_first(skel, first, sib, bfs);
    /* Each node's distance along its branch from where the branch leaves its
     * parent (a lobe's seed's offset on its limb, for its laterals' lengths);
     * the farthest is the branch's length. */
    for (size_t k = 0; k < reached; k++) {
        int32_t v = bfs[k], p = skel->parent[v], b = skel->branch[v];
        arc[v] = (p >= 0 && skel->branch[p] == b ? arc[p] : 0) + (p >= 0 ? sy_skeleton_edge_length(skel, (size_t)v) : 0);
        if (b >= 0) len[b] = fmax(len[b], arc[v]);
    }
    for (size_t c = 0; c < n_lobes; c++) beyond[lobes->items[c].seed] += (double)lobes->items[c].n_twigs;
    for (size_t k = reached; k-- > 0;) {
        int32_t v = bfs[k], p = skel->parent[v];
        if (p >= 0) beyond[p] += beyond[v];
    }
    free(first), free(sib), free(bfs);
    for (size_t c = 0; c < n_lobes; c++) {
        int32_t seed = lobes->items[c].seed, b = skel->branch[seed], p = skel->parent[seed];
        seed_limb *l = &out[c];
        memset(l, 0, sizeof *l);
        l->length = len[b], l->base_radius = base[b], l->on_trunk = skel->order[seed] == 0;
        l->offset = arc[seed];
        if (l->on_trunk) l->length = fmax(l->length, height);
        l->twig_share = beyond[seed] > 0 ? (double)lobes->items[c].n_twigs / beyond[seed] : 0;
        if (taker[seed] == -2) taker[seed] = (int32_t)c;
        l->ends = taker[seed] == (int32_t)c;
        if (p >= 0) {
            for (int k = 0; k < 3; k++) l->dir[k] = (double)skel->pos[3 * seed + k] - skel->pos[3 * p + k];
            sy_v3_normalize(l->dir);
        }
    }
    free(len), free(base), free(taker), free(beyond), free(arc);
    return SY_OK;
}

/* One lobe textured on its own: its seed node alone (index 0) plus the
 * nodes and leaves it adds, branch ids counted from the skeleton's. Lobes
 * only read their seed and their own bark, so they run in parallel and are
 * merged in order: the bytes do not depend on the thread count. */
typedef struct {
    sy_skeleton out;
    sy_leaves leaves;
    float *leaf_key;
    int32_t next_branch;
    sy_synth_report rep;
    size_t occupied, cells[2];
    int skipped; /* a degenerate hull: bare, not textured */
    size_t prune_from; /* its patches' and carriers' nodes, where it holds leaves (else 0: none pruned) */
    sy_code rc;
    sy_error err;
} lobe_work;

typedef struct {
    const sy_skeleton *skel;
    const sy_clusters *lobes;
    const sy_branchlets *lib;
    const sy_synth_options *o;
    double max_thick;
    double ceiling; /* no synthesised bark rises above this height */
    double ground;  /* the skeleton's lowest node: the root on the ground */
    int32_t base_branches;
    lobe_work *work;
    const crown_grid *crown;
    const seed_limb *limbs;   /* per lobe: the limb its seed lies on */
    const int32_t *shaft;     /* a crown of fronds: the stem's top nodes every lobe hangs off, lowest first,
                                 the apex last (else NULL: each lobe its seed) */
    int n_shaft;
    const frond_aim *aims;    /* a crown of fronds: where each frond reaches, and in which lobe */
    size_t n_aims;
    const int *between;       /* a crown of fronds: per lobe, the fronds that fill it after the aimed ones */
} lobe_ctx;

static void lobe_work_free(lobe_work *w)
{
    sy_skeleton_free(&w->out);
    sy_leaves_free(&w->leaves);
    free(w->leaf_key);
}

static void texture_lobes(void *vctx, size_t begin, size_t end, size_t chunk)
{
    (void)chunk;
    const lobe_ctx *x = vctx;
    double density = x->o->leaf_density > 0 ? x->o->leaf_density : 1.5;
    int max_depth = x->o->max_depth > 0 ? x->o->max_depth : 7;
    for (size_t c = begin; c < end; c++) {
        lobe_work *w = &x->work[c];
        const sy_cluster *C = &x->lobes->items[c];
        if (C->n_tris < 4 || C->n_verts < 4) {
            w->skipped = 1;
            continue;
        }
        const sy_skeleton *k = x->skel;
        /* Its base: the seed, or a crown of fronds' shaft (local nodes 0..n-1). */
        const int32_t *base = x->shaft ? x->shaft : &C->seed;
        int n_base = x->shaft ? x->n_shaft : 1;
        ranked *cands = malloc((x->lib->n_patches + 1) * sizeof *cands);
        w->rc = cands ? sy_skeleton_init(&w->out, 0, &w->err) : sy_fail(&w->err, SY_EINTERNAL, "synthesize: out of memory");
        if (!w->rc) memcpy(w->out.origin, k->origin, sizeof w->out.origin);
        for (int b = 0; b < n_base && !w->rc; b++)
            if (sy_skeleton_add(&w->out, k->pos + 3 * base[b], k->radius[base[b]], b - 1, k->order[base[b]],
                                k->branch[base[b]], &w->err) < 0)
                w->rc = SY_EINTERNAL;
        if (!w->rc) {
            sy_cluster local = *C;
            local.seed = n_base - 1;
            synth_out so = {&w->out, &w->leaves, NULL, 0, x->base_branches, x->crown, 0};
            w->rc = texture_lobe(&local, (int32_t)c, x->lib, x->o, &x->limbs[c], x->aims, x->n_aims,
                                 x->between ? x->between[c] : 0, density, max_depth,
                                 x->max_thick, x->ceiling, x->ground, cands,
                                 &so, &w->rep, &w->occupied, w->cells, &w->err);
            w->leaf_key = so.leaf_key;
            w->next_branch = so.next_branch;
            w->prune_from = w->leaves.n > 0 && !x->o->bare ? so.patches_from : 0; /* a leaf-off tree's leaves are not drawn */
        }
        free(cands);
    }
}

/* Appends lobe w to so: its nodes 0..n_base-1 are the skeleton's nodes
 * base (its seed, or a crown of fronds' shaft), its other nodes follow
 * so's, and its own branch ids follow so's count. Where the
 * lobe holds leaves, the bark of its patches and their carriers that
 * carries no leaf anywhere beyond it is dropped: a patch keeps its wood
 * where its leaves fell in full blocks or outside the hull (stochastic
 * pruning), and those bare ends stood out of the crown as sticks (the
 * simulated palm's frond rachises, up to a metre past its foliage). The
 * scaffold (the limbs the scan hides) and traced twigs (returns) stay, and
 * a leaf-off lobe keeps all its wood. */
static sy_code merge_lobe(const lobe_work *w, const int32_t *base, int n_base, int32_t base_branches, synth_out *so,
                          size_t *pruned, sy_error *err)
{
    const sy_skeleton *l = &w->out;
    size_t n_own = (size_t)(w->next_branch - base_branches);
    /* new_id[i]: node i's index in so (-1: dropped); holds[i]: a leaf hangs
     * on node i or beyond it. A node's children follow it, so one pass from
     * the last node marks what the leaves hold up. */
    int32_t *new_id = malloc((l->n + 1) * sizeof *new_id), *new_branch = malloc((n_own + 1) * sizeof *new_branch);
    uint8_t *holds = calloc(l->n + 1, 1);
    if (!new_id || !new_branch || !holds) {
        free(new_id), free(new_branch), free(holds);
        return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    }
    size_t from = w->prune_from ? w->prune_from : l->n;
    for (size_t i = 0; i < w->leaves.n; i++) holds[w->leaves.node[i]] = 1;
    for (size_t i = l->n; i-- > 1;)
        if ((holds[i] || i < from) && l->parent[i] >= 0) holds[l->parent[i]] = 1;
    /* The lobe's own branch ids, renumbered on from so's in the order their
     * first kept node comes: a branch pruned whole leaves no gap. */
    for (size_t b = 0; b < n_own; b++) new_branch[b] = -1;
    for (int b = 0; b < n_base; b++) new_id[b] = base[b];
    sy_code rc = SY_OK;
    for (size_t i = (size_t)n_base; i < l->n && !rc; i++) {
        int32_t b = l->branch[i];
        new_id[i] = -1;
        if (i >= from && !holds[i]) {
            (*pruned)++;
            continue;
        }
        if (b >= base_branches) {
            if (new_branch[b - base_branches] < 0) new_branch[b - base_branches] = so->next_branch++;
            b = new_branch[b - base_branches];
        }
        /* A lobe's nodes are appended to what they hang from: a kept node's
         * parent is kept and already placed. */
        if (l->parent[i] < 0 || new_id[l->parent[i]] < 0) {
            rc = sy_fail(err, SY_EINTERNAL, "synthesize: lobe node %zu before its parent", i);
            break;
        }
        new_id[i] = sy_skeleton_add(so->out, l->pos + 3 * i, l->radius[i], new_id[l->parent[i]], l->order[i], b, err);
        if (new_id[i] < 0) rc = SY_EINTERNAL;
    }
    if (!rc && !keys_reserve(so, so->leaves->n + w->leaves.n)) rc = sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    for (size_t i = 0; !rc && i < w->leaves.n; i++) {
        so->leaf_key[so->leaves->n] = w->leaf_key[i];
        if (sy_leaves_add(so->leaves, w->leaves.pos + 3 * i, w->leaves.rot + 4 * i, w->leaves.scale[i],
                          new_id[w->leaves.node[i]], err))
            rc = SY_EINTERNAL;
    }
    free(new_id), free(new_branch), free(holds);
    return rc;
}

/* Where a palm's fronds leave its stem: the trunk's highest node (the apex)
 * and the trunk nodes below it within FROND_SHAFT metres, at most
 * FROND_SHAFT_NODES, lowest first. The simulated palm's 24 fronds leave
 * its top 0.48 m. Crowded on fewer nodes, their junctions do not weld: all
 * on the apex alone, 49 % of the bundled palm's LOD0 junctions welded;
 * within half a metre, 75 % of the airborne palm sample's (within a metre,
 * 90 %). Returns how many. */
#define FROND_SHAFT 1.0
#define FROND_SHAFT_NODES 12
static int stem_shaft(const sy_skeleton *skel, int32_t shaft[FROND_SHAFT_NODES])
{
    int32_t apex = 0;
    for (size_t i = 0; i < skel->n; i++)
        if (skel->order[i] == 0 && skel->pos[3 * i + 2] > skel->pos[3 * apex + 2]) apex = (int32_t)i;
    int32_t chain[FROND_SHAFT_NODES];
    int n = 0;
    for (int32_t v = apex; v >= 0 && n < FROND_SHAFT_NODES && skel->order[v] == 0; v = skel->parent[v]) {
        double dz = skel->pos[3 * apex + 2] - skel->pos[3 * v + 2];
        if (n > 0 && dz > FROND_SHAFT) break;
        chain[n++] = v;
    }
    for (int k = 0; k < n; k++) shaft[k] = chain[n - 1 - k];
    return n;
}

/* Where a crown of o->fronds fronds reach: the crown's hull vertices
 * farthest from the apex, taken greedily farthest first, each at least
 * FROND_APART from those taken as seen from the apex, up to o->fronds. A
 * frond sticks out of the crown as a spike of its hull, so they are the tips
 * the scan saw, high or drooping; evenly turned fronds (the golden angle
 * from a seeded start) missed them (top view IoU of the simulated palm
 * 0.750). *aims (malloc'd) gets them farthest first. */
#define FROND_APART (15 * M_PI / 180)
typedef struct {
    double d2;
    int32_t lobe;
    size_t vert;
} hull_vertex_at;

static int cmp_farthest(const void *a, const void *b)
{
    const hull_vertex_at *x = a, *y = b;
    if (x->d2 != y->d2) return x->d2 > y->d2 ? -1 : 1;
    if (x->lobe != y->lobe) return x->lobe < y->lobe ? -1 : 1;
    return x->vert < y->vert ? -1 : x->vert > y->vert;
}

/* The volume lobe c's returns occupy: its occupied cells (sy_cluster's
 * occupancy bits) times a cell's volume, else its hull's box. */
static double occupied_volume(const sy_cluster *c)
{
    float lo[3], hi[3];
    hull_box(c, lo, hi);
    double box = (double)(hi[0] - lo[0]) * (hi[1] - lo[1]) * (hi[2] - lo[2]);
    size_t cells = (size_t)c->occ_dims[0] * c->occ_dims[1] * c->occ_dims[2], set = 0;
    if (!c->occupancy || !cells) return box;
    for (size_t i = 0; i < cells; i++) set += (c->occupancy[i >> 3] >> (i & 7)) & 1;
    return box * (double)set / (double)cells;
}

/* How many fronds fill each lobe after the aimed ones (lay_fronds): twice
 * as many as were aimed, shared among the lobes by the volume their
 * returns occupy. Per lobe by its own aims, a lobe that drew none stayed
 * bare. between: one per lobe. */
static void fronds_between(const sy_clusters *lobes, size_t n_aims, int *between)
{
    double total = 0;
    for (size_t c = 0; c < lobes->n; c++) total += occupied_volume(&lobes->items[c]);
    for (size_t c = 0; c < lobes->n; c++)
        between[c] = total > 0 ? (int)lround(2.0 * (double)n_aims * occupied_volume(&lobes->items[c]) / total) : 0;
}

static sy_code fronds_aim(const sy_skeleton *skel, int32_t apex, const sy_clusters *lobes, const sy_synth_options *o,
                          frond_aim **aims, size_t *n_aims, sy_error *err)
{
    *aims = NULL, *n_aims = 0;
    size_t n_verts = 0;
    for (size_t c = 0; lobes && c < lobes->n; c++) n_verts += lobes->items[c].n_verts;
    if (!n_verts || o->fronds <= 0) return SY_OK;
    frond_aim *a = malloc((size_t)o->fronds * sizeof *a);
    hull_vertex_at *v = malloc(n_verts * sizeof *v);
    double *dir = malloc(3 * (size_t)o->fronds * sizeof *dir);
    if (!a || !v || !dir) {
        free(a), free(v), free(dir);
        return sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    }
    const float *ap = skel->pos + 3 * apex;
    size_t m = 0;
    for (size_t c = 0; c < lobes->n; c++)
        for (size_t i = 0; i < lobes->items[c].n_verts; i++) {
            const float *q = lobes->items[c].verts + 3 * i;
            double dx = q[0] - ap[0], dy = q[1] - ap[1], dz = q[2] - ap[2];
            v[m++] = (hull_vertex_at){dx * dx + dy * dy + dz * dz, (int32_t)c, i};
        }
    qsort(v, m, sizeof *v, cmp_farthest);
    double apart = cos(FROND_APART);
    size_t n = 0;
    for (size_t i = 0; i < m && n < (size_t)o->fronds && v[i].d2 > 0; i++) {
        const float *q = lobes->items[v[i].lobe].verts + 3 * v[i].vert;
        double r = sqrt(v[i].d2), u[3] = {(q[0] - ap[0]) / r, (q[1] - ap[1]) / r, (q[2] - ap[2]) / r};
        size_t j = 0;
        while (j < n && u[0] * dir[3 * j] + u[1] * dir[3 * j + 1] + u[2] * dir[3 * j + 2] < apart) j++;
        if (j < n) continue;
        memcpy(dir + 3 * n, u, sizeof u);
        a[n] = (frond_aim){{q[0], q[1], q[2]}, v[i].lobe};
        n++;
    }
    free(v), free(dir);
    *aims = a, *n_aims = n;
    return SY_OK;
}

sy_code sy_synthesize(const sy_skeleton *skel, const sy_clusters *lobes, const sy_branchlets *lib,
                      const sy_synth_options *o, sy_skeleton *out, sy_leaves *leaves, sy_synth_report *rep_out,
                      sy_error *err)
{
    double t0 = sy_now();
    sy_synth_report rep;
    memset(&rep, 0, sizeof rep);
    rep.leaf_size = o->leaf_size;
    memset(leaves, 0, sizeof *leaves);
    memset(out, 0, sizeof *out);
    sy_code rc = sy_synth_options_check(o, err);
    if (rc) return rc;
    if (!lib || lib->n_patches == 0) return sy_fail(err, SY_EINPUT, "synthesize: the branchlet library is empty");
    if ((rc = sy_skeleton_validate(skel, err))) return rc;
    for (size_t c = 0; lobes && c < lobes->n; c++) {
        const sy_cluster *C = &lobes->items[c];
        if (C->seed < 0 || (size_t)C->seed >= skel->n)
            return sy_fail(err, SY_EINPUT, "synthesize: lobe %zu hangs off node %d, which the skeleton lacks", c,
                           (int)C->seed);
        if (C->n_twigs && (!C->twig_pos || !C->twig_parent))
            return sy_fail(err, SY_EINPUT, "synthesize: lobe %zu has %zu twigs and no arrays", c, C->n_twigs);
        for (size_t i = 0; i < C->n_twigs; i++)
            if (C->twig_parent[i] < -1 || C->twig_parent[i] >= (int32_t)i || !isfinite(C->twig_pos[3 * i]) ||
                !isfinite(C->twig_pos[3 * i + 1]) || !isfinite(C->twig_pos[3 * i + 2]))
                return sy_fail(err, SY_EINPUT, "synthesize: lobe %zu twig %zu has a bad parent or position", c, i);
    }
    if ((rc = copy_skeleton(skel, out, err))) {
        sy_skeleton_free(out);
        return rc;
    }
    double max_thick = 0;
    for (size_t i = 0; i < lib->n_patches; i++)
        if (lib->patches[i].thickness > max_thick) max_thick = lib->patches[i].thickness;
    synth_out so = {out, leaves, NULL, 0, sy_skeleton_branch_count(skel), NULL, 0};
    size_t occupied = 0, cells[2] = {0, 0};
    size_t n_lobes = lobes ? lobes->n : 0;
    lobe_work *work = n_lobes ? calloc(n_lobes, sizeof *work) : NULL;
    if (n_lobes && !work) rc = sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    const int32_t ctx_branches = so.next_branch;
    int32_t shaft[FROND_SHAFT_NODES];
    int n_shaft = o->fronds ? stem_shaft(skel, shaft) : 0;
    frond_aim *aims = NULL;
    size_t n_aims = 0;
    int *between = NULL;
    if (!rc && n_shaft) rc = fronds_aim(skel, shaft[n_shaft - 1], lobes, o, &aims, &n_aims, err);
    if (!rc && n_shaft && n_lobes) {
        between = malloc(n_lobes * sizeof *between);
        if (between) fronds_between(lobes, n_aims, between);
        else rc = sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
    }
    if (!rc) {
        /* The scan's top: the highest skeleton node or lobe hull vertex (the
         * hulls enclose the returns). A willow's branchlets docked near the
         * crown top reached 0.26 m above AdTree's tree7 (height +5.2 %). */
        double ceiling = -INFINITY, ground = INFINITY;
        for (size_t i = 0; i < skel->n; i++) ceiling = fmax(ceiling, skel->pos[3 * i + 2]), ground = fmin(ground, skel->pos[3 * i + 2]);
        for (size_t c = 0; c < n_lobes; c++)
            for (size_t v = 0; v < lobes->items[c].n_verts; v++) ceiling = fmax(ceiling, lobes->items[c].verts[3 * v + 2]);
        crown_grid crown;
        rc = crown_build(lobes, &crown, err);
        seed_limb *limbs = n_lobes ? calloc(n_lobes, sizeof *limbs) : NULL;
        if (!rc && n_lobes && !limbs) rc = sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
        if (!rc) rc = seed_limbs_build(skel, lobes, ceiling - ground, limbs, err);
        if (!rc) {
            lobe_ctx ctx = {skel, lobes, lib, o, max_thick, ceiling, ground, ctx_branches, work, &crown, limbs,
                            n_shaft ? shaft : NULL, n_shaft, aims, n_aims, between};
            sy_parallel_for(n_lobes, 1, texture_lobes, &ctx);
        }
        free(crown.inside), free(limbs);
    }
    /* The lobes in order, as if textured one after another into out. */
    for (size_t c = 0; !rc && c < n_lobes; c++) {
        lobe_work *w = &work[c];
        if (w->skipped) {
            if (rep.lobes_bare < 8) rep.bare_lobe[rep.lobes_bare] = (int32_t)c, rep.bare_reason[rep.lobes_bare] = 0;
            rep.lobes_bare++;
            continue;
        }
        if (w->rc) {
            rc = w->rc;
            *err = w->err;
            break;
        }
        rc = merge_lobe(w, n_shaft ? shaft : &lobes->items[c].seed, n_shaft ? n_shaft : 1, ctx_branches, &so,
                        &rep.nodes_pruned, err);
        const sy_synth_report *r = &w->rep;
        if (r->lobes_bare) {
            if (rep.lobes_bare < 8) rep.bare_lobe[rep.lobes_bare] = r->bare_lobe[0], rep.bare_reason[rep.lobes_bare] = r->bare_reason[0];
            rep.lobes_bare++;
        }
        rep.patches += r->patches, rep.docks_filled += r->docks_filled, rep.docks_outside += r->docks_outside;
        rep.docks_depth += r->docks_depth, rep.docks_full += r->docks_full, rep.docks_rejected += r->docks_rejected;
        rep.nodes_added += r->nodes_added, rep.leaves_in_hull += r->leaves_in_hull, rep.coverage += r->coverage;
        rep.scaffold_nodes += r->scaffold_nodes;
        occupied += w->occupied, cells[0] += w->cells[0], cells[1] += w->cells[1];
    }
    for (size_t c = 0; c < n_lobes; c++) lobe_work_free(&work[c]);
    free(work), free(aims), free(between);
    rep.lobes = lobes ? lobes->n : 0;
    rep.coverage = occupied ? rep.coverage / (double)occupied : 0;
    /* How much of the hulls the scan's points fill: thin bare limbs leave
     * most of a hull empty, a foliated crown fills it (a diagnostic; on the
     * AdTree scans it does not separate leaf-off from leaf-on, 0.35-0.57). */
    rep.fill = cells[0] ? (double)cells[1] / (double)cells[0] : 1;
    rep.leaves = leaves->n;
    /* Stochastic-pruning order: every prefix holds the same leading share of each patch's stored order. */
    if (!rc && leaves->n > 1) {
        ranked *rk = malloc(leaves->n * sizeof *rk);
        sy_leaves sorted = {0};
        if (!rk) rc = sy_fail(err, SY_EINTERNAL, "synthesize: out of memory");
        for (size_t i = 0; !rc && i < leaves->n; i++) rk[i].key = so.leaf_key[i], rk[i].idx = i; /* float to double: exact */
        if (!rc) qsort(rk, leaves->n, sizeof *rk, cmp_ranked);
        for (size_t i = 0; !rc && i < leaves->n; i++) {
            size_t j = rk[i].idx;
            rc = sy_leaves_add(&sorted, leaves->pos + 3 * j, leaves->rot + 4 * j, leaves->scale[j], leaves->node[j], err);
        }
        free(rk);
        if (!rc) {
            sy_leaves_free(leaves);
            *leaves = sorted;
        } else {
            sy_leaves_free(&sorted);
        }
    }
    free(so.leaf_key);
    if (!rc) rc = sy_skeleton_validate(out, err);
    if (rc) {
        sy_skeleton_free(out);
        sy_leaves_free(leaves);
        return rc;
    }
    rep.seconds = sy_now() - t0;
    if (rep_out) *rep_out = rep;
    return SY_OK;
}
