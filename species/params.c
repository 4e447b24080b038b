/* Species parameter files: a strict INI reader for the Weber-Penn tree-type
 * layout of the Weber & Penn GPU-trees thesis's Appendix C ([General],
 * [ParamLevelN]) plus [Sylva].
 * Keys are case-insensitive; per-level keys may carry their level digit
 * ("1Branches"), which must then match the section. */
/* realpath() is XSI. */
#define _XOPEN_SOURCE 700

#include "species/params.h"

#include <ctype.h>
#include <limits.h>
#include <errno.h>
#include <math.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "species/library.h"
#include "stages/core/fileio.h"
#include "stages/core/lines.h"

typedef enum { K_FLOAT, K_INT, K_STRING, K_VEC3 } key_type;
typedef enum { S_NONE, S_GENERAL, S_LEVEL, S_SYLVA } section_kind;

typedef struct {
    const char *name;
    key_type type;
    size_t offset; /* in sy_species_params (general, sylva) or sy_wp_level (level) */
    double lo, hi; /* accepted range, inclusive */
} key_def;

#define GEN(n, t, f, lo, hi) {n, t, offsetof(sy_species_params, f), lo, hi}
#define LVL(n, t, f, lo, hi) {n, t, offsetof(sy_wp_level, f), lo, hi}
#define ANGLE 3600.0

static const key_def general_keys[] = {
    GEN("Shape", K_INT, shape, 0, 8),
    GEN("BaseSize", K_FLOAT, base_size, 0, 0.99),
    GEN("Scale", K_FLOAT, scale, 0.01, 500),
    GEN("ScaleV", K_FLOAT, scale_v, 0, 500),
    GEN("ZScale", K_FLOAT, zscale, 0.01, 100),
    GEN("ZScaleV", K_FLOAT, zscale_v, 0, 100),
    GEN("Levels", K_INT, levels, 1, SY_WP_LEVELS),
    GEN("recLevels", K_INT, levels, 1, SY_WP_LEVELS), /* the thesis's name */
    GEN("Ratio", K_FLOAT, ratio, 1e-6, 1),
    GEN("RatioPower", K_FLOAT, ratio_power, 0, 10),
    GEN("Lobes", K_INT, lobes, 0, 64),
    GEN("LobeDepth", K_FLOAT, lobe_depth, 0, 0.99),
    GEN("Flare", K_FLOAT, flare, 0, 10),
    GEN("0Scale", K_FLOAT, scale0, 1e-6, 100),
    GEN("0ScaleV", K_FLOAT, scale0_v, 0, 100),
    GEN("Leaves", K_FLOAT, leaves, -1000, 1000),
    GEN("LeafShape", K_INT, leaf_shape, 0, 9),
    GEN("LeafScale", K_FLOAT, leaf_scale, 1e-4, 50),
    GEN("LeafScaleX", K_FLOAT, leaf_scale_x, 1e-3, 10),
    GEN("LeafBend", K_FLOAT, leaf_bend, 0, 1),
    GEN("LeafQuality", K_FLOAT, leaf_quality, 1e-3, 10),
    GEN("AttractionUp", K_FLOAT, attraction_up, -10, 10),
    GEN("PruneRatio", K_FLOAT, prune_ratio, 0, 1),
    GEN("PruneWidth", K_FLOAT, prune_width, 1e-3, 10),
    GEN("PruneWidthPeak", K_FLOAT, prune_width_peak, 0, 1),
    GEN("PrunePowerLow", K_FLOAT, prune_power_low, 0, 100),
    GEN("PrunePowerHigh", K_FLOAT, prune_power_high, 0, 100),
    GEN("Material", K_STRING, material, 0, 0),
    GEN("MaterialNormal", K_STRING, material_normal, 0, 0),
    GEN("Ka", K_VEC3, ka, -1e6, 1e6),
    GEN("Kd", K_VEC3, kd, -1e6, 1e6),
    GEN("Ks", K_VEC3, ks, -1e6, 1e6),
};

