// The only translation unit of the preprocessing stage that includes PCL.

// Debian's libpcl is built as C++14, where PCL_MAKE_ALIGNED_OPERATOR_NEW
// gives point clouds Eigen's class operator new/delete; in C++17 Eigen leaves
// them out, so a cloud allocated inside libpcl would be deleted here with the
// global operator (ASan: alloc-dealloc mismatch). Match the library.
#ifndef EIGEN_HAS_CXX17_OVERALIGN
#define EIGEN_HAS_CXX17_OVERALIGN 0
#endif
// Likewise, under AddressSanitizer Eigen stops trusting glibc's 16-byte-aligned malloc
// and switches to its offset allocator, while libpcl was built trusting it:
// point vectors allocated here and freed inside libpcl (or the reverse) would
// then hit a bad free. Keep this file on the library's allocator.
#if defined(__SANITIZE_ADDRESS__) && defined(__linux__) && defined(__LP64__) && !defined(EIGEN_MALLOC_ALREADY_ALIGNED)
#define EIGEN_MALLOC_ALREADY_ALIGNED 1
#endif
// PCL's templates are instantiated here rather than taken from libpcl_features,
// _filters, _segmentation and _search: those carry ~190k relocations that the
// dynamic loader resolved at every start of every sylva command (97% of
// `sylva --version`'s 0.1 s), for the four classes used below. Only
// libpcl_common stays linked.
#define PCL_NO_PRECOMPILE
#include "pcl_filters.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <vector>

#include <Eigen/Eigenvalues>
#include <pcl/common/centroid.h>
#include <pcl/console/print.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/progressive_morphological_filter.h>

namespace {

// PCL prints its own warnings and errors on stderr (PCL_WARN/PCL_ERROR);
// Sylva reports every failure in one line itself, so PCL's console stays quiet.
struct QuietPcl {
    QuietPcl() { pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS); }
} quiet_pcl;

using Cloud = pcl::PointCloud<pcl::PointXYZ>;

Cloud::Ptr to_pcl(const float *xyz, size_t n)
{
    Cloud::Ptr c(new Cloud);
    c->resize(n);
    for (size_t i = 0; i < n; i++) {
        (*c)[i].x = xyz[3 * i];
        (*c)[i].y = xyz[3 * i + 1];
        (*c)[i].z = xyz[3 * i + 2];
    }
    c->width = static_cast<uint32_t>(n);
    c->height = 1;
    c->is_dense = true;
    return c;
}

sy_code fail(sy_error *err, const char *what, const char *why)
{
    return sy_fail(err, SY_EINTERNAL, "%s: %s", what, why);
}

} // namespace

extern "C" sy_code sy_pcl_outliers(const float *xyz, size_t n, int k, double std_mul, int threads, uint8_t *keep,
                                   sy_error *err)
{
    try {
        std::fill(keep, keep + n, uint8_t{0});
        if (n == 0) return SY_OK;
        if (n <= static_cast<size_t>(k)) { // too few points to judge any of them
            std::fill(keep, keep + n, uint8_t{1});
            return SY_OK;
        }
        Cloud::Ptr c = to_pcl(xyz, n);
        // pcl::StatisticalOutlierRemoval::applyFilterIndices (PCL 1.13), its
        // neighbour pass spread over threads as NormalEstimationOMP does: the
        // same unsorted KdTree, the same per-point float means, then the
        // mean and deviation summed in point order, so the same mask.
        pcl::search::KdTree<pcl::PointXYZ> tree(false);
        tree.setInputCloud(c);
        const int searcher_k = k + 1; // the query point comes back first
        std::vector<float> distances(n);
        std::vector<uint8_t> valid(n, 0);
        const long long count = static_cast<long long>(n);
#pragma omp parallel num_threads(threads > 0 ? threads : 1)
        {
            pcl::Indices nn_indices(searcher_k);
            std::vector<float> nn_dists(searcher_k);
#pragma omp for schedule(dynamic, 4096)
            for (long long i = 0; i < count; i++) {
                const pcl::PointXYZ &p = (*c)[static_cast<size_t>(i)];
                distances[i] = 0.0f;
                if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) continue;
                if (tree.nearestKSearch(static_cast<pcl::index_t>(i), searcher_k, nn_indices, nn_dists) == 0) continue;
                double dist_sum = 0.0;
                for (int j = 1; j < searcher_k; ++j) dist_sum += std::sqrt(nn_dists[j]);
                distances[i] = static_cast<float>(dist_sum / k);
                valid[i] = 1;
            }
        }
        double sum = 0, sq_sum = 0, valid_distances = 0;
        for (size_t i = 0; i < n; i++) {
            sum += distances[i];
            sq_sum += distances[i] * distances[i];
            valid_distances += valid[i];
        }
        double mean = sum / valid_distances;
        double variance = (sq_sum - sum * sum / valid_distances) / (valid_distances - 1);
        double threshold = mean + std_mul * std::sqrt(variance);
        for (size_t i = 0; i < n; i++) keep[i] = !(distances[i] > threshold);
        return SY_OK;
    } catch (const std::exception &e) {
        return fail(err, "outlier removal", e.what());
    } catch (...) {
        return fail(err, "outlier removal", "PCL failed");
    }
}

