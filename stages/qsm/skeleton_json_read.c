/* Skeleton JSON in: Sylva's own skeleton file (skeleton_json_write.c) and the
 * truth layout (docs/truth-format.md), both holding nodes
 * {"id","parent","x","y","z","radius","order","branch"} in world coordinates.
 * A skeleton file's "origin" is the float origin the writer used, so reading
 * it back gives the same float positions; without one the origin is floor()
 * of the root, as for the other formats. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "qsm_internal.h"
#include "stages/core/json_read.h"

typedef struct {
    const char *path, *where;
    sy_error *err;
} jctx;

/* "path:line:col: where: what" (the eval truth reader's wording). */
static sy_code jfail(const jctx *c, const sy_jv *at, const char *what)
{
    if (at) return sy_fail(c->err, SY_EINPUT, "%s:%d:%d: %s: %s", c->path, at->line, at->col, c->where, what);
    return sy_fail(c->err, SY_EINPUT, "%s: %s: %s", c->path, c->where, what);
}

/* An optional number member: 1 found, 0 absent (or null), -1 wrong type. */
static int member(const jctx *c, const sy_jv *obj, const char *key, const char *label, double *out)
{
    const sy_jv *v = sy_jv_get(obj, key);
    if (!v || v->type == SY_JV_NULL) return 0;
    if (sy_jv_number(v, out)) return 1;
    char what[160];
    snprintf(what, sizeof what, "%s: '%s' must be a number", label, key);
    jfail(c, v, what);
    return -1;
}

static int whole(double v, double lo, double hi) { return v == floor(v) && v >= lo && v <= hi; }

typedef struct {
    double *world;
    float *radius;
    int32_t *order, *branch, *parent;
    uint32_t *edges;
    size_t *edge_line;
} node_arrays;

static void arrays_free(node_arrays *a)
{
    free(a->world);
    free(a->radius);
    free(a->order);
    free(a->branch);
    free(a->parent);
    free(a->edges);
    free(a->edge_line);
}

/* One node object into slot i; *structured stays 1 while every node so far
 * carried both order and branch. */
static sy_code parse_node(const jctx *c, const sy_jv *nd, size_t i, size_t n, node_arrays *a, int *structured)
{
    char label[48], what[200];
    snprintf(label, sizeof label, "node %zu", i);
    if (nd->type != SY_JV_OBJECT) {
        snprintf(what, sizeof what, "%s: expected an object, found %s", label, sy_jv_type_name(nd->type));
        return jfail(c, nd, what);
    }
    static const char *axes[3] = {"x", "y", "z"};
    for (int k = 0; k < 3; k++) {
        int got = member(c, nd, axes[k], label, &a->world[3 * i + k]);
        if (got < 0) return SY_EINPUT;
        if (!got) {
            snprintf(what, sizeof what, "%s: '%s' is missing", label, axes[k]);
            return jfail(c, nd, what);
        }
    }
    double r, parent, id, order = 0, branch = 0;
    int got = member(c, nd, "radius", label, &r);
    if (got < 0) return SY_EINPUT;
    if (!got || !(r > 0) || !((float)r > 0) || !isfinite((float)r)) {
        snprintf(what, sizeof what, "%s: 'radius' must be a number > 0", label);
        return jfail(c, nd, what);
    }
    if ((got = member(c, nd, "parent", label, &parent)) < 0) return SY_EINPUT;
    if (!got || !whole(parent, -1, (double)n - 1) || parent == (double)i) {
        snprintf(what, sizeof what, "%s: 'parent' must be -1 or the index of another node", label);
        return jfail(c, nd, what);
    }
    if ((got = member(c, nd, "id", label, &id)) < 0) return SY_EINPUT;
    if (got && id != (double)i) {
        snprintf(what, sizeof what, "%s: 'id' must equal the node's index in 'nodes'", label);
        return jfail(c, nd, what);
    }
    int has_order = member(c, nd, "order", label, &order), has_branch = member(c, nd, "branch", label, &branch);
    if (has_order < 0 || has_branch < 0) return SY_EINPUT;
    if (has_order && !whole(order, 0, 255)) {
        snprintf(what, sizeof what, "%s: 'order' must be a whole number 0..255", label);
        return jfail(c, nd, what);
    }
    if (has_branch && !whole(branch, 0, INT32_MAX)) {
        snprintf(what, sizeof what, "%s: 'branch' must be a whole number >= 0", label);
        return jfail(c, nd, what);
    }
    *structured &= has_order && has_branch;
    a->radius[i] = (float)r;
    a->parent[i] = (int32_t)parent;
    a->order[i] = (int32_t)order;
    a->branch[i] = (int32_t)branch;
    return SY_OK;
}

