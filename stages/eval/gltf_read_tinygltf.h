/* Triangles of a glTF/GLB file through tinygltf, for evaluation. */
#ifndef SYLVA_GLTF_READ_TINYGLTF_H
#define SYLVA_GLTF_READ_TINYGLTF_H

#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Reads every triangle of the default scene (or of scene 0, or of all root
 * nodes when the file names no scene): node transforms and
 * EXT_mesh_gpu_instancing instance transforms applied, then glTF's Y-up
 * turned into Sylva's Z-up: (x, y, z) -> (x, -z, y), then moved by
 * asset.extras.origin [x, y, z] (Z-up world, as `sylva mesh` writes it)
 * when the file has one. *tri gets 9 doubles per
 * triangle (malloc'd); *hull one entry per triangle (malloc'd): 0, or k >= 1
 * when the triangle belongs to the k-th closed hull, a connected part of a
 * mesh named "foliage_proxy" (Sylva's cluster hulls, each closed and facing
 * outward; one hull per part and instance). Returns 0 on success; otherwise
 * 2 (bad input) or 3 (out of memory) with a one-line reason in msg. */
int sy_gltf_read_triangles(const char *path, double **tri, size_t *n_tri, size_t **hull, char *msg,
                           size_t msg_size);

#ifdef __cplusplus
}
#endif

#endif
