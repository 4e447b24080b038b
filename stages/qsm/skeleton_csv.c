/* Cylinder tables with the SimpleForest / rTwig column names (the layout of
 * rTwig's inst/extdata/QSM.csv): one cylinder per skeleton edge. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "qsm_internal.h"
#include "stages/core/fileio.h"
#include "stages/core/array.h"

/* A start within this distance of its parent's end is that end node. */
#define CSV_JOIN_TOL 1e-6

enum { C_ID, C_PARENT, C_SX, C_SY, C_SZ, C_EX, C_EY, C_EZ, C_RADIUS, C_ORDER, C_SEGMENT, C_COUNT };

static const char *const COL_NAMES[C_COUNT] = {"ID",   "parentID", "startX", "startY", "startZ",    "endX",
                                               "endY", "endZ",     "radius", "branchOrder", "segmentID"};
#define C_REQUIRED C_ORDER /* the columns before this one must be present */

#define MAX_FIELDS 256

/* Splits [b, e) at commas into trimmed, unquoted fields; returns the count
 * or -1 when there are more than MAX_FIELDS. */
static int split_fields(const char *b, const char *e, const char **fb, const char **fe)
{
    int n = 0;
    for (const char *p = b;;) {
        const char *q = p;
        while (q < e && *q != ',') q++;
        if (n == MAX_FIELDS) return -1;
        const char *x = p, *y = q;
        sy_trim(&x, &y);
        if (y - x >= 2 && *x == '"' && y[-1] == '"') {
            x++;
            y--;
        }
        fb[n] = x;
        fe[n] = y;
        n++;
        if (q >= e) break;
        p = q + 1;
    }
    return n;
}

typedef struct {
    const char *path;
    size_t line;
    sy_error *err;
} row_ctx;

static sy_code field_number(const row_ctx *r, const char *b, const char *e, int col, double *v)
{
    if (!sy_qsm_parse_number(b, e, v))
        return sy_fail(r->err, SY_EINPUT, "%s:%zu: malformed number '%.*s' in column %s", r->path, r->line,
                       (int)(e - b > 40 ? 40 : e - b), b, COL_NAMES[col]);
    if (!isfinite(*v))
        return sy_fail(r->err, SY_EINPUT, "%s:%zu: %s is not finite", r->path, r->line, COL_NAMES[col]);
    return SY_OK;
}

static sy_code field_int(const row_ctx *r, const char *b, const char *e, int col, long long lo, long long hi,
                         long long *v)
{
    double d;
    sy_code rc = field_number(r, b, e, col, &d);
    if (rc) return rc;
    if (d != floor(d) || d < (double)lo || d > (double)hi)
        return sy_fail(r->err, SY_EINPUT, "%s:%zu: %s %.*s is not an integer in [%lld, %lld]", r->path, r->line,
                       COL_NAMES[col], (int)(e - b > 40 ? 40 : e - b), b, lo, hi);
    *v = (long long)d;
    return SY_OK;
}

static sy_code parse_row(const row_ctx *r, const int *col, const char **fb, const char **fe, sy_cyl *c)
{
    sy_code rc;
    long long v = 0;
    memset(c, 0, sizeof *c);
    c->line = r->line;
    if ((rc = field_int(r, fb[col[C_ID]], fe[col[C_ID]], C_ID, 0, (1LL << 53), &v))) return rc;
    c->id = v;
    /* An empty parentID marks a root, as -1 does. */
    if (fb[col[C_PARENT]] == fe[col[C_PARENT]]) c->parent_id = -1;
    else if ((rc = field_int(r, fb[col[C_PARENT]], fe[col[C_PARENT]], C_PARENT, -1, (1LL << 53), &v))) return rc;
    else c->parent_id = v;
    for (int k = 0; k < 3; k++) {
        if ((rc = field_number(r, fb[col[C_SX + k]], fe[col[C_SX + k]], C_SX + k, &c->start[k]))) return rc;
        if ((rc = field_number(r, fb[col[C_EX + k]], fe[col[C_EX + k]], C_EX + k, &c->end[k]))) return rc;
    }
    double rad;
    if ((rc = field_number(r, fb[col[C_RADIUS]], fe[col[C_RADIUS]], C_RADIUS, &rad))) return rc;
    if (rad < 0) return sy_fail(r->err, SY_EINPUT, "%s:%zu: negative radius %g", r->path, r->line, rad);
    if (!((float)rad > 0)) return sy_fail(r->err, SY_EINPUT, "%s:%zu: radius %g is not positive", r->path, r->line, rad);
    c->radius = (float)rad;
    c->order = -1;
    c->branch = -1;
    if (col[C_ORDER] >= 0) {
        if ((rc = field_int(r, fb[col[C_ORDER]], fe[col[C_ORDER]], C_ORDER, 0, 255, &v))) return rc;
        c->order = (int)v;
    }
    if (col[C_SEGMENT] >= 0) {
        if ((rc = field_int(r, fb[col[C_SEGMENT]], fe[col[C_SEGMENT]], C_SEGMENT, 0, INT32_MAX, &v))) return rc;
        c->branch = (int32_t)v;
    }
    return SY_OK;
}

