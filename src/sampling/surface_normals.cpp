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
    // reproduces, the order of neighbours at equal distance). Rays grouped by voxel: over the
    // groups' first rays only, the points thinning would have kept, so the normals are those of
    // the thinned scans, shared by each group's rays.
    const std::size_t groups = rays.num_groups();
    std::vector<IndexedPoint> endpoints(groups);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, groups, 65536), [&](const auto& range) {
        for (std::size_t g = range.begin(); g != range.end(); ++g) {
            const std::size_t ray = rays.first_ray_of_group(g);
            endpoints[g] = {rays.endpoint(ray), static_cast<std::uint32_t>(ray)};
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
    if (rays.grouped()) {
        const std::size_t first = rays.group_at_or_after(ray_begin);
        const std::size_t last = rays.group_at_or_after(ray_end);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(first, last, 4096),
                          [&](const auto& range) {
                              for (std::size_t g = range.begin(); g != range.end(); ++g) {
                                  const std::size_t lead = rays.first_ray_of_group(g);
                                  const std::size_t end = rays.first_ray_of_group(g + 1);
                                  for (std::size_t r = lead + 1; r < end; ++r) {
                                      normals[r] = normals[lead];
                                  }
                              }
                          });
    }
    return normals;
}

}  // namespace shine
