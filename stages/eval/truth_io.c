/* Truth and skeleton JSON -> sy_forest (docs/truth-format.md). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "eval.h"
#include "stages/core/fileio.h"
#include "stages/core/json_read.h"

void sy_forest_free(sy_forest *f)
{
    for (size_t i = 0; i < f->n_trees; i++) sy_skeleton_free(&f->trees[i].skel);
    free(f->trees);
    memset(f, 0, sizeof *f);
}

sy_code sy_forest_add(sy_forest *f, const sy_eval_tree *t, sy_error *err)
{
    sy_eval_tree *grown = realloc(f->trees, (f->n_trees + 1) * sizeof *grown);
    if (!grown) return sy_fail(err, SY_EINTERNAL, "forest: out of memory");
    f->trees = grown;
    f->trees[f->n_trees++] = *t;
    return SY_OK;
}

/* The trunk: from the root, always into the child of order 0 (else the
 * thickest child). Returns the node count written to path (<= s->n). */
static size_t trunk_path(const sy_skeleton *s, int32_t root, const uint32_t *child_start, const int32_t *children,
                         int32_t *path)
{
    size_t n = 0;
    for (int32_t v = root; v >= 0 && n < s->n;) {
        path[n++] = v;
        int32_t next = -1;
        for (uint32_t k = child_start[v]; k < child_start[v + 1]; k++) {
            int32_t c = children[k];
            if (next < 0 || (s->order[c] == 0 && s->order[next] != 0) ||
                ((s->order[c] == 0) == (s->order[next] == 0) && s->radius[c] > s->radius[next]))
                next = c;
        }
        v = next;
    }
    return n;
}

/* Children lists in CSR form: children of v are children[start[v]..start[v+1]). */
static int child_lists(const sy_skeleton *s, uint32_t **start, int32_t **children)
{
    *start = calloc(s->n + 1, sizeof **start);
    *children = calloc(s->n ? s->n : 1, sizeof **children);
    if (!*start || !*children) {
        free(*start);
        free(*children);
        return 0;
    }
    for (size_t i = 0; i < s->n; i++)
        if (s->parent[i] >= 0) (*start)[s->parent[i] + 1]++;
    for (size_t i = 0; i < s->n; i++) (*start)[i + 1] += (*start)[i];
    uint32_t *fill = calloc(s->n + 1, sizeof *fill);
    if (!fill) {
        free(*start);
        free(*children);
        return 0;
    }
    memcpy(fill, *start, (s->n + 1) * sizeof *fill);
    for (size_t i = 0; i < s->n; i++)
        if (s->parent[i] >= 0) (*children)[fill[s->parent[i]]++] = (int32_t)i;
    free(fill);
    return 1;
}

static int32_t find_root(const sy_skeleton *s)
{
    for (size_t i = 0; i < s->n; i++)
        if (s->parent[i] < 0) return (int32_t)i;
    return -1;
}

double sy_skeleton_dbh(const sy_skeleton *s)
{
    int32_t root = find_root(s);
    uint32_t *start;
    int32_t *children;
    if (root < 0 || !child_lists(s, &start, &children)) return NAN;
    int32_t *path = malloc(s->n * sizeof *path);
    double dbh = NAN;
    if (path) {
        size_t n = trunk_path(s, root, start, children, path);
        double z0 = s->pos[3 * root + 2], zb = z0 + 1.3;
        for (size_t i = 1; i < n; i++) {
            double za = s->pos[3 * path[i - 1] + 2], zc = s->pos[3 * path[i] + 2];
            if ((za <= zb && zc >= zb) || (za >= zb && zc <= zb)) {
                double t = zc != za ? (zb - za) / (zc - za) : 0;
                dbh = 2 * (s->radius[path[i - 1]] + t * (s->radius[path[i]] - s->radius[path[i - 1]]));
                break;
            }
        }
    }
    free(path);
    free(start);
    free(children);
    return dbh;
}

/* ---- parsing ---- */

typedef struct {
    const char *name;
    sy_error *err;
} ctx;

static sy_code bad(const ctx *c, const sy_jv *at, const char *fmt, const char *a, const char *b)
{
    char what[512];
    snprintf(what, sizeof what, fmt, a ? a : "", b ? b : "");
    if (at) return sy_fail(c->err, SY_EINPUT, "%s:%d:%d: %s", c->name, at->line, at->col, what);
    return sy_fail(c->err, SY_EINPUT, "%s: %s", c->name, what);
}

