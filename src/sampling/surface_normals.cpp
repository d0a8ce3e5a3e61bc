#include "shine/sampling/surface_normals.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

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
                normals[ray] = fit_plane_normal(
                    used, [&](int i) -> const Eigen::Vector3f& { return neighbors[i].position; }, p,
                    rays.origin_of_ray(ray), config);
            }
        });
    return normals;
}

}  // namespace shine
