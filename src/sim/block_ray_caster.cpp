#include "shine/sim/block_ray_caster.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <mutex>
#include <numeric>
#include <optional>
#include <string>

#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"

namespace shine::sim {

BlockRayCaster::BlockRayCaster(const TriangleMesh& mesh, const std::vector<TriangleBlock>& blocks,
                               bool show_progress) {
    std::vector<std::size_t> by_start(blocks.size());
    std::iota(by_start.begin(), by_start.end(), std::size_t{0});
    std::sort(by_start.begin(), by_start.end(), [&](std::size_t a, std::size_t b) {
        return blocks[a].first_triangle < blocks[b].first_triangle;
    });
    for (std::size_t k = 0; k < by_start.size(); ++k) {
        const TriangleBlock& b = blocks[by_start[k]];
        if (b.first_triangle > mesh.triangles.size() ||
            b.num_triangles > mesh.triangles.size() - b.first_triangle) {
            throw ConfigError("BlockRayCaster: block " + std::to_string(by_start[k]) +
                              " (triangles from " + std::to_string(b.first_triangle) + ", " +
                              std::to_string(b.num_triangles) + " of them) exceeds the mesh of " +
                              std::to_string(mesh.triangles.size()) + " triangles");
        }
        if (k > 0) {
            const TriangleBlock& previous = blocks[by_start[k - 1]];
            if (previous.first_triangle + previous.num_triangles > b.first_triangle) {
                throw ConfigError("BlockRayCaster: blocks " + std::to_string(by_start[k - 1]) +
                                  " and " + std::to_string(by_start[k]) +
                                  " share triangles; give each triangle to one block");
            }
        }
    }
    std::size_t total_triangles = 0;
    for (const TriangleBlock& b : blocks) total_triangles += b.num_triangles;
    // Build the largest blocks first so that the last ones to finish are small.
    std::vector<std::size_t> build_order = by_start;
    std::stable_sort(build_order.begin(), build_order.end(), [&](std::size_t a, std::size_t b) {
        return blocks[a].num_triangles > blocks[b].num_triangles;
    });
    std::vector<std::optional<RayCaster>> built(blocks.size());
    std::mutex progress_mutex;  // Progress is not thread-safe
    std::size_t done = 0;
    Progress progress("bvh", blocks.size(), show_progress);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, build_order.size(), 1),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t k = range.begin(); k != range.end(); ++k) {
                              const TriangleBlock& b = blocks[build_order[k]];
                              built[build_order[k]].emplace(mesh, b.first_triangle,
                                                            b.num_triangles);
                              const std::lock_guard<std::mutex> lock(progress_mutex);
                              progress.update(++done, "blocks");
                          }
                      });
    progress.finish(std::to_string(blocks.size()) + " blocks, " + std::to_string(total_triangles) +
                    " triangles");
    casters_.reserve(blocks.size());
    bounds_.reserve(blocks.size());
    for (auto& caster : built) {
        bounds_.push_back(caster->bounds());
        casters_.push_back(std::move(*caster));
    }
}

std::size_t BlockRayCaster::num_triangles() const {
    std::size_t n = 0;
    for (const RayCaster& c : casters_) n += c.num_triangles();
    return n;
}

BlockSelection BlockRayCaster::select(const Eigen::Vector3d& point_m, double radius_m) const {
    BlockSelection selection;
    selection.owner_ = this;
    std::vector<std::pair<double, std::size_t>> near;
    for (std::size_t i = 0; i < bounds_.size(); ++i) {
        if (bounds_[i].isEmpty()) continue;
        const Eigen::Vector3d lower = bounds_[i].min().cast<double>();
        const Eigen::Vector3d upper = bounds_[i].max().cast<double>();
        const Eigen::Vector3d outside =
            (lower - point_m).cwiseMax(point_m - upper).cwiseMax(Eigen::Vector3d::Zero());
        const double distance_m = outside.norm();
        if (distance_m <= radius_m) near.emplace_back(distance_m, i);
    }
    std::sort(near.begin(), near.end());
    selection.blocks_.reserve(near.size());
    for (const auto& [distance_m, index] : near) selection.blocks_.push_back(index);
    return selection;
}

RayHit BlockRayCaster::cast(const Eigen::Vector3d& origin_m, const Eigen::Vector3d& direction_unit,
                            double t_min_m, double t_max_m) const {
    return select(origin_m, std::numeric_limits<double>::infinity())
        .cast(origin_m, direction_unit, t_min_m, t_max_m);
}

RayHit BlockSelection::cast(const Eigen::Vector3d& origin_m, const Eigen::Vector3d& direction_unit,
                            double t_min_m, double t_max_m) const {
    RayHit best;
    best.distance_m = t_max_m;
    for (const std::size_t index : blocks_) {
        const RayHit hit =
            owner_->casters_[index].cast(origin_m, direction_unit, t_min_m, best.distance_m);
        if (!hit.hit()) continue;
        // Same tie rule as inside one BVH: the closer hit, or the lower triangle id at equal
        // distance.
        if (!best.hit() || hit.distance_m < best.distance_m ||
            (hit.distance_m == best.distance_m && hit.triangle_id < best.triangle_id)) {
            best = hit;
        }
    }
    if (!best.hit()) best.distance_m = std::numeric_limits<double>::infinity();
    return best;
}

}  // namespace shine::sim
