#include "shine/colour/reflectance_voxels.hpp"

#include <cmath>
#include <limits>
#include <string>

#include "shine/core/error.hpp"

namespace shine {

ReflectanceVoxels::ReflectanceVoxels(double voxel_size_m) : voxel_size_m_(voxel_size_m) {
    if (!(voxel_size_m > 0.0) || !std::isfinite(voxel_size_m)) {
        throw ConfigError("reflectance voxels: voxel size " + std::to_string(voxel_size_m) +
                          " m must be positive");
    }
}

std::uint64_t ReflectanceVoxels::key(const Eigen::Vector3i& voxel) {
    // 21 bits per axis: +-1e6 voxels, 100 km at 0.1 m around the map's origin.
    const auto part = [](int c) { return static_cast<std::uint64_t>(c + (1 << 20)) & 0x1FFFFF; };
    return part(voxel.x()) | (part(voxel.y()) << 21) | (part(voxel.z()) << 42);
}

Eigen::Vector3i ReflectanceVoxels::voxel_of(const Eigen::Vector3d& p_map) const {
    return (p_map / voxel_size_m_).array().floor().cast<int>();
}

void ReflectanceVoxels::add(const std::vector<Eigen::Vector3d>& points_map,
                            const std::vector<float>& intensity) {
    if (points_map.size() != intensity.size()) {
        throw DataError("reflectance voxels: " + std::to_string(points_map.size()) +
                        " points but " + std::to_string(intensity.size()) + " intensities");
    }
    constexpr double kLimit = 0.9 * (1 << 20);  // voxels beyond the key's range are skipped
    for (std::size_t i = 0; i < points_map.size(); ++i) {
        if (!std::isfinite(intensity[i]) || !points_map[i].allFinite()) continue;
        if ((points_map[i].array().abs() / voxel_size_m_ > kLimit).any()) continue;
        Cell& cell = voxels_[key(voxel_of(points_map[i]))];
        cell.intensity_sum += intensity[i];
        cell.position_sum += points_map[i];
        ++cell.count;
        ++points_;
    }
}

float ReflectanceVoxels::at(const Eigen::Vector3d& p_map) const {
    if (!p_map.allFinite()) return std::numeric_limits<float>::quiet_NaN();
    const Eigen::Vector3i centre = voxel_of(p_map);
    const double inv_sigma2 = 1.0 / (voxel_size_m_ * voxel_size_m_);
    double sum = 0.0, weight = 0.0;
    for (int dz = -1; dz <= 1; ++dz) {
        for (int dy = -1; dy <= 1; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
                const auto it = voxels_.find(key(centre + Eigen::Vector3i(dx, dy, dz)));
                if (it == voxels_.end()) continue;
                const Cell& cell = it->second;
                const Eigen::Vector3d mean = cell.position_sum / cell.count;
                const double w = cell.count * std::exp(-(mean - p_map).squaredNorm() * inv_sigma2);
                sum += w * (cell.intensity_sum / cell.count);
                weight += w;
            }
        }
    }
    return weight > 0.0 ? static_cast<float>(sum / weight)
                        : std::numeric_limits<float>::quiet_NaN();
}

}  // namespace shine
