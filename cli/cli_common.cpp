#include "cli_common.hpp"

#include <sys/resource.h>

#include <cstdio>
#include <cstdlib>
#include <thread>

#include "shine/core/error.hpp"
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

}  // namespace shine::cli
