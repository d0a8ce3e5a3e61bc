// Bakes the neural SDF into an OpenVDB narrow-band level set (openvdb::FloatGrid, class
// LEVEL_SET, world-unit distances), restricted to the observed region.
//
// Voxel (i,j,k) samples the SDF at (i,j,k) * voxel_size_m in the map frame; only voxels inside
// allocated level-0 cells are evaluated (the region the scans observed). Voxels within
// half_width_voxels of the surface are active; the rest of the grid is inactive with the signed
// background (-/+ half-width in metres) filled by OpenVDB's signedFloodFill, so OpenVDB tools,
// Blender and Houdini see a proper level set. The grid's transform places it in the world frame
// (map origin added).
#pragma once

#include <openvdb/openvdb.h>

#include "shine/model/neural_sdf.hpp"

namespace shine {

struct BakeConfig {
    double voxel_size_m = 0.0;       ///< 0: half the leaf size
    float half_width_voxels = 3.0f;  ///< narrow band half-width (OpenVDB's default is 3)
    /// The surface is baked inside the allocated cells of this level: 0 keeps it to the finest
    /// cells around the points; 1 also fills the gaps between them that the next level covers.
    int mask_level = 0;
};

/// Statistics of a bake, for logs and stats.json.
struct BakeStats {
    std::size_t evaluated_voxels = 0;
    std::size_t active_voxels = 0;
    double voxel_size_m = 0.0;
};

/// Voxel size a config resolves to for a map with the given leaf size.
double resolve_bake_voxel_size_m(const BakeConfig& config, double leaf_size_m);

/// Bakes `sdf` into a level set named "surface". Throws ConfigError on a non-positive voxel size.
openvdb::FloatGrid::Ptr bake_level_set(const NeuralSdf& sdf, const BakeConfig& config,
                                       BakeStats* stats = nullptr);

}  // namespace shine
