// Range window and voxel thinning of the points registration uses.
#include "shine/odometry/registration_points.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "shine/core/error.hpp"
#include "shine/core/key_index_table.hpp"
#include "shine/core/random.hpp"

namespace shine {

namespace registration_points_internal {
namespace {

/// A voxel's integer coordinates packed into 64 bits (21 bits each, offset to be positive): at
/// 0.05 m voxels this spans +-52 km, far beyond any LiDAR's range.
std::uint64_t voxel_key(const Eigen::Vector3f& p, double voxel_size_m) {
    constexpr std::int64_t kOffset = std::int64_t(1) << 20;
    std::uint64_t key = 0;
    for (int a = 0; a < 3; ++a) {
        const std::int64_t v = std::int64_t(std::floor(double(p[a]) / voxel_size_m)) + kOffset;
        key = (key << 21) | (std::uint64_t(v) & ((std::uint64_t(1) << 21) - 1));
    }
    return key;
}

/// voxel_key's value for a point outside the range window (voxel keys use 63 bits).
constexpr std::uint64_t kNoVoxel = KeyIndexTable::kNoKey;

}  // namespace
}  // namespace registration_points_internal

std::vector<std::size_t> select_registration_point_indices(
    const std::vector<Eigen::Vector3f>& points_sensor, const RegistrationPointConfig& config) {
    if (!(config.voxel_size_m >= 0.0)) {
        throw ConfigError("registration voxel_size_m must be >= 0 (got " +
                          std::to_string(config.voxel_size_m) + ")");
    }
    if (!(config.min_range_m >= 0.0) || !(config.max_range_m > config.min_range_m)) {
        throw ConfigError("registration range window [" + std::to_string(config.min_range_m) +
                          ", " + std::to_string(config.max_range_m) +
                          "] m is empty: need 0 <= min_range_m < max_range_m");
    }
    const double min_sq = config.min_range_m * config.min_range_m;
    const double max_sq = config.max_range_m * config.max_range_m;
    const std::size_t n = points_sensor.size();
    const auto in_window = [&](const Eigen::Vector3f& p) {
        if (!p.allFinite()) return false;
        const double r2 = p.cast<double>().squaredNorm();
        return !(r2 < min_sq || r2 > max_sq);
    };
    std::vector<std::size_t> out;
    if (config.voxel_size_m <= 0.0) {
        for (std::size_t i = 0; i < n; ++i) {
            if (in_window(points_sensor[i])) out.push_back(i);
        }
        return out;
    }
    using registration_points_internal::kNoVoxel;
    // The points' voxels (kNoVoxel outside the window), in parallel.
    std::vector<std::uint64_t> keys(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 16384),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              const Eigen::Vector3f& p = points_sensor[i];
                              keys[i] = in_window(p) ? registration_points_internal::voxel_key(
                                                           p, config.voxel_size_m)
                                                     : kNoVoxel;
                          }
                      });
    // Per voxel, the point whose index has the smallest hash: a draw independent of where the
    // point lies in the voxel or in the scan (header). mix_seed is a bijection, so the draw has
    // no ties.
    KeyIndexTable voxels;
    std::vector<std::size_t> drawn;    // per voxel: the point drawn so far
    std::vector<std::uint64_t> ranks;  // and its hash
    for (std::size_t i = 0; i < n; ++i) {
        if (keys[i] == kNoVoxel) continue;
        bool inserted = false;
        const std::uint32_t voxel = voxels.find_or_insert(keys[i], &inserted);
        const std::uint64_t rank = mix_seed(i);
        if (inserted) {
            drawn.push_back(i);
            ranks.push_back(rank);
        } else if (rank < ranks[voxel]) {
            drawn[voxel] = i;
            ranks[voxel] = rank;
        }
    }
    // Ascending: marked, then collected in order.
    std::vector<std::uint8_t> chosen(n, 0);
    for (const std::size_t i : drawn) chosen[i] = 1;
    out.reserve(drawn.size());
    for (std::size_t i = 0; i < n; ++i) {
        if (chosen[i]) out.push_back(i);
    }
    return out;
}

std::vector<Eigen::Vector3f> select_registration_points(
    const std::vector<Eigen::Vector3f>& points_sensor, const RegistrationPointConfig& config) {
    const std::vector<std::size_t> indices =
        select_registration_point_indices(points_sensor, config);
    std::vector<Eigen::Vector3f> out;
    out.reserve(indices.size());
    for (const std::size_t i : indices) out.push_back(points_sensor[i]);
    return out;
}

}  // namespace shine
