#include "shine/sim/object_simulation.hpp"

#include <chrono>
#include <cmath>
#include <sstream>
#include <string>

#include "sequence_files.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/geometry/ray_caster.hpp"
#include "shine/io/ply.hpp"
#include "sim_random.hpp"

namespace shine::sim {
namespace object_simulation_internal {

using random_internal::derive_seed;
using sequence_internal::json_number;

/// Independent random streams (the scene uses the seed itself).
enum Stream : std::uint64_t { kNoise = 0x300 };

constexpr double kDegToRad = M_PI / 180.0;

}  // namespace object_simulation_internal

using namespace object_simulation_internal;

void validate(const TurntableConfig& c) {
    if (c.scans_per_ring < 1 || c.scans_per_ring > 10000) {
        throw ConfigError("turntable: scans_per_ring = " + std::to_string(c.scans_per_ring) +
                          " must be in [1, 10000]");
    }
    if (c.ring_heights_m.empty()) {
        throw ConfigError("turntable: ring_heights_m is empty; give at least one sensor height");
    }
    for (const double h : c.ring_heights_m) {
        if (!(h > 0.0 && h <= 100.0)) {
            throw ConfigError("turntable: ring height " + std::to_string(h) +
                              " m must be in (0, 100] (above the plate)");
        }
    }
    if (!(c.distance_m > 0.0 && c.distance_m <= 100.0)) {
        throw ConfigError("turntable: distance_m = " + std::to_string(c.distance_m) +
                          " must be in (0, 100]");
    }
    if (!std::isfinite(c.aim_height_m) || !std::isfinite(c.ring_phase_deg)) {
        throw ConfigError("turntable: aim_height_m and ring_phase_deg must be finite");
    }
}

std::vector<Eigen::Isometry3d> make_turntable_poses(const TurntableConfig& c) {
    validate(c);
    std::vector<Eigen::Isometry3d> poses;
    const Eigen::Vector3d aim(0.0, 0.0, c.aim_height_m);
    for (std::size_t ring = 0; ring < c.ring_heights_m.size(); ++ring) {
        for (int k = 0; k < c.scans_per_ring; ++k) {
            const double azimuth = 2.0 * M_PI * k / c.scans_per_ring +
                                   static_cast<double>(ring) * c.ring_phase_deg * kDegToRad;
            const Eigen::Vector3d position(c.distance_m * std::cos(azimuth),
                                           c.distance_m * std::sin(azimuth),
                                           c.ring_heights_m[ring]);
            const Eigen::Vector3d x = (aim - position).normalized();
            const Eigen::Vector3d y = Eigen::Vector3d::UnitZ().cross(x).normalized();
            Eigen::Matrix3d R;
            R << x, y, x.cross(y);
            Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
            T.linear() = R;
            T.translation() = position;
            poses.push_back(T);
        }
    }
    return poses;
}

LidarConfig object_scanner_defaults() {
    LidarConfig lidar;
    lidar.num_beams = 200;
    lidar.elevation_max_deg = 10.0;
    lidar.elevation_min_deg = -10.0;
    lidar.azimuth_steps = 360;
    lidar.azimuth_fov_deg = 30.0;
    lidar.min_range_m = 0.1;
    lidar.max_range_m = 3.0;
    return lidar;
}

void validate(const ObjectSimulationConfig& config) {
    validate(config.scene);
    validate(config.turntable);
    validate(config.lidar);
}

SimulationSummary simulate_object_sequence(const ObjectSimulationConfig& config,
                                           const std::filesystem::path& out_dir) {
    validate(config);
    const auto start = std::chrono::steady_clock::now();
    ObjectSceneConfig scene_config = config.scene;
    scene_config.seed = config.seed;
    ObjectScene scene = make_object_scene(scene_config);
    const RayCaster caster(scene.mesh);
    const std::vector<Eigen::Isometry3d> poses = make_turntable_poses(config.turntable);
    const int num_frames = static_cast<int>(poses.size());

    ensure_directory(out_dir / "velodyne");
    sequence_internal::remove_stale_scans(out_dir / "velodyne", num_frames);
    SimulationSummary summary;
    summary.num_frames = num_frames;
    summary.num_triangles = scene.mesh.triangles.size();
    sequence_internal::simulate_and_write_scans(
        caster, config.lidar, poses,
        [&](int frame) {
            return derive_seed(config.seed, kNoise + static_cast<std::uint64_t>(frame));
        },
        Eigen::Vector3d::Zero(), config.show_progress, out_dir, scene.mesh, summary);
    write_ply_mesh(out_dir / "gt_mesh.ply", scene.mesh);

    const auto& l = config.lidar;
    const auto& t = config.turntable;
    const auto& s = scene_config;
    const Eigen::Vector3d size_m = scene.object_m.sizes();
    std::ostringstream heights;
    for (std::size_t i = 0; i < t.ring_heights_m.size(); ++i) {
        heights << (i ? ", " : "") << json_number(t.ring_heights_m[i]);
    }
    std::ostringstream json;
    sequence_internal::write_simulation_json_opening(
        json, "shine simulate --scene object", config.seed, num_frames, Eigen::Vector3d::Zero(), l);
    json << "  \"turntable\": {\"scans_per_ring\": " << t.scans_per_ring
         << ", \"ring_heights_m\": [" << heights.str()
         << "], \"distance_m\": " << json_number(t.distance_m)
         << ", \"aim_height_m\": " << json_number(t.aim_height_m)
         << ", \"ring_phase_deg\": " << json_number(t.ring_phase_deg) << "},\n"
         << "  \"scene\": {\"kind\": \"object\", \"plate_size_m\": " << json_number(s.plate_size_m)
         << ", \"box_m\": [" << json_number(s.box_length_m) << ", " << json_number(s.box_width_m)
         << ", " << json_number(s.box_height_m) << "], \"object_size_m\": ["
         << json_number(size_m.x()) << ", " << json_number(size_m.y()) << ", "
         << json_number(size_m.z()) << "], \"parts\": " << scene.num_parts
         << ", \"max_edge_length_m\": " << json_number(s.max_edge_length_m) << "},\n"
         << "  \"results\": {\"num_triangles\": " << summary.num_triangles
         << ", \"num_observed_triangles\": " << summary.num_observed_triangles
         << ", \"total_points\": " << summary.total_points
         << ", \"min_points_per_scan\": " << summary.min_points_per_scan
         << ", \"max_points_per_scan\": " << summary.max_points_per_scan << "}\n"
         << "}\n";
    write_stream_atomically(out_dir / "simulation.json",
                            [&](std::ostream& out) { out << json.str(); });
    write_stream_atomically(out_dir / "README.txt", [&](std::ostream& out) {
        out << "Simulated object scan written by `shine simulate --scene object` (ShineVDB).\n\n"
            << "Scene: a shoebox-sized object (seed " << config.seed << ", " << size_m.x() << " x "
            << size_m.y() << " x " << size_m.z() << " m, " << scene.num_parts - 1
            << " closed parts) on a " << s.plate_size_m << " m square turntable plate whose top "
            << "is z = 0;\n"
            << summary.num_triangles << " triangles, no edge longer than " << s.max_edge_length_m
            << " m.\n"
            << "Scanner: " << l.num_beams << " beams from " << l.elevation_max_deg << " to "
            << l.elevation_min_deg << " deg, " << l.azimuth_steps << " azimuth steps over "
            << l.azimuth_fov_deg << " deg, range " << l.min_range_m << " - " << l.max_range_m
            << " m, Gaussian range noise sigma " << l.range_noise_sigma_m << " m;\n"
            << num_frames << " scans: " << t.scans_per_ring << " per ring at "
            << t.ring_heights_m.size() << " heights, " << t.distance_m
            << " m from the turntable's axis, aimed at its axis " << t.aim_height_m
            << " m above the plate.\n\n";
        sequence_internal::write_readme_file_list(out, summary.num_observed_triangles);
        out << "Map it at object scale, e.g. `shine map DIR -o OUT --leaf-size-m 0.003`.\n";
    });
    summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return summary;
}

}  // namespace shine::sim