extern "C" sy_code sy_pcl_normals(const float *xyz, size_t n, int k, int threads, float *normals,
                                  sy_pcl_progress_fn progress, void *ctx, sy_error *err)
{
    try {
        std::fill(normals, normals + 3 * n, 0.0f);
        if (n < 3) return SY_OK;
        Cloud::Ptr c = to_pcl(xyz, n);
        pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
        tree->setInputCloud(c);
        pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> ne(threads > 0 ? threads : 1);
        ne.setInputCloud(c);
        ne.setSearchMethod(tree);
        ne.setKSearch(std::min<int>(k, static_cast<int>(n)));
        // Chunks only give progress lines; each normal is computed the same way
        // whatever the chunking.
        const size_t chunk = 100000;
        for (size_t begin = 0; begin < n; begin += chunk) {
            size_t end = std::min(n, begin + chunk);
            pcl::IndicesPtr idx(new pcl::Indices(end - begin));
            for (size_t i = begin; i < end; i++) (*idx)[i - begin] = static_cast<pcl::index_t>(i);
            ne.setIndices(idx);
            pcl::PointCloud<pcl::Normal> out;
            ne.compute(out);
            for (size_t i = begin; i < end; i++) {
                const pcl::Normal &p = out[i - begin];
                if (std::isfinite(p.normal_x) && std::isfinite(p.normal_y) && std::isfinite(p.normal_z)) {
                    normals[3 * i] = p.normal_x;
                    normals[3 * i + 1] = p.normal_y;
                    normals[3 * i + 2] = p.normal_z;
                }
            }
            if (progress) progress(ctx, end);
        }
        return SY_OK;
    } catch (const std::exception &e) {
        return fail(err, "normal estimation", e.what());
    } catch (...) {
        return fail(err, "normal estimation", "PCL failed");
    }
}

extern "C" sy_code sy_pcl_local_pca(const float *xyz, size_t n, int k, float *direction, float *normal,
                                    float *eigen, sy_error *err)
{
    try {
        std::fill(direction, direction + 3 * n, 0.0f);
        std::fill(normal, normal + 3 * n, 0.0f);
        std::fill(eigen, eigen + 3 * n, 0.0f);
        if (n < 3) return SY_OK;
        Cloud::Ptr c = to_pcl(xyz, n);
        pcl::KdTreeFLANN<pcl::PointXYZ> tree;
        tree.setInputCloud(c);
        int kk = std::min<int>(k, static_cast<int>(n));
        pcl::Indices nb;
        std::vector<float> d2;
        for (size_t i = 0; i < n; i++) {
            if (tree.nearestKSearch((*c)[i], kk, nb, d2) < 3) continue;
            EIGEN_ALIGN16 Eigen::Matrix3f cov;
            Eigen::Vector4f centroid;
            if (pcl::computeMeanAndCovarianceMatrix(*c, nb, cov, centroid) < 3) continue;
            Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> es(cov);
            if (es.info() != Eigen::Success) continue;
            // Eigen sorts eigenvalues ascending.
            const Eigen::Vector3f &w = es.eigenvalues();
            for (int a = 0; a < 3; a++) {
                direction[3 * i + a] = es.eigenvectors()(a, 2);
                normal[3 * i + a] = es.eigenvectors()(a, 0);
                eigen[3 * i + a] = std::max(0.0f, w(2 - a));
            }
        }
        return SY_OK;
    } catch (const std::exception &e) {
        return fail(err, "local PCA", e.what());
    } catch (...) {
        return fail(err, "local PCA", "PCL failed");
    }
}

extern "C" sy_code sy_pcl_ground_pmf(const float *xyz, size_t n, double cell, double slope, double max_window,
                                     double initial_distance, double max_distance, uint8_t *ground,
                                     sy_error *err)
{
    try {
        std::fill(ground, ground + n, uint8_t{0});
        if (n == 0) return SY_OK;
        Cloud::Ptr c = to_pcl(xyz, n);
        pcl::ProgressiveMorphologicalFilter<pcl::PointXYZ> pmf;
        pmf.setInputCloud(c);
        pmf.setCellSize(static_cast<float>(cell));
        // PCL computes the threshold as slope * (window growth in metres) * cell
        // size; dividing by the cell size restores Zhang's slope * growth.
        pmf.setSlope(static_cast<float>(slope / cell));
        pmf.setMaxWindowSize(static_cast<float>(max_window));
        pmf.setInitialDistance(static_cast<float>(initial_distance));
        pmf.setMaxDistance(static_cast<float>(max_distance));
        pcl::Indices g;
        pmf.extract(g);
        for (auto i : g) ground[i] = 1;
        return SY_OK;
    } catch (const std::exception &e) {
        return fail(err, "ground filter", e.what());
    } catch (...) {
        return fail(err, "ground filter", "PCL failed");
    }
}
