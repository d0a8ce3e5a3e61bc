// Deskewing the scans of a sequence while mapping (`shine map --deskew`, docs/odometry.md): which
// scans are deskewed, with which motion, over which interval.
//
// A scan whose points carry times (Scan::point_time_s, seconds relative to the scan's pose;
// io/point_times.hpp) is moved into the sensor frame at its pose's instant by
// odometry/scan_deskew.hpp, at constant velocity between consecutive poses:
//   - given poses: a point measured after the scan's pose (t >= 0) at the velocity of the motion
//     to the next scan's pose, pose(i)^-1 pose(i+1); one measured before it (t < 0) at that of the
//     motion from the previous one, pose(i-1)^-1 pose(i) (deskew_scan_between). The first scan
//     has only the motion to the next, the last only the motion from the previous, for all its
//     points; a sequence of one scan is left as it is. On the simulated street (a weaving,
//     pitching drive) this leaves points within 1.2 cm of the walls where the previous motion
//     alone leaves 11 cm (tests/test_deskew_simulated_sweep.cpp);
//   - estimated poses: for registration, the last estimated motion (the constant-velocity
//     prediction's; the first two scans are registered as measured), then for mapping the motion
//     to the estimated pose (the first scan is mapped as measured: no motion is known yet).
// Interval: the scans' stamps when the sequence has them (recordings), else scan_period_s times
// the number of frames between them (frame_step and held-out scans counted).
//
// Modes: `on` (--deskew) deskews every scan and stops at the first scan without times, naming
// it; `auto` (the default) deskews with estimated poses when the scans carry times, and with any
// poses when the scans' times come from their azimuths (scans without a time field of a sequence
// the sweep test judged skewed: io/sweep_times.hpp, mapper/sweep_test.hpp); with given poses
// and times from the files it leaves the scans as measured, as before deskewing existed; `off`
// never deskews.
//
// Times from the azimuth (deskew.azimuth_times): `auto` (the default) lets the sweep test decide
// whether a sequence of scans without time fields is skewed and which way its beams turn, where
// given poses are refined (`shine map` applies it there only: batch mode, and incremental mode,
// whose consolidation refines; at given poses, fitted by an odometry to the skewed scans,
// deskewing lost 0.7-0.8 points of held-out rays on the real KITTI-360 drive, with refined poses
// it gained 0.8-0.9 in either mode; docs/field.md); `on` times them with
// deskew.sweep_direction / sweep_start_deg / pose_azimuth_deg as configured, in every mode;
// `off` never.
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <string>

#include "shine/io/point_times.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/io/sweep_times.hpp"

namespace shine {

/// When scans are deskewed (file comment).
enum class DeskewMode : std::uint8_t { kAuto, kOn, kOff };

/// "auto" / "on" / "off".
const char* to_string(DeskewMode mode);

/// Settings of deskewing (YAML section `deskew:`).
struct DeskewConfig {
    DeskewMode mode = DeskewMode::kAuto;
    /// Seconds between consecutive scans of a sequence without stamps (files): 0.1 s, 10 Hz;
    /// also the sweep period of times from the azimuth.
    double scan_period_s = 0.1;
    /// Scans without a time field timed from their azimuths (file comment): auto (the default),
    /// on or off.
    DeskewMode azimuth_times = DeskewMode::kAuto;
    /// The sweep of azimuth_times on (its period is scan_period_s); with auto, the sweep test
    /// keeps the start and pose azimuths and chooses the direction.
    SweepTimeModel sweep;
};

/// What deskewing did in one run (stats.json "deskew").
struct DeskewStats {
    bool active = false;                ///< the run deskews (mode on, or auto with estimated poses)
    std::size_t scans_deskewed = 0;     ///< scans mapped deskewed
    std::size_t scans_as_measured = 0;  ///< scans mapped as measured (no times, or no motion yet)
    PointTimeFormat time_format;        ///< of the first scan with times
    double max_shift_m = 0.0;           ///< the largest distance a point was moved
};

/// Whether the run deskews: mode on, or auto with estimated poses or with times from the azimuth
/// (`sweep_times`: the sequence's ScanSequence::has_sweep_times()).
bool deskew_active(const DeskewConfig& config, bool estimate_poses, bool sweep_times = false);

/// Throws DataError naming scan.source (and the fix) if the scan carries no per-point times.
void require_point_times(const Scan& scan);

/// Seconds between the reference times of scans `a` and `b` (a < b) of `sequence` (file comment);
/// throws DataError naming both scans if it is not positive.
double scan_interval_s(const ScanSequence& sequence, std::size_t a, std::size_t b,
                       double scan_period_s);

/// Moves scan.points_sensor into the sensor frame at the scan's pose, points before it (t < 0) at
/// the velocity of T_prev_cur over interval_prev_s, the others at that of T_cur_next over
/// interval_next_s (odometry/scan_deskew.hpp), and counts it in `stats`; the times are kept.
/// scan.point_origin_sensor becomes the sensor's position at each point's time in that frame
/// (the rays' origins for training). Returns the largest distance a point moved.
double deskew_in_place(Scan& scan, const Eigen::Isometry3d& T_prev_cur, double interval_prev_s,
                       const Eigen::Isometry3d& T_cur_next, double interval_next_s,
                       DeskewStats& stats);

/// deskew_in_place with one motion for the whole sweep.
double deskew_in_place(Scan& scan, const Eigen::Isometry3d& T_prev_cur, double interval_s,
                       DeskewStats& stats);

/// Deskews scan `i` of `sequence` with the sequence's own poses (given poses, file comment), or
/// counts it as measured when it has no times or the sequence a single scan. With config.mode on,
/// a scan without times is a DataError (require_point_times).
void deskew_with_sequence_poses(Scan& scan, const ScanSequence& sequence, std::size_t i,
                                const DeskewConfig& config, DeskewStats& stats);

}  // namespace shine