sy_code sy_skeleton_from_json_nodes(const char *path, const char *where, const sy_jv *nodes, const double *origin,
                                    sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err)
{
    memset(out, 0, sizeof *out);
    jctx c = {path, where, err};
    if (!nodes || nodes->type != SY_JV_ARRAY) return jfail(&c, nodes, "'nodes' must be an array");
    size_t n = nodes->len;
    if (n == 0) return jfail(&c, nodes, "'nodes' is empty");
    if (n > (size_t)INT32_MAX) return jfail(&c, nodes, "too many nodes");
    node_arrays a = {0};
    a.world = sy_calloc(n, 3 * sizeof(double), err, "skeleton JSON");
    a.radius = sy_calloc(n, sizeof(float), err, "skeleton JSON");
    a.order = sy_calloc(n, sizeof(int32_t), err, "skeleton JSON");
    a.branch = sy_calloc(n, sizeof(int32_t), err, "skeleton JSON");
    a.parent = sy_calloc(n, sizeof(int32_t), err, "skeleton JSON");
    a.edges = sy_calloc(2 * n, sizeof(uint32_t), err, "skeleton JSON");
    a.edge_line = sy_calloc(n, sizeof(size_t), err, "skeleton JSON");
    if (!a.world || !a.radius || !a.order || !a.branch || !a.parent || !a.edges || !a.edge_line) {
        arrays_free(&a);
        return SY_EINTERNAL;
    }
    int structured = 1;
    sy_code rc = SY_OK;
    for (size_t i = 0; i < n && !rc; i++) rc = parse_node(&c, &nodes->items[i], i, n, &a, &structured);
    long root = -1;
    size_t roots = 0, m = 0;
    for (size_t i = 0; i < n && !rc; i++) {
        if (a.parent[i] < 0) {
            roots++;
            root = (long)i;
            continue;
        }
        a.edges[2 * m] = (uint32_t)a.parent[i];
        a.edges[2 * m + 1] = (uint32_t)i;
        a.edge_line[m++] = (size_t)nodes->items[i].line;
    }
    if (!rc && roots != 1) {
        char what[96];
        snprintf(what, sizeof what, "%zu root nodes (parent -1), expected exactly one", roots);
        rc = jfail(&c, nodes, what);
    }
    if (!rc) {
        char label[512];
        snprintf(label, sizeof label, "%s: %s", path, where);
        sy_graph_in g = {n, m, a.world, a.radius, structured ? a.order : NULL, structured ? a.branch : NULL,
                         a.edges, a.edge_line, root, origin};
        rc = sy_graph_to_skeleton(label, &g, out, info, err);
    }
    arrays_free(&a);
    return rc;
}

/* The file's "origin" (a skeleton file's float origin): 1 set, 0 absent. */
static int read_origin(const jctx *c, const sy_jv *doc, double origin[3], sy_code *rc)
{
    const sy_jv *o = sy_jv_get(doc, "origin");
    *rc = SY_OK;
    if (!o || o->type == SY_JV_NULL) return 0;
    if (o->type != SY_JV_ARRAY || o->len != 3) {
        *rc = jfail(c, o, "'origin' must be [x, y, z]");
        return 0;
    }
    for (int k = 0; k < 3; k++)
        if (!sy_jv_number(&o->items[k], &origin[k])) {
            *rc = jfail(c, o, "'origin' must hold numbers");
            return 0;
        }
    return 1;
}

