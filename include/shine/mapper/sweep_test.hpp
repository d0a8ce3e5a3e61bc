// Is a sequence of scans without time fields skewed by the sensor's motion, and which way do its
// beams turn? The sweep test judges it from the data, so that real spinning-LiDAR drives
// (KITTI, KITTI-360) are deskewed by default while instantaneous scans (simulated, or already
// deskewed by the recording's driver) are left as they are.
//
// A skewed sweep is not a rigid copy of the scene: each point sits where the sensor was at its
// own time, so two scans of a drive see one surface bent by different amounts (their azimuths to
// it differ) and no rigid pose aligns them well. For a few pairs of scans (i, i + gap) spread
// over the sequence, each hypothesis -- as measured, or timed from the azimuth turning
// clockwise, or counter-clockwise (io/sweep_times.hpp) and deskewed at constant velocity between
// the poses around each scan (odometry/scan_deskew.hpp) -- is scored by point-to-plane ICP of
// scan i + gap onto scan i: the share of its points within inlier_m of the other's planes after
// the alignment. A deskewing hypothesis wins when its share beats the as-measured one by at least
// min_gain (absolute) and the two directions differ by at least min_asymmetry; the better
// direction wins between the two.
//
// The poses around a scan are the sequence's (given) or, without poses, the ICP of each raw scan
// onto the one before (a plain odometry good to centimetres over one scan, enough for the
// motion during a sweep).
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "shine/io/scan_sequence.hpp"
#include "shine/io/sweep_times.hpp"
#include "shine/mapper/sequence_deskew.hpp"

namespace shine {

/// How the sweep test samples and scores (file comment).
struct SweepTestConfig {
    std::size_t pairs = 4;      ///< scan pairs tested, spread over the sequence
    std::size_t gap = 4;        ///< scan j = i + gap is aligned onto scan i
    double voxel_size_m = 0.3;  ///< the scans are thinned to one point per voxel
    double min_range_m = 2.0;   ///< closer points are not used (the vehicle)
    double max_range_m = 50.0;  ///< farther points are not used
    double inlier_m = 0.03;     ///< a point within this of the other scan's planes is an inlier
    double min_gain = 0.005;    ///< a deskewing hypothesis must beat as-measured by this share
    /// ... and the two directions must differ by this share: an instantaneous scan deskewed
    /// either way is bent alike, a skewed one is straightened one way and bent twice the other.
    double min_asymmetry = 0.01;
    double min_sweep_motion_m = 0.02;  ///< slower sequences are not tested (nothing to deskew)
};

/// What the sweep test found.
struct SweepTestResult {
    bool tested = false;  ///< false: too few scans, scans with times, or too little motion
    bool skewed = false;  ///< a deskewing hypothesis won
    SweepDirection direction = SweepDirection::kClockwise;  ///< the winner's (when skewed)
    std::size_t pairs = 0;                                  ///< pairs scored
    /// Mean inlier share over the pairs: as measured, clockwise, counter-clockwise.
    double inliers_as_measured = 0.0;
    double inliers_clockwise = 0.0;
    double inliers_counterclockwise = 0.0;
    double sweep_motion_m = 0.0;  ///< median distance the sensor moves in one sweep
    double seconds = 0.0;
    std::string reason;  ///< one line: why the test decided as it did
};

/// Runs the sweep test on `sequence` with `model`'s start and pose azimuths and period (its
/// direction is what is tested). Throws what loading a scan throws.
SweepTestResult run_sweep_test(const ScanSequence& sequence, const SweepTimeModel& model,
                               const SweepTestConfig& config = {});

/// Whether a run times `sequence`'s scans from the azimuth (sequence_with_sweep_times): always
/// unless config.azimuth_times is auto, and under auto only where it was measured to win, given
/// poses that the run refines (`refining`: batch mode's refinement, or incremental mode's
/// consolidation) and does not estimate. The refinement registers the deskewed scans; at given
/// poses, fitted to the skewed scans, deskewing lost points on the real drive, and with estimated
/// poses it lost 0.3-0.9 points (docs/field.md).
bool sweep_times_apply(const DeskewConfig& config, bool refining, bool estimate_poses,
                       const ScanSequence& sequence);

/// `sequence` timed from the azimuth as config.azimuth_times says (on: config.sweep; auto: the
/// sweep test's verdict, with config.sweep's start and pose azimuths; off: unchanged). A sequence
/// whose scans carry times of their own is returned unchanged. `result` (optional) receives the
/// test's outcome (tested false when no test ran).
ScanSequence sequence_with_sweep_times(const ScanSequence& sequence, const DeskewConfig& config,
                                       SweepTestResult* result = nullptr);

}  // namespace shine
