#include "shine/eval/mesh_metrics.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/eval/mesh_sampling.hpp"
#include "shine/eval/nearest_distance.hpp"
#include "shine/eval/voxel_downsample.hpp"

namespace shine {
namespace mesh_metrics_internal {

void require_positive(double value, const char* name) {
    if (!(value > 0.0) || !std::isfinite(value)) {
        throw ConfigError(std::string("eval config: ") + name + " = " + std::to_string(value) +
                          " is invalid; it must be positive and finite");
    }
}

void validate(const EvalConfig& config) {
    require_positive(config.threshold_m, "threshold_m");
    require_positive(config.downsample_m, "downsample_m");
    require_positive(config.accuracy_max_m, "accuracy_max_m");
    require_positive(config.completion_cap_m, "completion_cap_m");
    require_positive(config.sample_density_per_m2, "sample_density_per_m2");
    if (config.max_samples_per_mesh == 0) {
        throw ConfigError("eval config: max_samples_per_mesh = 0 is invalid; it must be positive");
    }
    if (config.threshold_m > config.completion_cap_m) {
        throw ConfigError("eval config: threshold_m = " + std::to_string(config.threshold_m) +
                          " exceeds completion_cap_m = " + std::to_string(config.completion_cap_m) +
                          "; raise the cap or lower the threshold");
    }
}

bool all_observed(const TriangleMesh& mesh) {
    return std::all_of(mesh.face_observed.begin(), mesh.face_observed.end(),
                       [](std::uint8_t flag) { return flag != 0; });
}

/// Sampled and downsampled points of `mesh`.
std::vector<Eigen::Vector3f> sample_points(const TriangleMesh& mesh, double density_per_m2,
                                           const EvalConfig& config, FaceSelection faces) {
    return voxel_downsample_centroids(sample_mesh_surface(mesh, density_per_m2, config.seed, faces),
                                      config.downsample_m);
}

/// Share of `distances_m` strictly under `threshold_m`; 0 for an empty set.
double share_under(const std::vector<float>& distances_m, double threshold_m) {
    if (distances_m.empty()) return 0.0;
    const auto under = std::count_if(distances_m.begin(), distances_m.end(),
                                     [threshold_m](float d) { return d < threshold_m; });
    return static_cast<double>(under) / static_cast<double>(distances_m.size());
}

}  // namespace mesh_metrics_internal

EvalConfig eval_config_for_threshold(double threshold_m) {
    mesh_metrics_internal::require_positive(threshold_m, "threshold_m");
    EvalConfig config;
    const double street_threshold_m = config.threshold_m;
    config.threshold_m = threshold_m;
    if (threshold_m >= street_threshold_m) return config;
    const double scale = threshold_m / street_threshold_m;
    config.downsample_m *= scale;
    config.sample_density_per_m2 /= scale * scale;
    return config;
}

MeshMetrics evaluate_meshes(const TriangleMesh& pred_mesh, const TriangleMesh& ref,
                            const EvalConfig& config) {
    using namespace mesh_metrics_internal;
    validate(config);
    // Distances are measured in the reference's frame.
    std::optional<TriangleMesh> pred_moved;
    if (pred_mesh.origin_world_m != ref.origin_world_m) {
        pred_moved = in_frame(pred_mesh, ref.origin_world_m);
    }
    const TriangleMesh& pred = pred_moved ? *pred_moved : pred_mesh;

    MeshMetrics m;
    m.threshold_m = config.threshold_m;
    m.ref_area_m2 = mesh_surface_area_m2(ref, FaceSelection::kAll);
    m.ref_observed_area_m2 = mesh_surface_area_m2(ref, FaceSelection::kObserved);
    m.pred_area_m2 = mesh_surface_area_m2(pred, FaceSelection::kAll);
    if (!(m.ref_observed_area_m2 > 0.0)) {
        throw DataError("the reference mesh has no observed surface (" +
                        std::to_string(ref.triangles.size()) + " triangles, " +
                        std::to_string(m.ref_area_m2) +
                        " m^2 in all); evaluation needs a non-empty reference with at least one "
                        "non-degenerate triangle whose face_observed flag is set");
    }

    // One density for both meshes, lowered for big scenes so no point set exceeds the budget.
    const double largest_area_m2 = std::max(m.ref_area_m2, m.pred_area_m2);
    m.sample_density_per_m2 =
        std::min(config.sample_density_per_m2,
                 static_cast<double>(config.max_samples_per_mesh) / largest_area_m2);

    const std::vector<Eigen::Vector3f> pred_points =
        sample_points(pred, m.sample_density_per_m2, config, FaceSelection::kAll);
    const std::vector<Eigen::Vector3f> ref_points =
        sample_points(ref, m.sample_density_per_m2, config, FaceSelection::kAll);
    // Each triangle samples from its own seeded stream, so the observed samples are exactly the
    // whole-mesh samples that lie on observed faces (downsampled on their own).
    std::vector<Eigen::Vector3f> ref_observed_points;
    if (!all_observed(ref)) {
        ref_observed_points =
            sample_points(ref, m.sample_density_per_m2, config, FaceSelection::kObserved);
    }
    const std::vector<Eigen::Vector3f>& completion_queries =
        all_observed(ref) ? ref_points : ref_observed_points;

    m.pred_points = pred_points.size();
    m.ref_points = ref_points.size();
    m.ref_observed_points = completion_queries.size();
    if (completion_queries.empty()) {
        throw DataError("the observed reference surface (" +
                        std::to_string(m.ref_observed_area_m2) + " m^2) received no sample at " +
                        std::to_string(m.sample_density_per_m2) +
                        " points/m^2; raise sample_density_per_m2 or max_samples_per_mesh");
    }

    // pred -> whole reference: precision and accuracy. Searching up to the larger of the two radii
    // gives exact distances for both; farther points come back at the search radius.
    const std::vector<float> pred_to_ref_m = nearest_distances_m(
        ref_points, pred_points, std::max(config.accuracy_max_m, config.threshold_m));
    m.precision = share_under(pred_to_ref_m, config.threshold_m);
    double accuracy_sum_m = 0.0;
    for (const float d : pred_to_ref_m) {
        if (d < config.accuracy_max_m) {
            accuracy_sum_m += d;
            ++m.accuracy_points;
        }
    }
    m.accuracy_m = m.accuracy_points > 0 ? accuracy_sum_m / static_cast<double>(m.accuracy_points)
                                         : config.accuracy_max_m;

    // observed reference -> pred: completion (capped) and completion ratio.
    const std::vector<float> ref_to_pred_m =
        nearest_distances_m(pred_points, completion_queries, config.completion_cap_m);
    m.completion_ratio = share_under(ref_to_pred_m, config.threshold_m);
    double completion_sum_m = 0.0;
    for (const float d : ref_to_pred_m) completion_sum_m += d;
    m.completion_m = completion_sum_m / static_cast<double>(ref_to_pred_m.size());

    m.chamfer_l1_m = 0.5 * (m.accuracy_m + m.completion_m);
    const double pr_sum = m.precision + m.completion_ratio;
    m.fscore = pr_sum > 0.0 ? 2.0 * m.precision * m.completion_ratio / pr_sum : 0.0;
    return m;
}

}  // namespace shine
