/* Ingest: point-cloud readers and writers. Every reader fills an sy_cloud
 * (positions rebased on a double origin, computed bounds, meta for `sylva info`)
 * or fails with SY_EINPUT and a one-line message naming the file and the problem.
 * Readers never trust header counts to size allocations: a count is checked
 * against the bytes actually present before anything is allocated. */
#ifndef SYLVA_INGEST_H
#define SYLVA_INGEST_H

#include "../core/cloud.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Reads any supported format, chosen by magic bytes first, then extension:
 * LAS ("LASF"), LAZ (refused with a clear message), PLY ("ply\n"),
 * PCD ("# .PCD" / "VERSION"), a COLMAP workspace or sparse-model directory,
 * else XYZ/TXT/CSV text. */
sy_code sy_read_cloud(const char *path, sy_cloud *out, sy_error *err);

/* Writes by extension: .ply (binary little endian), .las (LAS 1.4, point
 * format 6, 7 with RGB, 8 with NIR, or 0-3 when the CRS is GeoTIFF keys;
 * extra bytes for named attributes), .xyz/.txt (ASCII x y z [attributes]).
 * Atomic: temp file + rename. */
sy_code sy_write_cloud(const char *path, const sy_cloud *c, sy_error *err);

/* The individual readers, over a file already in memory (path is for messages).
 * They are what the fuzz targets drive. */
sy_code sy_read_las_mem(const char *path, const unsigned char *data, size_t size, sy_cloud *out,
                        sy_error *err);
sy_code sy_read_ply_mem(const char *path, const unsigned char *data, size_t size, sy_cloud *out,
                        sy_error *err);
sy_code sy_read_pcd_mem(const char *path, const unsigned char *data, size_t size, sy_cloud *out,
                        sy_error *err);
sy_code sy_read_xyz_mem(const char *path, const unsigned char *data, size_t size, sy_cloud *out,
                        sy_error *err);
/* COLMAP points3D.txt / points3D.bin contents (kind: 't' or 'b'). */
sy_code sy_read_colmap_points_mem(const char *path, const unsigned char *data, size_t size, int kind,
                                  sy_cloud *out, sy_error *err);
/* One COLMAP model file in memory: path names it in messages; binary picks
 * the .bin layout over the .txt one. */
typedef struct {
    const char *path;
    const unsigned char *data;
    size_t size;
    int binary;
} sy_colmap_file;
/* A sparse model from its three files: cameras and images are validated
 * (camera models, parameter counts, image -> camera and track -> image
 * references), the points become the cloud. */
sy_code sy_read_colmap_model_mem(const sy_colmap_file *cameras, const sy_colmap_file *images,
                                 const sy_colmap_file *points, sy_cloud *out, sy_error *err);
/* A COLMAP workspace (dir with sparse/0/, sparse/ or the model files, or
 * dense/fused.ply): cameras, images and points3D in .txt or .bin. */
sy_code sy_read_colmap_dir(const char *dir, sy_cloud *out, sy_error *err);

sy_code sy_write_ply(const char *path, const sy_cloud *c, sy_error *err);
sy_code sy_write_las(const char *path, const sy_cloud *c, sy_error *err);
sy_code sy_write_xyz(const char *path, const sy_cloud *c, sy_error *err);

/* Shared by the readers: rejects non-finite coordinates with a message naming
 * path and the point index; returns SY_OK when all are finite. */
sy_code sy_check_finite(const char *path, double x, double y, double z, size_t index, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
