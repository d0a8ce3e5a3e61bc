#include "shine/mapper/map_localizer.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <numeric>

#include "shine/bake/level_set_bake.hpp"
#include "shine/core/error.hpp"
#include "shine/core/stopwatch.hpp"
#include "shine/geometry/map_frame.hpp"
#include "shine/mapper/neural_sdf_field.hpp"
#include "shine/mesh/level_set_mesh.hpp"
#include "shine/odometry/registration_points.hpp"
#include "shine/odometry/sdf_registration.hpp"
#include "shine/odometry/se3.hpp"

namespace shine {
namespace {

void require_localize(bool ok, const std::string& key, const std::string& rule) {
    if (!ok) throw ConfigError("localize." + key + " " + rule);
}

/// Every k-th point, so that at most `max_points` remain (all when max_points <= 0).
std::vector<Eigen::Vector3f> thinned(const std::vector<Eigen::Vector3f>& points, int max_points) {
    if (max_points <= 0 || points.size() <= static_cast<std::size_t>(max_points)) return points;
    const std::size_t stride =
        (points.size() + static_cast<std::size_t>(max_points) - 1) / max_points;
    std::vector<Eigen::Vector3f> out;
    out.reserve(points.size() / stride + 1);
    for (std::size_t i = 0; i < points.size(); i += stride) out.push_back(points[i]);
    return out;
}

/// `pose` turned by `yaw_rad` about the world's vertical axis through its position, and moved
/// by `offset_world`.
Eigen::Isometry3d turned(const Eigen::Isometry3d& pose, double yaw_rad,
                         const Eigen::Vector3d& offset_world) {
    Eigen::Isometry3d out = pose;
    out.linear() =
        Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix() * pose.linear();
    out.translation() += offset_world;
    return out;
}

}  // namespace

namespace map_localizer_internal {

using Clock = std::chrono::steady_clock;

/// `field`, each evaluation's time added to `seconds` (the stage split of LocalizeStageSeconds).
class TimedSdfField final : public SdfField {
  public:
    TimedSdfField(const SdfField& field, double& seconds) : field_(field), seconds_(seconds) {}

    void evaluate(const std::vector<Eigen::Vector3d>& points_world, std::vector<double>& sdf_m,
                  std::vector<Eigen::Vector3d>& gradient_world,
                  std::vector<std::uint8_t>& valid) const override {
        const Clock::time_point start = Clock::now();
        field_.evaluate(points_world, sdf_m, gradient_world, valid);
        seconds_ += seconds_since(start);
    }

  private:
    const SdfField& field_;
    double& seconds_;
};

/// `field` with a memory of its last few evaluations: the same points, bit for bit, again get the
/// stored results without an evaluation. The SDF registration's second stage starts at the pose
/// where the first ended, and step 3 scores the pose the last stage accepted: both are poses the
/// solver has evaluated (among the last few: refused trials may follow the accepted iterate).
class RecentSdfEvaluations final : public SdfField {
  public:
    struct Evaluation {
        std::vector<Eigen::Vector3d> points_world;
        std::vector<double> sdf_m;
        std::vector<Eigen::Vector3d> gradient_world;
        std::vector<std::uint8_t> valid;
    };

    explicit RecentSdfEvaluations(const SdfField& field) : field_(field) {}

    void evaluate(const std::vector<Eigen::Vector3d>& points_world, std::vector<double>& sdf_m,
                  std::vector<Eigen::Vector3d>& gradient_world,
                  std::vector<std::uint8_t>& valid) const override {
        if (const Evaluation* known = find(points_world)) {
            sdf_m = known->sdf_m;
            gradient_world = known->gradient_world;
            valid = known->valid;
            return;
        }
        field_.evaluate(points_world, sdf_m, gradient_world, valid);
        Evaluation& slot = recent_[next_];
        next_ = (next_ + 1) % kKept;
        slot.points_world = points_world;
        slot.sdf_m = sdf_m;
        slot.gradient_world = gradient_world;
        slot.valid = valid;
    }

    /// The stored evaluation at exactly `points_world`, or nullptr.
    const Evaluation* find(const std::vector<Eigen::Vector3d>& points_world) const {
        for (const Evaluation& e : recent_) {
            if (!points_world.empty() && e.points_world.size() == points_world.size() &&
                e.points_world.front() == points_world.front() && e.points_world == points_world) {
                return &e;
            }
        }
        return nullptr;
    }

