/* COLMAP sparse models (cameras, images, points3D as .txt or little-endian
 * .bin, the layouts of COLMAP's read_write_model) and workspaces holding one,
 * or only a dense fused.ply. The 3D points become the cloud (rgb, "error",
 * "track_length"); cameras and images are parsed to validate the model
 * (known camera models, parameter counts, references between the files) and
 * summarised in meta.vlr_summary. */
#include "ingest.h"
#include "text_scan.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "../core/fileio.h"
#include "../core/array.h"
#include "../core/sort.h"

/* COLMAP's camera model ids and parameter counts (src/base/camera_models.h);
 * the id is the index. */
static const struct {
    const char *name;
    unsigned params;
} MODELS[] = {
    {"SIMPLE_PINHOLE", 3}, {"PINHOLE", 4},         {"SIMPLE_RADIAL", 4},         {"RADIAL", 5},
    {"OPENCV", 8},         {"OPENCV_FISHEYE", 8},  {"FULL_OPENCV", 12},          {"FOV", 5},
    {"SIMPLE_RADIAL_FISHEYE", 4}, {"RADIAL_FISHEYE", 5}, {"THIN_PRISM_FISHEYE", 12},
};
#define N_MODELS (sizeof MODELS / sizeof MODELS[0])

/* Smallest binary records, used to check counts against the bytes present. */
#define BIN_CAMERA_MIN 24 /* id, model, width, height */
#define BIN_IMAGE_MIN 73  /* id, qvec, tvec, camera id, empty name, 2D count */
#define BIN_POINT_MIN 51  /* id, xyz, rgb, error, track length */

typedef struct {
    uint32_t id;
    int model;
} colmap_camera;

typedef struct {
    colmap_camera *cams;
    size_t ncams;
    uint32_t *images; /* sorted image ids */
    size_t nimages;
    int keep_poses;         /* also collect each image's pose and name */
    sy_colmap_pose *poses;  /* in file order */
    size_t nposes, poses_cap;
} colmap_model;

static void model_free(colmap_model *m)
{
    free(m->cams);
    free(m->images);
    free(m->poses);
    memset(m, 0, sizeof *m);
}

static int cmp_camera(const void *a, const void *b)
{
    uint32_t x = ((const colmap_camera *)a)->id, y = ((const colmap_camera *)b)->id;
    return (x > y) - (x < y);
}

/* Cameras are sorted once parsed (index_cameras), as image ids are: a model
 * with a camera per image has as many of each, and linear lookups made 100k
 * of them take seconds. */
static int has_camera(const colmap_model *m, uint64_t id)
{
    /* bsearch must not see a NULL array, even an empty one (UBSan, fuzz find). */
    if (id > UINT32_MAX || m->ncams == 0) return 0;
    colmap_camera key = {(uint32_t)id, 0};
    return bsearch(&key, m->cams, m->ncams, sizeof key, cmp_camera) != NULL;
}

static int has_image(const colmap_model *m, uint64_t id)
{
    if (id > UINT32_MAX || m->nimages == 0) return 0;
    uint32_t key = (uint32_t)id;
    return bsearch(&key, m->images, m->nimages, sizeof key, sy_cmp_u32) != NULL;
}

/* Appends to a growing array of elem-sized items. */
static void *grow(void *arr, size_t *cap, size_t n, size_t elem, sy_error *err)
{
    return sy_array_reserve(&arr, cap, n + 1, elem, 16, err, "COLMAP model") ? NULL : arr;
}

/* ---- binary cursor --------------------------------------------------- */

typedef struct {
    const char *path;
    const unsigned char *d;
    size_t size, pos;
} bin_cursor;

static int bin_has(const bin_cursor *c, uint64_t n) { return n <= c->size - c->pos; }