static sy_code check_header(const jctx *c, const sy_jv *doc)
{
    if (doc->type != SY_JV_OBJECT) return jfail(c, doc, "expected a JSON object at the top");
    const sy_jv *format = sy_jv_get(doc, "format");
    /* "sylva-tree" is a whole .sylva file as JSON (sylva decode -o): its skeleton reads the same way. */
    if (format && (!sy_jv_string(format) ||
                   (strcmp(format->str, "sylva-skeleton") != 0 && strcmp(format->str, "sylva-truth") != 0 &&
                    strcmp(format->str, "sylva-tree") != 0)))
        return jfail(c, format, "'format' must be \"sylva-skeleton\", \"sylva-tree\" or \"sylva-truth\"");
    double version = 1;
    const sy_jv *v = sy_jv_get(doc, "version");
    if (v && (!sy_jv_number(v, &version) || version != 1))
        return jfail(c, v, "only version 1 is supported");
    return SY_OK;
}

sy_code sy_skeleton_from_json(const char *path, const sy_jv *doc, long tree, sy_skeleton *out,
                              sy_skeleton_read_info *info, sy_error *err)
{
    memset(out, 0, sizeof *out);
    jctx c = {path, "file", err};
    sy_code rc = check_header(&c, doc);
    if (rc) return rc;
    double origin[3];
    int has_origin = read_origin(&c, doc, origin, &rc);
    if (rc) return rc;
    const sy_jv *trees = sy_jv_get(doc, "trees"), *nodes = sy_jv_get(doc, "nodes");
    char where[48] = "skeleton";
    if (trees) {
        if (trees->type != SY_JV_ARRAY) return jfail(&c, trees, "'trees' must be an array");
        size_t k = trees->len;
        if (k == 0) return jfail(&c, trees, "'trees' is empty");
        if (tree < 0 && k > 1)
            return sy_fail(err, SY_EINPUT, "%s: holds %zu trees; choose one by index (0..%zu)", path, k, k - 1);
        if (tree >= 0 && (size_t)tree >= k)
            return sy_fail(err, SY_EINPUT, "%s: tree %ld asked for, the file holds %zu (0..%zu)", path, tree, k,
                           k - 1);
        size_t t = tree < 0 ? 0 : (size_t)tree;
        snprintf(where, sizeof where, "tree %zu", t);
        const sy_jv *obj = &trees->items[t];
        if (obj->type != SY_JV_OBJECT) {
            c.where = where;
            return jfail(&c, obj, "expected an object");
        }
        nodes = sy_jv_get(obj, "nodes");
    } else {
        if (!nodes) return jfail(&c, doc, "neither 'trees' (truth file) nor 'nodes' (skeleton file) found");
        if (tree > 0) return sy_fail(err, SY_EINPUT, "%s: tree %ld asked for, a skeleton file holds one", path, tree);
    }
    if (!nodes) {
        c.where = where;
        return jfail(&c, NULL, "'nodes' is missing");
    }
    rc = sy_skeleton_from_json_nodes(path, where, nodes, has_origin ? origin : NULL, out, info, err);
    if (!rc && info) {
        info->format = SY_SKEL_JSON;
        info->origin_from_file = has_origin;
        /* A sylva-tree's leaf-off flag (sylva decode -o), read as the .sylva's is. */
        const sy_jv *off = sy_jv_get(doc, "leaf_off");
        info->leaf_off = off && off->type == SY_JV_BOOL && off->boolean;
    }
    return rc;
}

sy_code sy_skeleton_read_json_tree(const char *path, const unsigned char *data, size_t size, long tree,
                                   sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err)
{
    memset(out, 0, sizeof *out);
    sy_jv *doc;
    sy_code rc = sy_jv_parse(path, (const char *)data, size, NULL, &doc, err);
    if (rc) return rc;
    rc = sy_skeleton_from_json(path, doc, tree, out, info, err);
    sy_jv_free(doc);
    return rc;
}

sy_code sy_skeleton_read_json_mem(const char *path, const unsigned char *data, size_t size, sy_skeleton *out,
                                  sy_skeleton_read_info *info, sy_error *err)
{
    return sy_skeleton_read_json_tree(path, data, size, -1, out, info, err);
}
