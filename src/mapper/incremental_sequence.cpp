#include "shine/mapper/incremental_sequence.hpp"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <optional>
#include <thread>
#include <type_traits>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/core/stopwatch.hpp"
#include "shine/geometry/map_frame.hpp"
#include "shine/geometry/ray_caster.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/tum.hpp"
#include "shine/mapper/background_training.hpp"
#include "shine/mesh/level_set_mesh.hpp"
#include "shine/odometry/se3.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace {
std::string frame_name(std::size_t frame) {
    char name[32];
    std::snprintf(name, sizeof(name), "mesh_%06zu.ply", frame);
    return name;
}

/// Deskews scan `i` of `sequence` for mapping (sequence_deskew.hpp): with the sequence's poses,
/// or with the motion the odometry estimated during its sweep, or where it estimated none, the
/// motion from pose i-1 to the estimated pose i (scan 0 as measured).
void deskew_for_mapping(Scan& scan, const ScanSequence& sequence, std::size_t i,
                        const DeskewConfig& config, const ScanOdometry* odometry,
                        DeskewStats& stats) {
    if (!odometry) {
        deskew_with_sequence_poses(scan, sequence, i, config, stats);
        return;
    }
    if (config.mode == DeskewMode::kOn) require_point_times(scan);
    const bool estimated = odometry->records().at(i).sweep_estimated;
    if (scan.point_time_s.empty() || (i == 0 && !estimated)) {
        ++stats.scans_as_measured;
        return;
    }
    const std::vector<Eigen::Isometry3d>& poses = odometry->poses();
    const Eigen::Isometry3d motion =
        estimated ? odometry->sweep_motion(i) : poses.at(i - 1).inverse() * poses.at(i);
    // A sweep's motion is over the interval to the scan before it; the first scan's (from the
    // bootstrap) over the interval to the next one.
    const double interval_s = i == 0 ? scan_interval_s(sequence, 0, 1, config.scan_period_s)
                                     : scan_interval_s(sequence, i - 1, i, config.scan_period_s);
    deskew_in_place(scan, motion, interval_s, stats);
}

/// The prior of scan i's sweep motion for its registration (scans with per-point times): for the
/// second scan the first sweep's motion (when bootstrap_sweep estimated it), for later scans the
/// constant-velocity motion of the last two estimated poses over scan i's interval; none for the
/// first scan, which is registered as measured.
std::optional<SweepPrior> sweep_prior(const ScanSequence& sequence, std::size_t i,
                                      const ScanOdometry& odometry, double scan_period_s) {
    if (i == 0 || (i == 1 && !odometry.records()[0].sweep_estimated)) return std::nullopt;
    SweepPrior sweep;
    sweep.interval_s = scan_interval_s(sequence, i - 1, i, scan_period_s);
    if (i == 1) {
        sweep.T_expected = odometry.sweep_motion(0);
        return sweep;
    }
    const std::vector<Eigen::Isometry3d>& poses = odometry.poses();
    const double previous_s = scan_interval_s(sequence, i - 2, i - 1, scan_period_s);
    sweep.T_expected = interpolate_constant_velocity(poses[i - 2].inverse() * poses[i - 1],
                                                     sweep.interval_s / previous_s);
    return sweep;
}

/// A keyframe's training: the steps of how many scans (itself and, with
/// keyframes.keyframe_takes_deferred_steps, the scans deferred as redundant since the keyframe
/// before it); counts the deferred scans whose steps it took.
int keyframe_step_scans(const KeyframeConfig& config, IncrementalSequenceMap& result) {
    const std::size_t owed = config.keyframe_takes_deferred_steps ? result.steps_owed : 0;
    result.steps_owed = 0;
    result.deferred_steps_taken += owed;
    return 1 + static_cast<int>(owed);
}

/// A scan deferred by `choice`: a redundant one's steps are owed to the next keyframe (the scans
/// deferred by the budget or while the training was busy are not: the map could not take them).
void owe_steps(const KeyframeChoice& choice, IncrementalSequenceMap& result) {
    if (choice.reason == KeyframeReason::kRedundant) ++result.steps_owed;
}

