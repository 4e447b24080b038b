/* XYZ / TXT / CSV point clouds: one point a line, numbers separated by
 * whitespace, commas or semicolons.
 *
 * Lines: CRLF or LF; leading/trailing blanks and blank lines are ignored;
 * lines starting with '#' or '//' are comments. Before the first data row,
 * any line whose first token is not a number is a header line.
 *
 * Column names: the last header or comment line before the data that names
 * x, y and z (case-insensitive, after an optional '//' or '#', quotes and a
 * "scalar_" prefix removed) maps columns by name:
 *   x y z | r g b, red green blue | nx ny nz, normal_x.. | i, intensity |
 *   classification, class | gps_time | nir | return_number |
 *   number_of_returns | a, alpha (ignored) | anything else (label, treeID,
 *   ...) -> a named attribute. Columns beyond the names -> "col<k>" (1-based).
 *
 * Without such a header, by column count (k = 1-based column):
 *   3: x y z
 *   4: x y z + intensity when column 4 is integral in 0..65535, else "col4"
 *   6: x y z + rgb when columns 4-6 are integers in 0..255, else
 *      normals when every (c4,c5,c6) is a unit vector, else attributes
 *   7: x y z rgb + intensity (rgb as above, column 7 as the 4-column case),
 *      or x y z intensity rgb (the PTS order) when columns 5-7 are rgb
 *   other: x y z + attributes "col4", "col5", ...
 * A first data row holding a single integer is a point count (PTS files).
 *
 * Colours by value range: integers <= 255 are 8-bit (scaled *257 to the
 * 16-bit convention), values <= 1 with fractions are 0..1 (scaled *65535),
 * larger values are taken as 16-bit. Every data row must have as many
 * columns as the first one. */
#include "ingest.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../core/fileio.h"
#include "../core/lines.h"
#include "textnum.h"

#define XYZ_MAX_COLS 64

typedef enum {
    COL_ATTR, COL_X, COL_Y, COL_Z, COL_R, COL_G, COL_B, COL_NX, COL_NY, COL_NZ,
    COL_INTENSITY, COL_CLASS, COL_GPS_TIME, COL_NIR, COL_RETURN, COL_NUM_RETURNS, COL_IGNORE
} col_role;

typedef struct {
    col_role role;
    char name[32];
} col_map;

typedef struct {
    const char *path;
    sy_lines lines;
} line_reader;

static int is_blank(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v';
}

static int is_delim(char c)
{
    return c == ' ' || c == '\t' || c == ',' || c == ';';
}

/* Next line, trimmed of surrounding blanks; returns 0 at end of input. */
static int next_line(line_reader *r, const char **s, const char **e)
{
    const char *a, *b;
    if (!sy_lines_next(&r->lines, &a, &b)) return 0;
    while (a < b && is_blank(*a)) a++;
    while (b > a && is_blank(b[-1])) b--;
    *s = a;
    *e = b;
    return 1;
}

static int is_comment(const char *s, const char *e)
{
    return s < e && (*s == '#' || (*s == '/' && s + 1 < e && s[1] == '/'));
}

/* Parses the numbers of one row into vals (at most max); returns the column
 * count (max + 1 when there are more), or -1 with *bad at a malformed token. */
static int parse_row(const char *s, const char *e, double *vals, int max, const char **bad)
{
    int n = 0;
    while (s < e) {
        double v;
        const char *q = sy_parse_number(s, e, &v);
        if (!q || (q < e && !is_delim(*q))) {
            *bad = s;
            return -1;
        }
        if (n == max) return max + 1;
        vals[n++] = v;
        while (q < e && (*q == ' ' || *q == '\t')) q++;
        if (q < e && (*q == ',' || *q == ';'))
            for (q++; q < e && (*q == ' ' || *q == '\t'); q++) {}
        s = q;
    }
    return n;
}

/* Copies up to 24 characters of the token at s for a message, replacing
 * control bytes so the message stays one printable line. */
static const char *token_text(const char *s, const char *e, char buf[32])
{
    int n = 0;
    while (s < e && !is_delim(*s) && n < 24) {
        unsigned char c = (unsigned char)*s++;
        buf[n++] = (c < 32 || c == 127) ? '?' : (char)c;
    }
    buf[n] = '\0';
    return buf;
}

