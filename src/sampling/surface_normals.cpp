#include "shine/sampling/surface_normals.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cstdint>
#include <vector>

#include "shine/sampling/point_kdtree.hpp"

namespace shine {
namespace {

constexpr int kMaxNeighbors = PointKdTree::kMaxNeighbors;

}  // namespace

std::vector<Eigen::Vector3f> estimate_ray_normals(const RaySet& rays, const NormalConfig& config) {
    return estimate_ray_normals(rays, config, 0, rays.num_rays());
}

std::vector<Eigen::Vector3f> estimate_ray_normals(const RaySet& rays, const NormalConfig& config,
                                                  std::size_t ray_begin, std::size_t ray_end) {
    const std::size_t n = rays.num_rays();
    std::vector<Eigen::Vector3f> normals(n, Eigen::Vector3f::Zero());
    ray_end = std::min(ray_end, n);
    if (n < 3 || ray_begin >= ray_end) return normals;
    // The tree over all endpoints, in ray order (which decides, as in the nanoflann tree this one
    // reproduces, the order of neighbours at equal distance).
    std::vector<IndexedPoint> endpoints(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 65536), [&](const auto& range) {
        for (std::size_t ray = range.begin(); ray != range.end(); ++ray) {
            endpoints[ray] = {rays.endpoint(ray), static_cast<std::uint32_t>(ray)};
        }
    });
    const PointKdTree tree(std::move(endpoints));
    const int k = std::clamp(config.neighbors, 3, kMaxNeighbors);
    const float max_radius_sq = config.max_radius_m * config.max_radius_m;

    // Queries in the tree's slot order, so that consecutive queries share leaves; each query
    // writes only its own normal, so the order does not change the result.
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, tree.size(), 4096), [&](const auto& range) {
            PointNeighbor neighbors[kMaxNeighbors];
            for (std::size_t slot = range.begin(); slot != range.end(); ++slot) {
                const std::size_t ray = tree.index_at(slot);
                if (ray < ray_begin || ray >= ray_end) continue;
                const Eigen::Vector3f& p = rays.endpoint(ray);
                // Only neighbours within max_radius_m are used; the search bound prunes the tree
                // walk (sparse, far regions).
                const int used = tree.nearest(p, k, max_radius_sq, neighbors);
                if (used < 5) continue;
                Eigen::Vector3d mean = Eigen::Vector3d::Zero();
                for (int i = 0; i < used; ++i) mean += neighbors[i].position.cast<double>();
                mean /= used;
                Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
                for (int i = 0; i < used; ++i) {
                    const Eigen::Vector3d d = neighbors[i].position.cast<double>() - mean;
                    covariance += d * d.transpose();
                }
                Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
                eig.computeDirect(covariance);
                const Eigen::Vector3d lambda = eig.eigenvalues();  // ascending
                if (!(lambda(2) > 0.0)) continue;
                if (lambda(0) > config.max_flatness * lambda(1)) continue;  // not a plane
                if (lambda(1) < config.min_spread * lambda(2)) continue;    // a line
                Eigen::Vector3d normal = eig.eigenvectors().col(0).normalized();
                if (normal.dot((rays.origin_of_ray(ray) - p).cast<double>()) < 0.0)
                    normal = -normal;
                normals[ray] = normal.cast<float>();
            }
        });
    return normals;
}

}  // namespace shine
