#include "pipeline/tree_asset.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "species/materials.h"
#include "stages/core/fileio.h"
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

sy_code sy_tree_asset_options_check(const sy_tree_asset_options *o, sy_error *err)
{
    sy_mesh_options mo = sy_mesh_options_default();
    mo.n_lods = o->lods;
    mo.impostor = o->impostor;
    mo.impostor_size = o->impostor_size;
    sy_code rc = sy_mesh_options_check(&mo, err);
    if (rc) return rc;
    sy_export_options eo = sy_export_options_default();
    eo.meshopt = o->meshopt;
    eo.instancing = o->instancing;
    if ((rc = sy_export_options_check(&eo, err))) return rc;
    if (o->texture_size < 1 || o->texture_size > 8192)
        return sy_fail(err, SY_EUSAGE, "tree asset: texture_size %d outside [1, 8192]", o->texture_size);
    return SY_OK;
}

sy_glb_args sy_glb_args_default(void)
{
    sy_tree_asset_options d = sy_tree_asset_options_default();
    sy_glb_args g = {d.lods, d.impostor_size, d.meshopt, !d.instancing, !d.impostor, d.check, ""};
    const char *dir = getenv("SYLVA_CACHE_DIR"), *xdg = getenv("XDG_CACHE_HOME"), *home = getenv("HOME");
    if (dir) snprintf(g.texture_cache, sizeof g.texture_cache, "%s", dir);
    else if (xdg && xdg[0] == '/') snprintf(g.texture_cache, sizeof g.texture_cache, "%s/sylva", xdg);
    else if (home && home[0] == '/') snprintf(g.texture_cache, sizeof g.texture_cache, "%s/.cache/sylva", home);
    return g;
}

void sy_glb_args_apply(const sy_glb_args *g, sy_tree_asset_options *o)
{
    o->lods = g->lods;
    o->impostor = !g->no_impostor;
    o->impostor_size = g->impostor_size;
    o->meshopt = g->meshopt;
    o->instancing = !g->no_instancing;
    o->check = g->check;
    o->texture_cache = g->texture_cache[0] ? g->texture_cache : NULL;
}

void sy_tree_asset_report_lods_json(sy_json *j, const sy_tree_asset_report *rep)
{
    sy_json_array(j, "lod_triangles");
    for (size_t l = 0; l < rep->lods && l < 16; l++) sy_json_int(j, NULL, (long long)rep->triangles[l]);
    sy_json_end(j);
    if (!rep->checked) return;
    sy_json_array(j, "mesh_check");
    for (size_t l = 0; l < rep->check.n_levels; l++) {
        const sy_mesh_check_level *c = &rep->check.level[l];
        sy_json_object(j, NULL);
        sy_json_int(j, "lod", (long long)c->lod);
        sy_json_int(j, "triangles", (long long)c->triangles);
        sy_json_int(j, "bark_triangles", (long long)c->bark_triangles);
        sy_json_number(j, "ratio", c->ratio);
        sy_json_number(j, "silhouette_iou", c->silhouette_iou);
        sy_json_int(j, "sails", (long long)c->sails);
        sy_json_number(j, "max_off_surface", c->max_off_surface);
        sy_json_number(j, "max_across", c->max_across);
        sy_json_number(j, "max_edge_radii", c->max_edge_radii);
        sy_json_number(j, "max_edge", c->max_edge);
        sy_json_int(j, "degenerate", (long long)c->degenerate);
        sy_json_int(j, "slivers", (long long)c->slivers);
        sy_json_int(j, "collapsed", (long long)c->collapsed);
        sy_json_int(j, "boundary_edges", (long long)c->boundary_edges);
        sy_json_int(j, "nonmanifold_edges", (long long)c->nonmanifold_edges);
        sy_json_int(j, "misoriented_edges", (long long)c->misoriented_edges);
        sy_json_int(j, "components", (long long)c->components);
        if (c->lod < rep->welds.levels) {
            sy_json_int(j, "junctions", (long long)rep->welds.junctions[c->lod]);
            sy_json_int(j, "welded", (long long)rep->welds.welded[c->lod]);
        }
        sy_json_int(j, "below_ground", (long long)c->below_ground);
        sy_json_int(j, "leaves", (long long)c->leaves);
        sy_json_int(j, "leaves_far", (long long)c->leaves_far);
        sy_json_int(j, "leaves_below_ground", (long long)c->leaves_below_ground);
        sy_json_number(j, "max_leaf_gap", c->max_leaf_gap);
        sy_json_number(j, "mean_leaf_gap", c->mean_leaf_gap);
        sy_json_number(j, "bark_top", c->bark_top);
        sy_json_number(j, "leaf_top", c->leaf_top);
        sy_json_end(j);
    }
    sy_json_end(j);
}