static char lower(char c)
{
    return (c >= 'A' && c <= 'Z') ? (char)(c - 'A' + 'a') : c;
}

static int name_is(const char *name, const char *const *options)
{
    for (; *options; options++) {
        const char *a = name, *b = *options;
        while (*a && lower(*a) == *b) a++, b++;
        if (!*a && !*b) return 1;
    }
    return 0;
}

static col_role role_for_name(const char *name)
{
    static const struct {
        col_role role;
        const char *names[5];
    } table[] = {
        {COL_X, {"x", NULL}},
        {COL_Y, {"y", NULL}},
        {COL_Z, {"z", NULL}},
        {COL_R, {"r", "red", NULL}},
        {COL_G, {"g", "green", NULL}},
        {COL_B, {"b", "blue", NULL}},
        {COL_NX, {"nx", "normal_x", "normalx", NULL}},
        {COL_NY, {"ny", "normal_y", "normaly", NULL}},
        {COL_NZ, {"nz", "normal_z", "normalz", NULL}},
        {COL_INTENSITY, {"i", "intensity", NULL}},
        {COL_CLASS, {"classification", "class", NULL}},
        {COL_GPS_TIME, {"gps_time", "gpstime", NULL}},
        {COL_NIR, {"nir", NULL}},
        {COL_RETURN, {"return_number", NULL}},
        {COL_NUM_RETURNS, {"number_of_returns", NULL}},
        {COL_IGNORE, {"a", "alpha", NULL}},
    };
    for (size_t i = 0; i < sizeof table / sizeof table[0]; i++)
        if (name_is(name, table[i].names)) return table[i].role;
    return COL_ATTR;
}

/* Splits a header line into column names; returns 1 when it names x, y and z. */
static int parse_header(const char *s, const char *e, col_map *cols, int *ncols)
{
    if (s < e && *s == '#') s++;
    else if (e - s >= 2 && s[0] == '/' && s[1] == '/') s += 2;
    int n = 0, seen = 0;
    while (s < e && n < XYZ_MAX_COLS) {
        while (s < e && (is_delim(*s) || *s == '"' || *s == '\'')) s++;
        const char *t = s;
        while (s < e && !is_delim(*s) && *s != '"' && *s != '\'') s++;
        if (s == t) break;
        if (s - t > 7 && strncmp(t, "scalar_", 7) == 0) t += 7;
        char *name = cols[n].name;
        snprintf(name, sizeof cols[n].name, "%.*s", (int)(s - t), t);
        for (char *c = name; *c; c++)
            if ((unsigned char)*c < 32 || *c == 127) *c = '_';
        cols[n].role = role_for_name(name);
        if (cols[n].role == COL_X) seen |= 1;
        if (cols[n].role == COL_Y) seen |= 2;
        if (cols[n].role == COL_Z) seen |= 4;
        n++;
    }
    *ncols = n;
    return seen == 7;
}

/* Row-major table of the parsed numbers. */
typedef struct {
    double *v;
    size_t rows, cap;
    int cols;
} table;

static double cell(const table *t, size_t row, int col)
{
    return t->v[row * (size_t)t->cols + (size_t)col];
}

static int column_integral_in(const table *t, int col, double lo, double hi)
{
    for (size_t i = 0; i < t->rows; i++) {
        double v = cell(t, i, col);
        if (!(v >= lo && v <= hi) || v != floor(v)) return 0;
    }
    return 1;
}

static int columns_are_rgb(const table *t, int first)
{
    return first + 2 < t->cols && column_integral_in(t, first, 0, 255) &&
           column_integral_in(t, first + 1, 0, 255) && column_integral_in(t, first + 2, 0, 255);
}

static int columns_are_normals(const table *t, int first)
{
    for (size_t i = 0; i < t->rows; i++) {
        double a = cell(t, i, first), b = cell(t, i, first + 1), c = cell(t, i, first + 2);
        double len2 = a * a + b * b + c * c;
        if (!(fabs(len2 - 1.0) < 0.02 || len2 == 0.0)) return 0;
    }
    return 1;
}

static void set_roles(col_map *cols, int first, col_role a, col_role b, col_role c)
{
    cols[first].role = a;
    cols[first + 1].role = b;
    cols[first + 2].role = c;
}