  private:
    /// The accepted iterate, then at most a few refused trials (the damping grows tenfold each).
    static constexpr int kKept = 4;
    const SdfField& field_;
    mutable Evaluation recent_[kKept];
    mutable int next_ = 0;
};

}  // namespace map_localizer_internal

void validate(const LocalizeConfig& c) {
    require_localize(c.voxel_size_m >= 0.0, "voxel_size_m", "must be >= 0");
    require_localize(c.min_range_m >= 0.0 && c.max_range_m > c.min_range_m, "max_range_m",
                     "must exceed min_range_m (>= 0)");
    require_localize(!c.kernel_scales_m.empty(), "kernel_scales_m", "needs at least one scale");
    for (double s : c.start_motion_scales) {
        require_localize(std::isfinite(s) && s >= 0.0 && s <= 4.0, "start_motion_scales",
                         "must be within [0, 4]");
    }
    require_localize(c.start_yaw_range_deg >= 0.0 && c.start_yaw_range_deg <= 90.0,
                     "start_yaw_range_deg", "must be within [0, 90]");
    require_localize(c.start_yaw_step_deg > 0.0, "start_yaw_step_deg", "must be positive");
    require_localize(c.track_min_start_score >= 0.0 && c.track_min_start_score <= 1.0,
                     "track_min_start_score", "must be within [0, 1]");
    require_localize(c.prediction_good_score >= 0.0 && c.prediction_good_score <= 1.0,
                     "prediction_good_score", "must be within [0, 1]");
    const auto lookup_voxel_ok = [](double voxel_m, double radius_m) {
        return voxel_m == 0.0 ||
               (voxel_m > 0.0 && voxel_m <= radius_m && radius_m <= 1000.0 * voxel_m);
    };
    require_localize(
        lookup_voxel_ok(c.icp_lookup_voxel_m, c.icp_correspondence_m), "icp_lookup_voxel_m",
        "must be 0 (none) or from icp_correspondence_m / 1000 to icp_correspondence_m");
    require_localize(lookup_voxel_ok(c.icp_coarse_lookup_voxel_m, c.icp_coarse_correspondence_m),
                     "icp_coarse_lookup_voxel_m",
                     "must be 0 (none) or from icp_coarse_correspondence_m / 1000 to "
                     "icp_coarse_correspondence_m");
    for (double s : c.kernel_scales_m) {
        require_localize(s > 0.0, "kernel_scales_m", "must be positive");
    }
    require_localize(c.max_iterations >= 1, "max_iterations", "must be >= 1");
    require_localize(c.max_points >= 0 && c.recovery_max_points >= 0, "max_points",
                     "and recovery_max_points must be >= 0 (0: every selected point)");
    require_localize(c.max_condition_number > 1.0, "max_condition_number", "must exceed 1");
    require_localize(c.inlier_distance_m > 0.0, "inlier_distance_m", "must be positive");
    require_localize(c.min_inlier_ratio >= 0.0 && c.min_inlier_ratio <= 1.0, "min_inlier_ratio",
                     "must be within [0, 1]");
    require_localize(c.surface_voxel_m > 0.0, "surface_voxel_m", "must be positive");
    require_localize(c.icp_correspondence_m > 0.0 && c.icp_coarse_correspondence_m > 0.0,
                     "icp_correspondence_m", "and icp_coarse_correspondence_m must be positive");
    require_localize(c.icp_kernel_scale_m > 0.0, "icp_kernel_scale_m", "must be positive");
    require_localize(c.icp_converged_translation_m > 0.0 && c.icp_converged_rotation_rad > 0.0,
                     "icp_converged_translation_m",
                     "and icp_converged_rotation_rad must be positive");
    require_localize(c.icp_min_inlier_ratio >= 0.0 && c.icp_min_inlier_ratio <= 1.0,
                     "icp_min_inlier_ratio", "must be within [0, 1]");
    require_localize(c.search_radius_m >= 0.0, "search_radius_m", "must be >= 0");
    require_localize(c.search_spacing_m > 0.0, "search_spacing_m", "must be positive");
    require_localize(c.lost_search_radius_m >= 0.0, "lost_search_radius_m", "must be >= 0");
    require_localize(c.search_headings >= 1, "search_headings", "must be >= 1");
    require_localize(c.search_points >= 10, "search_points", "must be >= 10");
    require_localize(c.search_registrations >= 1, "search_registrations", "must be >= 1");
    require_localize(c.deep_search_registrations >= 0, "deep_search_registrations", "must be >= 0");
    require_localize(c.place_spacing_m > 0.0, "place_spacing_m", "must be positive");
    require_localize(c.global_search_after_failures >= 1, "global_search_after_failures",
                     "must be >= 1");
}

const char* to_string(LocalizeSource source) {
    switch (source) {
        case LocalizeSource::kTracked:
            return "tracked";
        case LocalizeSource::kRecovered:
            return "recovered";
        case LocalizeSource::kGlobalSearch:
            return "global-search";
        case LocalizeSource::kPrediction:
            return "prediction";
    }
    return "unknown";
}

/// One registration (or search) of a scan: its pose and how well it fits the map there.
struct MapLocalizer::Attempt {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    bool localized = false;
    double inlier_ratio = 0.0;
    std::size_t valid = 0;
    double residual_m = 0.0;
    double condition_number = 0.0;
    RegistrationStatus status = RegistrationStatus::kTooFewPoints;
    int iterations = 0;
    int candidates = 0;
};

MapLocalizer::MapLocalizer(const NeuralSdf& sdf, const LocalizeConfig& config,
                           std::vector<Eigen::Isometry3d> places_world)
    : sdf_(sdf), config_(config) {
    validate(config_);
    // The trajectory thinned: a place at least place_spacing_m from the one kept before it.
    for (const Eigen::Isometry3d& pose : places_world) {
        if (places_.empty() ||
            (pose.translation() - places_.back().translation()).norm() >= config_.place_spacing_m) {
            places_.push_back(pose);
        }
    }
    // Step 4's reference: the vertices of the map's zero level set with the mean normal of their
    // triangles (world frame).
    BakeConfig bake;
    bake.voxel_size_m = config_.surface_voxel_m;
    const TriangleMesh mesh = mesh_level_set(*bake_level_set(sdf_, bake), MeshConfig{});
    std::vector<Eigen::Vector3d> normals(mesh.vertices.size(), Eigen::Vector3d::Zero());
    for (const Eigen::Vector3i& t : mesh.triangles) {
        const Eigen::Vector3d a = mesh.vertices[t[0]].cast<double>();
        const Eigen::Vector3d n =
            (mesh.vertices[t[1]].cast<double>() - a).cross(mesh.vertices[t[2]].cast<double>() - a);
        for (int k = 0; k < 3; ++k) normals[t[k]] += n;
    }
    std::vector<Eigen::Vector3d> points;
    std::vector<Eigen::Vector3d> unit_normals;
    points.reserve(mesh.vertices.size());
    unit_normals.reserve(mesh.vertices.size());
    for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
        if (normals[v].norm() <= 0.0) continue;
        points.push_back(mesh.origin_world_m + mesh.vertices[v].cast<double>());
        unit_normals.push_back(normals[v].normalized());
    }
    if (points.empty()) {
        throw DataError("the map has no surface to localise against (its SDF never crosses zero)");
    }
    surface_ = std::make_unique<ReferencePlanes>(points, unit_normals);
    // Step 4's voxel lookups, built with the map rather than at the first recovery, which would
    // otherwise stall for them (1.5 s on one thread on the real walk's map).
    if (config_.icp_lookup_voxel_m > 0.0) {
        surface_->add_voxel_lookup(config_.icp_lookup_voxel_m, config_.icp_correspondence_m);
    }
    if (config_.icp_coarse_lookup_voxel_m > 0.0) {
        surface_->add_voxel_lookup(config_.icp_coarse_lookup_voxel_m,
                                   config_.icp_coarse_correspondence_m);
    }
}