static sy_code map_header(const char *path, size_t line, int nf, const char **fb, const char **fe, int *col,
                          sy_error *err)
{
    for (int k = 0; k < C_COUNT; k++) col[k] = -1;
    for (int f = 0; f < nf; f++)
        for (int k = 0; k < C_COUNT; k++)
            if ((size_t)(fe[f] - fb[f]) == strlen(COL_NAMES[k]) &&
                strncasecmp(fb[f], COL_NAMES[k], strlen(COL_NAMES[k])) == 0) {
                if (col[k] >= 0)
                    return sy_fail(err, SY_EINPUT, "%s:%zu: column %s appears twice", path, line, COL_NAMES[k]);
                col[k] = f;
            }
    for (int k = 0; k < C_REQUIRED; k++)
        if (col[k] < 0) return sy_fail(err, SY_EINPUT, "%s:%zu: missing column %s", path, line, COL_NAMES[k]);
    return SY_OK;
}

sy_code sy_skeleton_read_csv_mem(const char *path, const unsigned char *data, size_t size, sy_skeleton *out,
                                 sy_skeleton_read_info *info, sy_error *err)
{
    memset(out, 0, sizeof *out);
    if (size >= 3 && data[0] == 0xEF && data[1] == 0xBB && data[2] == 0xBF) {
        data += 3; /* UTF-8 byte order mark */
        size -= 3;
    }
    const char *fb[MAX_FIELDS], *fe[MAX_FIELDS];
    int col[C_COUNT], nf = 0, header = 0;
    sy_lines L;
    sy_lines_init(&L, data, size);
    const char *b, *e;
    sy_cyl *cyl = NULL;
    size_t n = 0, cap = 0;
    sy_code rc = SY_OK;
    while (!rc && sy_lines_next(&L, &b, &e)) {
        sy_trim(&b, &e);
        if (b == e) continue;
        int got = split_fields(b, e, fb, fe);
        if (got < 0) {
            rc = sy_fail(err, SY_EINPUT, "%s:%zu: more than %d columns", path, L.line, MAX_FIELDS);
            break;
        }
        if (!header) {
            nf = got;
            header = 1;
            rc = map_header(path, L.line, nf, fb, fe, col, err);
            continue;
        }
        if (got != nf) {
            rc = sy_fail(err, SY_EINPUT, "%s:%zu: %d fields, the header has %d", path, L.line, got, nf);
            break;
        }
        if ((rc = sy_array_reserve(&cyl, &cap, n + 1, sizeof *cyl, 256, err, path))) break;
        row_ctx r = {path, L.line, err};
        rc = parse_row(&r, col, fb, fe, &cyl[n]);
        if (!rc) n++;
    }
    if (!rc && !header) rc = sy_fail(err, SY_EINPUT, "%s: empty file, expected a cylinder table header", path);
    if (!rc) rc = sy_cylinders_to_skeleton(path, cyl, n, CSV_JOIN_TOL, out, info, err);
    if (!rc && info) info->format = SY_SKEL_CSV;
    free(cyl);
    return rc;
}

/* ------------------------------------------------------------ writing */

typedef struct {
    int32_t *id;      /* cylinder ID per node, -1: the root has none */
    int32_t *psid;    /* parentSegmentID per node */
    int32_t *bid;     /* branchID per node: the stem's, or the first-order branch it grows on */
    int32_t *rbo;
    double *growth;
    int root_cyl;     /* the root has its own zero-length cylinder */
} csv_plan;

static void plan_free(csv_plan *p)
{
    free(p->id);
    free(p->psid);
    free(p->bid);
    free(p->rbo);
    free(p->growth);
}

/* The root needs a cylinder of its own unless its single child's cylinder
 * carries the same radius, order and branch (then a reader recovers the root
 * from that cylinder's start, as with TreeQSM's first stem cylinder). */
static int root_needs_cylinder(const sy_skeleton *s, const sy_skel_topo *t)
{
    int32_t r = t->root;
    if (t->first[r + 1] - t->first[r] != 1) return 1;
    int32_t c = t->child[t->first[r]];
    return !(s->radius[c] == s->radius[r] && s->order[c] == s->order[r] && s->branch[c] == s->branch[r]);
}

