// `shine pretrain -o decoder.yaml`: the decoder incremental mode loads frozen. Simulates streets
// of other seeds than the bundled one (sim module), maps them jointly in batch mode (features and
// decoder trained together, each street shifted sideways so they do not overlap) and writes the
// decoder weights with the command that made them (docs/incremental.md).
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "command_registry.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/batch_mapper.hpp"
#include "shine/mapper/map_sequence.hpp"
#include "shine/model/decoder_file.hpp"
#include "shine/sim/lidar_simulator.hpp"

namespace shine::cli {
namespace {
namespace fs = std::filesystem;

/// Streets are placed this far apart along y; each is < 100 m wide with the LiDAR's reach, and
/// the map frame keeps float precision far beyond this.
constexpr double kStreetSpacingM = 500.0;

struct PretrainOptions {
    std::string out;
    std::string config_path;
    std::vector<std::uint64_t> seeds = {101, 102, 103};
    int frames = 20;
    int iterations = -1;
    double leaf_size_m = 0.0;
    int threads = 0;
    std::string work_dir;
    bool quiet = false;
};

std::string command_line(const PretrainOptions& opt, const MapperConfig& config) {
    std::ostringstream s;
    s << "shine pretrain -o " << fs::path(opt.out).filename().string() << " --seeds ";
    for (std::size_t i = 0; i < opt.seeds.size(); ++i) s << (i ? "," : "") << opt.seeds[i];
    s << " --frames " << opt.frames << " --iterations " << config.batch_iterations()
      << " --leaf-size-m " << config.octree.leaf_size_m;
    if (!opt.config_path.empty()) s << " -c " << opt.config_path;
    s << " (batch mode on simulated streets of these seeds, " << opt.frames
      << " frames each, mapped jointly; seed " << config.seed << "; " << config.threads
      << " threads requested)";
    return s.str();
}

int run_pretrain(const PretrainOptions& opt) {
    const auto start = std::chrono::steady_clock::now();
    Progress::set_globally_enabled(!opt.quiet);
    if (opt.seeds.empty()) throw ConfigError("--seeds needs at least one seed");
    if (opt.frames < 1) throw ConfigError("--frames must be at least 1");
    MapperConfig config;
    if (!opt.config_path.empty()) load_config_yaml(opt.config_path, config);
    if (opt.leaf_size_m != 0.0) {
        if (!(opt.leaf_size_m > 0.0)) throw ConfigError("--leaf-size-m must be positive");
        config.octree.leaf_size_m = opt.leaf_size_m;
    }
    if (opt.iterations >= 0) config.iterations = opt.iterations;
    config.threads = opt.threads;
    config.trainer.train_decoder = true;
    config.finalize();
    auto threads = limit_threads(config.threads);

    const fs::path work =
        opt.work_dir.empty()
            ? fs::temp_directory_path() / ("shine_pretrain_" + std::to_string(::getpid()))
            : fs::path(opt.work_dir);
    ensure_directory(work);
    BatchMapper mapper(config);
    for (std::size_t i = 0; i < opt.seeds.size(); ++i) {
        const fs::path street = work / ("street_" + std::to_string(opt.seeds[i]));
        if (!fs::exists(street / "poses.txt")) {
            sim::SimulationConfig sim_config;
            sim_config.seed = opt.seeds[i];
            sim_config.num_frames = opt.frames;
            sim_config.show_progress = !opt.quiet;
            sim::simulate_sequence(sim_config, street);
        }
        const ScanSequence sequence = ScanSequence::open(street);
        Progress progress("load " + std::to_string(opt.seeds[i]), sequence.size());
        for (std::size_t f = 0; f < sequence.size(); ++f) {
            Scan scan = sequence.load(f);
            scan.T_world_sensor.translation().y() += kStreetSpacingM * static_cast<double>(i);
            mapper.add_scan(scan);
            progress.update(f + 1);
        }
        progress.finish(std::to_string(mapper.stats().rays) + " rays in all");
    }
    mapper.finish_scans();
    train_with_progress(mapper, mapper.planned_iterations());
    const std::string provenance = command_line(opt, config);
    save_decoder(opt.out, mapper.sdf().decoder, provenance);
    if (opt.work_dir.empty()) fs::remove_all(work);
    std::printf("wrote %s (%zu weights, final bce %.4f) in %.1f s\n  %s\n", opt.out.c_str(),
                mapper.sdf().decoder.num_params(), mapper.stats().final_bce, seconds_since(start),
                provenance.c_str());
    return 0;
}

const RegisterCommand kRegisterPretrain(25, [](CLI::App& app, Action& action) {
    auto opt = std::make_shared<PretrainOptions>();
    CLI::App* cmd = app.add_subcommand(
        "pretrain",
        "Pretrain the decoder for incremental mode: simulate streets of the given seeds, map "
        "them jointly in batch mode, write the decoder weights (YAML) to OUT");
    cmd->add_option("-o,--output", opt->out, "Decoder weights file to write")->required();
    cmd->add_option("-c,--config", opt->config_path,
                    "YAML configuration (map, decoder, sampling, training sections apply)");
    cmd->add_option("--seeds", opt->seeds,
                    "Street seeds to simulate (keep them apart from the evaluation scenes)")
        ->delimiter(',')
        ->capture_default_str();
    cmd->add_option("--frames", opt->frames, "Scans per street")->capture_default_str();
    cmd->add_option("--iterations", opt->iterations,
                    "Optimisation steps (default: training.iterations)");
    cmd->add_option("--leaf-size-m", opt->leaf_size_m, "Level-0 cell size in metres");
    cmd->add_option("--threads", opt->threads, "Worker threads (0 = all cores)")
        ->capture_default_str();
    cmd->add_option("--work-dir", opt->work_dir,
                    "Where the simulated streets go (kept; default: a temporary directory)");
    cmd->add_flag("-q,--quiet", opt->quiet, "No progress output");
    cmd->callback([opt, &action] { action = [opt] { return run_pretrain(*opt); }; });
});

}  // namespace
}  // namespace shine::cli
