// TriangleMesh frames: moved_in_world() moves a mesh rigidly in the world and keeps its frame, in
// float precision even for a mesh whose frame lies at UTM-like coordinates.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>

#include "shine/geometry/triangle_mesh.hpp"

namespace {

shine::TriangleMesh far_mesh() {
    shine::TriangleMesh mesh;
    mesh.origin_world_m = Eigen::Vector3d(500000.0, 5000000.0, 30.0);
    mesh.vertices = {
        {0.0f, 0.0f, 0.0f}, {10.0f, 0.0f, 0.0f}, {0.0f, 20.0f, 1.5f}, {-3.25f, 7.5f, -2.0f}};
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
    mesh.face_observed = {1, 0};
    return mesh;
}

/// A small motion about a point near the mesh, as a trajectory alignment of a far-away map is
/// (its translation undoes the rotation's swing about the world origin, 5e6 m away).
Eigen::Isometry3d small_motion(const Eigen::Vector3d& centre_world) {
    const Eigen::Matrix3d R =
        Eigen::AngleAxisd(0.002, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()).matrix();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R;
    T.translation() = centre_world - R * centre_world + Eigen::Vector3d(0.04, -0.02, 0.01);
    return T;
}

}  // namespace

TEST(TriangleMesh, MovedInWorldMovesEveryVertexAndKeepsTheFrame) {
    const shine::TriangleMesh mesh = far_mesh();
    const Eigen::Isometry3d T = small_motion(mesh.origin_world_m + Eigen::Vector3d(5.0, 5.0, 0.0));
    const shine::TriangleMesh moved = shine::moved_in_world(mesh, T);
    EXPECT_EQ(moved.origin_world_m, mesh.origin_world_m);
    EXPECT_EQ(moved.triangles, mesh.triangles);
    EXPECT_EQ(moved.face_observed, mesh.face_observed);
    ASSERT_EQ(moved.vertices.size(), mesh.vertices.size());
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        // The world positions, in double; the vertices (within 25 m of the frame's origin) keep
        // float precision, better than 1e-5 m, although the frame is 5e6 m from the world's.
        const Eigen::Vector3d world = mesh.origin_world_m + mesh.vertices[i].cast<double>();
        const Eigen::Vector3d expected = T * world - mesh.origin_world_m;
        EXPECT_NEAR((moved.vertices[i].cast<double>() - expected).norm(), 0.0, 1e-5) << i;
    }
    // The identity leaves the mesh bit for bit; the inverse motion brings it back.
    const shine::TriangleMesh same = shine::moved_in_world(mesh, Eigen::Isometry3d::Identity());
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        EXPECT_EQ(same.vertices[i], mesh.vertices[i]) << i;
    }
    const shine::TriangleMesh back = shine::moved_in_world(moved, T.inverse());
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        EXPECT_NEAR((back.vertices[i] - mesh.vertices[i]).norm(), 0.0f, 2e-5f) << i;
    }
}
