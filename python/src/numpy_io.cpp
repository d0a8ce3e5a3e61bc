#include "numpy_io.hpp"

#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "mesh_colors.hpp"
#include "shine/geometry/map_frame.hpp"
#include "shine/io/ply.hpp"

namespace shinevdb {
namespace {

std::string shape_of(const py::array& a) {
    std::ostringstream out;
    out << "(";
    for (py::ssize_t d = 0; d < a.ndim(); ++d) out << (d ? ", " : "") << a.shape(d);
    out << (a.ndim() == 1 ? ",)" : ")");
    return out.str();
}

std::string dtype_of(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

[[noreturn]] void fail(const std::string& message) { throw py::value_error(message); }

bool is_float32(const py::array& a) { return a.dtype().is(py::dtype::of<float>()); }

void require_points_shape(const py::array& a, const char* name) {
    if (a.ndim() != 2 || a.shape(1) != 3) {
        fail(std::string(name) + " must have shape (N, 3), got " + shape_of(a) +
             " (pass an array of x, y, z rows, e.g. scan[:, :3])");
    }
}

/// Calls f(i, x, y, z) for every row of an (N, 3) float array, read in place.
template <typename T, typename F>
void for_each_row_typed(const py::array& a, F&& f) {
    const auto view = a.unchecked<T, 2>();
    for (py::ssize_t i = 0; i < view.shape(0); ++i) f(i, view(i, 0), view(i, 1), view(i, 2));
}

template <typename F>
void for_each_row(const py::array& a, F&& f) {
    if (is_float32(a)) {
        for_each_row_typed<float>(a, f);
    } else {
        for_each_row_typed<double>(a, f);
    }
}

}  // namespace

py::array float_array(const py::handle& obj, const char* name) {
    if (obj.is_none()) fail(std::string(name) + " must be a numpy array, got None");
    py::array a;
    if (py::isinstance<py::array>(obj)) {
        a = py::reinterpret_borrow<py::array>(obj);
    } else if (py::isinstance<py::list>(obj) || py::isinstance<py::tuple>(obj)) {
        a = py::array_t<double>::ensure(obj);
        if (!a) {
            PyErr_Clear();
            fail(std::string(name) +
                 " must be a numpy array of floats; the sequence given "
                 "could not be converted");
        }
    } else {
        fail(std::string(name) + " must be a numpy array, got " +
             py::str(py::type::handle_of(obj).attr("__name__")).cast<std::string>());
    }
    if (!a.dtype().is(py::dtype::of<float>()) && !a.dtype().is(py::dtype::of<double>())) {
        fail(std::string(name) + " must be float32 or float64, got " + dtype_of(a) +
             " (convert it with .astype(numpy.float64))");
    }
    return a;
}

std::vector<Eigen::Vector3f> points3f(const py::handle& obj, const char* name) {
    const py::array a = float_array(obj, name);
    require_points_shape(a, name);
    std::vector<Eigen::Vector3f> points(static_cast<std::size_t>(a.shape(0)));
    // The common case, float32 rows packed like Eigen::Vector3f: one memcpy.
    if (is_float32(a) && (a.flags() & py::array::c_style) && sizeof(Eigen::Vector3f) == 12) {
        if (!points.empty())
            std::memcpy(static_cast<void*>(points.data()), a.data(), points.size() * 12);
        return points;
    }
    for_each_row(a, [&](py::ssize_t i, auto x, auto y, auto z) {
        points[i] =
            Eigen::Vector3f(static_cast<float>(x), static_cast<float>(y), static_cast<float>(z));
    });
    return points;
}

std::vector<Eigen::Vector3d> points3d(const py::handle& obj, const char* name) {
    const py::array a = float_array(obj, name);
    require_points_shape(a, name);
    std::vector<Eigen::Vector3d> points(static_cast<std::size_t>(a.shape(0)));
    for_each_row(a, [&](py::ssize_t i, auto x, auto y, auto z) {
        points[i] =
            Eigen::Vector3d(static_cast<double>(x), static_cast<double>(y), static_cast<double>(z));
    });
    return points;
}

Eigen::Isometry3d pose_from_array(const py::handle& obj, const char* name) {
    const py::array a = float_array(obj, name);
    if (a.ndim() != 2 || a.shape(1) != 4 || (a.shape(0) != 4 && a.shape(0) != 3)) {
        fail(std::string(name) + " must be a (4, 4) or (3, 4) rigid transform [R | t], got shape " +
             shape_of(a));
    }
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    for (py::ssize_t r = 0; r < a.shape(0); ++r) {
        for (py::ssize_t c = 0; c < 4; ++c) {
            const double v = is_float32(a) ? static_cast<double>(a.unchecked<float, 2>()(r, c))
                                           : a.unchecked<double, 2>()(r, c);
            if (!std::isfinite(v)) {
                fail(std::string(name) + " must be finite, but entry [" + std::to_string(r) + ", " +
                     std::to_string(c) + "] is " + std::to_string(v));
            }
            m(r, c) = v;
        }
    }
    constexpr double kRowTolerance = 1e-9;
    if (a.shape(0) == 4 &&
        (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > kRowTolerance) {
        fail(std::string(name) + "'s last row must be [0, 0, 0, 1] (a rigid transform)");
    }
    // KITTI pose files store rotations to about 1e-6; 1e-3 catches scales and shears.
    constexpr double kRotationTolerance = 1e-3;
    const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
    if ((R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() >
            kRotationTolerance ||
        R.determinant() < 0.0) {
        fail(std::string(name) +
             "'s upper-left 3x3 block must be a rotation (orthonormal, determinant +1)");
    }
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = R;
    pose.translation() = m.block<3, 1>(0, 3);
    return pose;
}

std::vector<double> per_point_values(const py::handle& obj, std::size_t num_points,
                                     const char* name) {
    const py::array a = float_array(obj, name);
    if (a.ndim() != 1 || static_cast<std::size_t>(a.shape(0)) != num_points) {
        fail(std::string(name) + " must have shape (" + std::to_string(num_points) +
             ",), one value per point, got " + shape_of(a));
    }
    std::vector<double> values(num_points);
    for (std::size_t i = 0; i < num_points; ++i) {
        values[i] = is_float32(a) ? a.unchecked<float, 1>()(i) : a.unchecked<double, 1>()(i);
    }
    return values;
}

py::array_t<double> pose_to_array(const Eigen::Isometry3d& pose) {
    py::array_t<double> out({4, 4});
    auto view = out.mutable_unchecked<2>();
    const Eigen::Matrix4d m = pose.matrix();
    for (int r = 0; r < 4; ++r) {
        for (int c = 0; c < 4; ++c) view(r, c) = m(r, c);
    }
    return out;
}

py::array_t<double> poses_to_array(const std::vector<Eigen::Isometry3d>& poses) {
    py::array_t<double> out(
        {static_cast<py::ssize_t>(poses.size()), py::ssize_t{4}, py::ssize_t{4}});
    auto view = out.mutable_unchecked<3>();
    for (std::size_t k = 0; k < poses.size(); ++k) {
        const Eigen::Matrix4d m = poses[k].matrix();
        for (int r = 0; r < 4; ++r) {
            for (int c = 0; c < 4; ++c) view(static_cast<py::ssize_t>(k), r, c) = m(r, c);
        }
    }
    return out;
}

py::array_t<float> take_points(std::vector<Eigen::Vector3f>&& points) {
    static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float), "Vector3f must be packed");
    auto* owned = new std::vector<Eigen::Vector3f>(std::move(points));
    py::capsule owner(owned, [](void* p) { delete static_cast<std::vector<Eigen::Vector3f>*>(p); });
    return py::array_t<float>({static_cast<py::ssize_t>(owned->size()), py::ssize_t{3}},
                              reinterpret_cast<const float*>(owned->data()), owner);
}

py::tuple mesh_to_arrays(const shine::TriangleMesh& mesh) {
    std::vector<double> vertices(mesh.vertices.size() * 3);
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        for (int a = 0; a < 3; ++a) {
            vertices[3 * i + a] = mesh.origin_world_m[a] + static_cast<double>(mesh.vertices[i][a]);
        }
    }
    std::vector<std::int32_t> triangles(mesh.triangles.size() * 3);
    for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
        for (int a = 0; a < 3; ++a) triangles[3 * i + a] = mesh.triangles[i][a];
    }
    const auto nv = static_cast<py::ssize_t>(mesh.vertices.size());
    const auto nt = static_cast<py::ssize_t>(mesh.triangles.size());
    return py::make_tuple(take_vector(std::move(vertices), {nv, 3}),
                          take_vector(std::move(triangles), {nt, 3}));
}