// Incremental checkpoints: the frames done, the mapper's state, the stage profile so far and the
// progress meshes written so far.
void write_incremental_checkpoint(const RunControl& control, const IncrementalSequenceMap& result,
                                  std::size_t frames_done) {
    write_checkpoint(control.checkpoint_path, control.run_description, CheckpointMode::kIncremental,
                     [&](BinaryWriter& out) {
                         out.value<std::uint64_t>(frames_done);
                         // Only with odometry (its own tagged section): the checkpoints of
                         // runs with given poses keep their layout.
                         if (result.odometry) result.odometry->save(out);
                         if (result.keyframes) {
                             result.keyframes->save(out);
                             static_assert(std::is_trivially_copyable_v<KeyframeChoice>);
                             out.array(result.keyframe_choices.data(), frames_done);
                             out.array(std::vector<std::uint64_t>(result.deferred.begin(),
                                                                  result.deferred.end()));
                         }
                         result.mapper->save_state(out);
                         static_assert(std::is_trivially_copyable_v<StageSeconds>);
                         out.array(result.profile.frames);
                         out.value<std::uint64_t>(result.progress_meshes.size());
                         for (const ProgressMesh& m : result.progress_meshes) {
                             out.value<std::uint64_t>(m.frame);
                             out.string(m.path.string());
                             out.value<std::uint64_t>(m.triangles);
                             out.value(m.bake_seconds);
                             out.value(m.write_seconds);
                         }
                     });
}

