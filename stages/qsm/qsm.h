/* Skeleton and QSM interchange: the sy_skeleton noun in and out of the
 * formats peers use (docs/qsm-formats.md):
 *   .ply  AdTree / Easy3D skeleton graph (vertex x y z radius, edge
 *         vertex_indices), binary little endian; reads ASCII and binary
 *   .csv  one cylinder per row with the SimpleForest / rTwig column names
 *         (ID, parentID, startX .. endZ, radius, length, growthLength, ...)
 *   .txt  TreeQSM's cylinder text export (save_model_text.m), read only
 *   .obj  polyline skeleton (v / l) with per-vertex "# radius" comments
 *   .json Sylva's own skeleton JSON, and the truth layout of `sylva scan`
 *         (docs/truth-format.md: one tree of its "trees" array)
 *   .sylva Sylva's compact tree file (stages/encode): reads the skeleton
 *         and drops the cluster hulls, writes the skeleton alone
 * Writes are atomic. Reads choose the format by content (magic bytes, header
 * names), the extension breaking ties, and end with sy_skeleton_validate. */
#ifndef SYLVA_QSM_H
#define SYLVA_QSM_H

#include <stddef.h>
#include <stdio.h>

#include "stages/clusters/clusters.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/core/json_read.h"
#include "stages/core/skeleton.h"
#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    SY_SKEL_UNKNOWN = 0,
    SY_SKEL_PLY,
    SY_SKEL_CSV,         /* SimpleForest / rTwig cylinder table */
    SY_SKEL_TREEQSM_TXT, /* TreeQSM cylinder_*.txt / cyl_data_*.txt */
    SY_SKEL_OBJ,
    SY_SKEL_JSON,
    SY_SKEL_SYLVA
} sy_skel_format;

/* What a read found, for reports and `sylva info`. */
typedef struct {
    sy_skel_format format;
    size_t records;       /* cylinders (CSV, TXT) or vertices (PLY, OBJ) in the file */
    size_t input_roots;   /* cylinders without a parent in the file */
    int virtual_root;     /* several roots were joined under the lowest one */
    size_t gap_nodes;     /* cylinders whose start missed their parent's end and got a node */
    int origin_from_file; /* the file named the origin (a "sylva origin" comment) */
    int derived_structure; /* orders and branch ids were computed from the topology */
    int leaf_off;         /* a .sylva marked leaf-off (SY_SYLVA_LEAF_OFF): drawn without leaf cards */
} sy_skeleton_read_info;

const char *sy_skel_format_name(sy_skel_format f);

/* Format from the content (PLY magic, '{', cylinder header names, TreeQSM
 * header or a 15/17-column numeric first row, OBJ statements), the
 * extension of path breaking ties; SY_SKEL_UNKNOWN when nothing fits. */
sy_skel_format sy_skeleton_sniff(const char *path, const unsigned char *data, size_t size);

/* Writes by extension (.ply, .csv, .obj, .json, and .sylva without cluster
 * hulls); s must validate. */
sy_code sy_skeleton_write(const char *path, const sy_skeleton *s, sy_error *err);
/* Reads any supported format into out (initialised here, owned by the
 * caller; left empty on failure). info may be NULL. */
sy_code sy_skeleton_read(const char *path, sy_skeleton *out, sy_error *err);
sy_code sy_skeleton_read_ex(const char *path, sy_skeleton *out, sy_skeleton_read_info *info,
                            sy_error *err);
/* As sy_skeleton_read_ex; tree picks one entry of a truth file's "trees"
 * (0-based). tree -1 takes the file's only tree and fails, naming the count,
 * when a truth file holds several; other formats hold one tree (0 or -1). */
sy_code sy_skeleton_read_tree(const char *path, long tree, sy_skeleton *out, sy_skeleton_read_info *info,
                              sy_error *err);
