/* PCL's PLY and PCD readers (and its binary_compressed PCD writer, which
 * makes that benchmark file) behind C calls, for the ingest benchmark. */
#ifndef SYLVA_BENCH_PCL_READERS_H
#define SYLVA_BENCH_PCL_READERS_H
#include <stddef.h>
#ifdef __cplusplus
extern "C" {
#endif
/* Loads into pcl::PointCloud<pcl::PointXYZ>; returns the point count or -1. */
long bench_pcl_load_ply(const char *path);
long bench_pcl_load_pcd(const char *path);
/* Writes n points as a binary_compressed PCD; 0 or -1. */
int bench_pcl_save_pcd_compressed(const char *path, const float *xyz, size_t n);
#ifdef __cplusplus
}
#endif
#endif
