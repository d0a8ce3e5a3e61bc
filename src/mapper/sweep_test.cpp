// The sweep test: is a sequence skewed, and which way do its beams turn?
#include "shine/mapper/sweep_test.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>

#include "shine/core/median.hpp"
#include "shine/odometry/point_to_plane_icp.hpp"
#include "shine/odometry/registration_points.hpp"
#include "shine/odometry/scan_deskew.hpp"

namespace shine {

namespace {

/// The three hypotheses, in the order of SweepTestResult's shares.
enum Hypothesis { kAsMeasured = 0, kClockwise = 1, kCounterClockwise = 2 };

std::vector<Eigen::Vector3d> to_double(const std::vector<Eigen::Vector3f>& points) {
    std::vector<Eigen::Vector3d> out(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) out[i] = points[i].cast<double>();
    return out;
}

/// Loads, thins and caches the scans the test uses, and the motion between neighbours.
class SweepTestScans {
  public:
    SweepTestScans(const ScanSequence& sequence, const SweepTimeModel& model,
                   const SweepTestConfig& config)
        : sequence_(sequence), model_(model), config_(config) {}

    /// Scan a thinned, as measured (sensor frame).
    const std::vector<Eigen::Vector3f>& points(std::size_t a) {
        auto it = points_.find(a);
        if (it != points_.end()) return it->second;
        RegistrationPointConfig thin;
        thin.min_range_m = config_.min_range_m;
        thin.max_range_m = config_.max_range_m;
        thin.voxel_size_m = config_.voxel_size_m;
        return points_[a] = select_registration_points(sequence_.load(a).points_sensor, thin);
    }

    /// T_a_b: the motion from scan a's pose to scan b's (b = a + 1 without poses).
    Eigen::Isometry3d motion(std::size_t a, std::size_t b) {
        if (sequence_.has_poses()) return sequence_.pose(a).inverse() * sequence_.pose(b);
        const auto key = std::make_pair(a, b);
        auto it = motions_.find(key);
        if (it != motions_.end()) return it->second;
        // The raw scan b registered onto raw scan a, from the motion before when known.
        Eigen::Isometry3d initial = Eigen::Isometry3d::Identity();
        const auto before = motions_.find(std::make_pair(a - 1, a));
        if (a > 0 && before != motions_.end()) initial = before->second;
        // Coarse to fine: the car may have moved a metre or more since the scan before.
        const ReferencePlanes reference(to_double(points(a)), PlaneFitConfig{});
        Eigen::Isometry3d T = initial;
        for (const double correspondence_m : {4.0, 1.0}) {
            PointToPlaneIcpConfig icp;
            icp.max_correspondence_distance_m = correspondence_m;
            icp.solver.kernel.type = RobustKernelType::kGemanMcClure;
            icp.solver.kernel.scale_m = correspondence_m / 4.0;
            icp.solver.max_iterations = 50;
            const RegistrationResult result = register_point_to_plane(points(b), T, reference, icp);
            if (result.accepted()) T = result.T_world_sensor;
        }
        return motions_[key] = T;
    }

    double interval_s(std::size_t a, std::size_t b) const {
        return scan_interval_s(sequence_, a, b, model_.sweep_period_s);
    }

    /// Scan a under hypothesis h, deskewed with the motion around it.
    std::vector<Eigen::Vector3f> under(std::size_t a, Hypothesis h) {
        const std::vector<Eigen::Vector3f>& raw = points(a);
        if (h == kAsMeasured) return raw;
        SweepTimeModel timed = model_;
        timed.direction =
            h == kClockwise ? SweepDirection::kClockwise : SweepDirection::kCounterClockwise;
        const std::vector<double> times_s = sweep_point_times_s(raw, timed);
        const std::size_t n = sequence_.size();
        const std::size_t p = a > 0 ? a - 1 : a;
        const std::size_t q = a + 1 < n ? a + 1 : a;
        const Eigen::Isometry3d before = a > 0 ? motion(p, a) : motion(a, q);
        const double before_s = a > 0 ? interval_s(p, a) : interval_s(a, q);
        const Eigen::Isometry3d after = a + 1 < n ? motion(a, q) : before;
        const double after_s = a + 1 < n ? interval_s(a, q) : before_s;
        return deskew_scan_between(raw, times_s, before, before_s, after, after_s);
    }

