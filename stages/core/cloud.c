#include "cloud.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

sy_code sy_cloud_init(sy_cloud *c, size_t n, sy_error *err)
{
    memset(c, 0, sizeof *c);
    c->meta.point_format = -1;
    c->xyz = sy_calloc(n, 3 * sizeof(float), err, "point positions");
    if (!c->xyz) return SY_EINTERNAL;
    c->n = n;
    return SY_OK;
}

void sy_cloud_free(sy_cloud *c)
{
    if (!c) return;
    free(c->xyz);
    free(c->normal);
    free(c->intensity);
    free(c->rgb);
    free(c->nir);
    free(c->classification);
    free(c->return_number);
    free(c->num_returns);
    free(c->gps_time);
    for (size_t i = 0; i < c->n_attrs; i++) free(c->attrs[i].values);
    free(c->attrs);
    free(c->meta.crs);
    free(c->meta.vlr_summary);
    free(c->meta.crs_wkt);
    free(c->meta.geotiff);
    memset(c, 0, sizeof *c);
}

/* Allocates *slot with n*width elements of size bytes if absent. */
static sy_code add_array(void **slot, size_t n, size_t width, size_t size, sy_error *err,
                         const char *what)
{
    if (*slot) return SY_OK;
    *slot = sy_calloc(n ? n * width : 1, size, err, what);
    return *slot ? SY_OK : SY_EINTERNAL;
}

sy_code sy_cloud_add_normals(sy_cloud *c, sy_error *err)
{
    return add_array((void **)&c->normal, c->n, 3, sizeof(float), err, "normals");
}
sy_code sy_cloud_add_intensity(sy_cloud *c, sy_error *err)
{
    return add_array((void **)&c->intensity, c->n, 1, sizeof(uint16_t), err, "intensity");
}
sy_code sy_cloud_add_rgb(sy_cloud *c, sy_error *err)
{
    return add_array((void **)&c->rgb, c->n, 3, sizeof(uint16_t), err, "colours");
}
sy_code sy_cloud_add_classification(sy_cloud *c, sy_error *err)
{
    return add_array((void **)&c->classification, c->n, 1, 1, err, "classification");
}
sy_code sy_cloud_add_returns(sy_cloud *c, sy_error *err)
{
    sy_code rc = add_array((void **)&c->return_number, c->n, 1, 1, err, "return numbers");
    if (rc) return rc;
    return add_array((void **)&c->num_returns, c->n, 1, 1, err, "return counts");
}
sy_code sy_cloud_add_gps_time(sy_cloud *c, sy_error *err)
{
    return add_array((void **)&c->gps_time, c->n, 1, sizeof(double), err, "GPS time");
}

double *sy_cloud_attr(const sy_cloud *c, const char *name)
{
    for (size_t i = 0; i < c->n_attrs; i++)
        if (strcmp(c->attrs[i].name, name) == 0) return c->attrs[i].values;
    return NULL;
}

double *sy_cloud_add_attr(sy_cloud *c, const char *name, sy_error *err)
{
    double *v = sy_cloud_attr(c, name);
    if (v) return v;
    sy_attr *grown = realloc(c->attrs, (c->n_attrs + 1) * sizeof *grown);
    if (!grown) {
        sy_fail(err, SY_EINTERNAL, "attribute %s: out of memory", name);
        return NULL;
    }
    c->attrs = grown;
    sy_attr *a = &c->attrs[c->n_attrs];
    memset(a, 0, sizeof *a);
    snprintf(a->name, sizeof a->name, "%s", name);
    a->values = sy_calloc(c->n, sizeof(double), err, name);
    if (!a->values) return NULL;
    c->n_attrs++;
    return a->values;
}

void sy_cloud_bounds(const sy_cloud *c, double min[3], double max[3])
{
    float lo[3] = {FLT_MAX, FLT_MAX, FLT_MAX}, hi[3] = {-FLT_MAX, -FLT_MAX, -FLT_MAX};
    for (size_t i = 0; i < c->n; i++)
        for (int k = 0; k < 3; k++) {
            float v = c->xyz[3 * i + k];
            if (v < lo[k]) lo[k] = v;
            if (v > hi[k]) hi[k] = v;
        }
    for (int k = 0; k < 3; k++) {
        min[k] = c->n ? c->origin[k] + lo[k] : 0.0;
        max[k] = c->n ? c->origin[k] + hi[k] : 0.0;
    }
}

/* Compacts one array of n elements of elem bytes in place. */
static void compact(void *base, size_t n, size_t elem, const uint8_t *keep)
{
    if (!base) return;
    unsigned char *b = base;
    size_t j = 0;
    for (size_t i = 0; i < n; i++)
        if (keep[i]) {
            if (i != j) memmove(b + j * elem, b + i * elem, elem);
            j++;
        }
}