/* An optional number member: 1 found, 0 absent, -1 wrong type (err set). */
static int opt_number(const ctx *c, const sy_jv *obj, const char *key, const char *where, double *out)
{
    const sy_jv *v = sy_jv_get(obj, key);
    if (!v || v->type == SY_JV_NULL) return 0;
    if (!sy_jv_number(v, out)) {
        bad(c, v, "%s: '%s' must be a number", where, key);
        return -1;
    }
    return 1;
}

static int whole(double v, double lo, double hi) { return v == floor(v) && v >= lo && v <= hi; }

/* Order and branch from the topology: a node's first child continues its
 * stem, further children start new stems one order higher. Parents must be
 * valid and acyclic (checked before). */
static sy_code derive_branches(sy_skeleton *s, const ctx *c)
{
    uint32_t *start;
    int32_t *children;
    int32_t root = find_root(s);
    int32_t *stack = malloc((s->n ? s->n : 1) * sizeof *stack);
    if (!stack || !child_lists(s, &start, &children)) {
        free(stack);
        return sy_fail(c->err, SY_EINTERNAL, "%s: out of memory", c->name);
    }
    int32_t next_branch = 0, top = 0;
    s->order[root] = 0;
    s->branch[root] = next_branch++;
    stack[top++] = root;
    while (top > 0) {
        int32_t v = stack[--top];
        for (uint32_t k = start[v]; k < start[v + 1]; k++) {
            int32_t ch = children[k];
            if (k == start[v]) {
                s->order[ch] = s->order[v];
                s->branch[ch] = s->branch[v];
            } else {
                s->order[ch] = (uint8_t)(s->order[v] < 255 ? s->order[v] + 1 : 255);
                s->branch[ch] = next_branch++;
            }
            stack[top++] = ch;
        }
    }
    free(stack);
    free(start);
    free(children);
    return SY_OK;
}

/* One root, parents in range, no cycles. */
static sy_code check_topology(const sy_skeleton *s, const ctx *c, const char *where)
{
    size_t roots = 0;
    for (size_t i = 0; i < s->n; i++) roots += s->parent[i] < 0;
    char count[32];
    snprintf(count, sizeof count, "%zu", roots);
    if (roots != 1) return bad(c, NULL, "%s: %s root nodes (parent -1), expected exactly one", where, count);
    uint8_t *state = calloc(s->n, 1);
    if (!state) return sy_fail(c->err, SY_EINTERNAL, "%s: out of memory", c->name);
    for (size_t i = 0; i < s->n; i++) {
        int32_t v = (int32_t)i;
        while (v >= 0 && state[v] == 0) {
            state[v] = 1;
            v = s->parent[v];
        }
        if (v >= 0 && state[v] == 1) {
            free(state);
            snprintf(count, sizeof count, "%d", v);
            return bad(c, NULL, "%s: parent links form a cycle through node %s", where, count);
        }
        for (v = (int32_t)i; v >= 0 && state[v] == 1; v = s->parent[v]) state[v] = 2;
    }
    free(state);
    return SY_OK;
}

