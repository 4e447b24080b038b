/* Interim body while the real reader lands; replaced wholesale by it. */
#include "ingest.h"
sy_code sy_read_colmap_points_mem(const char *path, const unsigned char *data, size_t size, int kind, sy_cloud *out, sy_error *err)
{ (void)data; (void)size; (void)kind; (void)out; return sy_fail(err, SY_EINTERNAL, "%s: reader missing", path); }
sy_code sy_read_colmap_dir(const char *path, sy_cloud *out, sy_error *err)
{ (void)out; return sy_fail(err, SY_EINTERNAL, "%s: reader missing", path); }