static void set_intensity_or_attr(const table *t, col_map *cols, int col)
{
    cols[col].role = column_integral_in(t, col, 0, 65535) ? COL_INTENSITY : COL_ATTR;
}

/* Column roles for a file without a naming header (rules in the file comment). */
static void guess_roles(const table *t, col_map *cols)
{
    int n = t->cols;
    for (int k = 0; k < n; k++) {
        cols[k].role = COL_ATTR;
        snprintf(cols[k].name, sizeof cols[k].name, "col%d", k + 1);
    }
    set_roles(cols, 0, COL_X, COL_Y, COL_Z);
    if (n == 4) set_intensity_or_attr(t, cols, 3);
    if (n == 6 && columns_are_rgb(t, 3)) set_roles(cols, 3, COL_R, COL_G, COL_B);
    else if (n == 6 && columns_are_normals(t, 3)) set_roles(cols, 3, COL_NX, COL_NY, COL_NZ);
    if (n == 7 && columns_are_rgb(t, 3)) {
        set_roles(cols, 3, COL_R, COL_G, COL_B);
        set_intensity_or_attr(t, cols, 6);
    } else if (n == 7 && columns_are_rgb(t, 4)) {
        set_roles(cols, 4, COL_R, COL_G, COL_B);
        set_intensity_or_attr(t, cols, 3);
    }
}

/* Completes header-named columns: unnamed ones become "col<k>" attributes,
 * duplicate roles after the first become attributes too. */
static void finish_named_roles(col_map *cols, int named, int n)
{
    for (int k = named; k < n; k++) {
        cols[k].role = COL_ATTR;
        snprintf(cols[k].name, sizeof cols[k].name, "col%d", k + 1);
    }
    for (int k = 0; k < n; k++)
        for (int j = 0; j < k; j++)
            if (cols[k].role != COL_ATTR && cols[k].role != COL_IGNORE && cols[j].role == cols[k].role) {
                cols[k].role = COL_ATTR;
                break;
            }
}

static uint16_t clamp_u16(double v)
{
    if (!(v > 0)) return 0;
    if (v >= 65535) return 65535;
    return (uint16_t)lrint(v);
}

static uint8_t clamp_u8(double v)
{
    if (!(v > 0)) return 0;
    if (v >= 255) return 255;
    return (uint8_t)lrint(v);
}

/* Scale for colour columns, chosen once for all three so they stay consistent. */
static double colour_scale(const table *t, const col_map *cols)
{
    double max = 0;
    int fractional = 0;
    for (int k = 0; k < t->cols; k++) {
        if (cols[k].role != COL_R && cols[k].role != COL_G && cols[k].role != COL_B) continue;
        for (size_t i = 0; i < t->rows; i++) {
            double v = cell(t, i, k);
            if (v > max) max = v;
            if (v != floor(v)) fractional = 1;
        }
    }
    if (max <= 1.0 && fractional) return 65535.0;
    if (max <= 255.0) return 257.0;
    return 1.0;
}

/* A unique attribute for column k: its name, or "col<k>" when the name is taken. */
static double *attr_for_column(sy_cloud *c, const col_map *col, int k, sy_error *err)
{
    char name[32];
    snprintf(name, sizeof name, "%s", col->name);
    if (sy_cloud_attr(c, name)) snprintf(name, sizeof name, "col%d", k + 1);
    return sy_cloud_add_attr(c, name, err);
}

/* Allocates the arrays the roles need; attr[k] receives column k's values. */
static sy_code add_arrays_for(sy_cloud *c, const col_map *cols, int n, double **attr, sy_error *err)
{
    sy_code rc = SY_OK;
    for (int k = 0; k < n && rc == SY_OK; k++) {
        switch (cols[k].role) {
        case COL_R: case COL_G: case COL_B: rc = sy_cloud_add_rgb(c, err); break;
        case COL_NX: case COL_NY: case COL_NZ: rc = sy_cloud_add_normals(c, err); break;
        case COL_INTENSITY: rc = sy_cloud_add_intensity(c, err); break;
        case COL_CLASS: rc = sy_cloud_add_classification(c, err); break;
        case COL_GPS_TIME: rc = sy_cloud_add_gps_time(c, err); break;
        case COL_NIR:
            if (!c->nir) {
                c->nir = sy_calloc(c->n, sizeof(uint16_t), err, "near infrared");
                if (!c->nir) rc = SY_EINTERNAL;
            }
            break;
        case COL_RETURN: case COL_NUM_RETURNS: rc = sy_cloud_add_returns(c, err); break;
        case COL_ATTR:
            attr[k] = attr_for_column(c, &cols[k], k, err);
            if (!attr[k]) rc = SY_EINTERNAL;
            break;
        default: break;
        }
    }
    return rc;
}

