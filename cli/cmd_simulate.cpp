// `shine simulate`: writes the example data set — a procedural street scanned by a simulated
// 64-beam spinning LiDAR — in the KITTI layout, with the reference mesh for evaluation; with
// --route-km, a long drive through a procedural city instead; with --pose-noise-m/-deg, the poses
// written with noise and the true ones beside them (for pose refinement); with --cameras, a front
// camera's image of the street's true colours per scan (for colour fusion).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include "cli_common.hpp"
#include "command_registry.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/io/kitti.hpp"
#include "shine/sim/camera_simulator.hpp"
#include "shine/sim/lidar_simulator.hpp"
#include "shine/sim/object_simulation.hpp"
#include "shine/sim/pose_noise.hpp"
#include "shine/sim/route_simulation.hpp"

namespace shine::cli {
namespace {

struct SimulateOptions {
    std::string out_dir;
    sim::SimulationConfig config;
    std::vector<double> origin_offset_m;  ///< E,N,U (x, y, z) added to every pose
    int threads = 0;
    double route_km = 0.0;             ///< > 0: the city route instead of the street
    bool route_requested = false;      ///< --route-km was given
    bool frames_given = false;         ///< --frames was given
    bool frame_spacing_given = false;  ///< --frame-spacing-m was given
    std::string scene = "street";      ///< street | object
    bool max_range_given = false;      ///< --max-range-m was given
    bool max_edge_given = false;       ///< --max-edge-m was given
    sim::PoseNoiseConfig pose_noise;   ///< --pose-noise-m/-deg; its seed is --seed
    bool cameras = false;              ///< --cameras: a front camera's images beside the scans
};

/// `--scene object`: the turntable scan (object_simulation.hpp) with this run's seed, noise and
/// the street options that make sense for it.
int run_object(const SimulateOptions& options) {
    if (options.route_requested || options.frames_given || options.frame_spacing_given ||
        !options.origin_offset_m.empty()) {
        throw ConfigError(
            "--scene object scans a turntable (24 scans on two rings): --route-km, --frames, "
            "--frame-spacing-m and --origin-offset-m belong to the street");
    }
    const auto& street = options.config;
    sim::ObjectSimulationConfig config;
    config.seed = street.seed;
    config.lidar.range_noise_sigma_m = street.lidar.range_noise_sigma_m;
    if (options.max_range_given) config.lidar.max_range_m = street.lidar.max_range_m;
    if (options.max_edge_given) config.scene.max_edge_length_m = street.scene.max_edge_length_m;
    config.show_progress = street.show_progress;
    const sim::SimulationSummary summary = sim::simulate_object_sequence(config, options.out_dir);
    std::printf(
        "wrote %s: %d scans of an object on a turntable (%zu points, %zu..%zu per scan), "
        "poses.txt, gt_mesh.ply (%zu triangles, %zu observed), simulation.json, README.txt in "
        "%.1f s\n",
        options.out_dir.c_str(), summary.num_frames, summary.total_points,
        summary.min_points_per_scan, summary.max_points_per_scan, summary.num_triangles,
        summary.num_observed_triangles, summary.seconds);
    return 0;
}

/// Longest --route-km: ~5x KITTI 00; the city's scene needs ~0.55 GB of memory per km.
constexpr double kMaxRouteKm = 20.0;

std::string format_number(double value) {
    char buffer[64];
    std::snprintf(buffer, sizeof(buffer), "%g", value);
    return buffer;
}

int run_route(const SimulateOptions& options, const sim::SimulationConfig& street) {
    if (!(options.route_km > 0.0)) {
        throw ConfigError("--route-km = " + format_number(options.route_km) +
                          " must be > 0 (the length of the drive in km, e.g. 4 for a "
                          "KITTI-00-like drive)");
    }
    if (!(options.route_km <= kMaxRouteKm)) {
        throw ConfigError("--route-km = " + format_number(options.route_km) + " is more than " +
                          format_number(kMaxRouteKm) +
                          " km: the city's scene needs ~0.55 GB of memory per km (2.1 GB for 4 "
                          "km); simulate several shorter routes (--seed) instead");
    }
    if (options.frames_given) {
        throw ConfigError(
            "--frames cannot be combined with --route-km: the route's length and "
            "--frame-spacing-m set the number of scans");
    }
    sim::RouteSimulationConfig config;
    config.seed = street.seed;
    config.city.route_length_m = options.route_km * 1000.0;
    config.city.street.max_edge_length_m = street.scene.max_edge_length_m;
    if (options.frame_spacing_given) {
        config.trajectory.frame_spacing_m = street.trajectory.frame_spacing_m;
    }
    config.lidar = street.lidar;
    config.movers = street.movers;
    config.origin_offset_world_m = street.origin_offset_world_m;
    config.show_progress = street.show_progress;
    const sim::RouteSimulationSummary result =
        sim::simulate_route_sequence(config, options.out_dir);
    const sim::SimulationSummary& summary = result.sequence;
    std::printf(
        "wrote %s: a %.3f km drive through a city of %zu street blocks and %zu junctions "
        "(loop %.3f km, then %.0f m again through the first street)%s: %d scans (%zu points, "
        "%zu..%zu per scan), poses.txt, gt_mesh.ply (%zu triangles, %zu observed), "
        "simulation.json, README.txt in %.1f s (city %.1f s, ray-cast index %.1f s)\n",
        options.out_dir.c_str(), result.route_length_m / 1000.0, result.num_streets,
        result.num_junctions, result.loop_length_m / 1000.0,
        result.route_length_m - result.loop_length_m,
        result.num_movers > 0
            ? (" with " + std::to_string(result.num_movers) + " movers (simulation.json)").c_str()
            : "",
        summary.num_frames, summary.total_points, summary.min_points_per_scan,
        summary.max_points_per_scan, summary.num_triangles, summary.num_observed_triangles,
        summary.seconds, result.scene_seconds, result.index_seconds);
    return 0;
}

/// The pose file of a simulated sequence (its true twin when the poses carry noise:
/// kTruePosesFile, cli_common.hpp).
constexpr const char* kPosesFile = "poses.txt";

/// The bytes of a file the simulation wrote; IoError naming it if it cannot be read.
std::string read_file(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw IoError("cannot read " + path.string() + " that the simulation just wrote");
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
}

/// A number for simulation.json with 10 significant digits (as the simulator writes them).
std::string json_number(double value) {
    char buffer[64];
    std::snprintf(buffer, sizeof(buffer), "%.10g", value);
    return buffer;
}

/// --cameras: the front camera's images of the street (sim/camera_simulator.hpp) and a README.txt
/// entry.
void write_cameras(const std::filesystem::path& out_dir, const sim::SimulationConfig& config) {
    const sim::CameraConfig camera;
    const sim::CameraSequenceSummary summary =
        sim::simulate_street_cameras(config, camera, out_dir);
    const std::filesystem::path readme_path = out_dir / "README.txt";
    const std::string readme = read_file(readme_path);
    write_stream_atomically(readme_path, [&](std::ostream& out) {
        out << readme << "cameras/front/       camera.yaml: a " << camera.width << " x "
            << camera.height << " pinhole (fx " << camera.fx << ", fy " << camera.fy
            << ", no distortion) and T_lidar_camera;\n"
            << "                     NNNNNN.png: scan NNNNNN's image of the scene's true "
               "colours (albedo,\n"
            << "                     sim/scene_albedo.hpp) from the scan's pose, movers where "
               "they are at its start\n";
    });
    std::printf(
        "cameras/front: camera.yaml and %d images of %d x %d pixels of the street's true colours, "
        "one per scan (NNNNNN.png), in %.1f s\n",
        summary.num_images, camera.width, camera.height, summary.seconds);
}

/// Rejects a negative or non-finite --pose-noise-m / --pose-noise-deg before anything is simulated.
void check_pose_noise_flag(double value, const char* flag, const char* what) {
    if (!(std::isfinite(value) && value >= 0.0)) {
        throw ConfigError(std::string(flag) + " = " + format_number(value) +
                          " must be a finite number >= 0: the standard deviation of each axis of "
                          "the noise added to the written poses' " +
                          what + " (0, the default, for none)");
    }
}

/// --pose-noise-m/-deg: the scans are measured from the true poses as always; afterwards the true
/// poses.txt is kept as poses_true.txt (byte for byte) and poses.txt is rewritten with every pose
/// perturbed (sim/pose_noise.hpp); simulation.json gains "pose_noise" and README.txt a line.
/// Without noise nothing is rewritten, and a poses_true.txt left by an earlier noisy run in the
/// same directory is removed, so that it cannot be taken for the truth of these poses.
void write_pose_noise(const std::filesystem::path& out_dir, const sim::PoseNoiseConfig& noise) {
    namespace fs = std::filesystem;
    const fs::path poses_path = out_dir / kPosesFile;
    const fs::path true_path = out_dir / kTruePosesFile;
    if (!sim::has_pose_noise(noise)) {
        std::error_code ec;
        if (!fs::remove(true_path, ec) && ec) {
            throw IoError("cannot remove " + true_path.string() + " left by an earlier run: " +
                          ec.message() + "; delete it or choose another output directory");
        }
        return;
    }
    const std::string true_text = read_file(poses_path);
    const std::vector<Eigen::Isometry3d> truth = parse_kitti_poses(true_text, poses_path);
    write_stream_atomically(true_path, [&](std::ostream& out) { out << true_text; });
    write_kitti_poses(poses_path, sim::add_pose_noise(truth, noise));

    // simulation.json ends with the root object's closing brace: the record goes before it.
    const fs::path json_path = out_dir / "simulation.json";
    std::string json = read_file(json_path);
    const std::size_t root_end = json.find_last_of('}');
    const std::size_t last_value =
        root_end == std::string::npos ? root_end : json.find_last_not_of(" \n", root_end - 1);
    if (last_value == std::string::npos) {
        throw IoError(json_path.string() + " does not end with a JSON object");
    }
    json =
        json.substr(0, last_value + 1) +
        ",\n  \"pose_noise\": {\"translation_sigma_m\": " + json_number(noise.translation_sigma_m) +
        ", \"rotation_sigma_deg\": " + json_number(noise.rotation_sigma_deg) +
        ", \"seed\": " + std::to_string(noise.seed) +
        ",\n                 \"model\": \"R = exp(dphi) R_true, t = t_true + dt; dt [m] and dphi "
        "[rad] independent Gaussians per axis, per scan, every scan (the first too)\",\n"
        "                 \"poses\": \"poses.txt, the true poses with this noise\", "
        "\"true_poses\": \"poses_true.txt, the poses the scans were measured from\"}\n}\n";
    if (!nlohmann::json::accept(json)) {
        throw IoError("the pose noise record made " + json_path.string() +
                      " invalid JSON (an internal error: please report it)");
    }
    write_stream_atomically(json_path, [&](std::ostream& out) { out << json; });

    const fs::path readme_path = out_dir / "README.txt";
    const std::string readme = read_file(readme_path);
    write_stream_atomically(readme_path, [&](std::ostream& out) {
        out << readme
            << "poses_true.txt       the true T_world_sensor the scans were measured from; "
               "poses.txt holds\n"
            << "                     them with noise: Gaussians of " << noise.translation_sigma_m
            << " m and " << noise.rotation_sigma_deg << " deg per axis, each\n"
            << "                     scan its own (seed " << noise.seed
            << ", simulation.json \"pose_noise\")\n";
    });
    std::printf(
        "poses.txt: the true poses with noise of %s m and %s deg per axis (seed %llu); the true "
        "poses in poses_true.txt\n",
        format_number(noise.translation_sigma_m).c_str(),
        format_number(noise.rotation_sigma_deg).c_str(),
        static_cast<unsigned long long>(noise.seed));
}

int simulate_scans(const SimulateOptions& options) {
    const auto& c = options.config;
    if (!options.route_requested && c.num_frames < 1) {
        throw ConfigError("--frames = " + std::to_string(c.num_frames) + " must be >= 1");
    }
    if (!(c.lidar.range_noise_sigma_m >= 0.0)) {
        throw ConfigError("--noise-m = " + std::to_string(c.lidar.range_noise_sigma_m) +
                          " must be >= 0 (0 for noise-free ranges)");
    }
    sim::SimulationConfig config = c;
    if (!options.origin_offset_m.empty()) {
        if (options.origin_offset_m.size() != 3) {
            throw ConfigError(
                "--origin-offset-m takes three numbers E,N,U (x,y,z in metres), got " +
                std::to_string(options.origin_offset_m.size()));
        }
        config.origin_offset_world_m = Eigen::Vector3d(
            options.origin_offset_m[0], options.origin_offset_m[1], options.origin_offset_m[2]);
    }
    const auto thread_limit = limit_threads(options.threads);
    if (c.motion_distortion && (options.scene == "object" || options.route_requested)) {
        throw ConfigError(
            "--motion-distortion moves the sensor during each sweep of the street's drive: it "
            "cannot be combined with --scene object or --route-km");
    }
    if (options.cameras && (options.scene == "object" || options.route_requested)) {
        throw ConfigError(
            "--cameras renders the street's scans (a front camera per scan): it cannot be "
            "combined with --scene object or --route-km yet; simulate the street without them");
    }
    if (c.movers.num_movers > 0 && options.scene == "object") {
        throw ConfigError(
            "--movers puts cars, cyclists and pedestrians on the street: it cannot "
            "be combined with --scene object");
    }
    if (options.scene == "object") return run_object(options);
    if (options.max_edge_given && !(c.scene.max_edge_length_m >= 0.02)) {
        throw ConfigError("--max-edge-m = " + format_number(c.scene.max_edge_length_m) +
                          " is below 0.02 m: the street would need billions of triangles (finer "
                          "edges are for --scene object)");
    }
    if (options.route_requested) return run_route(options, config);
    const sim::SimulationSummary summary = sim::simulate_sequence(config, options.out_dir);
    const std::string movers =
        c.movers.num_movers > 0
            ? " with " + std::to_string(c.movers.num_movers) + " movers (simulation.json)"
            : "";
    const std::string distortion =
        c.motion_distortion
            ? ", distorted by the sensor's motion during each sweep (" +
                  format_number(c.trajectory.frame_spacing_m / c.movers.frame_period_s) +
                  " m/s), in scans/NNNNNN.ply with per-point times t"
            : "";
    std::printf(
        "wrote %s: %d scans%s%s (%zu points, %zu..%zu per scan), poses.txt, gt_mesh.ply "
        "(%zu triangles, %zu observed), simulation.json, README.txt in %.1f s\n",
        options.out_dir.c_str(), summary.num_frames, movers.c_str(), distortion.c_str(),
        summary.total_points, summary.min_points_per_scan, summary.max_points_per_scan,
        summary.num_triangles, summary.num_observed_triangles, summary.seconds);
    if (options.cameras) write_cameras(options.out_dir, config);
    return 0;
}

int run_simulate(const SimulateOptions& options) {
    check_pose_noise_flag(options.pose_noise.translation_sigma_m, "--pose-noise-m", "positions, m");
    check_pose_noise_flag(options.pose_noise.rotation_sigma_deg, "--pose-noise-deg",
                          "rotations, deg");
    // Without --cameras, images an earlier run with --cameras left in the directory would be
    // taken for this run's: they go.
    if (!options.cameras && sim::remove_street_cameras(options.out_dir)) {
        std::printf("removed %s, left by an earlier run with --cameras\n",
                    sim::front_camera_dir(options.out_dir).c_str());
    }
    const int exit_code = simulate_scans(options);
    sim::PoseNoiseConfig noise = options.pose_noise;
    noise.seed = options.config.seed;
    write_pose_noise(options.out_dir, noise);
    return exit_code;
}

const RegisterCommand kSimulateCommand(10, [](CLI::App& app, Action& action) {
    auto options = std::make_shared<SimulateOptions>();
    auto& c = options->config;
    CLI::App* cmd = app.add_subcommand(
        "simulate",
        "Simulate the example data: a procedural street scanned by a 64-beam spinning LiDAR on a "
        "driving car. Writes DIR/velodyne/NNNNNN.bin (sensor frame), DIR/poses.txt "
        "(T_world_sensor), DIR/gt_mesh.ply (reference, observed faces marked), "
        "DIR/simulation.json. With --route-km: a long drive through a procedural city that ends "
        "by driving its first street again (a loop closure). With --cameras: a front camera's "
        "image of the true colours per scan, DIR/cameras/front/NNNNNN.png and camera.yaml.");
    cmd->add_option("-o,--output", options->out_dir, "output directory (created if missing)")
        ->required();
    cmd->add_option("--scene", options->scene,
                    "street (the default), or object: a shoebox-sized object on a turntable "
                    "scanned 24 times from 1 m by a dense 30 x 20 deg scanner (~1.6 mm between "
                    "rays); map it with --leaf-size-m 0.003")
        ->check(CLI::IsMember({"street", "object"}))
        ->capture_default_str();
    CLI::Option* frames = cmd->add_option("--frames", c.num_frames, "number of scans (>= 1)")
                              ->check(CLI::Range(1, 100000))
                              ->capture_default_str();
    cmd->add_option("--seed", c.seed, "seed of the street layout, trajectory and noise")
        ->capture_default_str();
    cmd->add_option("--noise-m", c.lidar.range_noise_sigma_m,
                    "standard deviation of Gaussian range noise, m (>= 0)")
        ->check(CLI::Range(0.0, 10.0))
        ->capture_default_str();
    cmd->add_option("--lane-offset-m", c.trajectory.lane_offset_m,
                    "drive this far left (+) or right (-) of the street's centre line, m: a "
                    "second drive in another lane")
        ->capture_default_str();
    CLI::Option* frame_spacing =
        cmd->add_option("--frame-spacing-m,--scan-spacing-m", c.trajectory.frame_spacing_m,
                        "distance driven between scans, m (1.6 with --route-km)")
            ->check(CLI::Range(0.01, 100.0))
            ->capture_default_str();
    CLI::Option* route = cmd->add_option(
        "--route-km", options->route_km,
        "instead of the street: drive this many km (<= 20) through a procedural city of varied "
        "streets, ending with a loop back through the first street; 4 is like KITTI 00 (2501 "
        "scans 1.6 m apart)");
    CLI::Option* max_range =
        cmd->add_option("--max-range-m", c.lidar.max_range_m, "maximum LiDAR range, m")
            ->check(CLI::Range(2.0, 1000.0))
            ->capture_default_str();
    CLI::Option* max_edge =
        cmd->add_option("--max-edge-m", c.scene.max_edge_length_m,
                        "longest triangle edge of the reference mesh, m (street >= 0.02; object: "
                        "default 0.002)")
            ->check(CLI::Range(0.0002, 10.0))
            ->capture_default_str();
    cmd->add_option("--origin-offset-m", options->origin_offset_m,
                    "E,N,U: move the drive to these world coordinates, m (e.g. "
                    "500000,5000000,0 for UTM-like poses); poses.txt includes it, gt_mesh.ply "
                    "keeps small vertex coordinates and names the offset in its header")
        ->delimiter(',')
        ->expected(3);
    cmd->add_option("--movers", c.movers.num_movers,
                    "put N moving objects on the street: cars in the lanes (overtaking, "
                    "oncoming, one parked then leaving), cyclists and pedestrians on the "
                    "sidewalks; each ray sees them at its own time (scan k at k * 0.1 s, 0.1 s "
                    "sweep); gt_mesh.ply stays static, simulation.json lists their paths "
                    "(docs/movers.md). With --route-km: N movers per 100 m of straight drive, "
                    "each present while the sensor passes")
        ->check(CLI::Range(0, 1000))
        ->capture_default_str();
    cmd->add_flag("--motion-distortion", c.motion_distortion,
                  "the sensor keeps moving during each 0.1 s sweep (speed = --frame-spacing-m "
                  "per 0.1 s: 10 m/s by default): each ray leaves from the pose along the drive "
                  "at its own time; the scans, whose points carry that time, are written as "
                  "scans/NNNNNN.ply (float x y z t, t in s after the scan's pose) instead of "
                  "velodyne/*.bin (docs/odometry.md)");
    cmd->add_option("--pose-noise-m", options->pose_noise.translation_sigma_m,
                    "write poses.txt with noise for pose refinement: each scan's position moved "
                    "by a Gaussian of this standard deviation per axis, m; the scans are measured "
                    "from the true poses, written to poses_true.txt (docs/odometry.md)")
        ->capture_default_str();
    cmd->add_option("--pose-noise-deg", options->pose_noise.rotation_sigma_deg,
                    "the same for the rotations: each scan turned by exp of a rotation vector "
                    "whose axes are Gaussians of this standard deviation, deg (world axes, about "
                    "the sensor's position)")
        ->capture_default_str();
    cmd->add_flag("--cameras", options->cameras,
                  "also write a front camera's image of the street's true colours per scan: "
                  "cameras/front/camera.yaml (640 x 240 pinhole 0.27 m ahead of and 0.08 m below "
                  "the LiDAR, looking along its +x) and cameras/front/NNNNNN.png, the stem of "
                  "each scan's file; movers are seen where they are at the scan's start "
                  "(docs/simulated_cameras.md)");
    cmd->add_option("--threads", options->threads, "worker threads (0 = all cores)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    cmd->add_flag(
        "--no-progress", [options](std::int64_t) { options->config.show_progress = false; },
        "do not draw the progress line");
    cmd->callback([options, &action, frames, frame_spacing, route, max_range, max_edge] {
        options->max_range_given = max_range->count() > 0;
        options->max_edge_given = max_edge->count() > 0;
        options->frames_given = frames->count() > 0;
        options->frame_spacing_given = frame_spacing->count() > 0;
        options->route_requested = route->count() > 0;
        action = [options] { return run_simulate(*options); };
    });
});

}  // namespace
}  // namespace shine::cli
