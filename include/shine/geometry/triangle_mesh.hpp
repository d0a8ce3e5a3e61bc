// A triangle mesh (metres) in a frame translated from the world frame by `origin_world_m`.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <vector>

namespace shine {

/// Indexed triangle mesh. `face_observed` is optional (empty, or one flag per triangle): the
/// simulator marks the reference triangles that at least one LiDAR ray hit, and evaluation counts
/// completion only over those.
///
/// Vertices are float32 in a local frame: world position = origin_world_m + vertex. Far-away
/// (e.g. UTM, 5e6 m) coordinates do not fit a float (its spacing there is 0.5 m), so meshes of
/// such maps keep the map's origin here (in double) and small vertex coordinates; near the world
/// origin origin_world_m is zero and the vertices are world coordinates. PLY files carry it as a
/// header comment (ply.hpp).
struct TriangleMesh {
    std::vector<Eigen::Vector3f> vertices;  ///< relative to origin_world_m
    std::vector<Eigen::Vector3i> triangles;
    std::vector<std::uint8_t> face_observed;
    /// Optional per-vertex appearance (empty, or one entry per vertex): the surface's colour
    /// (8-bit sRGB, fused from camera images) and the LiDAR's reflectance as the sensor gives it
    /// (NaN where no scan measured it). PLY files carry them as vertex properties red, green,
    /// blue (uchar) and intensity (float).
    std::vector<std::array<std::uint8_t, 3>> vertex_rgb;
    std::vector<float> vertex_intensity;
    Eigen::Vector3d origin_world_m = Eigen::Vector3d::Zero();  ///< world position of the frame

    bool empty() const { return triangles.empty(); }
};

/// `mesh` with its vertices moved into the frame whose world position is `origin_world_m`. The
/// shift between the frames is computed in double, so two meshes of a far-away (UTM) map that
/// share or nearly share an origin keep their float precision.
inline TriangleMesh in_frame(const TriangleMesh& mesh, const Eigen::Vector3d& origin_world_m) {
    TriangleMesh moved = mesh;
    const Eigen::Vector3d shift_m = mesh.origin_world_m - origin_world_m;
    for (Eigen::Vector3f& v : moved.vertices) v = (v.cast<double>() + shift_m).cast<float>();
    moved.origin_world_m = origin_world_m;
    return moved;
}

/// `mesh` moved rigidly in the world: every vertex's world position x becomes T_world * x. The
/// mesh keeps its frame (origin_world_m); the move is computed in double about the world origin,
/// as T_world says, so a far-away (UTM) mesh keeps its float precision.
inline TriangleMesh moved_in_world(const TriangleMesh& mesh, const Eigen::Isometry3d& T_world) {
    TriangleMesh moved = mesh;
    const Eigen::Vector3d& origin = mesh.origin_world_m;
    for (Eigen::Vector3f& v : moved.vertices) {
        v = (T_world * (origin + v.cast<double>()) - origin).cast<float>();
    }
    return moved;
}

}  // namespace shine
