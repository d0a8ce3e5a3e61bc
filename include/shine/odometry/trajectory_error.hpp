// How far an estimated trajectory is from a reference one: the absolute trajectory error after a
// rigid (or similarity) alignment, and the KITTI odometry benchmark's relative error.
//
// Alignment (Umeyama 1991, "Least-squares estimation of transformation parameters between two
// point patterns", IEEE TPAMI 13(4), Eqs. (40)-(42)): the rotation R, translation t and, for
// Sim(3), scale s minimising sum_i |ref_i - (s R est_i + t)|^2 over the positions. Computed by
// Eigen::umeyama, which implements that paper.
//
// Absolute trajectory error (Sturm et al. 2012, "A benchmark for the evaluation of RGB-D SLAM
// systems", Sec. VI-B): the translation residuals |ref_i - (s R est_i + t)| after alignment;
// reported as RMSE, mean, median and maximum.
//
// Relative error (Geiger et al. 2012, "Are we ready for autonomous driving?", CVPR, Sec. 3.2;
// the KITTI odometry devkit's evaluate_odometry.cpp): from every `step_frames`-th first frame i
// and for each segment length L, the first frame j whose distance along the REFERENCE path
// exceeds that of i by more than L; the error of the relative motion is
//   E = (est_i^-1 est_j)^-1 (ref_i^-1 ref_j),
// its translation |t_E| / L and rotation angle(E) / L. Averaged over all (i, L) pairs, reported
// as translation in percent and rotation in degrees per 100 m. KITTI's lengths are 100, 200, ...,
// 800 m; a trajectory shorter than 100 m has none of them, so it is scored on 10 %, 20 %, ...,
// 80 % of its own length instead (RelativePoseError::kitti_lengths tells which).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace shine {

/// Which transformation aligns the estimate to the reference before the absolute error.
enum class TrajectoryAlignment : std::uint8_t {
    kNone,  ///< compare as given (same world frame)
    kSe3,   ///< rotation and translation
    kSim3   ///< rotation, translation and scale (monocular-style estimates)
};

/// "none" / "se3" / "sim3".
const char* to_string(TrajectoryAlignment alignment);
/// Parses "none" / "se3" / "sim3"; throws ConfigError naming `key` otherwise.
TrajectoryAlignment parse_trajectory_alignment(const std::string& text, const std::string& key);

/// x -> scale * R x + t.
struct SimilarityTransform {
    Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
    double scale = 1.0;

    Eigen::Vector3d apply(const Eigen::Vector3d& x) const { return scale * (R * x) + t; }
};

/// The transform minimising sum |target_i - T(source_i)|^2 (Umeyama 1991), with the scale fixed
/// at 1 unless `with_scale`. Throws DataError if the counts differ or there are fewer than 3
/// points, and DataError if the source points all coincide (nothing to align).
SimilarityTransform umeyama_alignment(const std::vector<Eigen::Vector3d>& source,
                                      const std::vector<Eigen::Vector3d>& target, bool with_scale);

/// Translation errors after alignment, metres.
struct AbsoluteTrajectoryError {
    std::size_t num_poses = 0;
    double rmse_m = 0.0;
    double mean_m = 0.0;
    double median_m = 0.0;
    double max_m = 0.0;
    TrajectoryAlignment alignment = TrajectoryAlignment::kSe3;
    SimilarityTransform estimate_to_reference;  ///< applied to the estimate's positions
};

/// The absolute trajectory error of `estimate` against `reference` (pose i of one paired with
/// pose i of the other). Throws DataError if the counts differ or there are fewer than 3 poses.
AbsoluteTrajectoryError absolute_trajectory_error(const std::vector<Eigen::Isometry3d>& estimate,
                                                  const std::vector<Eigen::Isometry3d>& reference,
                                                  TrajectoryAlignment alignment);

/// Settings of the relative error.
struct RelativePoseErrorConfig {
    /// Segment lengths along the reference path, m (the KITTI benchmark's).
    std::vector<double> lengths_m = {100, 200, 300, 400, 500, 600, 700, 800};
    /// Every step_frames-th frame starts segments (the devkit's step_size = 10).
    int step_frames = 10;
    /// Used instead of lengths_m when none of them is shorter than the trajectory: these
    /// fractions of the reference path's length.
    std::vector<double> short_fractions = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8};
};

/// The errors of the segments of one length.
struct RelativeErrorOfLength {
    double length_m = 0.0;
    std::size_t num_segments = 0;        ///< 0: no segment this long fits
    double translation_percent = 0.0;    ///< mean |t_E| / L, %
    double rotation_deg_per_100m = 0.0;  ///< mean angle(E) / L, deg / 100 m
};

/// The KITTI-style relative error, per length and averaged over all segments.
struct RelativePoseError {
    double path_length_m = 0.0;  ///< length of the reference path
    bool kitti_lengths = true;   ///< false: the short-sequence fractions were used
    std::vector<RelativeErrorOfLength> per_length;
    std::size_t num_segments = 0;        ///< over all lengths
    double translation_percent = 0.0;    ///< mean over all segments (the devkit's average)
    double rotation_deg_per_100m = 0.0;  ///< mean over all segments
};

/// The relative error of `estimate` against `reference` (paired by index). Throws DataError if
/// the counts differ or there are fewer than 3 poses, ConfigError for step_frames < 1 or a
/// non-positive length, DataError if the reference does not move (path length 0).
RelativePoseError relative_pose_error(const std::vector<Eigen::Isometry3d>& estimate,
                                      const std::vector<Eigen::Isometry3d>& reference,
                                      const RelativePoseErrorConfig& config = {});

}  // namespace shine
