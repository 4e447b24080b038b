/* PLY point clouds: ascii, binary_little_endian and binary_big_endian.
 *
 * Any number of elements in any order; only "vertex" is read, the elements
 * before it are skipped item by item (list lengths are read per item). Vertex
 * properties in any order, every PLY type name (char..double and
 * int8..float64). Mapping: x y z (required) | nx ny nz -> normals |
 * red green blue (r g b, diffuse_*) -> 16-bit rgb: 8-bit types *257, 16-bit
 * kept, floats taken as 0..1 | alpha ignored | intensity -> uint16 (rounded,
 * clamped) | classification, gps_time, nir, return_number,
 * number_of_returns -> their arrays | list properties skipped | every other
 * scalar -> a named attribute, "scalar_" prefix removed.
 *
 * The writer emits binary little endian with double x y z (world
 * coordinates, so survey positions survive), float normals, uchar colours,
 * ushort intensity, uchar classification and double attributes. */
#include "ingest.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../core/fileio.h"
#include "textnum.h"

#define PLY_MAX_ELEMENTS 64
#define PLY_MAX_PROPS 1024

typedef enum { T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 } ply_type;

typedef enum {
    P_ATTR, P_X, P_Y, P_Z, P_NX, P_NY, P_NZ, P_R, P_G, P_B, P_INTENSITY, P_CLASS, P_GPS_TIME,
    P_NIR, P_RETURN, P_NUM_RETURNS, P_IGNORE
} prop_role;

typedef struct {
    char name[64];
    ply_type type;
    int is_list;
    ply_type count_type;
    prop_role role;
    double *attr; /* destination for P_ATTR */
} ply_prop;

typedef struct {
    char name[64];
    uint64_t count;
    int first_prop, n_props;
} ply_element;

typedef enum { ENC_ASCII, ENC_LE, ENC_BE } ply_encoding;

typedef struct {
    const char *path;
    ply_encoding enc;
    char version[8];
    ply_element elems[PLY_MAX_ELEMENTS];
    int n_elems;
    ply_prop props[PLY_MAX_PROPS];
    int n_props;
    const unsigned char *p, *end; /* data cursor */
} ply_file;

static const struct {
    const char *name;
    ply_type type;
} type_names[] = {
    {"char", T_I8},   {"int8", T_I8},     {"uchar", T_U8},    {"uint8", T_U8},
    {"short", T_I16}, {"int16", T_I16},   {"ushort", T_U16},  {"uint16", T_U16},
    {"int", T_I32},   {"int32", T_I32},   {"uint", T_U32},    {"uint32", T_U32},
    {"float", T_F32}, {"float32", T_F32}, {"double", T_F64},  {"float64", T_F64},
};

static const size_t type_size[] = {1, 1, 2, 2, 4, 4, 4, 8};

static int parse_type(const char *name, ply_type *t)
{
    for (size_t i = 0; i < sizeof type_names / sizeof type_names[0]; i++)
        if (strcmp(name, type_names[i].name) == 0) {
            *t = type_names[i].type;
            return 1;
        }
    return 0;
}

/* ---- header ---- */

/* Splits a header line into at most max blank-separated tokens (copied). */
static int split(const char *s, const char *e, char tok[][64], int max)
{
    int n = 0;
    while (s < e && n < max) {
        while (s < e && (*s == ' ' || *s == '\t')) s++;
        const char *t = s;
        while (s < e && *s != ' ' && *s != '\t') s++;
        if (s == t) break;
        snprintf(tok[n], 64, "%.*s", (int)(s - t), t);
        for (char *c = tok[n]; *c; c++)
            if ((unsigned char)*c < 32 || *c == 127) *c = '?';
        n++;
    }
    return n;
}

static int parse_count(const char *s, uint64_t *out)
{
    uint64_t v = 0;
    if (!*s) return 0;
    for (; *s; s++) {
        if (*s < '0' || *s > '9' || v > (UINT64_MAX - 9) / 10) return 0;
        v = v * 10 + (uint64_t)(*s - '0');
    }
    *out = v;
    return 1;
}