static sy_code parse_nodes(const ctx *c, const sy_jv *nodes, const double offset[3], const char *where,
                           sy_skeleton *s)
{
    if (!nodes || nodes->type != SY_JV_ARRAY) return bad(c, nodes, "%s: 'nodes' must be an array%s", where, NULL);
    size_t n = nodes->len;
    if (n == 0) return bad(c, nodes, "%s: 'nodes' is empty%s", where, NULL);
    if (n > INT32_MAX) return bad(c, nodes, "%s: too many nodes%s", where, NULL);
    if (sy_skeleton_init(s, n, c->err)) return SY_EINTERNAL;
    const sy_jv *first = sy_jv_at(nodes, 0);
    double origin[3];
    for (int k = 0; k < 3; k++) {
        double v = 0;
        sy_jv_number(sy_jv_get(first, k == 0 ? "x" : k == 1 ? "y" : "z"), &v);
        /* Whole metres keep float offsets small and exact to ~1e-6 m. */
        origin[k] = isfinite(v) ? floor(v + offset[k]) : 0;
    }
    memcpy(s->origin, origin, sizeof origin);
    int has_topology = 1;
    for (size_t i = 0; i < n; i++) {
        const sy_jv *nd = &nodes->items[i];
        char label[96];
        snprintf(label, sizeof label, "%s node %zu", where, i);
        if (nd->type != SY_JV_OBJECT) return bad(c, nd, "%s: expected an object%s", label, NULL);
        double v[3], r, parent, id, order = 0, branch = 0;
        static const char *axes[3] = {"x", "y", "z"};
        for (int k = 0; k < 3; k++) {
            int got = opt_number(c, nd, axes[k], label, &v[k]);
            if (got < 0) return SY_EINPUT;
            if (!got) return bad(c, nd, "%s: '%s' is missing", label, axes[k]);
        }
        int got = opt_number(c, nd, "radius", label, &r);
        if (got < 0) return SY_EINPUT;
        if (!got || !(r >= 0)) return bad(c, nd, "%s: 'radius' must be a number >= 0%s", label, NULL);
        got = opt_number(c, nd, "parent", label, &parent);
        if (got < 0) return SY_EINPUT;
        if (!got || !whole(parent, -1, (double)n - 1) || parent == (double)i)
            return bad(c, nd, "%s: 'parent' must be -1 or the index of another node%s", label, NULL);
        got = opt_number(c, nd, "id", label, &id);
        if (got < 0) return SY_EINPUT;
        if (got && id != (double)i) return bad(c, nd, "%s: 'id' must equal the node's index in 'nodes'%s", label, NULL);
        int has_order = opt_number(c, nd, "order", label, &order), has_branch = opt_number(c, nd, "branch", label, &branch);
        if (has_order < 0 || has_branch < 0) return SY_EINPUT;
        if (has_order && !whole(order, 0, 255)) return bad(c, nd, "%s: 'order' must be a whole number 0..255%s", label, NULL);
        if (has_branch && !whole(branch, 0, INT32_MAX)) return bad(c, nd, "%s: 'branch' must be a whole number >= 0%s", label, NULL);
        has_topology &= has_order && has_branch;
        for (int k = 0; k < 3; k++) s->pos[3 * i + k] = (float)(v[k] + offset[k] - origin[k]);
        s->radius[i] = (float)r;
        s->parent[i] = (int32_t)parent;
        s->order[i] = (uint8_t)order;
        s->branch[i] = (int32_t)branch;
    }
    sy_code rc = check_topology(s, c, where);
    if (rc) return rc;
    return has_topology ? SY_OK : derive_branches(s, c);
}

static sy_code parse_tree(const ctx *c, const sy_jv *obj, const double offset[3], const char *where, sy_eval_tree *t)
{
    memset(t, 0, sizeof *t);
    t->tree_id = -1;
    t->species_id = -1;
    t->height = t->dbh = t->crown_width = NAN;
    if (obj->type != SY_JV_OBJECT) return bad(c, obj, "%s: expected an object%s", where, NULL);
    double v;
    int got = opt_number(c, obj, "tree_id", where, &v);
    if (got < 0) return SY_EINPUT;
    if (got) {
        if (!whole(v, -9e15, 9e15)) return bad(c, sy_jv_get(obj, "tree_id"), "%s: 'tree_id' must be a whole number%s", where, NULL);
        t->tree_id = (long long)v;
    }
    const sy_jv *sp = sy_jv_get(obj, "species");
    if (sp && sp->type != SY_JV_NULL) {
        if (!sy_jv_string(sp)) return bad(c, sp, "%s: 'species' must be a string%s", where, NULL);
        snprintf(t->species, sizeof t->species, "%s", sp->str);
    }
    if ((got = opt_number(c, obj, "species_id", where, &v)) < 0) return SY_EINPUT;
    if (got) t->species_id = whole(v, 0, 1e9) ? (int)v : -1;
    static const char *sizes[3] = {"height", "dbh", "crown_width"};
    double *dst[3] = {&t->height, &t->dbh, &t->crown_width};
    for (int k = 0; k < 3; k++) {
        if ((got = opt_number(c, obj, sizes[k], where, &v)) < 0) return SY_EINPUT;
        if (got) *dst[k] = v;
    }
    sy_code rc = parse_nodes(c, sy_jv_get(obj, "nodes"), offset, where, &t->skel);
    if (rc) {
        sy_skeleton_free(&t->skel);
        return rc;
    }
    const sy_jv *pos = sy_jv_get(obj, "position");
    int32_t root = find_root(&t->skel);
    for (int k = 0; k < 3; k++) t->position[k] = t->skel.origin[k] + t->skel.pos[3 * root + k];
    if (pos) {
        if (sy_jv_count(pos) != 3 || pos->type != SY_JV_ARRAY) {
            sy_skeleton_free(&t->skel);
            return bad(c, pos, "%s: 'position' must be [x, y, z]%s", where, NULL);
        }
        for (int k = 0; k < 3; k++)
            if (!sy_jv_number(&pos->items[k], &t->position[k])) {
                sy_skeleton_free(&t->skel);
                return bad(c, &pos->items[k], "%s: 'position' must hold numbers%s", where, NULL);
            }
        for (int k = 0; k < 3; k++) t->position[k] += offset[k];
    }
    if (isnan(t->dbh)) t->dbh = sy_skeleton_dbh(&t->skel);
    if (isnan(t->height)) t->height = sy_skeleton_height(&t->skel);
    return SY_OK;
}