sy_code sy_cloud_filter(sy_cloud *c, const uint8_t *keep, sy_error *err)
{
    (void)err;
    size_t kept = 0;
    for (size_t i = 0; i < c->n; i++) kept += keep[i] != 0;
    compact(c->xyz, c->n, 3 * sizeof(float), keep);
    compact(c->normal, c->n, 3 * sizeof(float), keep);
    compact(c->intensity, c->n, sizeof(uint16_t), keep);
    compact(c->rgb, c->n, 3 * sizeof(uint16_t), keep);
    compact(c->nir, c->n, sizeof(uint16_t), keep);
    compact(c->classification, c->n, 1, keep);
    compact(c->return_number, c->n, 1, keep);
    compact(c->num_returns, c->n, 1, keep);
    compact(c->gps_time, c->n, sizeof(double), keep);
    for (size_t a = 0; a < c->n_attrs; a++) compact(c->attrs[a].values, c->n, sizeof(double), keep);
    c->n = kept;
    return SY_OK;
}

static char *dup_string(const char *s, int *failed)
{
    if (!s || *failed) return NULL;
    size_t len = strlen(s) + 1;
    char *p = malloc(len);
    if (!p) *failed = 1;
    else memcpy(p, s, len);
    return p;
}

/* The elements (each `size` bytes, n of them) of src that keep marks, kept
 * in all, into a new array; every element when keep is NULL (kept = n). */
static void *gather_array(const void *src, size_t n, size_t size, const uint8_t *keep, size_t kept, const char *what,
                          sy_error *err, int *failed)
{
    if (!src || *failed) return NULL;
    unsigned char *p = sy_calloc(kept ? kept : 1, size, err, what);
    if (!p) {
        *failed = 1;
        return NULL;
    }
    const unsigned char *s = src;
    if (!keep) memcpy(p, s, n * size);
    else
        for (size_t i = 0, j = 0; i < n; i++)
            if (keep[i]) memcpy(p + size * j++, s + size * i, size);
    return p;
}

/* A new cloud of the points of src that keep marks (all of them when keep is
 * NULL), every attribute and the metadata copied: what sy_cloud_copy and
 * sy_cloud_subset both are. */
static sy_code copy_points(sy_cloud *dst, const sy_cloud *src, const uint8_t *keep, const char *what, sy_error *err)
{
    int failed = 0;
    size_t n = src->n, kept = n;
    if (keep) {
        kept = 0;
        for (size_t i = 0; i < n; i++) kept += keep[i] != 0;
    }
    memset(dst, 0, sizeof *dst);
    dst->n = kept;
    memcpy(dst->origin, src->origin, sizeof dst->origin);
    dst->meta = src->meta;
    dst->meta.crs = dup_string(src->meta.crs, &failed);
    dst->meta.vlr_summary = dup_string(src->meta.vlr_summary, &failed);
    dst->meta.crs_wkt = dup_string(src->meta.crs_wkt, &failed);
    size_t gl = src->meta.geotiff_len;
    dst->meta.geotiff = gather_array(src->meta.geotiff, gl, 1, NULL, gl, what, err, &failed);
    dst->xyz = gather_array(src->xyz, n, 3 * sizeof(float), keep, kept, what, err, &failed);
    dst->normal = gather_array(src->normal, n, 3 * sizeof(float), keep, kept, what, err, &failed);
    dst->intensity = gather_array(src->intensity, n, sizeof(uint16_t), keep, kept, what, err, &failed);
    dst->rgb = gather_array(src->rgb, n, 3 * sizeof(uint16_t), keep, kept, what, err, &failed);
    dst->nir = gather_array(src->nir, n, sizeof(uint16_t), keep, kept, what, err, &failed);
    dst->classification = gather_array(src->classification, n, 1, keep, kept, what, err, &failed);
    dst->return_number = gather_array(src->return_number, n, 1, keep, kept, what, err, &failed);
    dst->num_returns = gather_array(src->num_returns, n, 1, keep, kept, what, err, &failed);
    dst->gps_time = gather_array(src->gps_time, n, sizeof(double), keep, kept, what, err, &failed);
    if (src->n_attrs && !failed) {
        dst->attrs = sy_calloc(src->n_attrs, sizeof(sy_attr), err, "attributes");
        if (!dst->attrs) failed = 1;
        for (size_t a = 0; a < src->n_attrs && !failed; a++) {
            memcpy(dst->attrs[a].name, src->attrs[a].name, sizeof dst->attrs[a].name);
            dst->attrs[a].values = gather_array(src->attrs[a].values, n, sizeof(double), keep, kept, what, err, &failed);
            if (!failed) dst->n_attrs++;
        }
    }
    if (failed) {
        sy_cloud_free(dst);
        return sy_fail(err, SY_EINTERNAL, "%s: out of memory", what);
    }
    return SY_OK;
}

sy_code sy_cloud_copy(sy_cloud *dst, const sy_cloud *src, sy_error *err)
{
    return copy_points(dst, src, NULL, "point cloud copy", err);
}

