/* PointCloud: the noun every scan becomes. Structure of arrays; positions are
 * float offsets from a double origin, because survey coordinates (e.g. 1.17e6 m)
 * lose centimetres in float otherwise. Z is up inside Sylva. Every optional
 * array is NULL when absent. */
#ifndef SYLVA_CLOUD_H
#define SYLVA_CLOUD_H

#include <stddef.h>
#include <stdint.h>

#include "status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A named per-point scalar (LAS extra bytes such as treeID, PLY scalar fields,
 * extra XYZ columns). Values are kept as double so integer ids stay exact. */
typedef struct {
    char name[32];
    double *values; /* n values */
} sy_attr;

/* Where a cloud came from: what `sylva info` reports. Filled by readers. */
typedef struct {
    char format[16];        /* "LAS", "PLY", "XYZ", "PCD", "COLMAP" */
    char version[32];       /* "1.4", "binary_little_endian 1.0", ... */
    int point_format;       /* LAS point data record format, -1 otherwise */
    char *crs;              /* CRS summary (WKT or GeoTIFF keys), NULL if none; owned */
    char *vlr_summary;      /* one line per VLR "user_id/record_id: description", owned */
    uint64_t header_count;  /* count promised by the header (0 if none) */
    /* What a LAS writer needs to carry the CRS over exactly (the summary above
     * is cut and normalised): the whole WKT text of a WKT VLR, and the GeoTIFF
     * VLRs (LASF_Projection 34735-34737) as complete 54-byte-header records. */
    char *crs_wkt;           /* owned, NULL if none */
    unsigned char *geotiff;  /* owned, geotiff_len bytes holding geotiff_vlrs records */
    size_t geotiff_len;
    unsigned geotiff_vlrs;
    unsigned las_global_encoding; /* as read from a LAS header (reported by `sylva info`) */
    /* gps_time holds adjusted standard GPS time (GPS seconds - 1e9, LAS global
     * encoding bit 0) rather than seconds of the GPS week: the same numbers
     * mean different instants, so writers must keep the flag with the values. */
    int gps_time_standard;
} sy_cloud_meta;

typedef struct {
    size_t n;
    double origin[3];        /* world position = origin + xyz */
    float *xyz;              /* 3n */
    float *normal;           /* 3n or NULL */
    uint16_t *intensity;     /* n or NULL */
    uint16_t *rgb;           /* 3n or NULL, 16-bit per channel (LAS convention) */
    uint16_t *nir;           /* n or NULL */
    uint8_t *classification; /* n or NULL (ASPRS classes: 2 = ground) */
    uint8_t *return_number;  /* n or NULL */
    uint8_t *num_returns;    /* n or NULL */
    double *gps_time;        /* n or NULL */
    size_t n_attrs;
    sy_attr *attrs;
    sy_cloud_meta meta;
} sy_cloud;

/* Bounds on coordinates. A world coordinate beyond SY_WORLD_MAX metres (far
 * past any terrestrial CRS) or a point farther than SY_CLOUD_MAX_SPAN from the
 * cloud's origin is a corrupt value, not a scene: rejecting it where the file
 * is read keeps every later step bounded by the data, never by one number. */
#define SY_WORLD_MAX 1e9
#define SY_CLOUD_MAX_SPAN 1e6

/* SY_EINPUT naming path and the first point that breaks those bounds (or is
 * not finite); SY_OK otherwise. Vectorised: it runs after every reader. */
sy_code sy_cloud_check_range(const sy_cloud *c, const char *path, sy_error *err);

/* Allocates xyz for n points (other arrays stay NULL). */
sy_code sy_cloud_init(sy_cloud *c, size_t n, sy_error *err);
void sy_cloud_free(sy_cloud *c);

/* Optional arrays, zero-filled, allocated on demand. */
sy_code sy_cloud_add_normals(sy_cloud *c, sy_error *err);
sy_code sy_cloud_add_intensity(sy_cloud *c, sy_error *err);
sy_code sy_cloud_add_rgb(sy_cloud *c, sy_error *err);
sy_code sy_cloud_add_classification(sy_cloud *c, sy_error *err);
sy_code sy_cloud_add_returns(sy_cloud *c, sy_error *err);
sy_code sy_cloud_add_gps_time(sy_cloud *c, sy_error *err);
/* Adds (or returns the existing) named attribute, zero-filled. */
double *sy_cloud_add_attr(sy_cloud *c, const char *name, sy_error *err);
/* The named attribute's values or NULL. */
double *sy_cloud_attr(const sy_cloud *c, const char *name);

/* Computed bounds in world coordinates (never trusted from headers). */
void sy_cloud_bounds(const sy_cloud *c, double min[3], double max[3]);

/* Keeps the points with keep[i] != 0, in order, across every array. */
sy_code sy_cloud_filter(sy_cloud *c, const uint8_t *keep, sy_error *err);

/* Deep copy. */
sy_code sy_cloud_copy(sy_cloud *dst, const sy_cloud *src, sy_error *err);

/* Deep copy of the points with keep[i] != 0 only, in order, every array and
 * the meta kept: what sy_cloud_copy + sy_cloud_filter give, without holding
 * the whole copy (a tree out of a plot of millions). */
sy_code sy_cloud_subset(sy_cloud *dst, const sy_cloud *src, const uint8_t *keep, sy_error *err);

/* Sets origin to the bounds' lower corner (rounded to the metre) and rebases
 * xyz, so float positions stay small. */
void sy_cloud_rebase(sy_cloud *c);

/* Comma-separated attribute list, e.g. "xyz,intensity,rgb,treeID". */
void sy_cloud_attribute_names(const sy_cloud *c, char *buf, size_t size);

/* One value a point of the scalar named as sy_cloud_attribute_names lists
 * it: an extra-bytes attribute, or a standard field (intensity, nir,
 * classification, return_number, number_of_returns, gps_time, and red,
 * green, blue of rgb), so labels can live in either. *out: n doubles
 * (malloc'd), NULL when the cloud has no such field (SY_OK all the same). */
sy_code sy_cloud_scalar(const sy_cloud *c, const char *name, double **out, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
