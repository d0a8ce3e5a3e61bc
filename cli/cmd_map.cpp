// `shine map [DATA] -o OUT`: scans -> neural map (map.vdb) -> level set (surface.vdb) -> mesh.ply,
// with stats.json, and metrics against a reference mesh when one is available.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "cli_common.hpp"
#include "command_registry.hpp"
#include "shine/bake/level_set_bake.hpp"
#include "shine/bake/level_set_file.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/eval/mesh_metrics.hpp"
#include "shine/eval/metrics_report.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/map/map_file.hpp"
#include "shine/mapper/batch_mapper.hpp"
#include "shine/mesh/level_set_mesh.hpp"
#include "shine/sim/lidar_simulator.hpp"

namespace shine::cli {
namespace {
namespace fs = std::filesystem;

struct MapOptions {
    std::string data;
    std::string out = "out";
    std::string config_path;
    double leaf_size_m = 0.0;
    int threads = -1;
    int iterations = -1;
    long long seed = -1;
    int first_frame = 0, last_frame = -1, frame_step = 1;
    std::string poses_path;
    std::string ref_path;
    bool no_eval = false;
    bool quiet = false;
    bool print_config = false;
    std::string mode = "batch";
};

void write_json(const fs::path& path, const nlohmann::json& json) {
    write_stream_atomically(path, [&](std::ostream& out) { out << json.dump(2) << "\n"; });
}

int run_map(const MapOptions& opt) {
    const auto start_total = std::chrono::steady_clock::now();
    Progress::set_globally_enabled(!opt.quiet);
    if (opt.mode != "batch") {
        throw ConfigError("--mode " + opt.mode + " is not available yet (only 'batch')");
    }
    MapperConfig config;
    if (!opt.config_path.empty()) load_config_yaml(opt.config_path, config);
    if (opt.leaf_size_m != 0.0) {
        if (!(opt.leaf_size_m > 0.0)) throw ConfigError("--leaf-size-m must be positive");
        config.octree.leaf_size_m = opt.leaf_size_m;
    }
    if (opt.threads >= 0) config.threads = opt.threads;
    if (opt.iterations >= 0) config.iterations = opt.iterations;
    if (opt.seed >= 0) config.seed = static_cast<std::uint64_t>(opt.seed);
    config.finalize();
    if (opt.print_config) {
        std::printf("%s", config_to_yaml(config).c_str());
        return 0;
    }
    auto threads = limit_threads(config.threads);

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
    const ScanSequence sequence = ScanSequence::open(data, seq_options);
    fs::path ref = opt.ref_path;
    if (ref.empty() && !opt.no_eval && fs::exists(data / "gt_mesh.ply")) ref = data / "gt_mesh.ply";
    if (!ref.empty() && !fs::is_regular_file(ref)) {
        throw IoError("reference mesh '" + ref.string() + "' does not exist");
    }
    const fs::path out = opt.out;
    ensure_directory(out);

    BatchMapper mapper(config);
    {
        Progress progress("load", sequence.size());
        for (std::size_t i = 0; i < sequence.size(); ++i) {
            mapper.add_scan(sequence.load(i));
            progress.update(i + 1, std::to_string(mapper.sdf().octree.num_corners()) + " corners");
        }
        progress.finish(std::to_string(mapper.stats().rays) + " rays, " +
                        std::to_string(mapper.sdf().octree.num_corners()) + " corners");
    }
    {
        Progress progress("train", static_cast<std::size_t>(config.iterations));
        mapper.train([&](std::size_t done, double bce) {
            char detail[64];
            std::snprintf(detail, sizeof(detail), "bce %.4f", bce);
            progress.update(done, detail);
        });
        progress.finish();
    }
    const NeuralSdf& sdf = mapper.sdf();
    const std::string config_yaml = config_to_yaml(config);
    auto t0 = std::chrono::steady_clock::now();
    save_neural_map(out / "map.vdb", sdf, config_yaml);
    const double save_seconds = seconds_since(t0);

    t0 = std::chrono::steady_clock::now();
    BakeStats bake_stats;
    auto surface = bake_level_set(sdf, config.bake, &bake_stats);
    write_level_set(out / "surface.vdb", surface);
    const double bake_seconds = seconds_since(t0);

    t0 = std::chrono::steady_clock::now();
    const TriangleMesh mesh = mesh_level_set(*surface, config.mesh);
    write_ply_mesh(out / "mesh.ply", mesh);
    const double mesh_seconds = seconds_since(t0);

    const MappingStats& stats = mapper.stats();
    nlohmann::json json;
    json["data"] = data.string();
    json["frames"] = stats.frames;
    json["rays"] = stats.rays;
    json["threads"] = config.threads;
    json["leaf_size_m"] = config.octree.leaf_size_m;
    json["iterations"] = stats.iterations;
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
                       {"total", seconds_since(start_total)}};
    json["seconds_per_frame"] =
        stats.frames ? (stats.load_seconds + stats.allocate_seconds + stats.normals_seconds +
                        stats.train_seconds) /
                           static_cast<double>(stats.frames)
                     : 0.0;
    json["map"] = {{"corners", sdf.octree.num_corners()},
                   {"feature_bytes", sdf.octree.feature_bytes()},
                   {"structure_bytes", sdf.octree.structure_bytes()},
                   {"decoder_bytes", sdf.decoder.num_params() * sizeof(float)},
                   {"map_bytes", sdf.memory_bytes()},
                   {"file_bytes", file_bytes(out / "map.vdb")}};
    json["surface"] = {{"voxel_size_m", bake_stats.voxel_size_m},
                       {"active_voxels", bake_stats.active_voxels},
                       {"mem_bytes", surface->memUsage()},
                       {"file_bytes", file_bytes(out / "surface.vdb")}};
    json["mesh"] = {{"vertices", mesh.vertices.size()}, {"triangles", mesh.triangles.size()}};
    json["loss"] = {{"bce", stats.final_bce}, {"eikonal", stats.final_eikonal}};

