// Absolute (after Umeyama alignment) and KITTI-style relative trajectory errors.
#include "shine/odometry/trajectory_error.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "shine/core/error.hpp"
#include "shine/odometry/se3.hpp"

namespace shine {

namespace trajectory_error_internal {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

void check_pair(std::size_t estimate, std::size_t reference) {
    if (estimate != reference) {
        throw DataError("trajectory error: the estimate has " + std::to_string(estimate) +
                        " poses and the reference " + std::to_string(reference) +
                        "; they are compared pose by pose, so pair them first (same count)");
    }
    if (estimate < 3) {
        throw DataError("trajectory error: " + std::to_string(estimate) +
                        " poses; at least 3 are needed");
    }
}

/// Cumulative distance along the positions: the devkit's trajectoryDistances.
std::vector<double> path_distances(const std::vector<Eigen::Isometry3d>& poses) {
    std::vector<double> d(poses.size(), 0.0);
    for (std::size_t i = 1; i < poses.size(); ++i) {
        d[i] = d[i - 1] + (poses[i].translation() - poses[i - 1].translation()).norm();
    }
    return d;
}

/// First frame j > i whose distance exceeds distance[i] + length: the devkit's
/// lastFrameFromSegmentLength; -1 when the path ends first.
long last_frame_of_segment(const std::vector<double>& distance, std::size_t first,
                           double length_m) {
    for (std::size_t j = first; j < distance.size(); ++j) {
        if (distance[j] > distance[first] + length_m) return long(j);
    }
    return -1;
}

}  // namespace
}  // namespace trajectory_error_internal

const char* to_string(TrajectoryAlignment alignment) {
    switch (alignment) {
        case TrajectoryAlignment::kNone:
            return "none";
        case TrajectoryAlignment::kSe3:
            return "se3";
        case TrajectoryAlignment::kSim3:
            return "sim3";
    }
    return "?";
}

TrajectoryAlignment parse_trajectory_alignment(const std::string& text, const std::string& key) {
    if (text == "none") return TrajectoryAlignment::kNone;
    if (text == "se3") return TrajectoryAlignment::kSe3;
    if (text == "sim3") return TrajectoryAlignment::kSim3;
    throw ConfigError(key + " '" + text + "' is not an alignment: use se3, sim3 or none");
}

SimilarityTransform umeyama_alignment(const std::vector<Eigen::Vector3d>& source,
                                      const std::vector<Eigen::Vector3d>& target, bool with_scale) {
    trajectory_error_internal::check_pair(source.size(), target.size());
    const Eigen::Index n = Eigen::Index(source.size());
    Eigen::Matrix3Xd src(3, n), dst(3, n);
    for (Eigen::Index i = 0; i < n; ++i) {
        src.col(i) = source[std::size_t(i)];
        dst.col(i) = target[std::size_t(i)];
    }
    const Eigen::Vector3d mean = src.rowwise().mean();
    if ((src.colwise() - mean).squaredNorm() <= 0.0) {
        throw DataError("trajectory alignment: all " + std::to_string(n) +
                        " estimated positions coincide; nothing to align (use --align none)");
    }
    const Eigen::Matrix4d T = Eigen::umeyama(src, dst, with_scale);
    SimilarityTransform out;
    const Eigen::Matrix3d sR = T.topLeftCorner<3, 3>();
    out.scale = with_scale ? std::cbrt(sR.determinant()) : 1.0;
    out.R = sR / out.scale;
    out.t = T.topRightCorner<3, 1>();
    return out;
}

