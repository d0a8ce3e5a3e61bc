#include "shine/mapper/scan_odometry.hpp"

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

#include "shine/core/error.hpp"
#include "shine/io/binary_stream.hpp"
#include "shine/mapper/neural_sdf_field.hpp"
#include "shine/odometry/point_to_plane_icp.hpp"
#include "shine/odometry/registration_points.hpp"
#include "shine/odometry/sdf_registration.hpp"
#include "shine/odometry/se3.hpp"

namespace shine {
namespace {

void require_odometry(bool ok, const std::string& key, const std::string& rule) {
    if (!ok) throw ConfigError("odometry." + key + " " + rule);
}

RegistrationPointConfig point_config(const OdometryConfig& c, double voxel_size_m) {
    RegistrationPointConfig points;
    points.min_range_m = c.min_range_m;
    points.max_range_m = c.max_range_m;
    points.voxel_size_m = voxel_size_m;
    return points;
}

RegistrationSolverConfig solver_config(const OdometryConfig& c, double kernel_scale_m) {
    RegistrationSolverConfig solver;
    solver.max_iterations = c.max_iterations;
    solver.max_condition_number = c.max_condition_number;
    solver.kernel.type = RobustKernelType::kGemanMcClure;
    solver.kernel.scale_m = kernel_scale_m;
    // A step below 0.3 mm (at the street's 0.5 m registration voxels; it follows the voxel as
    // the other lengths do) and 0.0017 deg ends a scan's solve, three times the solver's
    // defaults: on the streets, distorted or not, the estimates stay within 0.3 mm of ATE and
    // 0.07 points of F-score of the tighter ones, in about a fifth fewer iterations
    // (docs/odometry.md, "Time per scan").
    solver.converged_translation_m = 6e-4 * c.voxel_size_m;
    solver.converged_rotation_rad = 3e-5;
    // The step below those is not evaluated: one pass over the points fewer in each of a scan's
    // ICP and SDF stages. On the real drive without poses a deferred scan 98 -> 88 ms (medians of
    // three alternated rounds, 2 threads); the held-out rays and the streets' F-scores and ATE
    // moved within their run-to-run spread (docs/realtime.md).
    solver.try_converged_step = false;
    return solver;
}

/// Point-to-plane ICP coarse to fine from `start`: the last stage's result, its pose (the start
/// when no stage was accepted), its fitness and the iterations of all stages.
struct IcpRun {
    RegistrationResult result;
    Eigen::Isometry3d pose;
    double inlier_ratio = 0.0;
    int iterations = 0;
};

/// The stages of OdometryConfig (icp_coarse_correspondence_m, then icp_max_correspondence_m) on
/// `points` (deskewed), or on `measured` with their sweep's motion estimated when `sweep` is
/// given; the fitness is the deskewed points'.
IcpRun run_icp_stages(const OdometryConfig& c, const std::vector<Eigen::Vector3f>& points,
                      const std::vector<Eigen::Vector3f>* measured, const SweepModel* sweep,
                      const ReferencePlanes& planes, const Eigen::Isometry3d& start) {
    std::vector<std::pair<double, double>> stages;  // correspondence, kernel scale
    if (c.icp_coarse_correspondence_m > c.icp_max_correspondence_m) {
        stages.emplace_back(c.icp_coarse_correspondence_m, 0.25 * c.icp_coarse_correspondence_m);
    }
    stages.emplace_back(c.icp_max_correspondence_m, c.icp_kernel_scale_m);
    IcpRun run;
    run.pose = start;
    // Each point's match, passed from iteration to iteration, stage to stage and to the fitness:
    // the searches start near their answer (PlaneMatches).
    PlaneMatches matches;
    for (const auto& [correspondence_m, scale_m] : stages) {
        PointToPlaneIcpConfig icp_config;
        icp_config.max_correspondence_distance_m = correspondence_m;
        icp_config.solver = solver_config(c, scale_m);
        run.result =
            sweep
                ? register_point_to_plane(*measured, run.pose, planes, icp_config, sweep, &matches)
                : register_point_to_plane(points, run.pose, planes, icp_config, nullptr, &matches);
        run.iterations += run.result.iterations;
        if (run.result.accepted()) run.pose = run.result.T_world_sensor;
    }
    run.inlier_ratio = point_to_plane_inlier_ratio(
        points, run.pose, planes, c.icp_max_correspondence_m, c.icp_kernel_scale_m, &matches);
    return run;
}

/// The points of `selected` of `points_sensor`, each moved by exp(t_i / interval_s * twist)
/// (deskewed at constant velocity; as they are for a zero twist).
std::vector<Eigen::Vector3f> deskewed_points(const std::vector<Eigen::Vector3f>& points_sensor,
                                             const std::vector<double>& times_s,
                                             const std::vector<std::size_t>& selected,
                                             const Vector6d& twist, double interval_s) {
    std::vector<Eigen::Vector3f> out(selected.size());
    for (std::size_t j = 0; j < selected.size(); ++j) {
        const std::size_t i = selected[j];
        out[j] = (se3_exp(times_s[i] / interval_s * twist) * points_sensor[i].cast<double>())
                     .cast<float>();
    }
    return out;
}

}  // namespace

const char* to_string(PoseSource source) {
    switch (source) {
        case PoseSource::kFirst:
            return "first";
        case PoseSource::kIcp:
            return "icp";
        case PoseSource::kSdf:
            return "sdf";
        case PoseSource::kPrediction:
            return "prediction";
        case PoseSource::kSkipped:
            return "skipped";
    }
    return "?";
}

const char* to_string(RegistrationMethod method) {
    switch (method) {
        case RegistrationMethod::kNone:
            return "none";
        case RegistrationMethod::kIcp:
            return "icp";
        case RegistrationMethod::kSdf:
            return "sdf";
    }
    return "?";
}

ScanOdometry::ScanOdometry(const OdometryConfig& config) : config_(config) {
    require_odometry(config.voxel_size_m >= 0.0, "voxel_size_m", "must be >= 0");
    require_odometry(config.min_range_m >= 0.0 && config.max_range_m > config.min_range_m,
                     "max_range_m", "must exceed odometry.min_range_m (>= 0)");
    require_odometry(config.max_iterations >= 1, "max_iterations", "must be at least 1");
    require_odometry(config.icp_warmup_scans >= 0, "icp_warmup_scans", "must be >= 0");
    require_odometry(config.icp_reference_scans >= 1, "icp_reference_scans", "must be at least 1");
    require_odometry(config.icp_max_correspondence_m > 0.0, "icp_max_correspondence_m",
                     "must be positive");
    require_odometry(config.icp_kernel_scale_m > 0.0, "icp_kernel_scale_m", "must be positive");
    require_odometry(config.icp_yaw_hypotheses >= 1, "icp_yaw_hypotheses", "must be at least 1");
    require_odometry(config.icp_min_inlier_ratio >= 0.0 && config.icp_min_inlier_ratio <= 1.0,
                     "icp_min_inlier_ratio", "must be in [0, 1]");
    require_odometry(config.sdf_kernel_scale_m > 0.0, "sdf_kernel_scale_m", "must be positive");
    require_odometry(config.max_condition_number > 1.0, "max_condition_number", "must exceed 1");
    require_odometry(config.min_scan_points >= 0, "min_scan_points", "must be >= 0");
    require_odometry(config.sweep_prior_translation_m > 0.0, "sweep_prior_translation_m",
                     "must be positive");
    require_odometry(config.sweep_prior_rotation_deg > 0.0, "sweep_prior_rotation_deg",
                     "must be positive");
}

Eigen::Isometry3d ScanOdometry::sweep_motion(std::size_t i) const {
    const OdometryRecord& record = records_.at(i);
    Vector6d twist;
    for (int j = 0; j < 6; ++j) twist[j] = record.sweep_twist[j];
    return se3_exp(twist);
}

const OdometryRecord& ScanOdometry::estimate(const Scan& scan, const NeuralSdf& map,
                                             const SweepPrior* sweep_prior) {
    return finish(prepare(scan, sweep_prior), map);
}

PreparedScan ScanOdometry::prepare(const Scan& scan, const SweepPrior* sweep_prior) const {
    const auto start = std::chrono::steady_clock::now();
    PreparedScan out;
    OdometryRecord& record = out.record;
    // 1. Registration points: as measured (`measured`, with their sweep fractions) and deskewed
    // at the prior's motion (`points`), or as given without a prior.
    const std::vector<std::size_t> selected = select_registration_point_indices(
        scan.points_sensor, point_config(config_, config_.voxel_size_m));
    std::vector<Eigen::Vector3f>& points = out.points;
    points.resize(selected.size());
    for (std::size_t j = 0; j < selected.size(); ++j) points[j] = scan.points_sensor[selected[j]];
    std::vector<Eigen::Vector3f>& measured = out.measured;
    SweepModel& sweep = out.sweep;
    if (sweep_prior) {
        if (scan.point_time_s.size() != scan.points_sensor.size()) {
            throw DataError("scan '" + scan.source.string() + "' has " +
                            std::to_string(scan.point_time_s.size()) + " point times for " +
                            std::to_string(scan.points_sensor.size()) + " points");
        }
        if (!(sweep_prior->interval_s > 0.0)) {
            throw DataError("scan '" + scan.source.string() +
                            "': the sweep's interval must be positive");
        }
        sweep.twist_prior = se3_log(sweep_prior->T_expected);
        sweep.prior_sigma_translation_m = config_.sweep_prior_translation_m;
        sweep.prior_sigma_rotation_rad = config_.sweep_prior_rotation_deg * M_PI / 180.0;
        if (config_.sweep_prior_from_poses && !poses_.empty()) {
            sweep.T_world_previous = poses_.back();
        }
        sweep.fractions.resize(selected.size());
        for (std::size_t j = 0; j < selected.size(); ++j) {
            sweep.fractions[j] =
                static_cast<float>(scan.point_time_s[selected[j]] / sweep_prior->interval_s);
        }
        measured = points;
        points = deskewed_points(scan.points_sensor, scan.point_time_s, selected, sweep.twist_prior,
                                 sweep_prior->interval_s);
        for (int j = 0; j < 6; ++j) record.sweep_twist[j] = sweep.twist_prior[j];
    }
    record.points = points.size();

    // 2. Prediction.
    const std::size_t k = poses_.size();
    out.scan = k;
    Eigen::Isometry3d& prediction = out.prediction;
    prediction = scan.T_world_sensor;  // the first scan anchors the world
    // The second scan: at rest, or where the first sweep's motion (bootstrap_sweep) took it.
    if (k == 1) prediction = poses_[0] * sweep_motion(0);
    if (k >= 2) prediction = predict_constant_velocity(poses_[k - 2], poses_[k - 1]);
    out.sdf_start = prediction;

    if (points.size() < static_cast<std::size_t>(config_.min_scan_points)) {
        record.source = PoseSource::kSkipped;
    } else if (k == 0) {
        record.source = PoseSource::kFirst;
        record.accepted = true;
    } else {
        // 3. Registration from the prediction, coarse to fine: a stage starts from the previous
        // stage's pose if that was accepted, else from the prediction.
        out.registers = true;
        out.icp = k <= static_cast<std::size_t>(config_.icp_warmup_scans);
        // The last stage estimates the sweep's motion: the SDF's, or ICP's in the warm-up.
        out.continuous = sweep_prior && config_.estimate_sweep;
        // After the warm-up, ICP (when icp_before_sdf) only finds the SDF registration's start.
        if (out.icp || config_.icp_before_sdf) {
            record.tried = RegistrationMethod::kIcp;
            std::vector<Eigen::Vector3d> reference, normals;
            for (std::size_t r = 0; r < reference_world_.size(); ++r) {
                reference.insert(reference.end(), reference_world_[r].begin(),
                                 reference_world_[r].end());
                normals.insert(normals.end(), reference_normals_[r].begin(),
                               reference_normals_[r].end());
            }
            if (!reference.empty()) {
                const ReferencePlanes planes(reference, normals);
                const bool icp_sweep = out.icp && out.continuous;
                const auto run_icp = [&](const Eigen::Isometry3d& start) {
                    IcpRun run = run_icp_stages(config_, points, icp_sweep ? &measured : nullptr,
                                                icp_sweep ? &sweep : nullptr, planes, start);
                    out.iterations += run.iterations;
                    return run;
                };
                IcpRun best = run_icp(prediction);
                const bool short_of_fitness =
                    !best.result.accepted() || best.inlier_ratio < config_.icp_min_inlier_ratio;
                if (short_of_fitness && config_.icp_yaw_hypotheses > 1) {
                    // Headings about the world's vertical through the previous sensor position.
                    const Eigen::Isometry3d& previous = poses_[k - 1];
                    for (int h = 0; h < config_.icp_yaw_hypotheses; ++h) {
                        const double yaw = 2.0 * M_PI * h / config_.icp_yaw_hypotheses;
                        Eigen::Isometry3d start = previous;
                        start.linear() =
                            Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                            previous.linear();
                        IcpRun run = run_icp(start);
                        if (run.result.accepted() &&
                            (!best.result.accepted() || run.inlier_ratio > best.inlier_ratio)) {
                            best = std::move(run);
                        }
                    }
                    record.yaw_hypotheses = config_.icp_yaw_hypotheses;
                }
                out.result = best.result;
                record.icp_inlier_ratio = best.inlier_ratio;
                out.sdf_start = best.pose;
                out.icp_found_start = out.result.accepted();
            }
        }
    }
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return out;
}

const OdometryRecord& ScanOdometry::finish(PreparedScan prepared, const NeuralSdf& map) {
    const auto start = std::chrono::steady_clock::now();
    if (prepared.scan != poses_.size()) {
        throw std::logic_error("ScanOdometry::finish: the scan was prepared as scan " +
                               std::to_string(prepared.scan) + " but " +
                               std::to_string(poses_.size()) + " poses are kept");
    }
    replaying_ = false;
    OdometryRecord& record = prepared.record;
    Eigen::Isometry3d estimate = prepared.prediction;
    if (prepared.registers) {
        RegistrationResult& result = prepared.result;
        int& iterations = prepared.iterations;
        if (!prepared.icp) {
            record.tried = RegistrationMethod::kSdf;
            // From ICP's pose the SDF refines in one narrow stage; from the prediction, coarse to
            // fine.
            std::vector<double> scales;
            if (!prepared.icp_found_start &&
                config_.sdf_coarse_kernel_scale_m > config_.sdf_kernel_scale_m) {
                scales.push_back(config_.sdf_coarse_kernel_scale_m);
            }
            scales.push_back(config_.sdf_kernel_scale_m);
            const NeuralSdfField field(map);
            Eigen::Isometry3d from = prepared.sdf_start;
            for (const double scale_m : scales) {
                SdfRegistrationConfig sdf_config;
                sdf_config.solver = solver_config(config_, scale_m);
                sdf_config.solver.min_incidence_cosine = config_.sdf_min_incidence_cosine;
                result = prepared.continuous
                             ? register_to_sdf(prepared.measured, from, field, sdf_config,
                                               &prepared.sweep)
                             : register_to_sdf(prepared.points, from, field, sdf_config);
                iterations += result.iterations;
                if (result.accepted()) from = result.T_world_sensor;
            }
        }
        if (prepared.continuous && result.accepted()) {
            for (int j = 0; j < 6; ++j) record.sweep_twist[j] = result.sweep_twist[j];
            record.sweep_estimated = true;
        }
        // 4. The last stage's pose if it was accepted; else ICP's, when ICP found the SDF stage's
        // start (a registration to the map that does not converge within max_iterations, e.g.
        // where the map is thin, still has ICP's fit to the last scans); else the prediction.
        record.status = result.status;
        record.accepted = result.accepted();
        record.iterations = iterations;
        record.initial_cost = result.initial_cost;
        record.final_cost = result.final_cost;
        record.condition_number = result.condition_number;
        // The map's coverage (keyframe_policy.hpp): oblique points have a value in the map too.
        record.valid_points = result.num_valid_points + result.num_oblique_points;
        if (record.accepted) {
            estimate = result.T_world_sensor;
            record.source = prepared.icp ? PoseSource::kIcp : PoseSource::kSdf;
        } else if (prepared.icp_found_start) {
            estimate = prepared.sdf_start;
            record.source = PoseSource::kIcp;
        } else {
            record.source = PoseSource::kPrediction;
        }
        const Vector6d correction = se3_log(prepared.prediction.inverse() * estimate);
        record.correction_m = correction.head<3>().norm();
        record.correction_rad = correction.tail<3>().norm();
    }
    record.seconds =
        prepared.seconds +
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    // Rounded back onto SO(3): the constant-velocity prediction multiplies by the transpose of
    // the previous rotation, so a rotation that is off by e grows by about 3e a scan, and after
    // 30 scans the rounding of the first one is a millidegree shear.
    estimate.linear() = Eigen::Quaterniond(estimate.linear()).normalized().toRotationMatrix();
    poses_.push_back(estimate);
    records_.push_back(record);
    return records_.back();
}

bool ScanOdometry::bootstrap_sweep(const Scan& first, const Scan& second, double interval_s) {
    if (records_.size() != 1 || records_[0].source != PoseSource::kFirst ||
        !config_.estimate_sweep || first.point_time_s.size() != first.points_sensor.size() ||
        second.point_time_s.size() != second.points_sensor.size() || first.points_sensor.empty() ||
        second.points_sensor.empty() || !(interval_s > 0.0)) {
        return false;
    }
    const std::vector<std::size_t> reference_selected = select_registration_point_indices(
        first.points_sensor, point_config(config_, 0.5 * config_.voxel_size_m));
    const std::vector<std::size_t> selected = select_registration_point_indices(
        second.points_sensor, point_config(config_, config_.voxel_size_m));
    if (selected.size() < static_cast<std::size_t>(config_.min_scan_points)) return false;
    // The fixed point of "both scans deskewed at the motion between their poses": the relative
    // pose of two sweeps bent alike barely depends on the bend, so a few rounds settle it.
    constexpr int kMaxRounds = 8;
    const Eigen::Isometry3d& T_first = poses_[0];
    Vector6d twist = Vector6d::Zero();
    bool found = false;
    for (int round = 0; round < kMaxRounds; ++round) {
        const std::vector<Eigen::Vector3f> reference_sensor = deskewed_points(
            first.points_sensor, first.point_time_s, reference_selected, twist, interval_s);
        std::vector<Eigen::Vector3d> reference(reference_sensor.size());
        for (std::size_t j = 0; j < reference.size(); ++j) {
            reference[j] = T_first * reference_sensor[j].cast<double>();
        }
        const ReferencePlanes planes(reference, PlaneFitConfig{});
        const std::vector<Eigen::Vector3f> points =
            deskewed_points(second.points_sensor, second.point_time_s, selected, twist, interval_s);
        const IcpRun run =
            run_icp_stages(config_, points, nullptr, nullptr, planes, T_first * se3_exp(twist));
        if (!run.result.accepted()) break;
        const Vector6d next = se3_log(T_first.inverse() * run.pose);
        const Vector6d change = next - twist;
        twist = next;
        found = true;
        if (change.head<3>().norm() < 1e-3 && change.tail<3>().norm() < 1e-4) break;
    }
    if (!found) return false;
    for (int j = 0; j < 6; ++j) records_[0].sweep_twist[j] = twist[j];
    records_[0].sweep_estimated = true;
    return true;
}

void ScanOdometry::remember_scan(const Scan& scan) {
    // Only while a scan still to come registers by ICP: scan poses_.size() is the next one.
    if (!config_.icp_before_sdf &&
        poses_.size() > static_cast<std::size_t>(config_.icp_warmup_scans)) {
        reference_world_.clear();
        reference_normals_.clear();
        return;
    }
    const auto start = std::chrono::steady_clock::now();
    // The reference is denser than the scan (half its voxel), so that each scan point finds a
    // neighbour on the same surface and the plane fits have points to use.
    const std::vector<Eigen::Vector3f> points = select_registration_points(
        scan.points_sensor, point_config(config_, 0.5 * config_.voxel_size_m));
    std::vector<Eigen::Vector3d> world(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
        world[i] = scan.T_world_sensor * points[i].cast<double>();
    }
    reference_world_.push_back(std::move(world));
    while (reference_world_.size() > static_cast<std::size_t>(config_.icp_reference_scans)) {
        reference_world_.pop_front();
        reference_normals_.pop_front();
    }
    // The new scan's planes, among the points of the reference it joins (its own last). Fitted
    // once: the older scans keep theirs, so a scan costs one scan's fits, not the reference's.
    std::vector<Eigen::Vector3d> reference;
    for (const auto& scan_points : reference_world_) {
        reference.insert(reference.end(), scan_points.begin(), scan_points.end());
    }
    reference_normals_.push_back(fit_plane_normals(
        reference, reference.size() - reference_world_.back().size(), PlaneFitConfig{}));
    if (!replaying_ && !records_.empty()) {
        records_.back().seconds +=
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    }
}

void ScanOdometry::save(BinaryWriter& out) const {
    out.tag("scan odometry");
    static_assert(std::is_trivially_copyable_v<OdometryRecord>);
    out.array(records_);
    std::vector<double> matrices;
    matrices.reserve(poses_.size() * 12);
    for (const Eigen::Isometry3d& T : poses_) {
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 4; ++c) matrices.push_back(T.matrix()(r, c));
        }
    }
    out.array(matrices);
}

void ScanOdometry::load(BinaryReader& in) {
    in.expect_tag("scan odometry");
    std::vector<OdometryRecord> records = in.array<OdometryRecord>("odometry records");
    const std::vector<double> matrices = in.array<double>("estimated poses");
    if (matrices.size() != records.size() * 12) {
        in.fail("estimated poses", "hold " + std::to_string(matrices.size() / 12) + " poses for " +
                                       std::to_string(records.size()) + " odometry records");
    }
    poses_.clear();
    for (std::size_t i = 0; i < records.size(); ++i) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 4; ++c) T.matrix()(r, c) = matrices[i * 12 + r * 4 + c];
        }
        poses_.push_back(T);
    }
    records_ = std::move(records);
    reference_world_.clear();
    reference_normals_.clear();
    replaying_ = true;  // the replayed scans' remember_scan() time is not theirs to count
}

}  // namespace shine