static uint64_t bin_le(bin_cursor *c, unsigned bytes)
{
    uint64_t v = 0;
    for (unsigned i = 0; i < bytes; i++) v |= (uint64_t)c->d[c->pos + i] << (8 * i);
    c->pos += bytes;
    return v;
}

static double bin_f64(bin_cursor *c)
{
    uint64_t u = bin_le(c, 8);
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

static sy_code bin_truncated(const bin_cursor *c, const char *what, size_t index, sy_error *err)
{
    return sy_fail(err, SY_EINPUT, "%s: truncated in %s %zu (byte %zu of %zu)", c->path, what, index, c->pos, c->size);
}

/* Reads the leading uint64 count and checks it against the bytes left. */
static sy_code bin_count(bin_cursor *c, size_t min_record, const char *what, size_t *n, sy_error *err)
{
    if (!bin_has(c, 8)) return sy_fail(err, SY_EINPUT, "%s: truncated: no %s count", c->path, what);
    uint64_t count = bin_le(c, 8);
    if (count > (c->size - c->pos) / min_record)
        return sy_fail(err, SY_EINPUT, "%s: %llu %s of at least %zu bytes each do not fit in %zu bytes", c->path,
                       (unsigned long long)count, what, min_record, c->size - c->pos);
    *n = (size_t)count;
    return SY_OK;
}

static sy_code bin_end(const bin_cursor *c, sy_error *err)
{
    if (c->pos == c->size) return SY_OK;
    return sy_fail(err, SY_EINPUT, "%s: %zu unexpected bytes after the last record", c->path, c->size - c->pos);
}

/* ---- cameras ----------------------------------------------------------- */

/* Sorts the cameras for lookup and rejects duplicate ids. */
static sy_code index_cameras(const char *path, colmap_model *m, sy_error *err)
{
    if (m->ncams) qsort(m->cams, m->ncams, sizeof *m->cams, cmp_camera);
    for (size_t i = 1; i < m->ncams; i++)
        if (m->cams[i].id == m->cams[i - 1].id)
            return sy_fail(err, SY_EINPUT, "%s: duplicate camera id %u", path, (unsigned)m->cams[i].id);
    return SY_OK;
}

/* unit/where locate the record in messages: "camera 3" or "line 7". */
static sy_code add_camera(colmap_model *m, size_t *cap, uint64_t id, int model, const char *path, const char *unit,
                          size_t where, sy_error *err)
{
    if (id > UINT32_MAX)
        return sy_fail(err, SY_EINPUT, "%s: %s %zu: camera id %llu out of range", path, unit, where, (unsigned long long)id);
    colmap_camera *cams = grow(m->cams, cap, m->ncams, sizeof *cams, err);
    if (!cams) return SY_EINTERNAL;
    m->cams = cams;
    m->cams[m->ncams++] = (colmap_camera){(uint32_t)id, model};
    return SY_OK;
}

static sy_code cameras_bin(const char *path, const unsigned char *d, size_t size, colmap_model *m, sy_error *err)
{
    bin_cursor c = {path, d, size, 0};
    size_t n = 0, cap = 0;
    sy_code rc = bin_count(&c, BIN_CAMERA_MIN, "cameras", &n, err);
    for (size_t i = 0; i < n && !rc; i++) {
        if (!bin_has(&c, BIN_CAMERA_MIN)) return bin_truncated(&c, "camera", i, err);
        uint64_t id = bin_le(&c, 4);
        int32_t model = (int32_t)(uint32_t)bin_le(&c, 4);
        uint64_t width = bin_le(&c, 8), height = bin_le(&c, 8);
        if (model < 0 || (size_t)model >= N_MODELS)
            return sy_fail(err, SY_EINPUT, "%s: camera %zu: unknown camera model id %d", path, i, (int)model);
        if (width == 0 || height == 0)
            return sy_fail(err, SY_EINPUT, "%s: camera %zu: image size %llux%llu", path, i,
                           (unsigned long long)width, (unsigned long long)height);
        if (!bin_has(&c, 8 * (uint64_t)MODELS[model].params)) return bin_truncated(&c, "camera", i, err);
        c.pos += 8 * (size_t)MODELS[model].params;
        rc = add_camera(m, &cap, id, model, path, "camera", i, err);
    }
    if (!rc) rc = bin_end(&c, err);
    return rc ? rc : index_cameras(path, m, err);
}

static sy_code camera_line(const char *path, size_t line, const char *p, const char *e, colmap_model *m, size_t *cap,
                           sy_error *err)
{
    sy_tok id, name, w, h;
    uint64_t cid, width, height;
    if (!sy_tok_next(&p, e, &id) || !sy_tok_next(&p, e, &name) || !sy_tok_next(&p, e, &w) || !sy_tok_next(&p, e, &h))
        return sy_fail(err, SY_EINPUT, "%s: line %zu: want CAMERA_ID MODEL WIDTH HEIGHT PARAMS...", path, line);
    if (!sy_tok_u64(&id, &cid) || !sy_tok_u64(&w, &width) || !sy_tok_u64(&h, &height) || !width || !height)
        return sy_fail(err, SY_EINPUT, "%s: line %zu: bad camera id or image size", path, line);
    int model = -1;
    for (size_t k = 0; k < N_MODELS && model < 0; k++)
        if (sy_tok_is(&name, MODELS[k].name)) model = (int)k;
    if (model < 0)
        return sy_fail(err, SY_EINPUT, "%s: line %zu: unknown camera model '%.*s'", path, line, sy_tok_shown(&name), name.s);
    size_t nparams = 0;
    for (sy_tok t; sy_tok_next(&p, e, &t); nparams++) {
        double v;
        if (!sy_tok_double(&t, &v))
            return sy_fail(err, SY_EINPUT, "%s: line %zu: bad camera parameter '%.*s'", path, line, sy_tok_shown(&t), t.s);
    }
    if (nparams != MODELS[model].params)
        return sy_fail(err, SY_EINPUT, "%s: line %zu: %s takes %u parameters, found %zu", path, line, MODELS[model].name,
                       MODELS[model].params, nparams);
    return add_camera(m, cap, cid, model, path, "line", line, err);
}

/* The next data line of l, [*p, *e): neither blank nor a '#' comment (the
 * three text files share the rule); 0 at the end. */
static int next_data_line(sy_lines *l, const char **p, const char **e)
{
    while (sy_lines_next(l, p, e)) {
        const char *q = *p;
        sy_tok first;
        if (sy_tok_next(&q, *e, &first) && first.s[0] != '#') return 1;
    }
    return 0;
}

static sy_code cameras_txt(const char *path, const unsigned char *d, size_t size, colmap_model *m, sy_error *err)
{
    sy_lines l;
    sy_lines_init(&l, d, size);
    const char *p, *e;
    size_t cap = 0;
    while (next_data_line(&l, &p, &e)) {
        sy_code rc = camera_line(path, l.line, p, e, m, &cap, err);
        if (rc) return rc;
    }
    return index_cameras(path, m, err);
}

/* ---- images ------------------------------------------------------------ */

/* Keeps one image's pose when the caller asked for poses. */
static sy_code keep_pose(colmap_model *m, uint64_t id, const double qt[7], const char *name, size_t name_len,
                         sy_error *err)
{
    if (!m->keep_poses) return SY_OK;
    sy_colmap_pose *p = grow(m->poses, &m->poses_cap, m->nposes, sizeof *p, err);
    if (!p) return SY_EINTERNAL;
    m->poses = p;
    sy_colmap_pose *q = &m->poses[m->nposes++];
    memset(q, 0, sizeof *q);
    q->id = (uint32_t)id;
    memcpy(q->q, qt, 4 * sizeof(double));
    memcpy(q->t, qt + 4, 3 * sizeof(double));
    if (name_len >= sizeof q->name) name_len = sizeof q->name - 1;
    memcpy(q->name, name, name_len);
    return SY_OK;
}

static sy_code add_image(colmap_model *m, size_t *cap, uint64_t id, uint64_t camera, const char *path,
                         const char *unit, size_t where, sy_error *err)
{
    if (id > UINT32_MAX)
        return sy_fail(err, SY_EINPUT, "%s: %s %zu: image id %llu out of range", path, unit, where, (unsigned long long)id);
    if (!has_camera(m, camera))
        return sy_fail(err, SY_EINPUT, "%s: %s %zu: image %llu uses camera %llu, which cameras does not define", path,
                       unit, where, (unsigned long long)id, (unsigned long long)camera);
    uint32_t *ids = grow(m->images, cap, m->nimages, sizeof *ids, err);
    if (!ids) return SY_EINTERNAL;
    m->images = ids;
    m->images[m->nimages++] = (uint32_t)id;
    return SY_OK;
}

/* Sorts image ids for lookup and rejects duplicates. */
static sy_code index_images(const char *path, colmap_model *m, sy_error *err)
{
    if (m->nimages) qsort(m->images, m->nimages, sizeof *m->images, sy_cmp_u32);
    for (size_t i = 1; i < m->nimages; i++)
        if (m->images[i] == m->images[i - 1])
            return sy_fail(err, SY_EINPUT, "%s: duplicate image id %u", path, (unsigned)m->images[i]);
    return SY_OK;
}

static sy_code images_bin(const char *path, const unsigned char *d, size_t size, colmap_model *m, sy_error *err)
{
    bin_cursor c = {path, d, size, 0};
    size_t n = 0, cap = 0;
    sy_code rc = bin_count(&c, BIN_IMAGE_MIN, "images", &n, err);
    for (size_t i = 0; i < n && !rc; i++) {
        if (!bin_has(&c, 64)) return bin_truncated(&c, "image", i, err);
        uint64_t id = bin_le(&c, 4);
        double qt[7];
        for (int k = 0; k < 7; k++) qt[k] = bin_f64(&c); /* the pose; any value is a pose */
        uint64_t camera = bin_le(&c, 4);
        const unsigned char *nul = memchr(c.d + c.pos, 0, c.size - c.pos);
        if (!nul) return bin_truncated(&c, "image name", i, err);
        const char *name = (const char *)c.d + c.pos;
        if ((rc = keep_pose(m, id, qt, name, (size_t)((const char *)nul - name), err))) return rc;
        c.pos = (size_t)(nul - c.d) + 1;
        if (!bin_has(&c, 8)) return bin_truncated(&c, "image", i, err);
        uint64_t npoints = bin_le(&c, 8);
        if (npoints > (c.size - c.pos) / 24) return bin_truncated(&c, "2D points of image", i, err);
        c.pos += (size_t)npoints * 24;
        rc = add_image(m, &cap, id, camera, path, "image", i, err);
    }
    if (!rc) rc = bin_end(&c, err);
    return rc ? rc : index_images(path, m, err);
}

/* POINTS2D line: (X, Y, POINT3D_ID) triples, POINT3D_ID -1 when unmatched. */
static sy_code points2d_line(const char *path, size_t line, const char *p, const char *e, sy_error *err)
{
    size_t k = 0;
    for (sy_tok t; sy_tok_next(&p, e, &t); k++) {
        double v;
        int64_t id;
        int ok = k % 3 == 2 ? sy_tok_i64(&t, &id) && id >= -1 : sy_tok_double(&t, &v);
        if (!ok) return sy_fail(err, SY_EINPUT, "%s: line %zu: bad 2D point value '%.*s'", path, line, sy_tok_shown(&t), t.s);
    }
    if (k % 3)
        return sy_fail(err, SY_EINPUT, "%s: line %zu: %zu values, 2D points come as X Y POINT3D_ID triples", path, line, k);
    return SY_OK;
}

static sy_code image_line(const char *path, size_t line, const char *p, const char *e, colmap_model *m, size_t *cap,
                          sy_error *err)
{
    sy_tok t;
    uint64_t id = 0, camera = 0;
    double qt[7] = {0};
    for (int k = 0; k < 9; k++) {
        int ok = sy_tok_next(&p, e, &t) &&
                 (k == 0 ? sy_tok_u64(&t, &id) : k == 8 ? sy_tok_u64(&t, &camera) : sy_tok_double(&t, &qt[k - 1]));
        if (!ok)
            return sy_fail(err, SY_EINPUT, "%s: line %zu: want IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME", path, line);
    }
    if (!sy_tok_next(&p, e, &t)) return sy_fail(err, SY_EINPUT, "%s: line %zu: image without a NAME", path, line);
    sy_code rc = keep_pose(m, id, qt, t.s, t.n, err);
    return rc ? rc : add_image(m, cap, id, camera, path, "line", line, err);
}

static sy_code images_txt(const char *path, const unsigned char *d, size_t size, colmap_model *m, sy_error *err)
{
    sy_lines l;
    sy_lines_init(&l, d, size);
    const char *p, *e;
    size_t cap = 0;
    while (next_data_line(&l, &p, &e)) {
        sy_code rc = image_line(path, l.line, p, e, m, &cap, err);
        /* The next line always holds the image's 2D points, even when empty. */
        if (!rc && sy_lines_next(&l, &p, &e)) rc = points2d_line(path, l.line, p, e, err);
        if (rc) return rc;
    }
    return index_images(path, m, err);
}

/* ---- points3D ------------------------------------------------------------ */

typedef struct {
    const char *path;
    const colmap_model *model; /* NULL: tracks are not checked against images */
    sy_cloud *c;
    double *error, *track;
    size_t n;
} point_sink;

static sy_code sink_open(point_sink *s, size_t n, sy_error *err)
{
    sy_code rc = sy_cloud_init(s->c, n, err);
    if (!rc) rc = sy_cloud_add_rgb(s->c, err);
    if (rc) return rc;
    s->error = sy_cloud_add_attr(s->c, "error", err);
    s->track = s->error ? sy_cloud_add_attr(s->c, "track_length", err) : NULL;
    return s->track ? SY_OK : SY_EINTERNAL;
}

static sy_code sink_point(point_sink *s, const double xyz[3], const unsigned rgb[3], double error, uint64_t track,
                          sy_error *err)
{
    sy_cloud *c = s->c;
    size_t j = s->n;
    sy_code rc = sy_check_finite(s->path, xyz[0], xyz[1], xyz[2], j, err);
    if (rc) return rc;
    if (j == 0)
        for (int k = 0; k < 3; k++) c->origin[k] = floor(xyz[k]);
    for (int k = 0; k < 3; k++) {
        c->xyz[3 * j + k] = (float)(xyz[k] - c->origin[k]);
        c->rgb[3 * j + k] = (uint16_t)(rgb[k] * 257);
    }
    s->error[j] = error;
    s->track[j] = (double)track;
    s->n++;
    return SY_OK;
}

static sy_code check_track_image(const point_sink *s, uint64_t image, const char *unit, size_t where, sy_error *err)
{
    if (!s->model || has_image(s->model, image)) return SY_OK;
    return sy_fail(err, SY_EINPUT, "%s: %s %zu: track refers to image %llu, which images does not define", s->path, unit,
                   where, (unsigned long long)image);
}

static sy_code points_bin(point_sink *s, const unsigned char *d, size_t size, sy_error *err)
{
    bin_cursor c = {s->path, d, size, 0};
    size_t n = 0;
    sy_code rc = bin_count(&c, BIN_POINT_MIN, "points", &n, err);
    if (!rc) rc = sink_open(s, n, err);
    for (size_t i = 0; i < n && !rc; i++) {
        if (!bin_has(&c, BIN_POINT_MIN)) return bin_truncated(&c, "point", i, err);
        c.pos += 8; /* point id */
        double xyz[3];
        for (int k = 0; k < 3; k++) xyz[k] = bin_f64(&c);
        unsigned rgb[3];
        for (int k = 0; k < 3; k++) rgb[k] = (unsigned)bin_le(&c, 1);
        double error = bin_f64(&c);
        uint64_t track = bin_le(&c, 8);
        if (track > (c.size - c.pos) / 8) return bin_truncated(&c, "track of point", i, err);
        for (uint64_t k = 0; k < track && !rc; k++) {
            uint64_t image = bin_le(&c, 4);
            c.pos += 4; /* 2D point index */
            rc = check_track_image(s, image, "point", i, err);
        }
        if (!rc) rc = sink_point(s, xyz, rgb, error, track, err);
    }
    return rc ? rc : bin_end(&c, err);
}

static sy_code point_line(point_sink *s, size_t line, const char *p, const char *e, sy_error *err)
{
    sy_tok t[8];
    for (int k = 0; k < 8; k++)
        if (!sy_tok_next(&p, e, &t[k]))
            return sy_fail(err, SY_EINPUT, "%s: line %zu: want POINT3D_ID X Y Z R G B ERROR TRACK...", s->path, line);
    uint64_t id, rgb64[3];
    double xyz[3], error;
    int ok = sy_tok_u64(&t[0], &id) && sy_tok_double(&t[7], &error);
    for (int k = 0; k < 3 && ok; k++)
        ok = sy_tok_double(&t[1 + k], &xyz[k]) && sy_tok_u64(&t[4 + k], &rgb64[k]) && rgb64[k] <= 255;
    if (!ok) return sy_fail(err, SY_EINPUT, "%s: line %zu: bad point id, position, colour or error", s->path, line);
    uint64_t entries = 0;
    for (sy_tok tk; sy_tok_next(&p, e, &tk); entries++) {
        uint64_t v;
        if (!sy_tok_u64(&tk, &v) || v > UINT32_MAX)
            return sy_fail(err, SY_EINPUT, "%s: line %zu: bad track value '%.*s'", s->path, line, sy_tok_shown(&tk), tk.s);
        if (entries % 2 == 0) {
            sy_code rc = check_track_image(s, v, "line", line, err);
            if (rc) return rc;
        }
    }
    if (entries % 2)
        return sy_fail(err, SY_EINPUT, "%s: line %zu: track has an odd number of values (IMAGE_ID POINT2D_IDX pairs)",
                       s->path, line);
    unsigned rgb[3] = {(unsigned)rgb64[0], (unsigned)rgb64[1], (unsigned)rgb64[2]};
    sy_code rc = sink_point(s, xyz, rgb, error, entries / 2, err);
    if (rc == SY_EINPUT) return sy_fail(err, SY_EINPUT, "%s: line %zu: non-finite position", s->path, line);
    return rc;
}

static sy_code points_txt(point_sink *s, const unsigned char *d, size_t size, sy_error *err)
{
    sy_lines l;
    sy_lines_init(&l, d, size);
    const char *p, *e;
    size_t n = 0;
    while (next_data_line(&l, &p, &e)) n++;
    sy_code rc = sink_open(s, n, err);
    sy_lines_init(&l, d, size);
    while (!rc && next_data_line(&l, &p, &e)) rc = point_line(s, l.line, p, e, err);
    return rc;
}

static sy_code read_points(const char *path, const unsigned char *d, size_t size, int binary,
                           const colmap_model *model, sy_cloud *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    point_sink s = {path, model, out, NULL, NULL, 0};
    sy_code rc = binary ? points_bin(&s, d, size, err) : points_txt(&s, d, size, err);
    if (rc) {
        sy_cloud_free(out);
        return rc;
    }
    out->n = s.n;
    snprintf(out->meta.format, sizeof out->meta.format, "COLMAP");
    snprintf(out->meta.version, sizeof out->meta.version, "sparse %s", binary ? "binary" : "text");
    out->meta.header_count = binary ? s.n : 0;
    sy_cloud_rebase(out);
    return SY_OK;
}

sy_code sy_read_colmap_points_mem(const char *path, const unsigned char *data, size_t size, int kind, sy_cloud *out,
                                  sy_error *err)
{
    if (kind != 't' && kind != 'b') {
        memset(out, 0, sizeof *out);
        return sy_fail(err, SY_EINTERNAL, "%s: unknown COLMAP points kind '%c'", path, kind);
    }
    return read_points(path, data, size, kind == 'b', NULL, out, err);
}

/* ---- workspace ------------------------------------------------------------ */

static int is_file(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

/* "<dir>/<stem>.bin" when present, else "<dir>/<stem>.txt"; 0 if neither. */
static int pick_file(const char *dir, const char *stem, char *out, size_t size, int *binary)
{
    for (int b = 1; b >= 0; b--) {
        int len = snprintf(out, size, "%s/%s.%s", dir, stem, b ? "bin" : "txt");
        if (len > 0 && (size_t)len < size && is_file(out)) {
            *binary = b;
            return 1;
        }
    }
    return 0;
}

static int has_model_files(const char *dir)
{
    static const char *stems[] = {"cameras", "images", "points3D"};
    char path[4200];
    int binary;
    for (int i = 0; i < 3; i++)
        if (pick_file(dir, stems[i], path, sizeof path, &binary)) return 1;
    return 0;
}

/* Reads "<dir>/<stem>.bin" or ".txt" into *b and describes it in *f (whose
 * path points into path). */
static sy_code load_model_file(const char *dir, const char *stem, char *path, size_t cap, sy_buffer *b,
                               sy_colmap_file *f, sy_error *err)
{
    int binary;
    if (!pick_file(dir, stem, path, cap, &binary))
        return sy_fail(err, SY_EINPUT, "%s: COLMAP model lacks %s.bin or %s.txt", dir, stem, stem);
    sy_code rc = sy_read_file(path, b, err);
    if (rc) return rc;
    *f = (sy_colmap_file){path, b->data, b->size, binary};
    return SY_OK;
}

/* meta.vlr_summary: "N cameras, M images" and the camera models in use. */
static sy_code summarize(const colmap_model *m, sy_cloud *c, sy_error *err)
{
    size_t cap = 64 + N_MODELS * 48;
    char *s = sy_calloc(cap, 1, err, "COLMAP summary");
    if (!s) return SY_EINTERNAL;
    size_t used = (size_t)snprintf(s, cap, "%zu camera%s, %zu image%s\ncamera models:", m->ncams,
                                   m->ncams == 1 ? "" : "s", m->nimages, m->nimages == 1 ? "" : "s");
    int first = 1;
    for (size_t k = 0; k < N_MODELS; k++) {
        size_t count = 0;
        for (size_t i = 0; i < m->ncams; i++) count += m->cams[i].model == (int)k;
        if (count) used += (size_t)snprintf(s + used, cap - used, "%s %s x%zu", first ? "" : ",", MODELS[k].name, count), first = 0;
    }
    c->meta.vlr_summary = s;
    return SY_OK;
}

sy_code sy_read_colmap_model_mem(const sy_colmap_file *cameras, const sy_colmap_file *images,
                                 const sy_colmap_file *points, sy_cloud *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    colmap_model m;
    memset(&m, 0, sizeof m);
    sy_code rc = (cameras->binary ? cameras_bin : cameras_txt)(cameras->path, cameras->data, cameras->size, &m, err);
    if (!rc) rc = (images->binary ? images_bin : images_txt)(images->path, images->data, images->size, &m, err);
    if (!rc) rc = read_points(points->path, points->data, points->size, points->binary, &m, out, err);
    if (!rc && out->n == 0) rc = sy_fail(err, SY_EINPUT, "%s: no points", points->path);
    if (!rc) rc = summarize(&m, out, err);
    if (rc) sy_cloud_free(out);
    model_free(&m);
    return rc;
}

static sy_code read_model(const char *dir, sy_cloud *out, sy_error *err)
{
    static const char *stems[3] = {"cameras", "images", "points3D"};
    char paths[3][4200];
    sy_buffer bufs[3] = {{NULL, 0}, {NULL, 0}, {NULL, 0}};
    sy_colmap_file files[3];
    /* points3D first: a model without points is not worth parsing. */
    sy_code rc = load_model_file(dir, stems[2], paths[2], sizeof paths[2], &bufs[2], &files[2], err);
    for (int i = 0; i < 2 && !rc; i++)
        rc = load_model_file(dir, stems[i], paths[i], sizeof paths[i], &bufs[i], &files[i], err);
    if (!rc) rc = sy_read_colmap_model_mem(&files[0], &files[1], &files[2], out, err);
    for (int i = 0; i < 3; i++) sy_buffer_free(&bufs[i]);
    return rc;
}

sy_code sy_read_colmap_poses(const char *dir, sy_colmap_pose **poses, size_t *n, sy_error *err)
{
    *poses = NULL;
    *n = 0;
    char paths[2][4200];
    sy_buffer bufs[2] = {{NULL, 0}, {NULL, 0}};
    sy_colmap_file files[2];
    static const char *stems[2] = {"cameras", "images"};
    colmap_model m;
    memset(&m, 0, sizeof m);
    m.keep_poses = 1;
    sy_code rc = SY_OK;
    for (int i = 0; i < 2 && !rc; i++)
        rc = load_model_file(dir, stems[i], paths[i], sizeof paths[i], &bufs[i], &files[i], err);
    if (!rc) rc = (files[0].binary ? cameras_bin : cameras_txt)(files[0].path, files[0].data, files[0].size, &m, err);
    if (!rc) rc = (files[1].binary ? images_bin : images_txt)(files[1].path, files[1].data, files[1].size, &m, err);
    for (int i = 0; i < 2; i++) sy_buffer_free(&bufs[i]);
    if (!rc) {
        *poses = m.poses;
        *n = m.nposes;
        m.poses = NULL;
    }
    model_free(&m);
    return rc;
}

static sy_code read_fused(const char *path, sy_cloud *out, sy_error *err)
{
    sy_code rc = sy_read_cloud(path, out, err);
    if (rc) return rc;
    snprintf(out->meta.format, sizeof out->meta.format, "COLMAP");
    snprintf(out->meta.version, sizeof out->meta.version, "fused PLY");
    return SY_OK;
}

sy_code sy_read_colmap_dir(const char *dir, sy_cloud *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    if (strlen(dir) > 4000) return sy_fail(err, SY_EINPUT, "%.64s...: path too long", dir);
    static const char *sparse[] = {"/sparse/0", "/sparse", ""};
    static const char *fused[] = {"/dense/0/fused.ply", "/dense/fused.ply", "/fused.ply"};
    char path[4200];
    for (size_t i = 0; i < 3; i++) {
        snprintf(path, sizeof path, "%s%s", dir, sparse[i]);
        if (has_model_files(path)) return read_model(path, out, err);
    }
    for (size_t i = 0; i < 3; i++) {
        snprintf(path, sizeof path, "%s%s", dir, fused[i]);
        if (is_file(path)) return read_fused(path, out, err);
    }
    return sy_fail(err, SY_EINPUT,
                   "%s: not a COLMAP workspace: no cameras/images/points3D (.bin or .txt) in sparse/0/, sparse/ or the "
                   "directory, and no dense fused.ply",
                   dir);
}
