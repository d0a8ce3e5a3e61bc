// shinevdb.TSDFVolume: the TSDF-fusion baseline (VDBFusion's algorithm, tsdf/tsdf_volume.hpp) with
// VDBFusion's Python names, so that a VDBFusion script runs with its import changed to
// `from shinevdb import TSDFVolume as VDBVolume`.
//
// As in VDBFusion, integrate() takes world-frame points and the sensor's pose (only its position
// is used: the origin of the rays). The volume works in a frame shifted from the world by whole
// kilometres (fixed by the first scan), so far-away (UTM) coordinates keep their precision;
// meshes come back in the world frame.
#include "shine/tsdf/tsdf_volume.hpp"

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>

#include "long_call.hpp"
#include "numpy_io.hpp"
#include "shine/geometry/map_frame.hpp"
#include "shine/tsdf/tsdf_file.hpp"
#include "shine/tsdf/tsdf_mesh.hpp"

namespace shinevdb {
namespace {
using namespace shine;

TsdfConfig make_config(double voxel_size, double sdf_trunc, bool space_carving) {
    if (!(voxel_size > 0.0) || !std::isfinite(voxel_size)) {
        throw py::value_error("voxel_size must be a positive number of metres, got " +
                              std::to_string(voxel_size));
    }
    if (!(sdf_trunc > 0.0) || !std::isfinite(sdf_trunc)) {
        throw py::value_error("sdf_trunc must be a positive number of metres, got " +
                              std::to_string(sdf_trunc));
    }
    TsdfConfig config;
    config.voxel_size_m = voxel_size;
    config.trunc_m = sdf_trunc;
    config.space_carving = space_carving;
    config.validate();
    return config;
}

/// The sensor origin of VDBFusion's `extrinsic`: a 4x4 (or 3x4) pose, or a 3-vector.
Eigen::Vector3d origin_of(const py::handle& extrinsic) {
    const py::array a = float_array(extrinsic, "extrinsic");
    if (a.ndim() == 1) {
        if (a.shape(0) != 3) {
            throw py::value_error(
                "extrinsic must be a (4, 4) pose or a (3,) sensor origin, got "
                "shape (" +
                std::to_string(a.shape(0)) + ",)");
        }
        const py::array_t<double> v = py::array_t<double, py::array::forcecast>::ensure(a);
        const Eigen::Vector3d origin(v.at(0), v.at(1), v.at(2));
        if (!origin.allFinite())
            throw py::value_error("extrinsic (the sensor origin) must be finite");
        return origin;
    }
    return pose_from_array(a, "extrinsic").translation();
}

class TSDFVolume {
  public:
    TSDFVolume(double voxel_size, double sdf_trunc, bool space_carving)
        : volume_(make_config(voxel_size, sdf_trunc, space_carving)) {}

    void integrate(const py::handle& points, const py::handle& extrinsic) {
        const std::vector<Eigen::Vector3d> points_world = points3d(points, "points");
        const Eigen::Vector3d origin_world = origin_of(extrinsic);
        {
            py::gil_scoped_release release;
            if (!origin_set_) {
                volume_.set_origin_world_m(map_origin_world_m(origin_world));
                origin_set_ = true;
            }
            const Eigen::Vector3d shift = volume_.origin_world_m();
            std::vector<Eigen::Vector3d> points_map;
            points_map.reserve(points_world.size());
            for (const auto& p : points_world) points_map.push_back(p - shift);
            volume_.integrate(points_map, origin_world - shift);
        }
        check_signals();
    }

    py::tuple extract_triangle_mesh(bool fill_holes, float min_weight) const {
        TsdfMeshConfig config;
        config.fill_holes = fill_holes;
        config.min_weight = min_weight;
        if (!(min_weight >= 0.0f) || !std::isfinite(min_weight)) {
            throw py::value_error("min_weight must be >= 0, got " + std::to_string(min_weight));
        }
        TriangleMesh mesh;
        {
            py::gil_scoped_release release;
            mesh = extract_tsdf_mesh(volume_, config);
        }
        check_signals();
        return mesh_to_arrays(mesh);
    }

    void extract_vdb_grids(const py::object& path) const {
        const std::string file =
            py::str(py::module_::import("os").attr("fspath")(path)).cast<std::string>();
        py::gil_scoped_release release;
        write_tsdf_volume(file, volume_);
    }

    double voxel_size() const { return volume_.config().voxel_size_m; }
    double sdf_trunc() const { return volume_.config().trunc_m; }
    bool space_carving() const { return volume_.config().space_carving; }
    std::size_t memory_bytes() const { return volume_.memory_bytes(); }
    std::size_t active_voxels() const { return volume_.active_voxels(); }

  private:
    TsdfVolume volume_;
    bool origin_set_ = false;
};

}  // namespace

void bind_tsdf_volume(py::module_& m) {
    py::class_<TSDFVolume>(m, "TSDFVolume", R"doc(
TSDF fusion with VDBFusion's algorithm and Python names (the baseline of ``shine tsdf``).

``from shinevdb import TSDFVolume as VDBVolume`` runs a VDBFusion script unchanged:
``VDBVolume(voxel_size, sdf_trunc, space_carving)``, ``integrate(points, extrinsic)``,
``extract_triangle_mesh(fill_holes, min_weight)``.
)doc")
        .def(py::init<double, double, bool>(), py::arg("voxel_size"), py::arg("sdf_trunc"),
             py::arg("space_carving") = false,
             "voxel_size and sdf_trunc (truncation distance) in metres.")
        .def("integrate", &TSDFVolume::integrate, py::arg("points"), py::arg("extrinsic"), R"doc(
Integrates one scan.

Args:
    points: (N, 3) float32/float64 points in the world frame (VDBFusion's convention).
    extrinsic: the sensor pose T_world_sensor as a (4, 4) matrix, or its (3,) position.
)doc")
        .def("extract_triangle_mesh", &TSDFVolume::extract_triangle_mesh,
             py::arg("fill_holes") = true, py::arg("min_weight") = 0.0f, R"doc(
Marching cubes over the observed voxels (VDBFusion's defaults).

Returns:
    (vertices (V, 3) float64 world frame, triangles (T, 3) int32).
)doc")
        .def("extract_vdb_grids", &TSDFVolume::extract_vdb_grids, py::arg("out_file"),
             "Writes the TSDF and weight grids to a .vdb file (as `shine tsdf` does).")
        .def_property_readonly("voxel_size", &TSDFVolume::voxel_size)
        .def_property_readonly("sdf_trunc", &TSDFVolume::sdf_trunc)
        .def_property_readonly("space_carving", &TSDFVolume::space_carving)
        .def_property_readonly("memory_bytes", &TSDFVolume::memory_bytes,
                               "memUsage() of the TSDF and weight grids, in bytes.")
        .def_property_readonly("active_voxels", &TSDFVolume::active_voxels,
                               "Voxels updated at least once.");
}

}  // namespace shinevdb
