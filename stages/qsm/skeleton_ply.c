/* Skeleton graphs in PLY, AdTree's layout: AdTree saves its smoothed skeleton
 * through Easy3D's GraphIO (binary little endian, `element vertex` with float
 * x y z and float radius, `element edge` with `property list uint32 int
 * vertex_indices`). Sylva adds int order and branch per vertex and a
 * "comment sylva origin" line; Easy3D keeps unknown vertex properties. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "qsm_internal.h"
#include "stages/core/fileio.h"

/* ------------------------------------------------------------ writing */

static void put_u32(FILE *fp, uint32_t v)
{
    unsigned char b[4] = {(unsigned char)v, (unsigned char)(v >> 8), (unsigned char)(v >> 16),
                          (unsigned char)(v >> 24)};
    fwrite(b, 1, 4, fp);
}

static void put_f32(FILE *fp, float f)
{
    uint32_t v;
    memcpy(&v, &f, 4);
    put_u32(fp, v);
}

static void put_f64(FILE *fp, double d)
{
    uint64_t v;
    memcpy(&v, &d, 8);
    put_u32(fp, (uint32_t)v);
    put_u32(fp, (uint32_t)(v >> 32));
}

sy_code sy_skeleton_write_ply(const char *path, const sy_skeleton *s, sy_error *err)
{
    sy_code rc = sy_skeleton_validate(s, err);
    if (rc) return rc;
    /* World coordinates: floats are exact only while the origin is zero;
     * otherwise doubles keep origin + pos exact. */
    int wide = s->origin[0] != 0 || s->origin[1] != 0 || s->origin[2] != 0;
    const char *ct = wide ? "double" : "float";
    sy_atomic_file f;
    if ((rc = sy_atomic_open(&f, path, err))) return rc;
    FILE *fp = f.fp;
    fprintf(fp,
            "ply\nformat binary_little_endian 1.0\ncomment Saved by Sylva (AdTree skeleton layout)\n"
            "comment sylva origin %.17g %.17g %.17g\nelement vertex %zu\nproperty %s x\nproperty %s y\n"
            "property %s z\nproperty float radius\nproperty int order\nproperty int branch\n"
            "element edge %zu\nproperty list uint32 int vertex_indices\nend_header\n",
            s->origin[0], s->origin[1], s->origin[2], s->n, ct, ct, ct, s->n - 1);
    for (size_t i = 0; i < s->n; i++) {
        for (int k = 0; k < 3; k++) {
            if (wide) put_f64(fp, s->origin[k] + (double)s->pos[3 * i + k]);
            else put_f32(fp, s->pos[3 * i + k]);
        }
        put_f32(fp, s->radius[i]);
        put_u32(fp, s->order[i]);
        put_u32(fp, (uint32_t)s->branch[i]);
    }
    for (size_t i = 0; i < s->n; i++) {
        if (s->parent[i] < 0) continue;
        put_u32(fp, 2);
        put_u32(fp, (uint32_t)s->parent[i]);
        put_u32(fp, (uint32_t)i);
    }
    return sy_atomic_commit(&f, err);
}

/* ------------------------------------------------------------ reading */

typedef enum { T_NONE, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 } ply_type;

static const struct {
    const char *name;
    ply_type t;
} TYPE_NAMES[] = {{"char", T_I8},    {"int8", T_I8},    {"uchar", T_U8},  {"uint8", T_U8},   {"short", T_I16},
                  {"int16", T_I16},  {"ushort", T_U16}, {"uint16", T_U16}, {"int", T_I32},   {"int32", T_I32},
                  {"uint", T_U32},   {"uint32", T_U32}, {"float", T_F32}, {"float32", T_F32}, {"double", T_F64},
                  {"float64", T_F64}};

static const int TYPE_SIZE[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};

static ply_type type_of(const char *name)
{
    for (size_t i = 0; i < sizeof TYPE_NAMES / sizeof TYPE_NAMES[0]; i++)
        if (strcmp(name, TYPE_NAMES[i].name) == 0) return TYPE_NAMES[i].t;
    return T_NONE;
}

#define MAX_ELEMENTS 16
#define MAX_PROPS 32

