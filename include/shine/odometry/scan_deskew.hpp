// Motion compensation ("deskew") of a scan whose points were measured at different times.
//
// A spinning LiDAR measures its points over a whole sweep (0.1 s at 10 Hz) while the vehicle
// moves, so a scan read as if taken at one instant is bent: at 20 m/s the last points are 2 m
// from where the first ones would place them. With a time per point, each point is moved into
// the sensor frame at the scan's reference time, assuming the sensor moved at constant velocity.
//
// Reference time: the instant of the scan's pose (the T_world_sensor the scan is registered to
// and mapped with), which is also the origin of the per-point times: t_i = 0 at the reference,
// negative before it, positive after. Whether that instant is the start, the middle or the end
// of the sweep is the data's convention; only consistency matters (scan i's pose and times refer
// to the same instant).
//
// Velocity: with T_prev_cur the motion from the previous scan's reference pose to this one's,
// Delta seconds apart, the constant body twist is xi = log(T_prev_cur) / Delta, and the sensor at
// time t sits at T_ref_t = exp(t xi) in the reference frame (se3.hpp). A point p measured at t is
// then T_ref_t p in the reference sensor frame.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

namespace shine {

/// The points of one sweep, each moved from the sensor frame at its own time `times_s[i]`
/// (seconds relative to the reference time) into the sensor frame at the reference time,
/// assuming the constant velocity of `T_prev_cur` over `interval_s` seconds (the time between
/// the previous scan's reference and this one's). Parallel; deterministic. Throws DataError if the
/// counts differ, ConfigError if interval_s is not positive.
std::vector<Eigen::Vector3f> deskew_scan(const std::vector<Eigen::Vector3f>& points_sensor,
                                         const std::vector<double>& times_s,
                                         const Eigen::Isometry3d& T_prev_cur, double interval_s);

/// The same with the motion on either side of the reference: a point measured before it (t < 0)
/// moves at the velocity of T_prev_cur over interval_prev_s, one measured after it (t >= 0) at
/// that of T_cur_next (the motion to the next scan's pose) over interval_next_s. With given poses
/// this is the motion between the two poses around each point's time, which on a curving drive
/// is closer than one velocity for the whole sweep (docs/odometry.md). With `origins_sensor`,
/// it also receives where the sensor was at each point's time (the ray origins of the deskewed
/// points), from the same pose as its point. Throws as deskew_scan.
std::vector<Eigen::Vector3f> deskew_scan_between(
    const std::vector<Eigen::Vector3f>& points_sensor, const std::vector<double>& times_s,
    const Eigen::Isometry3d& T_prev_cur, double interval_prev_s,
    const Eigen::Isometry3d& T_cur_next, double interval_next_s,
    std::vector<Eigen::Vector3f>* origins_sensor = nullptr);

/// The sensor's pose at time `time_s` (relative to the reference) in the reference sensor frame:
/// exp((time_s / interval_s) log T_prev_cur).
Eigen::Isometry3d sensor_pose_at(const Eigen::Isometry3d& T_prev_cur, double interval_s,
                                 double time_s);

}  // namespace shine
