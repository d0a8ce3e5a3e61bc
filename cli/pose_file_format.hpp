// Which of the two pose file formats the subcommands read a file is in: KITTI (a row-major 3x4
// [R|t] a line, 12 numbers) or TUM (time tx ty tz qx qy qz qw, 8 numbers), told by the first line
// with data ('#' lines are comments).
#pragma once

#include <string>

namespace shine::cli {

enum class PoseFileFormat { kKitti, kTum };

/// "kitti" / "tum".
const char* to_string(PoseFileFormat format);

/// The format of the pose file `path` from its first line with data. Throws IoError naming `what`
/// and `path` when the file cannot be read, holds no pose, or its first pose line has another
/// number of fields (the message then ends with `hint`).
PoseFileFormat detect_pose_file_format(const std::string& path, const std::string& what,
                                       const std::string& hint = "");

}  // namespace shine::cli