static const key_def level_keys[] = {
    LVL("DownAngle", K_FLOAT, down_angle, -ANGLE, ANGLE),
    LVL("DownAngleV", K_FLOAT, down_angle_v, -ANGLE, ANGLE),
    LVL("Rotate", K_FLOAT, rotate, -ANGLE, ANGLE),
    LVL("RotateV", K_FLOAT, rotate_v, 0, ANGLE),
    LVL("Branches", K_FLOAT, branches, 0, 1000),
    LVL("BranchesV", K_FLOAT, branches_v, 0, 1000),
    LVL("Length", K_FLOAT, length, 0, 10),
    LVL("LengthV", K_FLOAT, length_v, 0, 10),
    LVL("Taper", K_FLOAT, taper, 0, 3),
    LVL("BaseSplits", K_FLOAT, base_splits, 0, 16),
    LVL("SegSplits", K_FLOAT, seg_splits, 0, 5),
    LVL("SplitAngle", K_FLOAT, split_angle, 0, 180),
    LVL("SplitAngleV", K_FLOAT, split_angle_v, 0, 180),
    LVL("CurveRes", K_INT, curve_res, 1, 64),
    LVL("Curve", K_FLOAT, curve, -ANGLE, ANGLE),
    LVL("CurveBack", K_FLOAT, curve_back, -ANGLE, ANGLE),
    LVL("CurveV", K_FLOAT, curve_v, -ANGLE, ANGLE),
};

/* [Sylva] keys; offsets into sy_species_params. */
static const key_def sylva_keys[] = {
    GEN("name", K_STRING, name, 0, 0),
    GEN("bark", K_STRING, bark_texture, 0, 0),
    GEN("leaf", K_STRING, leaf_texture, 0, 0),
    GEN("translucency", K_FLOAT, leaf_translucency, 0, 1),
    GEN("leaf_fill", K_FLOAT, leaf_fill, 0.01, 1),
    GEN("beta", K_FLOAT, beta, 0, 10),
    GEN("gamma", K_FLOAT, gamma, 0.1, 5),
    GEN("bark_color", K_VEC3, bark_color, 0, 255),
    GEN("twigs", K_INT, twigs, 0, 1),
};

#define N_GENERAL (sizeof general_keys / sizeof general_keys[0])
#define N_LEVEL (sizeof level_keys / sizeof level_keys[0])
#define N_SYLVA (sizeof sylva_keys / sizeof sylva_keys[0])

double sy_species_leaf_fit(const sy_species_params *sp, double tree_height, double seen)
{
    double full = sp->scale * (seen > 0 && seen <= 1 ? seen : 1);
    if (!(full > 0) || !(tree_height > 0) || tree_height >= full) return 1;
    return fmax(tree_height / full, 0.25);
}

sy_species_params sy_species_params_default(void)
{
    sy_species_params s, *sp = &s;
    /* Weber & Penn's generic values (their quaking aspen where the paper has
     * no neutral choice); docs/species.md lists them. */
    static const sy_wp_level lv[SY_WP_LEVELS] = {
        {0, 0, 0, 0, 0, 0, 1, 0, 1, 0, 0, 0, 0, 3, 0, 0, 20},
        {60, -50, 140, 0, 50, 0, 0.3f, 0, 1, 0, 0, 0, 0, 5, -40, 0, 50},
        {45, 10, 140, 0, 30, 0, 0.6f, 0, 1, 0, 0, 0, 0, 3, -40, 0, 75},
        {45, 10, 77, 0, 10, 0, 0.4f, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0},
    };
    memset(sp, 0, sizeof *sp);
    sp->shape = 7;
    sp->base_size = 0.4f;
    sp->scale = 13;
    sp->zscale = 1;
    sp->levels = 3;
    sp->ratio = 0.015f;
    sp->ratio_power = 1.2f;
    sp->flare = 0.6f;
    sp->scale0 = 1;
    sp->leaf_scale = 0.17f;
    sp->leaf_scale_x = 1;
    sp->leaf_bend = 0.3f;
    sp->leaf_quality = 1;
    sp->prune_width = 0.5f;
    sp->prune_width_peak = 0.5f;
    sp->prune_power_low = 0.5f;
    sp->prune_power_high = 0.5f;
    memcpy(sp->level, lv, sizeof lv);
    sp->leaf_translucency = 0.4f;
    sp->bark_color[0] = sp->bark_color[1] = sp->bark_color[2] = -1;
    sp->leaf_fill = 1;
    sp->beta = 1;
    sp->gamma = 2;
    sp->twigs = 1;
    return s;
}

