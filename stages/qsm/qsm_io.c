/* Format choice for skeleton files: content first, the extension breaking
 * ties, then one reader or writer per format. */
#include <stdio.h>
#include <string.h>
#include <strings.h>

#include "qsm_internal.h"
#include "stages/core/fileio.h"
#include "stages/encode/encode.h"

const char *sy_skel_format_name(sy_skel_format f)
{
    switch (f) {
    case SY_SKEL_PLY: return "ply";
    case SY_SKEL_CSV: return "csv";
    case SY_SKEL_TREEQSM_TXT: return "treeqsm-txt";
    case SY_SKEL_OBJ: return "obj";
    case SY_SKEL_JSON: return "json";
    case SY_SKEL_SYLVA: return "sylva";
    default: return "unknown";
    }
}

static sy_skel_format by_extension(const char *path)
{
    char ext[16];
    sy_extension(path, ext, sizeof ext);
    if (strcmp(ext, "ply") == 0) return SY_SKEL_PLY;
    if (strcmp(ext, "csv") == 0) return SY_SKEL_CSV;
    if (strcmp(ext, "txt") == 0) return SY_SKEL_TREEQSM_TXT;
    if (strcmp(ext, "obj") == 0) return SY_SKEL_OBJ;
    if (strcmp(ext, "json") == 0) return SY_SKEL_JSON;
    if (strcmp(ext, "sylva") == 0) return SY_SKEL_SYLVA;
    return SY_SKEL_UNKNOWN;
}

static int contains_ci(const char *b, const char *e, const char *word)
{
    size_t w = strlen(word);
    for (const char *p = b; p + w <= e; p++)
        if (strncasecmp(p, word, w) == 0) return 1;
    return 0;
}

/* A first data line of 15 or 17 numbers is TreeQSM's headerless export. */
static int numeric_columns(const char *b, const char *e)
{
    int n = 0;
    while (b < e) {
        while (b < e && (*b == ' ' || *b == '\t')) b++;
        if (b == e) break;
        const char *q = b;
        while (q < e && *q != ' ' && *q != '\t') q++;
        double v;
        if (!sy_qsm_parse_number(b, q, &v)) return -1;
        n++;
        b = q;
    }
    return n;
}

sy_skel_format sy_skeleton_sniff(const char *path, const unsigned char *data, size_t size)
{
    if (size >= 4 && memcmp(data, "SYLV", 4) == 0) return SY_SKEL_SYLVA;
    if (size >= 4 && memcmp(data, "ply", 3) == 0 && (data[3] == '\n' || data[3] == '\r')) return SY_SKEL_PLY;
    sy_lines L;
    sy_lines_init(&L, data, size);
    const char *b, *e;
    int seen = 0, obj_statements = 0;
    while (seen < 64 && sy_lines_next(&L, &b, &e)) {
        sy_trim(&b, &e);
        if (b == e) continue;
        if (seen++ == 0) {
            if (*b == '{' || *b == '[') return SY_SKEL_JSON;
            if (contains_ci(b, e, "parentID") && memchr(b, ',', (size_t)(e - b))) return SY_SKEL_CSV;
            if (strncmp(b, "radius", 6) == 0 && contains_ci(b, e, "parent")) return SY_SKEL_TREEQSM_TXT;
            int nc = numeric_columns(b, e);
            if (nc == 15 || nc == 17) return SY_SKEL_TREEQSM_TXT;
        }
        if (e - b >= 2 && (*b == 'v' || *b == 'l') && (b[1] == ' ' || b[1] == '\t')) obj_statements++;
        else if (*b != '#' && !(e - b >= 2 && (*b == 'o' || *b == 'g') && b[1] == ' ')) break;
    }
    if (obj_statements) return SY_SKEL_OBJ;
    return by_extension(path);
}

typedef sy_code (*reader_fn)(const char *, const unsigned char *, size_t, sy_skeleton *, sy_skeleton_read_info *,
                             sy_error *);

/* hulls NULL: the cluster hulls are dropped (a skeleton reader's answer). */
static sy_code read_sylva(const char *path, const unsigned char *data, size_t size, sy_skeleton *out,
                          sy_clusters *hulls, sy_skeleton_read_info *info, sy_error *err)
{
    sy_clusters cl;
    sy_sylva_meta meta;
    sy_code rc = sy_decode_mem(path, data, size, out, &cl, &meta, err);
    if (rc) return rc;
    if (hulls) *hulls = cl;
    else sy_clusters_free(&cl);
    if (info) {
        info->records = out->n;
        info->input_roots = 1;
        info->origin_from_file = 1;
        info->leaf_off = (meta.flags & SY_SYLVA_LEAF_OFF) != 0;
    }
    return SY_OK;
}

