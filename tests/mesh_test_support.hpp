// Hand-made meshes for the evaluation tests.
#pragma once

#include <Eigen/Core>

#include "shine/geometry/triangle_mesh.hpp"

namespace shine::mesh_test {

/// Appends the quad a, b, c, d (two triangles).
inline void add_quad(TriangleMesh& mesh, const Eigen::Vector3f& a, const Eigen::Vector3f& b,
                     const Eigen::Vector3f& c, const Eigen::Vector3f& d) {
    const int i = static_cast<int>(mesh.vertices.size());
    mesh.vertices.insert(mesh.vertices.end(), {a, b, c, d});
    mesh.triangles.push_back({i, i + 1, i + 2});
    mesh.triangles.push_back({i, i + 2, i + 3});
}

}  // namespace shine::mesh_test