void sy_species_params_free(sy_species_params *sp)
{
    free(sp->material);
    free(sp->material_normal);
    free(sp->name);
    free(sp->bark_texture);
    free(sp->leaf_texture);
    sp->material = sp->material_normal = sp->name = sp->bark_texture = sp->leaf_texture = NULL;
}

/* One table's keys of base (sy_species_params or sy_wp_level) as a JSON object.
 * Aliases (recLevels = Levels) share an offset and are written once;
 * BaseSplits only on the trunk, where the parser accepts it. */
/* A texture path as asset extras keep it: relative to the library folder
 * lib (canonical; "" when there is none) when it lies in it, else the file
 * name only (the absolute path belongs to the machine that grew the tree). */
static const char *library_relative(const char *v, const char *lib, char *buf, size_t size)
{
    size_t n = strlen(lib);
    char canon[PATH_MAX];
    const char *c = realpath(v, canon) ? canon : v;
    if (n && strncmp(c, lib, n) == 0 && c[n] == '/') {
        snprintf(buf, size, "%s", c + n + 1);
        return buf;
    }
    const char *slash = strrchr(v, '/');
    return slash ? slash + 1 : v;
}

static void write_keys(sy_json *j, const char *section, const key_def *keys, size_t n, const void *base, int level,
                       const char *lib)
{
    sy_json_object(j, section);
    for (size_t i = 0; i < n; i++) {
        const key_def *k = &keys[i];
        int alias = 0;
        for (size_t e = 0; e < i; e++) alias |= keys[e].offset == k->offset;
        if (alias || (level > 0 && k->offset == offsetof(sy_wp_level, base_splits) && keys == level_keys)) continue;
        const char *field = (const char *)base + k->offset;
        switch (k->type) {
        case K_FLOAT: sy_json_float(j, k->name, *(const float *)field); break;
        case K_INT: sy_json_int(j, k->name, *(const int *)field); break;
        case K_VEC3:
            /* A default below the key's range means unset (bark_color): left
             * out, as the file leaves it out. */
            if (((const float *)field)[0] < k->lo) break;
            sy_json_array(j, k->name);
            for (int c = 0; c < 3; c++) sy_json_float(j, NULL, ((const float *)field)[c]);
            sy_json_end(j);
            break;
        case K_STRING: {
            const char *v = *(char *const *)field;
            char rel[4096];
            if (!v) break;
            /* Textures: relative to the library folder when they are in it
             * (as its .ini files write them), else the file name only. */
            if (keys == sylva_keys && k->offset != offsetof(sy_species_params, name))
                v = library_relative(v, lib, rel, sizeof rel);
            sy_json_string(j, k->name, v);
            break;
        }
        }
    }
    sy_json_end(j);
}

void sy_species_params_write_json(const sy_species_params *sp, sy_json *j)
{
    char lib[4096];
    if (sy_library_locate(lib, sizeof lib, NULL)) lib[0] = '\0';
    write_keys(j, "General", general_keys, N_GENERAL, sp, 0, lib);
    for (int l = 0; l < SY_WP_LEVELS; l++) {
        char section[24];
        snprintf(section, sizeof section, "ParamLevel%d", l);
        write_keys(j, section, level_keys, N_LEVEL, &sp->level[l], l, lib);
    }
    write_keys(j, "Sylva", sylva_keys, N_SYLVA, sp, 0, lib);
}

/* Parser state: where we are, for messages and the duplicate check. */
typedef struct {
    const char *path;
    const char *base_dir;
    int line;
    section_kind section;
    int level;
    int keys; /* key = value lines read */
    /* seen[s][k]: s = 0 general, 1..4 levels, 5 sylva */
    unsigned char seen[6][N_GENERAL > N_LEVEL ? N_GENERAL : N_LEVEL];
    sy_error *err;
} parser;

