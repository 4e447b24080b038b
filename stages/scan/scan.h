/* Virtual LiDAR: scenes of generated trees (exact primitives built from the
 * skeleton and leaf cards, never from a mesh) on a heightfield terrain, a BVH
 * over them, and terrestrial / mobile / airborne scanners with a beam model
 * (divergence sub-rays, range noise, multiple returns, intensity). Every point
 * carries the truth of what it hit: treeID, speciesID, isWood, branchID.
 * See docs/scan.md for the models and their defaults. */
#ifndef SYLVA_SCAN_H
#define SYLVA_SCAN_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "stages/core/bvh.h"
#include "stages/core/cloud.h"
#include "stages/core/skeleton.h"
#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------ primitives */

enum { SY_PRIM_CONE, SY_PRIM_QUAD, SY_PRIM_TRI };
enum { SY_MAT_WOOD, SY_MAT_LEAF, SY_MAT_GROUND };

/* One ray-traceable surface with its labels.
 * cone: v[0..2] axis start a, v[3..5] axis end b, v[6] radius at a, v[7] at b
 *       (lateral surface of a truncated cone, no caps);
 * quad: v[0..2] leaf base, v[3..5] half-width vector (local +X), v[6..8] length
 *       vector (local +Y), v[9..11] unit normal (+Z); the card spans
 *       base + s*u + t*v for s in [-1,1], t in [0,1] (elliptic: the inscribed ellipse);
 *       gaps > 0: a needle shoot's card, open in that share (gaps/256) of its
 *       SY_CARD_GAP_CELL cells (sy_prim_quad_gaps);
 * tri:  v[0..2], v[3..5], v[6..8] the corners. */
typedef struct {
    float v[12];
    int32_t tree_id;    /* 0: ground and understory */
    int32_t species_id; /* -1: ground and understory */
    int32_t branch_id;  /* -1 unless tree wood or leaf */
    uint8_t kind, material, elliptic, understory;
    uint8_t gaps; /* quads: the open share of the card in 1/256 (0: solid) */
} sy_prim;

/* A conifer's leaf card stands for a shoot of needles: a beam meets needles on
 * only part of its area (the species' leaf_fill, docs/species.md). The card is
 * cut into cells of this size (1 cm, a few needles' width), each open or
 * needled by a hash of the cell and the card, so a beam's sub-rays that fall
 * in different cells pass or stop independently and the same ray always does
 * the same. */
#define SY_CARD_GAP_CELL 0.01

typedef struct {
    sy_prim *p;
    size_t n, cap;
} sy_prims;

sy_code sy_prims_push(sy_prims *list, const sy_prim *p, sy_error *err);
void sy_prims_free(sy_prims *list);

sy_prim sy_prim_cone(const float a[3], float ra, const float b[3], float rb);
/* x_axis, y_axis: unit local +X (across) and +Y (base to tip). */
sy_prim sy_prim_quad(const float base[3], const float x_axis[3], const float y_axis[3], float length, float width,
                     int elliptic);
sy_prim sy_prim_tri(const float a[3], const float b[3], const float c[3]);
/* Makes a quad a shoot card that a beam meets on the share fill in (0, 1] of
 * its area (1: a solid leaf). */
void sy_prim_quad_gaps(sy_prim *quad, double fill);

/* Exact intersection of the ray o + t d (|d| = 1) with tmin < t < tmax:
 * returns 1 and sets *t, else 0. */
int sy_prim_intersect(const sy_prim *p, const double o[3], const double d[3], double tmin, double tmax, double *t);
/* Unit surface normal at the surface point x (sign arbitrary). */
void sy_prim_normal(const sy_prim *p, const double x[3], double n[3]);
/* Axis-aligned bounds (conservative, exact for triangles and quads). */
void sy_prim_bounds(const sy_prim *p, sy_box *box);

/* ------------------------------------------------------------------- BVH */

/* Hits nearer than this are the surface a ray starts from. */
#define SY_SCAN_TMIN 1e-6

/* sy_bvh_ray_fn over an array of sy_prim (ctx): sy_prim_intersect with
 * SY_SCAN_TMIN < t < tmax. */
int sy_prim_ray_hit(const void *prims, uint32_t i, const double o[3], const double d[3], double tmax, double *t);
/* Builds the BVH over the list's bounds and rearranges the list into the
 * BVH's leaf order (hit indices are positions in the rearranged list). */
sy_code sy_prims_index(sy_prims *list, sy_bvh *bvh, sy_error *err);

/* --------------------------------------------------------------- terrain */

