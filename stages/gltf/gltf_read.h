/* The one glTF reader: what tests check in an exported .glb, what eval
 * scores and what the viewer draws. Two views of a file: its JSON and BIN
 * chunks with values at JSON pointers (sy_gltf_open), and its triangles in
 * Sylva's Z-up world frame (sy_gltf_read_triangles). Production export
 * (stages/export) writes glTF and never reads it back. */
#ifndef SYLVA_GLTF_READ_H
#define SYLVA_GLTF_READ_H

#include <stddef.h>

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A GLB's JSON chunk (parsed) and BIN chunk. */
typedef struct sy_gltf_file sy_gltf_file;
sy_code sy_gltf_open(const char *path, sy_gltf_file **out, sy_error *err);
void sy_gltf_close(sy_gltf_file *f);
/* Values at an RFC 6901 JSON pointer ("/materials/1/alphaMode"). */
int sy_gltf_has(const sy_gltf_file *f, const char *pointer);
double sy_gltf_number(const sy_gltf_file *f, const char *pointer, double fallback);
/* Copies the string into buf ("" when absent or not a string); returns buf. */
const char *sy_gltf_string(const sy_gltf_file *f, const char *pointer, char *buf, size_t size);
/* Length of the array or object at pointer, -1 when absent or a scalar. */
int sy_gltf_size(const sy_gltf_file *f, const char *pointer);
/* The index-th key of the object at pointer (in the JSON's key order), ""
 * when absent; returns buf. */
const char *sy_gltf_key(const sy_gltf_file *f, const char *pointer, int index, char *buf, size_t size);
/* The BIN chunk (buffer 0). */
const unsigned char *sy_gltf_bin(const sy_gltf_file *f, size_t *size);
/* SY_OK if tinygltf itself loads the file without errors or warnings, else
 * SY_EINPUT with tinygltf's complaint (files whose only buffer is the BIN
 * chunk; a meshopt fallback buffer has no data to load). */
sy_code sy_gltf_tinygltf_check(const char *path, sy_error *err);

/* Reads every triangle of the default scene (or of scene 0, or of all root
 * nodes when the file names no scene): node transforms and
 * EXT_mesh_gpu_instancing instance transforms applied, then glTF's Y-up
 * turned into Sylva's Z-up: (x, y, z) -> (x, -z, y), then moved by
 * asset.extras.origin [x, y, z] (Z-up world, as `sylva mesh` writes it)
 * when the file has one. *tri gets 9 doubles per
 * triangle (malloc'd); *hull one entry per triangle (malloc'd): 0, or k >= 1
 * when the triangle belongs to the k-th closed hull, a connected part of a
 * mesh named "foliage_proxy" (Sylva's cluster hulls, each closed and facing
 * outward; one hull per part and instance). SY_EINPUT (not a readable
 * glTF) or SY_EINTERNAL (out of memory) with a one-line message naming path. */
sy_code sy_gltf_read_triangles(const char *path, double **tri, size_t *n_tri, size_t **hull, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
