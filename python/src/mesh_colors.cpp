// shinevdb.Mesh, read_mesh(), extract_mesh() and read_surface_grids(): meshes with the colour and
// reflectance `shine map` adds to mesh.ply and surface.vdb (mesh_colors.hpp has the sampling rule).
#include "mesh_colors.hpp"

#include <openvdb/io/File.h>
#include <openvdb/math/Maps.h>
#include <pybind11/numpy.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "numpy_io.hpp"
#include "shine/bake/level_set_file.hpp"
#include "shine/bake/surface_attribute_grids.hpp"
#include "shine/core/error.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/vdb_file_check.hpp"
#include "shine/mesh/level_set_mesh.hpp"

namespace shinevdb {
namespace fs = std::filesystem;

namespace mesh_colors_internal {
namespace {

/// The result type: plain arrays, None for what the mesh does not carry.
struct Mesh {
    py::object vertices;
    py::object triangles;
    py::object colors = py::none();
    py::object intensity = py::none();
};

std::string path_string(const py::handle& path) {
    return py::str(py::module_::import("os").attr("fspath")(path)).cast<std::string>();
}

/// An 8-bit sRGB value stored as value / 255 (make_color_grid), back to the byte.
std::uint8_t to_byte(float value) {
    const float scaled = std::round(value * 255.0f);
    if (!(scaled > 0.0f)) return 0;  // also NaN
    return scaled >= 255.0f ? std::uint8_t{255} : static_cast<std::uint8_t>(scaled);
}

/// The grid's frame in the world: its shine_origin_world_m metadata, zero without it.
Eigen::Vector3d grid_origin_world_m(const openvdb::GridBase& grid) {
    if (const auto origin = grid.getMetadata<openvdb::Vec3DMetadata>(shine::kOriginMetadataKey)) {
        const openvdb::Vec3d& o = origin->value();
        return {o.x(), o.y(), o.z()};
    }
    return Eigen::Vector3d::Zero();
}

/// The value of the nearest active voxel among the 27 around `index`'s voxel (mesh_colors.hpp).
template <typename Accessor, typename Value>
bool nearest_active_value(const Accessor& accessor, const openvdb::Vec3d& index, Value& out) {
    const openvdb::Coord centre = openvdb::Coord::round(index);
    double best_sq = std::numeric_limits<double>::infinity();
    bool found = false;
    for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
            for (int dz = -1; dz <= 1; ++dz) {
                const openvdb::Coord q = centre.offsetBy(dx, dy, dz);
                Value value;
                if (!accessor.probeValue(q, value)) continue;
                const double d_sq = (index - q.asVec3d()).lengthSqr();
                if (d_sq < best_sq) {
                    best_sq = d_sq;
                    out = value;
                    found = true;
                }
            }
        }
    }
    return found;
}

/// Calls f(i, index) for every vertex with its index-space position in `grid`, in parallel, and
/// one accessor of `grid` per task.
template <typename GridT, typename F>
void for_each_vertex_index(const GridT& grid, const shine::TriangleMesh& mesh, F&& f) {
    const Eigen::Vector3d shift_m = mesh.origin_world_m - grid_origin_world_m(grid);
    const openvdb::math::Transform& xform = grid.transform();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, mesh.vertices.size(), 4096),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          auto accessor = grid.getConstAccessor();
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              const Eigen::Vector3d p = mesh.vertices[i].cast<double>() + shift_m;
                              f(accessor, i,
                                xform.worldToIndex(openvdb::Vec3d(p.x(), p.y(), p.z())));
                          }
                      });
}

template <typename GridT>
typename GridT::Ptr read_typed_grid(openvdb::io::File& file, const fs::path& path, const char* name,
                                    const char* type) {
    if (!file.hasGrid(name)) return nullptr;
    // dynamic_pointer_cast, not openvdb::gridPtrCast: the latter instantiates Tree::treeType()
    // here, whose call_once the module would export and libopenvdb's own initialize() would then
    // run with this copy's statics, leaving libopenvdb's tree type names unset (a crash).
    auto grid = std::dynamic_pointer_cast<GridT>(file.readGrid(name));
    if (!grid) {
        throw shine::IoError("'" + path.string() + "': grid '" + name + "' is not a " + type +
                             " (surface.vdb of `shine map` holds it as one; was the file written "
                             "by another program?)");
    }
    return grid;
}

