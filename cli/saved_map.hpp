// A map saved by `shine map`, as the subcommands that reuse one find it: the output folder's
// map.vdb (or the file given) and the trajectory the map was made along, from the folder.
#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "shine/geometry/pose_frame_correction.hpp"

namespace shine::cli {

/// The map.vdb of a `shine map` output folder, or `given` itself when it is a file. Throws
/// IoError naming `label` (the option or argument, e.g. "map", "--from") and `given` when it is
/// missing or a folder without map.vdb.
std::filesystem::path saved_map_file(const std::string& given, const std::string& label);

/// The trajectory the map in `map_file` was made along, from its folder: the refined poses of a
/// batch run (poses_refined.txt), else the estimated ones (poses.txt); empty when neither is
/// there. `source` is set to the file read (empty for none).
std::vector<Eigen::Isometry3d> saved_map_trajectory(const std::filesystem::path& map_file,
                                                    std::string& source);

/// With pose refinement the map was made at poses_refined.txt, and poses_given.txt beside it
/// holds the poses it started from, line by line: the correction between the two frames
/// (geometry/pose_frame_correction.hpp). std::nullopt without both files (no refinement, or a
/// map written before poses_given.txt existed); `note` then says why when the files are there
/// but unusable (unreadable, different counts).
std::optional<PoseFrameCorrection> saved_map_frame_correction(const std::filesystem::path& map_file,
                                                              std::string& note);

}  // namespace shine::cli