typedef struct {
    double slope_deg;   /* steepest slope of the base plane */
    double aspect_deg;  /* direction (from +X, counter-clockwise) the plane rises towards */
    double roughness;   /* amplitude (metres) of the seeded value noise */
    double feature;     /* noise wavelength in metres (default 6) */
    double base;        /* height at the origin before noise */
    uint64_t seed;
    double lo[2], hi[2]; /* extent */
    double step;         /* triangulation grid, metres */
} sy_terrain;

/* The continuous surface the grid samples. */
double sy_terrain_field(const sy_terrain *t, double x, double y);
/* Height of the triangulated surface (what rays hit) at (x, y); the field
 * value outside the extent. */
double sy_terrain_height(const sy_terrain *t, double x, double y);
/* Appends the grid's triangles (two per cell, split along the same diagonal
 * sy_terrain_height uses) as ground primitives. */
sy_code sy_terrain_triangulate(const sy_terrain *t, sy_prims *out, sy_error *err);

/* ------------------------------------------------------------------ scene */

/* One tree of the scene with what the truth file reports. */
typedef struct {
    int tree_id;
    char species[64];
    int species_id;
    uint64_t seed;
    double pos[3]; /* world position of the trunk base */
    double yaw_deg;
    sy_skeleton skel; /* world coordinates (origin 0) */
    size_t leaf_count;
    size_t pruned_nodes; /* grown nodes that went under the terrain and were cut off with what they carry */
    double height, dbh, crown_width;
} sy_scan_tree;

typedef struct {
    sy_prims prims;
    sy_scan_tree *trees;
    size_t n_trees;
    int has_terrain;
    sy_terrain terrain;
    double area_lo[2], area_hi[2]; /* the surveyed area (airborne strips, mobile paths) */
    double veg_lo[3], veg_hi[3];   /* bounds of trees and understory (empty: lo > hi) */
    sy_bvh bvh; /* over prims, which sy_scene_finish puts into its leaf order */
} sy_scene;

void sy_scene_init(sy_scene *s);
void sy_scene_free(sy_scene *s);
/* How a tree's leaf cards are traced: width over length (the species'
 * leaf_scale_x), the inscribed ellipse or the whole quad, and the share of a
 * card's area a beam meets (the species' leaf_fill: 1 a solid leaf, less a
 * needle shoot; sy_prim_quad_gaps). */
typedef struct {
    float width, fill;
    int elliptic;
} sy_card_form;

/* Adds a tree grown in its local frame (trunk base at the origin), rotated by
 * yaw about Z and moved to pos. leaves may be NULL (then cards is unused).
 * The skeleton is copied. */
sy_code sy_scene_add_tree(sy_scene *s, const sy_skeleton *local, const sy_leaves *leaves, const sy_card_form *cards,
                          const char *species, int species_id, uint64_t seed, const double pos[3], double yaw_deg,
                          sy_error *err);
/* Triangulates the terrain into the scene. */
sy_code sy_scene_add_terrain(sy_scene *s, const sy_terrain *t, sy_error *err);
/* Small random shrubs (stems and leaf blobs) over the area, `density` per m^2,
 * keeping clear of tree trunks. Labelled treeID 0, speciesID -1, isWood 0. */
sy_code sy_scene_add_understory(sy_scene *s, double density, uint64_t seed, sy_error *err);
/* Builds the BVH; call once after adding everything. */
sy_code sy_scene_finish(sy_scene *s, sy_error *err);

/* Trunk radius at `above` metres over the root along the trunk stem
 * (linear between nodes, as the cones are); NaN if the trunk is shorter. */
double sy_trunk_radius_at(const sy_skeleton *s, double above);

/* Plots and single trees as the CLI builds them. */
typedef struct {
    const char *species[32]; /* names or .ini paths */
    int n_species;
    double plot_size;  /* 0: a single tree at the origin */
    int trees;         /* plot only */
    double understory; /* shrubs per m^2 (default: 0.05 in plots, 0 for a single tree) */
    double slope_deg, aspect_deg, roughness;
    int terrain;       /* 0: no ground at all */
    int leaves;        /* 0: wood only */
    int elliptic;      /* leaf cards masked to their inscribed ellipse */
    uint64_t seed;
    /* Forest-grown habit, 0 (open-grown, the species file as it is) .. 1: a
     * stand's competition for light raises the crown base (Weber-Penn
     * BaseSize moves towards half the height), narrows the crown (level-1
     * branch lengths shrink to 0.3 of the file's) and slims the trunk (the
     * radius ratio halves). */
    double forest;
    /* Single tree only: this many trees of the same species (their own seeds
     * and headings) stand on a ring around it, crowns about touching, so the
     * scanner sees the tree through its neighbours. */
    int neighbours;
} sy_scene_options;