static sy_code header_format(ply_file *f, char tok[][64], int n, sy_error *err)
{
    if (n < 2) return sy_fail(err, SY_EINPUT, "%s: format line without an encoding", f->path);
    if (strcmp(tok[1], "ascii") == 0) f->enc = ENC_ASCII;
    else if (strcmp(tok[1], "binary_little_endian") == 0) f->enc = ENC_LE;
    else if (strcmp(tok[1], "binary_big_endian") == 0) f->enc = ENC_BE;
    else return sy_fail(err, SY_EINPUT, "%s: unknown PLY encoding '%s'", f->path, tok[1]);
    snprintf(f->version, sizeof f->version, "%s", n > 2 ? tok[2] : "1.0");
    return SY_OK;
}

static sy_code header_element(ply_file *f, char tok[][64], int n, sy_error *err)
{
    if (n != 3) return sy_fail(err, SY_EINPUT, "%s: element line needs a name and a count", f->path);
    if (f->n_elems == PLY_MAX_ELEMENTS)
        return sy_fail(err, SY_EINPUT, "%s: more than %d elements", f->path, PLY_MAX_ELEMENTS);
    ply_element *el = &f->elems[f->n_elems];
    if (!parse_count(tok[2], &el->count))
        return sy_fail(err, SY_EINPUT, "%s: element '%s' has a bad count '%s'", f->path, tok[1], tok[2]);
    snprintf(el->name, sizeof el->name, "%s", tok[1]);
    el->first_prop = f->n_props;
    el->n_props = 0;
    f->n_elems++;
    return SY_OK;
}

static sy_code header_property(ply_file *f, char tok[][64], int n, sy_error *err)
{
    if (f->n_elems == 0) return sy_fail(err, SY_EINPUT, "%s: property before any element", f->path);
    if (f->n_props == PLY_MAX_PROPS)
        return sy_fail(err, SY_EINPUT, "%s: more than %d properties", f->path, PLY_MAX_PROPS);
    ply_prop *pr = &f->props[f->n_props];
    memset(pr, 0, sizeof *pr);
    int is_list = n >= 2 && strcmp(tok[1], "list") == 0;
    if (n != (is_list ? 5 : 3))
        return sy_fail(err, SY_EINPUT, "%s: malformed property line (%s)", f->path,
                       is_list ? "property list COUNT_TYPE ITEM_TYPE NAME" : "property TYPE NAME");
    const char *tname = is_list ? tok[3] : tok[1];
    if (!parse_type(tname, &pr->type))
        return sy_fail(err, SY_EINPUT, "%s: unknown property type '%s'", f->path, tname);
    if (is_list && !parse_type(tok[2], &pr->count_type))
        return sy_fail(err, SY_EINPUT, "%s: unknown property type '%s'", f->path, tok[2]);
    if (is_list && (pr->count_type == T_F32 || pr->count_type == T_F64))
        return sy_fail(err, SY_EINPUT, "%s: list count type '%s' is not an integer type", f->path, tok[2]);
    pr->is_list = is_list;
    snprintf(pr->name, sizeof pr->name, "%s", tok[is_list ? 4 : 2]);
    f->n_props++;
    f->elems[f->n_elems - 1].n_props++;
    return SY_OK;
}

/* Parses the header; leaves f->p at the first data byte. */
static sy_code parse_header(ply_file *f, const unsigned char *data, size_t size, sy_error *err)
{
    const char *s = (const char *)data, *end = s + size;
    int line = 0, have_format = 0;
    for (;;) {
        const char *nl = memchr(s, '\n', (size_t)(end - s));
        if (!nl) return sy_fail(err, SY_EINPUT, "%s: PLY header has no end_header line", f->path);
        const char *e = nl;
        while (e > s && (e[-1] == '\r' || e[-1] == ' ' || e[-1] == '\t')) e--;
        char tok[6][64];
        int n = split(s, e, tok, 6);
        s = nl + 1;
        sy_code rc = SY_OK;
        if (line++ == 0) {
            if (n != 1 || strcmp(tok[0], "ply") != 0)
                return sy_fail(err, SY_EINPUT, "%s: not a PLY file (no 'ply' magic line)", f->path);
            continue;
        }
        if (n == 0 || strcmp(tok[0], "comment") == 0 || strcmp(tok[0], "obj_info") == 0) continue;
        if (strcmp(tok[0], "end_header") == 0) break;
        if (strcmp(tok[0], "format") == 0) {
            rc = header_format(f, tok, n, err);
            have_format = 1;
        } else if (strcmp(tok[0], "element") == 0) {
            rc = header_element(f, tok, n, err);
        } else if (strcmp(tok[0], "property") == 0) {
            rc = header_property(f, tok, n, err);
        } else {
            rc = sy_fail(err, SY_EINPUT, "%s: unexpected PLY header line '%s' (missing end_header?)",
                         f->path, tok[0]);
        }
        if (rc) return rc;
    }
    if (!have_format) return sy_fail(err, SY_EINPUT, "%s: PLY header has no format line", f->path);
    f->p = (const unsigned char *)s;
    f->end = data + size;
    return SY_OK;
}