MapLocalizer::~MapLocalizer() = default;

MapLocalizer::Attempt MapLocalizer::recover(const std::vector<Eigen::Vector3f>& points,
                                            const std::vector<Eigen::Vector3f>& track_points,
                                            const Eigen::Isometry3d& start,
                                            const Eigen::Isometry3d* headings_from) const {
    PointToPlaneIcpConfig icp;
    icp.solver.max_iterations = 30;
    icp.solver.max_condition_number = config_.max_condition_number;
    icp.solver.kernel.type = RobustKernelType::kGemanMcClure;
    icp.solver.converged_translation_m = config_.icp_converged_translation_m;
    icp.solver.converged_rotation_rad = config_.icp_converged_rotation_rad;
    int iterations = 0;
    // Each point's match at the last pose tried bounds its next search, across every start,
    // stage, iteration and fitness of this recovery, as the odometry's ICP does: the same matches
    // (PlaneMatches), but no measurable gain here (the searches of the first iterations, metres
    // off, dominate).
    PlaneMatches matches;
    // ICP from `from`, coarse to fine unless `fine_only`: its pose (from itself when no stage
    // was accepted) and the share of the points on a plane there.
    const auto run_icp = [&](const Eigen::Isometry3d& from, bool fine_only, double& inlier_ratio) {
        Eigen::Isometry3d pose = from;
        const double stages[2][2] = {
            {config_.icp_coarse_correspondence_m, config_.icp_coarse_correspondence_m / 4.0},
            {config_.icp_correspondence_m, config_.icp_kernel_scale_m}};
        for (int s = fine_only ? 1 : 0; s < 2; ++s) {
            icp.max_correspondence_distance_m = stages[s][0];
            icp.solver.kernel.scale_m = stages[s][1];
            const auto icp_start = map_localizer_internal::Clock::now();
            const RegistrationResult r =
                register_point_to_plane(points, pose, *surface_, icp, nullptr, &matches);
            stage_seconds_.icp += seconds_since(icp_start);
            iterations += r.iterations;
            // A stage that ran out of iterations still moved towards the basin: the next stage
            // (or the SDF) goes on from there.
            if (r.accepted() ||
                (r.status == RegistrationStatus::kMaxIterations && r.final_cost < r.initial_cost)) {
                pose = r.accepted() ? r.T_world_sensor : r.T_world_sensor_solved;
            }
        }
        const auto ratio_start = map_localizer_internal::Clock::now();
        inlier_ratio =
            point_to_plane_inlier_ratio(points, pose, *surface_, config_.icp_correspondence_m,
                                        config_.icp_kernel_scale_m, &matches);
        stage_seconds_.icp += seconds_since(ratio_start);
        return pose;
    };
    // The narrow stage alone first (a start within about a metre), then coarse to fine, then
    // the headings.
    double best_ratio = 0.0;
    Eigen::Isometry3d best = run_icp(start, true, best_ratio);
    if (best_ratio < config_.icp_min_inlier_ratio) {
        double ratio = 0.0;
        const Eigen::Isometry3d pose = run_icp(start, false, ratio);
        if (ratio > best_ratio) {
            best_ratio = ratio;
            best = pose;
        }
    }
    if (headings_from && best_ratio < config_.icp_min_inlier_ratio) {
        // Nearest headings first (0, +1, -1, +2, ... steps); the first that puts enough points
        // on a plane ends the loop.
        const double step = 2.0 * M_PI / config_.search_headings;
        for (int k = 0; k < config_.search_headings; ++k) {
            const int h = (k % 2 == 0 ? 1 : -1) * ((k + 1) / 2);
            const Eigen::Isometry3d from =
                turned(*headings_from, h * step, Eigen::Vector3d::Zero());
            // The coarse-to-fine run from `start` above, again (the second scan's prediction is
            // the last pose): the same pose and share.
            if (from.matrix() == start.matrix()) continue;
            double ratio = 0.0;
            const Eigen::Isometry3d pose = run_icp(from, false, ratio);
            if (ratio > best_ratio) {
                best_ratio = ratio;
                best = pose;
            }
            if (best_ratio >= config_.icp_min_inlier_ratio) break;
        }
    }
    Attempt attempt = track(track_points, best);
    attempt.iterations += iterations;
    return attempt;
}

