// Nearest reference point by voxel: for every voxel whose centre lies within `radius_m` of a
// reference point, the index of the point nearest to that centre. A query then costs one hash
// look-up instead of a k-d tree search, and answers with the point nearest to the centre of the
// query's voxel: within half a voxel diagonal of the true nearest point's distance (the triangle
// inequality), which is what point-to-plane ICP from metres away needs, since it matches a point
// to a tangent plane and the planes of neighbouring surface points agree.
//
// Built by a walk outwards from the voxels that hold points, through face, edge and corner
// neighbours, each voxel's nearest point found by a k-d tree search from its centre (exact up to
// the tree's float coordinates, relative to the first point); the walk passes through every
// voxel within the radius plus half a voxel diagonal of a point, which reaches every voxel within
// the radius. Deterministic for any thread count.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "shine/core/key_index_table.hpp"

namespace shine {

class VoxelNearestLookup {
  public:
    /// Throws ConfigError for a non-positive voxel size, or a radius under half a voxel diagonal
    /// or over 1000 voxels.
    VoxelNearestLookup(const std::vector<Eigen::Vector3d>& points_world, double voxel_m,
                       double radius_m);

    double voxel_m() const { return voxel_m_; }
    double radius_m() const { return radius_m_; }
    /// Voxels held: those whose centre is within radius_m of a point.
    std::size_t voxels() const { return nearest_.size(); }

    /// The index of the reference point nearest to the centre of `query_world`'s voxel, or -1
    /// when no point lies within radius_m of that centre.
    long find(const Eigen::Vector3d& query_world) const;

  private:
    std::uint64_t key_of(const Eigen::Vector3i& voxel) const;

    double voxel_m_;
    double radius_m_;
    Eigen::Vector3d origin_world_ = Eigen::Vector3d::Zero();  ///< the first point
    KeyIndexTable table_;
    std::vector<std::int32_t> nearest_;  ///< per table index
};

}  // namespace shine
