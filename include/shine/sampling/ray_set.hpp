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
    /// Sensor origin of scan s (also of a scan without rays).
    const Eigen::Vector3f& origin_of_scan(std::uint32_t scan) const { return origins_[scan]; }
    std::uint32_t scan_of_ray(std::size_t ray) const { return scan_of_ray_[ray]; }
    /// Unit surface normal at the ray's endpoint, oriented towards the sensor; zero when unknown
    /// (the default; see surface_normals.hpp).
    Eigen::Vector3f normal(std::size_t ray) const {
        return normals_.empty() ? Eigen::Vector3f::Zero() : normals_[ray];
    }
    /// One normal per ray; an empty vector forgets them all. Throws DataError if the size is
    /// neither 0 nor num_rays().
    void set_normals(std::vector<Eigen::Vector3f> normals);
    /// First ray of scan s (rays of a scan are contiguous); first_ray(num_scans()) = num_rays().
    std::size_t first_ray(std::uint32_t scan) const { return scan_begin_[scan]; }
    std::size_t memory_bytes() const;

  private:
    std::vector<Eigen::Vector3f> endpoints_;
    std::vector<std::uint32_t> scan_of_ray_;
    std::vector<Eigen::Vector3f> normals_;
    std::vector<Eigen::Vector3f> origins_;
    std::vector<std::size_t> scan_begin_{0};
};

}  // namespace shine