/* ---- data access ---- */

static int host_is_big_endian(void)
{
    const uint16_t one = 1;
    unsigned char first;
    memcpy(&first, &one, 1);
    return first == 0;
}

/* The n bytes at b as an unsigned integer, reversed when swap is set. The
 * fixed-size memcpy forms compile to single loads. */
static uint64_t load_uint(const unsigned char *b, size_t n, int swap)
{
    uint16_t h;
    uint32_t w;
    uint64_t q;
    switch (n) {
    case 1: return b[0];
    case 2: memcpy(&h, b, 2); return swap ? (uint16_t)((h >> 8) | (h << 8)) : h;
    case 4: memcpy(&w, b, 4); return swap ? __builtin_bswap32(w) : w;
    default: memcpy(&q, b, 8); return swap ? __builtin_bswap64(q) : q;
    }
}

/* One binary value of type t at b (enough bytes checked by the caller). */
static double decode(const unsigned char *b, ply_type t, int swap)
{
    uint64_t u = load_uint(b, type_size[t], swap);
    switch (t) {
    case T_I8: return (double)(int8_t)(uint8_t)u;
    case T_U8: return (double)(uint8_t)u;
    case T_I16: return (double)(int16_t)(uint16_t)u;
    case T_U16: return (double)(uint16_t)u;
    case T_I32: return (double)(int32_t)(uint32_t)u;
    case T_U32: return (double)(uint32_t)u;
    case T_F32: {
        uint32_t w = (uint32_t)u;
        float fl;
        memcpy(&fl, &w, sizeof fl);
        return fl;
    }
    case T_F64: {
        double d;
        memcpy(&d, &u, sizeof d);
        return d;
    }
    }
    return 0;
}

/* Whether binary values need their bytes reversed on this host. */
static int needs_swap(const ply_file *f)
{
    return (f->enc == ENC_BE) != host_is_big_endian();
}

static int is_space(unsigned char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v';
}

/* Reads the next value: a binary field of type t or an ascii token. */
static sy_code read_value(ply_file *f, ply_type t, double *v, sy_error *err)
{
    if (f->enc != ENC_ASCII) {
        size_t n = type_size[t];
        if ((size_t)(f->end - f->p) < n) return sy_fail(err, SY_EINPUT, "%s: binary data truncated", f->path);
        *v = decode(f->p, t, needs_swap(f));
        f->p += n;
        return SY_OK;
    }
    while (f->p < f->end && is_space(*f->p)) f->p++;
    if (f->p == f->end) return sy_fail(err, SY_EINPUT, "%s: ascii data truncated", f->path);
    const char *s = (const char *)f->p, *e = (const char *)f->end;
    const char *q = sy_parse_number(s, e, v);
    if (!q || (q < e && !is_space((unsigned char)*q))) {
        char tok[28];
        int n = 0;
        while (s < e && !is_space((unsigned char)*s) && n < 24) {
            unsigned char c = (unsigned char)*s++;
            tok[n++] = (c < 32 || c == 127) ? '?' : (char)c;
        }
        tok[n] = '\0';
        return sy_fail(err, SY_EINPUT, "%s: malformed ascii number '%s'", f->path, tok);
    }
    f->p = (const unsigned char *)q;
    return SY_OK;
}

