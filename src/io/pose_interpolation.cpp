// Poses matched to scans by time (linear translation, slerp rotation).
#include "shine/io/pose_interpolation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "shine/core/error.hpp"

namespace shine {

namespace pose_interpolation_internal {
namespace {

std::string seconds(double t) {
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%.6f s", t);  // microseconds: the matching tolerance
    return buf;
}

}  // namespace
}  // namespace pose_interpolation_internal

void check_pose_times(const std::vector<StampedPose>& poses, const std::string& source) {
    using pose_interpolation_internal::seconds;
    for (std::size_t i = 1; i < poses.size(); ++i) {
        if (!(poses[i].timestamp_s > poses[i - 1].timestamp_s)) {
            throw DataError("pose file '" + source + "': pose " + std::to_string(i + 1) +
                            " has time " + seconds(poses[i].timestamp_s) +
                            ", not after the previous pose's " + seconds(poses[i - 1].timestamp_s) +
                            ": poses matched by time must be sorted with distinct timestamps");
        }
    }
}

Eigen::Isometry3d interpolate_pose(const std::vector<StampedPose>& poses, double stamp_s,
                                   const std::string& source) {
    using pose_interpolation_internal::seconds;
    if (poses.empty()) throw DataError("pose file '" + source + "' has no poses");
    const double first = poses.front().timestamp_s;
    const double last = poses.back().timestamp_s;
    if (!(stamp_s >= first - kPoseStampToleranceS && stamp_s <= last + kPoseStampToleranceS)) {
        throw DataError("the scan stamped " + seconds(stamp_s) +
                        " lies outside the time span of pose file '" + source + "' (" +
                        seconds(first) + " to " + seconds(last) +
                        "): give a trajectory that covers every scan, or select the covered "
                        "scans with --first-frame / --last-frame");
    }
    // First pose with time >= stamp - tolerance.
    const auto it =
        std::lower_bound(poses.begin(), poses.end(), stamp_s - kPoseStampToleranceS,
                         [](const StampedPose& p, double t) { return p.timestamp_s < t; });
    if (it != poses.end() && std::abs(it->timestamp_s - stamp_s) <= kPoseStampToleranceS) {
        return it->T_world_sensor;
    }
    if (it == poses.begin() || it == poses.end()) {
        return (it == poses.end() ? poses.back() : poses.front()).T_world_sensor;
    }
    const StampedPose& a = *(it - 1);
    const StampedPose& b = *it;
    const double s = (stamp_s - a.timestamp_s) / (b.timestamp_s - a.timestamp_s);
    const Eigen::Quaterniond qa(a.T_world_sensor.rotation());
    const Eigen::Quaterniond qb(b.T_world_sensor.rotation());
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = qa.slerp(s, qb).normalized().toRotationMatrix();
    T.translation() =
        (1.0 - s) * a.T_world_sensor.translation() + s * b.T_world_sensor.translation();
    return T;
}

}  // namespace shine
