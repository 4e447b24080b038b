/* .sylva as JSON: see sylva_json.h. The skeleton part is the skeleton JSON of
 * stages/qsm (one writer, one reader); this file adds the meta data and the
 * cluster hulls. */
#include "sylva_json.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/qsm/qsm.h"

static const char *hull_names[3] = {"alpha", "convex", "box"};

int sy_sylva_json_is_tree(const sy_jv *doc)
{
    const char *f = sy_jv_string(sy_jv_get(doc, "format"));
    return f && strcmp(f, "sylva-tree") == 0;
}

static void write_cluster(sy_json *j, FILE *fp, const sy_cluster *c, const double origin[3])
{
    fputc('\n', fp);
    sy_json_object(j, NULL);
    sy_json_int(j, "seed", c->seed);
    sy_json_string(j, "hull", hull_names[c->hull >= 0 && c->hull <= 2 ? c->hull : 0]);
    sy_json_number(j, "alpha", c->alpha);
    sy_json_array(j, "vertices");
    for (size_t i = 0; i < 3 * c->n_verts; i++) sy_json_number(j, NULL, origin[i % 3] + (double)c->verts[i]);
    sy_json_end(j);
    sy_json_array(j, "triangles");
    for (size_t i = 0; i < 3 * c->n_tris; i++) sy_json_int(j, NULL, c->tris[i]);
    sy_json_end(j);
    size_t ob = sy_cluster_occupancy_bytes(c);
    if (ob) {
        sy_json_array(j, "occupancy_dims");
        for (int k = 0; k < 3; k++) sy_json_int(j, NULL, c->occ_dims[k]);
        sy_json_end(j);
        char *hex = malloc(2 * ob + 1);
        if (hex) {
            for (size_t k = 0; k < ob; k++) snprintf(hex + 2 * k, 3, "%02x", c->occupancy[k]);
            sy_json_string(j, "occupancy", hex);
            free(hex);
        }
    }
    if (c->n_twigs) {
        /* x y z parent per node, parent -1: the seed (docs/sylva-format.md). */
        sy_json_number(j, "twig_voxel", c->twig_voxel);
        sy_json_array(j, "twigs");
        for (size_t i = 0; i < c->n_twigs; i++) {
            for (int k = 0; k < 3; k++) sy_json_number(j, NULL, origin[k] + (double)c->twig_pos[3 * i + k]);
            sy_json_int(j, NULL, c->twig_parent[i]);
        }
        sy_json_end(j);
    }
    sy_json_end(j);
}

sy_code sy_sylva_json_write(const char *path, const sy_skeleton *s, const sy_clusters *cl, const sy_sylva_meta *meta,
                            sy_error *err)
{
    sy_atomic_file f;
    sy_json j;
    sy_code rc = sy_skeleton_json_open(path, s, "sylva-tree", &f, &j, err);
    if (rc) return rc;
    sy_json_int(&j, "species_id", meta->species_id);
    char seed[32]; /* as a string: a 64-bit seed does not fit a JSON double */
    snprintf(seed, sizeof seed, "%llu", (unsigned long long)meta->seed);
    sy_json_string(&j, "seed", seed);
    sy_json_bool(&j, "leaf_off", (meta->flags & SY_SYLVA_LEAF_OFF) != 0);
    sy_json_object(&j, "quant");
    sy_json_int(&j, "step_log2", meta->quant.step_log2);
    sy_json_array(&j, "box_min");
    for (int k = 0; k < 3; k++) sy_json_int(&j, NULL, meta->quant.box_min[k]);
    sy_json_end(&j);
    sy_json_number(&j, "log2_rmin", meta->quant.log2_rmin);
    sy_json_number(&j, "log2_rmax", meta->quant.log2_rmax);
    sy_json_end(&j);
    sy_skeleton_json_members(&j, f.fp, s);
    sy_json_array(&j, "clusters");
    for (size_t c = 0; c < cl->n; c++) write_cluster(&j, f.fp, &cl->items[c], s->origin);
    sy_json_end(&j);
    sy_json_end(&j);
    sy_json_finish(&j);
    return sy_atomic_commit(&f, err);
}

/* ---- reading ------------------------------------------------------------ */

static sy_code fail_at(sy_error *err, const char *path, const sy_jv *at, const char *where, const char *what)
{
    return sy_fail(err, SY_EINPUT, "%s:%d:%d: %s: %s", path, at->line, at->col, where, what);
}

