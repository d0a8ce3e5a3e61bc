// `shine tsdf [DATA] -o OUT`: the VDBFusion baseline -- scans -> TSDF volume (tsdf.vdb) ->
// mesh.ply, with stats.json, and metrics against a reference mesh when one is available.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "cli_common.hpp"
#include "command_registry.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/eval/mesh_metrics.hpp"
#include "shine/eval/metrics_report.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/io/scene_preset.hpp"
#include "shine/sim/lidar_simulator.hpp"
#include "shine/tsdf/tsdf_file.hpp"
#include "shine/tsdf/tsdf_mapper.hpp"

namespace shine::cli {
namespace {
namespace fs = std::filesystem;

struct TsdfOptions {
    std::string data;
    std::string out = "out-tsdf";
    TsdfMapperConfig config;
    int threads = 0;
    int first_frame = 0, last_frame = -1, frame_step = 1;
    int holdout_every = 0;  ///< > 0: every N-th scan is not fused but scores the mesh
    std::string poses_path;
    std::string topic;
    std::string ref_path;
    bool no_eval = false;
    bool quiet = false;
    std::string scene = "auto";  ///< outdoor | indoor | object | auto (from the voxel size)
    bool min_range_given = false, max_range_given = false;
    bool trunc_given = false, downsample_given = false;
};

/// The scene's defaults for the options not given. Outdoors nothing changes (VDBFusion's street
/// settings); indoors and for objects the ranges come from the preset, the truncation is 3 voxels
/// and the input thinning half a voxel, as the outdoor defaults are at 0.1 m voxels.
TsdfMapperConfig config_for_scene(const TsdfOptions& opt, ScenePreset preset) {
    TsdfMapperConfig config = opt.config;
    if (preset == ScenePreset::kOutdoor) return config;
    const SceneDefaults scene = scene_defaults(preset);
    if (!opt.min_range_given) config.preprocess.min_range_m = scene.min_range_m;
    if (!opt.max_range_given) config.preprocess.max_range_m = scene.max_range_m;
    if (!opt.trunc_given) config.tsdf.trunc_m = 3.0 * config.tsdf.voxel_size_m;
    if (!opt.downsample_given) config.preprocess.voxel_downsample_m = config.tsdf.voxel_size_m / 2;
    return config;
}

std::size_t size_of(const fs::path& path) { return static_cast<std::size_t>(fs::file_size(path)); }

int run_tsdf(const TsdfOptions& opt) {
    const auto start_total = std::chrono::steady_clock::now();
    Progress::set_globally_enabled(!opt.quiet);
    const ScenePreset preset = opt.scene == "auto" ? scene_for_leaf(opt.config.tsdf.voxel_size_m)
                                                   : parse_scene_preset(opt.scene, "--scene");
    const TsdfMapperConfig config = config_for_scene(opt, preset);
    config.validate();
    auto thread_limit = limit_threads(opt.threads);

    // Data: the bundled street unless a directory is given; simulated on first use.
    fs::path data = opt.data;
    if (data.empty()) {
        data = bundled_example_dir();
        if (!fs::exists(data / "poses.txt")) {
            std::fprintf(stderr, "shine: simulating the bundled example street into %s\n",
                         data.c_str());
            sim::SimulationConfig sim_config;
            sim_config.show_progress = !opt.quiet;
            sim::simulate_sequence(sim_config, data);
        }
    }
    ScanSequenceOptions seq_options;
    seq_options.first_frame = opt.first_frame;
    seq_options.last_frame = opt.last_frame;
    seq_options.frame_step = opt.frame_step;
    seq_options.poses_path = opt.poses_path;
    seq_options.topic = opt.topic;
    const ScanSequence selected = ScanSequence::open(data, seq_options);
    // With --holdout-every N every N-th scan is not fused; they score the mesh afterwards.
    const HoldoutSplit split = split_holdout(selected, opt.holdout_every);
    const ScanSequence sequence = selected.subset(split.mapped);
    fs::path ref = opt.ref_path;
    if (ref.empty() && !opt.no_eval && fs::exists(data / "gt_mesh.ply")) ref = data / "gt_mesh.ply";
    if (!ref.empty() && !fs::is_regular_file(ref)) {
        throw IoError("reference mesh '" + ref.string() + "' does not exist");
    }
    const fs::path out = opt.out;
    ensure_directory(out);

    TsdfMapper mapper(config);
    double read_seconds = 0.0;
    {
        Progress progress("tsdf", sequence.size());
        for (std::size_t i = 0; i < sequence.size(); ++i) {
            const auto t0 = std::chrono::steady_clock::now();
            const Scan scan = sequence.load(i);
            read_seconds += seconds_since(t0);
            mapper.add_scan(scan);
            progress.update(i + 1, std::to_string(mapper.stats().voxel_updates) + " updates");
        }
        progress.finish(std::to_string(mapper.stats().points) + " points, " +
                        std::to_string(mapper.volume().active_voxels()) + " voxels");
    }
    const TsdfVolume& volume = mapper.volume();
    const TsdfMappingStats& stats = mapper.stats();

    auto t0 = std::chrono::steady_clock::now();
    const TriangleMesh mesh = mapper.extract_mesh();
    const double mesh_seconds = seconds_since(t0);

    t0 = std::chrono::steady_clock::now();
    write_tsdf_volume(out / "tsdf.vdb", volume);
    write_ply_mesh(out / "mesh.ply", mesh);
    const double save_seconds = seconds_since(t0);

    const Eigen::Vector3d& origin = volume.origin_world_m();
    nlohmann::json json;
    json["method"] = "tsdf";
    json["data"] = data.string();
    json["frames"] = stats.frames;
    json["points"] = stats.points;
    json["threads"] = opt.threads;
    json["scene"] = to_string(preset);
    json["parameters"] = {{"voxel_size_m", config.tsdf.voxel_size_m},
                          {"trunc_m", config.tsdf.trunc_m},
                          {"space_carving", config.tsdf.space_carving},
                          {"min_weight", config.mesh.min_weight},
                          {"fill_holes", config.mesh.fill_holes}};
    json["preprocess"] = {{"input_points", stats.preprocess.input},
                          {"dropped_nonfinite", stats.preprocess.dropped_nonfinite},
                          {"dropped_zero_range", stats.preprocess.dropped_zero_range},
                          {"dropped_range", stats.preprocess.dropped_range},
                          {"dropped_box", stats.preprocess.dropped_box},
                          {"dropped_downsample", stats.preprocess.dropped_downsample},
                          {"output_points", stats.preprocess.output}};
    json["origin_world_m"] = {origin.x(), origin.y(), origin.z()};
    json["seconds"] = {{"read", read_seconds},
                       {"preprocess", stats.preprocess_seconds},
                       {"integrate", stats.integrate_seconds},
                       {"mesh", mesh_seconds},
                       {"save", save_seconds}};
    const double per_frame =
        stats.frames ? (stats.preprocess_seconds + stats.integrate_seconds) / stats.frames : 0.0;
    json["seconds_per_frame"] = per_frame;
    json["tsdf"] = {{"active_voxels", volume.active_voxels()},
                    {"voxel_updates", stats.voxel_updates},
                    {"tsdf_mem_bytes", volume.tsdf_memory_bytes()},
                    {"weight_mem_bytes", volume.weight_memory_bytes()},
                    {"mem_bytes", volume.memory_bytes()},
                    {"file_bytes", size_of(out / "tsdf.vdb")}};
    json["mesh"] = {{"vertices", mesh.vertices.size()},
                    {"triangles", mesh.triangles.size()},
                    {"file_bytes", size_of(out / "mesh.ply")}};

    std::printf(
        "integrated %zu frames (%zu points) in %.1f s: %.3f s/frame, TSDF + weight %.2f MB "
        "(%zu voxels)\n",
        stats.frames, stats.points, stats.preprocess_seconds + stats.integrate_seconds, per_frame,
        volume.memory_bytes() / 1e6, volume.active_voxels());
    std::printf("wrote %s, %s (%zu triangles)\n", (out / "tsdf.vdb").c_str(),
                (out / "mesh.ply").c_str(), mesh.triangles.size());
    json["seconds"]["mapping_total"] = seconds_since(start_total);
    if (!ref.empty()) {
        t0 = std::chrono::steady_clock::now();
        const MeshMetrics metrics =
            evaluate_meshes(mesh, read_ply_mesh(ref),
                            eval_config_for_threshold(scene_defaults(preset).eval_threshold_m));
        json["eval"] = nlohmann::json::parse(metrics_to_json(metrics));
        json["eval"]["reference"] = ref.string();
        json["seconds"]["eval"] = seconds_since(t0);
        std::printf("accuracy against %s:\n%s", ref.c_str(), format_metrics(metrics).c_str());
    }
    score_heldout(out / "mesh.ply", selected, split, opt.holdout_every, config.preprocess, json);
    json["seconds"]["total"] = seconds_since(start_total);
    json["peak_rss_bytes"] = peak_rss_bytes();
    write_stream_atomically(out / "stats.json",
                            [&](std::ostream& os) { os << json.dump(2) << "\n"; });
    return 0;
}

const RegisterCommand kRegisterTsdf(60, [](CLI::App& app, Action& action) {
    auto opt = std::make_shared<TsdfOptions>();
    auto& c = opt->config;
    CLI::App* cmd = app.add_subcommand(
        "tsdf",
        "Baseline: TSDF fusion with VDBFusion's algorithm into OUT/tsdf.vdb (grids tsdf, weight), "
        "OUT/mesh.ply, OUT/stats.json (see docs/tsdf.md)");
    cmd->add_option("data", opt->data,
                    "Sequence directory (KITTI layout or .ply/.pcd scans with poses); default: the "
                    "bundled example street, simulated on first use");
    cmd->add_option("-o,--output", opt->out, "Output directory")->capture_default_str();
    cmd->add_option("--voxel-size-m", c.tsdf.voxel_size_m, "Voxel edge, m (VDBFusion voxel_size)")
        ->capture_default_str();
    cmd->add_option("--scene", opt->scene,
                    "outdoor, indoor or object: ranges and evaluation threshold as `shine map "
                    "--scene`; indoor and object also default to 3 voxels of truncation and half "
                    "a voxel of thinning; auto: from the voxel size (outdoor from 0.1 m)")
        ->check(CLI::IsMember({"auto", "outdoor", "indoor", "object"}))
        ->capture_default_str();
    CLI::Option* trunc =
        cmd->add_option("--trunc-m", c.tsdf.trunc_m,
                        "Truncation distance, m (VDBFusion sdf_trunc; it uses 3 voxels)")
            ->capture_default_str();
    CLI::Option* downsample =
        cmd->add_option(
               "--voxel-downsample-m", c.preprocess.voxel_downsample_m,
               "Keep one point per voxel of this size before fusing, m (0: every point, as "
               "VDBFusion's loaders)")
            ->check(CLI::NonNegativeNumber)
            ->capture_default_str();
    CLI::Option* min_range = cmd->add_option("--min-range-m", c.preprocess.min_range_m,
                                             "Drop points closer than this, m")
                                 ->check(CLI::NonNegativeNumber)
                                 ->capture_default_str();
    CLI::Option* max_range = cmd->add_option("--max-range-m", c.preprocess.max_range_m,
                                             "Drop points farther than this, m")
                                 ->check(CLI::PositiveNumber)
                                 ->capture_default_str();
    cmd->add_flag("--space-carving", c.tsdf.space_carving,
                  "Update every voxel from the sensor to the point, not only the band");
    cmd->add_option("--min-weight", c.mesh.min_weight,
                    "Mesh only cubes whose 8 corners have at least this weight, i.e. this many "
                    "updates (VDBFusion min_weight; 0.5 = observed at least once)")
        ->capture_default_str();
    cmd->add_flag("--fill-holes", c.mesh.fill_holes,
                  "Let the mesher use unobserved corners (VDBFusion fill_holes; only has an "
                  "effect with --min-weight 0)");
    cmd->add_option("--threads", opt->threads, "Worker threads (0 = all cores)")
        ->check(CLI::NonNegativeNumber);
    add_scan_selection_options(cmd, opt->first_frame, opt->last_frame, opt->frame_step,
                               opt->poses_path);
    add_topic_option(cmd, opt->topic);
    add_evaluation_options(cmd, opt->ref_path, opt->no_eval);
    add_holdout_option(cmd, opt->holdout_every);
    cmd->add_flag("-q,--quiet", opt->quiet, "No progress output");
    cmd->callback([opt, &action, trunc, downsample, min_range, max_range] {
        opt->trunc_given = trunc->count() > 0;
        opt->downsample_given = downsample->count() > 0;
        opt->min_range_given = min_range->count() > 0;
        opt->max_range_given = max_range->count() > 0;
        action = [opt] { return run_tsdf(*opt); };
    });
});

}  // namespace
}  // namespace shine::cli