AbsoluteTrajectoryError absolute_trajectory_error(const std::vector<Eigen::Isometry3d>& estimate,
                                                  const std::vector<Eigen::Isometry3d>& reference,
                                                  TrajectoryAlignment alignment) {
    trajectory_error_internal::check_pair(estimate.size(), reference.size());
    std::vector<Eigen::Vector3d> est(estimate.size()), ref(reference.size());
    for (std::size_t i = 0; i < estimate.size(); ++i) {
        est[i] = estimate[i].translation();
        ref[i] = reference[i].translation();
    }
    AbsoluteTrajectoryError out;
    out.alignment = alignment;
    out.num_poses = est.size();
    if (alignment != TrajectoryAlignment::kNone) {
        out.estimate_to_reference =
            umeyama_alignment(est, ref, alignment == TrajectoryAlignment::kSim3);
    }
    std::vector<double> errors(est.size());
    double sum = 0.0, sum_sq = 0.0;
    for (std::size_t i = 0; i < est.size(); ++i) {
        errors[i] = (ref[i] - out.estimate_to_reference.apply(est[i])).norm();
        sum += errors[i];
        sum_sq += errors[i] * errors[i];
        out.max_m = std::max(out.max_m, errors[i]);
    }
    const double n = double(errors.size());
    out.mean_m = sum / n;
    out.rmse_m = std::sqrt(sum_sq / n);
    std::sort(errors.begin(), errors.end());
    const std::size_t mid = errors.size() / 2;
    out.median_m = errors.size() % 2 ? errors[mid] : 0.5 * (errors[mid - 1] + errors[mid]);
    return out;
}

RelativePoseError relative_pose_error(const std::vector<Eigen::Isometry3d>& estimate,
                                      const std::vector<Eigen::Isometry3d>& reference,
                                      const RelativePoseErrorConfig& config) {
    using namespace trajectory_error_internal;
    check_pair(estimate.size(), reference.size());
    if (config.step_frames < 1) {
        throw ConfigError("relative error step_frames must be at least 1 (got " +
                          std::to_string(config.step_frames) + ")");
    }
    for (const double l : config.lengths_m) {
        if (!(l > 0.0)) throw ConfigError("relative error segment lengths must be positive");
    }
    for (const double f : config.short_fractions) {
        if (!(f > 0.0 && f < 1.0)) {
            throw ConfigError("relative error short_fractions must be in (0, 1)");
        }
    }
    const std::vector<double> distance = path_distances(reference);
    RelativePoseError out;
    out.path_length_m = distance.back();
    if (!(out.path_length_m > 0.0)) {
        throw DataError(
            "relative error: the reference trajectory does not move (path length 0 "
            "m), so no segment has a length");
    }
    std::vector<double> lengths;
    for (const double l : config.lengths_m) {
        if (l < out.path_length_m) lengths.push_back(l);
    }
    if (lengths.empty()) {
        out.kitti_lengths = false;
        for (const double f : config.short_fractions) lengths.push_back(f * out.path_length_m);
    }

    double sum_t = 0.0, sum_r = 0.0;
    for (const double length : lengths) {
        RelativeErrorOfLength row;
        row.length_m = length;
        double row_t = 0.0, row_r = 0.0;
        for (std::size_t first = 0; first < reference.size(); first += config.step_frames) {
            const long last = last_frame_of_segment(distance, first, length);
            if (last < 0) continue;
            const Eigen::Isometry3d delta_ref = reference[first].inverse() * reference[last];
            const Eigen::Isometry3d delta_est = estimate[first].inverse() * estimate[last];
            const Eigen::Isometry3d E = delta_est.inverse() * delta_ref;
            row_t += E.translation().norm() / length;
            row_r += rotation_angle_rad(E) / length;
            ++row.num_segments;
        }
        if (row.num_segments > 0) {
            row.translation_percent = 100.0 * row_t / double(row.num_segments);
            row.rotation_deg_per_100m = 100.0 * kRadToDeg * row_r / double(row.num_segments);
        }
        sum_t += row_t;
        sum_r += row_r;
        out.num_segments += row.num_segments;
        out.per_length.push_back(row);
    }
    if (out.num_segments > 0) {
        out.translation_percent = 100.0 * sum_t / double(out.num_segments);
        out.rotation_deg_per_100m = 100.0 * kRadToDeg * sum_r / double(out.num_segments);
    }
    return out;
}

}  // namespace shine