static sy_code parse_doc(const ctx *c, const sy_jv *root, sy_forest *out)
{
    if (root->type != SY_JV_OBJECT) return bad(c, root, "expected a JSON object at the top%s%s", NULL, NULL);
    const sy_jv *format = sy_jv_get(root, "format");
    if (format && (!sy_jv_string(format) || (strcmp(format->str, "sylva-truth") && strcmp(format->str, "sylva-skeleton"))))
        return bad(c, format, "'format' is '%s', expected 'sylva-truth' or 'sylva-skeleton'%s",
                   sy_jv_string(format) ? format->str : sy_jv_type_name(format->type), NULL);
    double version = 1;
    if (opt_number(c, root, "version", "file", &version) < 0) return SY_EINPUT;
    if (version != 1) {
        char vb[32];
        snprintf(vb, sizeof vb, "%g", version);
        return bad(c, sy_jv_get(root, "version"), "version %s is not supported (this reader knows version 1)%s", vb, NULL);
    }
    double offset[3] = {0, 0, 0};
    const sy_jv *origin = sy_jv_get(root, "origin");
    if (origin) {
        if (origin->type != SY_JV_ARRAY || origin->len != 3) return bad(c, origin, "'origin' must be [x, y, z]%s%s", NULL, NULL);
        for (int k = 0; k < 3; k++)
            if (!sy_jv_number(&origin->items[k], &offset[k])) return bad(c, origin, "'origin' must hold numbers%s%s", NULL, NULL);
    }
    const sy_jv *trees = sy_jv_get(root, "trees");
    memset(out, 0, sizeof *out);
    if (!trees) {
        if (!sy_jv_get(root, "nodes")) return bad(c, root, "neither 'trees' (truth file) nor 'nodes' (skeleton file) found%s%s", NULL, NULL);
        sy_eval_tree t;
        sy_code rc = parse_tree(c, root, offset, "skeleton", &t);
        if (rc) return rc;
        if ((rc = sy_forest_add(out, &t, c->err))) sy_skeleton_free(&t.skel);
        return rc;
    }
    if (trees->type != SY_JV_ARRAY) return bad(c, trees, "'trees' must be an array%s%s", NULL, NULL);
    if (trees->len == 0) return bad(c, trees, "'trees' is empty%s%s", NULL, NULL);
    for (size_t i = 0; i < trees->len; i++) {
        char where[48];
        snprintf(where, sizeof where, "tree %zu", i);
        sy_eval_tree t;
        sy_code rc = parse_tree(c, &trees->items[i], offset, where, &t);
        if (!rc && (rc = sy_forest_add(out, &t, c->err))) sy_skeleton_free(&t.skel);
        if (rc) {
            sy_forest_free(out);
            return rc;
        }
    }
    return SY_OK;
}

sy_code sy_forest_parse(const char *name, const char *text, size_t len, sy_forest *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    sy_jv *root;
    sy_code rc = sy_jv_parse(name, text, len, NULL, &root, err);
    if (rc) return rc;
    ctx c = {name, err};
    rc = parse_doc(&c, root, out);
    sy_jv_free(root);
    return rc;
}

sy_code sy_forest_read(const char *path, sy_forest *out, sy_error *err)
{
    sy_buffer b;
    memset(out, 0, sizeof *out);
    sy_code rc = sy_read_file(path, &b, err);
    if (rc) return rc;
    rc = sy_forest_parse(path, (const char *)b.data, b.size, out, err);
    sy_buffer_free(&b);
    return rc;
}
