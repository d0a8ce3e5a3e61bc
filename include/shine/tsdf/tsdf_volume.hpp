// TSDF fusion with VDBFusion's algorithm (Vizzo et al., "VDBFusion: Flexible and Efficient TSDF
// Integration of Range Sensor Data", Sensors 2022): the baseline ShineVDB is compared against.
//
// Two OpenVDB float grids over one voxel lattice: the truncated signed distance D (background
// +trunc, or -trunc with space carving, as in VDBFusion) and the integration weight W
// (background 0). Voxel (i, j, k) covers [i, i+1) x [j, j+1) x [k, k+1) voxels of the map frame,
// so its centre is at ((i, j, k) + 1/2) * voxel_size_m there, and at origin_world_m plus that in
// the world frame: like the neural map, the volume works in a map frame shifted from the world
// by whole kilometres, so float coordinates stay precise far from the world origin.
//
// Integration of one scan (VDBFusion's VDBVolume::Integrate), for every point p seen from the
// sensor origin o, in the order given:
//   - walk the ray o + t * (p - o)/|p - o| through the voxels it crosses (openvdb::math::DDA in
//     index space), for t in [|p - o| - trunc, |p - o| + trunc], or [0, |p - o| + trunc] with
//     space carving;
//   - at each voxel centre c: sdf = |p - c|, negative if (c - o) . (p - c) < 0 (the voxel lies
//     behind the point along the ray), as VDBFusion defines it (not the distance along the ray);
//   - only if sdf > -trunc: D <- (D * W + min(sdf, trunc)) / (W + 1), W <- W + 1 (weight 1 per
//     update; a voxel crossed by the rays of two points of one scan is updated twice).
// The arithmetic is VDBFusion's, in float (the geometry in double: VDBFusion walks a float ray,
// which can differ from ours only where a ray grazes a voxel edge). Scans are integrated serially,
// point by point, as VDBFusion does: the running average in float depends on the update order,
// so a parallel version would have to replay every voxel's updates in point order to give the
// same grids; the baseline's timings are those of the serial algorithm.
#pragma once

#include <openvdb/openvdb.h>

#include <Eigen/Core>
#include <cstddef>
#include <vector>

namespace shine {

/// TSDF parameters; the comments give VDBFusion's names and its defaults for LiDAR data.
struct TsdfConfig {
    double voxel_size_m = 0.1;   ///< voxel_size (0.1 m)
    double trunc_m = 0.3;        ///< sdf_trunc (0.3 m): band half-width and clamp of the SDF
    bool space_carving = false;  ///< space_carving (false): walk from the sensor, not just the band

    /// Throws ConfigError naming the option (--voxel-size-m, --trunc-m) if out of range.
    void validate() const;
};

/// VDBFusion's signed distance of a voxel centre from a measured point: |point - centre|,
/// negative when the centre lies behind the point seen from `origin`, i.e. when
/// (centre - origin) . (point - centre) < 0. VDBFusion's sign is proj / |proj|, which is NaN (and
/// skips the update) for proj == 0; here proj == 0 counts as in front.
float point_sdf_m(const Eigen::Vector3d& origin, const Eigen::Vector3d& point,
                  const Eigen::Vector3d& centre);

/// A TSDF volume (VDBFusion's VDBVolume without colours).
class TsdfVolume {
  public:
    /// An empty volume. Throws ConfigError if `config` is out of range.
    explicit TsdfVolume(const TsdfConfig& config,
                        const Eigen::Vector3d& origin_world_m = Eigen::Vector3d::Zero());

    /// A volume from existing grids (e.g. read from a file). Throws DataError if the grids do
    /// not match `config` (voxel size, backgrounds).
    TsdfVolume(const TsdfConfig& config, const Eigen::Vector3d& origin_world_m,
               openvdb::FloatGrid::Ptr tsdf, openvdb::FloatGrid::Ptr weight);

    /// Integrates one scan: points and sensor origin in the map frame (world minus
    /// origin_world_m). Non-finite points and points at the sensor origin are skipped (the
    /// caller's preprocessing normally removes them). Returns the number of voxel updates.
    std::size_t integrate(const std::vector<Eigen::Vector3d>& points_map,
                          const Eigen::Vector3d& sensor_origin_map);

    /// Moves the map frame; only allowed while the volume is empty (throws std::logic_error).
    void set_origin_world_m(const Eigen::Vector3d& origin_world_m);

    const TsdfConfig& config() const { return config_; }
    /// World position of the map frame's origin.
    const Eigen::Vector3d& origin_world_m() const { return origin_world_m_; }

    /// The voxel containing a map-frame point.
    openvdb::Coord voxel_of(const Eigen::Vector3d& point_map) const;
    /// Centre of a voxel in the map frame.
    Eigen::Vector3d voxel_centre_map(const openvdb::Coord& voxel) const;
    /// Stored signed distance (the background for voxels never updated).
    float tsdf(const openvdb::Coord& voxel) const;
    /// Integration weight (0 for voxels never updated).
    float weight(const openvdb::Coord& voxel) const;

    /// The signed-distance grid; its transform maps voxel indices to world-frame voxel centres.
    const openvdb::FloatGrid& tsdf_grid() const { return *tsdf_; }
    /// The weight grid, on the same lattice.
    const openvdb::FloatGrid& weight_grid() const { return *weight_; }
    openvdb::FloatGrid::ConstPtr tsdf_grid_ptr() const { return tsdf_; }
    openvdb::FloatGrid::ConstPtr weight_grid_ptr() const { return weight_; }

    /// Voxels ever updated (active in both grids).
    std::size_t active_voxels() const;
    /// OpenVDB memUsage() of the TSDF grid, of the weight grid, and their sum.
    std::size_t tsdf_memory_bytes() const;
    std::size_t weight_memory_bytes() const;
    std::size_t memory_bytes() const { return tsdf_memory_bytes() + weight_memory_bytes(); }
    bool empty() const { return active_voxels() == 0; }

  private:
    void update_transforms();

    TsdfConfig config_;
    Eigen::Vector3d origin_world_m_;
    openvdb::FloatGrid::Ptr tsdf_;
    openvdb::FloatGrid::Ptr weight_;
};

}  // namespace shine