/* Fills the cloud from the table according to the column roles. */
static sy_code build_cloud(const char *path, const table *t, const col_map *cols, sy_cloud *c,
                           sy_error *err)
{
    int ix = -1, iy = -1, iz = -1;
    for (int k = 0; k < t->cols; k++) {
        if (cols[k].role == COL_X && ix < 0) ix = k;
        if (cols[k].role == COL_Y && iy < 0) iy = k;
        if (cols[k].role == COL_Z && iz < 0) iz = k;
    }
    sy_code rc = sy_cloud_init(c, t->rows, err);
    if (rc) return rc;
    double *attr[XYZ_MAX_COLS] = {0};
    rc = add_arrays_for(c, cols, t->cols, attr, err);
    if (rc) return rc;
    if (t->rows) {
        c->origin[0] = floor(cell(t, 0, ix));
        c->origin[1] = floor(cell(t, 0, iy));
        c->origin[2] = floor(cell(t, 0, iz));
    }
    double cscale = colour_scale(t, cols);
    for (size_t i = 0; i < t->rows; i++) {
        const double *row = t->v + i * (size_t)t->cols;
        rc = sy_check_finite(path, row[ix], row[iy], row[iz], i, err);
        if (rc) return rc;
        for (int k = 0; k < 3; k++) {
            int col = k == 0 ? ix : k == 1 ? iy : iz;
            c->xyz[3 * i + k] = (float)(row[col] - c->origin[k]);
        }
        for (int k = 0; k < t->cols; k++) {
            double v = row[k];
            switch (cols[k].role) {
            case COL_R: c->rgb[3 * i] = clamp_u16(v * cscale); break;
            case COL_G: c->rgb[3 * i + 1] = clamp_u16(v * cscale); break;
            case COL_B: c->rgb[3 * i + 2] = clamp_u16(v * cscale); break;
            case COL_NX: c->normal[3 * i] = (float)v; break;
            case COL_NY: c->normal[3 * i + 1] = (float)v; break;
            case COL_NZ: c->normal[3 * i + 2] = (float)v; break;
            case COL_INTENSITY: c->intensity[i] = clamp_u16(v); break;
            case COL_CLASS: c->classification[i] = clamp_u8(v); break;
            case COL_GPS_TIME: c->gps_time[i] = v; break;
            case COL_NIR: c->nir[i] = clamp_u16(v); break;
            case COL_RETURN: c->return_number[i] = clamp_u8(v); break;
            case COL_NUM_RETURNS: c->num_returns[i] = clamp_u8(v); break;
            case COL_ATTR: attr[k][i] = v; break;
            default: break;
            }
        }
    }
    return SY_OK;
}

/* Rows can be no shorter than "0 0 0\n": bounds the table by the bytes left. */
static size_t max_rows(const char *p, const char *end, int cols)
{
    size_t lines = 1;
    for (const char *q = p; (q = memchr(q, '\n', (size_t)(end - q))) != NULL; q++) lines++;
    size_t by_bytes = (size_t)(end - p) / (2 * (size_t)cols) + 1;
    return lines < by_bytes ? lines : by_bytes;
}

typedef struct {
    col_map names[XYZ_MAX_COLS];
    int n_names; /* > 0 once a header naming x, y, z was seen */
    uint64_t pts_count;
} header_info;

/* Reads lines up to the first data row: header and comment lines, and a
 * PTS point count. Sets *cols to the first row's column count (0: no rows). */
