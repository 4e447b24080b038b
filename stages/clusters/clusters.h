/* Clusters: the parts of a scanned tree that the skeleton cannot resolve into
 * branches (foliage, dense twigs). Each cluster hangs off one seed node of the
 * main skeleton, owns its input points and is enclosed by a closed, outward
 * hull (an alpha shape simplified to a coarse mesh; see docs/skeleton.md).
 * Hull vertices are in the skeleton's frame (relative to the cloud origin). */
#ifndef SYLVA_CLUSTERS_H
#define SYLVA_CLUSTERS_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/skeleton.h"
#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    SY_HULL_ALPHA = 0,  /* alpha shape (alpha_scale * alpha_min), possibly simplified */
    SY_HULL_CONVEX = 1, /* convex hull: the alpha shape was not a closed manifold or lost points */
    SY_HULL_BOX = 2     /* oriented box: too few or coplanar points for a 3-D hull */
} sy_hull_kind;

typedef struct {
    int32_t seed;        /* node of the main skeleton the cluster hangs off */
    size_t n_points;
    uint32_t *points;    /* indices into the input cloud, ascending */
    size_t n_verts;
    float *verts;        /* 3 * n_verts */
    size_t n_tris;
    uint32_t *tris;      /* 3 * n_tris, counter-clockwise seen from outside */
    float alpha;         /* CGAL alpha (a SQUARED radius) of the shape; 0 unless SY_HULL_ALPHA */
    int hull;            /* sy_hull_kind */
    /* Where the points lie inside the hull, for synthesis (decode has no
     * points): occ_dims[0] x [1] x [2] cells (each 1..8, 0 0 0 = none) over
     * the hull's vertex bounding box, bit x + nx (y + ny z) set when a point
     * falls in that cell (sy_cluster_occupancy). */
    uint8_t occ_dims[3];
    uint8_t *occupancy;  /* ceil(nx ny nz / 8) bytes or NULL */
    /* The twigs its returns trace (sy_clusters_trace_twigs): n_twigs nodes
     * in depth-first preorder from the seed, each a return of the lobe;
     * twig_parent[i] < i, or -1 for a node hanging off the seed. */
    size_t n_twigs;
    float *twig_pos;      /* 3 * n_twigs, the skeleton's frame */
    int32_t *twig_parent;
    float twig_voxel;     /* the voxel the returns were thinned to, metres (0: no twigs) */
} sy_cluster;

typedef struct {
    size_t n;
    sy_cluster *items;
} sy_clusters;

void sy_clusters_free(sy_clusters *c);

/* The low-confidence edge rule (Pirk 2013 eq. 3.2 and §3.3.2, interpretation B
 * of the digest): the edge parent->child is low-confidence when the mean
 * distance of the child's supporting points from the edge segment exceeds
 * fs * the child's diameter, i.e. the points spread wider than a branch of
 * that diameter could.
 * With around != 0 the distance is taken from the skeleton around the child
 * instead: the segments parent->child and child->next[k] (its n_next
 * children), or for a tip the ray from the parent through the child. A level
 * set straddles its node, so half its points lie beyond the incoming
 * segment's end and their axial offset counts as spread (a 1 cm limb in a
 * 7 cm bin fails on that alone), and a fork's level set holds the rings of
 * both limbs, each near its own outgoing segment. Returns 1 for low
 * confidence. */
int sy_edge_low_confidence(const float parent[3], const float child[3], int around, const float *next, size_t n_next,
                           const float *xyz, const uint32_t *points, size_t n_points, double diameter, double fs);

/* Walks the full skeleton from the root and stops at low-confidence edges.
 * cluster_of[i] = -1 for nodes of the main skeleton, else the cluster index;
 * seed_of[c] = the seed node of cluster c. Groups of low-confidence subtrees
 * with fewer than min_points supporting points in total stay on the skeleton.
 * measured (may be NULL): per node a measured radius (a ring of returns was
 * fitted, 0 = none); such an edge is high-confidence whatever its spread.
 * around: the spread of sy_edge_low_confidence.
 * full must carry support. seed_of has room for full->n entries. */
sy_code sy_clusters_cut(const sy_skeleton *full, const float *xyz, const float *measured, int around, double fs,
                        int min_points,
                        int32_t *cluster_of, int32_t *seed_of, size_t *n_clusters, sy_error *err);

