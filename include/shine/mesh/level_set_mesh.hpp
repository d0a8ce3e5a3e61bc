// Triangle mesh of a level set's zero crossing, with OpenVDB's volumeToMesh (the same extraction
// Houdini and Blender use), quads split into triangles.
#pragma once

#include <openvdb/openvdb.h>

#include <cstddef>
#include <filesystem>

#include "shine/geometry/triangle_mesh.hpp"

namespace shine {

struct MeshConfig {
    double isovalue_m = 0.0;
    double adaptivity = 0.0;                  ///< 0 keeps every triangle (no decimation)
    std::size_t min_component_triangles = 0;  ///< drop connected pieces smaller than this
};

/// Grid metadata (Vec3d) holding the world position of the frame a ShineVDB level set is in.
inline constexpr char kOriginMetadataKey[] = "shine_origin_world_m";

/// Extracts the surface of `level_set` in the grid's frame (index-to-world transform, vertices as
/// float); the mesh's origin_world_m is the grid's kOriginMetadataKey metadata (zero without it).
TriangleMesh mesh_level_set(const openvdb::FloatGrid& level_set, const MeshConfig& config);

/// What write_level_set_mesh() wrote.
struct MeshFileStats {
    std::size_t vertices = 0;
    std::size_t triangles = 0;
    std::size_t regions = 0;  ///< regions meshed one after another (1: the whole grid at once)
};

/// Edge (voxels) of the square columns write_level_set_mesh() meshes one at a time.
inline constexpr int kMeshRegionVoxels = 256;

/// Meshes `level_set` as mesh_level_set() does and writes the mesh to `path` (binary PLY,
/// atomically), region by region: columns `region_voxels` voxels square (a multiple of 8), as tall
/// as the grid, are cut out with a margin and meshed, and each polygon is kept by the one column
/// that holds its centre; vertices on column seams are welded. The triangles are
/// mesh_level_set()'s, in another order (a quad's diagonal may differ), and memory stays that of
/// one column, whatever the grid's extent. Adaptivity and the removal of small components need
/// the whole mesh: with either set, it meshes the grid at once.
/// With `written`, the mesh is also left there as the file holds it (what read_ply_mesh() gives
/// back: vertices, triangles, origin), for a caller that would read the file next; the mesh is
/// then held whole.
MeshFileStats write_level_set_mesh(const openvdb::FloatGrid& level_set, const MeshConfig& config,
                                   const std::filesystem::path& path,
                                   int region_voxels = kMeshRegionVoxels,
                                   TriangleMesh* written = nullptr);

/// Removes connected components (by shared vertices) with fewer than `min_triangles` triangles
/// and drops unreferenced vertices. Returns the number of triangles removed.
std::size_t remove_small_components(TriangleMesh& mesh, std::size_t min_triangles);

}  // namespace shine