static sy_code make_plan(const sy_skeleton *s, const sy_skel_topo *t, csv_plan *p, sy_error *err)
{
    size_t n = s->n;
    memset(p, 0, sizeof *p);
    p->id = sy_calloc(n, sizeof(int32_t), err, "csv");
    p->psid = sy_calloc(n, sizeof(int32_t), err, "csv");
    p->bid = sy_calloc(n, sizeof(int32_t), err, "csv");
    p->rbo = sy_calloc(n, sizeof(int32_t), err, "csv");
    p->growth = sy_calloc(n, sizeof(double), err, "csv");
    if (!p->id || !p->psid || !p->bid || !p->rbo || !p->growth) return SY_EINTERNAL;
    sy_code rc = sy_skeleton_growth_length(s, p->growth, err);
    if (!rc) rc = sy_skeleton_reverse_order(s, p->rbo, err);
    if (rc) return rc;
    p->root_cyl = root_needs_cylinder(s, t);
    int32_t next = 0;
    if (p->root_cyl) p->id[t->root] = next++;
    else p->id[t->root] = -1;
    for (size_t i = 0; i < n; i++)
        if ((int32_t)i != t->root) p->id[i] = next++;
    for (size_t k = 0; k < n; k++) {
        int32_t v = t->bfs[k], par = s->parent[v];
        if (par < 0) {
            p->psid[v] = -1;
            p->bid[v] = s->branch[v];
            continue;
        }
        p->psid[v] = s->branch[par] != s->branch[v] ? s->branch[par] : p->psid[par];
        /* rTwig's branchID: 0-order cylinders all belong to the stem; each
         * branch leaving it numbers its whole subtree. */
        p->bid[v] = s->order[v] == 0 ? s->branch[t->root] : s->order[par] == 0 ? s->branch[v] : p->bid[par];
    }
    return SY_OK;
}

static void put_coords(FILE *fp, const sy_skeleton *s, int32_t node, const double ro[3])
{
    char buf[40];
    for (int k = 0; k < 3; k++) {
        sy_fmt_coord(buf, sizeof buf, s->origin[k] + (double)s->pos[3 * node + k], ro[k]);
        fprintf(fp, ",%s", buf);
    }
}

static void put_row(FILE *fp, const sy_skeleton *s, const csv_plan *p, int32_t node, int32_t from,
                    const double ro[3])
{
    char rad[32];
    int32_t par = s->parent[node];
    int32_t pid = par >= 0 ? p->id[par] : -1;
    double len = node == from ? 0 : sy_skel_edge_length(s, node);
    sy_fmt_float(rad, sizeof rad, s->radius[node]);
    fprintf(fp, "%d,%d", p->id[node], pid);
    put_coords(fp, s, from, ro);
    put_coords(fp, s, node, ro);
    fprintf(fp, ",%s,%.9g,%.9g,0,%d,%d,%d,%d,%d\n", rad, len, p->growth[node], s->branch[node], p->psid[node],
            s->order[node], p->rbo[node], p->bid[node]);
}

sy_code sy_skeleton_write_csv(const char *path, const sy_skeleton *s, sy_error *err)
{
    sy_code rc = sy_skeleton_validate(s, err);
    if (rc) return rc;
    if (s->n < 2) return sy_fail(err, SY_EINPUT, "%s: a cylinder table needs at least two nodes", path);
    sy_skel_topo t;
    if ((rc = sy_skel_topo_build(s, &t, err))) return rc;
    csv_plan plan;
    rc = make_plan(s, &t, &plan, err);
    sy_atomic_file f;
    if (!rc) rc = sy_atomic_open(&f, path, err);
    if (!rc) {
        /* Readers take floor(root) as origin; print coordinates for it. */
        double rw[3], ro[3];
        for (int k = 0; k < 3; k++) rw[k] = s->origin[k] + (double)s->pos[3 * t.root + k];
        sy_origin_floor(rw, ro);
        fputs("ID,parentID,startX,startY,startZ,endX,endY,endZ,radius,length,growthLength,"
              "averagePointDistance,segmentID,parentSegmentID,branchOrder,reverseBranchOrder,branchID\n",
              f.fp);
        if (plan.root_cyl) put_row(f.fp, s, &plan, t.root, t.root, ro);
        for (size_t i = 0; i < s->n; i++)
            if ((int32_t)i != t.root) put_row(f.fp, s, &plan, (int32_t)i, s->parent[i], ro);
        rc = sy_atomic_commit(&f, err);
    }
    plan_free(&plan);
    sy_skel_topo_free(&t);
    return rc;
}