/* The floor an airborne crown's lobes reach down to (docs/skeleton.md 8d):
 * each hull also holds a copy of each of its points at height z, drawn in
 * toward the stem at (axis) as the species' crown narrows from the point's
 * height to the floor: the copy keeps min(1, profile(floor) / profile(its
 * height)) of the point's horizontal offset, profile read over SY_CROWN_SLABS
 * slabs from z (0) to top. A profile of zeros keeps every offset: columns. */
#define SY_CROWN_SLABS 8
typedef struct {
    double z;                        /* NaN: no floor */
    double axis[2], top;
    float profile[SY_CROWN_SLABS];   /* the crown's radius per slab, any scale */
} sy_hull_floor;

/* The crown's roof, for a scan seen from below (terrestrial stations): the
 * lower crown hides the top from them. A dome's top quarter holds a third
 * of its leaves and returns 1-4 % of the points (docs/synthesize.md
 * "Stop 32"), and between those few returns the crown's top looks notched.
 * The roof is the crown's highest point per cell of a grid over its
 * footprint, raised to the least surface over it that is concave along the
 * grid's rows, columns and diagonals (the crown's upper hull, read per
 * cell). A lobe's point that stands at its cell's top, more than lift_min
 * under the roof, reaches up to it (sy_crown_roof_lift). */
typedef struct {
    double x0, y0, cell; /* the grid's corner and cell side, metres */
    int nx, ny;
    float *top;          /* nx * ny: the highest point per cell (NaN: none) */
    float *roof;         /* nx * ny: the roof over the cells that hold points (NaN: none) */
    double z0, height;   /* the points' lowest z and their height */
    double lift_min;     /* metres */
} sy_crown_roof;

/* The roof's grid: cells along the footprint's wider side; a point reaches
 * up to the roof more than this share of the height under it; a scan's
 * crown is roofed when its top stands SY_ROOF_GAP_RATIO times further under
 * its roof than its species' own, and at least SY_ROOF_GAP_MARGIN of its
 * height further (the pipeline's rule: a palm's rosette stands 0.03 of its
 * height under its roof, and its bundled scan's 0.046 is 1.51 times that). */
#define SY_ROOF_CELLS 24
#define SY_ROOF_LIFT 0.05
#define SY_ROOF_GAP_RATIO 1.5
#define SY_ROOF_GAP_MARGIN 0.03

/* The roof of the n points xyz (a whole tree): `cells` cells along the
 * wider side of its footprint, lift_min = lift times its height. */
sy_code sy_crown_roof_build(const float *xyz, size_t n, int cells, double lift, sy_crown_roof *r, sy_error *err);
void sy_crown_roof_free(sy_crown_roof *r);
/* The height point p reaches up to under roof r (NaN: it does not: no
 * roof, off its grid, under its cell's top, or within lift_min of it). */
double sy_crown_roof_lift(const sy_crown_roof *r, const float p[3]);
/* How far the crown's top stands under its roof: over the cells whose roof
 * lies in the upper half of the height, the mean of (roof - top) / height.
 * A closed dome's is small, a notched top's larger (0: no roof). */
double sy_crown_roof_gap(const sy_crown_roof *r);

/* Builds the hull of c from its points: the alpha shape of (a thinned copy
 * of) the points with alpha = alpha_scale * alpha_min, simplified towards
 * target_tris; it falls back to the convex hull and finally an oriented box
 * so that the result is always closed, outward and holds >= 95% of the points
 * within tol metres. anchor (3 floats, or NULL): a point the hull also holds;
 * base (NULL: none): the floor the hull also reaches down to; roof (NULL:
 * none): the roof its points at their cells' tops reach up to, how many of
 * the (thinned) points did in *lifted (may be NULL). */
sy_code sy_cluster_build_hull(sy_cluster *c, const float *xyz, double alpha_scale, int target_tris, double tol,
                              const float *anchor, const sy_hull_floor *base, const sy_crown_roof *roof,
                              int *lifted, sy_error *err);

/* Options of the hull step: the alpha shape's scale (alpha = alpha_scale *
 * alpha_min, both CGAL squared radii), the triangle budget per hull (the
 * encode stage's sy_sylva_hull_budget keeps a .sylva under 40 kB) and the
 * containment tolerance in metres. */