void MapLocalizer::set_initial_pose(const Eigen::Isometry3d& T_world_sensor) {
    has_initial_pose_ = true;
    initial_pose_ = T_world_sensor;
}

Eigen::Isometry3d MapLocalizer::prediction() const {
    if (records_.empty()) return has_initial_pose_ ? initial_pose_ : Eigen::Isometry3d::Identity();
    const Eigen::Isometry3d& last = records_.back().T_world_sensor;
    if (records_.size() == 1) return last;
    const Eigen::Isometry3d& before = records_[records_.size() - 2].T_world_sensor;
    return last * (before.inverse() * last);
}

void MapLocalizer::score(const std::vector<Eigen::Vector3f>& points, const Eigen::Isometry3d& pose,
                         double& inlier_ratio, std::size_t& valid, double& residual_m) const {
    const std::vector<Eigen::Vector3f> points_map =
        points_in_map_frame(points, map_from_sensor(pose, sdf_.origin_world_m));
    std::vector<float> sdf_m;
    std::vector<std::uint8_t> inside;
    sdf_.query(points_map, QueryMask::kLevel0, sdf_m, inside);
    std::vector<float> residuals;
    residuals.reserve(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
        if (inside[i]) residuals.push_back(std::abs(sdf_m[i]));
    }
    summarise(residuals, points.size(), inlier_ratio, valid, residual_m);
}

