// The LiDAR's reflectance fused onto the surface: every measured point's intensity accumulated in
// a sparse voxel hash (sum, count and mean position per voxel, the means kept ready for reading),
// then read at surface points as a
// Gaussian-weighted mean over the voxels around them.
//
// A LiDAR return lies on the first surface along its ray, so no occlusion test is needed: unlike
// a camera pixel, a point never carries the intensity of something behind it. Points are in the
// map frame (world position minus the map's origin), like mesh vertices.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "shine/core/key_index_table.hpp"

namespace shine {

class ReflectanceVoxels {
  public:
    /// Voxels of `voxel_size_m` (the baked level set's, so reads match the surface's detail).
    /// Throws ConfigError for a non-positive size.
    explicit ReflectanceVoxels(double voxel_size_m);

    /// Adds points (map frame) with their intensities (same length; NaN intensities skipped).
    /// Throws DataError for mismatched lengths.
    void add(const std::vector<Eigen::Vector3d>& points_map, const std::vector<float>& intensity);

    /// Mean intensity around `p_map`: voxels within one voxel of p's, each weighted by
    /// count * exp(-d^2 / voxel^2), d from p to the voxel's mean point. NaN where none.
    float at(const Eigen::Vector3d& p_map) const;

    bool empty() const { return sums_.empty(); }
    std::size_t num_voxels() const { return sums_.size(); }
    std::size_t num_points() const { return points_; }
    double voxel_size_m() const { return voxel_size_m_; }

  private:
    /// What add() accumulates per voxel, in the order the points come.
    struct Sums {
        double intensity_sum = 0.0;
        Eigen::Vector3d position_sum = Eigen::Vector3d::Zero();
        std::uint32_t count = 0;
        std::uint32_t stamp = 0;  ///< the add() call that last changed it
    };
    /// What at() reads per voxel, computed from its sums at the end of each add().
    struct Mean {
        Eigen::Vector3d position;
        double count;
        double intensity;
    };
    static std::uint64_t key(const Eigen::Vector3i& voxel);  ///< 63 bits: never kNoKey
    Eigen::Vector3i voxel_of(const Eigen::Vector3d& p_map) const;

    double voxel_size_m_;
    KeyIndexTable voxels_;     ///< key -> index into sums_ and means_
    std::vector<Sums> sums_;   ///< one per voxel, in order of first point
    std::vector<Mean> means_;  ///< same order
    std::uint32_t adds_ = 0;   ///< add() calls so far
    std::size_t points_ = 0;
};

}  // namespace shine