shine::TriangleMesh mesh_from_python(const py::handle& obj, const char* name) {
    const py::module_ os = py::module_::import("os");
    if (py::isinstance<py::str>(obj) || py::isinstance(obj, os.attr("PathLike"))) {
        const std::string path = py::str(os.attr("fspath")(obj)).cast<std::string>();
        py::gil_scoped_release release;
        return shine::read_ply_mesh(path);
    }
    if (is_python_mesh(obj)) return mesh_from_python(python_mesh_arrays(obj), name);
    if (!py::isinstance<py::tuple>(obj) && !py::isinstance<py::list>(obj)) {
        fail(std::string(name) +
             " must be a PLY path, a shinevdb.Mesh or a (vertices, triangles) tuple");
    }
    const py::sequence parts = py::reinterpret_borrow<py::sequence>(obj);
    if (parts.size() != 2 && parts.size() != 3) {
        fail(std::string(name) +
             " must be (vertices, triangles) or (vertices, triangles, "
             "face_observed), got " +
             std::to_string(parts.size()) + " items");
    }
    const std::string vname = std::string(name) + "[0] (vertices)";
    const std::vector<Eigen::Vector3d> vertices = points3d(parts[0], vname.c_str());
    shine::TriangleMesh mesh;
    if (!vertices.empty()) mesh.origin_world_m = shine::map_origin_world_m(vertices.front());
    mesh.vertices.reserve(vertices.size());
    for (const auto& v : vertices) mesh.vertices.push_back((v - mesh.origin_world_m).cast<float>());

    const std::string tname = std::string(name) + "[1] (triangles)";
    const py::array t = py::array::ensure(parts[1]);
    if (!t || t.ndim() != 2 || t.shape(1) != 3 ||
        (t.dtype().kind() != 'i' && t.dtype().kind() != 'u')) {
        PyErr_Clear();
        fail(tname + " must be an integer array of shape (T, 3)");
    }
    const py::array_t<std::int64_t> t64 = py::array_t<std::int64_t>::ensure(t);
    const auto tv = t64.unchecked<2>();
    mesh.triangles.reserve(static_cast<std::size_t>(tv.shape(0)));
    for (py::ssize_t i = 0; i < tv.shape(0); ++i) {
        Eigen::Vector3i tri;
        for (int a = 0; a < 3; ++a) {
            const std::int64_t index = tv(i, a);
            if (index < 0 || index >= static_cast<std::int64_t>(vertices.size())) {
                fail(tname + ": triangle " + std::to_string(i) + " refers to vertex " +
                     std::to_string(index) + " of " + std::to_string(vertices.size()));
            }
            tri[a] = static_cast<int>(index);
        }
        mesh.triangles.push_back(tri);
    }
    if (parts.size() == 3 && !parts[2].is_none()) {
        const py::array_t<std::uint8_t> observed =
            py::array_t<std::uint8_t, py::array::forcecast>::ensure(parts[2]);
        if (!observed || observed.ndim() != 1 ||
            static_cast<std::size_t>(observed.shape(0)) != mesh.triangles.size()) {
            PyErr_Clear();
            fail(std::string(name) + "[2] (face_observed) must have one flag per triangle");
        }
        const auto ov = observed.unchecked<1>();
        for (py::ssize_t i = 0; i < ov.shape(0); ++i) mesh.face_observed.push_back(ov(i) ? 1 : 0);
    }
    return mesh;
}

}  // namespace shinevdb
