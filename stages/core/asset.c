#include "asset.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void sy_mesh_free(sy_mesh *m)
{
    free(m->position);
    free(m->normal);
    free(m->tangent);
    free(m->uv);
    free(m->wind_w);
    free(m->wind_branch);
    free(m->indices);
    memset(m, 0, sizeof *m);
}

void sy_instances_free(sy_instances *in)
{
    free(in->translation);
    free(in->rotation);
    free(in->scale);
    free(in->wind_branch);
    free(in->wind_w);
    memset(in, 0, sizeof *in);
}

void sy_asset_free(sy_asset *a)
{
    for (size_t i = 0; i < a->n_meshes; i++) sy_mesh_free(&a->meshes[i]);
    for (size_t i = 0; i < a->n_images; i++) free(a->images[i].png);
    for (size_t i = 0; i < a->n_lods; i++)
        for (int k = 0; k < a->lods[i].n_instances; k++) sy_instances_free(&a->lods[i].instances[k]);
    free(a->meshes);
    free(a->materials);
    free(a->images);
    free(a->lods);
    free(a->wind);
    free(a->extras_json);
    memset(a, 0, sizeof *a);
}

/* Appends one element of elem bytes to *array of *count elements. */
static int append(void **array, size_t *count, const void *item, size_t elem, sy_error *err)
{
    void *grown = realloc(*array, (*count + 1) * elem);
    if (!grown) {
        sy_fail(err, SY_EINTERNAL, "asset: out of memory");
        return -1;
    }
    *array = grown;
    memcpy((char *)grown + *count * elem, item, elem);
    return (int)(*count)++;
}

int sy_asset_add_mesh(sy_asset *a, const sy_mesh *m, sy_error *err)
{
    return append((void **)&a->meshes, &a->n_meshes, m, sizeof *m, err);
}
int sy_asset_add_material(sy_asset *a, const sy_material *m, sy_error *err)
{
    return append((void **)&a->materials, &a->n_materials, m, sizeof *m, err);
}
int sy_asset_add_image(sy_asset *a, const sy_image *img, sy_error *err)
{
    return append((void **)&a->images, &a->n_images, img, sizeof *img, err);
}
int sy_asset_add_lod(sy_asset *a, const sy_lod *lod, sy_error *err)
{
    return append((void **)&a->lods, &a->n_lods, lod, sizeof *lod, err);
}

sy_material sy_material_default(const char *name)
{
    sy_material m;
    memset(&m, 0, sizeof m);
    snprintf(m.name, sizeof m.name, "%s", name);
    for (int k = 0; k < 4; k++) m.base_color[k] = 1.0f;
    m.metallic = 0.0f;
    m.roughness = 0.8f;
    m.base_color_image = m.normal_image = m.diffuse_transmission_image = m.thickness_image = -1;
    m.hl2_image[0] = m.hl2_image[1] = -1;
    m.alpha_mode = SY_ALPHA_OPAQUE;
    m.alpha_cutoff = 0.5f;
    return m;
}
