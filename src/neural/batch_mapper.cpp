#include "shine/mapper/batch_mapper.hpp"

#include <chrono>
#include <cmath>

#include "shine/core/error.hpp"
#include "shine/geometry/map_frame.hpp"
#include "shine/mapper/map_budget.hpp"
#include "shine/mapper/trainer.hpp"
#include "shine/sampling/surface_normals.hpp"

namespace shine {
namespace {
double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}
}  // namespace

BatchMapper::BatchMapper(const MapperConfig& config) : config_(config) {
    config_.finalize();
    sdf_ = std::make_unique<NeuralSdf>(config_.octree, config_.decoder);
}

BatchMapper::~BatchMapper() = default;

StageSeconds BatchMapper::add_scan(const Scan& scan) {
    StageSeconds stages;
    auto start = std::chrono::steady_clock::now();
    PreprocessStats pre;
    const std::vector<Eigen::Vector3f> points_sensor =
        preprocess_scan(scan.points_sensor, config_.preprocess, scan.source, &pre);
    stats_.preprocess += pre;
    if (!origin_set_) {
        sdf_->origin_world_m = map_origin_world_m(scan.T_world_sensor.translation());
        origin_set_ = true;
    }
    const Eigen::Isometry3d T_map_sensor =
        map_from_sensor(scan.T_world_sensor, sdf_->origin_world_m);
    const std::vector<Eigen::Vector3f> points_map =
        points_in_map_frame(points_sensor, T_map_sensor);
    const Eigen::Vector3f origin_map = T_map_sensor.translation().cast<float>();
    rays_.add_scan(origin_map, points_map);
    stages[Stage::kPreprocess] = seconds_since(start);
    stats_.load_seconds += stages[Stage::kPreprocess];

    start = std::chrono::steady_clock::now();
    sdf_->octree.allocate_cells(points_map);
    check_map_budget(*sdf_, config_.max_map_mb, stats_.frames, scan.source);
    stages[Stage::kAllocate] = seconds_since(start);
    stats_.allocate_seconds += stages[Stage::kAllocate];
    ++stats_.frames;
    stats_.rays = rays_.num_rays();
    return stages;
}

void BatchMapper::train(const std::function<void(std::size_t, double)>& on_progress) {
    if (rays_.num_rays() == 0) {
        throw DataError("no points left to map after preprocessing (check the range limits)");
    }
    auto start = std::chrono::steady_clock::now();
    if (config_.normals.enabled) rays_.set_normals(estimate_ray_normals(rays_, config_.normals));
    stats_.normals_seconds += seconds_since(start);
    start = std::chrono::steady_clock::now();
    Trainer trainer(*sdf_, config_.trainer, config_.sampling);
    const float lr0 = config_.trainer.feature_adam.learning_rate;
    const float dlr0 = config_.trainer.decoder_adam.learning_rate;
    const int iterations = config_.batch_iterations();
    TrainStepStats last;
    double bce_avg = 0.0;
    for (int it = 0; it < iterations; ++it) {
        // Cosine decay from lr to final_learning_rate_ratio * lr: large steps place the surface,
        // small ones refine it.
        const double progress = iterations > 1 ? static_cast<double>(it) / (iterations - 1) : 1.0;
        const double ratio =
            config_.final_learning_rate_ratio +
            (1.0 - config_.final_learning_rate_ratio) * 0.5 * (1.0 + std::cos(M_PI * progress));
        trainer.set_feature_learning_rate(static_cast<float>(lr0 * ratio));
        trainer.set_decoder_learning_rate(static_cast<float>(dlr0 * ratio));
        last = trainer.step(rays_, 0, rays_.num_rays(), static_cast<std::uint64_t>(it));
        bce_avg = it == 0 ? last.bce : 0.98 * bce_avg + 0.02 * last.bce;
        if (on_progress && (it % 50 == 0 || it + 1 == iterations)) on_progress(it + 1, bce_avg);
    }
    stats_.iterations += static_cast<std::size_t>(iterations);
    stats_.final_bce = last.bce;
    stats_.final_eikonal = last.eikonal;
    stats_.train_seconds += seconds_since(start);
    stats_.sample_seconds += trainer.seconds().sample;
}

}  // namespace shine
