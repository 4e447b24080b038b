/* Polyline skeletons in Wavefront OBJ: `v x y z` per node, `l a b` per edge
 * (1-based), and after each vertex a "# radius R order O branch B" comment
 * that plain OBJ tools ignore and this reader reads back. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "qsm_internal.h"
#include "stages/core/fileio.h"

sy_code sy_skeleton_write_obj(const char *path, const sy_skeleton *s, sy_error *err)
{
    sy_code rc = sy_skeleton_validate(s, err);
    if (rc) return rc;
    sy_atomic_file f;
    if ((rc = sy_atomic_open(&f, path, err))) return rc;
    FILE *fp = f.fp;
    fprintf(fp, "# Sylva skeleton: one vertex per node, one line per edge (parent child).\n"
                "# Each vertex is followed by its radius (metres), branch order and branch id.\n"
                "# sylva origin %.17g %.17g %.17g\n",
            s->origin[0], s->origin[1], s->origin[2]);
    char x[40], y[40], z[40], r[32];
    for (size_t i = 0; i < s->n; i++) {
        const float *p = s->pos + 3 * i;
        sy_fmt_coord(x, sizeof x, s->origin[0] + (double)p[0], s->origin[0]);
        sy_fmt_coord(y, sizeof y, s->origin[1] + (double)p[1], s->origin[1]);
        sy_fmt_coord(z, sizeof z, s->origin[2] + (double)p[2], s->origin[2]);
        sy_fmt_float(r, sizeof r, s->radius[i]);
        fprintf(fp, "v %s %s %s\n# radius %s order %d branch %d\n", x, y, z, r, s->order[i], s->branch[i]);
    }
    for (size_t i = 0; i < s->n; i++)
        if (s->parent[i] >= 0) fprintf(fp, "l %d %zu\n", s->parent[i] + 1, i + 1);
    return sy_atomic_commit(&f, err);
}

/* Growable arrays of the reader. */
typedef struct {
    double *world;
    float *radius;
    int32_t *order, *branch;
    size_t *vline;
    uint8_t *has_radius, *has_struct;
    size_t n, cap;
    uint32_t *edges;
    size_t *eline;
    size_t m, ecap;
} obj_data;

static void obj_free(obj_data *d)
{
    free(d->world);
    free(d->radius);
    free(d->order);
    free(d->branch);
    free(d->vline);
    free(d->has_radius);
    free(d->has_struct);
    free(d->edges);
    free(d->eline);
}

static int grow_vertices(obj_data *d)
{
    size_t cap = d->cap ? 2 * d->cap : 256;
    void *a = realloc(d->world, cap * 3 * sizeof(double));
    if (a) d->world = a;
    void *b = realloc(d->radius, cap * sizeof(float));
    if (b) d->radius = b;
    void *c = realloc(d->order, cap * sizeof(int32_t));
    if (c) d->order = c;
    void *e = realloc(d->branch, cap * sizeof(int32_t));
    if (e) d->branch = e;
    void *g = realloc(d->vline, cap * sizeof(size_t));
    if (g) d->vline = g;
    void *h = realloc(d->has_radius, cap);
    if (h) d->has_radius = h;
    void *k = realloc(d->has_struct, cap);
    if (k) d->has_struct = k;
    if (!a || !b || !c || !e || !g || !h || !k) return 0;
    d->cap = cap;
    return 1;
}

static int add_edge(obj_data *d, uint32_t a, uint32_t b, size_t line)
{
    if (d->m == d->ecap) {
        size_t cap = d->ecap ? 2 * d->ecap : 256;
        void *x = realloc(d->edges, cap * 2 * sizeof(uint32_t));
        if (x) d->edges = x;
        void *y = realloc(d->eline, cap * sizeof(size_t));
        if (y) d->eline = y;
        if (!x || !y) return 0;
        d->ecap = cap;
    }
    d->edges[2 * d->m] = a;
    d->edges[2 * d->m + 1] = b;
    d->eline[d->m++] = line;
    return 1;
}

