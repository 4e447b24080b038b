/* The preprocessing stage's window onto PCL: plain float arrays in, plain
 * arrays out, no PCL types. Positions are the cloud's float xyz (offsets from
 * its double origin), 3n floats. Every function returns SY_OK, or
 * SY_EINTERNAL with a one-line reason in err (PCL throws; the shim catches
 * everything). */
#ifndef SYLVA_PCL_FILTERS_H
#define SYLVA_PCL_FILTERS_H

#include <stddef.h>
#include <stdint.h>

#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Statistical outlier removal, pcl::StatisticalOutlierRemoval's rule on
 * `threads` threads: keep[i] = 1 when the mean distance of point i to its k
 * nearest neighbours is within std_mul standard deviations of the
 * cloud-wide mean. The same mask for any thread count. */
sy_code sy_pcl_outliers(const float *xyz, size_t n, int k, double std_mul, int threads, uint8_t *keep,
                        sy_error *err);

/* Called between chunks of a long computation with the points done so far. */
typedef void (*sy_pcl_progress_fn)(void *ctx, size_t done);

/* Normals from the k nearest neighbours (pcl::NormalEstimationOMP on
 * `threads` threads), unoriented, 3n floats. Every point's normal depends
 * only on its neighbourhood, so the result does not depend on threads.
 * Points whose neighbourhood is degenerate get (0, 0, 0). */
sy_code sy_pcl_normals(const float *xyz, size_t n, int k, int threads, float *normals,
                       sy_pcl_progress_fn progress, void *ctx, sy_error *err);

/* Local PCA over the k nearest neighbours: for each point the unit
 * eigenvectors of the neighbourhood covariance with the largest
 * (direction, 3n) and smallest (normal, 3n) eigenvalue, and the three
 * eigenvalues in descending order (eigen, 3n). */
sy_code sy_pcl_local_pca(const float *xyz, size_t n, int k, float *direction, float *normal, float *eigen,
                         sy_error *err);

/* Progressive morphological filter (pcl::ProgressiveMorphologicalFilter,
 * Zhang et al. 2003) with z as height: ground[i] = 1 for ground returns.
 * slope is the terrain slope (rise over run) the filter tolerates; the shim
 * compensates PCL's extra cell-size factor in its height thresholds. */
sy_code sy_pcl_ground_pmf(const float *xyz, size_t n, double cell, double slope, double max_window,
                          double initial_distance, double max_distance, uint8_t *ground, sy_error *err);

#ifdef __cplusplus
}
#endif

#endif