/* Reads a list length and skips its items. */
static sy_code skip_list(ply_file *f, const ply_prop *pr, sy_error *err)
{
    double len;
    sy_code rc = read_value(f, pr->count_type, &len, err);
    if (rc) return rc;
    size_t remaining = (size_t)(f->end - f->p);
    if (!(len >= 0) || len != floor(len))
        return sy_fail(err, SY_EINPUT, "%s: list property '%s' has a bad length %g", f->path, pr->name, len);
    /* Every item takes at least one byte (binary) or two (ascii). */
    size_t per = f->enc == ENC_ASCII ? 1 : type_size[pr->type];
    if (len > (double)(remaining / per))
        return sy_fail(err, SY_EINPUT, "%s: list property '%s' length %.0f runs past the end of the data "
                       "(truncated)", f->path, pr->name, len);
    size_t n = (size_t)len;
    if (f->enc != ENC_ASCII) {
        f->p += n * per;
        return SY_OK;
    }
    double v;
    for (size_t i = 0; i < n && rc == SY_OK; i++) rc = read_value(f, pr->type, &v, err);
    return rc;
}

/* Smallest number of bytes one item of el can take. */
static size_t min_item_bytes(const ply_file *f, const ply_element *el)
{
    size_t bytes = 0;
    for (int j = 0; j < el->n_props; j++) {
        const ply_prop *pr = &f->props[el->first_prop + j];
        if (f->enc == ENC_ASCII) bytes += 2; /* a digit and a separator */
        else bytes += type_size[pr->is_list ? pr->count_type : pr->type];
    }
    return bytes;
}

/* Rejects counts the remaining bytes cannot hold, before anything is sized from them. */
static sy_code check_count(const ply_file *f, const ply_element *el, sy_error *err)
{
    size_t per = min_item_bytes(f, el);
    size_t avail = (size_t)(f->end - f->p) + (f->enc == ENC_ASCII); /* last token needs no separator */
    if (per && el->count > avail / per)
        return sy_fail(err, SY_EINPUT, "%s: element '%s' claims %llu items but only %zu data bytes remain",
                       f->path, el->name, (unsigned long long)el->count, (size_t)(f->end - f->p));
    return SY_OK;
}

static sy_code skip_element(ply_file *f, const ply_element *el, sy_error *err)
{
    sy_code rc = check_count(f, el, err);
    if (rc || el->n_props == 0) return rc;
    int has_list = 0;
    for (int j = 0; j < el->n_props; j++) has_list |= f->props[el->first_prop + j].is_list;
    if (f->enc != ENC_ASCII && !has_list) {
        f->p += (size_t)el->count * min_item_bytes(f, el); /* checked above */
        return SY_OK;
    }
    double v;
    for (uint64_t i = 0; i < el->count; i++)
        for (int j = 0; j < el->n_props; j++) {
            const ply_prop *pr = &f->props[el->first_prop + j];
            rc = pr->is_list ? skip_list(f, pr, err) : read_value(f, pr->type, &v, err);
            if (rc) return rc;
        }
    return SY_OK;
}

/* ---- vertex mapping ---- */

static prop_role role_for_name(const char *name)
{
    static const struct {
        prop_role role;
        const char *names[4];
    } table[] = {
        {P_X, {"x", NULL}}, {P_Y, {"y", NULL}}, {P_Z, {"z", NULL}},
        {P_NX, {"nx", "normal_x", NULL}}, {P_NY, {"ny", "normal_y", NULL}}, {P_NZ, {"nz", "normal_z", NULL}},
        {P_R, {"red", "r", "diffuse_red", NULL}}, {P_G, {"green", "g", "diffuse_green", NULL}},
        {P_B, {"blue", "b", "diffuse_blue", NULL}}, {P_IGNORE, {"alpha", "a", "diffuse_alpha", NULL}},
        {P_INTENSITY, {"intensity", NULL}}, {P_CLASS, {"classification", NULL}},
        {P_GPS_TIME, {"gps_time", NULL}}, {P_NIR, {"nir", NULL}},
        {P_RETURN, {"return_number", NULL}}, {P_NUM_RETURNS, {"number_of_returns", NULL}},
    };
    for (size_t i = 0; i < sizeof table / sizeof table[0]; i++)
        for (const char *const *n = table[i].names; *n; n++)
            if (strcmp(name, *n) == 0) return table[i].role;
    return P_ATTR;
}