typedef struct {
    double alpha_scale; /* 5 */
    int triangles;      /* per hull, >= 12 (160) */
    double tol;         /* metres (0.01) */
    int seen_from_above; /* the scan saw the crown from above (airborne): a cell under one that holds
                            a return is occluded, not empty, and counts as occupied (0) */
    sy_hull_floor floor; /* floor.z NaN (default), or every hull reaches down to this floor (an
                            airborne crown's lobes reach down to its lowest return, or its crown base) */
    const sy_crown_roof *roof; /* NULL (default), or hulls reach up to this roof (a terrestrial crown's
                                  top, hidden from the stations) and their occupancy counts the cells
                                  between a return and the roof it reaches up to as occupied */
    const float *anchors; /* 3 per cluster or NULL: a point each hull also holds (an airborne crown's
                             lobes reach in to the skeleton node they hang from) */
} sy_hull_options;

sy_hull_options sy_hull_options_default(void);
/* SY_EUSAGE naming the field when a value is out of range. */
sy_code sy_hull_options_check(const sy_hull_options *o, sy_error *err);

typedef struct {
    size_t alpha, convex, box; /* which hull each cluster got */
    size_t twig_nodes;         /* traced twigs, when the caller traced them (sy_clusters_trace_twigs) */
    double twig_voxel;         /* their voxel, metres */
    double seconds;
} sy_hull_report;

/* Builds every cluster's hull (sy_cluster_build_hull) from xyz, the cloud
 * the clusters' point indices refer to. report may be NULL. */
sy_code sy_clusters_build_hulls(sy_clusters *cl, const float *xyz, const sy_hull_options *o, sy_hull_report *report,
                                sy_error *err);

/* Fills c->occ_dims and c->occupancy from its points and hull: the longest
 * side of the hull's box gets `cells` (1..8) cells, the others as many as
 * keep cells near cubic. With from_above, every cell under an occupied one
 * in its column is occupied too (what an airborne scanner cannot see under
 * the returns it got); with a roof (NULL: none), every cell from a point
 * that reaches up to it (sy_crown_roof_lift) to the roof over it (what
 * terrestrial stations cannot see over the crown's top). */
sy_code sy_cluster_occupancy(sy_cluster *c, const float *xyz, int cells, int from_above, const sy_crown_roof *roof,
                             sy_error *err);
/* The same grid (8 cells along the longest side) from c's traced twigs, one
 * return per voxel of its points, each marking every cell its voxel's
 * returns may lie in (a cube of one voxel either side of it): what a lobe
 * with twigs stores instead of its bits (the .sylva keeps its twigs). */
sy_code sy_cluster_occupancy_of_twigs(sy_cluster *c, sy_error *err);
/* Bytes of c's occupancy bits (0 without). */
size_t sy_cluster_occupancy_bytes(const sy_cluster *c);

/* ---- The twigs the returns trace (stages/clusters/twigs.c) ---- */

typedef struct {
    double voxel_min, voxel_max; /* the ladder of voxels tried, metres (0.02, 0.4: the largest real scan here,
                                   PyTLidar's 12.7 m tree_1, fits at 0.36) */
    size_t max_nodes;            /* twig nodes over all lobes at most (0: no twigs) */
} sy_twig_options;

sy_twig_options sy_twig_options_default(void);
/* SY_EUSAGE naming the field when a value is out of range. */
sy_code sy_twig_options_check(const sy_twig_options *o, sy_error *err);

typedef struct {
    size_t nodes;
    double voxel; /* metres; 0: no voxel of the ladder kept within max_nodes */
    double seconds;
} sy_twig_report;

/* Each lobe's twigs: its points thinned to one return per voxel (the one
 * nearest the voxel's mean) and joined, with its seed node on main, by
 * their Euclidean minimum spanning tree rooted at the seed; each tip then
 * stands at its voxel's return farthest from the node it hangs from. One voxel for
 * the whole tree: of voxel_min * 1.25^k (up to voxel_max), the finest whose
 * voxels over all lobes number at most max_nodes, found by bisection (or one
 * close to it: the counts fall with the voxel nearly always); none fits, or
 * a lobe of 2^22 points or more: no twigs. Replaces any twigs the clusters
 * had. report may be NULL. */