static sy_code perr(parser *p, const char *what, const char *detail)
{
    return sy_fail(p->err, SY_EINPUT, "%s:%d: %s%s", p->path, p->line, what, detail ? detail : "");
}

static char *trim(char *s)
{
    while (*s && isspace((unsigned char)*s)) s++;
    char *e = s + strlen(s);
    while (e > s && isspace((unsigned char)e[-1])) *--e = 0;
    return s;
}

static int parse_float(const char *s, double *out)
{
    if (!*s) return 0;
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || *end || !isfinite(v)) return 0;
    *out = v;
    return 1;
}

static int parse_int(const char *s, double *out)
{
    if (!*s) return 0;
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || *end || v < -1000000 || v > 1000000) return 0;
    *out = (double)v;
    return 1;
}

/* "{a, b, c}" */
static int parse_vec3(char *s, float v[3])
{
    size_t n = strlen(s);
    if (n < 2 || s[0] != '{' || s[n - 1] != '}') return 0;
    s[n - 1] = 0;
    char *tok = s + 1;
    for (int k = 0; k < 3; k++) {
        char *comma = strchr(tok, ',');
        if ((k < 2) != (comma != NULL)) return 0;
        if (comma) *comma = 0;
        double d;
        if (!parse_float(trim(tok), &d)) return 0;
        v[k] = (float)d;
        tok = comma ? comma + 1 : tok;
    }
    return 1;
}

static sy_code set_string(parser *p, char **dst, const char *value, int is_path)
{
    char buf[4096];
    size_t n = strlen(value);
    if (n >= 2 && value[0] == '"' && value[n - 1] == '"') { /* optional quotes */
        snprintf(buf, sizeof buf, "%.*s", (int)(n - 2), value + 1);
    } else {
        snprintf(buf, sizeof buf, "%s", value);
    }
    if (!buf[0]) return perr(p, "empty value", NULL);
    char full[8192];
    if (is_path && p->base_dir && buf[0] != '/')
        snprintf(full, sizeof full, "%s/%s", p->base_dir, buf);
    else
        snprintf(full, sizeof full, "%s", buf);
    char *copy = strdup(full);
    if (!copy) return sy_fail(p->err, SY_EINTERNAL, "%s: out of memory", p->path);
    free(*dst);
    *dst = copy;
    return SY_OK;
}

static sy_code set_value(parser *p, const key_def *k, void *base, char *value, int is_path)
{
    char *field = (char *)base + k->offset;
    double d = 0;
    char detail[160];
    switch (k->type) {
    case K_STRING:
        return set_string(p, (char **)field, value, is_path);
    case K_VEC3:
        if (!parse_vec3(value, (float *)field)) {
            snprintf(detail, sizeof detail, "%s expects {r, g, b}", k->name);
            return perr(p, "malformed value: ", detail);
        }
        for (int c = 0; c < 3; c++)
            if (!(((float *)field)[c] >= k->lo && ((float *)field)[c] <= k->hi)) {
                snprintf(detail, sizeof detail, "%s component %g is outside [%g, %g]", k->name,
                         (double)((float *)field)[c], k->lo, k->hi);
                return perr(p, "out of range: ", detail);
            }
        return SY_OK;
    case K_INT:
        if (!parse_int(value, &d)) {
            snprintf(detail, sizeof detail, "%s expects an integer, got \"%.60s\"", k->name, value);
            return perr(p, "malformed value: ", detail);
        }
        break;
    case K_FLOAT:
        if (!parse_float(value, &d)) {
            snprintf(detail, sizeof detail, "%s expects a number, got \"%.60s\"", k->name, value);
            return perr(p, "malformed value: ", detail);
        }
        break;
    }
    if (d < k->lo || d > k->hi) {
        snprintf(detail, sizeof detail, "%s = %g is outside [%g, %g]", k->name, d, k->lo, k->hi);
        return perr(p, "out of range: ", detail);
    }
    if (k->type == K_INT)
        *(int *)field = (int)d;
    else
        *(float *)field = (float)d;
    return SY_OK;
}

static const key_def *lookup(const key_def *table, size_t n, const char *name, size_t *index)
{
    for (size_t i = 0; i < n; i++)
        if (strcasecmp(table[i].name, name) == 0) {
            *index = i;
            return &table[i];
        }
    return NULL;
}