void MapLocalizer::summarise(std::vector<float>& abs_residuals_m, std::size_t points,
                             double& inlier_ratio, std::size_t& valid, double& residual_m) const {
    std::size_t inliers = 0;
    for (const float r : abs_residuals_m) {
        if (r <= config_.inlier_distance_m) ++inliers;
    }
    valid = abs_residuals_m.size();
    inlier_ratio = points == 0 ? 0.0 : static_cast<double>(inliers) / points;
    residual_m = 0.0;
    if (!abs_residuals_m.empty()) {
        auto middle = abs_residuals_m.begin() + abs_residuals_m.size() / 2;
        std::nth_element(abs_residuals_m.begin(), middle, abs_residuals_m.end());
        residual_m = *middle;
    }
}

MapLocalizer::Attempt MapLocalizer::track(const std::vector<Eigen::Vector3f>& points,
                                          const Eigen::Isometry3d& start) const {
    Attempt attempt;
    attempt.pose = start;
    const NeuralSdfField neural_field(sdf_);
    const map_localizer_internal::TimedSdfField timed_field(neural_field,
                                                            stage_seconds_.sdf_queries);
    const map_localizer_internal::RecentSdfEvaluations field(timed_field);
    Eigen::Isometry3d from = start;
    bool last_accepted = false;
    for (const double scale_m : config_.kernel_scales_m) {
        SdfRegistrationConfig registration;
        RegistrationSolverConfig& solver = registration.solver;
        solver.max_iterations = config_.max_iterations;
        solver.max_condition_number = config_.max_condition_number;
        solver.kernel.type = RobustKernelType::kGemanMcClure;
        solver.kernel.scale_m = scale_m;
        // As the odometry's stopping rule (odometry_config.hpp): 0.3 mm at 0.5 m voxels.
        solver.converged_translation_m = 6e-4 * std::max(config_.voxel_size_m, 0.1);
        solver.converged_rotation_rad = 3e-5;
        const RegistrationResult result = register_to_sdf(points, from, field, registration);
        attempt.iterations += result.iterations;
        attempt.status = result.status;
        attempt.condition_number = result.condition_number;
        last_accepted = result.accepted();
        if (last_accepted) from = result.T_world_sensor;
    }
    attempt.pose = from;
    const auto score_start = map_localizer_internal::Clock::now();
    // Step 3 at the pose the registration ended at: the solver evaluated the SDF there (the
    // field's value is NeuralSdf::query's, its validity QueryMask::kLevel0's), so no second pass
    // unless no stage was accepted. The points as the solver moves them (registration_solver).
    std::vector<Eigen::Vector3d> points_world(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
        const Eigen::Vector3d point_sensor = points[i].cast<double>();
        points_world[i] = from * point_sensor;
    }
    if (const auto* known = field.find(points_world)) {
        std::vector<float> residuals;
        residuals.reserve(points.size());
        for (std::size_t i = 0; i < points.size(); ++i) {
            if (known->valid[i]) residuals.push_back(std::abs(static_cast<float>(known->sdf_m[i])));
        }
        summarise(residuals, points.size(), attempt.inlier_ratio, attempt.valid,
                  attempt.residual_m);
    } else {
        score(points, from, attempt.inlier_ratio, attempt.valid, attempt.residual_m);
    }
    stage_seconds_.acceptance += seconds_since(score_start);
    attempt.localized = last_accepted && attempt.inlier_ratio >= config_.min_inlier_ratio;
    return attempt;
}