/// Replays the checkpoint's frames into `result` and restores its state; returns the frames done.
std::size_t resume_incremental(const RunControl& control, const ScanSequence& sequence,
                               IncrementalSequenceMap& result, const std::string& progress_tag,
                               const DeskewConfig* deskew) {
    std::string description;
    CheckpointMode mode;
    BinaryReader in = read_checkpoint_header(control.checkpoint_path, description, mode);
    if (mode != CheckpointMode::kIncremental) {
        throw IoError("checkpoint '" + control.checkpoint_path.string() +
                      "' belongs to a batch-mode run, not an incremental-mode one");
    }
    const auto frames_done = in.value<std::uint64_t>("frames done");
    if (frames_done > sequence.size()) {
        in.fail("frames done", std::to_string(frames_done) + " exceeds the sequence's " +
                                   std::to_string(sequence.size()) + " scans");
    }
    const bool has_odometry = in.next_is_tag("scan odometry");
    if (has_odometry != (result.odometry != nullptr)) {
        in.fail("odometry section", has_odometry ? "is there, but this run reads its poses"
                                                 : "is missing, but this run estimates its poses");
    }
    if (result.odometry) {
        result.odometry->load(in);
        if (result.odometry->poses().size() != frames_done) {
            in.fail("estimated poses", std::to_string(result.odometry->poses().size()) +
                                           " poses for " + std::to_string(frames_done) +
                                           " frames done");
        }
    }
    if (result.keyframes) {
        result.keyframes->load(in);
        result.keyframe_choices = in.array<KeyframeChoice>("keyframe choices");
        if (result.keyframe_choices.size() != frames_done) {
            in.fail("keyframe choices", std::to_string(result.keyframe_choices.size()) + " for " +
                                            std::to_string(frames_done) + " frames done");
        }
        for (const std::uint64_t j : in.array<std::uint64_t>("deferred scans")) {
            if (j >= frames_done) in.fail("deferred scans", "name a scan not done yet");
            result.deferred.push_back(static_cast<std::size_t>(j));
        }
    }
    {
        Progress progress(progress_tag.empty() ? "replay" : "replay " + progress_tag, frames_done);
        for (std::size_t i = 0; i < frames_done; ++i) {
            Scan scan = sequence.load(i);
            if (result.odometry) {
                scan.T_world_sensor = result.odometry->poses()[i];
                if (!result.odometry->mapped(i)) continue;
            }
            if (result.keyframes && !result.keyframe_choices[i].train) {
                // Deferred: not in the map yet, but in the odometry's ICP reference, as measured.
                owe_steps(result.keyframe_choices[i], result);
                result.odometry->remember_scan(scan);
                continue;
            }
            if (result.keyframes) {
                keyframe_step_scans(result.keyframes->config(), result);
            }
            if (deskew) {
                deskew_for_mapping(scan, sequence, i, *deskew, result.odometry.get(),
                                   result.deskew);
            }
            result.mapper->replay_scan(scan);
            result.mapper_scans.push_back(i);
            if (result.odometry) result.odometry->remember_scan(scan);
            progress.update(i + 1);
        }
        progress.finish("map rebuilt");
    }
    result.mapper->load_state(in);
    result.profile.frames = in.array<StageSeconds>("stage profile");
    const auto meshes = in.value<std::uint64_t>("progress mesh count");
    if (meshes > frames_done) in.fail("progress mesh count", "exceeds the frames done");
    for (std::uint64_t k = 0; k < meshes; ++k) {
        ProgressMesh m;
        m.frame = in.value<std::uint64_t>("progress mesh frame");
        m.path = in.string("progress mesh path");
        m.triangles = in.value<std::uint64_t>("progress mesh triangles");
        m.bake_seconds = in.value<double>("progress mesh seconds");
        m.write_seconds = in.value<double>("progress mesh seconds");
        result.progress_meshes.push_back(m);
    }
    in.expect_end();
    return static_cast<std::size_t>(frames_done);
}
/// The deferred scans after the last one (keyframe_policy.hpp): each loaded again, placed at its
/// estimated pose, deskewed as it would have been, and integrated untrained, in order.
void catch_up_deferred(const ScanSequence& sequence, const MapperConfig& config, bool deskew,
                       IncrementalSequenceMap& result, const std::string& progress_tag) {
    const auto start = std::chrono::steady_clock::now();
    Progress progress(progress_tag.empty() ? "catch up" : "catch up " + progress_tag,
                      result.deferred.size());
    std::size_t done = 0;
    StageSeconds stages;
    for (const std::size_t i : result.deferred) {
        const auto t_load = std::chrono::steady_clock::now();
        Scan scan = sequence.load(i);
        stages[Stage::kLoad] += seconds_since(t_load);
        scan.T_world_sensor = result.odometry->poses().at(i);
        if (deskew) {
            deskew_for_mapping(scan, sequence, i, config.deskew, result.odometry.get(),
                               result.deskew);
        }
        stages += result.mapper->add_scan_untrained(scan).stages;
        result.mapper_scans.push_back(i);
        progress.update(++done);
    }
    result.keyframes->counts().caught_up += result.deferred.size();
    result.deferred.clear();
    result.catch_up_seconds = seconds_since(start);
    result.profile.run += stages;
    char detail[64];
    std::snprintf(detail, sizeof(detail), "%zu deferred scans, %.2f s", done,
                  result.catch_up_seconds);
    progress.finish(detail);
}
/// Every scan's pose after a consolidation that refined the kept scans' poses: the kept scans
/// (the last of result.mapper_scans) corrected, T_world_new = T_world_map C T_map_world T_world,
/// the others as mapped.
std::vector<Eigen::Isometry3d> refined_after_consolidation(const ScanSequence& sequence,
                                                           const IncrementalSequenceMap& result) {
    std::vector<Eigen::Isometry3d> poses(sequence.size());
    for (std::size_t i = 0; i < sequence.size(); ++i) {
        poses[i] = result.odometry ? result.odometry->poses()[i] : sequence.pose(i);
    }
    const std::vector<Eigen::Isometry3d>& corrections =
        result.mapper->consolidation().corrections_map;
    if (corrections.size() > result.mapper_scans.size()) {
        throw Error("pose refinement: " + std::to_string(corrections.size()) + " corrections for " +
                    std::to_string(result.mapper_scans.size()) + " integrated scans");
    }
    Eigen::Isometry3d T_world_map = Eigen::Isometry3d::Identity();
    T_world_map.translation() = result.mapper->sdf().origin_world_m;
    const std::size_t first = result.mapper_scans.size() - corrections.size();
    for (std::size_t k = 0; k < corrections.size(); ++k) {
        const std::size_t i = result.mapper_scans[first + k];
        poses.at(i) = T_world_map * corrections[k] * T_world_map.inverse() * poses.at(i);
    }
    return poses;
}

/// The old drive's viewpoints that vote on a continued map's new scans: one wherever the sensor
/// moved this far or turned this much since the last.
constexpr double kViewpointSpacingM = 2.0;
constexpr double kViewpointTurnDeg = 15.0;
}  // namespace