static int whole_in(const sy_jv *v, double lo, double hi, double *out)
{
    return sy_jv_number(v, out) && *out == floor(*out) && *out >= lo && *out <= hi;
}

static sy_code read_meta(const char *path, const sy_jv *doc, sy_sylva_meta *meta, int *has_quant, sy_error *err)
{
    double v;
    const sy_jv *sp = sy_jv_get(doc, "species_id");
    if (sp) {
        if (!whole_in(sp, 0, 65535, &v)) return fail_at(err, path, sp, "species_id", "must be a whole number 0..65535");
        meta->species_id = (uint16_t)v;
    }
    const sy_jv *seed = sy_jv_get(doc, "seed");
    if (seed) {
        const char *t = sy_jv_string(seed);
        char *end = NULL;
        errno = 0;
        unsigned long long x = t && t[0] >= '0' && t[0] <= '9' ? strtoull(t, &end, 10) : 0;
        if (!t || !end || *end || errno)
            return fail_at(err, path, seed, "seed", "must be a string of decimal digits below 2^64");
        meta->seed = x;
    }
    const sy_jv *off = sy_jv_get(doc, "leaf_off");
    if (off) {
        if (off->type != SY_JV_BOOL) return fail_at(err, path, off, "leaf_off", "must be true or false");
        meta->flags = off->boolean ? SY_SYLVA_LEAF_OFF : 0;
    }
    const sy_jv *q = sy_jv_get(doc, "quant");
    *has_quant = q != NULL;
    if (!q) return SY_OK;
    const sy_jv *step = sy_jv_get(q, "step_log2"), *box = sy_jv_get(q, "box_min");
    double rmin, rmax;
    if (!step || !whole_in(step, -30, 30, &v))
        return fail_at(err, path, q, "quant", "'step_log2' must be a whole number -30..30");
    meta->quant.step_log2 = (int32_t)v;
    if (sy_jv_count(box) != 3 || box->type != SY_JV_ARRAY)
        return fail_at(err, path, q, "quant", "'box_min' must be an array of 3 whole numbers");
    for (int k = 0; k < 3; k++) {
        if (!whole_in(&box->items[k], -2147483648.0, 2147483647.0, &v))
            return fail_at(err, path, &box->items[k], "quant", "'box_min' must hold 32-bit whole numbers");
        meta->quant.box_min[k] = (int32_t)v;
    }
    if (!sy_jv_number(sy_jv_get(q, "log2_rmin"), &rmin) || !sy_jv_number(sy_jv_get(q, "log2_rmax"), &rmax) ||
        !(rmin <= rmax) || fabs(rmin) > 128 || fabs(rmax) > 128)
        return fail_at(err, path, q, "quant", "'log2_rmin' <= 'log2_rmax' must be numbers within +-128");
    meta->quant.log2_rmin = (float)rmin;
    meta->quant.log2_rmax = (float)rmax;
    return SY_OK;
}

static int hull_kind(const char *name)
{
    for (int k = 0; k < 3; k++)
        if (name && strcmp(name, hull_names[k]) == 0) return k;
    return -1;
}

/* The cluster's traced twigs, if it lists any: x y z parent per node. */
static sy_code read_twigs(const char *path, const sy_jv *o, const char *where, const sy_skeleton *s, sy_cluster *c,
                          sy_error *err)
{
    const sy_jv *tw = sy_jv_get(o, "twigs"), *vox = sy_jv_get(o, "twig_voxel");
    double v;
    if (!tw && !vox) return SY_OK;
    if (!tw || tw->type != SY_JV_ARRAY || tw->len % 4 || !tw->len)
        return fail_at(err, path, tw ? tw : o, where, "'twigs' must be x y z parent quadruples beside 'twig_voxel'");
    if (!vox || !sy_jv_number(vox, &v) || !(v > 0) || v > 1e3)
        return fail_at(err, path, vox ? vox : o, where, "'twig_voxel' must be a size in metres, > 0");
    c->twig_voxel = (float)v;
    c->n_twigs = tw->len / 4;
    c->twig_pos = sy_calloc(c->n_twigs, 3 * sizeof *c->twig_pos, err, "twigs");
    c->twig_parent = sy_calloc(c->n_twigs, sizeof *c->twig_parent, err, "twigs");
    if (!c->twig_pos || !c->twig_parent) return SY_EINTERNAL;
    for (size_t i = 0; i < c->n_twigs; i++) {
        for (int k = 0; k < 3; k++) {
            if (!sy_jv_number(&tw->items[4 * i + k], &v) || fabs(v - s->origin[k]) > 1e6)
                return fail_at(err, path, &tw->items[4 * i + k], where, "a twig coordinate is not a number within 1000 km");
            c->twig_pos[3 * i + k] = (float)(v - s->origin[k]);
        }
        if (!whole_in(&tw->items[4 * i + 3], -1, (double)i - 1, &v))
            return fail_at(err, path, &tw->items[4 * i + 3], where, "a twig's parent must be -1 (the seed) or an earlier twig");
        c->twig_parent[i] = (int32_t)v;
    }
    return SY_OK;
}

