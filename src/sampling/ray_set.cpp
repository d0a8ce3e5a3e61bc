#include "shine/sampling/ray_set.hpp"

#include <algorithm>
#include <limits>
#include <numeric>
#include <string>
#include <utility>

#include "shine/core/error.hpp"

namespace shine {

std::uint32_t RaySet::add_scan(const Eigen::Vector3f& origin_map,
                               const std::vector<Eigen::Vector3f>& endpoints_map,
                               const std::vector<std::uint32_t>& voxel_begin,
                               const std::vector<Eigen::Vector3f>& ray_origins_map) {
    if (!ray_origins_map.empty() && ray_origins_map.size() != endpoints_map.size()) {
        throw DataError("ray origins: got " + std::to_string(ray_origins_map.size()) +
                        " for a scan of " + std::to_string(endpoints_map.size()) + " rays");
    }
    if (!voxel_begin.empty()) {
        bool valid = voxel_begin.front() == 0 && voxel_begin.back() < endpoints_map.size();
        for (std::size_t i = 1; valid && i < voxel_begin.size(); ++i) {
            valid = voxel_begin[i - 1] < voxel_begin[i];
        }
        if (!valid) {
            throw DataError("RaySet::add_scan: the voxel starts do not describe runs of the " +
                            std::to_string(endpoints_map.size()) + " endpoints");
        }
    }
    const std::size_t first = endpoints_.size();
    if (!voxel_begin.empty() || grouped()) {
        if (!grouped()) {
            // The first grouped scan: every earlier ray becomes a group of its own.
            group_begin_.resize(first + 1);
            std::iota(group_begin_.begin(), group_begin_.end(), std::size_t{0});
        }
        group_begin_.pop_back();
        if (voxel_begin.empty()) {
            for (std::size_t i = 0; i < endpoints_map.size(); ++i)
                group_begin_.push_back(first + i);
        } else {
            for (const std::uint32_t b : voxel_begin) group_begin_.push_back(first + b);
        }
        group_begin_.push_back(first + endpoints_map.size());
    }
    const auto scan = static_cast<std::uint32_t>(origins_.size());
    origins_.push_back(origin_map);
    endpoints_.insert(endpoints_.end(), endpoints_map.begin(), endpoints_map.end());
    scan_of_ray_.insert(scan_of_ray_.end(), endpoints_map.size(), scan);
    scan_begin_.push_back(endpoints_.size());
    if (!normals_.empty()) normals_.resize(endpoints_.size(), Eigen::Vector3f::Zero());
    if (!ray_origins_map.empty() && ray_origins_.empty()) {
        // The first scan with ray origins: every earlier ray gets its scan's.
        ray_origins_.reserve(endpoints_.size());
        for (std::size_t r = 0; r < first; ++r) ray_origins_.push_back(origins_[scan_of_ray_[r]]);
    }
    if (!ray_origins_map.empty()) {
        ray_origins_.insert(ray_origins_.end(), ray_origins_map.begin(), ray_origins_map.end());
    } else if (!ray_origins_.empty()) {
        ray_origins_.resize(endpoints_.size(), origin_map);
    }
    return scan;
}

std::size_t RaySet::keep_rays(const std::vector<std::uint8_t>& keep) {
    const std::size_t n = endpoints_.size();
    if (keep.size() != n) {
        throw DataError("RaySet::keep_rays: " + std::to_string(keep.size()) + " flags for " +
                        std::to_string(n) + " rays");
    }
    const bool with_normals = !normals_.empty(), with_origins = !ray_origins_.empty();
    const bool with_groups = grouped();
    std::size_t kept = 0;
    std::size_t groups = 0;  // groups written so far (group_begin_ is rewritten in place)
    std::size_t group = 0;   // the group of ray r, when grouped
    // The last group that has a kept ray (groups never span two scans, so a scan's first kept
    // ray always opens a group).
    std::size_t last_opened = std::numeric_limits<std::size_t>::max();
    for (std::uint32_t s = 0; s < origins_.size(); ++s) {
        const std::size_t begin = scan_begin_[s], end = scan_begin_[s + 1];
        scan_begin_[s] = kept;
        for (std::size_t r = begin; r < end; ++r) {
            if (with_groups) {
                while (group_begin_[group + 1] <= r) ++group;
            }
            if (!keep[r]) continue;
            if (with_groups && group != last_opened) {
                // group_begin_[groups] is no longer read: groups <= group.
                group_begin_[groups++] = kept;
                last_opened = group;
            }
            endpoints_[kept] = endpoints_[r];
            scan_of_ray_[kept] = scan_of_ray_[r];
            if (with_normals) normals_[kept] = normals_[r];
            if (with_origins) ray_origins_[kept] = ray_origins_[r];
            ++kept;
        }
    }
    scan_begin_[origins_.size()] = kept;
    endpoints_.resize(kept);
    scan_of_ray_.resize(kept);
    if (with_normals) normals_.resize(kept);
    if (with_origins) ray_origins_.resize(kept);
    if (with_groups) {
        group_begin_.resize(groups);
        group_begin_.push_back(kept);
    }
    return n - kept;
}

std::uint32_t RaySet::add_scan_with_normals(const Eigen::Vector3f& origin_map,
                                            const std::vector<Eigen::Vector3f>& endpoints_map,
                                            const std::vector<Eigen::Vector3f>& normals,
                                            const std::vector<Eigen::Vector3f>& ray_origins_map) {
    if (!normals.empty() && normals.size() != endpoints_map.size()) {
        throw DataError("ray normals: got " + std::to_string(normals.size()) + " for a scan of " +
                        std::to_string(endpoints_map.size()) + " rays");
    }
    const std::size_t first = endpoints_.size();
    const std::uint32_t scan = add_scan(origin_map, endpoints_map, {}, ray_origins_map);
    if (!normals.empty()) {
        normals_.resize(first, Eigen::Vector3f::Zero());  // earlier rays without normals: zero
        normals_.insert(normals_.end(), normals.begin(), normals.end());
    }
    return scan;
}

void RaySet::truncate(std::uint32_t num_scans) {
    if (num_scans >= origins_.size()) return;
    const std::size_t end = scan_begin_[num_scans];
    endpoints_.resize(end);
    scan_of_ray_.resize(end);
    if (!normals_.empty()) normals_.resize(end);
    if (!ray_origins_.empty()) ray_origins_.resize(end);
    origins_.resize(num_scans);
    scan_begin_.resize(std::size_t{num_scans} + 1);
    if (grouped()) {
        // The groups of the kept scans, and num_rays() last; no group spans two scans.
        group_begin_.resize(group_at_or_after(end));
        group_begin_.push_back(end);
    }
}

void RaySet::clear() {
    truncate(0);
    group_begin_.clear();
    ray_origins_.clear();
}

void RaySet::erase_front(std::uint32_t num_scans) {
    num_scans = static_cast<std::uint32_t>(std::min<std::size_t>(num_scans, origins_.size()));
    if (num_scans == 0) return;
    const std::size_t first = scan_begin_[num_scans];
    const auto drop_front = [](auto& values, std::size_t count) {
        values.erase(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(count));
    };
    if (grouped()) {
        const std::size_t first_group = group_at_or_after(first);
        drop_front(group_begin_, first_group);
        for (std::size_t& b : group_begin_) b -= first;
    }
    drop_front(endpoints_, first);
    drop_front(scan_of_ray_, first);
    for (std::uint32_t& scan : scan_of_ray_) scan -= num_scans;
    if (!normals_.empty()) drop_front(normals_, first);
    if (!ray_origins_.empty()) drop_front(ray_origins_, first);
    drop_front(origins_, num_scans);
    drop_front(scan_begin_, num_scans);
    for (std::size_t& b : scan_begin_) b -= first;
}

void RaySet::transform_scan(std::uint32_t scan, const Eigen::Isometry3f& T_new_old) {
    if (scan >= origins_.size()) {
        throw DataError("ray set: scan " + std::to_string(scan) + " to move, but it holds " +
                        std::to_string(origins_.size()) + " scans");
    }
    const Eigen::Matrix3f R = T_new_old.linear();
    const std::size_t begin = scan_begin_[scan], end = scan_begin_[scan + 1];
    for (std::size_t r = begin; r < end; ++r) {
        endpoints_[r] = T_new_old * endpoints_[r];
        if (!ray_origins_.empty()) ray_origins_[r] = T_new_old * ray_origins_[r];
        if (!normals_.empty()) normals_[r] = R * normals_[r];
    }
    origins_[scan] = T_new_old * origins_[scan];
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
           ray_origins_.capacity() * sizeof(Eigen::Vector3f) +
           scan_begin_.capacity() * sizeof(std::size_t) +
           group_begin_.capacity() * sizeof(std::size_t);
}

std::size_t RaySet::group_at_or_after(std::size_t ray) const {
    if (!grouped()) return std::min(ray, endpoints_.size());
    return static_cast<std::size_t>(
        std::lower_bound(group_begin_.begin(), group_begin_.end() - 1, ray) - group_begin_.begin());
}

std::vector<std::uint32_t> RaySet::scan_voxel_begin(std::uint32_t scan) const {
    std::vector<std::uint32_t> result;
    if (!grouped()) return result;
    const std::size_t begin = scan_begin_[scan], end = scan_begin_[scan + 1];
    for (std::size_t g = group_at_or_after(begin); group_begin_[g] < end; ++g) {
        result.push_back(static_cast<std::uint32_t>(group_begin_[g] - begin));
    }
    return result;
}

}  // namespace shine
