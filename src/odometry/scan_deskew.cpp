// Constant-velocity deskew of a sweep into the sensor frame at its reference time.
#include "shine/odometry/scan_deskew.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "shine/core/error.hpp"
#include "shine/odometry/se3.hpp"

namespace shine {

Eigen::Isometry3d sensor_pose_at(const Eigen::Isometry3d& T_prev_cur, double interval_s,
                                 double time_s) {
    if (!(interval_s > 0.0)) {
        throw ConfigError("deskew: the interval between scans must be positive (got " +
                          std::to_string(interval_s) + " s)");
    }
    return se3_exp((time_s / interval_s) * se3_log(T_prev_cur));
}

namespace {

void check_interval(double interval_s) {
    if (!(interval_s > 0.0)) {
        throw ConfigError("deskew: the interval between scans must be positive (got " +
                          std::to_string(interval_s) + " s)");
    }
}

/// Each point moved by exp(t_i * velocity), velocity_before for t_i < 0, velocity_after else;
/// with `origins`, also the sensor's position at each point's time (the origin so moved).
std::vector<Eigen::Vector3f> move_points(const std::vector<Eigen::Vector3f>& points_sensor,
                                         const std::vector<double>& times_s,
                                         const Vector6d& velocity_before,
                                         const Vector6d& velocity_after,
                                         std::vector<Eigen::Vector3f>* origins = nullptr) {
    if (points_sensor.size() != times_s.size()) {
        throw DataError("deskew: " + std::to_string(points_sensor.size()) + " points but " +
                        std::to_string(times_s.size()) + " point times; give one time per point");
    }
    std::vector<Eigen::Vector3f> out(points_sensor.size());
    if (origins) origins->resize(points_sensor.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points_sensor.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              const Vector6d& velocity =
                                  times_s[i] < 0.0 ? velocity_before : velocity_after;
                              const Eigen::Isometry3d T_ref_t = se3_exp(times_s[i] * velocity);
                              out[i] = (T_ref_t * points_sensor[i].cast<double>()).cast<float>();
                              if (origins) {
                                  (*origins)[i] = (T_ref_t * Eigen::Vector3d::Zero()).cast<float>();
                              }
                          }
                      });
    return out;
}

}  // namespace

std::vector<Eigen::Vector3f> deskew_scan(const std::vector<Eigen::Vector3f>& points_sensor,
                                         const std::vector<double>& times_s,
                                         const Eigen::Isometry3d& T_prev_cur, double interval_s) {
    if (points_sensor.size() != times_s.size()) {
        throw DataError("deskew: " + std::to_string(points_sensor.size()) + " points but " +
                        std::to_string(times_s.size()) + " point times; give one time per point");
    }
    check_interval(interval_s);
    const Vector6d velocity = se3_log(T_prev_cur) / interval_s;  // body twist per second
    return move_points(points_sensor, times_s, velocity, velocity);
}

std::vector<Eigen::Vector3f> deskew_scan_between(const std::vector<Eigen::Vector3f>& points_sensor,
                                                 const std::vector<double>& times_s,
                                                 const Eigen::Isometry3d& T_prev_cur,
                                                 double interval_prev_s,
                                                 const Eigen::Isometry3d& T_cur_next,
                                                 double interval_next_s,
                                                 std::vector<Eigen::Vector3f>* origins_sensor) {
    check_interval(interval_prev_s);
    check_interval(interval_next_s);
    return move_points(points_sensor, times_s, se3_log(T_prev_cur) / interval_prev_s,
                       se3_log(T_cur_next) / interval_next_s, origins_sensor);
}

}  // namespace shine
