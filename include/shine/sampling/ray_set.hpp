// The rays a mapper trains on: scan endpoints in the map frame with the sensor origin of their
// scan.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace shine {

/// Endpoints of all rays of the scans added so far, and the sensor origin of each scan.
class RaySet {
  public:
    /// Adds a scan; returns its index.
    std::uint32_t add_scan(const Eigen::Vector3f& origin_map,
                           const std::vector<Eigen::Vector3f>& endpoints_map);
    std::size_t num_rays() const { return endpoints_.size(); }
    std::size_t num_scans() const { return origins_.size(); }
    const Eigen::Vector3f& endpoint(std::size_t ray) const { return endpoints_[ray]; }
    const Eigen::Vector3f& origin_of_ray(std::size_t ray) const {
        return origins_[scan_of_ray_[ray]];
    }
    std::uint32_t scan_of_ray(std::size_t ray) const { return scan_of_ray_[ray]; }
    /// Factor applied to the projective labels of the ray's samples (1 unless set).
    float label_scale(std::size_t ray) const {
        return label_scales_.empty() ? 1.0f : label_scales_[ray];
    }
    /// One factor per ray (e.g. |cos(incidence)|, see incidence.hpp); an empty vector resets
    /// every factor to 1. Throws DataError if the size is neither 0 nor num_rays().
    void set_label_scales(std::vector<float> scales);
    /// First ray of scan s (rays of a scan are contiguous); first_ray(num_scans()) = num_rays().
    std::size_t first_ray(std::uint32_t scan) const { return scan_begin_[scan]; }
    std::size_t memory_bytes() const;

  private:
    std::vector<Eigen::Vector3f> endpoints_;
    std::vector<std::uint32_t> scan_of_ray_;
    std::vector<float> label_scales_;
    std::vector<Eigen::Vector3f> origins_;
    std::vector<std::size_t> scan_begin_{0};
};

}  // namespace shine