sy_code sy_clusters_trace_twigs(sy_clusters *cl, const sy_skeleton *main, const float *xyz, const sy_twig_options *o,
                                sy_twig_report *report, sy_error *err);
void sy_cluster_twigs_free(sy_cluster *c);

/* Splits the low-confidence groups of a cut (sy_clusters_cut's cluster_of /
 * seed_of over full) into lobes no longer than max_extent metres (largest
 * side of their points' box): a subtree that is larger has its top node kept
 * on the main skeleton (cluster_of = -1) and its children's subtrees split in
 * turn, so each lobe hangs off the skeleton node next to it; siblings' small
 * subtrees share a lobe while the union stays within the bound. The points
 * of a kept top node (a level set through foliage, often a shell across the
 * crown) are foliage too: they are chunked by a grid of max_extent cells
 * into lobes, each seeded at the kept node holding most of its points
 * (point_lobe[point] = lobe; -1 for every other point). Groups under min_points stay on the skeleton. Rewrites
 * cluster_of, seed_of and *n_clusters; seed_of needs room for full->n +
 * the point count entries, point_lobe one per input point. */
sy_code sy_clusters_split_lobes(const sy_skeleton *full, const float *xyz, double max_extent, int min_points,
                                int32_t *cluster_of, int32_t *seed_of, int32_t *point_lobe, size_t *n_clusters,
                                sy_error *err);

/* ---- The cut: the full skeleton -> main skeleton + clusters. ---- */

typedef struct {
    int clusters;      /* 0: no cut, every point stays on the skeleton (1) */
    double fs;         /* scan-density factor f_s of eq. 3.2, in (0, 1] (1 = leafless) */
    int min_points;    /* smaller low-confidence groups stay on the skeleton (24) */
    int spread_around; /* the spread of sy_edge_low_confidence: around the node (0) */
    double lobe_size;  /* lobes no larger than this share of the cloud's largest extent, [0, 1]
                          (0.25; 0 = one cluster a cut, as Pirk 2013 §3.3.2 alone gives) */
} sy_cut_options;

sy_cut_options sy_cut_options_default(void);
/* SY_EUSAGE naming the field when a value is out of range. */
sy_code sy_cut_options_check(const sy_cut_options *o, sy_error *err);

typedef struct {
    size_t nodes, branches;   /* of the main skeleton */
    size_t clusters, cluster_points, skeleton_points;
    double seconds;
} sy_cut_report;

/* The cut of a full skeleton (the skeleton stage's sy_reconstruct_skeleton)
 * of the cloud xyz: sy_clusters_cut, then sy_clusters_split_lobes when
 * o->lobe_size > 0, then the split of nodes and points into out (the main
 * skeleton, branch ids renumbered, support filled) and clusters (seeds in
 * out, point lists ascending, no hulls yet: sy_clusters_build_hulls). Leaf
 * points (f->wood) join the cluster of their cut node or one foliage cluster
 * per branch; a root above the known ground gets a foot down to it. clusters
 * NULL or o->clusters 0: no cut, every point stays on the main skeleton. Every
 * input point ends up in exactly one place: the support of one node or the
 * point list of one cluster. On failure out and clusters hold nothing to
 * free. report may be NULL. */
sy_code sy_clusters_extract(const sy_full_skeleton *f, const float *xyz, const sy_cut_options *o, sy_skeleton *out,
                            sy_clusters *clusters, sy_cut_report *report, sy_error *err);

/* ---- Mesh checks (used by the hull builder and the tests). ---- */

/* *bad: the edges not shared by exactly two triangles traversing them in
 * opposite directions; 0 for a closed, consistently oriented 2-manifold (no
 * triangles count as one bad edge). SY_EINTERNAL when out of memory. */
sy_code sy_mesh_bad_edges(const uint32_t *tris, size_t n_tris, size_t n_verts, size_t *bad, sy_error *err);
/* Signed volume (> 0 when the triangles face outward). */
double sy_mesh_signed_volume(const float *verts, const uint32_t *tris, size_t n_tris);
/* Fraction of the points inside the closed mesh or within tol of it. */
double sy_mesh_containment(const float *verts, const uint32_t *tris, size_t n_tris, const float *xyz,
                           const uint32_t *points, size_t n_points, double tol);

#ifdef __cplusplus
}
#endif

#endif