/* "scalar_" marks a per-point scalar (CloudCompare): it may name a LAS-like
 * field (scalar_intensity) but never a coordinate or colour. */
static prop_role role_for_prop(const char *name)
{
    if (strncmp(name, "scalar_", 7) != 0) return role_for_name(name);
    prop_role r = role_for_name(name + 7);
    return r >= P_INTENSITY && r != P_IGNORE ? r : P_ATTR;
}

static const char *attr_name(const char *name)
{
    return strncmp(name, "scalar_", 7) == 0 && name[7] ? name + 7 : name;
}

/* x, y and z must be scalar vertex properties; checked before allocating. */
static int has_xyz(const ply_file *f, const ply_element *el)
{
    int seen = 0;
    for (int j = 0; j < el->n_props; j++) {
        const ply_prop *pr = &f->props[el->first_prop + j];
        prop_role r = role_for_prop(pr->name);
        if (!pr->is_list && r >= P_X && r <= P_Z) seen |= 1 << (r - P_X);
    }
    return seen == 7;
}

static sy_code prepare_vertex(ply_file *f, const ply_element *el, sy_cloud *c, sy_error *err)
{
    sy_code rc = SY_OK;
    for (int j = 0; j < el->n_props && rc == SY_OK; j++) {
        ply_prop *pr = &f->props[el->first_prop + j];
        if (pr->is_list) continue;
        pr->role = role_for_prop(pr->name);
        switch (pr->role) {
        case P_X: case P_Y: case P_Z: break;
        case P_NX: case P_NY: case P_NZ: rc = sy_cloud_add_normals(c, err); break;
        case P_R: case P_G: case P_B: rc = sy_cloud_add_rgb(c, err); break;
        case P_INTENSITY: rc = sy_cloud_add_intensity(c, err); break;
        case P_CLASS: rc = sy_cloud_add_classification(c, err); break;
        case P_GPS_TIME: rc = sy_cloud_add_gps_time(c, err); break;
        case P_NIR:
            if (!c->nir) c->nir = sy_calloc(c->n, sizeof(uint16_t), err, "near infrared");
            rc = c->nir ? SY_OK : SY_EINTERNAL;
            break;
        case P_RETURN: case P_NUM_RETURNS: rc = sy_cloud_add_returns(c, err); break;
        case P_ATTR:
            pr->attr = sy_cloud_add_attr(c, attr_name(pr->name), err);
            rc = pr->attr ? SY_OK : SY_EINTERNAL;
            break;
        case P_IGNORE: break;
        }
    }
    return rc;
}

static uint16_t clamp_u16(double v)
{
    if (!(v > 0)) return 0;
    return v >= 65535 ? 65535 : (uint16_t)lrint(v);
}

static uint8_t clamp_u8(double v)
{
    if (!(v > 0)) return 0;
    return v >= 255 ? 255 : (uint8_t)lrint(v);
}

/* 16-bit colour from a stored channel: 8-bit types scale to the full range. */
static uint16_t colour16(double v, ply_type t)
{
    if (t == T_U8 || t == T_I8) return clamp_u16(v * 257.0);
    if (t == T_F32 || t == T_F64) return clamp_u16(v * 65535.0);
    return clamp_u16(v);
}

static void store(sy_cloud *c, const ply_prop *pr, size_t i, double v, double pos[3])
{
    switch (pr->role) {
    case P_X: pos[0] = v; break;
    case P_Y: pos[1] = v; break;
    case P_Z: pos[2] = v; break;
    case P_NX: c->normal[3 * i] = (float)v; break;
    case P_NY: c->normal[3 * i + 1] = (float)v; break;
    case P_NZ: c->normal[3 * i + 2] = (float)v; break;
    case P_R: c->rgb[3 * i] = colour16(v, pr->type); break;
    case P_G: c->rgb[3 * i + 1] = colour16(v, pr->type); break;
    case P_B: c->rgb[3 * i + 2] = colour16(v, pr->type); break;
    case P_INTENSITY: c->intensity[i] = clamp_u16(v); break;
    case P_CLASS: c->classification[i] = clamp_u8(v); break;
    case P_GPS_TIME: c->gps_time[i] = v; break;
    case P_NIR: c->nir[i] = clamp_u16(v); break;
    case P_RETURN: c->return_number[i] = clamp_u8(v); break;
    case P_NUM_RETURNS: c->num_returns[i] = clamp_u8(v); break;
    case P_ATTR: pr->attr[i] = v; break;
    case P_IGNORE: break;
    }
}

