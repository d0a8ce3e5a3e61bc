// Triangle mesh of a TSDF volume's zero crossing, as VDBFusion's ExtractTriangleMesh makes it.
//
// Marching cubes over the voxel lattice, our own code (table: marching_cubes.hpp), chosen over
// openvdb::tools::volumeToMesh because VDBFusion's surface is defined by its own marching cubes:
//   - every active TSDF voxel v is the (0,0,0) corner of one cube with corners v + {0,1}^3;
//   - a cube is skipped if any corner has weight < min_weight, or, without fill_holes, weight 0
//     (never observed); with fill_holes and min_weight <= 0, unobserved corners take the grid's
//     background (+trunc, or -trunc with space carving) -- fill_holes has no effect otherwise;
//   - a corner is inside when its TSDF is < 0; the surface crosses an edge at the linear zero
//     crossing, |D_a| / (|D_a| + |D_b|) of the way from corner a to corner b;
//   - a vertex per crossed lattice edge, shared by the cubes around it.
// volumeToMesh would mesh a different surface (dual contouring-like vertex placement, no weight
// mask, polygons wherever an active voxel's sign differs from a neighbour's, including the
// unobserved background). Vertices are in the volume's map frame (float) and the mesh's
// origin_world_m is the volume's, so world = origin_world_m + vertex at full precision;
// triangles are wound counter-clockwise seen from free space (positive TSDF), so their normals
// point towards the sensor, as in ShineVDB's other meshes. Differences from VDBFusion: the
// triangulation inside ambiguous or multi-triangle cubes (see marching_cubes.hpp) and the
// vertex order (VDBFusion's follows its iteration; ours is deterministic leaf by leaf).
#pragma once

#include "shine/geometry/triangle_mesh.hpp"
#include "shine/tsdf/tsdf_volume.hpp"

namespace shine {

/// Mesh extraction parameters (VDBFusion's ExtractTriangleMesh arguments).
struct TsdfMeshConfig {
    /// min_weight: every corner needs weight >= this. VDBFusion's library default is 0.5 (every
    /// corner observed once; weights are update counts); its KITTI configs use 5 on raw scans,
    /// which on ShineVDB's 5 cm-downsampled scans masks much of the street (docs/tsdf.md).
    float min_weight = 0.5f;
    /// fill_holes: let unobserved corners take the background; only matters if min_weight <= 0.
    bool fill_holes = false;

    /// Throws ConfigError naming --min-weight if it is negative or not finite.
    void validate() const;
};

/// Extracts the zero crossing of `volume` (parallel over OpenVDB leaf nodes; the result does not
/// depend on the thread count). Throws ConfigError if `config` is invalid.
TriangleMesh extract_tsdf_mesh(const TsdfVolume& volume, const TsdfMeshConfig& config = {});

}  // namespace shine
