#include "shine/eval/ghost_area.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/eval/mesh_sampling.hpp"
#include "shine/eval/nearest_distance.hpp"
#include "shine/eval/voxel_downsample.hpp"

namespace shine {
namespace ghost_area_internal {

constexpr double kMaxYawStepRad = 0.5 * M_PI / 180.0;  ///< turning segments: 0.5 deg pieces

/// Whether the box [lo, hi] (body frame, yaw `yaw_rad`) slid from `a` to `b` covers `p`: is there
/// an s in [0, 1] with R^T (p - a - s (b - a)) inside the box? One interval of s per axis.
bool inside_slid_box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double yaw_rad,
                     const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& p) {
    const Eigen::Matrix3d R_body_world =
        Eigen::AngleAxisd(-yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const Eigen::Vector3d q0 = R_body_world * (p - a);
    const Eigen::Vector3d dq = R_body_world * (b - a);
    double s_min = 0.0, s_max = 1.0;
    for (int i = 0; i < 3; ++i) {
        if (dq[i] == 0.0) {
            if (q0[i] < lo[i] || q0[i] > hi[i]) return false;
            continue;
        }
        // lo <= q0 - s dq <= hi
        double s0 = (q0[i] - hi[i]) / dq[i];
        double s1 = (q0[i] - lo[i]) / dq[i];
        if (s0 > s1) std::swap(s0, s1);
        s_min = std::max(s_min, s0);
        s_max = std::min(s_max, s1);
        if (s_min > s_max) return false;
    }
    return true;
}

}  // namespace ghost_area_internal

using namespace ghost_area_internal;

bool inside_swept_volume(const MoverTrack& mover, const Eigen::Vector3d& point, double margin_m) {
    const Eigen::AlignedBox3d box = mover.box_body();
    const Eigen::Vector3d lo = box.min().array() - margin_m;
    const Eigen::Vector3d hi = box.max().array() + margin_m;
    const auto& w = mover.waypoints;
    if (w.empty()) return false;
    if (w.size() == 1) {
        return inside_slid_box(lo, hi, w[0].yaw_rad, w[0].position_m, w[0].position_m, point);
    }
    for (std::size_t k = 0; k + 1 < w.size(); ++k) {
        const double turn_rad = w[k + 1].yaw_rad - w[k].yaw_rad;
        const int pieces =
            std::max(1, static_cast<int>(std::ceil(std::abs(turn_rad) / kMaxYawStepRad)));
        for (int j = 0; j < pieces; ++j) {
            const double s0 = static_cast<double>(j) / pieces;
            const double s1 = static_cast<double>(j + 1) / pieces;
            const Eigen::Vector3d a =
                w[k].position_m + s0 * (w[k + 1].position_m - w[k].position_m);
            const Eigen::Vector3d b =
                w[k].position_m + s1 * (w[k + 1].position_m - w[k].position_m);
            const double yaw_rad = w[k].yaw_rad + 0.5 * (s0 + s1) * turn_rad;
            if (inside_slid_box(lo, hi, yaw_rad, a, b, point)) return true;
        }
    }
    return false;
}

GhostMetrics measure_ghost_area(const TriangleMesh& pred_mesh, const TriangleMesh& ref,
                                const MoverTracks& tracks, const GhostConfig& config) {
    const EvalConfig& eval = config.eval;
    if (!(eval.threshold_m > 0.0) || !(eval.downsample_m > 0.0) ||
        !(eval.sample_density_per_m2 > 0.0) || eval.max_samples_per_mesh == 0) {
        throw ConfigError(
            "ghost config: threshold_m, downsample_m, sample_density_per_m2 and "
            "max_samples_per_mesh must be positive");
    }
    std::optional<TriangleMesh> pred_moved;
    if (pred_mesh.origin_world_m != ref.origin_world_m) {
        pred_moved = in_frame(pred_mesh, ref.origin_world_m);
    }
    const TriangleMesh& pred = pred_moved ? *pred_moved : pred_mesh;

    GhostMetrics m;
    m.threshold_m = eval.threshold_m;
    m.swept_margin_m = config.swept_margin_m < 0.0 ? eval.threshold_m : config.swept_margin_m;
    m.num_movers = tracks.movers.size();
    m.ref_observed_area_m2 = mesh_surface_area_m2(ref, FaceSelection::kObserved);
    if (!(m.ref_observed_area_m2 > 0.0)) {
        throw DataError(
            "the reference mesh has no observed surface; the ghost share needs a non-empty "
            "reference with at least one face marked observed");
    }
    const double ref_area_m2 = mesh_surface_area_m2(ref, FaceSelection::kAll);
    const double pred_area_m2 = mesh_surface_area_m2(pred, FaceSelection::kAll);
    m.sample_density_per_m2 =
        std::min(eval.sample_density_per_m2, static_cast<double>(eval.max_samples_per_mesh) /
                                                 std::max(ref_area_m2, pred_area_m2));

    // Every predicted sample stands for 1/d m^2: no downsampling on this side.
    const std::vector<Eigen::Vector3f> pred_samples =
        sample_mesh_surface(pred, m.sample_density_per_m2, eval.seed, FaceSelection::kAll);
    const std::vector<Eigen::Vector3f> ref_points = voxel_downsample_centroids(
        sample_mesh_surface(ref, m.sample_density_per_m2, eval.seed, FaceSelection::kAll),
        eval.downsample_m);
    m.pred_samples = pred_samples.size();
    m.pred_area_m2 = static_cast<double>(m.pred_samples) / m.sample_density_per_m2;
    if (pred_samples.empty()) return m;

    // Distances are capped at the threshold: a sample at the cap is off the static scene.
    const std::vector<float> to_static_m =
        nearest_distances_m(ref_points, pred_samples, eval.threshold_m);

    // A box around each mover's swept volume culls most samples before the exact test.
    std::vector<Eigen::AlignedBox3d> bounds;
    for (const MoverTrack& mover : tracks.movers) {
        const double reach_m = 0.5 * mover.size_m.head<2>().norm() + m.swept_margin_m;
        Eigen::AlignedBox3d box;
        for (const MoverWaypoint& p : mover.waypoints) {
            box.extend(p.position_m +
                       Eigen::Vector3d(reach_m, reach_m, mover.size_m.z() + m.swept_margin_m));
            box.extend(p.position_m - Eigen::Vector3d(reach_m, reach_m, m.swept_margin_m));
        }
        bounds.push_back(box);
    }
    std::size_t off_static = 0;
    for (std::size_t i = 0; i < pred_samples.size(); ++i) {
        if (to_static_m[i] < eval.threshold_m) continue;
        ++off_static;
        const Eigen::Vector3d p = pred_samples[i].cast<double>();
        for (std::size_t k = 0; k < tracks.movers.size(); ++k) {
            if (bounds[k].contains(p) &&
                inside_swept_volume(tracks.movers[k], p, m.swept_margin_m)) {
                ++m.ghost_samples;
                break;
            }
        }
    }
    m.off_static_area_m2 = static_cast<double>(off_static) / m.sample_density_per_m2;
    m.ghost_area_m2 = static_cast<double>(m.ghost_samples) / m.sample_density_per_m2;
    m.ghost_share = m.ghost_area_m2 / m.ref_observed_area_m2;
    return m;
}

std::string format_ghost_metrics(const GhostMetrics& m) {
    char buffer[1024];
    std::snprintf(buffer, sizeof(buffer),
                  "ghost area        %8.2f m^2 (%.2f %% of the observed static surface, "
                  "%.1f m^2)\n"
                  "off static scene  %8.2f m^2 of %.1f m^2 predicted (threshold %.1f cm)\n"
                  "movers            %zu (swept boxes grown by %.1f cm); %zu of %zu samples are "
                  "ghosts\n",
                  m.ghost_area_m2, m.ghost_share * 100.0, m.ref_observed_area_m2,
                  m.off_static_area_m2, m.pred_area_m2, m.threshold_m * 100.0, m.num_movers,
                  m.swept_margin_m * 100.0, m.ghost_samples, m.pred_samples);
    return buffer;
}

std::string ghost_metrics_to_json(const GhostMetrics& m) {
    const nlohmann::ordered_json json = {
        {"ghost_area_m2", m.ghost_area_m2},
        {"ghost_share", m.ghost_share},
        {"off_static_area_m2", m.off_static_area_m2},
        {"pred_area_m2", m.pred_area_m2},
        {"ref_observed_area_m2", m.ref_observed_area_m2},
        {"threshold_m", m.threshold_m},
        {"swept_margin_m", m.swept_margin_m},
        {"sample_density_per_m2", m.sample_density_per_m2},
        {"num_movers", m.num_movers},
        {"pred_samples", m.pred_samples},
        {"ghost_samples", m.ghost_samples},
    };
    return json.dump();
}

}  // namespace shine
