// Colour and reflectance beside the level set in surface.vdb: a Vec3SGrid named "color" (8-bit
// sRGB values / 255, so 0..1) and a FloatGrid named "intensity" (the LiDAR's reflectance as the
// sensor gives it), with the level set's transform and origin metadata, on the level set's
// active voxels where a value is known (inactive elsewhere, background 0).
//
// A voxel's values are those of its surface point: the voxel centre x moved to the zero
// crossing, x - phi(x) * grad(phi)(x) / |grad(phi)(x)|^2 (central differences), then one more step
// along the normal by the distance sampled there (trilinear): the point a mesh vertex near it
// would sit on.
#pragma once

#include <openvdb/openvdb.h>

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <vector>

namespace shine {

/// The level set's active voxels and their surface points, in the grid's frame (the map frame:
/// world = kOriginMetadataKey origin + point).
struct LevelSetSurfacePoints {
    std::vector<openvdb::Coord> voxels;
    std::vector<Eigen::Vector3d> points_map;   ///< on the zero crossing
    std::vector<Eigen::Vector3d> normals_map;  ///< unit gradient (outward), zero where flat
};

/// Every active voxel of `level_set` with its surface point, in a fixed order.
LevelSetSurfacePoints level_set_surface_points(const openvdb::FloatGrid& level_set);

/// Grid names in surface.vdb.
inline constexpr char kColorGridName[] = "color";
inline constexpr char kIntensityGridName[] = "intensity";

/// A "color" grid on `voxels` (rgb / 255) where weight > 0; the level set's transform and
/// metadata. Throws DataError for mismatched lengths.
openvdb::Vec3SGrid::Ptr make_color_grid(const openvdb::FloatGrid& level_set,
                                        const std::vector<openvdb::Coord>& voxels,
                                        const std::vector<std::array<std::uint8_t, 3>>& rgb,
                                        const std::vector<float>& weight);

/// An "intensity" grid on `voxels` where the value is finite. Throws DataError for mismatched
/// lengths.
openvdb::FloatGrid::Ptr make_intensity_grid(const openvdb::FloatGrid& level_set,
                                            const std::vector<openvdb::Coord>& voxels,
                                            const std::vector<float>& intensity);

/// Writes the level set and `extra` grids to `path` atomically (the level set first, so readers
/// that take the first float level set find it). Throws IoError naming the file.
void write_surface_grids(const std::filesystem::path& path,
                         const openvdb::FloatGrid::Ptr& level_set,
                         const openvdb::GridPtrVec& extra);

}  // namespace shine
