// Range window and voxel thinning of the points registration uses.
#include "shine/odometry/registration_points.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <unordered_map>

#include "shine/core/error.hpp"
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
    std::vector<std::size_t> out;
    // Per voxel, the point whose index has the smallest hash: a draw independent of where the
    // point lies in the voxel or in the scan (header).
    struct Drawn {
        std::uint64_t rank;
        std::size_t index;
    };
    std::unordered_map<std::uint64_t, Drawn> drawn;
    for (std::size_t i = 0; i < points_sensor.size(); ++i) {
        const Eigen::Vector3f& p = points_sensor[i];
        if (!p.allFinite()) continue;
        const double r2 = p.cast<double>().squaredNorm();
        if (r2 < min_sq || r2 > max_sq) continue;
        if (config.voxel_size_m <= 0.0) {
            out.push_back(i);
            continue;
        }
        const Drawn candidate{mix_seed(i), i};
        const auto [it, inserted] = drawn.try_emplace(
            registration_points_internal::voxel_key(p, config.voxel_size_m), candidate);
        if (!inserted && candidate.rank < it->second.rank) it->second = candidate;
    }
    if (config.voxel_size_m > 0.0) {
        out.reserve(drawn.size());
        for (const auto& [key, chosen] : drawn) out.push_back(chosen.index);
        std::sort(out.begin(), out.end());
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