sy_code sy_skeleton_read_sylva_mem(const char *path, const unsigned char *data, size_t size, sy_skeleton *out,
                                   sy_skeleton_read_info *info, sy_error *err)
{
    return read_sylva(path, data, size, out, NULL, info, err);
}

/* One row per readable format. */
static const struct {
    sy_skel_format format;
    reader_fn read;
} READERS[] = {
    {SY_SKEL_PLY, sy_skeleton_read_ply_mem},
    {SY_SKEL_CSV, sy_skeleton_read_csv_mem},
    {SY_SKEL_TREEQSM_TXT, sy_skeleton_read_treeqsm_mem},
    {SY_SKEL_OBJ, sy_skeleton_read_obj_mem},
    {SY_SKEL_JSON, sy_skeleton_read_json_mem},
    {SY_SKEL_SYLVA, sy_skeleton_read_sylva_mem},
};

sy_code sy_skeleton_read_model_mem(const char *path, const unsigned char *data, size_t size, long tree,
                                   sy_skeleton *out, sy_clusters *hulls, sy_skeleton_read_info *info, sy_error *err)
{
    memset(out, 0, sizeof *out);
    if (hulls) memset(hulls, 0, sizeof *hulls);
    sy_skeleton_read_info local;
    if (!info) info = &local;
    memset(info, 0, sizeof *info);
    sy_skel_format f = sy_skeleton_sniff(path, data, size);
    if (tree >= 0 && f == SY_SKEL_JSON) /* only truth files hold several trees: the index goes to the JSON reader */
        return sy_skeleton_read_json_tree(path, data, size, tree, out, info, err);
    if (tree > 0)
        return sy_fail(err, SY_EINPUT, "%s: tree %ld asked for, a %s skeleton file holds one", path, tree,
                       sy_skel_format_name(f));
    sy_code rc = sy_fail(err, SY_EINPUT,
                         "%s: not a skeleton file this build reads (PLY, cylinder CSV, TreeQSM text, OBJ, JSON, .sylva)",
                         path);
    if (f == SY_SKEL_SYLVA && hulls) {
        /* The one format that holds more than a skeleton: keep the hulls. */
        sy_error_clear(err);
        rc = read_sylva(path, data, size, out, hulls, info, err);
    } else
        for (size_t i = 0; i < sizeof READERS / sizeof READERS[0]; i++)
            if (READERS[i].format == f) {
                sy_error_clear(err);
                rc = READERS[i].read(path, data, size, out, info, err);
                break;
            }
    if (rc == SY_OK) info->format = f;
    return rc;
}

sy_code sy_skeleton_read_model(const char *path, long tree, sy_skeleton *out, sy_clusters *hulls,
                               sy_skeleton_read_info *info, sy_error *err)
{
    memset(out, 0, sizeof *out);
    if (hulls) memset(hulls, 0, sizeof *hulls);
    if (info) memset(info, 0, sizeof *info);
    sy_buffer buf;
    sy_code rc = sy_read_file(path, &buf, err);
    if (rc) return rc;
    rc = sy_skeleton_read_model_mem(path, buf.data, buf.size, tree, out, hulls, info, err);
    sy_buffer_free(&buf);
    return rc;
}

sy_code sy_skeleton_read_tree(const char *path, long tree, sy_skeleton *out, sy_skeleton_read_info *info,
                              sy_error *err)
{
    return sy_skeleton_read_model(path, tree, out, NULL, info, err);
}

sy_code sy_skeleton_read_ex(const char *path, sy_skeleton *out, sy_skeleton_read_info *info, sy_error *err)
{
    return sy_skeleton_read_tree(path, -1, out, info, err);
}

sy_code sy_skeleton_read(const char *path, sy_skeleton *out, sy_error *err)
{
    return sy_skeleton_read_ex(path, out, NULL, err);
}

sy_code sy_skeleton_write(const char *path, const sy_skeleton *s, sy_error *err)
{
    switch (by_extension(path)) {
    case SY_SKEL_PLY: return sy_skeleton_write_ply(path, s, err);
    case SY_SKEL_CSV: return sy_skeleton_write_csv(path, s, err);
    case SY_SKEL_OBJ: return sy_skeleton_write_obj(path, s, err);
    case SY_SKEL_JSON: return sy_skeleton_write_json(path, s, err);
    case SY_SKEL_SYLVA: return sy_encode_write(path, s, NULL, 0, 0, err); /* no hulls, unknown species */
    default:
        return sy_fail(err, SY_EUSAGE, "%s: unknown skeleton extension (use .sylva, .ply, .csv, .obj or .json)",
                       path);
    }
}
