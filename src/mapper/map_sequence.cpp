#include "shine/mapper/map_sequence.hpp"

#include <tbb/global_control.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <optional>

#include "shine/bake/level_set_file.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/core/stopwatch.hpp"
#include "shine/io/ply.hpp"
#include "shine/mapper/surface_appearance.hpp"
#include "shine/mesh/level_set_mesh.hpp"
#include "shine/model/map_file.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace {

std::string tagged(const std::string& label, const std::string& tag) {
    return tag.empty() ? label : label + " " + tag;
}
}  // namespace

bool train_with_progress(BatchMapper& mapper, int iterations, const std::string& label,
                         const std::function<bool()>& stop) {
    Progress progress(label, static_cast<std::size_t>(std::max(iterations, 0)));
    if (mapper.iterations_done() > 0) {
        progress.update(static_cast<std::size_t>(mapper.iterations_done()), "resumed");
    }
    const bool done = mapper.train(
        [&](std::size_t done_steps, double bce) {
            char detail[64];
            std::snprintf(detail, sizeof(detail), "bce %.4f", bce);
            progress.update(done_steps, detail);
        },
        stop);
    progress.finish(done ? std::string()
                         : "paused at step " + std::to_string(mapper.iterations_done()));
    return done;
}

MapProducts write_map_products(const NeuralSdf& sdf, const MapperConfig& config,
                               const fs::path& out_dir, bool keep_surface) {
    MapProducts products;
    const std::string config_yaml = config_to_yaml(config);
    // The map is saved while the level set is baked, and the level set written while it is
    // meshed (each a stage of its own in the seconds below; writing is mostly one core's work).
    openvdb::FloatGrid::Ptr surface;
    tbb::parallel_invoke(
        [&] {
            const auto t0 = std::chrono::steady_clock::now();
            save_neural_map(out_dir / "map.vdb", sdf, config_yaml);
            products.save_seconds = seconds_since(t0);
        },
        [&] {
            const auto t0 = std::chrono::steady_clock::now();
            surface = bake_level_set(sdf, config.bake, &products.bake);
            products.bake_seconds = seconds_since(t0);
        });
    products.surface_mem_bytes = surface->memUsage();
    tbb::parallel_invoke(
        [&] {
            const auto t0 = std::chrono::steady_clock::now();
            write_level_set(out_dir / "surface.vdb", surface);
            products.bake_seconds += seconds_since(t0);
        },
        [&] {
            const auto t0 = std::chrono::steady_clock::now();
            if (keep_surface) products.written.emplace();
            products.mesh =
                write_level_set_mesh(*surface, config.mesh, out_dir / "mesh.ply", kMeshRegionVoxels,
                                     keep_surface ? &products.written->mesh : nullptr);
            products.mesh_seconds = seconds_since(t0);
        });
    if (keep_surface) products.written->level_set = surface;
    return products;
}