static sy_code read_preamble(line_reader *r, header_info *h, double *row0, size_t *row0_line,
                             int *cols, sy_error *err)
{
    const char *s, *e, *bad = NULL;
    int seen_count = 0;
    char tok[32];
    *cols = 0;
    while (next_line(r, &s, &e)) {
        if (s == e) continue;
        double first;
        const char *q = sy_parse_number(s, e, &first);
        if (is_comment(s, e) || !q || (q < e && !is_delim(*q))) {
            col_map names[XYZ_MAX_COLS];
            int n_names;
            if (parse_header(s, e, names, &n_names)) {
                memcpy(h->names, names, sizeof names);
                h->n_names = n_names;
            }
            continue;
        }
        int n = parse_row(s, e, row0, XYZ_MAX_COLS, &bad);
        if (n < 0)
            return sy_fail(err, SY_EINPUT, "%s: line %zu: malformed number '%s'", r->path, r->lines.line,
                           token_text(bad, e, tok));
        if (n > XYZ_MAX_COLS)
            return sy_fail(err, SY_EINPUT, "%s: line %zu: more than %d columns", r->path, r->lines.line,
                           XYZ_MAX_COLS);
        if (n == 1 && !seen_count && row0[0] >= 0 && row0[0] == floor(row0[0]) && row0[0] < 1e18) {
            h->pts_count = (uint64_t)row0[0];
            seen_count = 1;
            continue;
        }
        if (n < 3)
            return sy_fail(err, SY_EINPUT, "%s: line %zu: %d column%s, need at least 3 (x y z)", r->path,
                           r->lines.line, n, n == 1 ? "" : "s");
        *cols = n;
        *row0_line = r->lines.line;
        return SY_OK;
    }
    return SY_OK;
}

/* The hot loop: every remaining line into the table. */
static sy_code read_rows(line_reader *r, table *t, size_t row0_line, sy_error *err)
{
    const char *s, *e, *bad = NULL;
    double extra[XYZ_MAX_COLS + 1];
    while (next_line(r, &s, &e)) {
        if (s == e || is_comment(s, e)) continue;
        if (t->rows == t->cap)
            return sy_fail(err, SY_EINPUT, "%s: line %zu: more rows than the file size allows", r->path,
                           r->lines.line);
        double *dst = t->v + t->rows * (size_t)t->cols;
        int n = parse_row(s, e, dst, t->cols, &bad);
        if (n > t->cols) n = parse_row(s, e, extra, XYZ_MAX_COLS + 1, &bad); /* the real count */
        char tok[32];
        if (n < 0)
            return sy_fail(err, SY_EINPUT, "%s: line %zu: malformed number '%s'", r->path, r->lines.line,
                           token_text(bad, e, tok));
        if (n != t->cols)
            return sy_fail(err, SY_EINPUT, "%s: line %zu: %d columns, expected %d as on line %zu",
                           r->path, r->lines.line, n, t->cols, row0_line);
        t->rows++;
    }
    return SY_OK;
}

/* Roles from the header names when they cover x, y and z within the data's
 * columns, else from the column-count rules. */
static void choose_roles(const table *t, const header_info *h, col_map *roles)
{
    if (h->n_names) {
        memcpy(roles, h->names, sizeof h->names);
        finish_named_roles(roles, h->n_names < t->cols ? h->n_names : t->cols, t->cols);
        int xyz = 0;
        for (int k = 0; k < t->cols; k++)
            if (roles[k].role >= COL_X && roles[k].role <= COL_Z) xyz |= 1 << (roles[k].role - COL_X);
        if (xyz == 7) return;
    }
    guess_roles(t, roles);
}

