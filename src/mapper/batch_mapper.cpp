#include "shine/mapper/batch_mapper.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <type_traits>

#include "shine/core/error.hpp"
#include "shine/core/stopwatch.hpp"
#include "shine/geometry/map_frame.hpp"
#include "shine/geometry/voxel_groups.hpp"
#include "shine/io/binary_stream.hpp"
#include "shine/mapper/checkpoint.hpp"
#include "shine/mapper/map_budget.hpp"
#include "shine/mapper/scan_in_map.hpp"
#include "shine/mapper/trainer.hpp"
#include "shine/optim/cosine_decay.hpp"
#include "shine/sampling/surface_normals.hpp"

namespace shine {
void apply_batch_defaults(MapperConfig& config) {
    if (config.resolved_scene() != ScenePreset::kOutdoor) return;
    const bool fine = config.fine_outdoor_leaf();
    if (fine && !config.is_set("bake.mask_level") && config.bake.mask_level == 0 &&
        config.octree.num_levels > 1) {
        config.bake.mask_level = 1;
    }
    if (!config.is_set("preprocess.voxel_points")) {
        config.preprocess.voxel_points = VoxelPoints::kAll;
    }
    if (config.automatic_batch_schedule() &&
        config.holds_default("training.eikonal_weight", config.trainer.eikonal_weight,
                             TrainerConfig{}.eikonal_weight)) {
        config.trainer.eikonal_weight = 0.0f;
    }
    if (!fine &&
        config.holds_default("sampling.every_point_share", config.sampling.every_point_share,
                             SamplingConfig{}.every_point_share)) {
        config.sampling.every_point_share = kCoarseOutdoorEveryPointShare;
    }
}

BatchMapper::BatchMapper(const MapperConfig& config) : config_(config) {
    config_.finalize();
    apply_batch_defaults(config_);
    sdf_ = std::make_unique<NeuralSdf>(config_.octree, config_.decoder);
}

BatchMapper::~BatchMapper() = default;

StageSeconds BatchMapper::add_scan(const Scan& scan) {
    StageSeconds stages;
    auto start = std::chrono::steady_clock::now();
    const ScanInMap in_map =
        scan_in_map_frame(scan, config_, *sdf_, origin_set_, stats_.preprocess, true);
    const std::vector<Eigen::Vector3f>& points_map = in_map.points_map;
    poses_map_.push_back(map_from_sensor(scan.T_world_sensor, sdf_->origin_world_m));
    const std::uint32_t index =
        rays_.add_scan(in_map.origin_map, points_map, in_map.voxel_begin, in_map.point_origins_map);
    const bool filter = config_.dynamic.enabled;
    if (filter) {
        if (dynamic_dropped_) {
            throw Error("BatchMapper::add_scan after training started: the map is allocated");
        }
        const auto vote_start = std::chrono::steady_clock::now();
        // The new scan's points are voted on by the scans before it, and it votes on theirs; the
        // scans after it vote when they arrive.
        // Votes are per voxel group, taken at each group's first point.
        votes_.resize(rays_.num_groups());
        if (rays_.grouped()) {
            group_leads_.reserve(rays_.num_groups());
            for (std::size_t g = group_leads_.size(); g < rays_.num_groups(); ++g) {
                group_leads_.push_back(rays_.endpoint(rays_.first_ray_of_group(g)));
            }
        }
        const auto leads = [this](std::uint32_t s) {
            const std::size_t g = rays_.group_at_or_after(rays_.first_ray(s));
            const std::size_t count = rays_.group_at_or_after(rays_.first_ray(s + 1)) - g;
            const Eigen::Vector3f* points =
                count == 0 ? nullptr : (rays_.grouped() ? &group_leads_[g] : &rays_.endpoint(g));
            return std::make_tuple(points, count, g);
        };
        Voter voter;
        voter.scan = index;
        voter.T_sensor_map =
            map_from_sensor(scan.T_world_sensor, sdf_->origin_world_m).inverse().cast<float>();
        voter.image = RangeImage(scan.points_sensor);
        voter.image.prepare_window(config_.dynamic.window_bins);  // asked for many points
        // Scans more than vote_frames apart vote as far scans (free_space_votes.hpp).
        const auto [points, count, first_group] = leads(index);
        for (const Voter& past : voters_) {
            const bool far =
                index - past.scan > static_cast<std::uint32_t>(config_.dynamic.vote_frames);
            if (count > 0) {
                add_free_space_votes(past.image, past.T_sensor_map, points, count, config_.dynamic,
                                     &votes_[first_group], far);
            }
            const auto [past_points, past_count, past_group] = leads(past.scan);
            if (past_count == 0) continue;
            add_free_space_votes(voter.image, voter.T_sensor_map, past_points, past_count,
                                 config_.dynamic, &votes_[past_group], far);
        }
        voters_.push_back(std::move(voter));
        scan_sources_.push_back(scan.source);
        const std::size_t voting_frames = static_cast<std::size_t>(
            std::max(config_.dynamic.vote_frames, config_.dynamic.far_vote_frames));
        while (voters_.size() > voting_frames) voters_.pop_front();
        stats_.dynamic_seconds += seconds_since(vote_start);
    }
    stages[Stage::kPreprocess] = seconds_since(start);
    stats_.load_seconds += stages[Stage::kPreprocess];

    if (!filter) {
        start = std::chrono::steady_clock::now();
        sdf_->octree.allocate_cells(points_map);
        check_map_budget(*sdf_, config_.max_map_mb, stats_.frames, scan.source);
        stages[Stage::kAllocate] = seconds_since(start);
        stats_.allocate_seconds += stages[Stage::kAllocate];
    }
    ++stats_.frames;
    stats_.rays = rays_.num_rays();
    return stages;
}

void BatchMapper::finish_scans() {
    drop_dynamic_points();
    // The map is complete: its rows in tree order (FeatureOctree::renumber_rows_in_tree_order),
    // once per size, and only while no optimiser state refers to the rows. Training gives the
    // same results in any row order; in tree order a step's cell lookups and feature reads
    // touch fewer cache lines.
    if (!trainer_ && sdf_->octree.num_corners() != renumbered_corners_) {
        sdf_->octree.renumber_rows_in_tree_order();
        renumbered_corners_ = sdf_->octree.num_corners();
    }
}

void BatchMapper::drop_dynamic_points() {
    if (!config_.dynamic.enabled || dynamic_dropped_) return;
    dynamic_dropped_ = true;
    auto start = std::chrono::steady_clock::now();
    const std::uint32_t num_scans = rays_.num_scans();
    // Each scan's points, their own votes (their voxel group's) and compact objects.
    std::vector<std::vector<Eigen::Vector3f>> scan_points(num_scans);
    std::vector<std::vector<std::uint8_t>> dynamic(num_scans);
    std::vector<ScanObjects> objects(num_scans);
    tbb::parallel_for(std::uint32_t(0), num_scans, [&](std::uint32_t s) {
        const std::size_t begin = rays_.first_ray(s), end = rays_.first_ray(s + 1);
        std::vector<Eigen::Vector3f>& points = scan_points[s];
        points.reserve(end - begin);
        for (std::size_t r = begin; r < end; ++r) points.push_back(rays_.endpoint(r));
        const std::vector<std::uint32_t> voxel_begin = rays_.scan_voxel_begin(s);
        const std::size_t first_group = rays_.group_at_or_after(begin);
        dynamic[s].assign(points.size(), 0);
        for_each_point_run(points.size(), voxel_begin, [&](std::size_t i, std::size_t run) {
            dynamic[s][i] = is_dynamic(votes_[first_group + run], config_.dynamic) ? 1 : 0;
        });
        if (config_.dynamic.objects.min_dynamic_share > 0.0f) {
            objects[s] = find_scan_objects(points, config_.dynamic.objects);
        }
    });
    // The points of objects that move between the scans are dynamic (moving_objects.hpp).
    if (config_.dynamic.motion.enabled) {
        std::vector<const std::vector<Eigen::Vector3f>*> views(num_scans);
        for (std::uint32_t s = 0; s < num_scans; ++s) views[s] = &scan_points[s];
        MovingObjectStats motion;
        const std::vector<std::vector<std::uint8_t>> moving =
            find_moving_points(views, config_.dynamic.objects, config_.dynamic.motion, &motion);
        for (std::uint32_t s = 0; s < num_scans; ++s) {
            for (std::size_t i = 0; i < scan_points[s].size(); ++i) dynamic[s][i] |= moving[s][i];
        }
        stats_.moving_objects += motion.moving_objects;
    }
    // The dynamic points' whole objects too; then the static rays are kept, in place.
    std::vector<std::uint8_t> keep(rays_.num_rays(), 0);
    std::vector<std::size_t> objects_dynamic(num_scans, 0);
    tbb::parallel_for(std::uint32_t(0), num_scans, [&](std::uint32_t s) {
        const std::size_t begin = rays_.first_ray(s);
        if (objects[s].object_of.size() == scan_points[s].size()) {
            objects_dynamic[s] =
                spread_dynamic_to_objects(objects[s], dynamic[s], config_.dynamic.objects)
                    .objects_dynamic;
        }
        for (std::size_t i = 0; i < dynamic[s].size(); ++i) keep[begin + i] = !dynamic[s][i];
    });
    for (const std::size_t count : objects_dynamic) stats_.dynamic_objects += count;
    scan_points.clear();  // their memory, before the rays are compacted
    const std::size_t dropped = rays_.keep_rays(keep);
    votes_ = {};
    group_leads_ = {};
    voters_ = {};
    stats_.dynamic_points_dropped = dropped;
    stats_.dynamic_seconds += seconds_since(start);
    stats_.load_seconds += seconds_since(start);

    start = std::chrono::steady_clock::now();
    std::vector<Eigen::Vector3f> points;
    for (std::uint32_t s = 0; s < rays_.num_scans(); ++s) {
        const std::size_t begin = rays_.first_ray(s), end = rays_.first_ray(s + 1);
        points.clear();
        for (std::size_t r = begin; r < end; ++r) points.push_back(rays_.endpoint(r));
        if (!points.empty()) sdf_->octree.allocate_cells(points);
        check_map_budget(*sdf_, config_.max_map_mb, s, scan_sources_[s]);
    }
    stats_.allocate_seconds += seconds_since(start);
}

bool BatchMapper::train(const std::function<void(std::size_t, double)>& on_progress,
                        const std::function<bool()>& stop) {
    return run_steps(planned_iterations(), false, on_progress, stop);
}

std::optional<std::vector<Eigen::Isometry3d>> BatchMapper::refine_poses(
    const std::function<void(std::size_t, double)>& on_progress,
    const std::function<bool()>& stop) {
    if (refinement().rounds > 0 && !run_steps(refinement_steps(), true, on_progress, stop)) {
        return std::nullopt;
    }
    return poses_world();
}

bool BatchMapper::run_steps(int until, bool refining,
                            const std::function<void(std::size_t, double)>& on_progress,
                            const std::function<bool()>& stop) {
    finish_scans();
    if (rays_.num_rays() == 0) {
        throw DataError("no points left to map after preprocessing (check the range limits)");
    }
    sdf_->octree.compact_structure();  // the map is complete: no dead slots from allocation
    auto start = std::chrono::steady_clock::now();
    if (config_.normals.enabled && !normals_done_) {
        rays_.set_normals(estimate_ray_normals(rays_, config_.normals));
    }
    normals_done_ = true;
    stats_.normals_seconds += seconds_since(start);
    start = std::chrono::steady_clock::now();
    if (!trainer_)
        trainer_ = std::make_unique<Trainer>(*sdf_, config_.batch_trainer(), config_.sampling);
    Trainer& trainer = *trainer_;
    trainer.reset_seconds();
    const BatchSchedule schedule = config_.batch_schedule(schedule_corners());
    const float lr0 = schedule.learning_rate;
    const float dlr0 = config_.trainer.decoder_adam.learning_rate;
    const int iterations = schedule.iterations;
    const PoseRefinementConfig refine = refinement();
    // Pose refinement's rounds (pose_refinement.hpp) between the steps of refine_poses(): every
    // scan registered to the map as it stands and its rays moved, then training goes on.
    const auto run_rounds = [&](int step) {
        while (refining && static_cast<int>(rounds_.size()) < refine.rounds &&
               refine.round_step(static_cast<int>(rounds_.size()), iterations) <= step) {
            PoseRefinementRound round;
            round_start_poses_.push_back(poses_map_);  // the poses the steps before trained at
            std::vector<Eigen::Isometry3d> refined = refine_scan_poses(
                *sdf_, rays_, poses_map_, refine, static_cast<int>(rounds_.size()), &round);
            move_scans(rays_, poses_map_, refined);
            poses_map_ = std::move(refined);
            round.step = step;
            rounds_.push_back(round);
        }
    };
    bool stopped = false;
    while (iterations_done_ < until) {
        const int it = iterations_done_;
        run_rounds(it);
        // Cosine decay from lr to final_learning_rate_ratio * lr: large steps place the surface,
        // small ones refine it.
        const double ratio = cosine_decay_ratio(it, iterations, config_.final_learning_rate_ratio);
        trainer.set_feature_learning_rate(static_cast<float>(lr0 * ratio));
        trainer.set_decoder_learning_rate(static_cast<float>(dlr0 * ratio));
        const TrainStepStats last =
            trainer.step(rays_, 0, rays_.num_rays(), static_cast<std::uint64_t>(it));
        bce_average_ = it == 0 ? last.bce : 0.98 * bce_average_ + 0.02 * last.bce;
        stats_.final_bce = last.bce;
        stats_.final_eikonal = last.eikonal;
        ++iterations_done_;
        ++stats_.iterations;
        if (on_progress && (it % 50 == 0 || it + 1 == until)) on_progress(it + 1, bce_average_);
        if (stop && iterations_done_ < until && stop()) {
            stopped = true;
            break;
        }
    }
    if (refining && !stopped) run_rounds(until);
    stats_.train_seconds += seconds_since(start);
    stats_.sample_seconds += trainer.seconds().sample;
    return !stopped;
}

void BatchMapper::save_state(BinaryWriter& out) const {
    out.tag("batch mapper");
    static_assert(std::is_trivially_copyable_v<MappingStats>);
    out.value(stats_);
    out.value<std::int32_t>(iterations_done_);
    out.value(bce_average_);
    save_sdf_parameters(out, *sdf_);
    out.value<std::uint8_t>(trainer_ ? 1 : 0);
    if (trainer_) trainer_->save_state(out);
}

void BatchMapper::load_state(BinaryReader& in) {
    in.expect_tag("batch mapper");
    const auto stats = in.value<MappingStats>("mapping statistics");
    finish_scans();  // as train() did before the checkpoint
    if (stats.frames != stats_.frames || stats.rays != stats_.rays) {
        in.fail("mapping statistics",
                "record " + std::to_string(stats.frames) + " scans with " +
                    std::to_string(stats.rays) + " points, but the data now gives " +
                    std::to_string(stats_.frames) + " scans with " + std::to_string(stats_.rays) +
                    " (did the data or the frame selection change?)");
    }
    const auto iterations_done = in.value<std::int32_t>("iterations done");
    if (iterations_done < 0 || iterations_done > planned_iterations()) {
        in.fail("iterations done", std::to_string(iterations_done) + " is outside 0.." +
                                       std::to_string(planned_iterations()));
    }
    const auto bce_average = in.value<double>("running BCE");
    load_sdf_parameters(in, *sdf_);
    if (in.value<std::uint8_t>("trainer flag")) {
        trainer_ = std::make_unique<Trainer>(*sdf_, config_.batch_trainer(), config_.sampling);
        trainer_->load_state(in);
    } else {
        trainer_.reset();
    }
    // The time and the steps spent before the interruption count; the load and allocate stages
    // just ran again and are counted again.
    const MappingStats reloaded = stats_;
    stats_ = stats;
    stats_.load_seconds += reloaded.load_seconds;
    stats_.allocate_seconds += reloaded.allocate_seconds;
    stats_.dynamic_seconds += reloaded.dynamic_seconds;
    normals_done_ = false;  // the normals are not stored: train() estimates them again
    iterations_done_ = iterations_done;
    bce_average_ = bce_average;
}

std::size_t BatchMapper::warm_start(const NeuralSdf& source, int first_step) {
    finish_scans();
    if (trainer_ || iterations_done_ > 0) {
        throw ConfigError("warm start: training has already begun");
    }
    if (source.origin_world_m != sdf_->origin_world_m ||
        source.decoder.num_params() != sdf_->decoder.num_params()) {
        throw ConfigError("warm start: the maps differ in origin or decoder shape");
    }
    const std::size_t copied = sdf_->octree.copy_shared_features(source.octree);
    sdf_->decoder = source.decoder;
    iterations_done_ = std::clamp(first_step, 0, planned_iterations());
    return copied;
}

PoseRefinementConfig BatchMapper::refinement() const { return config_.scaled_refinement(); }

int BatchMapper::refinement_steps() const {
    const PoseRefinementConfig refine = refinement();
    if (refine.rounds <= 0) return 0;
    return refine.round_step(refine.rounds - 1, planned_iterations());
}

std::vector<Eigen::Isometry3d> BatchMapper::poses_world() const {
    std::vector<Eigen::Isometry3d> poses = poses_map_;
    for (Eigen::Isometry3d& T : poses) T.translation() += sdf_->origin_world_m;
    return poses;
}

RelativePoseChange BatchMapper::refinement_relative_change() const {
    RelativePoseChange largest;
    for (const std::vector<Eigen::Isometry3d>& trained_at : round_start_poses_) {
        const RelativePoseChange change = relative_pose_change(trained_at, poses_map_);
        largest.median_translation_m =
            std::max(largest.median_translation_m, change.median_translation_m);
        largest.median_rotation_deg =
            std::max(largest.median_rotation_deg, change.median_rotation_deg);
    }
    return largest;
}

int BatchMapper::planned_iterations() const { return config_.batch_iterations(schedule_corners()); }

std::size_t BatchMapper::schedule_corners() const {
    return schedule_corners_ > 0 ? schedule_corners_ : sdf_->octree.num_corners();
}

}  // namespace shine
