#include "cli_common.hpp"

#include <sys/resource.h>

#include <cstdio>
#include <cstdlib>
#include <optional>
#include <thread>

#include "shine/core/error.hpp"
#include "shine/eval/heldout_ranges.hpp"
#include "shine/io/ply.hpp"
#include "shine/mapper/sequence_deskew.hpp"
#include "shine/mapper/sweep_test.hpp"
#include "shine/sim/lidar_simulator.hpp"

namespace shine::cli {

std::unique_ptr<tbb::global_control> limit_threads(int threads) {
    const int n =
        threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, n);
}

std::size_t peak_rss_bytes() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return static_cast<std::size_t>(usage.ru_maxrss) * 1024;  // Linux reports KiB
}

std::filesystem::path bundled_example_dir() {
    if (const char* env = std::getenv("SHINE_EXAMPLE_DIR")) return env;
    return std::filesystem::path(SHINE_SOURCE_DIR) / "examples" / "street";
}

std::filesystem::path resolve_data_dir(const std::string& data, bool quiet) {
    if (!data.empty()) return data;
    const std::filesystem::path dir = bundled_example_dir();
    if (!std::filesystem::exists(dir / "poses.txt")) {
        std::fprintf(stderr, "shine: simulating the bundled example street into %s\n", dir.c_str());
        sim::SimulationConfig sim_config;
        sim_config.show_progress = !quiet;
        sim::simulate_sequence(sim_config, dir);
    }
    return dir;
}

std::filesystem::path resolve_reference(const std::filesystem::path& data,
                                        const std::string& ref_path, bool no_eval) {
    std::filesystem::path ref = ref_path;
    if (ref.empty() && !no_eval && std::filesystem::exists(data / "gt_mesh.ply")) {
        ref = data / "gt_mesh.ply";
    }
    if (!ref.empty() && !std::filesystem::is_regular_file(ref)) {
        throw IoError("reference mesh '" + ref.string() + "' does not exist");
    }
    return ref;
}

void add_scan_selection_options(CLI::App* cmd, int& first_frame, int& last_frame, int& frame_step,
                                std::string& poses_path) {
    cmd->add_option("--first-frame", first_frame, "First scan (recordings: message) index")
        ->capture_default_str();
    cmd->add_option("--last-frame", last_frame, "Last scan index, -1 = all")->capture_default_str();
    cmd->add_option("--frame-step", frame_step, "Use every n-th scan")->capture_default_str();
    cmd->add_option("--poses", poses_path,
                    "Pose file (default: found in DATA); for a recording a TUM trajectory matched "
                    "to the scans by time");
}

void add_topic_option(CLI::App* cmd, std::string& topic) {
    cmd->add_option(
        "--topic", topic,
        "Recordings: the sensor_msgs/PointCloud2 topic to read (default: the only one)");
}

void add_evaluation_options(CLI::App* cmd, std::string& ref_path, bool& no_eval) {
    cmd->add_option("--ref", ref_path,
                    "Reference mesh to evaluate against (default: DATA/gt_mesh.ply if present)");
    cmd->add_flag("--no-eval", no_eval, "Skip the evaluation");
}

void add_holdout_option(CLI::App* cmd, int& holdout_every) {
    cmd->add_option("--holdout-every", holdout_every,
                    "Map without every N-th selected scan (N-1, 2N-1, ...) and score the mesh on "
                    "those: their rays cast into it, range errors (stats.json \"heldout\")")
        ->check(CLI::Range(2, 1000000));
}

HoldoutSplit split_holdout(const ScanSequence& selected, int every) {
    HoldoutSplit split;
    if (every != 0) split.heldout = holdout_frames(selected.size(), every);
    for (std::size_t i = 0, h = 0; i < selected.size(); ++i) {
        if (h < split.heldout.size() && split.heldout[h] == i) {
            ++h;
        } else {
            split.mapped.push_back(i);
        }
    }
    if (every != 0 && split.heldout.empty()) {
        throw ConfigError("--holdout-every " + std::to_string(every) +
                          " holds out no scan of the " + std::to_string(selected.size()) +
                          " selected: use a smaller N");
    }
    return split;
}

void score_heldout(const std::filesystem::path& mesh_path, const ScanSequence& selected,
                   const HoldoutSplit& split, int every, const PreprocessConfig& preprocess,
                   nlohmann::json& json, const std::string& key, const DeskewConfig* deskew,
                   const TriangleMesh* mesh) {
    if (split.heldout.empty()) return;
    const auto start = std::chrono::steady_clock::now();
    HeldoutConfig config;
    config.min_range_m = preprocess.min_range_m;
    config.max_range_m = preprocess.max_range_m;
    DeskewStats deskew_stats;
    ScanPreparation prepare;
    if (deskew) {
        prepare = [&](std::size_t frame, Scan& scan) {
            deskew_with_sequence_poses(scan, selected, frame, *deskew, deskew_stats);
        };
    }
    std::optional<TriangleMesh> read;
    if (!mesh) mesh = &read.emplace(read_ply_mesh(mesh_path));
    const HeldoutReport report = evaluate_heldout(*mesh, selected, split.heldout, config, prepare);
    json[key] = nlohmann::json::parse(heldout_to_json(report));
    json[key]["every"] = every;
    json[key]["scans_deskewed"] = deskew_stats.scans_deskewed;
    json["seconds"][key] = seconds_since(start);
    std::printf("%s", format_heldout(report).c_str());
}

std::vector<Eigen::Isometry3d> heldout_poses_local_to_estimate(
    const ScanSequence& selected, const HoldoutSplit& split,
    const std::vector<Eigen::Isometry3d>& mapped_world_sensor) {
    if (mapped_world_sensor.size() != split.mapped.size()) {
        throw DataError(std::to_string(mapped_world_sensor.size()) + " estimated poses for " +
                        std::to_string(split.mapped.size()) + " mapped scans");
    }
    std::vector<Eigen::Isometry3d> poses(selected.size(), Eigen::Isometry3d::Identity());
    std::size_t m = 0;  // the last mapped scan so far, as an index into split.mapped
    bool any_mapped = false;
    for (std::size_t i = 0; i < selected.size(); ++i) {
        if (m < split.mapped.size() && split.mapped[m] == i) {
            poses[i] = mapped_world_sensor[m];
            any_mapped = true;
            ++m;
            continue;
        }
        if (!any_mapped) {
            throw DataError("held-out scan " + std::to_string(i) +
                            " comes before every mapped scan: nothing to place it from");
        }
        const std::size_t a = m - 1;
        poses[i] =
            mapped_world_sensor[a] * selected.pose(split.mapped[a]).inverse() * selected.pose(i);
    }
    return poses;
}

ScanSequence with_sweep_times_if_skewed(const ScanSequence& selected, const DeskewConfig& config,
                                        bool quiet) {
    SweepTestResult test;
    ScanSequence result = sequence_with_sweep_times(selected, config, &test);
    if (!quiet && test.tested) {
        std::printf(
            "sweep test (%.1f s): %s: %s\n", test.seconds, test.reason.c_str(),
            result.has_sweep_times()
                ? ("deskewing, times from the azimuth: " + result.sweep_times().describe()).c_str()
                : "scans left as measured");
    } else if (!quiet && result.has_sweep_times()) {
        std::printf("scans without times timed from the azimuth: %s\n",
                    result.sweep_times().describe().c_str());
    }
    return result;
}

}  // namespace shine::cli