std::vector<std::pair<Eigen::Isometry3f, RangeImage>> surface_viewpoints(
    const TriangleMesh& surface, const std::vector<Eigen::Isometry3d>& trajectory_world,
    const Eigen::Vector3d& origin_world_m, const std::vector<Eigen::Vector3f>& points_sensor,
    double max_range_m) {
    const TriangleMesh surface_map = in_frame(surface, origin_world_m);
    const RayCaster caster(surface_map);
    std::vector<Eigen::Vector3d> directions;
    directions.reserve(points_sensor.size());
    for (const Eigen::Vector3f& p : points_sensor) {
        const double range = p.cast<double>().norm();
        if (std::isfinite(range) && range > 1e-6) directions.push_back(p.cast<double>() / range);
    }
    std::vector<std::pair<Eigen::Isometry3f, RangeImage>> viewpoints(trajectory_world.size());
    tbb::parallel_for(std::size_t(0), trajectory_world.size(), [&](std::size_t k) {
        const Eigen::Isometry3d T_map_sensor = map_from_sensor(trajectory_world[k], origin_world_m);
        const Eigen::Vector3d origin = T_map_sensor.translation();
        std::vector<Eigen::Vector3f> returns_sensor;
        returns_sensor.reserve(directions.size());
        for (const Eigen::Vector3d& d : directions) {
            const RayHit hit = caster.cast(origin, T_map_sensor.linear() * d, 0.0, max_range_m);
            if (hit.hit()) returns_sensor.push_back((d * hit.distance_m).cast<float>());
        }
        viewpoints[k] = {T_map_sensor.inverse().cast<float>(), RangeImage(returns_sensor)};
    });
    return viewpoints;
}

