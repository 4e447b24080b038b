/* Interim bodies while the real readers land (this file is deleted then). */
#include "ingest.h"
#define NYI(fn, args) sy_code fn args { (void)data; (void)size; (void)out; return sy_fail(err, SY_EINTERNAL, "%s: reader missing", path); }
NYI(sy_read_las_mem, (const char *path, const unsigned char *data, size_t size, sy_cloud *out, sy_error *err))
NYI(sy_read_ply_mem, (const char *path, const unsigned char *data, size_t size, sy_cloud *out, sy_error *err))
NYI(sy_read_pcd_mem, (const char *path, const unsigned char *data, size_t size, sy_cloud *out, sy_error *err))
NYI(sy_read_xyz_mem, (const char *path, const unsigned char *data, size_t size, sy_cloud *out, sy_error *err))
sy_code sy_read_colmap_points_mem(const char *path, const unsigned char *data, size_t size, int kind, sy_cloud *out, sy_error *err) { (void)data; (void)size; (void)kind; (void)out; return sy_fail(err, 3, "%s: x", path); }
sy_code sy_read_colmap_dir(const char *path, sy_cloud *out, sy_error *err) { (void)out; return sy_fail(err, 3, "%s: x", path); }
sy_code sy_write_ply(const char *path, const sy_cloud *out, sy_error *err) { (void)out; return sy_fail(err, 3, "%s: x", path); }
sy_code sy_write_las(const char *path, const sy_cloud *out, sy_error *err) { (void)out; return sy_fail(err, 3, "%s: x", path); }
sy_code sy_write_xyz(const char *path, const sy_cloud *out, sy_error *err) { (void)out; return sy_fail(err, 3, "%s: x", path); }
