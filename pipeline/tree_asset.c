#include "pipeline/tree_asset.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "species/materials.h"
#include "stages/core/json.h"
#include "stages/core/progress.h"
#include "stages/export/export.h"
#include "stages/mesh/mesh.h"

sy_tree_asset_options sy_tree_asset_options_default(void)
{
    sy_tree_asset_options o;
    memset(&o, 0, sizeof o);
    o.lods = 4;
    o.impostor = 1;
    o.impostor_size = 512;
    o.instancing = 1;
    o.texture_size = 512;
    o.seed = 1;
    return o;
}

/* asset.extras: which species and parameters made the tree. */
static char *species_extras(const sy_species *sp)
{
    char *buf = NULL;
    size_t len = 0;
    FILE *fp = open_memstream(&buf, &len);
    if (!fp) return NULL;
    sy_json j;
    sy_json_begin(&j, fp, 0);
    sy_json_object(&j, NULL);
    sy_json_string(&j, "generator", "sylva");
    if (sp) {
        sy_json_string(&j, "species", sp->name ? sp->name : "");
        sy_json_object(&j, "parameters");
        sy_json_int(&j, "shape", sp->shape);
        sy_json_number(&j, "scale", sp->scale);
        sy_json_int(&j, "levels", sp->levels);
        sy_json_number(&j, "base_size", sp->base_size);
        sy_json_number(&j, "ratio", sp->ratio);
        sy_json_number(&j, "leaves", sp->leaves);
        sy_json_number(&j, "leaf_scale", sp->leaf_scale);
        sy_json_number(&j, "leaf_scale_x", sp->leaf_scale_x);
        sy_json_number(&j, "beta", sp->beta);
        sy_json_number(&j, "gamma", sp->gamma);
        sy_json_end(&j);
    }
    sy_json_end(&j);
    fclose(fp);
    return buf;
}

sy_code sy_tree_asset_build(const sy_skeleton *skel, const sy_leaves *leaves, const sy_species *species,
                            const sy_tree_asset_options *opt, sy_asset *out, sy_tree_asset_report *rep,
                            sy_error *err)
{
    memset(out, 0, sizeof *out);
    double t0 = sy_now();
    sy_material_spec ms = {species ? species->bark_texture : NULL, species ? species->leaf_texture : NULL,
                           species ? species->leaf_translucency : -1.0f, opt->texture_size};
    int bark = -1, leaf = -1;
    sy_code rc = sy_species_materials(&ms, out, &bark, &leaf, err);
    if (rc) goto fail;
    sy_mesh_options mo = sy_mesh_options_default();
    mo.n_lods = opt->lods;
    mo.impostor = opt->impostor;
    mo.impostor_size = opt->impostor_size;
    mo.seed = opt->seed;
    mo.bark_material = bark;
    mo.leaf_material = leaf;
    if (species) {
        mo.leaf_aspect = species->leaf_scale_x;
        mo.leaf_shape = species->leaf_shape;
    }
    if ((rc = sy_mesh_tree(skel, leaves, &mo, out, err))) goto fail;
    snprintf(out->name, sizeof out->name, "%s", species && species->name ? species->name : "tree");
    if (!(out->extras_json = species_extras(species))) {
        rc = sy_fail(err, SY_EINTERNAL, "asset extras: out of memory");
        goto fail;
    }
    if (rep) {
        memset(rep, 0, sizeof *rep);
        rep->nodes = skel->n;
        rep->branches = (size_t)sy_skeleton_branch_count(skel);
        rep->leaves = leaves ? leaves->n : 0;
        rep->lods = out->n_lods;
        for (size_t l = 0; l < out->n_lods && l < 16; l++) {
            const sy_lod *lod = &out->lods[l];
            for (int k = 0; k < lod->n_meshes; k++) rep->triangles[l] += out->meshes[lod->meshes[k]].n_indices / 3;
            for (int k = 0; k < lod->n_instances; k++) {
                const sy_instances *in = &lod->instances[k];
                rep->leaf_cards[l] += in->n;
                rep->triangles[l] += in->n * (out->meshes[in->mesh].n_indices / 3);
            }
        }
        rep->seconds_mesh = sy_now() - t0;
    }
    return SY_OK;
fail:
    sy_asset_free(out);
    return rc;
}

sy_code sy_tree_asset_write(const char *path, const sy_skeleton *skel, const sy_leaves *leaves,
                            const sy_species *species, const sy_tree_asset_options *opt, sy_tree_asset_report *rep,
                            sy_error *err)
{
    sy_asset asset;
    sy_code rc = sy_tree_asset_build(skel, leaves, species, opt, &asset, rep, err);
    if (rc) return rc;
    double t0 = sy_now();
    sy_export_options eo = sy_export_options_default();
    eo.meshopt = opt->meshopt;
    eo.instancing = opt->instancing;
    rc = sy_export_glb(path, &asset, &eo, err);
    if (rep && rc == SY_OK) {
        rep->seconds_export = sy_now() - t0;
        rep->bytes = sy_export_last_size(path);
    }
    sy_asset_free(&asset);
    return rc;
}

void sy_tree_asset_report_text(const sy_tree_asset_report *rep, const char *path)
{
    fprintf(stderr, "wrote %s: %zu bytes, %zu nodes, %zu branches, %zu leaves\n", path, rep->bytes, rep->nodes,
            rep->branches, rep->leaves);
    for (size_t l = 0; l < rep->lods && l < 16; l++)
        fprintf(stderr, "  LOD%zu: %zu triangles (%zu leaf cards)\n", l, rep->triangles[l], rep->leaf_cards[l]);
    fprintf(stderr, "  mesh %.3f s, export %.3f s\n", rep->seconds_mesh, rep->seconds_export);
}