    std::printf("mapped %zu frames (%zu rays) in %.1f s: %.3f s/frame, map %.2f MB (%zu corners)\n",
                stats.frames, stats.rays, seconds_since(start_total),
                json["seconds_per_frame"].get<double>(), sdf.memory_bytes() / 1e6,
                sdf.octree.num_corners());
    std::printf("wrote %s, %s, %s (%zu triangles)\n", (out / "map.vdb").c_str(),
                (out / "surface.vdb").c_str(), (out / "mesh.ply").c_str(), mesh.triangles.size());
    if (!ref.empty()) {
        t0 = std::chrono::steady_clock::now();
        const MeshMetrics metrics = evaluate_meshes(mesh, read_ply_mesh(ref));
        json["eval"] = nlohmann::json::parse(metrics_to_json(metrics));
        json["eval"]["reference"] = ref.string();
        json["seconds"]["eval"] = seconds_since(t0);
        std::printf("accuracy against %s:\n%s", ref.c_str(), format_metrics(metrics).c_str());
    }
    json["peak_rss_bytes"] = peak_rss_bytes();
    write_json(out / "stats.json", json);
    return 0;
}

const RegisterCommand kRegister(20, [](CLI::App& app, Action& action) {
    auto opt = std::make_shared<MapOptions>();
    CLI::App* cmd = app.add_subcommand(
        "map",
        "Map a scan sequence into OUT/map.vdb, OUT/surface.vdb, OUT/mesh.ply, OUT/stats.json");
    cmd->add_option("data", opt->data,
                    "Sequence directory (KITTI layout or .ply/.pcd scans with poses); default: the "
                    "bundled example street, simulated on first use");
    cmd->add_option("-o,--output", opt->out, "Output directory")->capture_default_str();
    cmd->add_option("-c,--config", opt->config_path,
                    "YAML configuration (see examples/config.yaml)");
    cmd->add_option("--leaf-size-m", opt->leaf_size_m, "Level-0 cell size in metres (default 0.2)");
    cmd->add_option("--threads", opt->threads, "Worker threads (0 = all cores)");
    cmd->add_option("--iterations", opt->iterations, "Optimisation steps (batch mode)");
    cmd->add_option("--seed", opt->seed, "Random seed (features, decoder, sampling)");
    cmd->add_option("--mode", opt->mode, "batch (incremental: not yet available)");
    cmd->add_option("--first-frame", opt->first_frame, "First scan index")->capture_default_str();
    cmd->add_option("--last-frame", opt->last_frame, "Last scan index, -1 = all")
        ->capture_default_str();
    cmd->add_option("--frame-step", opt->frame_step, "Use every n-th scan")->capture_default_str();
    cmd->add_option("--poses", opt->poses_path, "Pose file (default: found in DATA)");
    cmd->add_option("--ref", opt->ref_path,
                    "Reference mesh to evaluate against (default: DATA/gt_mesh.ply if present)");
    cmd->add_flag("--no-eval", opt->no_eval, "Skip the evaluation");
    cmd->add_flag("-q,--quiet", opt->quiet, "No progress output");
    cmd->add_flag("--print-config", opt->print_config,
                  "Print the effective configuration as YAML and exit");
    cmd->callback([opt, &action] { action = [opt] { return run_map(*opt); }; });
});

}  // namespace
}  // namespace shine::cli
