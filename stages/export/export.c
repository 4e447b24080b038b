/* Asset -> .glb. This file checks the asset, decides the glTF layout (one
 * bufferView per attribute stream, 4-byte aligned; leaves as
 * EXT_mesh_gpu_instancing nodes or baked; one group node per LOD chained with
 * MSFT_lod; optional EXT_meshopt_compression) and hands the finished document
 * to the tinygltf shim for serialisation. docs/gltf.md describes the output. */
#include "export.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "gltf_tinygltf.h"
#include "meshopt_codec.h"
#include "stages/core/fileio.h"
#include "stages/core/vec3.h"
#include "stages/core/array.h"

#define SY_MAX_LODS 65 /* sy_gltf_node holds 64 lower-level ids */

sy_export_options sy_export_options_default(void)
{
    sy_export_options o;
    memset(&o, 0, sizeof o);
    o.meshopt = 0;
    o.instancing = 1;
    o.generator = NULL;
    return o;
}

sy_code sy_export_options_check(const sy_export_options *o, sy_error *err)
{
    if ((o->meshopt != 0 && o->meshopt != 1) || (o->instancing != 0 && o->instancing != 1))
        return sy_fail(err, SY_EUSAGE, "export: meshopt and instancing must be 0 or 1 (got %d, %d)", o->meshopt,
                       o->instancing);
    if (o->generator && strlen(o->generator) > 256)
        return sy_fail(err, SY_EUSAGE, "export: generator must be at most 256 characters");
    return SY_OK;
}

/* ------------------------------------------------------------------ checks */

static int all_finite(const float *v, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(v[i])) return 0;
    return 1;
}

static int material_has_textures(const sy_material *m)
{
    return m->base_color_image >= 0 || m->normal_image >= 0 ||
           (m->diffuse_transmission > 0 && m->diffuse_transmission_image >= 0) || m->thickness_image >= 0 ||
           m->hl2_image[0] >= 0 || m->hl2_image[1] >= 0;
}

static sy_code check_mesh(const char *path, const sy_asset *a, size_t i, sy_error *err)
{
    const sy_mesh *m = &a->meshes[i];
    if (m->n_vertices == 0 || !m->position || !m->normal)
        return sy_fail(err, SY_EINPUT, "%s: mesh %zu '%s' has no vertices, positions or normals", path, i, m->name);
    if (m->n_vertices > UINT32_MAX - 1)
        return sy_fail(err, SY_EINPUT, "%s: mesh %zu '%s' has too many vertices (%zu)", path, i, m->name, m->n_vertices);
    if (!m->indices || m->n_indices == 0 || m->n_indices % 3 != 0)
        return sy_fail(err, SY_EINPUT, "%s: mesh %zu '%s' has %zu indices, not a triangle list", path, i, m->name,
                       m->n_indices);
    for (size_t k = 0; k < m->n_indices; k++)
        if (m->indices[k] >= m->n_vertices)
            return sy_fail(err, SY_EINPUT, "%s: mesh %zu '%s' index %u at %zu out of range (%zu vertices)", path, i,
                           m->name, m->indices[k], k, m->n_vertices);
    if (!all_finite(m->position, 3 * m->n_vertices))
        return sy_fail(err, SY_EINPUT, "%s: mesh %zu '%s' has NaN or infinite positions", path, i, m->name);
    if (!all_finite(m->normal, 3 * m->n_vertices))
        return sy_fail(err, SY_EINPUT, "%s: mesh %zu '%s' has NaN or infinite normals", path, i, m->name);
    if ((m->uv && !all_finite(m->uv, 2 * m->n_vertices)) || (m->tangent && !all_finite(m->tangent, 4 * m->n_vertices)) ||
        (m->wind_w && !all_finite(m->wind_w, 4 * m->n_vertices)))
        return sy_fail(err, SY_EINPUT, "%s: mesh %zu '%s' has NaN or infinite uv, tangent or wind values", path, i,
                       m->name);
    if (m->material < 0 || (size_t)m->material >= a->n_materials)
        return sy_fail(err, SY_EINPUT, "%s: mesh %zu '%s' refers to missing material %d (%zu materials)", path, i,
                       m->name, m->material, a->n_materials);
    if (material_has_textures(&a->materials[m->material]) && !m->uv)
        return sy_fail(err, SY_EINPUT, "%s: mesh %zu '%s' uses textured material '%s' but has no uv", path, i, m->name,
                       a->materials[m->material].name);
    if (m->wind_branch)
        for (size_t k = 0; k < m->n_vertices; k++)
            if (m->wind_branch[k] >= a->n_wind)
                return sy_fail(err, SY_EINPUT, "%s: mesh %zu '%s' vertex %zu names wind branch %u of %zu", path, i,
                               m->name, k, m->wind_branch[k], a->n_wind);
    return SY_OK;
}

static sy_code check_image_ref(const char *path, const sy_asset *a, const sy_material *m, int image, sy_error *err)
{
    if (image < -1 || image >= (int)a->n_images)
        return sy_fail(err, SY_EINPUT, "%s: material '%s' refers to missing image %d (%zu images)", path, m->name,
                       image, a->n_images);
    return SY_OK;
}

