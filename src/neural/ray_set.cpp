#include "shine/sampling/ray_set.hpp"

#include <string>
#include <utility>

#include "shine/core/error.hpp"

namespace shine {

std::uint32_t RaySet::add_scan(const Eigen::Vector3f& origin_map,
                               const std::vector<Eigen::Vector3f>& endpoints_map) {
    const auto scan = static_cast<std::uint32_t>(origins_.size());
    origins_.push_back(origin_map);
    endpoints_.insert(endpoints_.end(), endpoints_map.begin(), endpoints_map.end());
    scan_of_ray_.insert(scan_of_ray_.end(), endpoints_map.size(), scan);
    scan_begin_.push_back(endpoints_.size());
    if (!label_scales_.empty()) label_scales_.resize(endpoints_.size(), 1.0f);
    return scan;
}

void RaySet::set_label_scales(std::vector<float> scales) {
    if (!scales.empty() && scales.size() != endpoints_.size()) {
        throw DataError("label scales: got " + std::to_string(scales.size()) + " for " +
                        std::to_string(endpoints_.size()) + " rays");
    }
    label_scales_ = std::move(scales);
}

std::size_t RaySet::memory_bytes() const {
    return endpoints_.capacity() * sizeof(Eigen::Vector3f) +
           scan_of_ray_.capacity() * sizeof(std::uint32_t) +
           label_scales_.capacity() * sizeof(float) +
           origins_.capacity() * sizeof(Eigen::Vector3f) +
           scan_begin_.capacity() * sizeof(std::size_t);
}

}  // namespace shine
