#include "shine/sampling/surface_normals.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <nanoflann.hpp>

namespace shine {
namespace {

/// nanoflann's view of the ray endpoints.
struct EndpointCloud {
    const RaySet& rays;

    std::size_t kdtree_get_point_count() const { return rays.num_rays(); }
    float kdtree_get_pt(std::uint32_t ray, std::size_t axis) const {
        return rays.endpoint(ray)[static_cast<Eigen::Index>(axis)];
    }
    template <class BoundingBox>
    bool kdtree_get_bbox(BoundingBox& /*unused*/) const {
        return false;
    }
};

using EndpointTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, EndpointCloud>,
                                        EndpointCloud, 3, std::uint32_t>;

constexpr int kMaxNeighbors = 64;

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
    const EndpointCloud cloud{rays};
    EndpointTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    tree.buildIndex();
    const int k = std::clamp(config.neighbors, 3, kMaxNeighbors);
    const float max_radius_sq = config.max_radius_m * config.max_radius_m;
    const float search_bound_sq =
        std::nextafter(max_radius_sq, std::numeric_limits<float>::infinity());

    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(ray_begin, ray_end, 4096), [&](const auto& range) {
            std::uint32_t index[kMaxNeighbors];
            float distance_sq[kMaxNeighbors];
            for (std::size_t ray = range.begin(); ray != range.end(); ++ray) {
                const Eigen::Vector3f& p = rays.endpoint(ray);
                nanoflann::KNNResultSet<float, std::uint32_t> result(static_cast<std::size_t>(k));
                result.init(index, distance_sq);
                // Only neighbours within max_radius_m are used: starting the search with that
                // bound as the k-th distance prunes the tree walk (sparse, far regions) and
                // finds the same neighbours as an unbounded search filtered afterwards.
                distance_sq[k - 1] = search_bound_sq;
                tree.findNeighbors(result, p.data(), nanoflann::SearchParams());
                const std::size_t found = result.size();
                Eigen::Vector3d mean = Eigen::Vector3d::Zero();
                int used = 0;
                for (std::size_t i = 0; i < found; ++i) {
                    if (distance_sq[i] > max_radius_sq) continue;
                    mean += rays.endpoint(index[i]).cast<double>();
                    ++used;
                }
                if (used < 5) continue;
                mean /= used;
                Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
                for (std::size_t i = 0; i < found; ++i) {
                    if (distance_sq[i] > max_radius_sq) continue;
                    const Eigen::Vector3d d = rays.endpoint(index[i]).cast<double>() - mean;
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
