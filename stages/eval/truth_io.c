/* Truth and skeleton JSON -> sy_forest (docs/truth-format.md). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "eval.h"
#include "stages/core/fileio.h"
#include "stages/core/json_read.h"
#include "stages/qsm/qsm.h"

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
        dbh = 2 * sy_skeleton_radius_at_height(s, path, n, s->pos[3 * root + 2] + 1.3, NULL);
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

/* origin: the float origin a skeleton file names (x y z are world
 * coordinates either way), NULL for floor() of the root. */
static sy_code parse_tree(const ctx *c, const sy_jv *obj, const double *origin, const char *where, sy_eval_tree *t)
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
    /* One node reader for every skeleton JSON: stages/qsm/skeleton_json_read.c. */
    sy_code rc = sy_skeleton_from_json_nodes(c->name, where, sy_jv_get(obj, "nodes"), origin, &t->skel, NULL, c->err);
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
            if (!sy_jv_number(&pos->items[k], &t->position[k]) || !(fabs(t->position[k]) <= SY_WORLD_MAX)) {
                sy_skeleton_free(&t->skel);
                return bad(c, &pos->items[k], "%s: 'position' must hold numbers within 1e9 m%s", where, NULL);
            }
    }
    if (isnan(t->dbh)) t->dbh = sy_skeleton_dbh(&t->skel);
    if (isnan(t->height)) t->height = sy_skeleton_height(&t->skel);
    return SY_OK;
}

static sy_code parse_doc(const ctx *c, const sy_jv *root, sy_forest *out)
{
    if (root->type != SY_JV_OBJECT) return bad(c, root, "expected a JSON object at the top%s%s", NULL, NULL);
    const sy_jv *format = sy_jv_get(root, "format");
    /* "sylva-tree" (sylva decode -o tree.json) is a skeleton file plus hulls. */
    if (format && (!sy_jv_string(format) || (strcmp(format->str, "sylva-truth") && strcmp(format->str, "sylva-skeleton") &&
                                             strcmp(format->str, "sylva-tree"))))
        return bad(c, format, "'format' is '%s', expected 'sylva-truth', 'sylva-skeleton' or 'sylva-tree'%s",
                   sy_jv_string(format) ? format->str : sy_jv_type_name(format->type), NULL);
    double version = 1;
    if (opt_number(c, root, "version", "file", &version) < 0) return SY_EINPUT;
    if (version != 1) {
        char vb[32];
        snprintf(vb, sizeof vb, "%g", version);
        return bad(c, sy_jv_get(root, "version"), "version %s is not supported (this reader knows version 1)%s", vb, NULL);
    }
    double file_origin[3] = {0, 0, 0};
    const sy_jv *origin = sy_jv_get(root, "origin");
    if (origin) {
        if (origin->type != SY_JV_ARRAY || origin->len != 3) return bad(c, origin, "'origin' must be [x, y, z]%s%s", NULL, NULL);
        for (int k = 0; k < 3; k++)
            if (!sy_jv_number(&origin->items[k], &file_origin[k])) return bad(c, origin, "'origin' must hold numbers%s%s", NULL, NULL);
    }
    const double *float_origin = origin ? file_origin : NULL;
    const sy_jv *trees = sy_jv_get(root, "trees");
    memset(out, 0, sizeof *out);
    if (!trees) {
        if (!sy_jv_get(root, "nodes")) return bad(c, root, "neither 'trees' (truth file) nor 'nodes' (skeleton file) found%s%s", NULL, NULL);
        sy_eval_tree t;
        sy_code rc = parse_tree(c, root, float_origin, "skeleton", &t);
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
        sy_code rc = parse_tree(c, &trees->items[i], NULL, where, &t);
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

/* Any other skeleton file (PLY, cylinder CSV, TreeQSM text, OBJ, .sylva) as a
 * one-tree forest, sized like a skeleton JSON without dbh/height. */
static sy_code forest_from_skeleton_file(const char *path, sy_forest *out, sy_error *err)
{
    sy_eval_tree t;
    memset(&t, 0, sizeof t);
    t.tree_id = -1;
    t.species_id = -1;
    t.crown_width = NAN;
    sy_code rc = sy_skeleton_read(path, &t.skel, err);
    if (rc) return rc;
    int32_t root = find_root(&t.skel);
    for (int k = 0; k < 3; k++) t.position[k] = t.skel.origin[k] + t.skel.pos[3 * root + k];
    t.dbh = sy_skeleton_dbh(&t.skel);
    t.height = sy_skeleton_height(&t.skel);
    if ((rc = sy_forest_add(out, &t, err))) sy_skeleton_free(&t.skel);
    return rc;
}

sy_code sy_forest_read(const char *path, sy_forest *out, sy_error *err)
{
    sy_buffer b;
    memset(out, 0, sizeof *out);
    sy_code rc = sy_read_file(path, &b, err);
    if (rc) return rc;
    if (sy_skeleton_sniff(path, b.data, b.size) == SY_SKEL_JSON)
        rc = sy_forest_parse(path, (const char *)b.data, b.size, out, err);
    else
        rc = forest_from_skeleton_file(path, out, err);
    sy_buffer_free(&b);
    return rc;
}