/// Active voxels of `grid` and their values, in the tree's order.
template <typename GridT, typename Value, typename Convert>
py::tuple active_voxels(const GridT& grid, int channels, Convert&& convert) {
    std::vector<std::int32_t> ijk;
    std::vector<Value> values;
    for (auto it = grid.cbeginValueOn(); it; ++it) {
        const openvdb::Coord c = it.getCoord();
        ijk.insert(ijk.end(), {c.x(), c.y(), c.z()});
        convert(*it, values);
    }
    const auto n = static_cast<py::ssize_t>(ijk.size() / 3);
    std::vector<py::ssize_t> shape{n};
    if (channels > 1) shape.push_back(channels);
    return py::make_tuple(take_vector(std::move(ijk), {n, 3}),
                          take_vector(std::move(values), shape));
}

double uniform_voxel_size_m(const openvdb::GridBase& grid, const fs::path& path) {
    const openvdb::math::Transform& xform = grid.transform();
    if (!xform.isLinear() || !xform.hasUniformScale() ||
        xform.indexToWorld(openvdb::Vec3d(0.0)).length() != 0.0) {
        throw shine::IoError("'" + path.string() + "': grid '" + grid.getName() +
                             "' does not have a uniform scale transform without translation, as "
                             "ShineVDB's surface grids do");
    }
    return xform.voxelSize()[0];
}

py::dict surface_grids_dict(const fs::path& path) {
    SurfaceGrids grids;
    {
        py::gil_scoped_release release;
        grids = read_surface_grids(path);
    }
    py::dict out;
    out["color_voxels"] = py::none();
    out["color"] = py::none();
    out["intensity_voxels"] = py::none();
    out["intensity"] = py::none();
    const openvdb::GridBase* any = nullptr;
    if (grids.color) {
        any = grids.color.get();
        const py::tuple color = active_voxels<openvdb::Vec3SGrid, std::uint8_t>(
            *grids.color, 3, [](const openvdb::Vec3s& v, std::vector<std::uint8_t>& out) {
                out.insert(out.end(), {to_byte(v.x()), to_byte(v.y()), to_byte(v.z())});
            });
        out["color_voxels"] = color[0];
        out["color"] = color[1];
    }
    if (grids.intensity) {
        any = grids.intensity.get();
        const py::tuple intensity = active_voxels<openvdb::FloatGrid, float>(
            *grids.intensity, 1, [](float v, std::vector<float>& out) { out.push_back(v); });
        out["intensity_voxels"] = intensity[0];
        out["intensity"] = intensity[1];
    }
    if (!any) {
        throw py::value_error("'" + path.string() +
                              "' holds no 'color' or 'intensity' grid: `shine map` adds them "
                              "when the sequence folder has camera images or the scans carry "
                              "intensity");
    }
    const Eigen::Vector3d origin = grid_origin_world_m(*any);
    out["voxel_size_m"] = uniform_voxel_size_m(*any, path);
    out["origin_world_m"] =
        take_vector(std::vector<double>{origin.x(), origin.y(), origin.z()}, {3});
    return out;
}

py::object read_mesh(const py::object& path) {
    const fs::path file = file_in_folder(path_string(path), "mesh.ply");
    shine::TriangleMesh mesh;
    {
        py::gil_scoped_release release;
        mesh = shine::read_ply_mesh(file);
    }
    return mesh_to_python(mesh);
}

py::object extract_mesh(const py::object& surface, double adaptivity) {
    if (!(adaptivity >= 0.0 && adaptivity <= 1.0)) {
        throw py::value_error("adaptivity must be in [0, 1] (0: every triangle), got " +
                              std::to_string(adaptivity));
    }
    const fs::path file = file_in_folder(path_string(surface), "surface.vdb");
    shine::TriangleMesh mesh;
    {
        py::gil_scoped_release release;
        const openvdb::FloatGrid::Ptr level_set = shine::read_level_set(file);
        shine::MeshConfig config;
        config.adaptivity = adaptivity;
        mesh = shine::mesh_level_set(*level_set, config);
        sample_surface_grids(read_surface_grids(file), mesh);
    }
    return mesh_to_python(mesh);
}

}  // namespace
}  // namespace mesh_colors_internal

