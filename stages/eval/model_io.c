/* Loading the MODEL argument of `sylva eval`: the one place that knows the
 * model kinds (glTF triangles, truth JSON, any skeleton file qsm_io reads). */
#include <stdlib.h>
#include <string.h>

#include "eval.h"
#include "gltf_read_tinygltf.h"
#include "stages/core/fileio.h"

void sy_eval_model_free(sy_eval_model *m)
{
    for (size_t i = 0; i < m->n_meshes; i++) free(m->meshes[i].tri);
    free(m->meshes);
    sy_forest_free(&m->skeletons);
    memset(m, 0, sizeof *m);
}

sy_code sy_eval_model_add_mesh(sy_eval_model *m, const double *tri, size_t n, int closed, sy_error *err)
{
    sy_tri_mesh *grown = realloc(m->meshes, (m->n_meshes + 1) * sizeof *grown);
    if (!grown) return sy_fail(err, SY_EINTERNAL, "model: out of memory");
    m->meshes = grown;
    double *copy = sy_calloc(n ? 9 * n : 1, sizeof *copy, err, "model triangles");
    if (!copy) return SY_EINTERNAL;
    if (n) memcpy(copy, tri, 9 * n * sizeof *copy);
    m->meshes[m->n_meshes++] = (sy_tri_mesh){n, copy, closed};
    return SY_OK;
}

static sy_code load_gltf(const char *path, int closed, sy_eval_model *out, sy_error *err)
{
    double *tri;
    size_t n;
    char msg[900];
    int rc = sy_gltf_read_triangles(path, &tri, &n, msg, sizeof msg);
    if (rc) return sy_fail(err, rc == 3 ? SY_EINTERNAL : SY_EINPUT, "%s", msg);
    if (!n) {
        free(tri);
        return sy_fail(err, SY_EINPUT, "%s: no triangles in the default scene", path);
    }
    sy_tri_mesh *one = malloc(sizeof *one);
    if (!one) {
        free(tri);
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    }
    *one = (sy_tri_mesh){n, tri, closed};
    out->meshes = one;
    out->n_meshes = 1;
    return SY_OK;
}

sy_code sy_eval_load_model(const char *path, int closed, sy_eval_model *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    char ext[16];
    sy_extension(path, ext, sizeof ext);
    if (strcmp(ext, "glb") == 0 || strcmp(ext, "gltf") == 0) return load_gltf(path, closed, out, err);
    static const char *skeleton_exts[] = {"json", "ply", "csv", "txt", "obj", "sylva"};
    for (size_t i = 0; i < sizeof skeleton_exts / sizeof skeleton_exts[0]; i++)
        if (strcmp(ext, skeleton_exts[i]) == 0) return sy_forest_read(path, &out->skeletons, err);
    return sy_fail(err, SY_EINPUT,
                   "%s: unknown model kind '.%s' (expected .glb, .gltf, a truth JSON or a skeleton file: .json .ply "
                   ".csv .txt .obj .sylva)",
                   path, ext);
}
