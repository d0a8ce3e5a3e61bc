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
    if (!normals_.empty()) normals_.resize(endpoints_.size(), Eigen::Vector3f::Zero());
    return scan;
}

void RaySet::set_normals(std::vector<Eigen::Vector3f> normals) {
    if (!normals.empty() && normals.size() != endpoints_.size()) {
        throw DataError("ray normals: got " + std::to_string(normals.size()) + " for " +
                        std::to_string(endpoints_.size()) + " rays");
    }
    normals_ = std::move(normals);
}

std::size_t RaySet::memory_bytes() const {
    return endpoints_.capacity() * sizeof(Eigen::Vector3f) +
           scan_of_ray_.capacity() * sizeof(std::uint32_t) +
           normals_.capacity() * sizeof(Eigen::Vector3f) +
           origins_.capacity() * sizeof(Eigen::Vector3f) +
           scan_begin_.capacity() * sizeof(std::size_t);
}

}  // namespace shine