  private:
    const ScanSequence& sequence_;
    SweepTimeModel model_;
    SweepTestConfig config_;
    std::map<std::size_t, std::vector<Eigen::Vector3f>> points_;
    std::map<std::pair<std::size_t, std::size_t>, Eigen::Isometry3d> motions_;
};

}  // namespace

SweepTestResult run_sweep_test(const ScanSequence& sequence, const SweepTimeModel& model,
                               const SweepTestConfig& config) {
    const auto start = std::chrono::steady_clock::now();
    SweepTestResult result;
    const std::size_t n = sequence.size();
    if (n < config.gap + 3) {
        result.reason = "too few scans to test (" + std::to_string(n) + ")";
        return result;
    }
    if (!sequence.load(0).point_time_s.empty()) {
        result.reason = "the scans carry times of their own";
        return result;
    }
    SweepTestScans scans(sequence, model, config);
    // Pairs (i, i + gap) with a neighbour on either side of both scans.
    const std::size_t last_first = n - 2 - config.gap;
    const std::size_t pairs = std::max<std::size_t>(1, std::min(config.pairs, last_first));
    std::vector<double> sweep_motion_m;
    std::array<double, 3> share_sum{0.0, 0.0, 0.0};
    for (std::size_t k = 0; k < pairs; ++k) {
        const std::size_t i = 1 + (pairs == 1 ? 0 : k * (last_first - 1) / (pairs - 1));
        const std::size_t j = i + config.gap;
        sweep_motion_m.push_back(scans.motion(i, i + 1).translation().norm() *
                                 model.sweep_period_s / scans.interval_s(i, i + 1));
        Eigen::Isometry3d T_i_j = Eigen::Isometry3d::Identity();
        for (std::size_t a = i; a < j; ++a) T_i_j = T_i_j * scans.motion(a, a + 1);
        for (const Hypothesis h : {kAsMeasured, kClockwise, kCounterClockwise}) {
            const ReferencePlanes reference(to_double(scans.under(i, h)), PlaneFitConfig{});
            const std::vector<Eigen::Vector3f> moved = scans.under(j, h);
            PointToPlaneIcpConfig icp;
            const RegistrationResult aligned =
                register_point_to_plane(moved, T_i_j, reference, icp);
            share_sum[h] +=
                point_to_plane_inlier_ratio(moved, aligned.T_world_sensor, reference,
                                            icp.max_correspondence_distance_m, config.inlier_m);
        }
    }
    result.tested = true;
    result.pairs = pairs;
    result.sweep_motion_m = median(sweep_motion_m);
    result.inliers_as_measured = share_sum[kAsMeasured] / pairs;
    result.inliers_clockwise = share_sum[kClockwise] / pairs;
    result.inliers_counterclockwise = share_sum[kCounterClockwise] / pairs;
    const bool clockwise_better = result.inliers_clockwise >= result.inliers_counterclockwise;
    const double best = std::max(result.inliers_clockwise, result.inliers_counterclockwise);
    result.direction =
        clockwise_better ? SweepDirection::kClockwise : SweepDirection::kCounterClockwise;
    char text[240];
    if (result.sweep_motion_m < config.min_sweep_motion_m) {
        std::snprintf(text, sizeof(text),
                      "the sensor moves %.3f m in a sweep, below %.3f m: nothing to deskew",
                      result.sweep_motion_m, config.min_sweep_motion_m);
    } else {
        const double asymmetry =
            std::abs(result.inliers_clockwise - result.inliers_counterclockwise);
        result.skewed = best >= result.inliers_as_measured + config.min_gain &&
                        asymmetry >= config.min_asymmetry;
        std::snprintf(text, sizeof(text),
                      "%.1f %% of points on the planes as measured, %.1f %% deskewed clockwise, "
                      "%.1f %% counter-clockwise (%zu pairs, %.2f m a sweep)",
                      100.0 * result.inliers_as_measured, 100.0 * result.inliers_clockwise,
                      100.0 * result.inliers_counterclockwise, pairs, result.sweep_motion_m);
    }
    result.reason = text;
    result.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
}

bool sweep_times_apply(const DeskewConfig& config, bool refining, bool estimate_poses,
                       const ScanSequence& sequence) {
    return config.azimuth_times != DeskewMode::kAuto ||
           (refining && !estimate_poses && sequence.has_poses());
}

ScanSequence sequence_with_sweep_times(const ScanSequence& sequence, const DeskewConfig& config,
                                       SweepTestResult* result) {
    if (result) *result = SweepTestResult{};
    if (config.azimuth_times == DeskewMode::kOff || config.mode == DeskewMode::kOff) {
        return sequence;
    }
    SweepTimeModel model = config.sweep;
    model.sweep_period_s = config.scan_period_s;
    if (config.azimuth_times == DeskewMode::kOn) return sequence.with_sweep_times(model);
    const SweepTestResult test = run_sweep_test(sequence, model);
    if (result) *result = test;
    if (!test.skewed) return sequence;
    model.direction = test.direction;
    return sequence.with_sweep_times(model);
}

}  // namespace shine
