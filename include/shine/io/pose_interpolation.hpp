// Poses matched to scans by time: a TUM trajectory sampled at a scan's stamp.
//
// Between two poses the translation is interpolated linearly and the rotation by slerp
// (Eigen::Quaterniond::slerp, shortest arc). A stamp within kPoseStampToleranceS of a pose's time
// takes that pose exactly (no arithmetic), so scans recorded at the pose times get bit-identical
// poses. A stamp outside the trajectory's time span (beyond the same tolerance) is a DataError:
// extrapolating a trajectory silently would bend the map.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "shine/io/tum.hpp"

namespace shine {

/// Stamps this close to a pose's time (1 microsecond) take that pose exactly.
constexpr double kPoseStampToleranceS = 1e-6;

/// Throws DataError naming `source` unless the poses' timestamps strictly increase.
void check_pose_times(const std::vector<StampedPose>& poses, const std::string& source);

/// T_world_sensor at `stamp_s` from `poses` (times strictly increasing, check_pose_times). Throws
/// DataError naming `source`, the stamp and the trajectory's span when the stamp is outside it.
Eigen::Isometry3d interpolate_pose(const std::vector<StampedPose>& poses, double stamp_s,
                                   const std::string& source);

}  // namespace shine
