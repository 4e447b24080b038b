/* Loading the MODEL argument of `sylva eval`: the one place that knows the
 * model kinds (glTF triangles, truth JSON, .sylva reconstructions, any skeleton
 * file qsm_io reads). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "eval.h"
#include "stages/gltf/gltf_read.h"
#include "stages/core/fileio.h"
#include "stages/encode/encode.h"

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

/* The glb's surfaces as one mesh (closed when the caller says so) and each
 * foliage-proxy hull as a closed mesh of its own, as load_sylva does for the
 * same hulls: a .sylva and the glb made from it score alike. */
static sy_code load_gltf(const char *path, int closed, sy_eval_model *out, sy_error *err)
{
    double *tri;
    size_t n, *hull;

    sy_code rc = sy_gltf_read_triangles(path, &tri, &n, &hull, err);
    if (rc) return rc;
    sy_code code = SY_OK;
    size_t n_groups = 1;
    for (size_t t = 0; t < n; t++) n_groups = hull[t] + 1 > n_groups ? hull[t] + 1 : n_groups;
    /* Triangles sorted by group (counting sort): group g is [first[g], first[g + 1]). */
    size_t *first = sy_calloc(n_groups + 1, sizeof *first, err, "model triangles");
    double *sorted = sy_calloc(n ? 9 * n : 1, sizeof *sorted, err, "model triangles");
    if (!n) code = sy_fail(err, SY_EINPUT, "%s: no triangles in the default scene", path);
    else if (!first || !sorted) code = SY_EINTERNAL;
    if (!code) {
        for (size_t t = 0; t < n; t++) first[hull[t] + 1]++;
        for (size_t g = 0; g < n_groups; g++) first[g + 1] += first[g];
        for (size_t t = 0; t < n; t++) memcpy(sorted + 9 * first[hull[t]]++, tri + 9 * t, 9 * sizeof *tri);
        for (size_t g = n_groups; g > 0; g--) first[g] = first[g - 1];
        first[0] = 0;
        for (size_t g = 0; g < n_groups && !code; g++)
            if (first[g + 1] > first[g] || g == 0)
                code = sy_eval_model_add_mesh(out, sorted + 9 * first[g], first[g + 1] - first[g], g ? 1 : closed,
                                              err);
    }
    free(first);
    free(sorted);
    free(tri);
    free(hull);
    if (code) sy_eval_model_free(out);
    return code;
}

/* One cluster hull as a closed mesh in world coordinates. */
static sy_code add_hull(sy_eval_model *m, const sy_cluster *h, const double origin[3], sy_error *err)
{
    double *tri = sy_calloc(9 * h->n_tris, sizeof *tri, err, "hull triangles");
    if (!tri) return SY_EINTERNAL;
    for (size_t t = 0; t < h->n_tris; t++)
        for (int k = 0; k < 3; k++)
            for (int a = 0; a < 3; a++)
                tri[9 * t + 3 * k + a] = origin[a] + h->verts[3 * (size_t)h->tris[3 * t + k] + a];
    sy_code rc = sy_eval_model_add_mesh(m, tri, h->n_tris, 1, err);
    free(tri);
    return rc;
}

/* A .sylva file: its skeleton as a skeleton model (cones) and every cluster
 * hull as a closed mesh, so points inside a hull are at distance 0. */
static sy_code load_sylva(const char *path, sy_eval_model *out, sy_error *err)
{
    sy_eval_tree t;
    memset(&t, 0, sizeof t);
    sy_clusters cl;
    sy_sylva_meta meta;
    sy_code rc = sy_decode_read(path, &t.skel, &cl, &meta, err);
    if (rc) return rc;
    t.tree_id = -1;
    t.species_id = meta.species_id ? (int)meta.species_id - 1 : -1;
    for (int a = 0; a < 3; a++) t.position[a] = t.skel.origin[a] + (t.skel.n ? t.skel.pos[a] : 0);
    t.dbh = sy_skeleton_dbh(&t.skel);
    /* The model's height is its highest part: crowns end in hulls. */
    t.height = sy_skeleton_height(&t.skel);
    double root_z = t.skel.n ? t.skel.pos[2] : 0;
    for (size_t c = 0; c < cl.n; c++)
        for (size_t i = 0; i < cl.items[c].n_verts; i++)
            t.height = fmax(t.height, cl.items[c].verts[3 * i + 2] - root_z);
    t.crown_width = NAN;
    double origin[3] = {t.skel.origin[0], t.skel.origin[1], t.skel.origin[2]};
    if ((rc = sy_forest_add(&out->skeletons, &t, err))) sy_skeleton_free(&t.skel);
    for (size_t c = 0; c < cl.n && !rc; c++)
        if (cl.items[c].n_tris) rc = add_hull(out, &cl.items[c], origin, err);
    sy_clusters_free(&cl);
    if (rc) sy_eval_model_free(out);
    return rc;
}

sy_code sy_eval_load_model(const char *path, int closed, sy_eval_model *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    char ext[16];
    sy_extension(path, ext, sizeof ext);
    if (strcmp(ext, "glb") == 0 || strcmp(ext, "gltf") == 0) return load_gltf(path, closed, out, err);
    if (strcmp(ext, "sylva") == 0) return load_sylva(path, out, err);
    static const char *skeleton_exts[] = {"json", "ply", "csv", "txt", "obj"};
    for (size_t i = 0; i < sizeof skeleton_exts / sizeof skeleton_exts[0]; i++)
        if (strcmp(ext, skeleton_exts[i]) == 0) return sy_forest_read(path, &out->skeletons, err);
    return sy_fail(err, SY_EINPUT,
                   "%s: unknown model kind '.%s' (expected .glb, .gltf, .sylva, a truth JSON or a skeleton file: "
                   ".json .ply .csv .txt .obj)",
                   path, ext);
}