void sy_tree_asset_root_to_origin(sy_skeleton *s, sy_clusters *hulls)
{
    double root[3];
    for (int k = 0; k < 3; k++) root[k] = s->origin[k] + (double)(s->n ? s->pos[k] : 0);
    /* In double through the world position: origin and root can be survey-sized. */
    for (size_t i = 0; i < s->n; i++)
        for (int k = 0; k < 3; k++) s->pos[3 * i + k] = (float)((s->origin[k] + (double)s->pos[3 * i + k]) - root[k]);
    for (size_t c = 0; hulls && c < hulls->n; c++) {
        sy_cluster *h = &hulls->items[c];
        for (size_t i = 0; i < h->n_verts; i++)
            for (int k = 0; k < 3; k++)
                h->verts[3 * i + k] = (float)((s->origin[k] + (double)h->verts[3 * i + k]) - root[k]);
        for (size_t i = 0; i < h->n_twigs; i++)
            for (int k = 0; k < 3; k++)
                h->twig_pos[3 * i + k] = (float)((s->origin[k] + (double)h->twig_pos[3 * i + k]) - root[k]);
    }
    memcpy(s->origin, root, sizeof root);
}

/* asset.extras: which species, every one of its parameters and the seed
 * (enough to grow the same tree again), and where a model from a file stands
 * in the world (docs/gltf.md). */
static char *asset_extras(const sy_species_params *sp, const sy_skeleton *skel, const sy_tree_asset_options *opt)
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
        sy_json_uint(&j, "seed", (unsigned long long)opt->seed);
        sy_json_object(&j, "parameters");
        sy_species_params_write_json(sp, &j);
        sy_json_end(&j);
    }
    if (opt->source) {
        sy_json_numbers(&j, "origin", skel->origin, 3);
        const char *slash = strrchr(opt->source, '/');
        sy_json_string(&j, "source", slash ? slash + 1 : opt->source);
        sy_json_string(&j, "source_format", opt->source_format ? opt->source_format : "");
    }
    sy_json_end(&j);
    fclose(fp);
    return buf;
}

/* One mesh of all hull triangles, turned to glTF's Y-up frame like the
 * mesher does: (x, y, z) -> (x, z, -y), a proper rotation, so the hulls'
 * outward winding stays counter-clockwise. Normals: area-weighted vertex
 * normals (the hulls are coarse blobs; smooth shading reads as foliage). */
static sy_code hull_mesh(const sy_clusters *cl, int material, sy_mesh *m, sy_error *err)
{
    memset(m, 0, sizeof *m);
    size_t nv = 0, nt = 0;
    for (size_t c = 0; c < cl->n; c++)
        if (cl->items[c].n_tris) {
            nv += cl->items[c].n_verts;
            nt += cl->items[c].n_tris;
        }
    if (nv > UINT32_MAX) return sy_fail(err, SY_EINTERNAL, "foliage proxy: %zu hull vertices are too many", nv);
    snprintf(m->name, sizeof m->name, "foliage_proxy");
    m->material = material;
    m->n_vertices = nv;
    m->n_indices = 3 * nt;
    m->position = sy_calloc(3 * nv, sizeof *m->position, err, "foliage proxy");
    m->normal = sy_calloc(3 * nv, sizeof *m->normal, err, "foliage proxy");
    m->indices = sy_calloc(3 * nt, sizeof *m->indices, err, "foliage proxy");
    if (!m->position || !m->normal || !m->indices) {
        sy_mesh_free(m);
        return SY_EINTERNAL;
    }
    size_t v0 = 0, t0 = 0;
    for (size_t c = 0; c < cl->n; c++) {
        const sy_cluster *h = &cl->items[c];
        if (!h->n_tris) continue;
        for (size_t i = 0; i < h->n_verts; i++) {
            const float *p = h->verts + 3 * i;
            float *q = m->position + 3 * (v0 + i);
            q[0] = p[0], q[1] = p[2], q[2] = -p[1];
        }
        for (size_t t = 0; t < 3 * h->n_tris; t++) m->indices[3 * t0 + t] = (uint32_t)(v0 + h->tris[t]);
        v0 += h->n_verts;
        t0 += h->n_tris;
    }
    for (size_t t = 0; t < nt; t++) {
        const uint32_t *f = m->indices + 3 * t;
        const float *a = m->position + 3 * f[0], *b = m->position + 3 * f[1], *c = m->position + 3 * f[2];
        float e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        float n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; k++)
            for (int d = 0; d < 3; d++) m->normal[3 * f[k] + d] += n[d]; /* |n| = 2 x area */
    }
    for (size_t i = 0; i < nv; i++) {
        float *n = m->normal + 3 * i;
        float len = sqrtf(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (len > 1e-20f && isfinite(len)) n[0] /= len, n[1] /= len, n[2] /= len;
        else n[0] = 0, n[1] = 1, n[2] = 0; /* a vertex of degenerate triangles only */
    }
    return SY_OK;
}