std::vector<double> MapLocalizer::surface_scores(
    const std::vector<Eigen::Vector3f>& sample,
    const std::vector<Eigen::Isometry3d>& candidates) const {
    const std::size_t n = sample.size();
    std::vector<Eigen::Vector3f> points_map(candidates.size() * n);
    tbb::parallel_for(std::size_t{0}, candidates.size(), [&](std::size_t c) {
        const std::vector<Eigen::Vector3f> moved =
            points_in_map_frame(sample, map_from_sensor(candidates[c], sdf_.origin_world_m));
        std::copy(moved.begin(), moved.end(), points_map.begin() + c * n);
    });
    std::vector<float> sdf_m;
    std::vector<std::uint8_t> inside;
    sdf_.query(points_map, QueryMask::kLevel0, sdf_m, inside);
    const double band = 2.0 * config_.inlier_distance_m;
    std::vector<double> scores(candidates.size(), 0.0);
    for (std::size_t c = 0; c < candidates.size(); ++c) {
        double s = 0.0;
        for (std::size_t i = 0; i < n; ++i) {
            if (inside[c * n + i]) s += std::max(0.0, 1.0 - std::abs(sdf_m[c * n + i]) / band);
        }
        scores[c] = n == 0 ? 0.0 : s / n;
    }
    return scores;
}