namespace {
// Batch checkpoints: a phase byte, then (training phase) the mapper's state. A stop during
// loading stores no state: resuming loads every scan anyway.
enum class BatchPhase : std::uint8_t { kLoading = 0, kTraining = 1 };

void write_batch_checkpoint(const RunControl& control, const BatchMapper& mapper,
                            BatchPhase phase) {
    write_checkpoint(control.checkpoint_path, control.run_description, CheckpointMode::kBatch,
                     [&](BinaryWriter& out) {
                         out.value(static_cast<std::uint8_t>(phase));
                         if (phase == BatchPhase::kTraining) mapper.save_state(out);
                     });
}

/// Loads the scans 0 .. count - 1 with load(i, seconds) and hands each to add(i, scan,
/// load_seconds), in order. Beside the adding of scan i (tbb::parallel_invoke), scan i + 1 is
/// loaded and alongside(i, scan i) runs, on the core that the map's preprocessing leaves idle at
/// times; for the first scan alongside() runs after add() (which may set what it reads: the map's
/// origin). An exception from any of them ends the loop once both sides have finished.
template <class Load, class Add, class Alongside>
void add_scans_loading_ahead(std::size_t count, const Load& load, const Add& add,
                             const Alongside& alongside) {
    double load_seconds = 0.0;
    Scan scan = count > 0 ? load(std::size_t(0), load_seconds) : Scan{};
    for (std::size_t i = 0; i < count; ++i) {
        Scan next;
        double next_load_seconds = 0.0;
        tbb::parallel_invoke([&] { add(i, scan, load_seconds); },
                             [&] {
                                 if (i > 0) alongside(i, scan);
                                 if (i + 1 < count) next = load(i + 1, next_load_seconds);
                             });
        if (i == 0) alongside(i, scan);
        scan = std::move(next);
        load_seconds = next_load_seconds;
    }
}

/// Pose refinement's first phase (pose_refinement.hpp): a map of every scan at the given poses,
/// trained up to the last round of refinement, the rounds on the way. The dynamic-point filter
/// is off here: at poses off by centimetres other scans see through true surfaces, and points
/// it drops are lost to the map made at the refined poses.
/// A stop request (control) ends it with a loading-phase checkpoint: a resumed run refines again.
/// `schedule_corners` gets the corner count its schedule was sized by.
std::vector<Eigen::Isometry3d> refine_sequence_poses(
    const MapperConfig& config, const ScanSequence& sequence, const std::string& progress_tag,
    const RunControl* control, std::vector<PoseRefinementRound>& rounds,
    std::unique_ptr<NeuralSdf>* first_map, RelativePoseChange& relative_change,
    std::size_t& schedule_corners) {
    MapperConfig first = config;
    first.dynamic.enabled = false;
    BatchMapper mapper(first);
    const bool deskew =
        deskew_active(config.deskew, config.odometry.estimate_poses, sequence.has_sweep_times());
    DeskewStats ignored;
    const bool checkpoints = control && !control->checkpoint_path.empty();
    const auto stop = [&] {
        return checkpoints && control->stop_requested && control->stop_requested();
    };
    const auto stop_here = [&](Progress& progress, const std::string& where) {
        progress.finish("stopped");
        write_batch_checkpoint(*control, mapper, BatchPhase::kLoading);
        throw_stopped_with_checkpoint(*control, where);
    };
    {
        Progress progress(tagged("load", progress_tag), sequence.size());
        add_scans_loading_ahead(
            sequence.size(),
            [&](std::size_t i, double&) {
                Scan scan = sequence.load(i);
                if (deskew) deskew_with_sequence_poses(scan, sequence, i, config.deskew, ignored);
                return scan;
            },
            [&](std::size_t i, const Scan& scan, double) {
                mapper.add_scan(scan);
                progress.update(i + 1,
                                std::to_string(mapper.sdf().octree.num_corners()) + " corners");
                if (i + 1 < sequence.size() && stop()) {
                    stop_here(progress, "while loading for pose refinement, after scan " +
                                            std::to_string(i + 1) + " of " +
                                            std::to_string(sequence.size()));
                }
            },
            [](std::size_t, const Scan&) {});
        mapper.finish_scans();
        progress.finish(std::to_string(mapper.stats().rays) + " rays");
    }
    std::vector<Eigen::Isometry3d> poses_world;
    {
        Progress progress(tagged("refine", progress_tag),
                          static_cast<std::size_t>(mapper.refinement_steps()));
        std::optional<std::vector<Eigen::Isometry3d>> refined = mapper.refine_poses(
            [&](std::size_t done, double bce) {
                char detail[64];
                std::snprintf(detail, sizeof(detail), "bce %.4f", bce);
                progress.update(done, detail);
            },
            stop);
        if (!refined) {
            stop_here(progress, "while refining poses, after step " +
                                    std::to_string(mapper.iterations_done()) + " of " +
                                    std::to_string(mapper.refinement_steps()) +
                                    " (a resumed run refines them again)");
        }
        poses_world = std::move(*refined);
        const PoseRefinementRound& last = mapper.refinement_rounds().back();
        char detail[128];
        std::snprintf(detail, sizeof(detail), "%zu rounds, last: %zu scans moved, median %.1f mm",
                      mapper.refinement_rounds().size(), last.accepted,
                      1000.0 * last.median_translation_m);
        progress.finish(detail);
    }
    rounds = mapper.refinement_rounds();
    relative_change = mapper.refinement_relative_change();
    schedule_corners = mapper.schedule_corners();
    if (first_map) *first_map = std::make_unique<NeuralSdf>(mapper.sdf().clone());
    return poses_world;
}

}  // namespace