/* Adds the foliage proxy (material + mesh) to every mesh level of out. */
static sy_code add_foliage_proxy(const sy_clusters *cl, sy_asset *out, size_t *n_tris, sy_error *err)
{
    sy_material mat = sy_material_default("foliage_proxy");
    const float green[4] = {0.28f, 0.45f, 0.18f, 0.5f};
    memcpy(mat.base_color, green, sizeof green);
    mat.roughness = 0.9f;
    mat.alpha_mode = SY_ALPHA_BLEND;
    mat.double_sided = 1;
    int mi = sy_asset_add_material(out, &mat, err);
    if (mi < 0) return SY_EINTERNAL;
    sy_mesh m;
    sy_code rc = hull_mesh(cl, mi, &m, err);
    if (rc) return rc;
    *n_tris = m.n_indices / 3;
    int idx = sy_asset_add_mesh(out, &m, err);
    if (idx < 0) {
        sy_mesh_free(&m);
        return SY_EINTERNAL;
    }
    /* The same mesh serves every level: the hulls are already coarse. */
    for (size_t l = 0; l < out->n_lods; l++) {
        sy_lod *lod = &out->lods[l];
        if (lod->n_meshes >= SY_LOD_MAX_PARTS)
            return sy_fail(err, SY_EINTERNAL, "foliage proxy: LOD%zu has no room for another part", l);
        lod->meshes[lod->n_meshes++] = idx;
    }
    return SY_OK;
}

static int has_hull_triangles(const sy_clusters *cl)
{
    for (size_t c = 0; cl && c < cl->n; c++)
        if (cl->items[c].n_tris) return 1;
    return 0;
}