// No `using namespace mesh_colors_internal`: the module is built as one unity source, where
// another file's helpers of the same names (path_string) would become ambiguous.

fs::path file_in_folder(const fs::path& path, const char* file_name) {
    return fs::is_directory(path) ? path / file_name : path;
}

SurfaceGrids read_surface_grids(const fs::path& path) {
    openvdb::initialize();
    if (!fs::is_regular_file(path)) {
        throw shine::IoError("surface file '" + path.string() +
                             "' does not exist (give a surface.vdb or a `shine map` output "
                             "folder)");
    }
    shine::check_vdb_file(path, "surface file");
    SurfaceGrids grids;
    grids.path = path;
    try {
        openvdb::io::File file(path.string());
        file.open(false);
        grids.color = mesh_colors_internal::read_typed_grid<openvdb::Vec3SGrid>(
            file, path, shine::kColorGridName, "Vec3SGrid (vec3s)");
        grids.intensity = mesh_colors_internal::read_typed_grid<openvdb::FloatGrid>(
            file, path, shine::kIntensityGridName, "FloatGrid (float)");
        file.close();
    } catch (const openvdb::Exception& e) {
        throw shine::IoError("cannot read '" + path.string() + "': not a valid .vdb file (" +
                             e.what() + ")");
    }
    return grids;
}

void sample_surface_grids(const SurfaceGrids& grids, shine::TriangleMesh& mesh) {
    const std::size_t n = mesh.vertices.size();
    if (grids.color) {
        mesh.vertex_rgb.assign(n, {0, 0, 0});
        mesh_colors_internal::for_each_vertex_index(
            *grids.color, mesh,
            [&](const auto& accessor, std::size_t i, const openvdb::Vec3d& ijk) {
                openvdb::Vec3s value;
                if (!mesh_colors_internal::nearest_active_value(accessor, ijk, value)) return;
                using mesh_colors_internal::to_byte;
                mesh.vertex_rgb[i] = {to_byte(value.x()), to_byte(value.y()), to_byte(value.z())};
            });
    }
    if (grids.intensity) {
        mesh.vertex_intensity.assign(n, std::numeric_limits<float>::quiet_NaN());
        mesh_colors_internal::for_each_vertex_index(
            *grids.intensity, mesh,
            [&](const auto& accessor, std::size_t i, const openvdb::Vec3d& ijk) {
                float value = 0.0f;
                if (mesh_colors_internal::nearest_active_value(accessor, ijk, value)) {
                    mesh.vertex_intensity[i] = value;
                }
            });
    }
}

py::object mesh_to_python(const shine::TriangleMesh& mesh) {
    using mesh_colors_internal::Mesh;
    const py::tuple arrays = mesh_to_arrays(mesh);
    Mesh out;
    out.vertices = arrays[0];
    out.triangles = arrays[1];
    const auto nv = static_cast<py::ssize_t>(mesh.vertices.size());
    if (!mesh.vertex_rgb.empty()) {
        std::vector<std::uint8_t> rgb(mesh.vertex_rgb.size() * 3);
        for (std::size_t i = 0; i < mesh.vertex_rgb.size(); ++i) {
            for (int c = 0; c < 3; ++c) rgb[3 * i + c] = mesh.vertex_rgb[i][c];
        }
        out.colors = take_vector(std::move(rgb), {nv, 3});
    }
    if (!mesh.vertex_intensity.empty()) {
        out.intensity = take_vector(std::vector<float>(mesh.vertex_intensity), {nv});
    }
    return py::cast(std::move(out));
}

bool is_python_mesh(const py::handle& obj) {
    return py::isinstance<mesh_colors_internal::Mesh>(obj);
}

py::tuple python_mesh_arrays(const py::handle& obj) {
    const auto& mesh = obj.cast<const mesh_colors_internal::Mesh&>();
    return py::make_tuple(mesh.vertices, mesh.triangles);
}

