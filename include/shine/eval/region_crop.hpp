// Restricting an evaluation to a part of the scene: a region of space as a set of voxels around
// points (e.g. everything the first quarter of a run observed), and meshes cropped to it.
//
// Used by the forgetting experiment (bench/forgetting_experiment.hpp): the reference surface
// "seen in the first quarter" is the observed reference whose triangles have their centroid in a
// voxel holding a point of those scans; the predicted mesh is cropped to the same region grown
// by a voxel, so that completion near the region's border is not penalised for predicted surface
// just across it, while precision is still measured against the whole reference.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <unordered_set>
#include <vector>

#include "shine/geometry/triangle_mesh.hpp"

namespace shine {

/// The union of the axis-aligned voxels (edge voxel_size_m, aligned to the origin) that hold at
/// least one of the points added.
class VoxelRegion {
  public:
    /// Throws ConfigError if `voxel_size_m` is not positive and finite.
    explicit VoxelRegion(double voxel_size_m);

    /// Adds the voxels of `points` (non-finite points are ignored).
    void add_points(const std::vector<Eigen::Vector3f>& points);
    /// The region grown by `voxels` voxels in every direction (a (2v+1)^3 cube around each).
    VoxelRegion dilated(int voxels) const;
    bool contains(const Eigen::Vector3f& point) const;

    double voxel_size_m() const { return voxel_size_m_; }
    std::size_t num_voxels() const { return voxels_.size(); }
    /// Volume in m^3.
    double volume_m3() const;

  private:
    std::uint64_t key(const Eigen::Vector3f& point) const;

    double voxel_size_m_;
    std::unordered_set<std::uint64_t> voxels_;
};

/// The centroid of triangle `t` of `mesh` (the crops' test of where a triangle lies).
inline Eigen::Vector3f triangle_centroid(const TriangleMesh& mesh, const Eigen::Vector3i& t) {
    return (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]) / 3.0f;
}

/// The triangles `indices` of `mesh`, in that order, with their vertices (renumbered in order of
/// first use), face_observed flags (if `mesh` has them) and frame. `vertex_slot` is scratch that
/// must hold mesh.vertices.size() entries of -1 and is left so (callers cutting many pieces out
/// of one big mesh reuse it).
TriangleMesh extract_triangles(const TriangleMesh& mesh, const std::vector<std::uint32_t>& indices,
                               std::vector<int>& vertex_slot);

/// The triangles of `mesh` whose centroid lies in `region`, with their vertices (renumbered)
/// and face_observed flags.
TriangleMesh crop_mesh(const TriangleMesh& mesh, const VoxelRegion& region);

/// A copy of `reference` whose face_observed flags are kept only inside `region` (by centroid);
/// a reference without flags counts as all observed first.
TriangleMesh restrict_observed(const TriangleMesh& reference, const VoxelRegion& region);

}  // namespace shine
