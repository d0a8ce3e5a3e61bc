// `shine forgetting [DATA] -o OUT`: the forgetting experiment (bench/forgetting_experiment.hpp):
// incremental mapping with and without the importance-weight regulariser, metrics on the whole
// map and on the part seen in the first quarter of the run, and the meshes side by side (PNG).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "cli_common.hpp"
#include "command_registry.hpp"
#include "shine/bench/forgetting_experiment.hpp"
#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/scan_sequence.hpp"

namespace shine::cli {
namespace {
namespace fs = std::filesystem;

struct ForgettingOptions {
    std::string data;
    std::string out = "out_forgetting";
    std::string config_path;
    std::string ref_path;
    double leaf_size_m = 0.0;
    double regularization_weight = -1.0;
    int iterations_per_frame = -1;
    int replay_frames = 0;  ///< 0: 1 unless the config sets incremental.replay_frames
    int threads = -1;
    double early_fraction = 0.25;
    double region_voxel_m = 1.0;
    int panel_width = 800;
    bool with_batch = false;
    bool quiet = false;
};

int run_forgetting(const ForgettingOptions& opt) {
    const auto start = std::chrono::steady_clock::now();
    Progress::set_globally_enabled(!opt.quiet);
    ForgettingConfig config;
    if (!opt.config_path.empty()) load_config_yaml(opt.config_path, config.mapper);
    if (opt.leaf_size_m != 0.0) {
        if (!(opt.leaf_size_m > 0.0)) throw ConfigError("--leaf-size-m must be positive");
        config.mapper.octree.leaf_size_m = opt.leaf_size_m;
    }
    if (opt.regularization_weight >= 0.0) {
        config.mapper.incremental.importance.regularization_weight =
            static_cast<float>(opt.regularization_weight);
    }
    if (opt.iterations_per_frame >= 0) {
        config.mapper.incremental.iterations_per_frame = opt.iterations_per_frame;
    }
    // The paper's experiment trains each scan on its own rays: replaying earlier scans (the
    // mapping default) also keeps the early region, so the two runs would differ little.
    if (opt.replay_frames >= 1) {
        config.mapper.incremental.replay_frames = opt.replay_frames;
    } else if (!config.mapper.is_set("incremental.replay_frames")) {
        config.mapper.incremental.replay_frames = 1;
    }
    if (opt.threads >= 0) config.mapper.threads = opt.threads;
    config.early_fraction = opt.early_fraction;
    config.region_voxel_m = opt.region_voxel_m;
    config.with_batch = opt.with_batch;
    if (opt.panel_width < 64 || opt.panel_width > 4096) {
        throw ConfigError("--panel-width must be between 64 and 4096 pixels");
    }
    config.image_panel_width = opt.panel_width;
    config.mapper.finalize();
    auto threads = limit_threads(config.mapper.threads);

    const fs::path data = resolve_data_dir(opt.data, opt.quiet);
    const ScanSequence sequence = ScanSequence::open(data);
    const fs::path ref = resolve_reference(data, opt.ref_path, false);
    if (ref.empty()) {
        throw IoError("no reference mesh: " + (data / "gt_mesh.ply").string() +
                      " does not exist; give one with --ref");
    }
    const TriangleMesh reference = read_ply_mesh(ref);
    const ForgettingReport report = run_forgetting_experiment(config, sequence, reference, opt.out);
    std::printf("%s", format_forgetting_report(report).c_str());
    std::printf(
        "wrote %s/{unregularized,regularized%s}/, forgetting.json, forgetting.png in %.1f s\n",
        opt.out.c_str(), opt.with_batch ? ",batch" : "", seconds_since(start));
    return 0;
}

const RegisterCommand kRegisterForgetting(75, [](CLI::App& app, Action& action) {
    auto opt = std::make_shared<ForgettingOptions>();
    CLI::App* cmd = app.add_subcommand(
        "forgetting",
        "The forgetting experiment: map DATA incrementally with and without the importance-weight "
        "regulariser, evaluate the whole map and the part seen in the first quarter of the run, "
        "draw both meshes side by side (OUT/forgetting.png, OUT/forgetting.json)");
    cmd->add_option("data", opt->data, "Sequence directory (default: the bundled example street)");
    cmd->add_option("-o,--output", opt->out, "Output directory")->capture_default_str();
    cmd->add_option("-c,--config", opt->config_path, "YAML configuration");
    cmd->add_option("--ref", opt->ref_path, "Reference mesh (default: DATA/gt_mesh.ply)");
    cmd->add_option("--leaf-size-m", opt->leaf_size_m, "Level-0 cell size in metres");
    cmd->add_option("--regularization-weight", opt->regularization_weight,
                    "lambda_r of the regularised run (default: incremental.regularization_weight)");
    cmd->add_option("--iterations-per-frame", opt->iterations_per_frame,
                    "Optimisation steps per scan (default: incremental.iterations_per_frame)");
    cmd->add_option("--replay-frames", opt->replay_frames,
                    "Scans each scan's steps draw from, itself included (default 1, the paper's "
                    "setting, unless the config sets incremental.replay_frames)")
        ->check(CLI::Range(1, 100000));
    cmd->add_option("--threads", opt->threads, "Worker threads (0 = all cores)");
    cmd->add_option("--early-fraction", opt->early_fraction,
                    "Share of the frames whose points define the early region")
        ->capture_default_str();
    cmd->add_option("--region-voxel-m", opt->region_voxel_m, "Voxel size of the early region")
        ->capture_default_str();
    cmd->add_option("--panel-width", opt->panel_width, "Width of each picture panel, pixels")
        ->capture_default_str();
    cmd->add_flag("--batch", opt->with_batch, "Also map in batch mode, for reference");
    cmd->add_flag("-q,--quiet", opt->quiet, "No progress output");
    cmd->callback([opt, &action] { action = [opt] { return run_forgetting(*opt); }; });
});

}  // namespace
}  // namespace shine::cli