void bind_mesh(py::module_& m) {
    using mesh_colors_internal::Mesh;
    namespace internal = mesh_colors_internal;
    py::class_<Mesh>(m, "Mesh", R"doc(
A triangle mesh with its per-vertex colour and LiDAR reflectance, when it has them.

Attributes:
    vertices: (V, 3) float64, world frame (metres).
    triangles: (T, 3) int32 vertex indices.
    colors: (V, 3) uint8 8-bit sRGB (the camera images' bytes, no gamma change), or None when
        the source holds no colour. A vertex no camera saw is (0, 0, 0), as in mesh.ply.
    intensity: (V,) float32 reflectance as the scans give it (never rescaled), NaN where no
        scan measured it, or None when the source holds none.

``evaluate()`` takes a Mesh wherever it takes ``(vertices, triangles)``.
)doc")
        .def_readonly("vertices", &Mesh::vertices)
        .def_readonly("triangles", &Mesh::triangles)
        .def_readonly("colors", &Mesh::colors)
        .def_readonly("intensity", &Mesh::intensity)
        .def("__repr__", [](const Mesh& mesh) {
            const auto rows = [](const py::object& a) { return std::to_string(py::len(a)); };
            return "shinevdb.Mesh(" + rows(mesh.vertices) + " vertices, " + rows(mesh.triangles) +
                   " triangles, colors " + (mesh.colors.is_none() ? "None" : "(V, 3) uint8") +
                   ", intensity " + (mesh.intensity.is_none() ? "None" : "(V,) float32") + ")";
        });

    m.def("read_mesh", &internal::read_mesh, py::arg("path"), R"doc(
Reads a PLY mesh with its per-vertex colour and intensity, if it has them.

Args:
    path: a .ply file, or a ``shine map`` output folder (its mesh.ply).
Returns:
    A Mesh. ``colors`` come from the vertex properties red, green, blue (all three, any scalar
    type, clamped to 0..255) and ``intensity`` from the property intensity, exactly as stored;
    each is None when the file lacks it. The shine_origin_world_m header comment of a far-away
    map is added back to the vertices.
Raises:
    OSError naming the file when it is missing or not a valid PLY.
)doc");

    m.def("extract_mesh", &internal::extract_mesh, py::arg("surface"), py::arg("adaptivity") = 0.0,
          R"doc(
Meshes a surface level set (OpenVDB volumeToMesh, as ``shine mesh``) with the colour and
reflectance baked beside it.

Args:
    surface: a surface.vdb (from ``shine map``, ``shine bake`` or NeuralMap.bake()) or a
        ``shine map`` output folder (its surface.vdb).
    adaptivity: mesh decimation in [0, 1]; 0 keeps every triangle.
Returns:
    A Mesh. ``colors`` / ``intensity`` are sampled from the file's "color" / "intensity" grids
    (None without them): each vertex takes the value of the nearest voxel centre where the
    grid is active, among the 3 x 3 x 3 voxels around the vertex's voxel (nearest, not
    trilinear: the bytes stay those fused from the images); (0, 0, 0) / NaN when there is none.
    These are the grids' values at the surface, not mesh.ply's colours (fused at mesh.ply's own
    vertices, with unseen vertices filled from their neighbours): use read_mesh() for those.
Raises:
    OSError naming the file when it is missing, not a .vdb, or holds no float level set.
)doc");

    m.def(
        "read_surface_grids",
        [](const py::object& path) {
            return internal::surface_grids_dict(
                file_in_folder(internal::path_string(path), "surface.vdb"));
        },
        py::arg("path"), R"doc(
The active voxels of a surface.vdb's "color" and "intensity" grids, as numpy arrays.

Args:
    path: a surface.vdb or a ``shine map`` output folder.
Returns:
    A dict: ``voxel_size_m``; ``origin_world_m`` (3,) float64; ``color_voxels`` (N, 3) int32
    voxel indices (i, j, k) and ``color`` (N, 3) uint8 (the stored value * 255, rounded: the
    8-bit sRGB bytes); ``intensity_voxels`` (M, 3) int32 and ``intensity`` (M,) float32; a grid
    the file lacks gives None for both of its entries. Voxel (i, j, k)'s centre is at
    ``origin_world_m + voxel_size_m * (i, j, k)`` in the world frame.
Raises:
    ValueError when the file has neither grid; OSError naming the file when it is missing or
    not a .vdb.
)doc");
}

}  // namespace shinevdb