static sy_code mark_seen(parser *p, int slot, size_t index, const char *key)
{
    if (p->seen[slot][index]) return perr(p, "duplicate key ", key);
    p->seen[slot][index] = 1;
    return SY_OK;
}

static sy_code handle_section(parser *p, char *s)
{
    size_t n = strlen(s);
    if (n < 2 || s[n - 1] != ']') return perr(p, "malformed section header ", s);
    s[n - 1] = 0;
    char *name = trim(s + 1);
    if (strcasecmp(name, "General") == 0) {
        p->section = S_GENERAL;
    } else if (strcasecmp(name, "Sylva") == 0) {
        p->section = S_SYLVA;
    } else if (strncasecmp(name, "ParamLevel", 10) == 0) {
        char *num = trim(name + 10);
        double lv;
        if (!parse_int(num, &lv) || lv < 0 || lv >= SY_WP_LEVELS)
            return perr(p, "unknown section: ", name);
        p->section = S_LEVEL;
        p->level = (int)lv;
    } else {
        return perr(p, "unknown section: ", name);
    }
    return SY_OK;
}

static sy_code handle_level_key(parser *p, sy_species_params *sp, const char *key, char *value, int level)
{
    size_t idx;
    const key_def *k = lookup(level_keys, N_LEVEL, key, &idx);
    if (!k) return perr(p, "unknown key ", key);
    if (k->offset == offsetof(sy_wp_level, base_splits) && level != 0)
        return perr(p, "BaseSplits is a trunk (level 0) key", NULL);
    sy_code rc = mark_seen(p, 1 + level, idx, key);
    if (rc) return rc;
    return set_value(p, k, &sp->level[level], value, 0);
}

static sy_code handle_key(parser *p, sy_species_params *sp, char *key, char *value)
{
    size_t idx;
    const key_def *k;
    if (p->section == S_NONE) return perr(p, "key outside any section: ", key);
    if (p->section == S_SYLVA) {
        if (!(k = lookup(sylva_keys, N_SYLVA, key, &idx))) return perr(p, "unknown key ", key);
        sy_code rc = mark_seen(p, 5, idx, key);
        if (rc) return rc;
        return set_value(p, k, sp, value, k->offset != offsetof(sy_species_params, name));
    }
    /* 0Scale/0ScaleV are trunk keys too: accept them in [ParamLevel0]. */
    int general_ok = p->section == S_GENERAL || (p->section == S_LEVEL && p->level == 0 && key[0] == '0');
    if (general_ok && (k = lookup(general_keys, N_GENERAL, key, &idx))) {
        sy_code rc = mark_seen(p, 0, idx, key);
        if (rc) return rc;
        return set_value(p, k, sp, value, k->type == K_STRING);
    }
    /* A per-level key: "<digit><Name>" or, inside [ParamLevelN], "<Name>". */
    int level = p->section == S_LEVEL ? p->level : -1;
    const char *name = key;
    if (isdigit((unsigned char)key[0])) {
        int digit = key[0] - '0';
        if (p->section == S_LEVEL && digit != p->level) {
            char detail[200];
            snprintf(detail, sizeof detail, "%s in [ParamLevel%d]: its level does not match the section", key,
                     p->level);
            return perr(p, "misplaced key ", detail);
        }
        if (digit >= SY_WP_LEVELS) return perr(p, "unknown key ", key);
        level = digit;
        name = key + 1;
    }
    if (level < 0) return perr(p, "unknown key ", key);
    return handle_level_key(p, sp, name, value, level);
}

/* Cross-key checks that no single range can express. */
static sy_code check_consistency(parser *p, sy_species_params *sp)
{
    p->line = 0;
    /* An empty file would silently grow the default tree. */
    if (p->keys == 0) return sy_fail(p->err, SY_EINPUT, "%s: no parameters (empty species file)", p->path);
    if (sp->scale_v >= sp->scale)
        return sy_fail(p->err, SY_EINPUT, "%s: ScaleV %g must be smaller than Scale %g", p->path, sp->scale_v,
                       sp->scale);
    if (sp->level[0].length <= 0)
        return sy_fail(p->err, SY_EINPUT, "%s: 0Length must be positive", p->path);
    return SY_OK;
}

