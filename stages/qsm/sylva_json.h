/* A .sylva file as JSON ("format": "sylva-tree"): everything the binary file
 * holds, readable and editable, for `sylva decode -o tree.json` and
 * `sylva encode tree.json -o tree.sylva` (docs/sylva-format.md).
 *
 * The document is Sylva's skeleton JSON (origin, nodes in world coordinates;
 * any skeleton reader takes it) plus species_id, seed, the quantisation grid
 * and the cluster hulls (vertices in world coordinates, triangles, kind,
 * alpha). Numbers are printed so they read back to the same float, and the
 * grid is kept, so decode -> JSON -> encode reproduces the .sylva file byte
 * for byte. */
#ifndef SYLVA_SYLVA_JSON_H
#define SYLVA_SYLVA_JSON_H

#include "stages/core/json_read.h"
#include "stages/encode/encode.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Writes the document atomically; s must validate. */
sy_code sy_sylva_json_write(const char *path, const sy_skeleton *s, const sy_clusters *cl, const sy_sylva_meta *meta,
                            sy_error *err);

/* Reads a "sylva-tree" document already parsed (doc); path names it in
 * messages. *has_quant says whether the file named its grid (meta->quant
 * is valid only then). Outputs are left empty on failure. */
sy_code sy_sylva_json_from_doc(const char *path, const sy_jv *doc, sy_skeleton *s, sy_clusters *cl,
                               sy_sylva_meta *meta, int *has_quant, sy_error *err);

/* The .sylva image of s, cl and meta (its grid when has_quant, its flags),
 * *bytes malloc'd: what `sylva encode` writes. An input error names path. */
sy_code sy_sylva_encode_meta(const sy_skeleton *s, const sy_clusters *cl, const sy_sylva_meta *meta, int has_quant,
                             const char *path, unsigned char **bytes, size_t *size, sy_error *err);

/* The .sylva image a "sylva-tree" document encodes to (byte for byte the
 * file `sylva decode -o` read it from), *bytes malloc'd. */
sy_code sy_sylva_json_encode(const char *path, const sy_jv *doc, unsigned char **bytes, size_t *size, sy_error *err);

/* 1 when doc is a JSON object whose "format" is "sylva-tree". */
int sy_sylva_json_is_tree(const sy_jv *doc);

#ifdef __cplusplus
}
#endif

#endif
