// The TSDF volume on disk: one .vdb file with two float grids, `tsdf` (class LEVEL_SET, world
// units) and `weight`, both on the same lattice, and file metadata with the parameters and the
// map origin:
//   shine_format          "shine_tsdf"
//   shine_voxel_size_m    double
//   shine_trunc_m         double
//   shine_space_carving   bool
//   shine_origin_world_m  vec3d: world position of the map frame (also stored on both grids)
// The grids' transform maps voxel (i, j, k) to its world-frame centre,
// origin_world_m + ((i, j, k) + 1/2) * voxel_size_m, so standard tools (vdb_print, Blender,
// Houdini) show the volume in place.
#pragma once

#include <filesystem>

#include "shine/tsdf/tsdf_volume.hpp"

namespace shine {

/// Writes `volume` to `path` atomically (temporary file + rename). Throws IoError naming the file.
void write_tsdf_volume(const std::filesystem::path& path, const TsdfVolume& volume);

/// Reads a volume written by write_tsdf_volume. Throws IoError naming the file if it is missing,
/// not a .vdb, or lacks the grids or metadata above.
TsdfVolume read_tsdf_volume(const std::filesystem::path& path);

}  // namespace shine