typedef struct {
    char name[32];
    ply_type type;  /* value type */
    ply_type count; /* list count type, T_NONE for scalars */
} ply_prop;

typedef struct {
    char name[32];
    size_t count;
    int nprops;
    ply_prop props[MAX_PROPS];
} ply_element;

typedef struct {
    const char *path;
    int format; /* 0 ascii, 1 little endian, 2 big endian */
    int nel;
    ply_element el[MAX_ELEMENTS];
    int has_origin;
    double origin[3];
    const unsigned char *p, *end; /* the body */
    size_t line;                 /* ASCII: current line */
    sy_error *err;
} ply_reader;

static sy_code header_fail(ply_reader *r, size_t line, const char *what)
{
    return sy_fail(r->err, SY_EINPUT, "%s:%zu: %s", r->path, line, what);
}

static sy_code parse_header_line(ply_reader *r, char *text, size_t line)
{
    char *save = NULL, *kw = strtok_r(text, " \t", &save);
    if (!kw) return SY_OK;
    if (strcmp(kw, "format") == 0) {
        char *fmt = strtok_r(NULL, " \t", &save);
        if (fmt && strcmp(fmt, "ascii") == 0) r->format = 0;
        else if (fmt && strcmp(fmt, "binary_little_endian") == 0) r->format = 1;
        else if (fmt && strcmp(fmt, "binary_big_endian") == 0) r->format = 2;
        else return header_fail(r, line, "unknown PLY format");
        return SY_OK;
    }
    if (strcmp(kw, "comment") == 0 || strcmp(kw, "obj_info") == 0) {
        char *a = strtok_r(NULL, " \t", &save), *b = strtok_r(NULL, " \t", &save);
        if (a && b && strcmp(a, "sylva") == 0 && strcmp(b, "origin") == 0) {
            for (int k = 0; k < 3; k++) {
                char *v = strtok_r(NULL, " \t", &save);
                if (!v || !sy_qsm_parse_number(v, v + strlen(v), &r->origin[k]) || !isfinite(r->origin[k]))
                    return header_fail(r, line, "malformed sylva origin comment");
            }
            r->has_origin = 1;
        }
        return SY_OK;
    }
    if (strcmp(kw, "element") == 0) {
        char *name = strtok_r(NULL, " \t", &save), *cnt = strtok_r(NULL, " \t", &save);
        double c;
        if (!name || !cnt || !sy_qsm_parse_number(cnt, cnt + strlen(cnt), &c) || c < 0 || c != floor(c) || c > 4e9)
            return header_fail(r, line, "malformed element line");
        if (r->nel == MAX_ELEMENTS) return header_fail(r, line, "too many elements");
        ply_element *e = &r->el[r->nel++];
        memset(e, 0, sizeof *e);
        snprintf(e->name, sizeof e->name, "%s", name);
        e->count = (size_t)c;
        return SY_OK;
    }
    if (strcmp(kw, "property") == 0) {
        if (r->nel == 0) return header_fail(r, line, "property before any element");
        ply_element *e = &r->el[r->nel - 1];
        if (e->nprops == MAX_PROPS) return header_fail(r, line, "too many properties");
        ply_prop *p = &e->props[e->nprops];
        char *t = strtok_r(NULL, " \t", &save);
        if (t && strcmp(t, "list") == 0) {
            char *ct = strtok_r(NULL, " \t", &save);
            p->count = ct ? type_of(ct) : T_NONE;
            if (p->count == T_NONE || p->count == T_F32 || p->count == T_F64)
                return header_fail(r, line, "bad list count type");
            t = strtok_r(NULL, " \t", &save);
        }
        p->type = t ? type_of(t) : T_NONE;
        char *name = strtok_r(NULL, " \t", &save);
        if (p->type == T_NONE || !name) return header_fail(r, line, "malformed property line");
        snprintf(p->name, sizeof p->name, "%s", name);
        e->nprops++;
        return SY_OK;
    }
    return header_fail(r, line, "unexpected header line");
}

