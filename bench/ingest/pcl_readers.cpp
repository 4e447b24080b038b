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
