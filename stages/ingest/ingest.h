/* Ingest: point-cloud readers and writers. Every reader fills an sy_cloud
 * (positions rebased on a double origin, computed bounds, meta for `sylva info`)
 * or fails with SY_EINPUT and a one-line message naming the file and the problem.
 * Readers never trust header counts to size allocations: a count is checked
 * against the bytes actually present before anything is allocated. */
#ifndef SYLVA_INGEST_H
#define SYLVA_INGEST_H

#include "../core/cloud.h"
#include "../core/fileio.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Reads any supported format, chosen by magic bytes first, then extension:
 * LAS or LAZ ("LASF"; LAZ chunks decode on sy_threads() threads), PLY ("ply\n"),
 * PCD ("# .PCD" / "VERSION"), a COLMAP workspace or sparse-model directory,
 * else XYZ/TXT/CSV text. */
sy_code sy_read_cloud(const char *path, sy_cloud *out, sy_error *err);

/* Writes by extension: .ply (binary little endian), .las (LAS 1.4, point
 * format 6, 7 with RGB, 8 with NIR, or 0-3 when the CRS is GeoTIFF keys;
 * extra bytes for named attributes), .laz (the same, LASzip-compressed),
 * .xyz/.txt (ASCII x y z [attributes]).
 * Atomic: temp file + rename. */
sy_code sy_write_cloud(const char *path, const sy_cloud *c, sy_error *err);

/* What `sylva info` prints, without holding the cloud where the format
 * allows: uncompressed LAS from its header, (E)VLRs and one streaming pass
 * over the records (bounded memory; the numbers and errors are those
 * of sy_read_cloud); other formats read whole. meta carries the format,
 * VLRs, CRS and the attribute arrays a full read keeps (free it with
 * sy_cloud_free); *n and the bounds are the cloud's. */
sy_code sy_cloud_info(const char *path, sy_cloud *meta, size_t *n, double lo[3], double hi[3], sy_error *err);
/* The streaming LAS part over a mapped file (headers and (E)VLRs are read
 * from data; the records too when fd < 0, else through a 1 MB buffer by
 * pread on fd): *done = 0 (nothing set, SY_OK) when the file needs the whole
 * reader (LAZ, or a check failed). */
sy_code sy_las_info_mem(const char *path, const unsigned char *data, size_t size, int fd, sy_cloud *meta, size_t *n,
                        double lo[3], double hi[3], int *done, sy_error *err);

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

/* One registered image of a COLMAP model: world-to-camera rotation as a unit
 * quaternion (w, x, y, z) and translation, so the camera centre is -R^T t
 * and its up direction -R^T (0, 1, 0) (image y points down). */
typedef struct {
    uint32_t id;
    double q[4], t[3];
    char name[128];
} sy_colmap_pose;
/* The image poses of the sparse model in dir (cameras and images .bin or
 * .txt, validated as sy_read_colmap_dir does); *poses is malloc'ed. */
sy_code sy_read_colmap_poses(const char *dir, sy_colmap_pose **poses, size_t *n, sy_error *err);

/* Lossless LAS <-> LAZ transcoding of a whole file in memory (header, VLRs,
 * EVLRs and every record byte kept; only the LASzip VLR, the compression bit
 * and the offsets they move change). out->data is malloc'ed; compressing and
 * then decompressing returns the input byte for byte. LAZ point formats:
 * 0-3 (LASzip's point-wise items) and 6-8 (its layered LAS 1.4 items). */
sy_code sy_laz_compress_mem(const char *path, const unsigned char *las, size_t size, sy_buffer *out, sy_error *err);
sy_code sy_laz_decompress_mem(const char *path, const unsigned char *laz, size_t size, sy_buffer *out,
                              sy_error *err);

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