static sy_code parse_header(ply_reader *r, const unsigned char *data, size_t size)
{
    const char *p = (const char *)data, *end = p + size;
    size_t line = 0;
    int saw_format = 0;
    for (;;) {
        const char *q = p;
        while (q < end && *q != '\n') q++;
        if (q >= end) return sy_fail(r->err, SY_EINPUT, "%s: PLY header has no end_header", r->path);
        line++;
        size_t len = (size_t)(q - p);
        if (len && p[len - 1] == '\r') len--;
        char text[256];
        if (len >= sizeof text) return header_fail(r, line, "header line too long");
        memcpy(text, p, len);
        text[len] = '\0';
        p = q + 1;
        if (line == 1) {
            if (strcmp(text, "ply") != 0) return header_fail(r, line, "not a PLY file");
            continue;
        }
        if (strcmp(text, "end_header") == 0) break;
        if (strncmp(text, "format", 6) == 0) saw_format = 1;
        sy_code rc = parse_header_line(r, text, line);
        if (rc) return rc;
    }
    if (!saw_format) return header_fail(r, line, "PLY header has no format line");
    r->p = (const unsigned char *)p;
    r->end = (const unsigned char *)end;
    r->line = line + 1;
    return SY_OK;
}

static void where(const ply_reader *r, const char *el, size_t idx, char *buf, size_t size)
{
    if (r->format == 0) snprintf(buf, size, "%zu", r->line);
    else snprintf(buf, size, " %s %zu", el, idx);
}

