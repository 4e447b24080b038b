/* Internals of the mesh stage shared by its source files and its tests.
 * Everything here works in Sylva's Z-up frame; conversion to glTF's Y-up
 * happens only when vertices are written (sy_to_yup). */
#ifndef SYLVA_MESH_INTERNAL_H
#define SYLVA_MESH_INTERNAL_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- small vector helpers ---- */
static inline float sy_dot3(const float a[3], const float b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static inline void sy_cross3(const float a[3], const float b[3], float out[3])
{
    float x = a[1] * b[2] - a[2] * b[1], y = a[2] * b[0] - a[0] * b[2], z = a[0] * b[1] - a[1] * b[0];
    out[0] = x;
    out[1] = y;
    out[2] = z;
}
/* Normalises v in place; returns its previous length (0 leaves v as is).
 * Inline: the mesher calls it for every ring and frame (5 % of a decode
 * as a call into frames.c). */
static inline float sy_normalize3(float v[3])
{
    float len = sqrtf(sy_dot3(v, v));
    if (len > 0) {
        v[0] /= len;
        v[1] /= len;
        v[2] /= len;
    }
    return len;
}
/* Z-up (x, y, z) -> Y-up (x, z, -y): a rotation of -90 degrees about X. */
static inline void sy_to_yup(const float v[3], float out[3])
{
    float x = v[0], y = v[1], z = v[2];
    out[0] = x;
    out[1] = z;
    out[2] = -y;
}

/* ---- curves and frames (frames.c) ---- */
/* Cubic Hermite in the natural order (p0, m0, p1, m1): position and first
 * derivative at t in [0,1]. */
void sy_hermite(const float p0[3], const float m0[3], const float p1[3], const float m1[3], float t, float pos[3],
                float der[3]);
/* Rotation-minimising frames by double reflection (Wang et al. 2008): given
 * n points x (3n) with unit tangents t (3n) and a unit r0 orthogonal to t[0],
 * writes the reference vectors r (3n), each unit and orthogonal to its tangent. */
void sy_rmf(size_t n, const float *x, const float *t, const float r0[3], float *r);

/* ---- stems: one generalised cylinder per skeleton branch (stems.c) ---- */
typedef struct {
    int32_t branch_id;
    int32_t parent;      /* stem index whose surface the base leaves, -1 for the root stem */
    int depth;           /* number of ancestor stems in the skeleton's hierarchy */
    int32_t attach_node; /* skeleton node the base attaches to, -1 for the root stem */
    float attach_s;      /* arc length on the parent curve at attach_node */
    /* A child whose base its parent buried in the grandparent leaves the
     * grandparent (parent, attach_s: reattach_buried in stems.c) but keeps
     * its place in the hierarchy for wind: its own parent and the arc
     * length on it. sy_stem_tree_parent / sy_stem_tree_attach_s read them. */
    int reattached;
    int32_t tree_parent;
    float tree_attach_s;
    int32_t *nodes;      /* chain of skeleton nodes, base to tip */
    size_t n_nodes;
    /* Polyline the curve interpolates: attachment node + chain, coincident
     * points removed. */
    size_t n_pts;
    float *pts, *rad, *pt_s; /* 3n, n, n (arc length at each point) */
    /* Rings at LOD0, base to tip, after the junction trim: centre, unit
     * tangent, frame normal N (B = T x N), radius, arc length, dr/ds. */
    size_t n_samp;
    float *sp, *st, *sn, *sr, *ss, *sdr;
    float length;        /* arc length of the whole curve (attachment to tip) */
    float r_base, r_tip; /* radii at the first and last polyline point */
    int radial;          /* ring vertices at LOD0 (without the seam duplicate) */
    int has_geometry;    /* 0: fewer than two distinct points, or buried in its parent */
    int junction;        /* base ring is projected onto the parent's surface */
    int has_children;    /* some stem attaches to it: keeps at least 6 ring vertices */
    int lean;            /* 1: drawn lean (sy_stem_lean), 2: and with three sides */
    /* Where the base ring lands on the parent (fit_on_parent in stems.c):
     * arc lengths fp_lo..fp_hi, azimuth fp_az +- fp_hw about the parent's
     * frame normal. */
    float fp_lo, fp_hi, fp_az, fp_hw;
    /* Weber-Penn lobes of an order-0 stem of a grown tree (sy_skeleton.lobes),
     * 0 / 0 otherwise: rings have radius R (1 + lobe_depth sin(lobes theta)). */
    int lobes;
    float lobe_depth;
    /* Wind: the asset.wind entry the vertices follow (itself, or its level-3
     * ancestor for deeper stems), the w template (ancestor attachment
     * positions) and the slot that receives the vertex's own position (-1:
     * the stem rides rigidly on its level-3 ancestor). */
    int32_t wind_index;
    float wind_w[4];
    int wind_slot;
} sy_stem;

/* The stem's parent and attachment in the skeleton's hierarchy (wind). */
static inline int32_t sy_stem_tree_parent(const sy_stem *s) { return s->reattached ? s->tree_parent : s->parent; }
static inline float sy_stem_tree_attach_s(const sy_stem *s) { return s->reattached ? s->tree_attach_s : s->attach_s; }

typedef struct {
    size_t n;
    sy_stem *s;
    int32_t *by_depth;  /* stem indices, parents before children */
    int32_t *node_stem; /* per skeleton node: the stem whose chain holds it */
    float *node_s;      /* per skeleton node: arc length along that stem */
    int32_t root;       /* the stem holding the root node */
    float trunk_radius; /* base radius of the root stem */
    float height;       /* extent of the skeleton along Z */
    float ground;       /* Z of the root node: nothing is drawn below it */
    float *reach;       /* per stem: how far its subtree (polylines and leaves) reaches from
                           its base, what dropping it moves (sy_stems_reach; NULL until then) */
} sy_stems;

sy_code sy_stems_build(const sy_skeleton *skel, const sy_mesh_options *opt, sy_stems *out, sy_error *err);
void sy_stems_free(sy_stems *st);

/* A stem and its base radius, ordered thickest first, then by index
 * (qsort): stems.c places each depth's stems so, tube.c welds each
 * parent's children so. */
typedef struct {
    int32_t stem;
    float r_base;
} sy_stem_by_radius;
int sy_stem_by_radius_cmp(const void *x, const void *y);
/* Fills st->reach from the stems' polylines and the leaves lv (may be NULL). */
sy_code sy_stems_reach(sy_stems *st, const sy_leaves *lv, sy_error *err);

/* Frame of stem s at arc length q, interpolated between the rings listed in
 * idx[0..n_idx) (a LOD's ring selection): centre c, unit tangent T, unit
 * normal N orthogonal to T, radius R. */
void sy_stem_frame_at(const sy_stem *s, const int32_t *idx, size_t n_idx, float q, float c[3], float T[3],
                      float N[3], float *R);
/* The point c of stem s's axis (rings idx, or every sample with NULL)
 * closest to x (the Z-up frame), by `iters` Newton steps along the axis
 * from arc length s_hint; its frame (T, N) and radius come with it.
 * Returns its arc length. */
float sy_stem_closest_on_axis(const sy_stem *s, const int32_t *idx, size_t n_idx, const float x[3], float s_hint,
                              int iters, float c[3], float T[3], float N[3], float *R);

/* ---- LOD selection and tube emission (lod.c, tube.c) ---- */
typedef struct {
    int level;
    int stride;     /* take every stride-th LOD0 ring (first and last always) */
    uint8_t *keep;  /* per stem: emitted at this level */
    int cap_rings;  /* intermediate rings of the tip hemisphere */
} sy_lod_params;

/* A lean branch (thinner at its base than sy_mesh_options.lean_radius,
 * which trees whose crowns are the twigs their scan's returns trace set) is
 * drawn with rings where it turns 30 degrees (not 10) and none for its taper
 * alone, as few rings as a leaf-bearing twig, a cone for a tip, and no more
 * ring vertices than its radius asks for (three under half the lean radius)
 * even where children leave it. Such a crown holds thousands of twigs:
 * drawn as limbs are, AdTree's tree1 took 190k triangles, over three times
 * the LOD0 budget (docs/mesh.md, "Stop 36"). */
static inline int sy_stem_lean(const sy_stem *s) { return s->lean != 0; }
int sy_stem_radial(const sy_stem *s, const sy_lod_params *lp);
/* Intermediate rings of the stem's tip hemisphere at this level. */
int sy_stem_cap_rings(const sy_stem *s, const sy_lod_params *lp);
/* Ring selection of stem s at this level: writes up to s->n_samp indices and
 * returns the count. */
size_t sy_stem_rings(const sy_stem *s, const sy_lod_params *lp, int32_t *idx);
/* Vertex and index counts of one stem at a level (0, 0 when not emitted). */
void sy_tube_counts(const sy_stems *st, size_t stem, const sy_lod_params *lp, size_t *nv, size_t *ni);
/* Writes one stem into m starting at vertex v0 / index i0 (space reserved
 * from sy_tube_counts). idx is scratch of 2 * (max n_samp) entries. */
void sy_tube_emit(const sy_stems *st, size_t stem, const sy_lod_params *lp, sy_mesh *m, size_t v0, size_t i0,
                  int32_t *idx);
/* Drops the least important stems (children before parents) until the bark
 * of lp's level has at most budget triangles; *count holds the level's
 * triangles on entry and after. Returns 1, or 0 when out of memory. */
int sy_lod_fit_budget(const sy_stems *st, sy_lod_params *lp, size_t *count, size_t budget);
/* Brings back stems of prev_keep that lp drops, most important first and
 * parents before children, while the bark stays within target triangles;
 * *count holds the level's triangles on entry and after. Returns 1, or 0
 * when out of memory. */
int sy_lod_restore(const sy_stems *st, const uint8_t *prev_keep, sy_lod_params *lp, size_t *count, size_t target);
/* The share of the previous level's triangles a level's selection aims at:
 * half, less what the junction strips may add after selection (welding a
 * level adds up to ~8 % of its triangles with the Steiner points of a wide
 * ring, the caps it replaces fewer), so the drawn level stays within half. */
#define SY_LOD_SHARE 0.42
/* Chooses the stems level lp->level keeps (lp->keep), a subset of prev_keep:
 * thin stems go first (the threshold doubles per level), children with
 * their parents, then the least important until the bark has at most
 * SY_LOD_SHARE of prev_tris triangles less `lent` (lent to the level's leaf
 * cards). Returns 0 when even the trunk alone is too many. */
int sy_lod_select(const sy_stems *st, const uint8_t *prev_keep, size_t prev_tris, size_t lent, sy_lod_params *lp,
                  size_t *tris);
/* Bark triangles of the kept stems at a level. */
size_t sy_lod_bark_triangles(const sy_stems *st, const sy_lod_params *lp);
/* Builds the bark mesh of all kept stems at a level. */
sy_code sy_bark_mesh(const sy_stems *st, const sy_lod_params *lp, int material, sy_mesh *out, sy_error *err);
/* The same, also counting the level's junctions and the welded ones
 * (either may be NULL). */
sy_code sy_bark_mesh_welds(const sy_stems *st, const sy_lod_params *lp, int material, sy_mesh *out,
                           size_t *junctions, size_t *welded, sy_error *err);

/* ---- slivers (slivers.c) ---- */
/* Triangles smaller than this (issue 19's near-degenerate sliver) are
 * flipped away where an edge flip can. */
#define SY_BARK_MIN_AREA SY_MESH_SLIVER_AREA
/* Area of the triangle a, b, c (positions), in double. */
double sy_tri_area(const float *a, const float *b, const float *c);
/* Flips the edges of m's triangles under min_area into the neighbour across
 * them where both new triangles face as the pair did and reach min_area;
 * positions, normals, UVs and wind are untouched, the mesh stays closed.
 * Returns the number of flips. */
size_t sy_mesh_flip_degenerates(sy_mesh *m, double min_area);

/* ---- wind (wind.c) ---- */
/* Tapered-beam deflection (Habel 2009 eq. 4.7, unit prefactor) at x in [0,1]
 * for taper ratio alpha = r_tip / r_base. */
double sy_beam_deflection(double alpha, double x);
/* Least-squares fit u(x) ~ c2 x^2 + c4 x^4 on the 101 samples x = i/100. */
void sy_beam_fit(double alpha, float *c2, float *c4);
/* Fills asset->wind (one entry per stem of levels 0-3: deeper stems ride on
 * their level-3 ancestor) and each stem's wind fields. */
sy_code sy_wind_build(sy_stems *st, sy_asset *asset, sy_error *err);

/* ---- leaves (leaves.c) ---- */
/* The leaf card mesh for a shape and aspect (local: stem at origin, +Y to
 * the tip, +Z normal). */
sy_code sy_leaf_card(int shape, float aspect, int material, sy_mesh *out, sy_error *err);
/* How much a level's leaf cards grow: across the leaf (card x) and along it
 * (card y, the petiole to the tip). */
typedef struct {
    float across, along;
} sy_card_growth;
/* The lowest z that leaf card l (the box |x| <= aspect/2, 0 <= y <= 1 of
 * its local frame, scaled by its size and g) reaches when hung at height z. */
float sy_card_lowest(const sy_leaves *lv, uint32_t l, float aspect, sy_card_growth g, float z);
/* Instances of the leaves list[0..n) (indices into lv) in glTF's frame, their
 * size multiplied by g, with the wind data of the stem each hangs on.
 * keep (per stem, may be NULL): a leaf whose stem is not drawn moves to the
 * nearest ring centre of its closest drawn ancestor (raised, if its card of
 * width aspect would reach below the ground there). */
sy_code sy_leaf_instances(const sy_leaves *lv, const sy_stems *st, const uint8_t *keep, float aspect,
                          const uint32_t *list, size_t n, sy_card_growth g, int mesh, sy_instances *out, sy_error *err);

/* ---- impostor (impostor.c) ---- */
/* Renders the LOD0 meshes and instances of lod0 from two orthogonal
 * horizontal directions, adds the atlas image, its material and the crossed
 * card mesh; returns the mesh index or -1. */
int sy_impostor_build(sy_asset *asset, const sy_lod *lod0, int size, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