/* Splits [b, e) at blanks into at most max tokens; returns the count. */
static int tokens(const char *b, const char *e, const char **tb, const char **te, int max)
{
    int n = 0;
    while (b < e && n < max) {
        while (b < e && (*b == ' ' || *b == '\t')) b++;
        if (b == e) break;
        tb[n] = b;
        while (b < e && *b != ' ' && *b != '\t') b++;
        te[n++] = b;
    }
    return n;
}

static int tok_is(const char *b, const char *e, const char *word)
{
    return (size_t)(e - b) == strlen(word) && memcmp(b, word, (size_t)(e - b)) == 0;
}

typedef struct {
    const char *path;
    size_t line;
    sy_error *err;
    obj_data *d;
    int has_origin;
    double origin[3];
} obj_ctx;

static sy_code read_comment(obj_ctx *c, int nt, const char **tb, const char **te)
{
    double v[3];
    if (nt >= 3 && tok_is(tb[1], te[1], "sylva") && tok_is(tb[2], te[2], "origin")) { /* "# sylva origin X Y Z" */
        if (nt != 6) return sy_fail(c->err, SY_EINPUT, "%s:%zu: malformed sylva origin comment", c->path, c->line);
        for (int k = 0; k < 3; k++)
            if (!sy_qsm_parse_number(tb[3 + k], te[3 + k], &c->origin[k]) || !isfinite(c->origin[k]))
                return sy_fail(c->err, SY_EINPUT, "%s:%zu: malformed sylva origin comment", c->path, c->line);
        c->has_origin = 1;
        return SY_OK;
    }
    if (nt < 3 || !tok_is(tb[1], te[1], "radius")) return SY_OK;
    obj_data *d = c->d;
    if (d->n == 0) return sy_fail(c->err, SY_EINPUT, "%s:%zu: radius comment before any vertex", c->path, c->line);
    size_t i = d->n - 1;
    if (!sy_qsm_parse_number(tb[2], te[2], &v[0]) || !isfinite(v[0]))
        return sy_fail(c->err, SY_EINPUT, "%s:%zu: malformed radius '%.*s'", c->path, c->line,
                       (int)(te[2] - tb[2] > 40 ? 40 : te[2] - tb[2]), tb[2]);
    if (v[0] < 0) return sy_fail(c->err, SY_EINPUT, "%s:%zu: negative radius %g", c->path, c->line, v[0]);
    if (!((float)v[0] > 0))
        return sy_fail(c->err, SY_EINPUT, "%s:%zu: radius %g is not positive", c->path, c->line, v[0]);
    d->radius[i] = (float)v[0];
    d->has_radius[i] = 1;
    if (nt >= 7 && tok_is(tb[3], te[3], "order") && tok_is(tb[5], te[5], "branch")) {
        if (!sy_qsm_parse_number(tb[4], te[4], &v[1]) || !sy_qsm_parse_number(tb[6], te[6], &v[2]) || v[1] < 0 ||
            v[1] > 255 || v[1] != floor(v[1]) || v[2] < 0 || v[2] > INT32_MAX || v[2] != floor(v[2]))
            return sy_fail(c->err, SY_EINPUT, "%s:%zu: malformed order or branch", c->path, c->line);
        d->order[i] = (int32_t)v[1];
        d->branch[i] = (int32_t)v[2];
        d->has_struct[i] = 1;
    }
    return SY_OK;
}

static sy_code read_vertex(obj_ctx *c, int nt, const char **tb, const char **te)
{
    obj_data *d = c->d;
    if (nt < 4) return sy_fail(c->err, SY_EINPUT, "%s:%zu: vertex needs x y z", c->path, c->line);
    if (d->n == d->cap && !grow_vertices(d)) return sy_fail(c->err, SY_EINTERNAL, "%s: out of memory", c->path);
    size_t i = d->n;
    for (int k = 0; k < 3; k++) {
        double v;
        if (!sy_qsm_parse_number(tb[1 + k], te[1 + k], &v))
            return sy_fail(c->err, SY_EINPUT, "%s:%zu: malformed number '%.*s'", c->path, c->line,
                           (int)(te[1 + k] - tb[1 + k] > 40 ? 40 : te[1 + k] - tb[1 + k]), tb[1 + k]);
        if (!isfinite(v)) return sy_fail(c->err, SY_EINPUT, "%s:%zu: coordinate is not finite", c->path, c->line);
        d->world[3 * i + k] = v;
    }
    d->vline[i] = c->line;
    d->has_radius[i] = d->has_struct[i] = 0;
    d->order[i] = d->branch[i] = 0;
    d->n++;
    return SY_OK;
}