/* Next value of type t as a double; 0 when the data ran out or is malformed. */
static int next_value(ply_reader *r, ply_type t, double *out)
{
    if (r->format == 0) {
        while (r->p < r->end && (*r->p == ' ' || *r->p == '\t' || *r->p == '\r' || *r->p == '\n')) {
            if (*r->p == '\n') r->line++;
            r->p++;
        }
        const unsigned char *b = r->p;
        while (r->p < r->end && !(*r->p == ' ' || *r->p == '\t' || *r->p == '\r' || *r->p == '\n')) r->p++;
        return sy_qsm_parse_number((const char *)b, (const char *)r->p, out);
    }
    int n = TYPE_SIZE[t];
    if (r->end - r->p < n) return 0;
    unsigned char b[8];
    for (int i = 0; i < n; i++) b[i] = r->p[r->format == 1 ? i : n - 1 - i];
    r->p += n;
    switch (t) {
    case T_I8: *out = (int8_t)b[0]; break;
    case T_U8: *out = b[0]; break;
    case T_I16: *out = (int16_t)(b[0] | b[1] << 8); break;
    case T_U16: *out = (uint16_t)(b[0] | b[1] << 8); break;
    case T_I32: *out = (int32_t)((uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24); break;
    case T_U32: *out = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24; break;
    case T_F32: {
        uint32_t v = (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
        float f;
        memcpy(&f, &v, 4);
        *out = f;
        break;
    }
    case T_F64: {
        uint64_t v = 0;
        for (int i = 7; i >= 0; i--) v = v << 8 | b[i];
        memcpy(out, &v, 8);
        break;
    }
    default: return 0;
    }
    return 1;
}

/* Smallest number of body bytes one instance of e can take, so a count can
 * be checked against the bytes present before allocating. */
static size_t min_instance_bytes(const ply_reader *r, const ply_element *e)
{
    size_t b = 0;
    for (int i = 0; i < e->nprops; i++)
        b += r->format == 0 ? 2 : (size_t)TYPE_SIZE[e->props[i].count ? e->props[i].count : e->props[i].type];
    return b ? b : 1;
}

typedef struct {
    double *world;
    float *radius;
    int32_t *order, *branch;
    uint32_t *edges;
    size_t *edge_line;
    size_t n, m;
} ply_data;

static void data_free(ply_data *d)
{
    free(d->world);
    free(d->radius);
    free(d->order);
    free(d->branch);
    free(d->edges);
    free(d->edge_line);
}

static int prop_index(const ply_element *e, const char *name)
{
    for (int i = 0; i < e->nprops; i++)
        if (strcmp(e->props[i].name, name) == 0) return i;
    return -1;
}

static sy_code read_vertices(ply_reader *r, const ply_element *e, ply_data *d)
{
    int ix = prop_index(e, "x"), iy = prop_index(e, "y"), iz = prop_index(e, "z");
    int ir = prop_index(e, "radius"), io = prop_index(e, "order"), ib = prop_index(e, "branch");
    if (ix < 0 || iy < 0 || iz < 0) return sy_fail(r->err, SY_EINPUT, "%s: vertex has no x y z", r->path);
    if (ir < 0) return sy_fail(r->err, SY_EINPUT, "%s: vertex has no radius property", r->path);
    size_t n = e->count;
    d->n = n;
    d->world = sy_calloc(n ? n : 1, 3 * sizeof(double), r->err, "ply");
    d->radius = sy_calloc(n ? n : 1, sizeof(float), r->err, "ply");
    if (io >= 0 && ib >= 0) {
        d->order = sy_calloc(n ? n : 1, sizeof(int32_t), r->err, "ply");
        d->branch = sy_calloc(n ? n : 1, sizeof(int32_t), r->err, "ply");
        if (!d->order || !d->branch) return SY_EINTERNAL;
    }
    if (!d->world || !d->radius) return SY_EINTERNAL;
    char at[48];
    for (size_t i = 0; i < n; i++) {
        for (int k = 0; k < e->nprops; k++) {
            const ply_prop *p = &e->props[k];
            double v, cnt = 1;
            where(r, "vertex", i, at, sizeof at);
            if (p->count && !next_value(r, p->count, &cnt))
                return sy_fail(r->err, SY_EINPUT, "%s:%s: truncated or malformed vertex data", r->path, at);
            for (double j = 0; j < cnt; j++)
                if (!next_value(r, p->type, &v))
                    return sy_fail(r->err, SY_EINPUT, "%s:%s: truncated or malformed vertex data", r->path, at);
            if (p->count) continue;
            if ((k == ix || k == iy || k == iz || k == ir) && !isfinite(v))
                return sy_fail(r->err, SY_EINPUT, "%s:%s: %s is not finite", r->path, at, p->name);
            if (k == ix) d->world[3 * i] = v;
            else if (k == iy) d->world[3 * i + 1] = v;
            else if (k == iz) d->world[3 * i + 2] = v;
            else if (k == ir) {
                if (v < 0) return sy_fail(r->err, SY_EINPUT, "%s:%s: negative radius %g", r->path, at, v);
                if (!((float)v > 0))
                    return sy_fail(r->err, SY_EINPUT, "%s:%s: radius %g is not positive", r->path, at, v);
                d->radius[i] = (float)v;
            } else if (k == io && d->order) {
                if (v < 0 || v > 255 || v != floor(v))
                    return sy_fail(r->err, SY_EINPUT, "%s:%s: order %g outside 0..255", r->path, at, v);
                d->order[i] = (int32_t)v;
            } else if (k == ib && d->branch) {
                if (v < 0 || v > INT32_MAX || v != floor(v))
                    return sy_fail(r->err, SY_EINPUT, "%s:%s: branch %g is not a non-negative integer", r->path,
                                   at, v);
                d->branch[i] = (int32_t)v;
            }
        }
    }
    return SY_OK;
}

static sy_code read_edges(ply_reader *r, const ply_element *e, ply_data *d)
{
    int il = prop_index(e, "vertex_indices");
    if (il < 0) il = prop_index(e, "vertex_index");
    int i1 = prop_index(e, "vertex1"), i2 = prop_index(e, "vertex2");
    if (il >= 0 && !e->props[il].count) il = -1;
    if (il < 0 && (i1 < 0 || i2 < 0))
        return sy_fail(r->err, SY_EINPUT, "%s: edge has neither vertex_indices nor vertex1 vertex2", r->path);
    size_t m = e->count;
    d->m = m;
    d->edges = sy_calloc(m ? 2 * m : 1, sizeof(uint32_t), r->err, "ply");
    if (r->format == 0) d->edge_line = sy_calloc(m ? m : 1, sizeof(size_t), r->err, "ply");
    if (!d->edges || (r->format == 0 && !d->edge_line)) return SY_EINTERNAL;
    char at[48];
    for (size_t i = 0; i < m; i++) {
        for (int k = 0; k < e->nprops; k++) {
            const ply_prop *p = &e->props[k];
            double v, cnt = 1;
            where(r, "edge", i, at, sizeof at);
            if (p->count && !next_value(r, p->count, &cnt))
                return sy_fail(r->err, SY_EINPUT, "%s:%s: truncated or malformed edge data", r->path, at);
            if (k == il && cnt != 2)
                return sy_fail(r->err, SY_EINPUT, "%s:%s: edge lists %g vertices, expected 2", r->path, at, cnt);
            for (int j = 0; j < (int)cnt; j++) {
                if (!next_value(r, p->type, &v))
                    return sy_fail(r->err, SY_EINPUT, "%s:%s: truncated or malformed edge data", r->path, at);
                int slot = k == il ? j : k == i1 ? 0 : k == i2 ? 1 : -1;
                if (slot < 0) continue;
                if (v < 0 || v >= 4294967295.0 || v != floor(v))
                    return sy_fail(r->err, SY_EINPUT, "%s:%s: bad vertex index %g", r->path, at, v);
                d->edges[2 * i + slot] = (uint32_t)v;
            }
            if (d->edge_line) d->edge_line[i] = r->line;
        }
    }
    return SY_OK;
}

/* Skips an element the skeleton does not use (faces, custom data). */
static sy_code skip_element(ply_reader *r, const ply_element *e)
{
    for (size_t i = 0; i < e->count; i++)
        for (int k = 0; k < e->nprops; k++) {
            double v, cnt = 1;
            if (e->props[k].count && !next_value(r, e->props[k].count, &cnt))
                return sy_fail(r->err, SY_EINPUT, "%s: truncated %s data", r->path, e->name);
            for (double j = 0; j < cnt; j++)
                if (!next_value(r, e->props[k].type, &v))
                    return sy_fail(r->err, SY_EINPUT, "%s: truncated %s data", r->path, e->name);
        }
    return SY_OK;
}

sy_code sy_skeleton_read_ply_mem(const char *path, const unsigned char *data, size_t size, sy_skeleton *out,
                                 sy_skeleton_read_info *info, sy_error *err)
{
    memset(out, 0, sizeof *out);
    ply_reader *r = calloc(1, sizeof *r);
    if (!r) return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    r->path = path;
    r->err = err;
    ply_data d;
    memset(&d, 0, sizeof d);
    sy_code rc = parse_header(r, data, size);
    int seen_v = 0, seen_e = 0, float_xyz = 1;
    for (int i = 0; !rc && i < r->nel; i++) {
        const ply_element *e = &r->el[i];
        /* +1: the last ASCII value needs no separator after it. */
        size_t avail = (size_t)(r->end - r->p) + (r->format == 0);
        if (e->count > avail / min_instance_bytes(r, e)) {
            rc = sy_fail(err, SY_EINPUT, "%s: element %s claims %zu entries, more than the file holds", path,
                         e->name, e->count);
            break;
        }
        if (strcmp(e->name, "vertex") == 0 && !seen_v) {
            seen_v = 1;
            int ix = prop_index(e, "x");
            float_xyz = ix >= 0 && e->props[ix].type != T_F64;
            rc = read_vertices(r, e, &d);
        } else if (strcmp(e->name, "edge") == 0 && !seen_e) {
            seen_e = 1;
            rc = read_edges(r, e, &d);
        } else rc = skip_element(r, e);
    }
    if (!rc && !seen_v) rc = sy_fail(err, SY_EINPUT, "%s: no vertex element", path);
    if (!rc && !seen_e && d.n > 1) rc = sy_fail(err, SY_EINPUT, "%s: no edge element", path);
    if (!rc) {
        /* Floats are what they are: shifting them by floor(root) only adds
         * rounding, so float files keep origin 0 unless they name one. */
        static const double zero[3] = {0, 0, 0};
        sy_graph_in g = {d.n, d.m, d.world, d.radius, d.order, d.branch, d.edges, d.edge_line,
                         r->has_origin ? 0 : -1, r->has_origin ? r->origin : float_xyz ? zero : NULL};
        rc = sy_graph_to_skeleton(path, &g, out, info, err);
        if (!rc && info) {
            info->format = SY_SKEL_PLY;
            info->origin_from_file = r->has_origin;
        }
    }
    data_free(&d);
    free(r);
    return rc;
}