/* One cluster object into c (zeroed by the caller). */
static sy_code read_cluster(const char *path, const sy_jv *o, size_t index, const sy_skeleton *s, sy_cluster *c,
                            sy_error *err)
{
    char where[40];
    snprintf(where, sizeof where, "cluster %zu", index);
    if (o->type != SY_JV_OBJECT) return fail_at(err, path, o, where, "expected an object");
    const sy_jv *seed = sy_jv_get(o, "seed"), *hull = sy_jv_get(o, "hull"), *alpha = sy_jv_get(o, "alpha");
    const sy_jv *verts = sy_jv_get(o, "vertices"), *tris = sy_jv_get(o, "triangles");
    double v;
    if (!seed || !whole_in(seed, 0, (double)s->n - 1, &v))
        return fail_at(err, path, o, where, "'seed' must be a node id of the skeleton");
    c->seed = (int32_t)v;
    c->hull = hull_kind(sy_jv_string(hull));
    if (c->hull < 0) return fail_at(err, path, hull ? hull : o, where, "'hull' must be \"alpha\", \"convex\" or \"box\"");
    if (alpha && (!sy_jv_number(alpha, &v) || !(v >= 0) || v > 3.4e38))
        return fail_at(err, path, alpha, where, "'alpha' must be a number >= 0");
    c->alpha = alpha ? (float)v : 0.0f;
    if (!verts || verts->type != SY_JV_ARRAY || verts->len % 3 || verts->len < 12)
        return fail_at(err, path, verts ? verts : o, where, "'vertices' must be x y z triples, at least 4 of them");
    if (!tris || tris->type != SY_JV_ARRAY || tris->len % 3 || tris->len < 12)
        return fail_at(err, path, tris ? tris : o, where, "'triangles' must be index triples, at least 4 of them");
    c->n_verts = verts->len / 3;
    c->n_tris = tris->len / 3;
    c->verts = sy_calloc(verts->len, sizeof *c->verts, err, "hull vertices");
    c->tris = sy_calloc(tris->len, sizeof *c->tris, err, "hull triangles");
    if (!c->verts || !c->tris) return SY_EINTERNAL;
    for (size_t i = 0; i < verts->len; i++) {
        if (!sy_jv_number(&verts->items[i], &v) || fabs(v - s->origin[i % 3]) > 1e6)
            return fail_at(err, path, &verts->items[i], where, "a vertex coordinate is not a number within 1000 km");
        c->verts[i] = (float)(v - s->origin[i % 3]);
    }
    for (size_t i = 0; i < tris->len; i++) {
        if (!whole_in(&tris->items[i], 0, (double)c->n_verts - 1, &v))
            return fail_at(err, path, &tris->items[i], where, "a triangle index is not a vertex of this hull");
        c->tris[i] = (uint32_t)v;
    }
    sy_code rc = read_twigs(path, o, where, s, c, err);
    if (rc) return rc;
    const sy_jv *od = sy_jv_get(o, "occupancy_dims"), *occ = sy_jv_get(o, "occupancy");
    if (!od && !occ) return c->n_twigs ? sy_cluster_occupancy_of_twigs(c, err) : SY_OK;
    if (!od || od->type != SY_JV_ARRAY || od->len != 3)
        return fail_at(err, path, od ? od : o, where, "'occupancy_dims' must be 3 cell counts 1..8 beside 'occupancy'");
    uint8_t d[3];
    for (int k = 0; k < 3; k++) {
        if (!whole_in(&od->items[k], 1, 8, &v))
            return fail_at(err, path, &od->items[k], where, "an occupancy side must be 1..8 cells");
        d[k] = (uint8_t)v;
    }
    size_t ob = ((size_t)d[0] * d[1] * d[2] + 7) / 8;
    const char *hex = sy_jv_string(occ);
    if (!hex || strlen(hex) != 2 * ob)
        return fail_at(err, path, occ ? occ : o, where, "'occupancy' must be a hex string of the grid's bits");
    c->occupancy = sy_calloc(ob, 1, err, "occupancy");
    if (!c->occupancy) return SY_EINTERNAL;
    for (size_t k = 0; k < ob; k++) {
        unsigned x;
        char pair[3] = {hex[2 * k], hex[2 * k + 1], 0};
        if (!isxdigit((unsigned char)pair[0]) || !isxdigit((unsigned char)pair[1]) || sscanf(pair, "%2x", &x) != 1)
            return fail_at(err, path, occ, where, "'occupancy' must be a hex string of the grid's bits");
        c->occupancy[k] = (uint8_t)x;
    }
    memcpy(c->occ_dims, d, 3);
    return SY_OK;
}

