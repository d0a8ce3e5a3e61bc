// `shine map [DATA] -o OUT`: scans -> neural map (map.vdb) -> level set (surface.vdb) -> mesh.ply,
// with stats.json, and metrics against a reference mesh when one is available.
#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>
#include <optional>

#include "cli_common.hpp"
#include "command_registry.hpp"
#include "map_appearance.hpp"
#include "map_from.hpp"
#include "product_stats.hpp"
#include "saved_map.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/median.hpp"
#include "shine/core/progress.hpp"
#include "shine/core/stop_request.hpp"
#include "shine/eval/mesh_metrics.hpp"
#include "shine/eval/metrics_report.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/run_deskew_record.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/io/tum.hpp"
#include "shine/mapper/checkpoint.hpp"
#include "shine/mapper/incremental_sequence.hpp"
#include "shine/mapper/map_sequence.hpp"
#include "shine/mapper/pose_refinement.hpp"
#include "shine/mapper/sweep_test.hpp"
#include "shine/model/map_file.hpp"
#include "shine/odometry/trajectory_error.hpp"

namespace shine::cli {
namespace {
namespace fs = std::filesystem;

struct MapOptions {
    std::string data;
    std::string out = "out";
    std::string config_path;
    double leaf_size_m = 0.0;
    std::string scene;  ///< empty: the configuration's map.scene
    int threads = -1;
    int iterations = -1;
    long long seed = -1;
    int first_frame = 0, last_frame = -1, frame_step = 1;
    int holdout_every = 0;  ///< > 0: every N-th scan is not mapped but scores the map
    std::string poses_path;
    std::string topic;  ///< recordings: the PointCloud2 topic
    std::string ref_path;
    bool no_eval = false;
    bool quiet = false;
    bool print_config = false;
    bool deskew = false;     ///< --deskew: deskew.mode on
    bool no_deskew = false;  ///< --no-deskew: deskew.mode off
    bool no_refine = false;  ///< --no-refine: refine.rounds 0
    bool half_features = false;
    std::string dynamic_filter;  ///< "on", "off" or empty (the configuration's)
    bool full_features = false;
    std::string mode = "batch";
    int mesh_every = -1;
    double max_map_mb = -1.0;       ///< < 0: the configuration's map.max_map_mb
    double max_ms_per_scan = -1.0;  ///< < 0: the configuration's keyframes.max_ms_per_scan
    bool profile = false;
    std::string from;                  ///< --from: the saved map (folder or map.vdb) to continue
    std::string resume_dir;            ///< continue the interrupted run in this output directory
    double checkpoint_minutes = 10.0;  ///< periodic checkpoints (0: only on Ctrl-C)
    int interrupt_after = 0;           ///< tests: raise SIGINT at the N-th step (hidden option)
    std::vector<std::string> given;    ///< the options given on the command line
};

fs::path checkpoint_file(const fs::path& out) { return out / "checkpoint.bin"; }

/// `--poses estimate`: no pose file, the odometry estimates the poses while mapping.
constexpr const char* kEstimatePoses = "estimate";

/// The options --resume accepts besides itself: they do not change the result.
bool allowed_with_resume(const std::string& option) {
    return option == "--threads" || option == "--quiet" || option == "--profile" ||
           option == "--checkpoint-minutes";
}

/// What a checkpoint stores to continue the run: everything that decides the result.
nlohmann::json describe_run(const MapOptions& opt, const fs::path& data,
                            const MapperConfig& config) {
    return {{"format", 1},
            {"data", fs::absolute(data).string()},
            {"mode", opt.mode},
            {"first_frame", opt.first_frame},
            {"last_frame", opt.last_frame},
            {"frame_step", opt.frame_step},
            {"holdout_every", opt.holdout_every},
            {"poses", opt.poses_path.empty() || opt.poses_path == kEstimatePoses
                          ? opt.poses_path
                          : fs::absolute(opt.poses_path).string()},
            {"topic", opt.topic},
            {"ref", opt.ref_path.empty() ? "" : fs::absolute(opt.ref_path).string()},
            {"no_eval", opt.no_eval},
            {"config_yaml", config_to_yaml(config)},
            // The keys the user set: the configuration above holds every key, and the defaults
            // that depend on the mode and the leaf (apply_incremental_defaults,
            // apply_batch_defaults) must move the same keys again when the run is resumed.
            {"set_keys", std::vector<std::string>(config.set_keys.begin(), config.set_keys.end())}};
}

/// The options and configuration of the run whose checkpoint is in `opt.resume_dir`, with this
/// invocation's --threads, --quiet, --profile and --checkpoint-minutes.
MapOptions options_from_checkpoint(const MapOptions& opt, MapperConfig& config) {
    for (const std::string& option : opt.given) {
        if (!option.empty() && option != "--resume" && !allowed_with_resume(option)) {
            throw ConfigError(
                "--resume continues a run with the settings stored in its "
                "checkpoint; only --threads, --quiet, --profile and "
                "--checkpoint-minutes may be given with it, not " +
                (option == "data" ? std::string("a data directory") : option));
        }
    }
    const fs::path file = checkpoint_file(opt.resume_dir);
    if (!fs::exists(file)) {
        throw IoError("cannot resume '" + opt.resume_dir +
                      "': it has no checkpoint.bin (only a "
                      "run stopped with Ctrl-C or SIGTERM, or one with periodic checkpoints, "
                      "leaves one)");
    }
    const std::string text = read_checkpoint_description(file);
    MapOptions resumed = opt;
    try {
        const nlohmann::json run = nlohmann::json::parse(text);
        if (run.at("format").get<int>() != 1) throw ConfigError("unknown run description format");
        resumed.data = run.at("data").get<std::string>();
        resumed.mode = run.at("mode").get<std::string>();
        resumed.first_frame = run.at("first_frame").get<int>();
        resumed.last_frame = run.at("last_frame").get<int>();
        resumed.frame_step = run.at("frame_step").get<int>();
        resumed.holdout_every = run.value("holdout_every", 0);
        resumed.poses_path = run.at("poses").get<std::string>();
        resumed.topic = run.value("topic", std::string());
        resumed.ref_path = run.at("ref").get<std::string>();
        resumed.no_eval = run.at("no_eval").get<bool>();
        parse_config_yaml(run.at("config_yaml").get<std::string>(),
                          "the configuration in '" + file.string() + "'", config);
        // Reading the stored configuration marks every key as set; the run had set only these
        // (checkpoints written before they were stored keep every key set).
        if (run.contains("set_keys")) {
            const auto keys = run.at("set_keys").get<std::vector<std::string>>();
            config.set_keys = std::set<std::string>(keys.begin(), keys.end());
        }
    } catch (const nlohmann::json::exception& e) {
        throw IoError("checkpoint '" + file.string() + "': its run description is damaged (" +
                      e.what() + ")");
    }
    resumed.out = opt.resume_dir;
    if (opt.threads >= 0) config.threads = opt.threads;
    return resumed;
}

void write_json(const fs::path& path, const nlohmann::json& json) {
    write_stream_atomically(path, [&](std::ostream& out) { out << json.dump(2) << "\n"; });
}

/// Per-frame timings (median over the run, with the thread count) and progress meshes.
void add_incremental_stats(const IncrementalSequenceMap& mapped, nlohmann::json& json) {
    const IncrementalMapper& mapper = *mapped.mapper;
    const IncrementalConfig& inc = mapper.config().incremental;
    nlohmann::json frames = nlohmann::json::array();
    for (const IncrementalFrameStats& f : mapper.frames()) {
        frames.push_back({{"rays", f.rays},
                          {"new_corners", f.new_corners},
                          {"rays_with_normal", f.rays_with_normal},
                          {"dynamic_dropped", f.dynamic_dropped},
                          {"dynamic_forgotten", f.dynamic_forgotten},
                          {"seconds", f.total_seconds},
                          {"train_seconds", f.train_seconds},
                          {"importance_seconds", f.importance_seconds},
                          {"optimizer_bytes", f.optimizer_bytes},
                          {"bce", f.bce},
                          {"regularization", f.regularization}});
    }
    nlohmann::json meshes = nlohmann::json::array();
    for (const ProgressMesh& m : mapped.progress_meshes) {
        meshes.push_back({{"frame", m.frame},
                          {"path", m.path.string()},
                          {"triangles", m.triangles},
                          {"bake_mesh_seconds", m.bake_seconds},
                          {"write_seconds", m.write_seconds}});
    }
    json["incremental"] = {{"iterations_per_frame", inc.iterations_per_frame},
                           {"learning_rate", inc.learning_rate},
                           {"regularization_weight", inc.importance.regularization_weight},
                           {"importance_cap", inc.importance.importance_cap},
                           {"decoder_weights", inc.decoder_weights},
                           {"median_seconds_per_frame", mapper.median_frame_seconds()},
                           {"threads_used", static_cast<int>(tbb::global_control::active_value(
                                                tbb::global_control::max_allowed_parallelism))},
                           {"state_bytes", mapper.state_bytes()},
                           {"consolidation",
                            {{"steps", mapper.consolidation().steps},
                             {"scans", mapper.consolidation().scans},
                             {"rays", mapper.consolidation().rays},
                             {"voxels", mapper.consolidation().voxels},
                             {"surface_band_m", mapper.consolidation().surface_band_m},
                             {"learning_rate", inc.consolidation_learning_rate},
                             {"free_samples", mapper.consolidation().free_samples},
                             {"batch_size", mapper.consolidation().batch_size},
                             {"seconds", mapper.consolidation().seconds},
                             {"bce", mapper.consolidation().bce},
                             {"dynamic_dropped", mapper.consolidation().dynamic_dropped},
                             {"vote_seconds", mapper.consolidation().vote_seconds}}},
                           {"frames", frames},
                           {"progress_meshes", meshes}};
}

/// The odometry's per-scan records and a summary (seconds per scan: odometry plus mapping, wall
/// clock from the scan's load to the end of its mapping).
/// What the keyframe policy did (stats.json "keyframes").
nlohmann::json keyframes_to_json(const KeyframePolicy& policy,
                                 const IncrementalSequenceMap& mapped) {
    const KeyframeConfig& c = policy.config();
    const KeyframeCounts& n = policy.counts();
    std::vector<double> trained_s;
    std::vector<double> deferred_s;
    for (std::size_t i = 0;
         i < mapped.keyframe_choices.size() && i < mapped.scan_wall_seconds.size(); ++i) {
        (mapped.keyframe_choices[i].train ? trained_s : deferred_s)
            .push_back(mapped.scan_wall_seconds[i]);
    }
    return {
        {"enabled", c.enabled},
        {"min_translation_m", c.min_translation_m},
        {"min_rotation_deg", c.min_rotation_deg},
        {"max_interval_scans", c.max_interval_scans},
        {"keyframe_takes_deferred_steps", c.keyframe_takes_deferred_steps},
        {"deferred_steps_taken", mapped.deferred_steps_taken},
        {"min_coverage", c.min_coverage},
        {"max_ms_per_scan", c.max_ms_per_scan},
        {"trained", n.trained},
        {"deferred", n.deferred},
        {"deferred_over_budget", n.over_budget},
        {"deferred_while_busy", n.busy},
        {"background_training", c.enabled && c.max_ms_per_scan > 0.0},
        {"caught_up", n.caught_up},
        {"skipped", n.skipped},
        {"catch_up_seconds", mapped.catch_up_seconds},
        {"median_seconds_per_trained_scan", median(trained_s)},
        {"median_seconds_per_deferred_scan", median(deferred_s)},
        {"mean_seconds_per_scan", mapped.scan_wall_seconds.empty()
                                      ? 0.0
                                      : std::accumulate(mapped.scan_wall_seconds.begin(),
                                                        mapped.scan_wall_seconds.end(), 0.0) /
                                            static_cast<double>(mapped.scan_wall_seconds.size())}};
}

void add_odometry_stats(const IncrementalSequenceMap& mapped, nlohmann::json& json) {
    const ScanOdometry& odometry = *mapped.odometry;
    nlohmann::json scans = nlohmann::json::array();
    std::vector<double> registration_seconds;
    std::map<std::string, int> counts;
    for (std::size_t i = 0; i < odometry.records().size(); ++i) {
        const OdometryRecord& r = odometry.records()[i];
        if (r.tried != RegistrationMethod::kNone) registration_seconds.push_back(r.seconds);
        ++counts[to_string(r.source)];
        scans.push_back(
            {{"method", to_string(r.source)},
             {"tried", to_string(r.tried)},
             {"status", r.tried == RegistrationMethod::kNone ? "none" : to_string(r.status)},
             {"accepted", r.accepted},
             {"iterations", r.iterations},
             {"initial_cost", r.initial_cost},
             {"final_cost", r.final_cost},
             {"condition_number", std::isfinite(r.condition_number)
                                      ? nlohmann::json(r.condition_number)
                                      : nlohmann::json("inf")},
             {"points", r.points},
             {"valid_points", r.valid_points},
             {"correction_m", r.correction_m},
             {"correction_deg", r.correction_rad * 180.0 / M_PI},
             {"icp_inlier_ratio", r.icp_inlier_ratio},
             {"yaw_hypotheses", r.yaw_hypotheses},
             {"sweep_estimated", r.sweep_estimated},
             {"sweep_twist", std::vector<double>(r.sweep_twist, r.sweep_twist + 6)},
             {"seconds", r.seconds}});
        if (i < mapped.keyframe_choices.size()) {
            const KeyframeChoice& k = mapped.keyframe_choices[i];
            scans.back()["trained"] = k.train;
            scans.back()["keyframe_reason"] = to_string(k.reason);
        }
        // Load to the end of its mapping (a resumed run has them for its own scans only).
        if (mapped.scan_wall_seconds.size() == odometry.records().size()) {
            scans.back()["wall_seconds"] = mapped.scan_wall_seconds[i];
        }
    }
    const OdometryConfig& c = odometry.config();
    json["odometry"] = {{"poses", "estimated"},
                        {"voxel_size_m", c.voxel_size_m},
                        {"icp_warmup_scans", c.icp_warmup_scans},
                        {"sdf_kernel_scale_m", c.sdf_kernel_scale_m},
                        {"sdf_min_incidence_cosine", c.sdf_min_incidence_cosine},
                        {"icp_kernel_scale_m", c.icp_kernel_scale_m},
                        {"estimate_sweep", c.estimate_sweep},
                        {"sweep_prior_centre", c.sweep_prior_from_poses ? "poses" : "prediction"},
                        {"counts", counts},
                        {"median_seconds_per_scan", median(mapped.scan_wall_seconds)},
                        {"median_registration_seconds", median(registration_seconds)},
                        {"scans", scans}};
    if (mapped.keyframes) json["keyframes"] = keyframes_to_json(*mapped.keyframes, mapped);
}

/// What deskewing did (stats.json "deskew").
nlohmann::json deskew_to_json(const DeskewConfig& config, const DeskewStats& stats,
                              bool estimated_poses) {
    nlohmann::json json = {{"mode", to_string(config.mode)},
                           {"active", stats.active},
                           {"motion", estimated_poses ? "estimated poses" : "given poses"},
                           {"scan_period_s", config.scan_period_s},
                           {"scans_deskewed", stats.scans_deskewed},
                           {"scans_as_measured", stats.scans_as_measured},
                           {"max_shift_m", stats.max_shift_m}};
    const PointTimeFormat& f = stats.time_format;
    if (!f.field.empty()) {
        json["point_time"] = {{"field", f.field},
                              {"type", f.type},
                              {"unit", f.nanoseconds ? "ns" : "s"},
                              {"reference", f.absolute ? "absolute" : "relative"},
                              {"description", f.describe()}};
    }
    return json;
}

/// Pose refinement's products: every selected scan's refined pose (the mapped scans' from
/// `refined_mapped`, the held-out ones from the corrections of the mapped scans around them,
/// never from their own points) written to poses_refined.txt and poses_refined_tum.txt, and
/// the poses the map started from to poses_given.txt, line by line with it (`shine localize`
/// reports poses in their frame, geometry/pose_frame_correction.hpp): the data's, or with an
/// `odometry` its estimates (held-out scans placed next to them). `json` gets the rounds, the
/// largest move from the given poses and the file. Returns the refined poses.
std::vector<Eigen::Isometry3d> write_refined_poses(
    const fs::path& out, const ScanSequence& selected, const HoldoutSplit& split,
    const ScanOdometry* odometry, const std::vector<Eigen::Isometry3d>& refined_mapped,
    const std::vector<PoseRefinementRound>& rounds, const MapperConfig& config,
    nlohmann::json& json) {
    std::vector<Eigen::Isometry3d> given(selected.size());
    for (std::size_t i = 0; i < selected.size(); ++i) given[i] = selected.pose(i);
    if (odometry) given = heldout_poses_local_to_estimate(selected, split, odometry->poses());
    const std::vector<Eigen::Isometry3d> refined =
        poses_with_corrections(selected, split.mapped, given, refined_mapped);
    write_kitti_poses(out / "poses_refined.txt", refined);
    write_kitti_poses(out / "poses_given.txt", given);
    std::vector<StampedPose> stamped(refined.size());
    for (std::size_t i = 0; i < refined.size(); ++i) {
        stamped[i].timestamp_s =
            selected.from_recording()
                ? selected.stamp_s(i)
                : static_cast<double>(selected.frame_number(i)) * config.deskew.scan_period_s;
        stamped[i].T_world_sensor = refined[i];
    }
    write_tum_poses(out / "poses_refined_tum.txt", stamped);
    json["rounds"] = nlohmann::json::array();
    for (const PoseRefinementRound& r : rounds) {
        json["rounds"].push_back({{"step", r.step},
                                  {"accepted", r.accepted},
                                  {"unfinished", r.unfinished},
                                  {"rejected", r.rejected},
                                  {"median_translation_m", r.median_translation_m},
                                  {"median_rotation_deg", r.median_rotation_deg},
                                  {"max_translation_m", r.max_translation_m},
                                  {"gauge_translation_m", r.gauge_translation_m},
                                  {"seconds", r.seconds}});
    }
    double moved_m = 0.0;
    for (std::size_t i = 0; i < refined.size(); ++i) {
        moved_m = std::max(moved_m, (refined[i].translation() - given[i].translation()).norm());
    }
    json["max_moved_m"] = moved_m;
    json["poses"] = (out / "poses_refined.txt").string();
    return refined;
}

/// The mesh scored again after the SE(3) alignment of the map's poses (`estimated`) to paired
/// reference poses (`reference`; Umeyama over their positions and axes), so that the frame the
/// map was made in and the map's own accuracy show apart: stats.json `key`. With estimated poses
/// the reference is the data's poses (the estimate's drift against them not counted); with
/// refined poses of a simulated sequence with noisy poses, the true ones (the frame the noisy
/// poses leave undetermined not counted). A small rotation matters: 0.1 deg moves a surface
/// 50 m away by 9 cm, the street's whole threshold.
void evaluate_aligned(const TriangleMesh& mesh, const TriangleMesh& reference,
                      const EvalConfig& eval_config,
                      const std::vector<Eigen::Isometry3d>& estimated,
                      const std::vector<Eigen::Isometry3d>& reference_poses, const char* key,
                      const char* transform_key, const std::string& description,
                      nlohmann::json& json) {
    // Each pose contributes its position and the points kAxisM along its three axes: positions
    // alone leave the rotation about the line of a straight drive undetermined (8 scans of a
    // street: 1 deg off); with the axes the poses' orientations fix it.
    constexpr double kAxisM = 10.0;
    std::vector<Eigen::Vector3d> from, to;
    for (std::size_t i = 0; i < estimated.size() && i < reference_poses.size(); ++i) {
        from.push_back(estimated[i].translation());
        to.push_back(reference_poses[i].translation());
        for (int axis = 0; axis < 3; ++axis) {
            from.push_back(estimated[i] * (kAxisM * Eigen::Vector3d::Unit(axis)));
            to.push_back(reference_poses[i] * (kAxisM * Eigen::Vector3d::Unit(axis)));
        }
    }
    const std::size_t scans = from.size() / 4;
    SimilarityTransform alignment;
    try {
        alignment = umeyama_alignment(from, to, /*with_scale=*/false);
    } catch (const DataError& e) {
        std::printf("no accuracy %s: %s\n", description.c_str(), e.what());
        return;
    }
    Eigen::Isometry3d T_reference_estimate = Eigen::Isometry3d::Identity();
    T_reference_estimate.linear() = alignment.R;
    T_reference_estimate.translation() = alignment.t;
    const double rotation_deg = Eigen::AngleAxisd(alignment.R).angle() * 180.0 / EIGEN_PI;
    const MeshMetrics aligned =
        evaluate_meshes(moved_in_world(mesh, T_reference_estimate), reference, eval_config);
    nlohmann::json& j = json[key];
    j = nlohmann::json::parse(metrics_to_json(aligned));
    j["alignment"] = {
        {"method", "se3, positions and axes"},
        {"scans", scans},
        {"rotation_deg", rotation_deg},
        {"translation_m", alignment.t.norm()},
        {transform_key,
         {{alignment.R(0, 0), alignment.R(0, 1), alignment.R(0, 2), alignment.t(0)},
          {alignment.R(1, 0), alignment.R(1, 1), alignment.R(1, 2), alignment.t(1)},
          {alignment.R(2, 0), alignment.R(2, 1), alignment.R(2, 2), alignment.t(2)}}}};
    std::printf("accuracy %s (SE(3) over %zu scans: %.4f deg, %.4f m):\n%s", description.c_str(),
                scans, rotation_deg, alignment.t.norm(), format_metrics(aligned).c_str());
}

/// The estimated poses of the registered scans and the data's poses of the same scans.
void evaluate_aligned_to_data_poses(const TriangleMesh& mesh, const TriangleMesh& reference,
                                    const EvalConfig& eval_config, const ScanOdometry& odometry,
                                    const ScanSequence& selected, const HoldoutSplit& split,
                                    nlohmann::json& json) {
    const std::vector<Eigen::Isometry3d>& poses = odometry.poses();
    std::vector<Eigen::Isometry3d> estimated, data;
    for (std::size_t m = 0; m < poses.size() && m < split.mapped.size(); ++m) {
        if (!odometry.mapped(m)) continue;  // a skipped scan's pose is only the prediction
        estimated.push_back(poses[m]);
        data.push_back(selected.pose(split.mapped[m]));
    }
    evaluate_aligned(mesh, reference, eval_config, estimated, data, "eval_aligned",
                     "T_data_estimate",
                     "with the estimated trajectory aligned to the data's poses (the drift "
                     "against the data's frame not counted)",
                     json);
}

/// With refined poses of a sequence that has kTruePosesFile: the mapped scans' refined poses and
/// their true ones (by frame number; skipped with a note when the file has too few lines).
void evaluate_aligned_to_true_poses(const TriangleMesh& mesh, const TriangleMesh& reference,
                                    const EvalConfig& eval_config,
                                    const std::vector<Eigen::Isometry3d>& refined,
                                    const ScanSequence& selected, const HoldoutSplit& split,
                                    nlohmann::json& json) {
    const fs::path path = selected.directory() / kTruePosesFile;
    std::vector<Eigen::Isometry3d> truth;
    try {
        truth = read_kitti_poses(path);
    } catch (const Error& e) {  // a diagnostic: the map and its other scores stand
        std::printf("no accuracy against %s: %s\n", path.c_str(), e.what());
        return;
    }
    std::vector<Eigen::Isometry3d> estimated, true_poses;
    for (const std::size_t i : split.mapped) {
        const std::size_t line = selected.frame_number(i);
        if (line >= truth.size() || i >= refined.size()) {
            std::printf("no accuracy against %s: it has %zu poses, scan %zu needs line %zu\n",
                        path.c_str(), truth.size(), i, line + 1);
            return;
        }
        estimated.push_back(refined[i]);
        true_poses.push_back(truth[line]);
    }
    evaluate_aligned(mesh, reference, eval_config, estimated, true_poses, "eval_aligned_to_true",
                     "T_true_refined",
                     "with the refined poses aligned to " + path.string() +
                         " (the frame the noisy given poses leave undetermined not counted)",
                     json);
}

/// The stage profile: per stage the median over frames and the run total, plus per frame.
nlohmann::json profile_to_json(const StageProfile& profile) {
    const StageSeconds medians = profile.frame_medians();
    const StageSeconds totals = profile.totals();
    nlohmann::json median_json, total_json;
    for (int i = 0; i < kNumStages; ++i) {
        const Stage stage = static_cast<Stage>(i);
        median_json[stage_name(stage)] = medians[stage];
        total_json[stage_name(stage)] = totals[stage];
    }
    nlohmann::json frames = nlohmann::json::array();
    for (const StageSeconds& f : profile.frames) {
        nlohmann::json frame;
        for (int i = 0; i < kNumStages; ++i) {
            frame[stage_name(static_cast<Stage>(i))] = f.seconds[i];
        }
        frames.push_back(frame);
    }
    return {{"threads", profile.threads},
            {"median_frame_seconds", profile.median_frame_seconds()},
            {"median_seconds_per_frame_by_stage", median_json},
            {"total_seconds_by_stage", total_json},
            {"frames", frames}};
}

/// The configuration of a new run: the file, then the command line's options over it.
MapperConfig config_from_options(const MapOptions& opt) {
    MapperConfig config;
    if (!opt.config_path.empty()) load_config_yaml(opt.config_path, config);
    if (opt.leaf_size_m != 0.0) {
        if (!(opt.leaf_size_m > 0.0)) throw ConfigError("--leaf-size-m must be positive");
        config.octree.leaf_size_m = opt.leaf_size_m;
        config.mark_set("map.leaf_size_m");
    }
    if (!opt.scene.empty()) {
        config.scene = opt.scene;
        config.mark_set("map.scene");
    }
    if (opt.threads >= 0) config.threads = opt.threads;
    if (opt.iterations >= 0) config.iterations = opt.iterations;
    if (opt.seed >= 0) config.seed = static_cast<std::uint64_t>(opt.seed);
    if (opt.half_features) config.octree.feature_precision = FeaturePrecision::kFloat16;
    if (opt.full_features) config.octree.feature_precision = FeaturePrecision::kFloat32;
    if (opt.mesh_every >= 0) config.incremental.mesh_every = opt.mesh_every;
    if (opt.max_map_mb >= 0.0) config.max_map_mb = opt.max_map_mb;
    if (opt.max_ms_per_scan >= 0.0)
        config.incremental.keyframes.max_ms_per_scan = opt.max_ms_per_scan;
    if (opt.deskew) config.deskew.mode = DeskewMode::kOn;
    if (opt.no_deskew) config.deskew.mode = DeskewMode::kOff;
    if (opt.no_refine) {
        config.refine.rounds = 0;
        config.mark_set("refine.rounds");
    }
    if (!opt.dynamic_filter.empty()) {
        config.dynamic.enabled = opt.dynamic_filter == "on";
        config.mark_set("dynamic.enabled");
    }
    return config;
}

/// With --from: the mode is incremental, and --mode batch is refused.
MapOptions with_continue_mode(const MapOptions& given) {
    if (given.from.empty()) return given;
    const bool mode_given =
        std::find(given.given.begin(), given.given.end(), "--mode") != given.given.end();
    if (mode_given && given.mode != "incremental") {
        throw ConfigError(
            "--from continues a saved map in incremental mode (the old map's "
            "features held by the importance weights, its decoder frozen); "
            "--mode " +
            given.mode +
            " cannot continue a map: drop --mode, or map all the data anew in batch "
            "mode");
    }
    MapOptions opt = given;
    opt.mode = "incremental";
    return opt;
}

/// `--from` with no new scan (DATA's scans all before --first-frame): OUT gets the old map
/// unchanged (write_map_without_new_scans), scored against the reference as any run's, and a
/// stats.json with 0 new scans and corners (docs/continue.md).
int map_without_new_scans(const MapOptions& opt, const MapperConfig& config, const fs::path& data,
                          NeuralSdf old_sdf, const fs::path& old_map_file, nlohmann::json from_json,
                          std::chrono::steady_clock::time_point start_total) {
    const fs::path ref = resolve_reference(data, opt.ref_path, opt.no_eval);
    const fs::path out = opt.out;
    if (fs::exists(checkpoint_file(out))) {
        throw ConfigError("'" + checkpoint_file(out).string() +
                          "' holds an interrupted run: continue it with `shine map --resume " +
                          out.string() + "`, or delete that file to start again from scratch");
    }
    const MapProducts products = write_map_without_new_scans(config, old_sdf, old_map_file, out);
    std::printf(
        "nothing new mapped: '%s' has %d scans, all before --first-frame %d; the map of '%s' is "
        "written unchanged\n",
        data.c_str(), opt.first_frame, opt.first_frame, old_map_file.c_str());
    from_json["poses"] = "none";
    from_json["new_scans"] = 0;
    from_json["new_corners"] = 0;
    nlohmann::json json;
    json["data"] = data.string();
    json["mode"] = opt.mode;
    json["resumed"] = false;
    json["from"] = from_json;
    json["frames"] = 0;
    json["rays"] = 0;
    json["threads"] = config.threads;
    json["leaf_size_m"] = config.octree.leaf_size_m;
    json["scene"] = to_string(config.resolved_scene());
    json["iterations"] = 0;
    json["incremental"] = {{"decoder_weights", old_map_file.string()}};
    add_product_stats(json, old_sdf, products, out);
    json["seconds"] = {{"save_map", products.save_seconds},
                       {"bake", products.bake_seconds},
                       {"mesh", products.mesh_seconds},
                       {"mapping_total", seconds_since(start_total)}};
    std::printf("wrote %s, %s, %s (%zu triangles)\n", (out / "map.vdb").c_str(),
                (out / "surface.vdb").c_str(), (out / "mesh.ply").c_str(), products.mesh.triangles);
    if (!ref.empty()) {
        const auto t0 = std::chrono::steady_clock::now();
        const EvalConfig eval_config =
            eval_config_for_threshold(scene_defaults(config.resolved_scene()).eval_threshold_m);
        const MeshMetrics metrics =
            evaluate_meshes(read_ply_mesh(out / "mesh.ply"), read_ply_mesh(ref), eval_config);
        json["eval"] = nlohmann::json::parse(metrics_to_json(metrics));
        json["eval"]["reference"] = ref.string();
        std::printf("accuracy against %s:\n%s", ref.c_str(), format_metrics(metrics).c_str());
        json["seconds"]["eval"] = seconds_since(t0);
    }
    json["seconds"]["total"] = seconds_since(start_total);
    json["peak_rss_bytes"] = peak_rss_bytes();
    write_json(out / "stats.json", json);
    return 0;
}

int run_map(const MapOptions& given_options) {
    const auto start_total = std::chrono::steady_clock::now();
    const bool resuming = !given_options.resume_dir.empty();
    MapperConfig config;
    const MapOptions opt = resuming ? options_from_checkpoint(given_options, config)
                                    : with_continue_mode(given_options);
    if (!resuming) config = config_from_options(opt);
    Progress::set_globally_enabled(!opt.quiet);
    const bool continuing = !opt.from.empty();
    const bool incremental = opt.mode == "incremental";
    if (opt.mode != "batch" && !incremental) {
        throw ConfigError("--mode must be 'batch' or 'incremental', got '" + opt.mode + "'");
    }
    if (!(opt.checkpoint_minutes >= 0.0)) {
        throw ConfigError("--checkpoint-minutes must be >= 0 (0: checkpoints only on Ctrl-C)");
    }
    config.finalize();
    if (opt.print_config) {
        std::printf("%s", config_to_yaml(config).c_str());
        return 0;
    }
    auto threads = limit_threads(config.threads);

    const fs::path data = resolve_data_dir(opt.data, opt.quiet);
    ScanSequenceOptions seq_options;
    seq_options.first_frame = opt.first_frame;
    seq_options.last_frame = opt.last_frame;
    seq_options.frame_step = opt.frame_step;
    const bool estimate_option = opt.poses_path == kEstimatePoses;
    if (!estimate_option) seq_options.poses_path = opt.poses_path;
    seq_options.topic = opt.topic;
    seq_options.poses = PoseFileUse::kIfPresent;
    // --from: --first-frame one past DATA's last scan selects none (nothing new since the old map).
    ScanSequence selected = continuing ? open_continued_selection(data, seq_options)
                                       : ScanSequence::open(data, seq_options);
    // Camera images colour the surface; a broken calibration is named before any mapping
    // (and before the sweep test reads scans).
    const std::optional<CameraRig> cameras = find_sequence_cameras(selected, opt.quiet || resuming);
    // Times from the azimuth where they were measured to win (sweep_times_apply).
    const bool refining =
        opt.mode == "batch" ? config.refine.rounds > 0 : config.refines_in_consolidation();
    if (sweep_times_apply(config.deskew, refining, estimate_option, selected)) {
        selected = with_sweep_times_if_skewed(selected, config.deskew, opt.quiet || resuming);
    }
    // --from: the old map, read before anything is written (a missing or damaged map is named
    // at once). Scans without poses (or with --poses estimate) are localised in it first and
    // mapped at those poses; with poses of their own, those are in its world frame.
    std::optional<LoadedMap> old_map;
    fs::path old_map_file;
    nlohmann::json from_json;
    if (continuing) {
        old_map_file = saved_map_file(opt.from, "--from");
        old_map.emplace(load_neural_map(old_map_file));
        from_json = {{"map", fs::absolute(old_map_file).string()},
                     {"corners", old_map->sdf.octree.num_corners()},
                     {"poses", "data"}};
        if (selected.size() == 0) {
            return map_without_new_scans(opt, config, data, std::move(old_map->sdf), old_map_file,
                                         from_json, start_total);
        }
        if (estimate_option || !selected.has_poses()) {
            if (opt.holdout_every > 0) {
                throw ConfigError(
                    "--holdout-every scores the map on held-out scans at their poses, but with "
                    "--from and no poses of their own the scans are localised and mapped: give a "
                    "pose file, or map without --holdout-every");
            }
            nlohmann::json localize_json;
            selected = localize_in_continued_map(selected, old_map->sdf, old_map_file, opt.quiet,
                                                 localize_json);
            from_json["poses"] = "localised";
            from_json["localize"] = localize_json;
        }
    }
    // --poses estimate: the odometry, except when continuing a map (localised in it above).
    const bool estimate_requested = estimate_option && !continuing;
    if (!selected.has_poses() && !incremental && !estimate_requested &&
        !config.odometry.estimate_poses) {
        const std::string estimate_hint =
            ", or estimate them with --poses estimate (with --mode incremental while mapping; "
            "in batch mode by an incremental run first)";
        if (selected.from_recording()) {
            throw ConfigError("recording '" + data.string() +
                              "' carries no poses: pass a TUM trajectory with --poses FILE (lines "
                              "'t x y z qx qy qz qw', matched to each scan's header stamp)" +
                              estimate_hint);
        }
        throw IoError("no pose file in '" + data.string() +
                      "': put poses.txt (KITTI, 12 numbers a line) or poses_tum.txt (TUM) there, "
                      "pass one with --poses FILE" +
                      estimate_hint);
    }
    if (estimate_requested) config.odometry.estimate_poses = true;
    if (!selected.has_poses()) {
        config.odometry.estimate_poses = true;
        if (!estimate_requested && !resuming) {
            std::printf(
                "'%s' has no pose file: estimating the poses while mapping (LiDAR "
                "odometry on the neural map, docs/odometry.md); they are written to "
                "%s\n",
                data.c_str(), (fs::path(opt.out) / "poses.txt").c_str());
        }
    }
    if (!selected.has_poses() && opt.holdout_every > 0) {
        throw ConfigError("--holdout-every scores the map on held-out scans at their poses, but '" +
                          data.string() +
                          "' has none: map without --holdout-every, or give a pose file");
    }
    if (config.incremental.keyframes.max_ms_per_scan > 0.0 &&
        !(incremental && config.odometry.estimate_poses)) {
        throw ConfigError(
            "--max-ms-per-scan (keyframes.max_ms_per_scan) is the budget of incremental mode "
            "without poses, whose tracking it keeps in time: add --mode incremental and "
            "--poses estimate (or map data without a pose file), or drop the budget");
    }
    if (config.odometry.estimate_poses && selected.has_poses() && !resuming) {
        std::printf(
            "estimating the poses%s; the data's poses are used only to place the first scan "
            "(the world frame) and to score\n",
            incremental ? " while mapping" : "");
    }
    if (config.odometry.estimate_poses && !incremental && !resuming) {
        std::printf(
            "batch mode: the poses come from an incremental run first (its map and poses in "
            "%s), then all scans are trained at them\n",
            (fs::path(opt.out) / "odometry").c_str());
    }
    // With --holdout-every N the map never sees every N-th scan; they score it afterwards.
    const HoldoutSplit split = split_holdout(selected, opt.holdout_every);
    const ScanSequence sequence = selected.subset(split.mapped);
    // Deskewing: the first scan says whether there are times, before anything is written.
    const bool deskew =
        deskew_active(config.deskew, config.odometry.estimate_poses, sequence.has_sweep_times());
    if (deskew) {
        const Scan first = sequence.load(0);
        if (config.deskew.mode == DeskewMode::kOn) require_point_times(first);
        if (!first.point_time_s.empty() && !resuming) {
            std::printf(
                "deskewing every scan at constant velocity between %s (scan times: %s; "
                "docs/odometry.md)\n",
                config.odometry.estimate_poses ? "the estimated poses" : "the given poses",
                first.point_time_format.describe().c_str());
        }
    }
    const fs::path ref = resolve_reference(data, opt.ref_path, opt.no_eval);
    const fs::path out = opt.out;
    if (!resuming && fs::exists(checkpoint_file(out))) {
        throw ConfigError("'" + checkpoint_file(out).string() +
                          "' holds an interrupted run: continue it with `shine map --resume " +
                          out.string() + "`, or delete that file to start again from scratch");
    }
    std::error_code exists_ec;
    const bool out_existed = fs::exists(out, exists_ec);
    ensure_directory(out);

    // Ctrl-C / SIGTERM finish the current step and write a checkpoint (checkpoint.hpp); a run
    // that continues a map writes none (docs/continue.md), and Ctrl-C ends it.
    std::optional<StopOnSignal> stop_on_signal;
    if (!continuing) stop_on_signal.emplace();
    RunControl control;
    control.checkpoint_path = checkpoint_file(out);
    control.run_description = describe_run(opt, data, config).dump(2);
    control.checkpoint_interval_s = opt.checkpoint_minutes * 60.0;
    control.resume = resuming;
    control.resume_hint = "shine map --resume " + out.string();
    std::size_t polls = 0;
    control.stop_requested = [&] {
        if (opt.interrupt_after > 0 && ++polls == static_cast<std::size_t>(opt.interrupt_after)) {
            std::raise(SIGINT);  // the real handler's path, at a reproducible step
        }
        return stop_requested();
    };

    std::optional<SequenceMap> batch_map;
    std::optional<IncrementalSequenceMap> incremental_map;
    // Batch mode with estimated poses: the odometry of an incremental run, then the batch map at
    // its poses. The odometry run is deterministic, so a resumed run repeats it (without a
    // checkpoint of its own) and goes on from the batch training's checkpoint.
    std::optional<IncrementalSequenceMap> odometry_run;
    // Batch mode keeps the level set and mesh it writes for the steps that read them next: the
    // colours, the scores against the reference and on the held-out scans.
    const bool keep_surface = cameras.has_value() || !ref.empty() || !split.heldout.empty();
    try {
        if (incremental && continuing) {
            MapToContinue from;
            from.file = old_map_file;
            from.sdf = &old_map->sdf;
            const OldDrive old_drive = read_old_drive(old_map_file, opt.quiet);
            from.surface = old_drive.surface ? &*old_drive.surface : nullptr;
            from.trajectory_world = old_drive.trajectory_world;
            incremental_map = map_sequence_incremental(config, sequence, out, {}, nullptr, &from);
            old_map.reset();
        } else if (incremental) {
            incremental_map = map_sequence_incremental(config, sequence, out, {}, &control);
        } else if (config.odometry.estimate_poses) {
            // Only its poses are used: its map is not consolidated, and every scan trains it
            // (keyframes would leave the deferred scans untrained: on the real drive the batch
            // map at the poses of a keyframe odometry scored 73.03 against 73.79 % of held-out
            // rays within 10 cm).
            MapperConfig odometry_config = config;
            odometry_config.incremental.consolidation_steps = 0;
            odometry_config.incremental.keyframes.enabled = false;
            odometry_run =
                map_sequence_incremental(odometry_config, sequence, out / "odometry", "odometry");
            const std::vector<Eigen::Isometry3d>& poses = odometry_run->odometry->poses();
            write_kitti_poses(out / "poses.txt", poses);
            batch_map =
                map_sequence(config, sequence.with_poses(poses), out, {}, &control, keep_surface);
        } else {
            batch_map = map_sequence(config, sequence, out, {}, &control, keep_surface);
        }
    } catch (const Error&) {
        // A scan that cannot be read (a damaged message deep in a recording) leaves no empty
        // output directory behind.
        std::error_code ec;
        if (!out_existed && fs::is_empty(out, ec)) fs::remove(out, ec);
        throw;
    }
    // Pose refinement (batch mode): the refined poses, and the held-out scans placed with the
    // corrections of the mapped scans around them (never with their own points).
    ScanSequence scored = selected;
    nlohmann::json refine_json;
    std::vector<Eigen::Isometry3d> refined;  // with pose refinement: every selected scan's pose
    if (batch_map && !batch_map->refinement.empty()) {
        refined = write_refined_poses(
            out, selected, split, odometry_run ? odometry_run->odometry.get() : nullptr,
            batch_map->refined_poses_world, batch_map->refinement, config, refine_json);
        scored = selected.with_poses(refined);
        refine_json["seconds"] = batch_map->refine_seconds;
        refine_json["warm_start"] = {
            {"used", batch_map->warm_start_corners > 0},
            {"corners", batch_map->warm_start_corners},
            {"from_step", batch_map->warm_start_step},
            {"steps_trained", batch_map->mapper->stats().iterations},
            {"relative_change_m", batch_map->relative_pose_change.median_translation_m},
            {"relative_change_deg", batch_map->relative_pose_change.median_rotation_deg}};
        const PoseRefinementRound& last = batch_map->refinement.back();
        std::printf(
            "poses refined with the map in %.1f s: %zu rounds, the last moved %zu scans by %.3f m "
            "/ %.3f deg (median), at most %.3f m from the given poses in all; wrote %s\n",
            batch_map->refine_seconds, batch_map->refinement.size(), last.accepted,
            last.median_translation_m, last.median_rotation_deg,
            refine_json["max_moved_m"].get<double>(), (out / "poses_refined.txt").c_str());
    }
    if (incremental_map && !incremental_map->refined_poses_world.empty()) {
        // Incremental mode refined its kept scans' poses in the consolidation: the poses it
        // mapped at (the data's or the estimates) corrected, held-out scans as in batch mode.
        // With estimated poses the held-out scans stay scored at the data's poses ("heldout",
        // the estimate's drift counted) and next to the refined estimate ("heldout_local").
        const std::vector<PoseRefinementRound>& rounds =
            incremental_map->mapper->consolidation().refinement;
        refined =
            write_refined_poses(out, selected, split, incremental_map->odometry.get(),
                                incremental_map->refined_poses_world, rounds, config, refine_json);
        if (!incremental_map->odometry) scored = selected.with_poses(refined);
        refine_json["in_consolidation"] = true;
        refine_json["kept_scans"] = incremental_map->mapper->consolidation().scans;
        const PoseRefinementRound& last = rounds.back();
        std::printf(
            "poses of the %zu kept scans refined in the consolidation: %zu rounds, the last "
            "moved %zu scans by %.3f m / %.3f deg (median), at most %.3f m in all; wrote %s\n",
            incremental_map->mapper->consolidation().scans, rounds.size(), last.accepted,
            last.median_translation_m, last.median_rotation_deg,
            refine_json["max_moved_m"].get<double>(), (out / "poses_refined.txt").c_str());
    }
    // Colour and reflectance, at the poses the map was made at.
    nlohmann::json appearance_json;
    ExposureTrack exposure;  // the images' gains, for the held-out images below
    {
        ScanSequence mapped_final = sequence;
        if (batch_map && !batch_map->refinement.empty()) {
            mapped_final = scored.subset(split.mapped);
        } else if (odometry_run) {
            mapped_final = sequence.with_poses(odometry_run->odometry->poses());
        } else if (incremental_map && !incremental_map->refined_poses_world.empty()) {
            mapped_final = sequence.with_poses(incremental_map->refined_poses_world);
        } else if (incremental_map && incremental_map->odometry) {
            mapped_final = sequence.with_poses(incremental_map->odometry->poses());
        }
        const ReflectanceVoxels* reflectance =
            batch_map && batch_map->reflectance ? &*batch_map->reflectance : nullptr;
        WrittenSurface* written =
            batch_map && batch_map->products.written ? &*batch_map->products.written : nullptr;
        exposure = add_map_appearance(out, mapped_final, config, cameras, reflectance, written,
                                      appearance_json);
        if (written) written->level_set.reset();  // only the mesh is read again
    }
    const MapProducts& products = incremental ? incremental_map->products : batch_map->products;
    const NeuralSdf& sdf = incremental ? incremental_map->mapper->sdf() : batch_map->mapper->sdf();
    const double save_seconds = products.save_seconds;
    const double bake_seconds = products.bake_seconds;
    const double mesh_seconds = products.mesh_seconds;

    const MappingStats& stats =
        incremental ? incremental_map->mapper->stats() : batch_map->mapper->stats();
    nlohmann::json json;
    json["data"] = data.string();
    json["mode"] = opt.mode;
    json["resumed"] = resuming;
    if (continuing) {
        from_json["new_scans"] = stats.frames;
        from_json["new_corners"] = sdf.octree.num_corners() - incremental_map->mapper->start_rows();
        from_json["old_viewpoints"] = incremental_map->old_viewpoints;
        from_json["old_viewpoint_seconds"] = incremental_map->old_viewpoint_seconds;
        json["from"] = from_json;
    }
    json["frames"] = stats.frames;
    json["rays"] = stats.rays;
    json["threads"] = config.threads;
    json["leaf_size_m"] = config.octree.leaf_size_m;
    json["scene"] = to_string(config.resolved_scene());
    // The schedule's steps; a warm-started batch map trained the last ones of them
    // (refine.warm_start.steps_trained).
    json["iterations"] = batch_map ? static_cast<std::size_t>(batch_map->mapper->iterations_done())
                                   : stats.iterations;
    json["dynamic"] = {
        {"enabled", config.dynamic.enabled},
        {"points_dropped", stats.dynamic_points_dropped},
        {"objects_dropped", stats.dynamic_objects},
        {"moving_objects", stats.moving_objects},
        {"share_dropped", stats.rays ? static_cast<double>(stats.dynamic_points_dropped) /
                                           static_cast<double>(stats.rays)
                                     : 0.0},
        {"seconds", stats.dynamic_seconds}};
    json["preprocess"] = {{"input_points", stats.preprocess.input},
                          {"dropped_nonfinite", stats.preprocess.dropped_nonfinite},
                          {"dropped_zero_range", stats.preprocess.dropped_zero_range},
                          {"dropped_range", stats.preprocess.dropped_range},
                          {"dropped_box", stats.preprocess.dropped_box},
                          {"dropped_downsample", stats.preprocess.dropped_downsample},
                          {"output_points", stats.preprocess.output}};
    json["seconds"] = {{"load", stats.load_seconds},
                       {"allocate", stats.allocate_seconds},
                       {"normals", stats.normals_seconds},
                       {"train", stats.train_seconds},
                       {"save_map", save_seconds},
                       {"bake", bake_seconds},
                       {"mesh", mesh_seconds},
                       {"mapping_total", seconds_since(start_total)}};
    json["seconds_per_frame"] = stats.frames ? (stats.load_seconds + stats.allocate_seconds +
                                                stats.normals_seconds + stats.train_seconds) /
                                                   static_cast<double>(stats.frames)
                                             : 0.0;
    add_product_stats(json, sdf, products, out);
    json["loss"] = {{"bce", stats.final_bce}, {"eikonal", stats.final_eikonal}};
    if (incremental) add_incremental_stats(*incremental_map, json);
    const IncrementalSequenceMap* odometry_map = incremental && incremental_map->odometry
                                                     ? &*incremental_map
                                                 : odometry_run ? &*odometry_run
                                                                : nullptr;
    if (odometry_map) add_odometry_stats(*odometry_map, json);
    const DeskewStats& deskew_stats = incremental ? incremental_map->deskew : batch_map->deskew;
    json["deskew"] = deskew_to_json(config.deskew, deskew_stats, config.odometry.estimate_poses);
    json["deskew"]["azimuth_times"] =
        sequence.has_sweep_times() ? sequence.sweep_times().describe() : std::string("none");
    // Read back by `shine eval --heldout --run` (mapped_run.hpp) to time held-out scans alike.
    if (sequence.has_sweep_times()) {
        json["deskew"]["sweep"] = nlohmann::json::parse(sweep_record_json(sequence.sweep_times()));
    }
    if (!refine_json.is_null()) json["refine"] = refine_json;
    if (odometry_run)
        json["deskew"]["odometry_scans_deskewed"] = odometry_run->deskew.scans_deskewed;
    if (deskew_stats.scans_deskewed > 0) {
        std::printf("deskew: %zu scans deskewed (%zu as measured), points moved up to %.3f m\n",
                    deskew_stats.scans_deskewed, deskew_stats.scans_as_measured,
                    deskew_stats.max_shift_m);
    }
    const StageProfile& profile = incremental ? incremental_map->profile : batch_map->profile;
    json["profile"] = profile_to_json(profile);

    std::printf("mapped %zu frames (%zu rays) in %.1f s: %.3f s/frame, map %.2f MB (%zu corners)\n",
                stats.frames, stats.rays, seconds_since(start_total),
                json["seconds_per_frame"].get<double>(), sdf.memory_bytes() / 1e6,
                sdf.octree.num_corners());
    if (incremental) {
        std::printf("incremental: median %.3f s/frame with %d threads\n",
                    json["incremental"]["median_seconds_per_frame"].get<double>(),
                    json["incremental"]["threads_used"].get<int>());
        const ConsolidationStats& c = incremental_map->mapper->consolidation();
        if (c.steps > 0) {
            std::printf("consolidation: %d steps over the last %zu scans in %.1f s\n", c.steps,
                        c.scans, c.seconds);
        }
    }
    if (odometry_map) {
        const nlohmann::json& o = json["odometry"];
        std::string counts;
        for (const auto& [source, n] : o["counts"].items()) {
            counts += (counts.empty() ? "" : ", ") + std::to_string(n.get<int>()) + " " + source;
        }
        std::printf("odometry: %zu poses (%s), median %.3f s/scan with mapping; wrote %s\n",
                    odometry_map->odometry->poses().size(), counts.c_str(),
                    o["median_seconds_per_scan"].get<double>(), (out / "poses.txt").c_str());
        if (json.contains("keyframes") && json["keyframes"]["enabled"].get<bool>()) {
            const nlohmann::json& k = json["keyframes"];
            std::printf(
                "keyframes: %d scans trained when they came (median %.3f s/scan), %d deferred "
                "(median %.3f s/scan; %d by the budget, %d while the background training was "
                "busy; the keyframes took the steps of %d), %d caught up after the last scan in "
                "%.1f s, %d skipped\n",
                k["trained"].get<int>(), k["median_seconds_per_trained_scan"].get<double>(),
                k["deferred"].get<int>(), k["median_seconds_per_deferred_scan"].get<double>(),
                k["deferred_over_budget"].get<int>(), k["deferred_while_busy"].get<int>(),
                k["deferred_steps_taken"].get<int>(), k["caught_up"].get<int>(),
                k["catch_up_seconds"].get<double>(), k["skipped"].get<int>());
        }
    }
    std::printf("wrote %s, %s, %s (%zu triangles)\n", (out / "map.vdb").c_str(),
                (out / "surface.vdb").c_str(), (out / "mesh.ply").c_str(), products.mesh.triangles);
    if (opt.profile) std::printf("%s", profile.format_table().c_str());
    // Batch mode keeps the mesh it wrote (and the appearance step gave back): the scores below
    // need not read mesh.ply again.
    const TriangleMesh* kept_mesh =
        batch_map && batch_map->products.written ? &batch_map->products.written->mesh : nullptr;
    const ScanOdometry* odometry = incremental_map ? incremental_map->odometry.get()
                                   : odometry_run  ? odometry_run->odometry.get()
                                                   : nullptr;
    if (!ref.empty()) {
        const auto t0 = std::chrono::steady_clock::now();
        std::optional<TriangleMesh> read;
        if (!kept_mesh) read = read_ply_mesh(out / "mesh.ply");
        const TriangleMesh& mesh = kept_mesh ? *kept_mesh : *read;
        const TriangleMesh reference = read_ply_mesh(ref);
        // At the scene's threshold: 10 cm outdoors (the street's protocol), 1 mm for an object.
        const EvalConfig eval_config =
            eval_config_for_threshold(scene_defaults(config.resolved_scene()).eval_threshold_m);
        const MeshMetrics metrics = evaluate_meshes(mesh, reference, eval_config);
        json["eval"] = nlohmann::json::parse(metrics_to_json(metrics));
        json["eval"]["reference"] = ref.string();
        std::printf("accuracy against %s:\n%s", ref.c_str(), format_metrics(metrics).c_str());
        if (odometry && selected.has_poses()) {
            evaluate_aligned_to_data_poses(mesh, reference, eval_config, *odometry, selected, split,
                                           json);
        }
        if (!refined.empty() && !selected.from_recording() &&
            fs::exists(selected.directory() / kTruePosesFile)) {
            evaluate_aligned_to_true_poses(mesh, reference, eval_config, refined, selected, split,
                                           json);
        }
        json["seconds"]["eval"] = seconds_since(t0);
    }
    score_heldout(out / "mesh.ply", scored, split, opt.holdout_every, config.preprocess, json,
                  "heldout", deskew ? &config.deskew : nullptr, kept_mesh);
    if (odometry && !split.heldout.empty()) {
        // The held-out scans at the data's poses also count the estimate's drift against them;
        // placed next to the mapped scan before each, they score the map alone.
        std::printf(
            "held-out scans placed relative to the estimated pose of the mapped scan before "
            "each (the data's relative motion; drift not counted):\n");
        // With poses refined in an incremental run's consolidation, next to the refined ones.
        const std::vector<Eigen::Isometry3d>& mapped_poses =
            incremental_map && !incremental_map->refined_poses_world.empty()
                ? incremental_map->refined_poses_world
                : odometry->poses();
        score_heldout(
            out / "mesh.ply",
            selected.with_poses(heldout_poses_local_to_estimate(selected, split, mapped_poses)),
            split, opt.holdout_every, config.preprocess, json, "heldout_local",
            deskew ? &config.deskew : nullptr, kept_mesh);
    }
    if (appearance_json.contains("appearance")) {
        json["appearance"] = appearance_json["appearance"];
        score_heldout_colours(out, scored, split, cameras, exposure, json);
    }
    json["seconds"]["total"] = seconds_since(start_total);
    json["peak_rss_bytes"] = peak_rss_bytes();
    write_json(out / "stats.json", json);
    // The products are complete: the checkpoint is no longer needed.
    std::error_code ignored;
    fs::remove(checkpoint_file(out), ignored);
    return 0;
}

const RegisterCommand kRegister(20, [](CLI::App& app, Action& action) {
    auto opt = std::make_shared<MapOptions>();
    CLI::App* cmd = app.add_subcommand(
        "map",
        "Map a scan sequence into OUT/map.vdb, OUT/surface.vdb, OUT/mesh.ply, OUT/stats.json");
    cmd->add_option("data", opt->data,
                    "Sequence directory (KITTI layout or .ply/.pcd scans with poses) or recording "
                    "(ROS 1 .bag, ROS 2 bag folder, .mcap, .db3; needs --poses); default: the "
                    "bundled example street, simulated on first use");
    cmd->add_option("-o,--output", opt->out, "Output directory")->capture_default_str();
    cmd->add_option("-c,--config", opt->config_path,
                    "YAML configuration (see examples/config.yaml)");
    cmd->add_option("--leaf-size-m", opt->leaf_size_m,
                    "Level-0 cell size in metres (default 0.2, or the --scene's); every length "
                    "default not set in the config (thinning, surface band, sigma, normal radius) "
                    "follows it in proportion");
    cmd->add_option("--scene", opt->scene,
                    "outdoor (1.5-60 m ranges, 0.2 m leaves, scored at 10 cm), indoor (0.3-20 m, "
                    "0.05 m, 2 cm) or object (0.1-3 m, 3 mm, 1 mm); default (map.scene: auto): "
                    "from the leaf size, outdoor from 0.1 m, object below 1 cm")
        ->check(CLI::IsMember({"auto", "outdoor", "indoor", "object"}));
    cmd->add_option("--threads", opt->threads, "Worker threads (0 = all cores)");
    cmd->add_option("--iterations", opt->iterations,
                    "Optimisation steps (batch mode). Default: automatic, 250 steps of 32768 "
                    "samples at 0.2 m leaves; a set count takes 4096-sample steps at lr 0.01 "
                    "unless training.batch_size / learning_rate are set");
    cmd->add_option("--seed", opt->seed, "Random seed (features, decoder, sampling)");
    cmd->add_option("--mode", opt->mode,
                    "batch (all scans, decoder trained) or incremental (scan by scan, pretrained "
                    "frozen decoder, importance weights against forgetting)")
        ->capture_default_str();
    cmd->add_option("--max-ms-per-scan", opt->max_ms_per_scan,
                    "Incremental mode without poses: the real-time budget of a scan in ms; the "
                    "keyframes train in the background and are deferred when the training or the "
                    "budget cannot take them, registration never (docs/realtime.md)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--mesh-every", opt->mesh_every,
                    "Incremental mode: write OUT/progress/mesh_NNNNNN.ply every K frames");
    add_scan_selection_options(cmd, opt->first_frame, opt->last_frame, opt->frame_step,
                               opt->poses_path);
    cmd->get_option("--poses")->description(
        "Pose file (default: found in DATA; for a recording a TUM trajectory matched to the "
        "scans by time), or `estimate`: estimate each scan's pose while mapping (in batch mode "
        "by an incremental run first; incremental mode does so for data without poses)");
    add_topic_option(cmd, opt->topic);
    add_evaluation_options(cmd, opt->ref_path, opt->no_eval);
    add_holdout_option(cmd, opt->holdout_every);
    cmd->add_flag("--deskew", opt->deskew,
                  "Deskew every scan: move its points, measured over the sweep, to the instant "
                  "of the scan's pose at the constant velocity between consecutive poses (given "
                  "or estimated). Needs per-point times (PLY/PCD/PointCloud2 field t, time, "
                  "timestamp or offset_time), or times from the azimuth (scans without them: "
                  "deskew.azimuth_times). Default (deskew.mode: auto): with --poses estimate when "
                  "the scans carry times, and with any poses when the sweep test finds scans "
                  "without times skewed");
    cmd->add_flag("--no-deskew", opt->no_deskew,
                  "Never deskew, not even with --poses estimate (deskew.mode: off)")
        ->excludes("--deskew");
    cmd->add_flag("--no-refine", opt->no_refine,
                  "Batch mode: keep the given poses instead of refining them with the map "
                  "(refine.rounds: 0)");
    cmd->add_flag("--half-features", opt->half_features,
                  "Store the features in float16 (the default; map.feature_precision: float16)");
    cmd->add_flag("--full-features", opt->full_features,
                  "Store the features in float32 (map.feature_precision: float32)")
        ->excludes("--half-features");
    cmd->add_option("--dynamic-filter", opt->dynamic_filter,
                    "on (the default): drop the points other scans see through (moving objects, "
                    "docs/movers.md); off: map every point (config dynamic.enabled)")
        ->check(CLI::IsMember({"on", "off"}));
    cmd->add_option("--max-map-mb", opt->max_map_mb,
                    "Stop before training if the map (features + structure) would exceed this "
                    "many MB (0 = unlimited; config map.max_map_mb)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_flag("--profile", opt->profile,
                  "Print seconds per stage (per-frame medians and run totals; also in "
                  "stats.json \"profile\")");
    cmd->add_option("--from", opt->from,
                    "Continue this saved map (a `shine map` output folder or its map.vdb) with "
                    "DATA's scans, in incremental mode: its features (held by the importance "
                    "weights), decoder (frozen) and world frame; DATA's poses are in that frame, "
                    "or without poses each scan is localised in the map first (scans not "
                    "localised are skipped). Needs the settings the map was made with. "
                    "--first-frame one past DATA's last scan selects no new scan: the map is "
                    "written again unchanged (docs/continue.md)");
    cmd->add_option("--resume", opt->resume_dir,
                    "Continue the run stopped (Ctrl-C, SIGTERM) with its checkpoint in this "
                    "output directory, to the result the uninterrupted run gives; its settings "
                    "come from the checkpoint");
    cmd->add_option("--checkpoint-minutes", opt->checkpoint_minutes,
                    "Also write OUT/checkpoint.bin every this many minutes (0: only when stopped "
                    "by Ctrl-C/SIGTERM); removed when the run completes")
        ->capture_default_str();
    cmd->add_option("--interrupt-after", opt->interrupt_after,
                    "Testing: act as if Ctrl-C were pressed during step N")
        ->group("");
    cmd->add_flag("-q,--quiet", opt->quiet, "No progress output");
    cmd->add_flag("--print-config", opt->print_config,
                  "Print the effective configuration as YAML and exit");
    cmd->callback([opt, cmd, &action] {
        opt->given.clear();
        for (const CLI::Option* option : cmd->get_options()) {
            if (option->count() > 0) opt->given.push_back(option->get_name());
        }
        action = [opt] { return run_map(*opt); };
    });
});

}  // namespace
}  // namespace shine::cli