sy_code sy_tree_asset_build(const sy_skeleton *skel, const sy_leaves *leaves, const sy_species_params *species,
                            const sy_tree_asset_options *opt, sy_asset *out, sy_tree_asset_report *rep,
                            sy_error *err)
{
    memset(out, 0, sizeof *out);
    double t0 = sy_now();
    sy_material_spec ms = {species ? species->bark_texture : NULL, species ? species->leaf_texture : NULL,
                           species ? species->leaf_translucency : -1.0f, opt->texture_size, NULL, 0,
                           opt->texture_cache, NULL};
    char leaf_maps[4096];
    if (species) {
        if (species->bark_color[0] >= 0) ms.bark_color = species->bark_color;
        /* A species' leaf maps from `sylva leaf`, when the library has them. */
        ms.leaf_maps = sy_species_leaf_maps(species->name, leaf_maps, sizeof leaf_maps);
        ms.leaf_length_m = species->leaf_scale > 0 ? species->leaf_scale : 0.1f;
    }
    int bark = -1, leaf = -1;
    sy_code rc = sy_materials_add(&ms, out, &bark, &leaf, err);
    if (rc) goto fail;
    sy_mesh_options mo = sy_mesh_options_default();
    mo.n_lods = opt->lods;
    int hulls = has_hull_triangles(opt->hulls);
    /* With hulls the impostor is made after they join the mesh levels. */
    mo.impostor = opt->impostor && !hulls;
    mo.impostor_size = opt->impostor_size;
    mo.lean_radius = opt->lean_radius;
    mo.seed = opt->seed;
    mo.keep_leaf_order = opt->keep_leaf_order;
    mo.bark_material = bark;
    mo.leaf_material = leaf;
    if (species) {
        mo.leaf_aspect = species->leaf_scale_x;
        mo.leaf_shape = species->leaf_shape;
    }
    sy_mesh_weld_stats welds;
    mo.weld_stats = &welds;
    if ((rc = sy_mesh_tree(skel, leaves, &mo, out, err))) goto fail;
    size_t hull_tris = 0;
    if (hulls) {
        if ((rc = add_foliage_proxy(opt->hulls, out, &hull_tris, err))) goto fail;
        if (opt->impostor && (rc = sy_mesh_add_impostor(out, 0, opt->impostor_size, err))) goto fail;
    }
    snprintf(out->name, sizeof out->name, "%s", species && species->name ? species->name : "tree");
    if (!(out->extras_json = asset_extras(species, skel, opt))) {
        rc = sy_fail(err, SY_EINTERNAL, "asset extras: out of memory");
        goto fail;
    }
    if (rep) {
        memset(rep, 0, sizeof *rep);
        rep->welds = welds;
        rep->nodes = skel->n;
        rep->branches = (size_t)sy_skeleton_branch_count(skel);
        rep->leaves = leaves ? leaves->n : 0;
        rep->lods = out->n_lods;
        rep->hull_triangles = hull_tris;
        for (size_t l = 0; l < out->n_lods && l < 16; l++) {
            const sy_lod *lod = &out->lods[l];
            for (int k = 0; k < lod->n_meshes; k++) rep->triangles[l] += out->meshes[lod->meshes[k]].n_indices / 3;
            rep->bark_triangles[l] = rep->triangles[l];
            for (int k = 0; k < lod->n_instances; k++) {
                const sy_instances *in = &lod->instances[k];
                rep->leaf_cards[l] += in->n;
                rep->triangles[l] += in->n * (out->meshes[in->mesh].n_indices / 3);
            }
        }
        rep->seconds_mesh = sy_now() - t0;
        if (opt->check) {
            sy_mesh_check_options co = sy_mesh_check_options_default();
            co.min_radius = mo.min_radius;
            for (size_t i = 0; i < skel->n; i++)
                if (skel->parent[i] < 0) {
                    /* The trunk's base disc tilts with a leaning trunk. */
                    co.ground = skel->pos[3 * i + 2] - fmax(skel->radius[i], mo.min_radius);
                    break;
                }
            if ((rc = sy_mesh_check(out, skel, &co, &rep->check, err))) goto fail;
            rep->checked = 1;
        }
    }
    return SY_OK;
fail:
    sy_asset_free(out);
    return rc;
}

sy_code sy_tree_asset_glb(const sy_skeleton *skel, const sy_leaves *leaves, const sy_species_params *species,
                          const sy_tree_asset_options *opt, const char *name, unsigned char **glb, size_t *size,
                          sy_tree_asset_report *rep, sy_error *err)
{
    *glb = NULL;
    *size = 0;
    sy_asset asset;
    sy_code rc = sy_tree_asset_build(skel, leaves, species, opt, &asset, rep, err);
    if (rc) return rc;
    double t0 = sy_now();
    sy_export_options eo = sy_export_options_default();
    eo.meshopt = opt->meshopt;
    eo.instancing = opt->instancing;
    rc = sy_export_glb(&asset, &eo, name, glb, size, err);
    if (rep && rc == SY_OK) {
        rep->seconds_export = sy_now() - t0;
        rep->bytes = *size;
    }
    sy_asset_free(&asset);
    return rc;
}

sy_code sy_tree_asset_write(const char *path, const sy_skeleton *skel, const sy_leaves *leaves,
                            const sy_species_params *species, const sy_tree_asset_options *opt, sy_tree_asset_report *rep,
                            sy_error *err)
{
    unsigned char *glb;
    size_t size;
    sy_code rc = sy_tree_asset_glb(skel, leaves, species, opt, path, &glb, &size, rep, err);
    if (!rc) rc = sy_write_file_atomic(path, glb, size, err);
    free(glb);
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
