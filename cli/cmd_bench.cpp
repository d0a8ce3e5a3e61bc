// `shine bench [DATA] -o OUT`: the memory/accuracy study -- ShineVDB (batch mode; with
// --modes batch,incremental incremental mode too) and the TSDF baseline on the same scans at
// several resolutions -> OUT/<method>_<size>/..., OUT/bench.csv, OUT/bench.json, OUT/bench.md,
// OUT/memory_vs_chamfer.png, a table with the ShineVDB/TSDF ratios and the study's checks; with
// --holdout-every, the held-out table (accuracy, wall time, memory per run).
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <system_error>

#include "bench_speed.hpp"
#include "cli_common.hpp"
#include "command_registry.hpp"
#include "shine/bench/bench_report.hpp"
#include "shine/bench/bench_runner.hpp"
#include "shine/bench/plot.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/scan_sequence.hpp"

namespace shine::cli {
namespace {
namespace fs = std::filesystem;

struct BenchOptions {
    std::string data;
    std::string out = "out-bench";
    std::string sizes_m = "0.1,0.2,0.5,1.0";
    std::string modes = "auto";  ///< auto: batch, or batch,incremental with --holdout-every
    std::string config_path;
    int threads = -1;
    int iterations = -1;
    long long seed = -1;
    int first_frame = 0, last_frame = -1, frame_step = 1;
    std::string poses_path;
    std::string ref_path;
    bool half_features = false;
    bool no_eval = false;
    bool quiet = false;
    int holdout_every = 0;  ///< > 0: every N-th scan is not mapped but scores both meshes
    bool speed = false;     ///< the speed study instead (bench_speed.hpp)
    int rounds = 3;
};

/// `shine bench --speed`: ShineVDB batch and incremental against the TSDF baseline, alternated.
int run_bench_speed(const BenchOptions& opt) {
    SpeedStudyOptions o;
    o.data = resolve_data_dir(opt.data, opt.quiet);
    // The sequence opens (and its pose file matches) before any run starts.
    ScanSequenceOptions seq_options;
    seq_options.first_frame = opt.first_frame;
    seq_options.last_frame = opt.last_frame;
    seq_options.frame_step = opt.frame_step;
    seq_options.poses_path = opt.poses_path;
    seq_options.poses = PoseFileUse::kIfPresent;  // without poses: the odometry's run alone
    const ScanSequence sequence = ScanSequence::open(o.data, seq_options);
    o.data_has_poses = sequence.has_poses();
    if (!opt.config_path.empty()) {
        MapperConfig check;
        load_config_yaml(opt.config_path, check);
        o.shine_args = "-c '" + opt.config_path + "'";
    }
    o.selection_args = "--first-frame " + std::to_string(opt.first_frame) + " --last-frame " +
                       std::to_string(opt.last_frame) + " --frame-step " +
                       std::to_string(opt.frame_step);
    if (!opt.poses_path.empty()) o.selection_args += " --poses '" + opt.poses_path + "'";
    o.out = opt.out;
    o.rounds = opt.rounds;
    o.threads = opt.threads >= 0 ? opt.threads : 2;
    o.quiet = opt.quiet;
    ensure_directory(o.out);
    const auto rows = run_speed_study(o);
    std::printf(
        "%s: %zu scans, %d rounds alternated, %d threads; TSDF %g m voxels (VDBFusion "
        "settings), ShineVDB %s\n%s",
        o.data.c_str(), sequence.size(), o.rounds, o.threads, o.tsdf_voxel_m,
        opt.config_path.empty() ? "defaults" : opt.config_path.c_str(),
        format_speed_table(rows).c_str());
    std::printf("wrote %s, %s\n", (o.out / "speed.md").c_str(), (o.out / "speed.json").c_str());
    return 0;
}

int run_bench(const BenchOptions& opt) {
    if (opt.speed) {
        if (opt.holdout_every > 0) {
            throw ConfigError("--holdout-every belongs to the accuracy study, not to --speed");
        }
        if (opt.modes != "auto") {
            throw ConfigError(
                "--modes belongs to the accuracy study; --speed always times the TSDF, ShineVDB "
                "batch and incremental");
        }
        return run_bench_speed(opt);
    }
    const auto start_total = std::chrono::steady_clock::now();
    Progress::set_globally_enabled(!opt.quiet);

    // Every option is checked before any scan is read or any file written.
    BenchConfig config;
    config.sizes_m = parse_sizes_m(opt.sizes_m);
    config.modes = parse_modes(opt.modes != "auto"     ? opt.modes
                               : opt.holdout_every > 0 ? "batch,incremental"
                                                       : "batch");
    if (!opt.config_path.empty()) load_config_yaml(opt.config_path, config.shine);
    if (opt.half_features) {
        // Through the configuration's own parser, so the key stays defined in one place.
        parse_config_yaml("map:\n  feature_precision: float16\n", "--half-features", config.shine);
    }
    if (opt.threads >= 0) config.shine.threads = opt.threads;
    if (opt.iterations >= 0) config.shine.iterations = opt.iterations;
    if (opt.seed >= 0) config.shine.seed = static_cast<std::uint64_t>(opt.seed);
    // Scored on held-out real scans against TSDF fusion as VDBFusion runs it: every point fused.
    if (opt.holdout_every > 0) config.tsdf.preprocess.voxel_downsample_m = 0.0;
    for (const double size_m : config.sizes_m) {
        shine_config_at(config, size_m);
        tsdf_config_at(config, size_m);
    }
    auto threads = limit_threads(config.shine.threads);

    const fs::path data = resolve_data_dir(opt.data, opt.quiet);
    ScanSequenceOptions seq_options;
    seq_options.first_frame = opt.first_frame;
    seq_options.last_frame = opt.last_frame;
    seq_options.frame_step = opt.frame_step;
    seq_options.poses_path = opt.poses_path;
    ScanSequence sequence = ScanSequence::open(data, seq_options);
    if (opt.holdout_every > 0) {
        config.heldout_frames = split_holdout(sequence, opt.holdout_every).heldout;
    }
    const fs::path ref = resolve_reference(data, opt.ref_path, opt.no_eval);
    std::unique_ptr<TriangleMesh> reference;
    if (!ref.empty()) reference = std::make_unique<TriangleMesh>(read_ply_mesh(ref));
    const fs::path out = opt.out;
    ensure_directory(out);

    const BenchScans scans(std::move(sequence), config.scan_cache_bytes);
    std::vector<BenchRow> rows;
    for (std::size_t k = 0; k < config.sizes_m.size(); ++k) {
        const double size_m = config.sizes_m[k];
        if (!opt.quiet) {
            std::fprintf(stderr, "== size %s m (%zu/%zu): ShineVDB leaf (%s), TSDF voxel %s m ==\n",
                         format_size_m(size_m).c_str(), k + 1, config.sizes_m.size(),
                         format_modes(config.modes).c_str(), format_size_m(size_m).c_str());
        }
        for (BenchRow& row : run_bench_size(config, size_m, scans, reference.get(), out)) {
            rows.push_back(row);
        }
    }

    BenchInfo info;
    info.data = data.string();
    info.reference = ref.string();
    info.config = opt.config_path;
    info.threads = config.shine.threads;
    info.iterations = config.shine.iterations;
    info.half_features = config.shine.octree.feature_precision == FeaturePrecision::kFloat16;
    info.trunc_voxels = config.trunc_voxels;
    info.holdout_every = opt.holdout_every;
    info.modes.clear();
    if (config.modes.batch) info.modes.push_back("batch");
    if (config.modes.incremental) info.modes.push_back("incremental");
    info.heldout_threshold_m = config.heldout.threshold_m;
    write_stream_atomically(out / "bench.csv", [&](std::ostream& os) { os << rows_to_csv(rows); });
    write_stream_atomically(out / "bench.json",
                            [&](std::ostream& os) { os << bench_to_json(rows, info); });
    write_stream_atomically(out / "bench.md",
                            [&](std::ostream& os) { os << bench_to_markdown(rows, info); });
    const fs::path plot = out / "memory_vs_chamfer.png";
    if (reference) {
        plot_memory_vs_chamfer(rows).write_png(plot);
    } else {
        std::error_code ignored;
        fs::remove(plot, ignored);  // a plot of an earlier run would not match these rows
    }

    std::printf("%s\n", format_rows_table(rows).c_str());
    std::printf("ShineVDB / TSDF per size (S = ShineVDB, T = TSDF):\n%s\n",
                format_ratios_table(compute_ratios(rows)).c_str());
    if (opt.holdout_every > 0) {
        std::printf(
            "held-out scans (%zu, 1 in %d, not mapped; their rays cast into each mesh; within "
            "%g cm; a miss is a failure; the TSDF fuses every point; seconds: wall time, scans in "
            "memory to mesh on disk):\n%s\n",
            config.heldout_frames.size(), opt.holdout_every, config.heldout.threshold_m * 100,
            format_heldout_table(rows).c_str());
    }
    if (reference) {
        std::printf("checks (against %s):\n%s\n", ref.c_str(),
                    format_checks(compute_checks(rows)).c_str());
    } else {
        std::printf("no reference mesh: accuracy columns, checks (b), (c) and the plot skipped\n");
        std::printf("%s\n", format_checks(compute_checks(rows)).c_str());
    }
    std::printf("wrote %s, %s, %s%s%s (%zu runs) in %.1f s\n", (out / "bench.csv").c_str(),
                (out / "bench.json").c_str(), (out / "bench.md").c_str(), reference ? ", " : "",
                reference ? plot.c_str() : "", rows.size(), seconds_since(start_total));
    return 0;
}

const RegisterCommand kRegisterBench(70, [](CLI::App& app, Action& action) {
    auto opt = std::make_shared<BenchOptions>();
    CLI::App* cmd = app.add_subcommand(
        "bench",
        "Memory/accuracy study: ShineVDB and the TSDF baseline on the same scans at several "
        "resolutions -> OUT/bench.csv, OUT/bench.json, OUT/bench.md, OUT/memory_vs_chamfer.png "
        "(see docs/benchmark.md)");
    cmd->add_option("data", opt->data,
                    "Sequence directory (KITTI layout or .ply/.pcd scans with poses); default: the "
                    "bundled example street, simulated on first use");
    cmd->add_option("-o,--output", opt->out, "Output directory")->capture_default_str();
    cmd->add_option("--sizes-m", opt->sizes_m,
                    "Resolutions in metres, comma-separated: ShineVDB leaf size and TSDF voxel "
                    "size (truncation 3 voxels)")
        ->capture_default_str();
    cmd->add_option("--modes", opt->modes,
                    "ShineVDB's modes, comma-separated: batch, incremental or batch,incremental. "
                    "Incremental mode runs as `shine map --mode incremental` (its schedule from "
                    "-c, not --iterations) -> OUT/shinevdb_incremental_<size>/. auto: batch, or "
                    "batch,incremental with --holdout-every")
        ->capture_default_str();
    cmd->add_option("-c,--config", opt->config_path,
                    "YAML configuration of ShineVDB (see examples/config.yaml); its leaf size is "
                    "replaced by each resolution, its preprocessing is used for both methods "
                    "(except the voxel thinning: the TSDF keeps its 0.05 m)");
    cmd->add_option("--threads", opt->threads, "Worker threads (0 = all cores)");
    cmd->add_option("--iterations", opt->iterations,
                    "ShineVDB optimisation steps per run (default: automatic per leaf size; a set "
                    "count takes 4096-sample steps, as `shine map --iterations`)");
    cmd->add_option("--seed", opt->seed, "Random seed of ShineVDB");
    cmd->add_flag(
        "--half-features", opt->half_features,
        "Store ShineVDB's features as float16 (the default; map.feature_precision: float16)");
    add_scan_selection_options(cmd, opt->first_frame, opt->last_frame, opt->frame_step,
                               opt->poses_path);
    add_evaluation_options(cmd, opt->ref_path, opt->no_eval);
    add_holdout_option(cmd, opt->holdout_every);
    cmd->add_flag("-q,--quiet", opt->quiet, "No progress output");
    cmd->add_flag("--speed", opt->speed,
                  "Speed study instead: the TSDF baseline at 0.1 m (VDBFusion settings), ShineVDB "
                  "batch and incremental (its configuration, 0.2 m by default), each its own "
                  "process, alternated over --rounds rounds -> OUT/speed.md, OUT/speed.json "
                  "(threads: --threads, default 2)");
    cmd->add_option("--rounds", opt->rounds, "Rounds of the speed study")
        ->check(CLI::Range(1, 100))
        ->capture_default_str();
    cmd->callback([opt, &action] { action = [opt] { return run_bench(*opt); }; });
});

}  // namespace
}  // namespace shine::cli
