// Meshes with their colour and reflectance for Python: the shinevdb.Mesh result, and per-vertex
// values sampled from the "color" and "intensity" grids `shine map` writes beside the level set
// in surface.vdb (bake/surface_attribute_grids.hpp).
//
// Sampling rule (one for both grids): a vertex takes the value of the nearest voxel centre at
// which the grid is active, among the 3 x 3 x 3 voxels around the voxel that holds the vertex;
// ties go to the first in (dx, dy, dz) order, each from -1 to 1. Nearest, not trilinear: the
// colours stay the 8-bit values fused from the images (round(255 * value) gives back the byte
// exactly), and a vertex between a seen and an unseen voxel is never darkened by the unseen one's
// background. A vertex with no active voxel around it has colour (0, 0, 0) -- what mesh.ply holds
// for a vertex no camera saw -- and intensity NaN.
#pragma once

#include <openvdb/openvdb.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <filesystem>
#include <string>

#include "shine/geometry/triangle_mesh.hpp"

namespace shinevdb {
namespace py = pybind11;

/// The appearance grids of a surface.vdb (either may be null) and the frame they are in.
struct SurfaceGrids {
    std::filesystem::path path;
    openvdb::Vec3SGrid::Ptr color;
    openvdb::FloatGrid::Ptr intensity;
    bool empty() const { return !color && !intensity; }
};

/// `path` itself, or `path`/`file_name` when `path` is a directory (a `shine map` output folder).
std::filesystem::path file_in_folder(const std::filesystem::path& path, const char* file_name);

/// Reads the "color" (Vec3SGrid) and "intensity" (FloatGrid) grids of a surface.vdb, if present.
/// Throws IoError naming the file when it is missing or not a .vdb, or a grid has another type.
SurfaceGrids read_surface_grids(const std::filesystem::path& path);

/// Fills mesh.vertex_rgb (when grids.color) and mesh.vertex_intensity (when grids.intensity)
/// by the sampling rule above; the grids' frame is their shine_origin_world_m metadata.
void sample_surface_grids(const SurfaceGrids& grids, shine::TriangleMesh& mesh);

/// `mesh` as a shinevdb.Mesh (its arrays own the data).
py::object mesh_to_python(const shine::TriangleMesh& mesh);

/// Whether `obj` is a shinevdb.Mesh, and its (vertices, triangles) if so.
bool is_python_mesh(const py::handle& obj);
py::tuple python_mesh_arrays(const py::handle& obj);

/// shinevdb.Mesh, read_mesh(), extract_mesh() and read_surface_grids().
void bind_mesh(py::module_& m);

}  // namespace shinevdb
