/* Skeleton: a rooted tree of nodes, the shared product of tree generation
 * (Weber-Penn) and reconstruction (shortest-path skeletons, QSM import), read by
 * meshing, export, encoding and evaluation. Z is up, metres, positions relative
 * to origin. Node 0 is the root; parent[i] < i is NOT required, but parent
 * links never form a cycle and exactly one node has parent -1. */
#ifndef SYLVA_SKELETON_H
#define SYLVA_SKELETON_H

#include <stddef.h>
#include <stdint.h>

#include "status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct {
    size_t n;
    double origin[3];
    float *pos;       /* 3n */
    float *radius;    /* n, metres */
    int32_t *parent;  /* n, -1 for the root */
    uint8_t *order;   /* n, branch order: 0 trunk, 1 its branches, ... */
    int32_t *branch;  /* n, branch id: the nodes of one stem (trunk, or one branch
                         from its base to its tip) share an id; a branch's first
                         node's parent lies on the parent branch */
    /* Optional: the input points that support each node (reconstruction only).
     * Points of node i are support[support_start[i] .. support_start[i+1]). */
    uint32_t *support_start; /* n+1 or NULL */
    uint32_t *support;       /* or NULL */
    /* Weber-Penn trunk lobes (grown trees): the cross-section of every
     * order-0 stem ripples as radius * (1 + lobe_depth * sin(lobes * angle)),
     * the node radius being the mean. 0 and 0 for reconstructed trees: a
     * scan's trunk has no such parameters. */
    int lobes;
    float lobe_depth; /* [0, 1) */
} sy_skeleton;

sy_code sy_skeleton_init(sy_skeleton *s, size_t n, sy_error *err);
void sy_skeleton_free(sy_skeleton *s);
/* Appends a node, growing arrays; returns its index or -1 (err set). */
int32_t sy_skeleton_add(sy_skeleton *s, const float pos[3], float radius, int32_t parent, int order,
                        int32_t branch, sy_error *err);
/* A tree is at most this wide: the tallest stand ~116 m, the widest crowns
 * ~150 m. A node farther from the root, or a radius over SY_SKELETON_MAX_RADIUS,
 * is a corrupt coordinate (1e30), and every step that samples a skeleton
 * (leaves, meshing, evaluation) scales with its extent. */
#define SY_SKELETON_MAX_SPAN 1000.0  /* metres from the root */
#define SY_SKELETON_MAX_RADIUS 100.0 /* metres */

/* Checks the invariants (one root, no cycles, parents in range, finite
 * positions within SY_SKELETON_MAX_SPAN of the root, |origin| <= SY_WORLD_MAX,
 * radius in (0, SY_SKELETON_MAX_RADIUS], lobes >= 0 with depth in [0, 1));
 * the message names the first violation. */
sy_code sy_skeleton_validate(const sy_skeleton *s, sy_error *err);
/* Number of branches (max branch id + 1). */
int32_t sy_skeleton_branch_count(const sy_skeleton *s);
/* Height: highest node z minus the root's z, metres. */
double sy_skeleton_height(const sy_skeleton *s);
/* Total length of all edges in metres. */
double sy_skeleton_length(const sy_skeleton *s);
/* The radius where the node path path[0..n) (each node followed by the next
 * along it: the trunk from the root) first passes height z, interpolated
 * between the two nodes it passes between; span (may be NULL): their
 * heights, lower first. NAN when the path does not reach z. */
double sy_skeleton_radius_at_height(const sy_skeleton *s, const int32_t *path, size_t n, double z, double span[2]);
/* Child lists (s->n entries each, -1 = none): node i's children are
 * first_child[i], next_sibling[first_child[i]], ... in ascending index order. */
void sy_skeleton_children(const sy_skeleton *s, int32_t *first_child, int32_t *next_sibling);
/* The nodes in breadth-first order from the roots (nodes without a parent),
 * over the child lists above; returns how many (s->n for a forest). */
