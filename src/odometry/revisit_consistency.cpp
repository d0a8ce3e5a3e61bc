// Revisits of a trajectory, registered scan to scan.
#include "shine/odometry/revisit_consistency.hpp"

#include <cmath>
#include <limits>
#include <string>

#include "shine/core/error.hpp"
#include "shine/odometry/point_to_plane_icp.hpp"
#include "shine/odometry/registration_points.hpp"
#include "shine/odometry/se3.hpp"

namespace shine {

std::vector<RevisitPair> find_revisits(const std::vector<Eigen::Isometry3d>& T_world_sensor,
                                       const std::vector<std::size_t>& sequence_number,
                                       const RevisitConfig& config) {
    if (T_world_sensor.size() != sequence_number.size()) {
        throw DataError("revisits: " + std::to_string(T_world_sensor.size()) + " poses but " +
                        std::to_string(sequence_number.size()) + " sequence numbers");
    }
    std::vector<RevisitPair> pairs;
    const std::size_t n = T_world_sensor.size();
    for (std::size_t i = 0; i < n; ++i) {
        RevisitPair best;
        best.distance_m = std::numeric_limits<double>::infinity();
        for (std::size_t j = i + 1; j < n; ++j) {
            if (sequence_number[j] < sequence_number[i] + config.min_gap_scans) continue;
            const double d =
                (T_world_sensor[j].translation() - T_world_sensor[i].translation()).norm();
            if (d <= config.max_distance_m && d < best.distance_m) best = {i, j, d};
        }
        if (std::isfinite(best.distance_m)) pairs.push_back(best);
    }
    return pairs;
}

RevisitRegistration register_revisit(const std::vector<Eigen::Vector3f>& first_sensor,
                                     const std::vector<Eigen::Vector3f>& second_sensor,
                                     const Eigen::Isometry3d& T_first_second_initial,
                                     const RevisitConfig& config) {
    RegistrationPointConfig points;
    points.min_range_m = config.min_range_m;
    points.max_range_m = config.max_range_m;
    points.voxel_size_m = config.voxel_size_m / 3.0;
    std::vector<Eigen::Vector3d> reference;
    for (const Eigen::Vector3f& p : select_registration_points(first_sensor, points)) {
        reference.push_back(p.cast<double>());
    }
    points.voxel_size_m = config.voxel_size_m;
    const std::vector<Eigen::Vector3f> scan = select_registration_points(second_sensor, points);
    RevisitRegistration out;
    out.points = scan.size();
    out.T_first_second = T_first_second_initial;
    if (reference.size() < 10 || scan.empty()) return out;
    const ReferencePlanes planes(reference, PlaneFitConfig{});

    // Coarse matches reach across a drift of a metre; the fine stage ignores what lies off the
    // surfaces both scans see.
    PointToPlaneIcpConfig icp;
    icp.max_correspondence_distance_m = 1.5;
    icp.solver.kernel.scale_m = 0.2;
    const RegistrationResult coarse =
        register_point_to_plane(scan, T_first_second_initial, planes, icp);
    if (!coarse.accepted()) return out;
    icp.max_correspondence_distance_m = 0.5;
    icp.solver.kernel.scale_m = 0.05;
    const RegistrationResult fine =
        register_point_to_plane(scan, coarse.T_world_sensor, planes, icp);
    if (!fine.accepted()) return out;
    out.T_first_second = fine.T_world_sensor;
    out.inlier_ratio = point_to_plane_inlier_ratio(scan, fine.T_world_sensor, planes, 0.5, 0.1);
    out.accepted = out.inlier_ratio >= config.min_inlier_ratio;
    return out;
}

PoseDisagreement pose_disagreement(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    const Eigen::Isometry3d d = a.inverse() * b;
    return {d.translation().norm(), rotation_angle_rad(d) * 180.0 / M_PI};
}

}  // namespace shine