static sy_code check_materials_images(const char *path, const sy_asset *a, sy_error *err)
{
    static const unsigned char png_sig[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    for (size_t i = 0; i < a->n_images; i++)
        if (!a->images[i].png || a->images[i].size < 8 || memcmp(a->images[i].png, png_sig, 8) != 0)
            return sy_fail(err, SY_EINPUT, "%s: image %zu '%s' is not PNG data", path, i, a->images[i].name);
    for (size_t i = 0; i < a->n_materials; i++) {
        const sy_material *m = &a->materials[i];
        sy_code rc;
        if ((rc = check_image_ref(path, a, m, m->base_color_image, err)) ||
            (rc = check_image_ref(path, a, m, m->normal_image, err)) ||
            (rc = check_image_ref(path, a, m, m->diffuse_transmission_image, err)) ||
            (rc = check_image_ref(path, a, m, m->thickness_image, err)) ||
            (rc = check_image_ref(path, a, m, m->hl2_image[0], err)) ||
            (rc = check_image_ref(path, a, m, m->hl2_image[1], err)))
            return rc;
        if (!isfinite(m->thickness_factor) || m->thickness_factor < 0 || !isfinite(m->hl2_min) ||
            !isfinite(m->hl2_max) || !all_finite(m->hl2_transmit, 2))
            return sy_fail(err, SY_EINPUT, "%s: material '%s' has a volume or HL2 factor that is NaN or negative", path,
                           m->name);
        if (m->alpha_mode != SY_ALPHA_OPAQUE && m->alpha_mode != SY_ALPHA_MASK && m->alpha_mode != SY_ALPHA_BLEND)
            return sy_fail(err, SY_EINPUT, "%s: material '%s' has unknown alpha mode %d", path, m->name,
                           (int)m->alpha_mode);
        if (!all_finite(m->base_color, 4) || !all_finite(m->emissive, 3) || !isfinite(m->metallic) || !isfinite(m->roughness) ||
            !isfinite(m->alpha_cutoff) || !isfinite(m->diffuse_transmission) ||
            !all_finite(m->diffuse_transmission_color, 3) || m->diffuse_transmission < 0 || m->diffuse_transmission > 1)
            return sy_fail(err, SY_EINPUT, "%s: material '%s' has a factor that is NaN or out of range", path, m->name);
    }
    return SY_OK;
}

static sy_code check_instances(const char *path, const sy_asset *a, size_t level, const sy_instances *in,
                               sy_error *err)
{
    if (in->mesh < 0 || (size_t)in->mesh >= a->n_meshes)
        return sy_fail(err, SY_EINPUT, "%s: LOD %zu instances refer to missing mesh %d", path, level, in->mesh);
    if (in->n == 0 || !in->translation || !in->rotation || !in->scale)
        return sy_fail(err, SY_EINPUT, "%s: LOD %zu instances of mesh %d have no transforms", path, level, in->mesh);
    if (!all_finite(in->translation, 3 * in->n) || !all_finite(in->rotation, 4 * in->n) ||
        !all_finite(in->scale, 3 * in->n))
        return sy_fail(err, SY_EINPUT, "%s: LOD %zu instances of mesh %d have NaN transforms", path, level, in->mesh);
    for (size_t k = 0; k < in->n; k++) {
        const float *q = in->rotation + 4 * k;
        double len = sqrt((double)q[0] * q[0] + (double)q[1] * q[1] + (double)q[2] * q[2] + (double)q[3] * q[3]);
        /* glTF requires unit quaternions; allow float rounding only. */
        if (fabs(len - 1.0) > 1e-3)
            return sy_fail(err, SY_EINPUT, "%s: LOD %zu instance %zu rotation is not a unit quaternion (|q| = %g)",
                           path, level, k, len);
        if (in->wind_branch && in->wind_branch[k] >= a->n_wind)
            return sy_fail(err, SY_EINPUT, "%s: LOD %zu instance %zu wind branch %u is past the %zu wind entries",
                           path, level, k, in->wind_branch[k], a->n_wind);
    }
    if (in->wind_w && !all_finite(in->wind_w, 4 * in->n))
        return sy_fail(err, SY_EINPUT, "%s: LOD %zu instance wind data is not finite", path, level);
    return SY_OK;
}

static sy_code check_lods(const char *path, const sy_asset *a, sy_error *err)
{
    if (a->n_lods == 0) return sy_fail(err, SY_EINPUT, "%s: asset has no LOD levels to export", path);
    if (a->n_lods > SY_MAX_LODS)
        return sy_fail(err, SY_EINPUT, "%s: asset has %zu LOD levels (at most %d)", path, a->n_lods, SY_MAX_LODS);
    for (size_t l = 0; l < a->n_lods; l++) {
        const sy_lod *lod = &a->lods[l];
        if (lod->n_meshes < 0 || lod->n_meshes > SY_LOD_MAX_PARTS || lod->n_instances < 0 ||
            lod->n_instances > SY_LOD_MAX_PARTS || lod->n_meshes + lod->n_instances == 0)
            return sy_fail(err, SY_EINPUT, "%s: LOD %zu has %d meshes and %d instance sets", path, l, lod->n_meshes,
                           lod->n_instances);
        for (int k = 0; k < lod->n_meshes; k++)
            if (lod->meshes[k] < 0 || (size_t)lod->meshes[k] >= a->n_meshes)
                return sy_fail(err, SY_EINPUT, "%s: LOD %zu refers to missing mesh %d", path, l, lod->meshes[k]);
        for (int k = 0; k < lod->n_instances; k++) {
            sy_code rc = check_instances(path, a, l, &lod->instances[k], err);
            if (rc) return rc;
        }
        if (!isfinite(lod->screen_coverage) || lod->screen_coverage < 0 || lod->screen_coverage > 1)
            return sy_fail(err, SY_EINPUT, "%s: LOD %zu screen coverage %g is not in [0,1]", path, l,
                           (double)lod->screen_coverage);
        /* MSFT_lod's thresholds only make sense strictly decreasing. */
        if (l > 0 && !(lod->screen_coverage < a->lods[l - 1].screen_coverage))
            return sy_fail(err, SY_EINPUT, "%s: LOD %zu screen coverage %g is not below LOD %zu's %g", path, l,
                           (double)lod->screen_coverage, l - 1, (double)a->lods[l - 1].screen_coverage);
    }
    return SY_OK;
}

static sy_code check_wind(const char *path, const sy_asset *a, sy_error *err)
{
    for (size_t i = 0; i < a->n_wind; i++) {
        const sy_wind_branch *w = &a->wind[i];
        if (w->parent < -1 || (w->parent >= 0 && (size_t)w->parent >= a->n_wind))
            return sy_fail(err, SY_EINPUT, "%s: wind branch %zu has missing parent %d", path, i, (int)w->parent);
        if (!all_finite(w->anchor, 3) || !all_finite(w->axis, 3) || !isfinite(w->length) || !isfinite(w->c2) ||
            !isfinite(w->c4) || !isfinite(w->frequency) || !isfinite(w->stiffness))
            return sy_fail(err, SY_EINPUT, "%s: wind branch %zu has NaN values", path, i);
    }
    return SY_OK;
}

static sy_code check_asset(const char *path, const sy_asset *a, sy_error *err)
{
    if (a->n_meshes == 0) return sy_fail(err, SY_EINPUT, "%s: asset has no meshes", path);
    sy_code rc = check_materials_images(path, a, err);
    for (size_t i = 0; !rc && i < a->n_meshes; i++) rc = check_mesh(path, a, i, err);
    if (!rc) rc = check_lods(path, a, err);
    if (!rc) rc = check_wind(path, a, err);
    return rc;
}

/* ----------------------------------------------------------- doc building */

typedef struct {
    sy_gltf_doc doc;
    const sy_asset *asset;
    const char *path;
    int meshopt;
    int *mesh_map;  /* asset mesh -> glTF mesh, -1 not yet written */
    int *image_map; /* asset image -> glTF image, -1 not yet written */
    sy_error *err;
} builder;

/* Makes room for one more element; returns 0 or sets err. */
static int reserve(builder *b, void **array, size_t *cap, size_t n, size_t elem)
{
    return sy_array_reserve(array, cap, n + 1, elem, 16, b->err, b->path) ? -1 : 0;
}

/* Appends bytes to the BIN chunk at a 4-byte aligned offset (padding zeroed). */
static int bin_append(builder *b, const void *data, size_t len, size_t *offset)
{
    sy_gltf_doc *d = &b->doc;
    size_t start = (d->bin_size + 3) & ~(size_t)3;
    if (start + len > d->bin_capacity) {
        size_t want = d->bin_capacity ? d->bin_capacity : 1 << 16;
        while (want < start + len) want *= 2;
        unsigned char *grown = realloc(d->bin, want);
        if (!grown) {
            sy_fail(b->err, SY_EINTERNAL, "%s: out of memory assembling glTF (%zu bytes)", b->path, want);
            return -1;
        }
        d->bin = grown;
        d->bin_capacity = want;
    }
    memset(d->bin + d->bin_size, 0, start - d->bin_size);
    memcpy(d->bin + start, data, len);
    d->bin_size = start + len;
    *offset = start;
    return 0;
}

/* One bufferView holding count elements of stride bytes. With meshopt the
 * view lives in the fallback buffer and its encoded bytes in the BIN chunk;
 * tri (the triangle list as uint32) selects mode TRIANGLES. */
static int add_view(builder *b, const void *data, size_t count, size_t stride, int target, const uint32_t *tri,
                    size_t n_vertices)
{
    sy_gltf_doc *d = &b->doc;
    if (reserve(b, (void **)&d->views, &d->cap_views, d->n_views, sizeof *d->views)) return -1;
    sy_gltf_view v;
    memset(&v, 0, sizeof v);
    v.length = count * stride;
    v.target = target;
    v.stride = target == SY_GLTF_ARRAY_BUFFER ? (int)stride : 0;
    /* Geometry and instance streams are compressed; images (stride 1) stay raw. */
    if (b->meshopt && (tri != NULL || stride % 4 == 0)) {
        unsigned char *enc = NULL;
        size_t enc_size = 0;
        sy_code rc = tri ? sy_meshopt_encode_triangles(tri, count, n_vertices, &enc, &enc_size, b->err)
                         : sy_meshopt_encode_attributes(data, count, stride, &enc, &enc_size, b->err);
        if (rc) return -1;
        int bad = bin_append(b, enc, enc_size, &v.meshopt_offset);
        free(enc);
        if (bad) return -1;
        v.buffer = 1;
        v.offset = (d->fallback_size + 3) & ~(size_t)3;
        d->fallback_size = v.offset + v.length;
        v.meshopt = tri ? SY_MESHOPT_TRIANGLES : SY_MESHOPT_ATTRIBUTES;
        v.meshopt_length = enc_size;
        v.meshopt_count = count;
        v.meshopt_stride = (int)stride;
        d->uses_meshopt = 1;
    } else {
        v.buffer = 0;
        if (bin_append(b, data, v.length, &v.offset)) return -1;
    }
    d->views[d->n_views] = v;
    return (int)d->n_views++;
}

static int add_accessor(builder *b, int view, int component_type, int components, size_t count,
                        const float *bounds_of)
{
    sy_gltf_doc *d = &b->doc;
    if (view < 0) return -1;
    if (reserve(b, (void **)&d->accessors, &d->cap_accessors, d->n_accessors, sizeof *d->accessors)) return -1;
    sy_gltf_accessor *acc = &d->accessors[d->n_accessors];
    memset(acc, 0, sizeof *acc);
    acc->view = view;
    acc->component_type = component_type;
    acc->components = components;
    acc->count = count;
    if (bounds_of) {
        acc->has_bounds = 1;
        for (int c = 0; c < components; c++) acc->min[c] = acc->max[c] = bounds_of[c];
        for (size_t i = 1; i < count; i++)
            for (int c = 0; c < components; c++) {
                double x = bounds_of[i * (size_t)components + (size_t)c];
                if (x < acc->min[c]) acc->min[c] = x;
                if (x > acc->max[c]) acc->max[c] = x;
            }
    }
    return (int)d->n_accessors++;
}

/* A float attribute stream of count x components as its own bufferView. */
static int add_float_stream(builder *b, const float *data, size_t count, int components, int target, int bounds)
{
    int view = add_view(b, data, count, (size_t)components * 4, target, NULL, 0);
    return add_accessor(b, view, SY_GLTF_FLOAT, components, count, bounds ? data : NULL);
}

/* The per-branch values a simple sway shader needs, copied from asset.wind
 * to every vertex or instance so it needs no table lookup (docs/wind.md):
 * the anchor of the branch each element follows (VEC3) and (level,
 * stiffness) (VEC2). Float, because the level is an exact small integer and
 * shaders read float attributes everywhere. Returns 0, or -1 with err set. */
static int add_wind_branch_streams(builder *b, const uint16_t *branch, size_t n, int target, int *anchor,
                                   int *level_stiffness)
{
    float *an = sy_calloc(3 * n, sizeof *an, b->err, "wind anchor stream");
    float *ls = an ? sy_calloc(2 * n, sizeof *ls, b->err, "wind level stream") : NULL;
    if (!ls) {
        free(an);
        return -1;
    }
    for (size_t i = 0; i < n; i++) {
        const sy_wind_branch *w = &b->asset->wind[branch[i]];
        memcpy(an + 3 * i, w->anchor, sizeof w->anchor);
        ls[2 * i] = (float)w->level;
        ls[2 * i + 1] = w->stiffness;
    }
    *anchor = add_float_stream(b, an, n, 3, target, 0);
    *level_stiffness = add_float_stream(b, ls, n, 2, target, 0);
    free(an);
    free(ls);
    return *anchor < 0 || *level_stiffness < 0 ? -1 : 0;
}

/* Tangents from uv derivatives, for normal-mapped meshes that came without
 * them (the validator warns when a viewer must generate them). glTF's v axis
 * points down the image while its normal maps have +Y up, so the bitangent
 * sign is taken against -dP/dv. */
static float *compute_tangents(const sy_mesh *m, sy_error *err)
{
    size_t n = m->n_vertices;
    double *acc = sy_calloc(n * 6, sizeof *acc, err, "tangents");
    float *t = acc ? sy_calloc(n * 4, sizeof *t, err, "tangents") : NULL;
    if (!t) {
        free(acc);
        return NULL;
    }
    for (size_t k = 0; k + 2 < m->n_indices; k += 3) {
        const uint32_t i0 = m->indices[k], i1 = m->indices[k + 1], i2 = m->indices[k + 2];
        const float *p0 = m->position + 3 * i0, *p1 = m->position + 3 * i1, *p2 = m->position + 3 * i2;
        const float *u0 = m->uv + 2 * i0, *u1 = m->uv + 2 * i1, *u2 = m->uv + 2 * i2;
        double e1[3], e2[3], du1 = u1[0] - u0[0], dv1 = u1[1] - u0[1], du2 = u2[0] - u0[0], dv2 = u2[1] - u0[1];
        for (int c = 0; c < 3; c++) e1[c] = p1[c] - p0[c], e2[c] = p2[c] - p0[c];
        double det = du1 * dv2 - du2 * dv1;
        if (fabs(det) < 1e-20) continue;
        double r = 1.0 / det;
        const uint32_t tri[3] = {i0, i1, i2};
        for (int v = 0; v < 3; v++)
            for (int c = 0; c < 3; c++) {
                acc[6 * tri[v] + c] += (e1[c] * dv2 - e2[c] * dv1) * r;     /* dP/du */
                acc[6 * tri[v] + 3 + c] += (e2[c] * du1 - e1[c] * du2) * r; /* dP/dv */
            }
    }
    for (size_t i = 0; i < n; i++) {
        const float *nn = m->normal + 3 * i;
        double *s = acc + 6 * i, *tv = acc + 6 * i + 3;
        double d = s[0] * nn[0] + s[1] * nn[1] + s[2] * nn[2];
        double o[3] = {s[0] - nn[0] * d, s[1] - nn[1] * d, s[2] - nn[2] * d};
        double len = sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
        if (len < 1e-12) { /* no uv gradient: any vector perpendicular to n */
            double ax[3] = {fabs(nn[0]) < 0.9 ? 1.0 : 0.0, fabs(nn[0]) < 0.9 ? 0.0 : 1.0, 0.0};
            d = ax[0] * nn[0] + ax[1] * nn[1];
            for (int c = 0; c < 3; c++) o[c] = ax[c] - nn[c] * d;
            len = sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
        }
        double bx = nn[1] * o[2] - nn[2] * o[1], by = nn[2] * o[0] - nn[0] * o[2], bz = nn[0] * o[1] - nn[1] * o[0];
        double handed = -(bx * tv[0] + by * tv[1] + bz * tv[2]);
        for (int c = 0; c < 3; c++) t[4 * i + c] = (float)(o[c] / len);
        t[4 * i + 3] = handed < 0 ? -1.0f : 1.0f;
    }
    free(acc);
    return t;
}

/* Writes one sy_mesh (an asset mesh or a baked instance set) as a glTF mesh. */
static int emit_mesh(builder *b, const sy_mesh *m)
{
    sy_gltf_doc *d = &b->doc;
    const sy_material *mat = &b->asset->materials[m->material];
    size_t n = m->n_vertices;
    sy_gltf_mesh gm;
    memset(&gm, 0, sizeof gm);
    snprintf(gm.name, sizeof gm.name, "%s", m->name);
    gm.material = m->material;
    gm.tangent = gm.texcoord = gm.wind_w = gm.wind_branch = gm.wind_anchor = gm.wind_level_stiffness = -1;
    gm.position = add_float_stream(b, m->position, n, 3, SY_GLTF_ARRAY_BUFFER, 1);
    gm.normal = add_float_stream(b, m->normal, n, 3, SY_GLTF_ARRAY_BUFFER, 0);
    if (gm.position < 0 || gm.normal < 0) return -1;
    float *own_tangent = NULL;
    const float *tangent = m->tangent;
    if (!tangent && mat->normal_image >= 0) {
        tangent = own_tangent = compute_tangents(m, b->err);
        if (!tangent) return -1;
    }
    if (tangent) {
        gm.tangent = add_float_stream(b, tangent, n, 4, SY_GLTF_ARRAY_BUFFER, 0);
        free(own_tangent);
        if (gm.tangent < 0) return -1;
    }
    if (m->uv && (gm.texcoord = add_float_stream(b, m->uv, n, 2, SY_GLTF_ARRAY_BUFFER, 0)) < 0) return -1;
    if (m->wind_w && (gm.wind_w = add_float_stream(b, m->wind_w, n, 4, SY_GLTF_ARRAY_BUFFER, 0)) < 0) return -1;
    if (m->wind_branch) {
        /* UNSIGNED_SHORT keeps the branch index exact; glTF wants every vertex
         * element 4-byte aligned, so the stream has byteStride 4. */
        uint16_t *padded = sy_calloc(2 * n, sizeof *padded, b->err, "wind branch stream");
        if (!padded) return -1;
        for (size_t i = 0; i < n; i++) padded[2 * i] = m->wind_branch[i];
        int view = add_view(b, padded, n, 4, SY_GLTF_ARRAY_BUFFER, NULL, 0);
        free(padded);
        gm.wind_branch = add_accessor(b, view, SY_GLTF_UNSIGNED_SHORT, 1, n, NULL);
        if (gm.wind_branch < 0 ||
            add_wind_branch_streams(b, m->wind_branch, n, SY_GLTF_ARRAY_BUFFER, &gm.wind_anchor,
                                    &gm.wind_level_stiffness))
            return -1;
    }
    /* 16-bit indices when every index fits below the primitive-restart value. */
    int narrow = n <= 65535;
    size_t isize = narrow ? 2 : 4;
    void *idx = malloc(m->n_indices * isize);
    if (!idx) {
        sy_fail(b->err, SY_EINTERNAL, "%s: out of memory for indices", b->path);
        return -1;
    }
    for (size_t k = 0; k < m->n_indices; k++) {
        if (narrow)
            ((uint16_t *)idx)[k] = (uint16_t)m->indices[k];
        else
            ((uint32_t *)idx)[k] = m->indices[k];
    }
    int view = add_view(b, idx, m->n_indices, isize, SY_GLTF_ELEMENT_ARRAY_BUFFER, m->indices, n);
    free(idx);
    gm.indices = add_accessor(b, view, narrow ? SY_GLTF_UNSIGNED_SHORT : SY_GLTF_UNSIGNED_INT, 1, m->n_indices, NULL);
    if (gm.indices < 0) return -1;
    if (reserve(b, (void **)&d->meshes, &d->cap_meshes, d->n_meshes, sizeof *d->meshes)) return -1;
    d->meshes[d->n_meshes] = gm;
    return (int)d->n_meshes++;
}

static int asset_mesh(builder *b, int index)
{
    if (b->mesh_map[index] < 0) b->mesh_map[index] = emit_mesh(b, &b->asset->meshes[index]);
    return b->mesh_map[index];
}

static int add_node(builder *b, const char *name, int mesh)
{
    sy_gltf_doc *d = &b->doc;
    if (reserve(b, (void **)&d->nodes, &d->cap_nodes, d->n_nodes, sizeof *d->nodes)) return -1;
    sy_gltf_node *nd = &d->nodes[d->n_nodes];
    memset(nd, 0, sizeof *nd);
    snprintf(nd->name, sizeof nd->name, "%s", name);
    nd->mesh = mesh;
    nd->inst_translation = nd->inst_rotation = nd->inst_scale = -1;
    nd->inst_wind_w = nd->inst_wind_branch = nd->inst_wind_anchor = nd->inst_wind_level_stiffness = -1;
    return (int)d->n_nodes++;
}

static void quat_rotate(const float *q, const double *v, double *out)
{
    /* v' = v + 2 q.xyz x (q.xyz x v + w v) */
    double t[3] = {q[1] * v[2] - q[2] * v[1] + q[3] * v[0], q[2] * v[0] - q[0] * v[2] + q[3] * v[1],
                   q[0] * v[1] - q[1] * v[0] + q[3] * v[2]};
    out[0] = v[0] + 2 * (q[1] * t[2] - q[2] * t[1]);
    out[1] = v[1] + 2 * (q[2] * t[0] - q[0] * t[2]);
    out[2] = v[2] + 2 * (q[0] * t[1] - q[1] * t[0]);
}

static void normalize3(double *v) { sy_v3_normalize(v); }

/* The instancing fallback: one mesh holding every copy, transformed by its
 * TRS. Normals use the inverse-transpose (1/scale); a mirroring scale flips
 * the winding and the tangent handedness. */
static sy_code bake_instances(builder *b, const sy_mesh *src, const sy_instances *in, sy_mesh *out)
{
    memset(out, 0, sizeof *out);
    size_t nv = src->n_vertices, ni = src->n_indices;
    if (in->n > UINT32_MAX / nv || nv * in->n > UINT32_MAX - 1)
        return sy_fail(b->err, SY_EINPUT, "%s: baking %zu instances of '%s' exceeds 32-bit indices", b->path, in->n,
                       src->name);
    size_t tv = nv * in->n;
    snprintf(out->name, sizeof out->name, "%.40s_baked", src->name);
    out->n_vertices = tv;
    out->n_indices = ni * in->n;
    out->material = src->material;
    out->position = sy_calloc(3 * tv, sizeof(float), b->err, "baked positions");
    out->normal = sy_calloc(3 * tv, sizeof(float), b->err, "baked normals");
    out->indices = sy_calloc(out->n_indices, sizeof(uint32_t), b->err, "baked indices");
    int ok = out->position && out->normal && out->indices;
    if (ok && src->tangent) ok = (out->tangent = sy_calloc(4 * tv, sizeof(float), b->err, "baked tangents")) != NULL;
    if (ok && src->uv) ok = (out->uv = sy_calloc(2 * tv, sizeof(float), b->err, "baked uv")) != NULL;
    int inst_wind = in->wind_w && in->wind_branch;
    if (ok && (src->wind_w || inst_wind))
        ok = (out->wind_w = sy_calloc(4 * tv, sizeof(float), b->err, "baked wind")) != NULL;
    if (ok && (src->wind_branch || inst_wind))
        ok = (out->wind_branch = sy_calloc(tv, sizeof(uint16_t), b->err, "baked wind")) != NULL;
    if (!ok) {
        sy_mesh_free(out);
        return b->err->code ? b->err->code : SY_EINTERNAL;
    }
    for (size_t k = 0; k < in->n; k++) {
        const float *T = in->translation + 3 * k, *R = in->rotation + 4 * k, *S = in->scale + 3 * k;
        int mirror = (double)S[0] * S[1] * S[2] < 0;
        size_t base = k * nv;
        for (size_t i = 0; i < nv; i++) {
            double p[3], q[3];
            for (int c = 0; c < 3; c++) p[c] = (double)src->position[3 * i + c] * S[c];
            quat_rotate(R, p, q);
            for (int c = 0; c < 3; c++) out->position[3 * (base + i) + c] = (float)(q[c] + T[c]);
            for (int c = 0; c < 3; c++) p[c] = S[c] != 0 ? src->normal[3 * i + c] / (double)S[c] : 0;
            quat_rotate(R, p, q);
            normalize3(q);
            for (int c = 0; c < 3; c++) out->normal[3 * (base + i) + c] = (float)q[c];
            if (src->tangent) {
                for (int c = 0; c < 3; c++) p[c] = (double)src->tangent[4 * i + c] * S[c];
                quat_rotate(R, p, q);
                normalize3(q);
                for (int c = 0; c < 3; c++) out->tangent[4 * (base + i) + c] = (float)q[c];
                out->tangent[4 * (base + i) + 3] = mirror ? -src->tangent[4 * i + 3] : src->tangent[4 * i + 3];
            }
            if (src->uv) memcpy(out->uv + 2 * (base + i), src->uv + 2 * i, 2 * sizeof(float));
            if (inst_wind) {
                memcpy(out->wind_w + 4 * (base + i), in->wind_w + 4 * k, 4 * sizeof(float));
                out->wind_branch[base + i] = in->wind_branch[k];
            } else {
                if (src->wind_w) memcpy(out->wind_w + 4 * (base + i), src->wind_w + 4 * i, 4 * sizeof(float));
                if (src->wind_branch) out->wind_branch[base + i] = src->wind_branch[i];
            }
        }
        for (size_t t = 0; t < ni; t += 3) {
            uint32_t *dst = out->indices + k * ni + t;
            dst[0] = (uint32_t)base + src->indices[t];
            dst[1] = (uint32_t)base + src->indices[t + (mirror ? 2 : 1)];
            dst[2] = (uint32_t)base + src->indices[t + (mirror ? 1 : 2)];
        }
    }
    return SY_OK;
}

/* One child node per instance set: EXT_mesh_gpu_instancing or baked. */
static int emit_instances(builder *b, const sy_instances *in, const char *name)
{
    const sy_mesh *src = &b->asset->meshes[in->mesh];
    if (b->doc.uses_instancing) {
        int mesh = asset_mesh(b, in->mesh);
        if (mesh < 0) return -1;
        int t = add_float_stream(b, in->translation, in->n, 3, 0, 0);
        int r = add_float_stream(b, in->rotation, in->n, 4, 0, 0);
        int s = add_float_stream(b, in->scale, in->n, 3, 0, 0);
        if (t < 0 || r < 0 || s < 0) return -1;
        int node = add_node(b, name, mesh);
        if (node < 0) return -1;
        b->doc.nodes[node].inst_translation = t;
        b->doc.nodes[node].inst_rotation = r;
        b->doc.nodes[node].inst_scale = s;
        /* Leaves sway with the branch they hang on: the instance carries that
         * branch's wind data (docs/wind.md). Branch indices are exact in float
         * below 2^24, far above the 65,535 branches the mesher allows. */
        if (in->wind_w && in->wind_branch) {
            float *branch = sy_calloc(in->n, sizeof(float), b->err, "instance wind");
            if (!branch) return -1;
            for (size_t i = 0; i < in->n; i++) branch[i] = in->wind_branch[i];
            int w = add_float_stream(b, in->wind_w, in->n, 4, 0, 0);
            int wb = add_float_stream(b, branch, in->n, 1, 0, 0);
            free(branch);
            if (w < 0 || wb < 0) return -1;
            b->doc.nodes[node].inst_wind_w = w;
            b->doc.nodes[node].inst_wind_branch = wb;
            if (add_wind_branch_streams(b, in->wind_branch, in->n, 0, &b->doc.nodes[node].inst_wind_anchor,
                                        &b->doc.nodes[node].inst_wind_level_stiffness))
                return -1;
        }
        return node;
    }
    sy_mesh baked;
    if (bake_instances(b, src, in, &baked)) return -1;
    int mesh = emit_mesh(b, &baked);
    sy_mesh_free(&baked);
    return mesh < 0 ? -1 : add_node(b, name, mesh);
}

/* LOD level l as one group node whose children are its parts. */
static int emit_level(builder *b, size_t l)
{
    const sy_lod *lod = &b->asset->lods[l];
    int children[SY_GLTF_MAX_CHILDREN], n = 0;
    char name[96];
    for (int k = 0; k < lod->n_meshes; k++) {
        int mesh = asset_mesh(b, lod->meshes[k]);
        snprintf(name, sizeof name, "LOD%d_%.40s", (int)l, b->asset->meshes[lod->meshes[k]].name);
        if (mesh < 0 || (children[n++] = add_node(b, name, mesh)) < 0) return -1;
    }
    for (int k = 0; k < lod->n_instances; k++) {
        snprintf(name, sizeof name, "LOD%d_%.40s_instances", (int)l, b->asset->meshes[lod->instances[k].mesh].name);
        if ((children[n++] = emit_instances(b, &lod->instances[k], name)) < 0) return -1;
    }
    snprintf(name, sizeof name, "%.60s_LOD%d", b->asset->name[0] ? b->asset->name : "tree", (int)l);
    int group = add_node(b, name, -1);
    if (group < 0) return -1;
    sy_gltf_node *g = &b->doc.nodes[group];
    g->n_children = n;
    memcpy(g->children, children, (size_t)n * sizeof *children);
    return group;
}

static int texture_for(builder *b, int image, int sampler)
{
    sy_gltf_doc *d = &b->doc;
    if (image < 0) return -1;
    if (b->image_map[image] < 0) {
        const sy_image *img = &b->asset->images[image];
        int view = add_view(b, img->png, img->size, 1, 0, NULL, 0);
        if (view < 0) return -2;
        b->image_map[image] = (int)d->n_images;
        d->image_views[d->n_images] = view;
        snprintf(d->image_names[d->n_images], sizeof d->image_names[0], "%s", img->name);
        d->n_images++;
    }
    for (size_t t = 0; t < d->n_textures; t++)
        if (d->textures[t].image == b->image_map[image] && d->textures[t].sampler == sampler) return (int)t;
    if (reserve(b, (void **)&d->textures, &d->cap_textures, d->n_textures, sizeof *d->textures)) return -2;
    d->textures[d->n_textures].image = b->image_map[image];
    d->textures[d->n_textures].sampler = sampler;
    return (int)d->n_textures++;
}

static sy_code emit_materials(builder *b)
{
    const sy_asset *a = b->asset;
    sy_gltf_doc *d = &b->doc;
    d->materials = sy_calloc(a->n_materials, sizeof *d->materials, b->err, "materials");
    if (!d->materials) return SY_EINTERNAL;
    d->n_materials = a->n_materials;
    for (size_t i = 0; i < a->n_materials; i++) {
        const sy_material *m = &a->materials[i];
        /* Opaque bark tiles along the trunk; cut-out cards and impostors map
         * their texture exactly once, where REPEAT would bleed opposite edges. */
        int sampler = m->alpha_mode == SY_ALPHA_OPAQUE ? 0 : 1;
        sy_gltf_material *gm = &d->materials[i];
        gm->src = m;
        gm->base_color_texture = texture_for(b, m->base_color_image, sampler);
        gm->normal_texture = texture_for(b, m->normal_image, sampler);
        gm->transmission_texture =
            m->diffuse_transmission > 0 ? texture_for(b, m->diffuse_transmission_image, sampler) : -1;
        /* Volume needs a transmission extension beside it, and the spec
         * forbids it on double-sided materials (a volume needs a closed
         * surface): double-sided leaf cards carry their thickness map in
         * SYLVA_leaf_translucency instead (docs/leafmaps.md). */
        int volume = m->thickness_factor > 0 && m->diffuse_transmission > 0 && !m->double_sided;
        gm->thickness_texture = m->thickness_factor > 0 ? texture_for(b, m->thickness_image, sampler) : -1;
        gm->volume = volume;
        for (int s = 0; s < 2; s++) gm->hl2_texture[s] = texture_for(b, m->hl2_image[s], sampler);
        if (gm->base_color_texture < -1 || gm->normal_texture < -1 || gm->transmission_texture < -1 ||
            gm->thickness_texture < -1 || gm->hl2_texture[0] < -1 || gm->hl2_texture[1] < -1)
            return b->err->code;
        if (m->diffuse_transmission > 0) d->uses_transmission = 1;
        if (volume && gm->thickness_texture >= 0) d->uses_volume = 1;
        if (gm->hl2_texture[0] >= 0 || gm->hl2_texture[1] >= 0 || (gm->thickness_texture >= 0 && !volume))
            d->uses_leaf_translucency = 1;
    }
    return SY_OK;
}

static sy_code build(builder *b, const sy_export_options *opt)
{
    const sy_asset *a = b->asset;
    sy_gltf_doc *d = &b->doc;
    d->uses_instancing = opt->instancing != 0;
    b->mesh_map = malloc(a->n_meshes * sizeof *b->mesh_map);
    b->image_map = malloc((a->n_images + 1) * sizeof *b->image_map);
    d->image_views = malloc((a->n_images + 1) * sizeof *d->image_views);
    d->image_names = malloc((a->n_images + 1) * sizeof *d->image_names);
    if (!b->mesh_map || !b->image_map || !d->image_views || !d->image_names)
        return sy_fail(b->err, SY_EINTERNAL, "%s: out of memory", b->path);
    for (size_t i = 0; i < a->n_meshes; i++) b->mesh_map[i] = -1;
    for (size_t i = 0; i < a->n_images; i++) b->image_map[i] = -1;
    sy_code rc = emit_materials(b);
    if (rc) return rc;
    int levels[SY_MAX_LODS];
    for (size_t l = 0; l < a->n_lods; l++)
        if ((levels[l] = emit_level(b, l)) < 0) return b->err->code ? b->err->code : SY_EINTERNAL;
    /* Instancing may have been asked for while no level has instances. */
    int any_instances = 0;
    for (size_t l = 0; l < a->n_lods; l++) any_instances |= a->lods[l].n_instances > 0;
    d->uses_instancing = d->uses_instancing && any_instances;
    sy_gltf_node *root = &d->nodes[levels[0]];
    d->scene_root = levels[0];
    root->n_lod_ids = (int)a->n_lods - 1;
    for (size_t l = 0; l < a->n_lods; l++) {
        if (l > 0) root->lod_ids[l - 1] = levels[l];
        root->coverage[l] = a->lods[l].screen_coverage;
    }
    d->uses_lod = a->n_lods > 1;
    root->carries_wind = a->n_wind > 0;
    d->wind = a->wind;
    d->n_wind = a->n_wind;
    d->extras_json = a->extras_json;
    d->asset_name = a->name;
    return SY_OK;
}

static void builder_free(builder *b)
{
    sy_gltf_doc *d = &b->doc;
    free(d->bin);
    free(d->views);
    free(d->accessors);
    free(d->image_views);
    free(d->image_names);
    free(d->textures);
    free(d->materials);
    free(d->meshes);
    free(d->nodes);
    free(b->mesh_map);
    free(b->image_map);
}

sy_code sy_export_glb(const sy_asset *asset, const sy_export_options *opt, const char *name, unsigned char **glb,
                      size_t *glb_size, sy_error *err)
{
    *glb = NULL;
    *glb_size = 0;
    const char *path = name ? name : "glb";
    sy_export_options o = opt ? *opt : sy_export_options_default();
    sy_code rc = sy_export_options_check(&o, err);
    if (rc) return rc;
    char generator[64];
    snprintf(generator, sizeof generator, "Sylva %s", SYLVA_VERSION);
    rc = check_asset(path, asset, err);
    if (rc) return rc;
    builder b;
    memset(&b, 0, sizeof b);
    b.asset = asset;
    b.path = path;
    b.meshopt = o.meshopt != 0;
    b.err = err;
    b.doc.generator = o.generator ? o.generator : generator;
    rc = build(&b, &o);
    if (!rc) rc = sy_gltf_write_glb(&b.doc, path, glb, glb_size, err);
    builder_free(&b);
    return rc;
}