sy_code sy_species_params_parse(const char *text, size_t size, const char *path, const char *base_dir,
                         sy_species_params *sp, sy_error *err)
{
    *sp = sy_species_params_default();
    parser *p = calloc(1, sizeof *p);
    if (!p) return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    p->path = path;
    p->base_dir = base_dir;
    p->err = err;
    sy_code rc = SY_OK;
    char line[4096];
    sy_lines L;
    sy_lines_init(&L, text, size);
    const char *lb, *le;
    while (rc == SY_OK && sy_lines_next(&L, &lb, &le)) {
        p->line++;
        size_t len = (size_t)(le - lb);
        if (len >= sizeof line) {
            rc = perr(p, "line too long", NULL);
            break;
        }
        memcpy(line, lb, len);
        line[len] = 0;
        if (memchr(line, 0, len)) {
            rc = perr(p, "NUL byte in text", NULL);
            break;
        }
        char *s = trim(line);
        if (p->line == 1 && (unsigned char)s[0] == 0xEF && (unsigned char)s[1] == 0xBB &&
            (unsigned char)s[2] == 0xBF)
            s = trim(s + 3); /* UTF-8 BOM from Windows editors */
        if (!*s || *s == ';' || *s == '#') continue;
        if (*s == '[') {
            rc = handle_section(p, s);
            continue;
        }
        char *eq = strchr(s, '=');
        if (!eq) {
            rc = perr(p, "expected key = value, got ", s);
            break;
        }
        *eq = 0;
        char *key = trim(s), *value = trim(eq + 1);
        if (!*key) {
            rc = perr(p, "missing key before '='", NULL);
            break;
        }
        rc = handle_key(p, sp, key, value);
        p->keys++;
    }
    if (rc == SY_OK) rc = check_consistency(p, sp);
    free(p);
    if (rc) sy_species_params_free(sp);
    return rc;
}

/* Directory part of path ("." when none), and the base name without ".ini". */
static void split_path(const char *path, char *dir, size_t dsz, char *stem, size_t ssz)
{
    const char *slash = strrchr(path, '/');
    if (slash)
        snprintf(dir, dsz, "%.*s", (int)(slash - path), path);
    else
        snprintf(dir, dsz, ".");
    if (slash && slash == path) snprintf(dir, dsz, "/");
    const char *base = slash ? slash + 1 : path;
    size_t n = strlen(base);
    if (n > 4 && strcasecmp(base + n - 4, ".ini") == 0) n -= 4;
    snprintf(stem, ssz, "%.*s", (int)n, base);
}

sy_code sy_species_params_load(const char *path, sy_species_params *sp, sy_error *err)
{
    sy_buffer buf;
    sy_code rc = sy_read_file(path, &buf, err);
    if (rc) {
        *sp = sy_species_params_default();
        return rc;
    }
    char dir[4096], stem[256];
    split_path(path, dir, sizeof dir, stem, sizeof stem);
    rc = sy_species_params_parse((const char *)buf.data, buf.size, path, dir, sp, err);
    sy_buffer_free(&buf);
    if (rc == SY_OK && !sp->name && !(sp->name = strdup(stem))) {
        sy_species_params_free(sp);
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory", path);
    }
    return rc;
}

sy_code sy_species_params_find(const char *name, sy_species_params *sp, sy_error *err)
{
    size_t n = strlen(name);
    if (strchr(name, '/') || (n > 4 && strcasecmp(name + n - 4, ".ini") == 0))
        return sy_species_params_load(name, sp, err);
    *sp = sy_species_params_default();
    sy_library lib;
    sy_code rc = sy_library_load(NULL, &lib, err);
    if (rc) return rc;
    const sy_library_entry *e = sy_library_find(&lib, name);
    if (e) rc = sy_library_params(&lib, e, sp, err);
    else rc = sy_fail(err, SY_EINPUT, "species \"%s\": not in the library %s/library.tsv (`sylva library list`)",
                      name, lib.dir);
    sy_library_free(&lib);
    return rc;
}