static sy_code read_vertices(ply_file *f, const ply_element *el, sy_cloud *c, sy_error *err)
{
    if (!has_xyz(f, el)) return sy_fail(err, SY_EINPUT, "%s: vertex element lacks x, y or z", f->path);
    sy_code rc = check_count(f, el, err);
    if (rc) return rc;
    rc = sy_cloud_init(c, (size_t)el->count, err);
    if (rc) return rc;
    rc = prepare_vertex(f, el, c, err);
    if (rc) return rc;
    int fixed = f->enc != ENC_ASCII;
    for (int j = 0; j < el->n_props; j++) fixed &= !f->props[el->first_prop + j].is_list;
    /* Fixed-size binary records: check_count proved they all fit, so decode
     * in place without per-value bounds checks. */
    size_t stride = fixed ? min_item_bytes(f, el) : 0;
    int swap = needs_swap(f);
    for (size_t i = 0; i < c->n; i++) {
        double pos[3] = {0, 0, 0}, v;
        const unsigned char *rec = f->p;
        for (int j = 0; j < el->n_props; j++) {
            const ply_prop *pr = &f->props[el->first_prop + j];
            if (fixed) {
                store(c, pr, i, decode(rec, pr->type, swap), pos);
                rec += type_size[pr->type];
                continue;
            }
            rc = pr->is_list ? skip_list(f, pr, err) : read_value(f, pr->type, &v, err);
            if (rc) return rc;
            if (!pr->is_list) store(c, pr, i, v, pos);
        }
        f->p += stride;
        if (!isfinite(pos[0]) || !isfinite(pos[1]) || !isfinite(pos[2]))
            return sy_check_finite(f->path, pos[0], pos[1], pos[2], i, err);
        if (i == 0)
            for (int k = 0; k < 3; k++) c->origin[k] = floor(pos[k]);
        for (int k = 0; k < 3; k++) c->xyz[3 * i + k] = (float)(pos[k] - c->origin[k]);
    }
    return SY_OK;
}

static const char *encoding_name(ply_encoding e)
{
    return e == ENC_ASCII ? "ascii" : e == ENC_LE ? "binary_little_endian" : "binary_big_endian";
}

sy_code sy_read_ply_mem(const char *path, const unsigned char *data, size_t size, sy_cloud *out,
                        sy_error *err)
{
    memset(out, 0, sizeof *out);
    ply_file *f = calloc(1, sizeof *f);
    if (!f) return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    f->path = path;
    sy_code rc = parse_header(f, data, size, err);
    int vertex = -1;
    for (int e = 0; rc == SY_OK && e < f->n_elems && vertex < 0; e++) {
        if (strcmp(f->elems[e].name, "vertex") == 0) vertex = e;
        else rc = skip_element(f, &f->elems[e], err);
    }
    if (rc == SY_OK && vertex < 0) rc = sy_fail(err, SY_EINPUT, "%s: PLY file has no vertex element", path);
    if (rc == SY_OK) rc = read_vertices(f, &f->elems[vertex], out, err);
    /* Elements after the vertices (faces) go unused, but a file cut short
     * inside them is still truncated. */
    for (int e = vertex + 1; rc == SY_OK && e < f->n_elems; e++) rc = skip_element(f, &f->elems[e], err);
    if (rc == SY_OK) {
        snprintf(out->meta.format, sizeof out->meta.format, "PLY");
        snprintf(out->meta.version, sizeof out->meta.version, "%s %.8s", encoding_name(f->enc), f->version);
        out->meta.header_count = f->elems[vertex].count;
    } else {
        sy_cloud_free(out);
    }
    free(f);
    return rc;
}

/* ---- writer ---- */

typedef struct {
    unsigned char *buf;
    size_t used;
} record;

/* Little endian on every host: bytes taken from the integer value. */
static void put_le(record *r, uint64_t u, size_t n)
{
    for (size_t i = 0; i < n; i++) r->buf[r->used++] = (unsigned char)(u >> (8 * i));
}

