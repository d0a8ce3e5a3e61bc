// numpy arrays in and out of the shinevdb module.
//
// Inputs: float32 or float64 arrays (any strides: they are read in place through numpy's
// buffer, never converted to a temporary array first), copied once into the C++ type the library
// takes. Anything else -- another dtype, a wrong shape, a non-finite pose -- raises ValueError
// whose message names the argument, the shape or dtype received and what is expected.
// Outputs: std::vectors moved into numpy arrays that own them (no copy).
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "shine/geometry/triangle_mesh.hpp"

namespace shinevdb {
namespace py = pybind11;

/// `obj` as a numpy array of dtype float32 or float64 (lists are converted to float64); raises
/// ValueError naming `name` otherwise.
py::array float_array(const py::handle& obj, const char* name);

/// (N, 3) points; raises ValueError naming `name` for another shape or dtype.
std::vector<Eigen::Vector3f> points3f(const py::handle& obj, const char* name);
std::vector<Eigen::Vector3d> points3d(const py::handle& obj, const char* name);

/// A rigid transform from a (4, 4) or (3, 4) matrix [R | t]; raises ValueError naming `name` if
/// an entry is not finite, the last row of a 4x4 is not [0, 0, 0, 1] or R is not a rotation.
Eigen::Isometry3d pose_from_array(const py::handle& obj, const char* name);

/// (N,) per-point values matching `num_points`; raises ValueError naming `name` otherwise.
std::vector<double> per_point_values(const py::handle& obj, std::size_t num_points,
                                     const char* name);

/// A (4, 4) float64 array of `pose`.
py::array_t<double> pose_to_array(const Eigen::Isometry3d& pose);
/// Poses as a (K, 4, 4) float64 array, in order.
py::array_t<double> poses_to_array(const std::vector<Eigen::Isometry3d>& poses);

/// The vector's storage as an array of `shape` that owns it.
template <typename T>
py::array_t<T> take_vector(std::vector<T>&& values, const std::vector<py::ssize_t>& shape) {
    auto* owned = new std::vector<T>(std::move(values));
    py::capsule owner(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
    return py::array_t<T>(shape, owned->data(), owner);
}

/// (N, 3) float32 array owning the points.
py::array_t<float> take_points(std::vector<Eigen::Vector3f>&& points);

/// (vertices (V, 3) float64 in the world frame, triangles (T, 3) int32) of `mesh`.
py::tuple mesh_to_arrays(const shine::TriangleMesh& mesh);

/// A mesh from a PLY path, a shinevdb.Mesh or a (vertices, triangles[, face_observed]) tuple;
/// world-frame float64 vertices are kept precise by moving them into a frame shifted by whole
/// kilometres.
shine::TriangleMesh mesh_from_python(const py::handle& obj, const char* name);

}  // namespace shinevdb
