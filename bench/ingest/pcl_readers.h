/* PCL's PLY and PCD readers behind a C call, for the ingest benchmark. */
#ifndef SYLVA_BENCH_PCL_READERS_H
#define SYLVA_BENCH_PCL_READERS_H
#include <stddef.h>
#ifdef __cplusplus
extern "C" {
#endif
/* Loads into pcl::PointCloud<pcl::PointXYZ>; returns the point count or -1. */
long bench_pcl_load_ply(const char *path);
long bench_pcl_load_pcd(const char *path);
#ifdef __cplusplus
}
#endif
#endif
