// TUM trajectory files: "timestamp tx ty tz qx qy qz qw" per line, '#' comments.
#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <string_view>
#include <vector>

namespace shine {

/// A pose with its timestamp in seconds.
struct StampedPose {
    double timestamp_s = 0.0;
    Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
};

/// Reads a TUM trajectory. Quaternions are normalised; a zero quaternion, a non-finite value, a
/// wrong field count, a non-number or a comment after data throws IoError naming the file and
/// the line; an empty file or one without poses throws IoError naming the file.
std::vector<StampedPose> read_tum_poses(const std::filesystem::path& path);

/// read_tum_poses on text already in memory; `source` names it in messages.
std::vector<StampedPose> parse_tum_poses(std::string_view text,
                                         const std::filesystem::path& source);

/// Writes a TUM trajectory atomically (full double precision, unit quaternions).
void write_tum_poses(const std::filesystem::path& path, const std::vector<StampedPose>& poses);

}  // namespace shine
