// Triangle mesh of a level set's zero crossing, with OpenVDB's volumeToMesh (the same extraction
// Houdini and Blender use), quads split into triangles.
#pragma once

#include <openvdb/openvdb.h>

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

/// Removes connected components (by shared vertices) with fewer than `min_triangles` triangles
/// and drops unreferenced vertices. Returns the number of triangles removed.
std::size_t remove_small_components(TriangleMesh& mesh, std::size_t min_triangles);

}  // namespace shine
