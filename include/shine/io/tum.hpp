// TUM trajectory files: "timestamp tx ty tz qx qy qz qw" per line, '#' comments.
#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <vector>

namespace shine {

/// A pose with its timestamp in seconds.
struct StampedPose {
    double timestamp_s = 0.0;
    Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
};

/// Reads a TUM trajectory. Quaternions are normalised; a zero or non-finite quaternion, a wrong
/// field count or a non-number throws IoError naming the file and the line.
std::vector<StampedPose> read_tum_poses(const std::filesystem::path& path);

/// Writes a TUM trajectory atomically (full double precision, unit quaternions).
void write_tum_poses(const std::filesystem::path& path, const std::vector<StampedPose>& poses);

}  // namespace shine