sy_code sy_cloud_subset(sy_cloud *dst, const sy_cloud *src, const uint8_t *keep, sy_error *err)
{
    return copy_points(dst, src, keep, "point cloud subset", err);
}

void sy_cloud_rebase(sy_cloud *c)
{
    if (c->n == 0) return;
    double min[3], max[3];
    sy_cloud_bounds(c, min, max);
    for (int k = 0; k < 3; k++) {
        double shift = floor(min[k]) - c->origin[k];
        for (size_t i = 0; i < c->n; i++) c->xyz[3 * i + k] = (float)(c->xyz[3 * i + k] - shift);
        c->origin[k] += shift;
    }
}

sy_code sy_cloud_scalar(const sy_cloud *c, const char *name, double **out, sy_error *err)
{
    *out = NULL;
    const double *extra = sy_cloud_attr(c, name);
    /* Standard fields: array, element type (1 u8, 2 u16, 8 f64), stride, first component. */
    struct { const char *name; const void *p; int type, stride, at; } fixed[] = {
        {"intensity", c->intensity, 2, 1, 0},       {"nir", c->nir, 2, 1, 0},
        {"classification", c->classification, 1, 1, 0}, {"return_number", c->return_number, 1, 1, 0},
        {"number_of_returns", c->num_returns, 1, 1, 0}, {"gps_time", c->gps_time, 8, 1, 0},
        {"red", c->rgb, 2, 3, 0}, {"green", c->rgb, 2, 3, 1}, {"blue", c->rgb, 2, 3, 2},
    };
    int which = -1;
    for (int f = 0; f < (int)(sizeof fixed / sizeof fixed[0]) && !extra; f++)
        if (fixed[f].p && strcmp(fixed[f].name, name) == 0) which = f;
    if (!extra && which < 0) return SY_OK;
    double *v = sy_calloc(c->n ? c->n : 1, sizeof *v, err, "point values");
    if (!v) return SY_EINTERNAL;
    for (size_t i = 0; i < c->n; i++) {
        if (extra) {
            v[i] = extra[i];
            continue;
        }
        size_t k = i * (size_t)fixed[which].stride + (size_t)fixed[which].at;
        const void *p = fixed[which].p;
        v[i] = fixed[which].type == 1   ? ((const uint8_t *)p)[k]
               : fixed[which].type == 2 ? ((const uint16_t *)p)[k]
                                        : ((const double *)p)[k];
    }
    *out = v;
    return SY_OK;
}

void sy_cloud_attribute_names(const sy_cloud *c, char *buf, size_t size)
{
    struct { const void *p; const char *name; } fixed[] = {
        {c->xyz, "xyz"},           {c->normal, "normal"},
        {c->intensity, "intensity"}, {c->rgb, "rgb"},
        {c->nir, "nir"},           {c->classification, "classification"},
        {c->return_number, "return_number"}, {c->num_returns, "number_of_returns"},
        {c->gps_time, "gps_time"},
    };
    size_t used = 0;
    buf[0] = '\0';
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; i++)
        if (fixed[i].p && used < size)
            used += snprintf(buf + used, size - used, "%s%s", used ? "," : "", fixed[i].name);
    for (size_t a = 0; a < c->n_attrs && used < size; a++)
        used += snprintf(buf + used, size - used, "%s%s", used ? "," : "", c->attrs[a].name);
}

sy_code sy_cloud_check_range(const sy_cloud *c, const char *path, sy_error *err)
{
    for (int k = 0; k < 3; k++)
        if (!(fabs(c->origin[k]) <= SY_WORLD_MAX))
            return sy_fail(err, SY_EINPUT, "%s: origin %g on axis %c lies beyond %g m (a corrupt offset?)", path,
                           c->origin[k], 'x' + k, SY_WORLD_MAX);
    /* Chunks OR-reduce "outside the span" (NaN included) without an exit per
     * value, so the compiler vectorises the scan; only a chunk that has one
     * is searched for it. */
    enum { CHUNK = 4096 };
    const float span = (float)SY_CLOUD_MAX_SPAN;
    const size_t total = 3 * c->n;
    for (size_t start = 0; start < total; start += CHUNK) {
        size_t end = total - start < CHUNK ? total : start + CHUNK;
        int bad = 0;
        for (size_t i = start; i < end; i++) bad |= !(fabsf(c->xyz[i]) <= span);
        for (size_t i = start; bad && i < end; i++) {
            float v = c->xyz[i];
            size_t p = i / 3;
            if (!isfinite(v))
                return sy_fail(err, SY_EINPUT, "%s: point %zu lies too far from the first point (beyond single precision)",
                               path, p);
            if (!(fabsf(v) <= span))
                return sy_fail(err, SY_EINPUT,
                               "%s: point %zu lies %.3g m from the first point on axis %c (a scene spans at most %g km)",
                               path, p, (double)v, 'x' + (int)(i % 3), SY_CLOUD_MAX_SPAN / 1000);
        }
    }
    return SY_OK;
}