sy_scene_options sy_scene_options_default(void);
/* SY_EUSAGE naming the field when a value is out of range (no species, too
 * many trees, neighbours in a plot, a vertical slope, ...). */
sy_code sy_scene_options_check(const sy_scene_options *o, sy_error *err);
/* Grows the trees, lays the terrain (sized to cover `reach` metres around the
 * plot, so scanners standing out there are on ground) and the understory, and
 * finishes the scene. */
sy_code sy_scene_build(sy_scene *s, const sy_scene_options *o, double reach, sy_error *err);

/* ---------------------------------------------------------------- scanner */

typedef enum { SY_SCANNER_TERRESTRIAL, SY_SCANNER_MOBILE, SY_SCANNER_AIRBORNE } sy_scanner_kind;

typedef struct {
    sy_scanner_kind kind;
    uint64_t seed;
    /* terrestrial */
    int positions;        /* stations on a circle around the scene centre */
    double radius;        /* circle radius, metres (0: automatic) */
    double height;        /* instrument height above ground (terrestrial and mobile) */
    double step_deg;      /* horizontal angular step */
    double vstep_deg;     /* vertical angular step (0: same as step_deg) */
    /* mobile */
    double speed;         /* m/s along the path */
    double rotation_hz;   /* profiler turns per second */
    const double *path;   /* x,y pairs of a polyline, or NULL for the default path */
    size_t path_points;
    int lawnmower;        /* default path: 1 lawnmower lines over the area, 0 a circle */
    double line_spacing;  /* lawnmower line spacing, metres */
    /* airborne */
    double altitude;      /* above the ground at the area centre */
    double swath_deg;     /* full scan angle */
    double density;       /* pulses per m^2 over the area */
    double overlap;       /* strip side overlap, 0..0.9 */
    /* beam */
    double divergence_mrad; /* full angle; 0: one ray per pulse */
    int subrays;            /* rays per pulse when divergence > 0 */
    double noise;           /* range noise sigma, metres */
    int max_returns;        /* 1..15 */
    double separation;      /* minimum range gap between two returns, metres */
    double max_range;
    double pulse_rate;      /* pulses per second (terrestrial and airborne timing) */
    size_t max_points;      /* 0: no cap */
} sy_scan_options;

/* Sensible defaults per kind (documented in docs/scan.md). */
sy_scan_options sy_scan_options_for(sy_scanner_kind kind);
/* The terrestrial defaults. */
sy_scan_options sy_scan_options_default(void);
/* SY_EUSAGE naming the field when an option is outside its range (the kind's
 * fields only); sy_scan calls it too. */
sy_code sy_scan_options_check(const sy_scan_options *sc, sy_error *err);
const char *sy_scanner_kind_name(sy_scanner_kind kind);

typedef struct {
    size_t pulses, points, wood, leaf, ground, understory;
    int stations; /* TLS positions, flight strips or path passes */
    double seconds;
} sy_scan_stats;

/* Scans the finished scene into out (xyz, intensity, returns, classification,
 * gps_time and the treeID/speciesID/isWood/branchID attributes). The result
 * depends only on the scene, the scanner and its seed, never on the thread
 * count. */
sy_code sy_scan(const sy_scene *s, const sy_scan_options *sc, sy_cloud *out, sy_scan_stats *stats, sy_error *err);

/* Cylinder segmentation, as tree extraction from a plot scan does it (the
 * TreeLS and lidR tools clip a stem's points within a radius): keeps the
 * points within `radius` metres horizontally of the world position (x, y),
 * whatever they hit (a neighbour's branches inside the cylinder stay, as in
 * real segmented trees), and recounts stats. */
sy_code sy_scan_clip_cylinder(sy_cloud *c, const double centre[2], double radius, sy_scan_stats *stats, sy_error *err);

/* Segmentation by the truth labels: keeps the points of the tree tree_id and
 * the ground and understory points within `radius` metres of (x, y), the
 * points a perfect segmentation of a plot scan would give that tree. */
sy_code sy_scan_isolate_tree(sy_cloud *c, int tree_id, const double centre[2], double radius, sy_scan_stats *stats,
                             sy_error *err);

/* The truth file (docs/truth-format.md) of a scene. */
void sy_write_truth(FILE *fp, const sy_scene *s, const sy_scan_options *sc, int stations);

#ifdef __cplusplus
}
#endif

#endif
