/* Shared plumbing of the skeleton/QSM readers and writers: topology walks,
 * number formatting that round-trips, text line splitting, and the two
 * assemblers every reader ends in (cylinders -> skeleton, graph -> skeleton). */
#ifndef SYLVA_QSM_INTERNAL_H
#define SYLVA_QSM_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/lines.h"
#include "stages/qsm/qsm.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ------------------------------------------------------------ topology */

/* Children of each node (CSR) and a breadth-first order from the root. */
typedef struct {
    int32_t *first; /* n+1: children of i are child[first[i] .. first[i+1]) */
    int32_t *child; /* n */
    int32_t *bfs;   /* n: root first, every parent before its children */
    int32_t root;
} sy_skel_topo;

/* s must have passed sy_skeleton_validate. */
sy_code sy_skel_topo_build(const sy_skeleton *s, sy_skel_topo *t, sy_error *err);
void sy_skel_topo_free(sy_skel_topo *t);
double sy_skel_edge_length(const sy_skeleton *s, int32_t i); /* parent[i] -> i, 0 at the root */
/* Orders and branch ids from the topology alone: at every node the child
 * heading the longest subtree continues the stem, the others start new
 * branches one order higher (AdTree's and TreeQSM's convention). */
sy_code sy_skel_derive_structure(sy_skeleton *s, sy_error *err);

/* ------------------------------------------------------------ numbers */

/* Shortest "%.Ng" text of v that reads back as the same float. */
void sy_fmt_float(char *buf, size_t size, float v);
/* Shortest text of a world coordinate w such that a reader subtracting
 * origin o and rounding to float gets (float)(w - o) back. */
void sy_fmt_coord(char *buf, size_t size, double w, double o);
/* Parses [b, e) as one finite or non-finite double; 0 on malformed text. */
int sy_qsm_parse_number(const char *b, const char *e, double *out);
/* floor() per axis: the origin readers pick when the file names none. */
void sy_origin_floor(const double world[3], double origin[3]);


/* ------------------------------------------------------------ assembly */

/* One cylinder as read from a table. */
typedef struct {
    long long id, parent_id; /* parent_id < 0: a root */
    double start[3], end[3]; /* world metres */
    float radius;
    int order;      /* -1: not in the file */
    int32_t branch; /* -1: not in the file */
    size_t line;
} sy_cyl;

/* Builds the skeleton: a cylinder ending at its child's start (within tol
 * metres) shares that node; a start that misses its parent's end gets a node
 * of its own hanging from the parent's start; a zero-length root cylinder is
 * the root node alone; several roots hang from the lowest one's start. */
sy_code sy_cylinders_to_skeleton(const char *path, const sy_cyl *c, size_t n, double tol,
                                 sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err);

/* Builds the skeleton from undirected edges (pairs of vertex indices):
 * root < 0 picks the lowest vertex; origin NULL picks floor(root); order and
 * branch NULL derive them. edge_line (may be NULL) names edges in messages,
 * else they are named by index. The root becomes node 0 (swapped with it). */
typedef struct {
    size_t n, m;
    const double *world; /* 3n */
    const float *radius; /* n */
    const int32_t *order, *branch; /* n or NULL */
    const uint32_t *edges;         /* 2m */
    const size_t *edge_line;       /* m or NULL */
    long root;
    const double *origin; /* 3 or NULL */
} sy_graph_in;

sy_code sy_graph_to_skeleton(const char *path, const sy_graph_in *g, sy_skeleton *out,
                             sy_skeleton_read_info *info, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
