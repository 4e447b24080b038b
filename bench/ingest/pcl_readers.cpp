#include "pcl_readers.h"

#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_types.h>

extern "C" long bench_pcl_load_ply(const char *path)
{
    pcl::PointCloud<pcl::PointXYZ> cloud;
    if (pcl::io::loadPLYFile(path, cloud) < 0) return -1;
    return (long)cloud.size();
}

extern "C" long bench_pcl_load_pcd(const char *path)
{
    pcl::PointCloud<pcl::PointXYZ> cloud;
    if (pcl::io::loadPCDFile(path, cloud) < 0) return -1;
    return (long)cloud.size();
}

extern "C" int bench_pcl_save_pcd_compressed(const char *path, const float *xyz, size_t n)
{
    pcl::PointCloud<pcl::PointXYZ> cloud;
    cloud.resize(n);
    for (size_t i = 0; i < n; i++) cloud[i] = pcl::PointXYZ(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    return pcl::io::savePCDFileBinaryCompressed(path, cloud) < 0 ? -1 : 0;
}