/* `l a b c ...`: consecutive pairs are edges; indices are 1-based, negative
 * ones count back from the last vertex (OBJ's relative form). */
static sy_code read_line(obj_ctx *c, const char *b, const char *e)
{
    long prev = -1;
    int count = 0;
    const char *p = b + 1;
    for (;;) {
        while (p < e && (*p == ' ' || *p == '\t')) p++;
        if (p >= e) break;
        const char *q = p;
        while (q < e && *q != ' ' && *q != '\t') q++;
        const char *slash = memchr(p, '/', (size_t)(q - p)); /* l v/vt: keep v */
        double v;
        if (!sy_qsm_parse_number(p, slash ? slash : q, &v) || v != floor(v) || v == 0 || fabs(v) > 4e9)
            return sy_fail(c->err, SY_EINPUT, "%s:%zu: malformed vertex index '%.*s'", c->path, c->line,
                           (int)(q - p > 40 ? 40 : q - p), p);
        long idx = v > 0 ? (long)v - 1 : (long)c->d->n + (long)v;
        if (idx < 0) return sy_fail(c->err, SY_EINPUT, "%s:%zu: vertex index %g before the first vertex", c->path, c->line, v);
        if (prev >= 0 && !add_edge(c->d, (uint32_t)prev, (uint32_t)idx, c->line))
            return sy_fail(c->err, SY_EINTERNAL, "%s: out of memory", c->path);
        prev = idx;
        count++;
        p = q;
    }
    if (count < 2) return sy_fail(c->err, SY_EINPUT, "%s:%zu: a line needs two vertices", c->path, c->line);
    return SY_OK;
}

sy_code sy_skeleton_read_obj_mem(const char *path, const unsigned char *data, size_t size, sy_skeleton *out,
                                 sy_skeleton_read_info *info, sy_error *err)
{
    memset(out, 0, sizeof *out);
    obj_data d;
    memset(&d, 0, sizeof d);
    obj_ctx c = {path, 0, err, &d, 0, {0, 0, 0}};
    sy_lines L;
    sy_lines_init(&L, data, size);
    const char *b, *e, *tb[8], *te[8];
    sy_code rc = SY_OK;
    while (!rc && sy_lines_next(&L, &b, &e)) {
        c.line = L.line;
        sy_trim(&b, &e);
        int nt = tokens(b, e, tb, te, 8);
        if (nt == 0) continue;
        if (tok_is(tb[0], te[0], "#")) rc = read_comment(&c, nt, tb, te);
        else if (tok_is(tb[0], te[0], "v")) rc = read_vertex(&c, nt, tb, te);
        else if (tok_is(tb[0], te[0], "l")) rc = read_line(&c, b, e);
        else if (tok_is(tb[0], te[0], "f"))
            rc = sy_fail(err, SY_EINPUT, "%s:%zu: faces: a mesh, not a polyline skeleton", path, L.line);
    }
    int all_struct = 1;
    for (size_t i = 0; !rc && i < d.n; i++) {
        if (!d.has_radius[i])
            rc = sy_fail(err, SY_EINPUT, "%s:%zu: vertex %zu has no '# radius' comment", path, d.vline[i], i + 1);
        if (!d.has_struct[i]) all_struct = 0;
    }
    if (!rc) {
        sy_graph_in g = {d.n,     d.m,
                         d.world, d.radius,
                         all_struct ? d.order : NULL, all_struct ? d.branch : NULL,
                         d.edges, d.eline,
                         c.has_origin ? 0 : -1, c.has_origin ? c.origin : NULL};
        rc = sy_graph_to_skeleton(path, &g, out, info, err);
        if (!rc && info) {
            info->format = SY_SKEL_OBJ;
            info->origin_from_file = c.has_origin;
        }
    }
    obj_free(&d);
    return rc;
}
