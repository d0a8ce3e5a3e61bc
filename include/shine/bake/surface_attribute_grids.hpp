// Colour and reflectance beside the level set in surface.vdb: a Vec3SGrid named "color" (8-bit
// sRGB values / 255, so 0..1) and a FloatGrid named "intensity" (the LiDAR's reflectance as the
// sensor gives it), with the level set's transform and metadata.
//
// The values come from the surface's mesh, whose vertices carry them (mapper/surface_appearance):
// each vertex lies in one cell of the voxel lattice, and every active level-set voxel at a corner
// of such a cell takes the mean of those vertices' values. The grids so hold the voxels next to
// the zero crossing (the two layers a trilinear lookup at the surface reads) and agree with the
// mesh; voxels farther out in the narrow band, and voxels next to no vertex with a known value,
// stay inactive (background 0).
#pragma once

#include <openvdb/openvdb.h>

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <vector>

namespace shine {

/// Grid names in surface.vdb.
inline constexpr char kColorGridName[] = "color";
inline constexpr char kIntensityGridName[] = "intensity";

/// The "color" grid of the mesh `vertices_map` (in the level set's frame) with colours `rgb`,
/// counting only vertices with `known` != 0 (same lengths; DataError otherwise).
openvdb::Vec3SGrid::Ptr color_grid_from_vertices(
    const openvdb::FloatGrid& level_set, const std::vector<Eigen::Vector3f>& vertices_map,
    const std::vector<std::array<std::uint8_t, 3>>& rgb, const std::vector<std::uint8_t>& known);

/// The "intensity" grid of the mesh `vertices_map` with reflectances `intensity` (NaN: unknown,
/// not counted). Throws DataError for mismatched lengths.
openvdb::FloatGrid::Ptr intensity_grid_from_vertices(
    const openvdb::FloatGrid& level_set, const std::vector<Eigen::Vector3f>& vertices_map,
    const std::vector<float>& intensity);

/// Writes the level set and `extra` grids to `path` atomically (the level set first, so readers
/// that take the first float level set find it). Throws IoError naming the file.
void write_surface_grids(const std::filesystem::path& path,
                         const openvdb::FloatGrid::Ptr& level_set,
                         const openvdb::GridPtrVec& extra);

}  // namespace shine