static void put_f64(record *r, double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    put_le(r, u, 8);
}

static void put_f32(record *r, float fl)
{
    uint32_t u;
    memcpy(&u, &fl, sizeof u);
    put_le(r, u, 4);
}

/* A property name the reader maps back to this attribute. */
static void attr_prop_name(const char *name, char out[48])
{
    char clean[32];
    snprintf(clean, sizeof clean, "%s", name[0] ? name : "attr");
    for (char *c = clean; *c; c++)
        if ((unsigned char)*c <= 32 || *c == 127) *c = '_';
    int reserved = role_for_name(clean) != P_ATTR || strncmp(clean, "scalar_", 7) == 0;
    snprintf(out, 48, "%s%s", reserved ? "scalar_" : "", clean);
}

static size_t write_header(FILE *fp, const sy_cloud *c)
{
    size_t rec = 24;
    fprintf(fp, "ply\nformat binary_little_endian 1.0\ncomment written by Sylva %s\n", SYLVA_VERSION);
    fprintf(fp, "element vertex %zu\nproperty double x\nproperty double y\nproperty double z\n", c->n);
    if (c->normal) fputs("property float nx\nproperty float ny\nproperty float nz\n", fp), rec += 12;
    if (c->rgb) fputs("property uchar red\nproperty uchar green\nproperty uchar blue\n", fp), rec += 3;
    if (c->intensity) fputs("property ushort intensity\n", fp), rec += 2;
    if (c->classification) fputs("property uchar classification\n", fp), rec += 1;
    if (c->gps_time) fputs("property double gps_time\n", fp), rec += 8;
    if (c->nir) fputs("property ushort nir\n", fp), rec += 2;
    if (c->return_number) fputs("property uchar return_number\n", fp), rec += 1;
    if (c->num_returns) fputs("property uchar number_of_returns\n", fp), rec += 1;
    for (size_t a = 0; a < c->n_attrs; a++) {
        char name[48];
        attr_prop_name(c->attrs[a].name, name);
        fprintf(fp, "property double %s\n", name);
        rec += 8;
    }
    fputs("end_header\n", fp);
    return rec;
}

static void pack_point(record *r, const sy_cloud *c, size_t i)
{
    for (int k = 0; k < 3; k++) put_f64(r, c->origin[k] + (double)c->xyz[3 * i + k]);
    if (c->normal)
        for (int k = 0; k < 3; k++) put_f32(r, c->normal[3 * i + k]);
    if (c->rgb)
        for (int k = 0; k < 3; k++) put_le(r, (c->rgb[3 * i + k] + 128u) / 257u, 1);
    if (c->intensity) put_le(r, c->intensity[i], 2);
    if (c->classification) put_le(r, c->classification[i], 1);
    if (c->gps_time) put_f64(r, c->gps_time[i]);
    if (c->nir) put_le(r, c->nir[i], 2);
    if (c->return_number) put_le(r, c->return_number[i], 1);
    if (c->num_returns) put_le(r, c->num_returns[i], 1);
    for (size_t a = 0; a < c->n_attrs; a++) put_f64(r, c->attrs[a].values[i]);
}

sy_code sy_write_ply(const char *path, const sy_cloud *c, sy_error *err)
{
    enum { CHUNK = 4096 };
    sy_atomic_file f;
    sy_code rc = sy_atomic_open(&f, path, err);
    if (rc) return rc;
    size_t rec = write_header(f.fp, c);
    record r = {sy_calloc(CHUNK, rec, err, "PLY write buffer"), 0};
    if (!r.buf) {
        sy_atomic_abort(&f);
        return SY_EINTERNAL;
    }
    for (size_t i = 0; i < c->n; i++) {
        pack_point(&r, c, i);
        if (r.used == CHUNK * rec || i + 1 == c->n) {
            if (fwrite(r.buf, 1, r.used, f.fp) != r.used) break;
            r.used = 0;
        }
    }
    free(r.buf);
    if (r.used) {
        sy_atomic_abort(&f);
        return sy_fail(err, SY_EINPUT, "%s: write failed", path);
    }
    return sy_atomic_commit(&f, err);
}
