// The rays a mapper trains on: scan endpoints in the map frame with the sensor origin of their
// scan, or of each ray where the sensor moved during the sweep (a deskewed scan).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace shine {

/// Endpoints of all rays of the scans added so far, and the sensor origin of each scan.
///
/// The rays may be grouped by voxel (preprocess.voxel_points: all): each group is a run of rays
/// of one scan whose endpoints share a voxel, led by the ray that thinning would have kept. A
/// trainer then draws a group uniformly and one of its rays uniformly, so that samples spread
/// over space as after thinning while every measured point is used. Without any grouped scan,
/// every ray is a group of its own and nothing is stored for the groups.
class RaySet {
  public:
    /// Adds a scan; returns its index. `voxel_begin` lists where each voxel's run of endpoints
    /// starts (ascending, the first 0; voxel_groups.hpp); empty: every ray its own group.
    /// `ray_origins_map` gives each ray its own origin (where the sensor was when it measured
    /// that point); empty: origin_map for every ray. Throws DataError for a list that does not
    /// describe runs of `endpoints_map` or a count of ray origins other than 0 or the endpoints'.
    std::uint32_t add_scan(const Eigen::Vector3f& origin_map,
                           const std::vector<Eigen::Vector3f>& endpoints_map,
                           const std::vector<std::uint32_t>& voxel_begin = {},
                           const std::vector<Eigen::Vector3f>& ray_origins_map = {});
    /// Adds a scan with a normal per endpoint (empty: zero normals) and, optionally, an origin per
    /// ray as add_scan; returns its index. Throws DataError for a normal count other than 0 or
    /// the endpoints'.
    std::uint32_t add_scan_with_normals(const Eigen::Vector3f& origin_map,
                                        const std::vector<Eigen::Vector3f>& endpoints_map,
                                        const std::vector<Eigen::Vector3f>& normals,
                                        const std::vector<Eigen::Vector3f>& ray_origins_map = {});
    /// Moves scan `scan`'s rays rigidly by `T_new_old` (map frame): endpoints, the scan's origin
    /// and its rays' own origins are mapped by it, normals rotated. Pose refinement
    /// (mapper/pose_refinement.hpp) corrects a scan this way; nothing else changes (grouping,
    /// order). Throws DataError for a scan index out of range.
    void transform_scan(std::uint32_t scan, const Eigen::Isometry3f& T_new_old);
    /// Keeps the rays r with keep[r] != 0 (one flag per ray), in place and in order: each scan
    /// keeps its place (and origin) and loses its removed rays, a voxel group loses its removed
    /// rays and disappears when none is left; as if each scan's kept rays were added again with
    /// filter_voxel_grouped()'s runs (voxel_groups.hpp), without new storage. Returns the number
    /// of rays removed. Throws DataError for a flag count other than num_rays().
    std::size_t keep_rays(const std::vector<std::uint8_t>& keep);
    /// Keeps the first `num_scans` scans (at most num_scans()) and drops the rest.
    void truncate(std::uint32_t num_scans);
    /// Drops the first `num_scans` scans (at most num_scans()); the later scans and their rays
    /// move to the front, renumbered from 0. The storage is kept (no reallocation).
    void erase_front(std::uint32_t num_scans);
    /// Drops every scan (and the grouping); the storage is kept.
    void clear();
    std::size_t num_rays() const { return endpoints_.size(); }
    std::size_t num_scans() const { return origins_.size(); }
    const Eigen::Vector3f& endpoint(std::size_t ray) const { return endpoints_[ray]; }
    /// Where ray `ray` starts: its own origin if its scan gave one, else its scan's.
    const Eigen::Vector3f& origin_of_ray(std::size_t ray) const {
        return ray_origins_.empty() ? origins_[scan_of_ray_[ray]] : ray_origins_[ray];
    }
    /// True once a scan with an origin per ray was added.
    bool has_ray_origins() const { return !ray_origins_.empty(); }
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

    /// True once a scan with voxel groups was added.
    bool grouped() const { return !group_begin_.empty(); }
    /// Number of groups (num_rays() when not grouped).
    std::size_t num_groups() const {
        return grouped() ? group_begin_.size() - 1 : endpoints_.size();
    }
    /// First ray of group g; first_ray_of_group(num_groups()) = num_rays().
    std::size_t first_ray_of_group(std::size_t group) const {
        return grouped() ? group_begin_[group] : group;
    }
    /// The first group whose first ray is at or after `ray` (for a scan boundary: the scan's first
    /// group; num_groups() for num_rays()).
    std::size_t group_at_or_after(std::size_t ray) const;
    /// The voxel starts of scan s's rays, relative to its first ray (empty when not grouped).
    std::vector<std::uint32_t> scan_voxel_begin(std::uint32_t scan) const;

  private:
    std::vector<Eigen::Vector3f> endpoints_;
    std::vector<std::uint32_t> scan_of_ray_;
    std::vector<Eigen::Vector3f> normals_;
    std::vector<Eigen::Vector3f> origins_;
    /// One origin per ray once a scan gave its rays their own (the others: their scan's); empty
    /// before.
    std::vector<Eigen::Vector3f> ray_origins_;
    std::vector<std::size_t> scan_begin_{0};
    /// First ray of each group and num_rays() last; empty while no scan is grouped.
    std::vector<std::size_t> group_begin_;
};

}  // namespace shine
