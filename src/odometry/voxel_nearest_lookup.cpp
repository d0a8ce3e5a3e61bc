#include "shine/odometry/voxel_nearest_lookup.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <string>

#include "shine/core/error.hpp"
#include "shine/sampling/point_kdtree.hpp"

namespace shine {
namespace voxel_nearest_lookup_internal {
namespace {

/// Voxel coordinates are kept within +-2^20 of the first point's voxel (21 bits each).
constexpr int kBias = 1 << 20;

}  // namespace
}  // namespace voxel_nearest_lookup_internal

std::uint64_t VoxelNearestLookup::key_of(const Eigen::Vector3i& voxel) const {
    using voxel_nearest_lookup_internal::kBias;
    return (static_cast<std::uint64_t>(voxel.x() + kBias) << 42) |
           (static_cast<std::uint64_t>(voxel.y() + kBias) << 21) |
           static_cast<std::uint64_t>(voxel.z() + kBias);
}

VoxelNearestLookup::VoxelNearestLookup(const std::vector<Eigen::Vector3d>& points_world,
                                       double voxel_m, double radius_m)
    : voxel_m_(voxel_m), radius_m_(radius_m) {
    using voxel_nearest_lookup_internal::kBias;
    // A point's own voxel's centre is at most half a diagonal from it: held.
    const double half_diagonal_m = 0.5 * std::sqrt(3.0) * voxel_m;
    if (!(voxel_m > 0.0) || !(radius_m >= half_diagonal_m) || radius_m > 1000.0 * voxel_m) {
        throw ConfigError("voxel nearest-point lookup: voxel " + std::to_string(voxel_m) +
                          " m and radius " + std::to_string(radius_m) +
                          " m must be positive, the radius from half a voxel diagonal to 1000 "
                          "voxels");
    }
    std::vector<IndexedPoint> indexed;
    indexed.reserve(points_world.size());
    for (std::size_t i = 0; i < points_world.size(); ++i) {
        if (!points_world[i].allFinite()) continue;
        if (indexed.empty()) origin_world_ = points_world[i];
        indexed.push_back(
            {(points_world[i] - origin_world_).cast<float>(), static_cast<std::uint32_t>(i)});
    }
    if (indexed.empty()) return;
    const auto voxel_of = [&](const Eigen::Vector3d& p) -> Eigen::Vector3i {
        const Eigen::Vector3d v = ((p - origin_world_) / voxel_m_).array().floor();
        return v.cast<int>();
    };
    // Voxel centres relative to the first point, as the tree's coordinates are.
    const auto centre_of = [&](const Eigen::Vector3i& v) -> Eigen::Vector3f {
        return ((v.cast<double>().array() + 0.5) * voxel_m_).matrix().cast<float>();
    };
    const int limit = kBias - static_cast<int>(std::ceil(radius_m / voxel_m)) - 2;
    const PointKdTree tree(indexed);
    // Every voxel within the radius is reached from a point's voxel through voxels within
    // radius + half a diagonal of that point (those the segment from the point to the voxel's
    // centre crosses), so the walk expands through those and keeps the ones within the radius.
    const double reach_m = radius_m + half_diagonal_m;
    const float reach_sq = static_cast<float>(reach_m * reach_m);
    const float radius_sq = static_cast<float>(radius_m * radius_m);
    KeyIndexTable visited;
    std::vector<Eigen::Vector3i> layer;
    for (const IndexedPoint& p : indexed) {
        const Eigen::Vector3i v = voxel_of(points_world[p.index]);
        if ((v.array().abs() > limit).any()) continue;  // farther than 2^20 voxels: not held
        bool inserted = false;
        visited.find_or_insert(key_of(v), &inserted);
        if (inserted) layer.push_back(v);
    }
    std::vector<PointNeighbor> found;
    std::vector<Eigen::Vector3i> next;
    while (!layer.empty()) {
        // The layer's nearest points in parallel (the tree is read-only), then the layer kept
        // and expanded in order: the result does not depend on the thread count.
        found.assign(layer.size(), PointNeighbor{});
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, layer.size(), 256),
            [&](const tbb::blocked_range<std::size_t>& r) {
                for (std::size_t i = r.begin(); i != r.end(); ++i) {
                    PointNeighbor nearest[1];
                    if (tree.nearest(centre_of(layer[i]), 1, reach_sq, nearest) == 1) {
                        found[i] = nearest[0];
                    } else {
                        found[i].distance_sq = -1.0f;  // beyond the reach
                    }
                }
            });
        next.clear();
        for (std::size_t i = 0; i < layer.size(); ++i) {
            if (found[i].distance_sq < 0.0f) continue;
            if (found[i].distance_sq <= radius_sq) {
                // Each voxel is in one layer only: its slot is the next one.
                table_.find_or_insert(key_of(layer[i]));
                nearest_.push_back(static_cast<std::int32_t>(found[i].index));
            }
            for (int dx = -1; dx <= 1; ++dx) {
                for (int dy = -1; dy <= 1; ++dy) {
                    for (int dz = -1; dz <= 1; ++dz) {
                        const Eigen::Vector3i w = layer[i] + Eigen::Vector3i(dx, dy, dz);
                        if ((w.array().abs() > limit).any()) continue;
                        bool inserted = false;
                        visited.find_or_insert(key_of(w), &inserted);
                        if (inserted) next.push_back(w);
                    }
                }
            }
        }
        layer.swap(next);
    }
}

long VoxelNearestLookup::find(const Eigen::Vector3d& query_world) const {
    using voxel_nearest_lookup_internal::kBias;
    if (nearest_.empty() || !query_world.allFinite()) return -1;
    const Eigen::Vector3d v = ((query_world - origin_world_) / voxel_m_).array().floor();
    if ((v.array().abs() > kBias - 2).any()) return -1;
    const std::int64_t slot = table_.find(key_of(v.cast<int>()));
    return slot < 0 ? -1 : nearest_[static_cast<std::size_t>(slot)];
}

}  // namespace shine