/* As sy_skeleton_read_tree, and hulls (may be NULL) receives what else the
 * file holds: the cluster hulls of a .sylva file (same frame as out), none
 * for the skeleton-only formats. Owned by the caller (sy_clusters_free). */
sy_code sy_skeleton_read_model(const char *path, long tree, sy_skeleton *out, sy_clusters *hulls,
                               sy_skeleton_read_info *info, sy_error *err);
/* As sy_skeleton_read_model, from the file's bytes already read (a pipe
 * reads once). */
sy_code sy_skeleton_read_model_mem(const char *path, const unsigned char *data, size_t size, long tree,
                                   sy_skeleton *out, sy_clusters *hulls, sy_skeleton_read_info *info, sy_error *err);

/* The individual writers and in-memory readers (path names the file in
 * messages); the readers are what fuzz targets drive. */
sy_code sy_skeleton_write_ply(const char *path, const sy_skeleton *s, sy_error *err);
sy_code sy_skeleton_write_csv(const char *path, const sy_skeleton *s, sy_error *err);
sy_code sy_skeleton_write_obj(const char *path, const sy_skeleton *s, sy_error *err);
sy_code sy_skeleton_write_json(const char *path, const sy_skeleton *s, sy_error *err);
/* The "origin" and "nodes" members of the skeleton JSON into an open object
 * of j (which writes to fp), for documents that carry more (.sylva as JSON). */
void sy_skeleton_json_members(sy_json *j, FILE *fp, const sy_skeleton *s);
/* Validates s, opens path atomically and starts the document's object with
 * "format" and "version": 1 (the caller adds members, ends, commits). */
sy_code sy_skeleton_json_open(const char *path, const sy_skeleton *s, const char *format, sy_atomic_file *f,
                              sy_json *j, sy_error *err);

sy_code sy_skeleton_read_ply_mem(const char *path, const unsigned char *data, size_t size,
                                 sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err);
sy_code sy_skeleton_read_csv_mem(const char *path, const unsigned char *data, size_t size,
                                 sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err);
sy_code sy_skeleton_read_treeqsm_mem(const char *path, const unsigned char *data, size_t size,
                                     sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err);
sy_code sy_skeleton_read_obj_mem(const char *path, const unsigned char *data, size_t size,
                                 sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err);
sy_code sy_skeleton_read_json_mem(const char *path, const unsigned char *data, size_t size,
                                  sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err);
sy_code sy_skeleton_read_json_tree(const char *path, const unsigned char *data, size_t size, long tree,
                                   sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err);
sy_code sy_skeleton_read_sylva_mem(const char *path, const unsigned char *data, size_t size,
                                   sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err);

/* JSON skeletons from a parsed document (stages/core/json_read.h), for
 * readers that hold the DOM already (eval's truth files). from_json takes a
 * skeleton or truth document (tree as in sy_skeleton_read_tree);
 * from_json_nodes one "nodes" array of world-coordinate nodes, where naming
 * the part in messages ("tree 2"); origin NULL picks floor() of the root.
 * Messages read "path:line:col: where: problem". */
sy_code sy_skeleton_from_json(const char *path, const sy_jv *doc, long tree, sy_skeleton *out,
                              sy_skeleton_read_info *info, sy_error *err);
sy_code sy_skeleton_from_json_nodes(const char *path, const char *where, const sy_jv *nodes, const double *origin,
                                    sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err);

/* Per-node cylinder attributes as the CSV writer defines them (index i
 * describes the edge parent[i] -> i; the root's entry describes the whole
 * tree): growth length = this edge plus every edge below it (rTwig /
 * SimpleForest), reverse branch order = 1 at a tip, +1 at each fork passed
 * on the way down to the farthest tip (rTwig's segment definition).
 * Arrays hold s->n entries. */
sy_code sy_skeleton_growth_length(const sy_skeleton *s, double *growth, sy_error *err);
sy_code sy_skeleton_reverse_order(const sy_skeleton *s, int32_t *rbo, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
