// Per-point times of a spinning LiDAR's sweep, inferred from each point's azimuth, for scans
// stored without a time field (KITTI .bin, KITTI-360, most .bin / PCD / PLY folders, Livox
// without per-point time). Deskewing (odometry/scan_deskew.hpp) needs a time per point; a
// spinning LiDAR measures its points in azimuth order at a nearly constant turn rate, so the
// azimuth gives the time:
//
//     phase(p) = s * (azimuth_start - azimuth(p))  mod 360 deg,  s = +1 clockwise, -1 counter-
//     t(p)     = (phase(p) - phase(pose)) / 360 deg * sweep_period_s
//
// azimuth = atan2(y, x) in the sensor frame (x forward, y left, z up: the spin axis), clockwise
// as seen from above. t is relative to the instant of the scan's pose, as every per-point time
// is (point_times.hpp), so phase(pose) is the phase of the azimuth the sensor faced then.
//
// The defaults are the spinning LiDARs' common case: Velodyne, Ouster and Hesai sensors turn
// clockwise; KITTI and KITTI-360 (HDL-64E) cut the sweep behind the car and take the scan's
// timestamp (the camera trigger) when the beams face forward, mid-sweep. A pose estimated by
// registering the skewed scan also belongs to about mid-sweep. The order in which a file stores
// the points is no evidence: KITTI's .bin files hold each ring counter-clockwise from the front.
// Whether a sequence is skewed at all, and which way it turns, is judged from the data by
// mapper/sweep_test.hpp: simulated scans are instantaneous.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace shine {

/// The way the beams turn, as seen from above (from the sensor's +z).
enum class SweepDirection : std::uint8_t { kClockwise, kCounterClockwise };

/// "clockwise" / "counterclockwise".
const char* to_string(SweepDirection direction);
/// Parses "clockwise" / "counterclockwise" (also "cw" / "ccw"); throws ConfigError naming `key`.
SweepDirection parse_sweep_direction(const std::string& text, const std::string& key);

/// How a spinning LiDAR's sweep maps azimuth to time (file comment).
struct SweepTimeModel {
    SweepDirection direction = SweepDirection::kClockwise;
    /// Where each sweep starts (the cut), degrees of azimuth: 180 = behind the sensor.
    double start_azimuth_deg = 180.0;
    /// The azimuth the beams face at the instant of the scan's pose: 0 = forward (mid-sweep for
    /// a sweep cut at the back).
    double pose_azimuth_deg = 0.0;
    /// Seconds of one turn: 0.1 s at 10 Hz.
    double sweep_period_s = 0.1;

    /// "clockwise from 180 deg, pose at 0 deg, 0.1 s" -- for logs and stats.json.
    std::string describe() const;
};

/// Seconds relative to the scan's pose of each point (file comment); NaN for a non-finite point,
/// 0 for one on the spin axis. Throws ConfigError for a period that is not
/// positive and finite or azimuths that are not finite.
std::vector<double> sweep_point_times_s(const std::vector<Eigen::Vector3f>& points_sensor,
                                        const SweepTimeModel& model);

}  // namespace shine