sy_code sy_read_xyz_mem(const char *path, const unsigned char *data, size_t size, sy_cloud *out,
                        sy_error *err)
{
    memset(out, 0, sizeof *out);
    line_reader r = {path, {0}};
    sy_lines_init(&r.lines, data, size);
    header_info h;
    memset(&h, 0, sizeof h);
    double row0[XYZ_MAX_COLS];
    size_t row0_line = 0;
    int cols = 0;
    sy_code rc = read_preamble(&r, &h, row0, &row0_line, &cols, err);
    if (rc) return rc;
    if (cols == 0) return sy_fail(err, SY_EINPUT, "%s: no point rows (x y z) found", path);

    table t = {NULL, 1, 0, cols};
    t.cap = max_rows(r.lines.p, r.lines.end, cols) + 1;
    t.v = sy_calloc(t.cap, (size_t)cols * sizeof(double), err, "XYZ rows");
    if (!t.v) return SY_EINTERNAL;
    memcpy(t.v, row0, (size_t)cols * sizeof(double));
    rc = read_rows(&r, &t, row0_line, err);

    col_map roles[XYZ_MAX_COLS];
    if (rc == SY_OK) {
        choose_roles(&t, &h, roles);
        rc = build_cloud(path, &t, roles, out, err);
    }
    free(t.v);
    if (rc) {
        sy_cloud_free(out);
        return rc;
    }
    snprintf(out->meta.format, sizeof out->meta.format, "XYZ");
    snprintf(out->meta.version, sizeof out->meta.version, "ascii");
    out->meta.header_count = h.pts_count;
    return SY_OK;
}

/* ---- writer ---- */

/* Attribute names go into a whitespace-separated header: no blanks inside. */
static void header_name(const char *name, char out[32])
{
    snprintf(out, 32, "%s", name[0] ? name : "attr");
    for (char *c = out; *c; c++)
        if (is_delim(*c) || (unsigned char)*c < 32 || *c == '"' || *c == '\'') *c = '_';
}

static void write_header(FILE *fp, const sy_cloud *c)
{
    fputs("//X Y Z", fp);
    if (c->rgb) fputs(" R G B", fp);
    if (c->normal) fputs(" Nx Ny Nz", fp);
    if (c->intensity) fputs(" Intensity", fp);
    if (c->classification) fputs(" Classification", fp);
    if (c->gps_time) fputs(" gps_time", fp);
    if (c->nir) fputs(" nir", fp);
    if (c->return_number) fputs(" return_number", fp);
    if (c->num_returns) fputs(" number_of_returns", fp);
    for (size_t a = 0; a < c->n_attrs; a++) {
        char name[32];
        header_name(c->attrs[a].name, name);
        fprintf(fp, " %s", name);
    }
    fputc('\n', fp);
}

/* Exact text for a double: integers (ids, labels) print short and fast,
 * anything else with the 17 digits that round-trip. */
static void put_exact(FILE *fp, double v)
{
    if (v == floor(v) && fabs(v) < 1e15) fprintf(fp, " %lld", (long long)v);
    else fprintf(fp, " %.17g", v);
}

static void write_point(FILE *fp, const sy_cloud *c, size_t i)
{
    /* 6 decimals: micrometres, well below the 0.1 mm survey tolerance, and
     * %f keeps large eastings/northings out of exponent notation. */
    fprintf(fp, "%.6f %.6f %.6f", c->origin[0] + c->xyz[3 * i], c->origin[1] + c->xyz[3 * i + 1],
            c->origin[2] + c->xyz[3 * i + 2]);
    if (c->rgb)
        fprintf(fp, " %u %u %u", (c->rgb[3 * i] + 128u) / 257u, (c->rgb[3 * i + 1] + 128u) / 257u,
                (c->rgb[3 * i + 2] + 128u) / 257u);
    if (c->normal)
        fprintf(fp, " %.9g %.9g %.9g", c->normal[3 * i], c->normal[3 * i + 1], c->normal[3 * i + 2]);
    if (c->intensity) fprintf(fp, " %u", c->intensity[i]);
    if (c->classification) fprintf(fp, " %u", c->classification[i]);
    if (c->gps_time) put_exact(fp, c->gps_time[i]);
    if (c->nir) fprintf(fp, " %u", c->nir[i]);
    if (c->return_number) fprintf(fp, " %u", c->return_number[i]);
    if (c->num_returns) fprintf(fp, " %u", c->num_returns[i]);
    for (size_t a = 0; a < c->n_attrs; a++) put_exact(fp, c->attrs[a].values[i]);
    fputc('\n', fp);
}

sy_code sy_write_xyz(const char *path, const sy_cloud *c, sy_error *err)
{
    sy_atomic_file f;
    sy_code rc = sy_atomic_open(&f, path, err);
    if (rc) return rc;
    write_header(f.fp, c);
    for (size_t i = 0; i < c->n; i++) write_point(f.fp, c, i);
    return sy_atomic_commit(&f, err);
}
