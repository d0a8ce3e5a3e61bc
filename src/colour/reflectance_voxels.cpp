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
    if (++adds_ == 0) {  // the stamps wrapped: none is current
        for (Sums& s : sums_) s.stamp = 0;
        adds_ = 1;
    }
    std::vector<std::uint32_t> touched;
    constexpr double kLimit = 0.9 * (1 << 20);  // voxels beyond the key's range are skipped
    for (std::size_t i = 0; i < points_map.size(); ++i) {
        if (!std::isfinite(intensity[i]) || !points_map[i].allFinite()) continue;
        if ((points_map[i].array().abs() / voxel_size_m_ > kLimit).any()) continue;
        const std::uint32_t index = voxels_.find_or_insert(key(voxel_of(points_map[i])));
        if (index == sums_.size()) sums_.emplace_back();
        Sums& cell = sums_[index];
        cell.intensity_sum += intensity[i];
        cell.position_sum += points_map[i];
        ++cell.count;
        ++points_;
        if (cell.stamp != adds_) {
            cell.stamp = adds_;
            touched.push_back(index);
        }
    }
    // The means of the voxels this call changed, as at() would compute them from the sums.
    means_.resize(sums_.size());
    for (const std::uint32_t index : touched) {
        const Sums& cell = sums_[index];
        Mean& mean = means_[index];
        mean.position = cell.position_sum / cell.count;
        mean.count = cell.count;
        mean.intensity = cell.intensity_sum / cell.count;
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
                const std::int64_t index = voxels_.find(key(centre + Eigen::Vector3i(dx, dy, dz)));
                if (index < 0) continue;
                const Mean& cell = means_[static_cast<std::size_t>(index)];
                const double w =
                    cell.count * std::exp(-(cell.position - p_map).squaredNorm() * inv_sigma2);
                sum += w * cell.intensity;
                weight += w;
            }
        }
    }
    return weight > 0.0 ? static_cast<float>(sum / weight)
                        : std::numeric_limits<float>::quiet_NaN();
}

}  // namespace shine