static sy_code read_clusters(const char *path, const sy_jv *doc, const sy_skeleton *s, sy_clusters *cl,
                             sy_error *err)
{
    const sy_jv *arr = sy_jv_get(doc, "clusters");
    if (!arr) return SY_OK;
    if (arr->type != SY_JV_ARRAY) return fail_at(err, path, arr, "clusters", "must be an array");
    if (!arr->len) return SY_OK;
    cl->items = sy_calloc(arr->len, sizeof *cl->items, err, "clusters");
    if (!cl->items) return SY_EINTERNAL;
    for (size_t i = 0; i < arr->len; i++) {
        cl->n = i + 1; /* so a failure frees what was read */
        sy_code rc = read_cluster(path, &arr->items[i], i, s, &cl->items[i], err);
        if (rc) return rc;
    }
    return SY_OK;
}

sy_code sy_sylva_json_from_doc(const char *path, const sy_jv *doc, sy_skeleton *s, sy_clusters *cl,
                               sy_sylva_meta *meta, int *has_quant, sy_error *err)
{
    memset(cl, 0, sizeof *cl);
    memset(meta, 0, sizeof *meta);
    *has_quant = 0;
    sy_code rc = sy_skeleton_from_json(path, doc, -1, s, NULL, err);
    if (rc) return rc;
    if (!(rc = read_meta(path, doc, meta, has_quant, err))) rc = read_clusters(path, doc, s, cl, err);
    if (rc) {
        sy_skeleton_free(s);
        sy_clusters_free(cl);
        memset(cl, 0, sizeof *cl);
    }
    return rc;
}

sy_code sy_sylva_encode_meta(const sy_skeleton *s, const sy_clusters *cl, const sy_sylva_meta *meta, int has_quant,
                             const char *path, unsigned char **bytes, size_t *size, sy_error *err)
{
    *bytes = NULL, *size = 0;
    sy_code rc = sy_encode_mem(s, cl, meta->species_id, meta->seed, has_quant ? &meta->quant : NULL, bytes, size, err);
    if (!rc && meta->flags) rc = sy_sylva_set_flags(*bytes, *size, meta->flags, err);
    if (rc) {
        free(*bytes), *bytes = NULL, *size = 0;
        /* The encoder names no file: an edited grid that no longer covers
         * its nodes is the document's fault. */
        if (rc == SY_EINPUT && path && !strstr(err->msg, path)) {
            sy_error e2 = *err;
            sy_fail(err, rc, "%s: %s", path, e2.msg);
        }
    }
    return rc;
}

sy_code sy_sylva_json_encode(const char *path, const sy_jv *doc, unsigned char **bytes, size_t *size, sy_error *err)
{
    sy_skeleton s;
    sy_clusters cl;
    sy_sylva_meta meta;
    int has_quant;
    *bytes = NULL, *size = 0;
    sy_code rc = sy_sylva_json_from_doc(path, doc, &s, &cl, &meta, &has_quant, err);
    if (rc) return rc;
    rc = sy_sylva_encode_meta(&s, &cl, &meta, has_quant, path, bytes, size, err);
    sy_skeleton_free(&s);
    sy_clusters_free(&cl);
    return rc;
}