IncrementalSequenceMap map_sequence_incremental(
    const MapperConfig& config_in, const ScanSequence& sequence, const fs::path& out_dir,
    const std::string& progress_tag, const RunControl* control, const MapToContinue* from) {
    MapperConfig config = config_in;
    config.finalize();
    if (from) {
        if (!from->sdf) throw Error("map_sequence_incremental: MapToContinue without a map");
        if (config.odometry.estimate_poses) {
            throw ConfigError("continuing map '" + from->file.string() +
                              "' needs the new scans' poses in its world frame: give a pose file, "
                              "or localise the scans in the map (`shine map --from` does so for "
                              "scans without poses, or with --poses estimate), not "
                              "odometry.estimate_poses");
        }
        if (control && control->resume) {
            throw ConfigError("a run that continues map '" + from->file.string() +
                              "' cannot be resumed from a checkpoint; start it again");
        }
        control = nullptr;  // no checkpoint: a resume would not have the old map
    }
    ensure_directory(out_dir);
    const int mesh_every = config.incremental.mesh_every;
    if (mesh_every > 0) ensure_directory(out_dir / "progress");
    IncrementalSequenceMap result;
    if (from) {
        // The old map's decoder replaces the pretrained one, which is not loaded.
        MapperConfig mapper_config = config;
        mapper_config.incremental.decoder_weights = "none";
        result.mapper = std::make_unique<IncrementalMapper>(mapper_config);
        result.mapper->start_from(std::move(*from->sdf), from->file.string());
        // Stored with the new map: where its decoder came from.
        config.incremental.decoder_weights = from->file.string();
    } else {
        result.mapper = std::make_unique<IncrementalMapper>(config);
    }
    IncrementalMapper& mapper = *result.mapper;
    if (config.odometry.estimate_poses) {
        result.odometry = std::make_unique<ScanOdometry>(config.odometry);
        result.keyframes = std::make_unique<KeyframePolicy>(config.incremental.keyframes);
    }
    const bool checkpoints = control && !control->checkpoint_path.empty();
    const bool deskew =
        deskew_active(config.deskew, config.odometry.estimate_poses, sequence.has_sweep_times());
    result.deskew.active = deskew;
    std::size_t first_frame = 0;
    if (checkpoints && control->resume) {
        first_frame = resume_incremental(*control, sequence, result, progress_tag,
                                         deskew ? &config.deskew : nullptr);
    }
    CheckpointClock clock(checkpoints ? control->checkpoint_interval_s : 0.0);
    // A test hook: SHINE_TEST_TRAINING_DELAY_MS makes each trained scan that much slower, as on a
    // slower machine, to check that a budget (keyframes.max_ms_per_scan) is kept.
    const std::chrono::milliseconds training_delay(
        std::getenv("SHINE_TEST_TRAINING_DELAY_MS")
            ? std::max(0, std::atoi(std::getenv("SHINE_TEST_TRAINING_DELAY_MS")))
            : 0);
    // With a budget, the keyframes train in the background (background_training.hpp).
    std::unique_ptr<BackgroundTraining> trainer;
    if (result.keyframes && config.incremental.keyframes.enabled &&
        config.incremental.keyframes.max_ms_per_scan > 0.0) {
        trainer = std::make_unique<BackgroundTraining>(mapper);
    }
    {
        Progress progress(progress_tag.empty() ? "map" : "map " + progress_tag, sequence.size());
        if (first_frame > 0) progress.update(first_frame, "resumed");
        // With odometry, the next scan is loaded and its registration prepared (what needs no
        // map: its points, the prediction, ICP) while the map trains on the current one; an
        // error on the way is kept for that scan's turn.
        struct Ahead {
            std::size_t index = 0;
            Scan scan;
            double load_seconds = 0.0;
            std::optional<PreparedScan> prepared;
            std::exception_ptr error;
        };
        std::optional<Ahead> ahead;
        const auto load_scan = [&](std::size_t j, Scan& scan, double& load_seconds) {
            const auto t_load = std::chrono::steady_clock::now();
            scan = sequence.load(j);
            load_seconds = seconds_since(t_load);
            if (deskew && config.deskew.mode == DeskewMode::kOn) require_point_times(scan);
        };
        const auto prepare_scan = [&](std::size_t j, const Scan& scan) {
            // Registered with the last estimated motion (the prediction's velocity) as its
            // sweep's prior (bootstrap_sweep below gives the first sweep's).
            std::optional<SweepPrior> sweep;
            if (deskew && !scan.point_time_s.empty()) {
                sweep = sweep_prior(sequence, j, *result.odometry, config.deskew.scan_period_s);
            }
            return result.odometry->prepare(scan, sweep ? &*sweep : nullptr);
        };
        // Loads and prepares scan j (when there is one) into `ahead`; an error is kept for j's
        // turn.
        const auto prepare_ahead = [&](std::size_t j) {
            if (j >= sequence.size()) return;
            ahead.emplace();
            ahead->index = j;
            try {
                load_scan(j, ahead->scan, ahead->load_seconds);
                ahead->prepared = prepare_scan(j, ahead->scan);
            } catch (...) {
                ahead->error = std::current_exception();
            }
        };
        // The stage profile of the scan the background training finished, if any.
        const auto take_trained = [&] {
            if (std::optional<TrainedScan> done = trainer->take_finished()) {
                result.profile.frames.push_back(done->stats.stages);
            }
        };
        // Waits for the background training (if any) and takes its scan.
        const auto collect_trained = [&] {
            if (!trainer) return;
            trainer->wait();
            take_trained();
        };
        for (std::size_t i = first_frame; i < sequence.size(); ++i) {
            const auto t_scan = std::chrono::steady_clock::now();
            Scan scan;
            double load_seconds = 0.0;
            std::optional<PreparedScan> prepared;
            if (ahead && ahead->index == i) {
                if (ahead->error) std::rethrow_exception(ahead->error);
                scan = std::move(ahead->scan);
                load_seconds = ahead->load_seconds;
                prepared = std::move(ahead->prepared);
            } else {
                load_scan(i, scan, load_seconds);
            }
            ahead.reset();
            const OdometryRecord* pose = nullptr;
            if (result.odometry) {
                if (!prepared) prepared = prepare_scan(i, scan);
                if (trainer) {
                    // The map as the last trained keyframe left it: registration never waits.
                    take_trained();
                    const std::shared_ptr<const NeuralSdf> map = trainer->snapshot();
                    pose = &result.odometry->finish(std::move(*prepared), *map);
                } else {
                    pose = &result.odometry->finish(std::move(*prepared), mapper.sdf());
                }
                if (deskew && i == 0 && sequence.size() > 1 && !scan.point_time_s.empty()) {
                    // No pose before the first scan tells its sweep's motion: the next scan
                    // does, before the first is mapped.
                    result.odometry->bootstrap_sweep(
                        scan, sequence.load(1),
                        scan_interval_s(sequence, 0, 1, config.deskew.scan_period_s));
                }
                scan.T_world_sensor = result.odometry->poses().back();
            }
            // Keyframes train now; the other scans wait for the catch-up after the last one.
            KeyframeChoice choice;
            if (result.keyframes) {
                choice = pose->source == PoseSource::kSkipped
                             ? KeyframeChoice{false, KeyframeReason::kRedundant}
                             : result.keyframes->choose(*pose, scan.T_world_sensor);
                if (choice.train && trainer && trainer->busy()) {
                    choice = {false, KeyframeReason::kBusy};
                }
            }
            double train_seconds = 0.0;
            if (deskew && choice.train && !(pose && pose->source == PoseSource::kSkipped)) {
                deskew_for_mapping(scan, sequence, i, config.deskew, result.odometry.get(),
                                   result.deskew);
            }
            if (pose && pose->source == PoseSource::kSkipped) {
                std::fprintf(stderr,
                             "\nwarning: scan %zu ('%s') has %llu registration points, fewer than "
                             "odometry.min_scan_points = %d: not mapped, its pose is the "
                             "constant-velocity prediction\n",
                             i, scan.source.string().c_str(),
                             static_cast<unsigned long long>(pose->points),
                             config.odometry.min_scan_points);
                progress.update(i + 1, "skipped");
            } else if (!choice.train) {
                // Registered only: its points join the ICP reference, and the next scan is
                // prepared; the scan itself is integrated after the last one.
                result.deferred.push_back(i);
                owe_steps(choice, result);
                if (result.deferred.size() >
                    static_cast<std::size_t>(config.incremental.keyframes.max_deferred_scans)) {
                    result.deferred.pop_front();
                    ++result.keyframes->counts().skipped;
                }
                result.odometry->remember_scan(scan);
                prepare_ahead(i + 1);
                StageSeconds stages;
                stages[Stage::kLoad] = load_seconds;
                result.profile.frames.push_back(stages);
                char detail[128];
                std::snprintf(detail, sizeof(detail), "pose %s (%.2f s), deferred (%s)",
                              to_string(pose->source), pose->seconds, to_string(choice.reason));
                progress.update(i + 1, detail);
            } else if (trainer) {
                // Trained in the background; this thread goes on with the next scan.
                result.odometry->remember_scan(scan);
                const int step_scans = keyframe_step_scans(config.incremental.keyframes, result);
                trainer->submit(i, std::move(scan), step_scans, training_delay);
                result.mapper_scans.push_back(i);
                prepare_ahead(i + 1);
                char detail[128];
                std::snprintf(detail, sizeof(detail), "pose %s (%.2f s), training",
                              to_string(pose->source), pose->seconds);
                progress.update(i + 1, detail);
            } else {
                const auto t_train = std::chrono::steady_clock::now();
                // The scan joins the odometry's ICP reference, and the next scan is prepared,
                // while the map trains on it: they share nothing, and the next scan's
                // registration to the map (finish) waits for both.
                const IncrementalFrameStats* mapped = nullptr;
                result.mapper_scans.push_back(i);
                const int step_scans =
                    result.keyframes ? keyframe_step_scans(config.incremental.keyframes, result)
                                     : 1;
                if (result.odometry) {
                    tbb::parallel_invoke([&] { mapped = &mapper.add_scan(scan, step_scans); },
                                         [&] {
                                             result.odometry->remember_scan(scan);
                                             prepare_ahead(i + 1);
                                         });
                } else {
                    mapped = &mapper.add_scan(scan, step_scans);
                }
                if (training_delay.count() > 0) std::this_thread::sleep_for(training_delay);
                const IncrementalFrameStats& frame = *mapped;
                train_seconds = seconds_since(t_train);
                StageSeconds stages = frame.stages;
                stages[Stage::kLoad] = load_seconds;
                result.profile.frames.push_back(stages);
                char detail[128];
                if (pose) {
                    std::snprintf(detail, sizeof(detail),
                                  "%.2f s/frame, pose %s (%.2f s), bce %.4f, %zu corners",
                                  frame.total_seconds + pose->seconds, to_string(pose->source),
                                  pose->seconds, frame.bce, mapper.sdf().octree.num_corners());
                } else {
                    std::snprintf(detail, sizeof(detail), "%.2f s/frame, bce %.4f, %zu corners",
                                  frame.total_seconds, frame.bce,
                                  mapper.sdf().octree.num_corners());
                }
                progress.update(i + 1, detail);
            }
            if (trainer && trainer->busy()) {
                // The rest of the scan's budget goes to the training: the sensor's next scan
                // would not have come yet.
                const double left_s =
                    1e-3 * config.incremental.keyframes.max_ms_per_scan - seconds_since(t_scan);
                if (left_s > 0.0) trainer->wait_for(left_s);
            }
            result.scan_wall_seconds.push_back(seconds_since(t_scan));
            if (result.keyframes) {
                if (!(pose && pose->source == PoseSource::kSkipped)) {
                    result.keyframes->record(choice, result.odometry->poses()[i],
                                             result.scan_wall_seconds.back(), train_seconds);
                }
                result.keyframe_choices.push_back(choice);
            }
            const bool last = i + 1 == sequence.size();
            if (mesh_every > 0 && ((i + 1) % static_cast<std::size_t>(mesh_every) == 0) && !last) {
                collect_trained();
                ProgressMesh snapshot;
                snapshot.frame = i;
                auto t0 = std::chrono::steady_clock::now();
                const auto surface = bake_level_set(mapper.sdf(), config.bake);
                const TriangleMesh mesh = mesh_level_set(*surface, config.mesh);
                snapshot.bake_seconds = seconds_since(t0);
                t0 = std::chrono::steady_clock::now();
                snapshot.path = out_dir / "progress" / frame_name(i);
                write_ply_mesh(snapshot.path, mesh);
                snapshot.write_seconds = seconds_since(t0);
                snapshot.triangles = mesh.triangles.size();
                result.progress_meshes.push_back(snapshot);
            }
            if (checkpoints && control->stop_requested && control->stop_requested()) {
                collect_trained();
                progress.finish("stopped");
                write_incremental_checkpoint(*control, result, i + 1);
                throw_stopped_with_checkpoint(*control, "after frame " + std::to_string(i + 1) +
                                                            " of " +
                                                            std::to_string(sequence.size()));
            }
            if (checkpoints && clock.due() && !last) {
                collect_trained();
                write_incremental_checkpoint(*control, result, i + 1);
                clock.reset();
            }
        }
        collect_trained();
        char detail[64];
        std::snprintf(detail, sizeof(detail), "median %.2f s/frame", mapper.median_frame_seconds());
        progress.finish(detail);
    }
    if (result.odometry) {
        const std::vector<Eigen::Isometry3d>& poses = result.odometry->poses();
        write_kitti_poses(out_dir / "poses.txt", poses);
        if (sequence.from_recording()) {
            std::vector<StampedPose> stamped(poses.size());
            for (std::size_t i = 0; i < poses.size(); ++i) {
                stamped[i].timestamp_s = sequence.stamp_s(i);
                stamped[i].T_world_sensor = poses[i];
            }
            write_tum_poses(out_dir / "poses_tum.txt", stamped);
        }
    }
    int consolidation_steps = mapper.config().incremental.consolidation_steps;
    if (!result.deferred.empty()) {
        if (consolidation_steps > 0) {
            // The steps the deferred scans did not take when they came are taken here, over
            // every kept scan, so that the final map gets at least the training of a run that
            // trains every scan (with keyframe_takes_deferred_steps the keyframes took them
            // once more, for the online map that registration reads).
            consolidation_steps += static_cast<int>(result.deferred.size()) *
                                   mapper.config().incremental.iterations_per_frame;
            catch_up_deferred(sequence, config, deskew, result, progress_tag);
        } else {
            // Nothing would train them: the map is as the keyframes left it.
            result.keyframes->counts().skipped += result.deferred.size();
            result.deferred.clear();
        }
    }
    if (from && from->surface && !from->trajectory_world.empty() && sequence.size() > 0 &&
        mapper.keeps_scan_images()) {
        // The old drive votes on the new drive's movers, from where it was, through the old
        // surface, in the new drive's LiDAR pattern.
        const auto start = std::chrono::steady_clock::now();
        // Viewpoints 2 m or 15 degrees apart: on the street, every second pose of a drive 1 m a
        // scan apart gave the F-score of every pose (95.384 against 95.385 %) in 1.2 s instead
        // of 2.0; every fourth 95.372 %.
        // Only poses within the LiDAR's range of a new scan can see what the new scans saw (a
        // city's old map has many more).
        const double reach_m = config.preprocess.max_range_m;
        const auto near_new_drive = [&](const Eigen::Isometry3d& pose) {
            for (std::size_t i = 0; i < sequence.size(); ++i) {
                if ((sequence.pose(i).translation() - pose.translation()).norm() <= reach_m) {
                    return true;
                }
            }
            return false;
        };
        std::vector<Eigen::Isometry3d> viewpoints;
        for (const Eigen::Isometry3d& pose : from->trajectory_world) {
            if (!near_new_drive(pose)) continue;
            if (!viewpoints.empty()) {
                const Eigen::Isometry3d step = viewpoints.back().inverse() * pose;
                if (step.translation().norm() < kViewpointSpacingM &&
                    rotation_angle_rad(step) < kViewpointTurnDeg * M_PI / 180.0) {
                    continue;
                }
            }
            viewpoints.push_back(pose);
        }
        result.old_viewpoints = viewpoints.size();
        mapper.add_old_viewpoints(
            surface_viewpoints(*from->surface, viewpoints, mapper.sdf().origin_world_m,
                               sequence.load(0).points_sensor, config.preprocess.max_range_m));
        result.old_viewpoint_seconds = seconds_since(start);
    }
    if (consolidation_steps > 0 && sequence.size() > 0) {
        // The kept scans trained together before the bake (IncrementalConfig). Like the bake, it
        // runs to its end once started: a stop request is honoured before it, after the last
        // frame's checkpoint.
        Progress progress(progress_tag.empty() ? "consolidate" : "consolidate " + progress_tag,
                          static_cast<std::size_t>(consolidation_steps));
        const PoseRefinementConfig refine = mapper.config().scaled_refinement();
        const bool refining = mapper.config().refines_in_consolidation();
        const ConsolidationStats& done = mapper.consolidate(
            consolidation_steps,
            [&](int step, int) { progress.update(static_cast<std::size_t>(step)); },
            refining ? &refine : nullptr);
        char detail[96];
        std::snprintf(detail, sizeof(detail), "%zu scans, %.2f s, bce %.4f", done.scans,
                      done.seconds, done.bce);
        progress.finish(detail);
        if (!done.corrections_map.empty()) {
            result.refined_poses_world = refined_after_consolidation(sequence, result);
        }
    }
    // The map is final: its training state's memory goes to the products.
    mapper.release_training_state();
    result.products = write_map_products(mapper.sdf(), config, out_dir);
    result.profile.threads = static_cast<int>(
        tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
    result.profile.run += product_stages(result.products);
    result.profile.run[Stage::kTrain] += mapper.consolidation().seconds;
    if (mesh_every > 0 && sequence.size() > 0) {
        // The final mesh is the last progress mesh too, so the series ends with the whole run.
        const auto t0 = std::chrono::steady_clock::now();
        ProgressMesh snapshot;
        snapshot.frame = sequence.size() - 1;
        snapshot.path = out_dir / "progress" / frame_name(snapshot.frame);
        write_file_atomically(snapshot.path, [&](const fs::path& tmp) {
            fs::copy_file(out_dir / "mesh.ply", tmp, fs::copy_options::overwrite_existing);
        });
        snapshot.write_seconds = seconds_since(t0);
        snapshot.bake_seconds = result.products.bake_seconds + result.products.mesh_seconds;
        snapshot.triangles = result.products.mesh.triangles;
        result.progress_meshes.push_back(snapshot);
    }
    return result;
}

}  // namespace shine