MapLocalizer::Attempt MapLocalizer::search(const std::vector<Eigen::Vector3f>& points,
                                           const std::vector<Eigen::Vector3f>& track_points,
                                           const std::vector<Eigen::Isometry3d>& centres,
                                           double radius_m, int deep_registrations) const {
    // The candidates: each centre moved on a horizontal grid within search_radius_m, turned to
    // each heading.
    std::vector<Eigen::Vector3d> offsets;
    const int steps = static_cast<int>(std::floor(radius_m / config_.search_spacing_m));
    for (int ix = -steps; ix <= steps; ++ix) {
        for (int iy = -steps; iy <= steps; ++iy) {
            const Eigen::Vector3d d(ix * config_.search_spacing_m, iy * config_.search_spacing_m,
                                    0.0);
            if (d.norm() <= radius_m + 1e-9) offsets.push_back(d);
        }
    }
    std::vector<Eigen::Isometry3d> candidates;
    candidates.reserve(centres.size() * offsets.size() * config_.search_headings);
    const double heading_step = 2.0 * M_PI / config_.search_headings;
    for (const Eigen::Isometry3d& centre : centres) {
        for (const Eigen::Vector3d& offset : offsets) {
            for (int h = 0; h < config_.search_headings; ++h) {
                candidates.push_back(turned(centre, h * heading_step, offset));
            }
        }
    }
    // Score: the mean over a few hundred points of max(0, 1 - |SDF| / 2 d) inside the map.
    const std::vector<double> scores =
        surface_scores(thinned(points, config_.search_points), candidates);
    std::vector<std::size_t> order(candidates.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    // The candidates ranked [first, end) by score registered (ranks before `first` are in place
    // already: the comparison's ties go by index, so the ranks are the same either way).
    const auto register_ranks = [&](int first_rank, int end_rank) {
        const std::size_t first = std::min<std::size_t>(order.size(), first_rank);
        const std::size_t end = std::min<std::size_t>(order.size(), end_rank);
        std::partial_sort(order.begin() + first, order.begin() + end, order.end(),
                          [&](std::size_t a, std::size_t b) {
                              return scores[a] != scores[b] ? scores[a] > scores[b] : a < b;
                          });
        Attempt chosen;
        chosen.pose = centres.empty() ? Eigen::Isometry3d::Identity() : centres.front();
        int iterations = 0;
        bool any = false;
        for (std::size_t k = first; k < end; ++k) {
            const Attempt attempt = recover(points, track_points, candidates[order[k]], nullptr);
            iterations += attempt.iterations;
            // A localised attempt beats one that is not; among equals, more points on the
            // surface.
            if (!any || (attempt.localized && !chosen.localized) ||
                (attempt.localized == chosen.localized &&
                 attempt.inlier_ratio > chosen.inlier_ratio)) {
                chosen = attempt;
                any = true;
            }
        }
        chosen.iterations = iterations;
        return chosen;
    };
    Attempt chosen = register_ranks(0, config_.search_registrations);
    if (!chosen.localized && deep_registrations > config_.search_registrations) {
        const int shallow_iterations = chosen.iterations;
        chosen = register_ranks(config_.search_registrations, deep_registrations);
        chosen.iterations += shallow_iterations;
    }
    chosen.candidates = static_cast<int>(candidates.size());
    return chosen;
}

const LocalizeRecord& MapLocalizer::localize(const std::vector<Eigen::Vector3f>& points_sensor) {
    using map_localizer_internal::Clock;
    const Clock::time_point start_time = Clock::now();
    stage_seconds_ = LocalizeStageSeconds{};
    RegistrationPointConfig selection;
    selection.min_range_m = config_.min_range_m;
    selection.max_range_m = config_.max_range_m;
    selection.voxel_size_m = config_.voxel_size_m;
    const std::vector<Eigen::Vector3f> selected =
        select_registration_points(points_sensor, selection);
    // Tracking with few points is fast; the recovery and the search, whose starts are far from
    // the pose, need more to tell the right minimum from a wrong one.
    const std::vector<Eigen::Vector3f> points = thinned(selected, config_.max_points);
    const std::vector<Eigen::Vector3f> wide = thinned(selected, config_.recovery_max_points);
    stage_seconds_.selection = seconds_since(start_time);

    LocalizeRecord record;
    record.points = points.size();
    const Eigen::Isometry3d predicted = prediction();
    const bool first = records_.empty();
    // The global search (only when it runs): around the map's places; without them around the
    // prediction and the last localised pose, farther (lost_search_radius_m).
    // On the first scan of a run of failures, the search goes deeper when its best candidates
    // fail (deep_search_registrations).
    const auto global_search = [&]() {
        const int deep = failures_in_a_row_ == 0 ? config_.deep_search_registrations : 0;
        const Clock::time_point search_start = Clock::now();
        Attempt found;
        if (!places_.empty()) {
            found = search(wide, points, places_, config_.search_radius_m, deep);
            stage_seconds_.search += seconds_since(search_start);
            return found;
        }
        std::vector<Eigen::Isometry3d> centres = {predicted};
        for (auto r = records_.rbegin(); r != records_.rend(); ++r) {
            if (!r->localized) continue;
            if ((r->T_world_sensor.translation() - predicted.translation()).norm() >
                config_.search_spacing_m) {
                centres.push_back(r->T_world_sensor);
            }
            break;
        }
        found = search(wide, points, centres,
                       std::max(config_.search_radius_m, config_.lost_search_radius_m), deep);
        stage_seconds_.search += seconds_since(search_start);
        return found;
    };

    Attempt attempt;
    LocalizeSource source = LocalizeSource::kTracked;
    int iterations = 0;
    if (first && !has_initial_pose_) {
        attempt = global_search();
        source = LocalizeSource::kGlobalSearch;
        record.points = wide.size();
    } else {
        // Step 2's starts around the prediction, scored; the best is tracked first.
        const Clock::time_point starts_start = Clock::now();
        std::vector<Eigen::Isometry3d> starts;
        std::vector<std::array<double, 2>> start_labels;  // motion scale, yaw (degrees)
        const Eigen::Isometry3d last =
            records_.empty() ? predicted : records_.back().T_world_sensor;
        const Eigen::Isometry3d motion =
            records_.size() >= 2 ? records_[records_.size() - 2].T_world_sensor.inverse() * last
                                 : Eigen::Isometry3d::Identity();
        const int yaw_steps = static_cast<int>(
            std::floor(config_.start_yaw_range_deg / config_.start_yaw_step_deg + 1e-9));
        std::vector<double> scales = {1.0};
        if (records_.size() >= 2) {
            for (const double scale : config_.start_motion_scales) {
                if (std::find(scales.begin(), scales.end(), scale) == scales.end()) {
                    scales.push_back(scale);
                }
            }
        }
        for (const double scale : scales) {
            const Eigen::Isometry3d from =
                scale == 1.0
                    ? predicted
                    : Eigen::Isometry3d(last * interpolate_constant_velocity(motion, scale));
            for (int k = 0; k <= 2 * yaw_steps; ++k) {
                const int h = (k % 2 == 0 ? 1 : -1) * ((k + 1) / 2);  // 0, -1, +1, -2, ...
                const double yaw_deg = h * config_.start_yaw_step_deg;
                starts.push_back(
                    h == 0 ? from : turned(from, yaw_deg * M_PI / 180.0, Eigen::Vector3d::Zero()));
                start_labels.push_back({scale, yaw_deg});
            }
        }
        // The prediction first: one that scores well is tracked without scoring the others.
        std::size_t best_start = 0;
        const std::vector<Eigen::Vector3f> sample = thinned(points, config_.search_points);
        record.prediction_score = surface_scores(sample, {predicted}).front();
        record.start_score = record.prediction_score;
        if (starts.size() > 1 && record.prediction_score < config_.prediction_good_score) {
            const std::vector<Eigen::Isometry3d> others(starts.begin() + 1, starts.end());
            const std::vector<double> scores = surface_scores(sample, others);
            // The first of the best; the prediction wins a tie.
            const std::size_t best_other = static_cast<std::size_t>(
                std::max_element(scores.begin(), scores.end()) - scores.begin());
            if (scores[best_other] > record.prediction_score) {
                best_start = best_other + 1;
                record.start_score = scores[best_other];
            }
        }
        record.start_motion_scale = start_labels[best_start][0];
        record.start_yaw_deg = start_labels[best_start][1];
        stage_seconds_.starts = seconds_since(starts_start);
        const Clock::time_point tracking_start = Clock::now();
        const bool try_tracking = record.start_score >= config_.track_min_start_score;
        if (try_tracking) attempt = track(points, starts[best_start]);
        if (try_tracking && !attempt.localized && best_start != 0) {
            iterations += attempt.iterations;
            attempt = track(points, predicted);
            if (attempt.localized) {
                record.start_motion_scale = 1.0;
                record.start_yaw_deg = 0.0;
            }
        }
        stage_seconds_.tracking = seconds_since(tracking_start);
        if (!attempt.localized) {
            iterations += attempt.iterations;
            // The headings turn the last pose: where the motion changed, the prediction
            // extrapolates the error (the odometry's rule, odometry_config.hpp).
            // From the best start when tracking was not tried, else from the prediction.
            const Eigen::Isometry3d recovery_start_pose =
                try_tracking ? predicted : starts[best_start];
            const Clock::time_point recovery_start = Clock::now();
            attempt = recover(wide, points, recovery_start_pose, &last);
            stage_seconds_.recovery = seconds_since(recovery_start);
            source = LocalizeSource::kRecovered;
            record.points = wide.size();
        }
        if (!attempt.localized && failures_in_a_row_ + 1 >= config_.global_search_after_failures) {
            iterations += attempt.iterations;
            attempt = global_search();
            source = LocalizeSource::kGlobalSearch;
        }
    }
    iterations += attempt.iterations;
    record.localized = attempt.localized;
    record.source = attempt.localized ? source : LocalizeSource::kPrediction;
    record.T_world_sensor = attempt.localized ? attempt.pose : predicted;
    if (!attempt.localized) {
        // Reported at the prediction that bridges the scan.
        score(wide, predicted, attempt.inlier_ratio, attempt.valid, attempt.residual_m);
        record.points = wide.size();
    }
    record.valid_points = attempt.valid;
    record.inlier_ratio = attempt.inlier_ratio;
    record.residual_m = attempt.residual_m;
    record.condition_number = attempt.condition_number;
    record.status = attempt.status;
    record.iterations = iterations;
    record.candidates = attempt.candidates;
    failures_in_a_row_ = record.localized ? 0 : failures_in_a_row_ + 1;
    record.seconds = seconds_since(start_time);
    record.stage_seconds = stage_seconds_;
    records_.push_back(record);
    return records_.back();
}

}  // namespace shine