size_t sy_skeleton_breadth_first(const sy_skeleton *s, const int32_t *first_child, const int32_t *next_sibling,
                                 int32_t *order);
/* Each node's lowest-index child of its own branch id (s->n entries, -1 at
 * a branch's end): the branch's chain. */
void sy_skeleton_branch_next(const sy_skeleton *s, int32_t *next);
/* The node each node's stem goes on through (s->n entries, -1 = its stem
 * ends there): its lowest-index child of the same branch id, else the
 * thickest child of another id turning by less than 60 degrees. The mesher
 * draws one stem along each chain and the mesh check measures against the
 * same chains. QSMs that number their segments between forks (rTwig's
 * segment ids) would otherwise end the trunk in a dome at every fork with
 * its continuation welded on as a branch; and a stem ending with children
 * on its tip (a QSM's fork into thinner limbs, a synthesised patch whose
 * next patch docks at its end, a lobe grown from the cut limb's last node)
 * can weld none of them: their rings stand off the stem's end and were
 * capped. Until stop 29 only a child >= 0.7 as thick turning < 45 degrees
 * went on: rTwig's QSM welded 30 of 100 junctions at LOD0 (now 56 of 72),
 * the airborne fir sample 468 of 708 (525 of 615). */
void sy_skeleton_continuations(const sy_skeleton *s, int32_t *cont);
/* Length of node i's incoming edge in metres (0 at the root). */
double sy_skeleton_edge_length(const sy_skeleton *s, size_t i);
/* l[i] = length of all edges below node i plus its incoming edge (so leaves
 * get their own edge length, never 0). Needs parent[i] < i (breadth-first
 * order). */
void sy_skeleton_subtree_lengths(const sy_skeleton *s, double *l);
/* Branch ids and orders from the subtree lengths l: each node's continuation
 * is its child with the largest l; the other children start new branches of
 * order + 1. Ids are numbered in node order. Needs breadth-first order. */
void sy_skeleton_assign_branches(sy_skeleton *s, const double *l);
/* Puts a new root under the old one, at the old root's x, y and height z:
 * the new node supports no points and carries the old root's radius, order
 * and branch; every old node's id grows by one. */
sy_code sy_skeleton_prepend_root(sy_skeleton *s, float z, sy_error *err);

/* A reconstructed skeleton before the cut into main skeleton and clusters,
 * as the skeleton stage hands it to the clusters stage: every node, the node
 * each input point belongs to, which points are wood, the radii a ring of
 * returns measured, and the ground under the base. */
typedef struct {
    sy_skeleton full;      /* breadth-first order; support holds the wood points of each node */
    size_t n_points;       /* points of the cloud the indices refer to */
    int32_t *point_node;   /* n_points: the node of full each point belongs to (leaf points too) */
    uint8_t *wood;         /* n_points: 1 = wood; NULL: every point is wood */
    float *measured;       /* full.n: radius a circle fit measured, 0 = none */
    double ground;         /* ground height under the base in the skeleton's frame; NaN: unknown */
    double foot_step;      /* extend the root down to the ground only when it lies more than this
                              above it (a foot worth a node: the level-set width) */
    double spacing;        /* the scan's point spacing the skeleton was built at (metres) */
    int stem_unseen;       /* the scan showed no stem: it saw the crown from above (airborne) */
} sy_full_skeleton;

void sy_full_skeleton_free(sy_full_skeleton *f);

/* Leaf placements of a generated tree: each leaf is a card of size scale,
 * positioned at pos, oriented by the unit quaternion rot (x, y, z, w) whose
 * local +Y is the leaf's axis (stem to tip) and +Z its normal, attached to
 * skeleton node `node`. */
typedef struct {
    size_t n;
    float *pos;    /* 3n, same frame as the skeleton */
    float *rot;    /* 4n */
    float *scale;  /* n, leaf length in metres */
    int32_t *node; /* n */
} sy_leaves;

void sy_leaves_free(sy_leaves *l);
sy_code sy_leaves_add(sy_leaves *l, const float pos[3], const float rot[4], float scale, int32_t node,
                      sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
