/* Format detection and dispatch for the readers and writers. */
#include "ingest.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include "../core/fileio.h"

sy_code sy_check_finite(const char *path, double x, double y, double z, size_t index, sy_error *err)
{
    if (isfinite(x) && isfinite(y) && isfinite(z)) return SY_OK;
    return sy_fail(err, SY_EINPUT, "%s: point %zu has a non-finite coordinate (%g %g %g)", path, index, x, y, z);
}

static int starts_with(const sy_buffer *b, const char *magic)
{
    size_t n = strlen(magic);
    return b->size >= n && memcmp(b->data, magic, n) == 0;
}

static int ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && strcmp(s + n - m, suffix) == 0;
}

/* PCD files open with comment lines or a VERSION line. */
static int looks_like_pcd(const sy_buffer *b, const char *ext)
{
    if (strcmp(ext, "pcd") == 0) return 1;
    return starts_with(b, "# .PCD") || starts_with(b, "VERSION .7") || starts_with(b, "VERSION 0.7");
}

/* LAS and LAZ, the formats of large scans, are decoded straight from a
 * read-only mapping of the file: no copy of it in memory beside the cloud,
 * and its pages are the kernel's to drop once read (POSIX_MADV_SEQUENTIAL), so the
 * file costs no memory the decoder holds. 1 when path was such a file (rc
 * set), 0 for anything else (other formats are read into a buffer: the text
 * readers rely on its terminating NUL). */
static int read_mapped_las(const char *path, sy_cloud *out, sy_code *rc, sy_error *err)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    if (fd < 0) return 0;
    struct stat st;
    void *map = MAP_FAILED;
    size_t size = 0;
    if (fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size >= 4) {
        size = (size_t)st.st_size;
        map = mmap(NULL, size, PROT_READ, MAP_PRIVATE, fd, 0);
    }
    close(fd);
    if (map == MAP_FAILED) return 0;
    int las = memcmp(map, "LASF", 4) == 0;
    if (las) {
        (void)posix_madvise(map, size, POSIX_MADV_SEQUENTIAL);
        *rc = sy_read_las_mem(path, map, size, out, err);
    }
    munmap(map, size);
    return las;
}

static sy_code read_any(const char *path, sy_cloud *out, sy_error *err)
{
    memset(out, 0, sizeof *out);
    if (sy_is_directory(path)) return sy_read_colmap_dir(path, out, err);
    char ext[16];
    sy_extension(path, ext, sizeof ext);
    sy_code rc = SY_OK;
    if (read_mapped_las(path, out, &rc, err)) {
        if (rc == SY_OK && out->n == 0) {
            sy_cloud_free(out);
            return sy_fail(err, SY_EINPUT, "%s: no points", path);
        }
        if (rc) sy_cloud_free(out);
        return rc;
    }
    sy_buffer b;
    rc = sy_read_file(path, &b, err);
    if (rc) return rc;
    if (b.size == 0) {
        sy_buffer_free(&b);
        return sy_fail(err, SY_EINPUT, "%s: empty file", path);
    }
    if (starts_with(&b, "LASF")) rc = sy_read_las_mem(path, b.data, b.size, out, err);
    else if (strcmp(ext, "laz") == 0 || strcmp(ext, "las") == 0)
        rc = sy_fail(err, SY_EINPUT, "%s: not a LAS file (no LASF signature)", path);
    else if (starts_with(&b, "ply\n") || starts_with(&b, "ply\r\n")) rc = sy_read_ply_mem(path, b.data, b.size, out, err);
    else if (strcmp(ext, "ply") == 0) rc = sy_fail(err, SY_EINPUT, "%s: not a PLY file (no 'ply' magic line)", path);
    else if (looks_like_pcd(&b, ext)) rc = sy_read_pcd_mem(path, b.data, b.size, out, err);
    else if (starts_with(&b, "glTF") || strcmp(ext, "glb") == 0 || strcmp(ext, "gltf") == 0)
        rc = sy_fail(err, SY_EINPUT, "%s: a glTF asset, not a point cloud (see `sylva view` or `sylva eval`)", path);
    else if (ends_with(path, "points3D.bin") || strcmp(ext, "bin") == 0)
        rc = sy_read_colmap_points_mem(path, b.data, b.size, 'b', out, err);
    else if (ends_with(path, "points3D.txt")) rc = sy_read_colmap_points_mem(path, b.data, b.size, 't', out, err);
    else rc = sy_read_xyz_mem(path, b.data, b.size, out, err);
    sy_buffer_free(&b);
    if (rc == SY_OK && out->n == 0) {
        sy_cloud_free(out);
        return sy_fail(err, SY_EINPUT, "%s: no points", path);
    }
    if (rc) sy_cloud_free(out);
    return rc;
}

sy_code sy_read_cloud(const char *path, sy_cloud *out, sy_error *err)
{
    sy_code rc = read_any(path, out, err);
    if (rc == SY_OK && (rc = sy_cloud_check_range(out, path, err))) sy_cloud_free(out);
    return rc;
}

sy_code sy_write_cloud(const char *path, const sy_cloud *c, sy_error *err)
{
    char ext[16];
    sy_extension(path, ext, sizeof ext);
    if (strcmp(ext, "ply") == 0) return sy_write_ply(path, c, err);
    if (strcmp(ext, "las") == 0 || strcmp(ext, "laz") == 0) return sy_write_las(path, c, err);
    if (strcmp(ext, "xyz") == 0 || strcmp(ext, "txt") == 0) return sy_write_xyz(path, c, err);
    return sy_fail(err, SY_EUSAGE, "%s: unknown output format '.%s' (use .ply, .las, .laz, .xyz or .txt)", path, ext);
}

sy_code sy_cloud_info(const char *path, sy_cloud *meta, size_t *n, double lo[3], double hi[3], sy_error *err)
{
    memset(meta, 0, sizeof *meta);
    int done = 0;
    sy_code rc = SY_OK;
    int fd = sy_is_directory(path) ? -1 : open(path, O_RDONLY);
    struct stat st;
    if (fd >= 0 && fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size >= 4) {
        size_t size = (size_t)st.st_size;
        void *map = mmap(NULL, size, PROT_READ, MAP_PRIVATE, fd, 0);
        if (map != MAP_FAILED) {
            if (memcmp(map, "LASF", 4) == 0) rc = sy_las_info_mem(path, map, size, fd, meta, n, lo, hi, &done, err);
            munmap(map, size);
        }
    }
    if (fd >= 0) close(fd);
    if (rc || done) return rc;
    if ((rc = sy_read_cloud(path, meta, err))) return rc;
    *n = meta->n;
    sy_cloud_bounds(meta, lo, hi);
    return SY_OK;
}