SequenceMap map_sequence(const MapperConfig& config_in, const ScanSequence& given_sequence,
                         const fs::path& out_dir, const std::string& progress_tag,
                         const RunControl* control, bool keep_surface) {
    MapperConfig config = config_in;
    config.finalize();
    ensure_directory(out_dir);
    SequenceMap result;
    // With pose refinement: the poses refined on a first map, then the map made at them.
    ScanSequence sequence = given_sequence;
    const PoseRefinementConfig refine = config.refine;
    std::unique_ptr<NeuralSdf> first_map;  // with refine.warm_start: where the map starts from
    // The first phase's corner count sizes both phases' schedule (BatchMapper::
    // set_schedule_corners): the map at the refined poses trains as many steps.
    std::size_t schedule_corners = 0;
    if (refine.rounds > 0 && sequence.size() >= 3) {
        const auto t0 = std::chrono::steady_clock::now();
        result.refined_poses_world =
            refine_sequence_poses(config, sequence, progress_tag, control, result.refinement,
                                  refine.warm_start ? &first_map : nullptr,
                                  result.relative_pose_change, schedule_corners);
        result.refine_seconds = seconds_since(t0);
        // The first map is reused only where its surfaces were sharp: where the poses it was
        // trained at differ little from the refined ones between consecutive scans.
        if (!config.scaled_refinement().warm_start_fits(result.relative_pose_change)) {
            first_map.reset();
        }
        sequence = sequence.with_poses(result.refined_poses_world);
    }
    config.refine.rounds = 0;
    result.mapper = std::make_unique<BatchMapper>(config);
    BatchMapper& mapper = *result.mapper;
    mapper.set_schedule_corners(schedule_corners);
    const bool checkpoints = control && !control->checkpoint_path.empty();
    const auto stop = [&] {
        return control && control->stop_requested && control->stop_requested();
    };
    CheckpointClock clock(checkpoints ? control->checkpoint_interval_s : 0.0);
    // A resumed run first checks the checkpoint's header, so that a damaged file fails at once.
    std::optional<BinaryReader> resume;
    if (checkpoints && control->resume) {
        std::string description;
        CheckpointMode mode;
        resume.emplace(read_checkpoint_header(control->checkpoint_path, description, mode));
        if (mode != CheckpointMode::kBatch) {
            throw IoError("checkpoint '" + control->checkpoint_path.string() +
                          "' belongs to an incremental-mode run, not a batch-mode one");
        }
    }
    {
        Progress progress(tagged("load", progress_tag), sequence.size());
        const bool deskew = deskew_active(config.deskew, config.odometry.estimate_poses,
                                          sequence.has_sweep_times());
        result.deskew.active = deskew;
        // The next scan is read and deskewed, and this one's intensities go into the
        // reflectance voxels, while this one is added (in order, as one after another would).
        add_scans_loading_ahead(
            sequence.size(),
            [&](std::size_t i, double& seconds) {
                const auto t0 = std::chrono::steady_clock::now();
                Scan scan = sequence.load(i);
                if (deskew) {
                    deskew_with_sequence_poses(scan, sequence, i, config.deskew, result.deskew);
                }
                seconds = seconds_since(t0);
                if (!scan.intensity.empty() && !result.reflectance) {
                    result.reflectance.emplace(
                        resolve_bake_voxel_size_m(config.bake, config.octree.leaf_size_m));
                }
                return scan;
            },
            [&](std::size_t i, const Scan& scan, double load_seconds) {
                StageSeconds stages = mapper.add_scan(scan);
                stages[Stage::kLoad] = load_seconds;
                result.profile.frames.push_back(stages);
                progress.update(
                    i + 1, config.dynamic.enabled
                               ? std::to_string(mapper.stats().rays) + " rays"
                               : std::to_string(mapper.sdf().octree.num_corners()) + " corners");
                if (checkpoints && !resume && i + 1 < sequence.size() && stop()) {
                    progress.finish("stopped");
                    write_batch_checkpoint(*control, mapper, BatchPhase::kLoading);
                    throw_stopped_with_checkpoint(*control, "while loading, after scan " +
                                                                std::to_string(i + 1) + " of " +
                                                                std::to_string(sequence.size()));
                }
            },
            [&](std::size_t, const Scan& scan) {
                if (scan.intensity.empty()) return;
                add_scan_reflectance(*result.reflectance, scan, mapper.sdf().origin_world_m,
                                     config.preprocess);
            });
        mapper.finish_scans();
        progress.finish(std::to_string(mapper.stats().rays) + " rays, " +
                        std::to_string(mapper.sdf().octree.num_corners()) + " corners");
    }
    if (first_map) {
        // The first phase trained up to its last round: the map at the refined poses goes on
        // from there (its scans moved by centimetres; the dynamic-point filter now on).
        result.warm_start_step = refine.round_step(refine.rounds - 1, mapper.planned_iterations());
        result.warm_start_corners = mapper.warm_start(*first_map, result.warm_start_step);
        first_map.reset();
    }
    if (resume) {
        const auto phase = resume->value<std::uint8_t>("phase");
        if (phase == static_cast<std::uint8_t>(BatchPhase::kTraining)) {
            mapper.load_state(*resume);
        } else if (phase != static_cast<std::uint8_t>(BatchPhase::kLoading)) {
            resume->fail("phase",
                         std::to_string(phase) + " is neither loading (0) nor training (1)");
        }
        resume->expect_end();
        resume.reset();
    }
    const int iterations = mapper.planned_iterations();
    if (checkpoints) {
        clock.reset();
        bool stopped = false;
        // Train in stretches between periodic checkpoints; a stop request ends the loop.
        while (true) {
            const bool done =
                train_with_progress(mapper, iterations, tagged("train", progress_tag), [&] {
                    stopped = stop();
                    return stopped || clock.due();
                });
            if (done || stopped) break;
            write_batch_checkpoint(*control, mapper, BatchPhase::kTraining);
            clock.reset();
        }
        if (stopped || stop()) {
            write_batch_checkpoint(*control, mapper, BatchPhase::kTraining);
            throw_stopped_with_checkpoint(*control, "after optimisation step " +
                                                        std::to_string(mapper.iterations_done()) +
                                                        " of " + std::to_string(iterations));
        }
    } else {
        train_with_progress(mapper, iterations, tagged("train", progress_tag));
    }
    const bool intensity = result.reflectance && !result.reflectance->empty();
    result.products =
        write_map_products(mapper.sdf(), mapper.config(), out_dir, keep_surface || intensity);
    const MappingStats& stats = mapper.stats();
    StageProfile& profile = result.profile;
    profile.threads = static_cast<int>(
        tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
    profile.run = product_stages(result.products);
    profile.run[Stage::kNormals] = stats.normals_seconds;
    profile.run[Stage::kSample] = stats.sample_seconds;
    profile.run[Stage::kTrain] = stats.train_seconds - stats.sample_seconds;
    // With the dynamic-point filter the map is allocated once, after every scan has voted
    // (BatchMapper::finish_scans): what the frames did not allocate ran once for the run.
    double frames_allocate_seconds = 0.0;
    for (const StageSeconds& frame : profile.frames) {
        frames_allocate_seconds += frame[Stage::kAllocate];
    }
    profile.run[Stage::kAllocate] = std::max(0.0, stats.allocate_seconds - frames_allocate_seconds);
    return result;
}

std::vector<Eigen::Isometry3d> poses_with_corrections(
    const ScanSequence& selected, const std::vector<std::size_t>& mapped,
    const std::vector<Eigen::Isometry3d>& given_world,
    const std::vector<Eigen::Isometry3d>& refined_mapped) {
    std::vector<double> frame_numbers(selected.size());
    std::vector<bool> is_mapped(selected.size(), false);
    for (std::size_t i = 0; i < selected.size(); ++i) {
        frame_numbers[i] = static_cast<double>(selected.frame_number(i));
    }
    for (const std::size_t m : mapped) is_mapped.at(m) = true;
    return interpolate_corrections(given_world, is_mapped, refined_mapped, frame_numbers);
}

StageSeconds product_stages(const MapProducts& products) {
    StageSeconds stages;
    stages[Stage::kBake] = products.bake_seconds;
    stages[Stage::kMesh] = products.mesh_seconds;
    return stages;
}

}  // namespace shine
