#include "shine/sim/lidar_simulator.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <sstream>
#include <string>
#include <type_traits>

#include "sequence_files.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/ply.hpp"
#include "sim_random.hpp"

namespace shine::sim {
namespace lidar_internal {

using random_internal::derive_seed;
using random_internal::normal_from_bits;
using random_internal::splitmix64;

constexpr double kDegToRad = M_PI / 180.0;

/// Independent random streams of a simulation (the scene uses the seed itself).
enum Stream : std::uint64_t { kTrajectory = 0x100, kNoise = 0x200, kMovers = 0x300 };

using sequence_internal::format_frame;
using sequence_internal::json_number;

/// Closest hit of one ray; only movers use the ray's time.
template <class Caster>
RayHit cast_ray(const Caster& caster, const Eigen::Vector3d& origin_world,
                const Eigen::Vector3d& direction_world, double max_range_m, double time_s) {
    if constexpr (std::is_same_v<Caster, MovingSceneSelection>) {
        return caster.cast(origin_world, direction_world, 0.0, max_range_m, time_s);
    } else {
        (void)time_s;
        return caster.cast(origin_world, direction_world, 0.0, max_range_m);
    }
}

/// Casts the rays of one scan against `caster` (a RayCaster, a BlockSelection or a
/// MovingSceneSelection), in parallel; the range noise of ray i is drawn from a generator seeded
/// by (noise_seed, i). The ray at azimuth step j is cast at time scan_time_s + sweep_s * j /
/// azimuth_steps.
/// With `step_poses` (one per azimuth step) the ray of step j leaves from step_poses[j] and the
/// scan's points get their times (sweep_s * j / azimuth_steps).
template <class Caster>
LidarScan cast_scan(const Caster& caster, const LidarConfig& config,
                    const Eigen::Isometry3d& T_world_sensor, std::uint64_t noise_seed,
                    double scan_time_s = 0.0, double sweep_s = 0.0,
                    const std::vector<Eigen::Isometry3d>* step_poses = nullptr) {
    const std::size_t num_rays =
        static_cast<std::size_t>(config.num_beams) * static_cast<std::size_t>(config.azimuth_steps);
    std::vector<double> ranges(num_rays, -1.0);
    std::vector<std::int32_t> ids(num_rays, -1);
    const Eigen::Vector3d origin_world = T_world_sensor.translation();
    const Eigen::Matrix3d R_world_sensor = T_world_sensor.linear();
    const double sigma = config.range_noise_sigma_m;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, num_rays, 256),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t ray = range.begin(); ray != range.end(); ++ray) {
                              const int beam = static_cast<int>(ray / config.azimuth_steps);
                              const int step = static_cast<int>(ray % config.azimuth_steps);
                              const Eigen::Vector3d direction_world =
                                  (step_poses ? (*step_poses)[step].linear() : R_world_sensor) *
                                  lidar_ray_direction(config, beam, step);
                              const Eigen::Vector3d& ray_origin_world =
                                  step_poses ? (*step_poses)[step].translation() : origin_world;
                              const double time_s =
                                  scan_time_s + sweep_s * step / config.azimuth_steps;
                              const RayHit hit = cast_ray(caster, ray_origin_world, direction_world,
                                                          config.max_range_m, time_s);
                              if (!hit.hit() || hit.distance_m < config.min_range_m) continue;
                              double r = hit.distance_m;
                              if (sigma > 0.0) {
                                  // Per-ray generator: the noise of a ray depends only on (seed,
                                  // ray index).
                                  const std::uint64_t a = splitmix64(noise_seed ^ splitmix64(ray));
                                  r += sigma * normal_from_bits(a, splitmix64(a));
                              }
                              if (!(r > 0.0)) continue;
                              ranges[ray] = r;
                              ids[ray] = hit.triangle_id;
                          }
                      });
    LidarScan scan;
    scan.points_sensor.reserve(num_rays);
    scan.triangle_ids.reserve(num_rays);
    for (std::size_t ray = 0; ray < num_rays; ++ray) {
        if (ranges[ray] < 0.0) continue;
        const int beam = static_cast<int>(ray / config.azimuth_steps);
        const int step = static_cast<int>(ray % config.azimuth_steps);
        scan.points_sensor.push_back(
            (lidar_ray_direction(config, beam, step) * ranges[ray]).cast<float>());
        scan.triangle_ids.push_back(ids[ray]);
        if (step_poses) scan.point_time_s.push_back(sweep_s * step / config.azimuth_steps);
    }
    return scan;
}

void check_motion(const LidarConfig& config, const SweepMotion& motion) {
    if (motion.T_world_sensor.size() != static_cast<std::size_t>(config.azimuth_steps) ||
        !(motion.sweep_s >= 0.0)) {
        throw ConfigError("lidar: a sweep with motion needs one sensor pose per azimuth step (" +
                          std::to_string(config.azimuth_steps) + "), got " +
                          std::to_string(motion.T_world_sensor.size()) +
                          ", and a non-negative sweep time");
    }
}

}  // namespace lidar_internal

using namespace lidar_internal;

void validate(const LidarConfig& c) {
    auto require = [](bool ok, const std::string& key, double value, const std::string& rule) {
        if (!ok) throw ConfigError("lidar: " + key + " = " + std::to_string(value) + " " + rule);
    };
    require(c.num_beams >= 1 && c.num_beams <= 1024, "num_beams", c.num_beams,
            "must be in [1, 1024]");
    require(c.azimuth_steps >= 1 && c.azimuth_steps <= 100000, "azimuth_steps", c.azimuth_steps,
            "must be in [1, 100000]");
    require(c.elevation_max_deg <= 90.0 && c.elevation_max_deg >= -90.0, "elevation_max_deg",
            c.elevation_max_deg, "must be in [-90, 90]");
    require(c.elevation_min_deg >= -90.0 && c.elevation_min_deg <= c.elevation_max_deg,
            "elevation_min_deg", c.elevation_min_deg, "must be in [-90, elevation_max_deg]");
    require(c.azimuth_fov_deg > 0.0 && c.azimuth_fov_deg <= 360.0, "azimuth_fov_deg",
            c.azimuth_fov_deg, "must be in (0, 360]");
    require(c.min_range_m >= 0.0, "min_range_m", c.min_range_m, "must be >= 0");
    require(c.max_range_m > c.min_range_m && std::isfinite(c.max_range_m), "max_range_m",
            c.max_range_m, "must be finite and > min_range_m");
    require(c.range_noise_sigma_m >= 0.0 && c.range_noise_sigma_m <= 10.0, "range_noise_sigma_m",
            c.range_noise_sigma_m, "must be in [0, 10]");
}

Eigen::Vector3d lidar_ray_direction(const LidarConfig& config, int beam, int azimuth_step) {
    const double elevation_deg =
        config.num_beams == 1
            ? config.elevation_max_deg
            : config.elevation_max_deg - (config.elevation_max_deg - config.elevation_min_deg) *
                                             beam / (config.num_beams - 1);
    const double elevation = elevation_deg * kDegToRad;
    // A full turn keeps its own formula (the street's scans stay bit for bit the same).
    const double azimuth =
        config.azimuth_fov_deg >= 360.0
            ? 2.0 * M_PI * azimuth_step / config.azimuth_steps
            : (config.azimuth_steps == 1
                   ? 0.0
                   : config.azimuth_fov_deg * kDegToRad *
                         (static_cast<double>(azimuth_step) / (config.azimuth_steps - 1) - 0.5));
    return Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                           std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
}

LidarScan simulate_scan(const RayCaster& caster, const LidarConfig& config,
                        const Eigen::Isometry3d& T_world_sensor, std::uint64_t noise_seed) {
    validate(config);
    return cast_scan(caster, config, T_world_sensor, noise_seed);
}

LidarScan simulate_scan(const BlockRayCaster& caster, const LidarConfig& config,
                        const Eigen::Isometry3d& T_world_sensor, std::uint64_t noise_seed) {
    validate(config);
    // Only blocks within the sensor's range can return a point.
    const BlockSelection near = caster.select(T_world_sensor.translation(), config.max_range_m);
    return cast_scan(near, config, T_world_sensor, noise_seed);
}

LidarScan simulate_scan(const MovingScene& scene, const LidarConfig& config,
                        const Eigen::Isometry3d& T_world_sensor, std::uint64_t noise_seed,
                        double scan_time_s) {
    validate(config);
    const double sweep_s = scene.tracks().sweep_s;
    const MovingSceneSelection near = scene.select(T_world_sensor.translation(), config.max_range_m,
                                                   scan_time_s, scan_time_s + sweep_s);
    return cast_scan(near, config, T_world_sensor, noise_seed, scan_time_s, sweep_s);
}

LidarScan simulate_scan(const RayCaster& caster, const LidarConfig& config,
                        const SweepMotion& motion, std::uint64_t noise_seed) {
    validate(config);
    check_motion(config, motion);
    return cast_scan(caster, config, motion.T_world_sensor.front(), noise_seed, 0.0, motion.sweep_s,
                     &motion.T_world_sensor);
}

LidarScan simulate_scan(const MovingScene& scene, const LidarConfig& config,
                        const SweepMotion& motion, std::uint64_t noise_seed, double scan_time_s) {
    validate(config);
    check_motion(config, motion);
    // Every ray leaves from within the sweep's path: the selection's radius covers it.
    const Eigen::Vector3d first_m = motion.T_world_sensor.front().translation();
    double travel_m = 0.0;
    for (const Eigen::Isometry3d& T : motion.T_world_sensor) {
        travel_m = std::max(travel_m, (T.translation() - first_m).norm());
    }
    const MovingSceneSelection near = scene.select(first_m, config.max_range_m + travel_m,
                                                   scan_time_s, scan_time_s + motion.sweep_s);
    return cast_scan(near, config, motion.T_world_sensor.front(), noise_seed, scan_time_s,
                     motion.sweep_s, &motion.T_world_sensor);
}

void validate(const SimulationConfig& config) {
    if (config.num_frames < 1 || config.num_frames > 100000) {
        throw ConfigError("simulation: num_frames = " + std::to_string(config.num_frames) +
                          " must be in [1, 100000]");
    }
    if (!(config.scene_margin_m >= 10.0 && config.scene_margin_m <= 1e4)) {
        throw ConfigError("simulation: scene_margin_m = " + std::to_string(config.scene_margin_m) +
                          " must be in [10, 10000]");
    }
    if (!config.origin_offset_world_m.allFinite() ||
        config.origin_offset_world_m.cwiseAbs().maxCoeff() > 1e9) {
        throw ConfigError("simulation: origin_offset_world_m must be finite and within 1e9 m");
    }
    validate(config.trajectory);
    validate(config.lidar);
    validate(config.movers);
    StreetSceneConfig scene = config.scene;
    scene.length_m = 100.0;  // set by simulate_sequence
    validate(scene);
}

StreetSceneConfig simulation_scene_config(const SimulationConfig& config) {
    StreetSceneConfig scene_config = config.scene;
    scene_config.seed = config.seed;
    const double drive_length_m = (config.num_frames - 1) * config.trajectory.frame_spacing_m;
    scene_config.start_x_m = -config.scene_margin_m;
    scene_config.length_m = drive_length_m + 2.0 * config.scene_margin_m;
    return scene_config;
}

std::vector<Eigen::Isometry3d> simulation_poses(const SimulationConfig& config) {
    return make_drive_trajectory(config.trajectory, config.num_frames,
                                 derive_seed(config.seed, kTrajectory));
}

MoverTracks simulation_movers(const SimulationConfig& config) {
    if (config.movers.num_movers <= 0) return {};
    const double drive_length_m = (config.num_frames - 1) * config.trajectory.frame_spacing_m;
    return make_street_movers(config.movers, simulation_scene_config(config), drive_length_m,
                              config.num_frames, derive_seed(config.seed, kMovers));
}

SimulationSummary simulate_sequence(const SimulationConfig& config,
                                    const std::filesystem::path& out_dir) {
    namespace fs = std::filesystem;
    validate(config);
    const auto start = std::chrono::steady_clock::now();

    const StreetSceneConfig scene_config = simulation_scene_config(config);
    StreetScene scene = make_street_scene(scene_config);
    const RayCaster caster(scene.mesh);
    const std::vector<Eigen::Isometry3d> poses = simulation_poses(config);

    const fs::path velodyne_dir = out_dir / "velodyne";
    // Remove scans of an earlier, longer run so that scans and poses.txt stay consistent. With
    // motion distortion the scans are scans/NNNNNN.ply: velodyne/ must hold none (a reader takes
    // velodyne/ first).
    std::function<SweepMotion(int)> sweep_motion;
    if (config.motion_distortion) {
        ensure_directory(out_dir / "scans");
        sequence_internal::remove_stale_scans(out_dir / "scans", config.num_frames, "ply");
        sequence_internal::remove_stale_scans(velodyne_dir, 0);
        const std::uint64_t trajectory_seed = derive_seed(config.seed, kTrajectory);
        sweep_motion = [&config, trajectory_seed](int frame) {
            SweepMotion motion;
            motion.sweep_s = config.movers.sweep_s;
            const int steps = config.lidar.azimuth_steps;
            motion.T_world_sensor.reserve(static_cast<std::size_t>(steps));
            for (int j = 0; j < steps; ++j) {
                const double t_s = motion.sweep_s * j / steps;
                const double frames = frame + t_s / config.movers.frame_period_s;
                motion.T_world_sensor.push_back(
                    drive_pose_at(config.trajectory, trajectory_seed,
                                  frames * config.trajectory.frame_spacing_m));
            }
            return motion;
        };
    } else {
        ensure_directory(velodyne_dir);
        sequence_internal::remove_stale_scans(velodyne_dir, config.num_frames);
    }

    SimulationSummary summary;
    summary.num_frames = config.num_frames;
    summary.num_triangles = scene.mesh.triangles.size();
    const auto noise_seed = [&](int frame) {
        return derive_seed(config.seed, kNoise + static_cast<std::uint64_t>(frame));
    };
    const MoverTracks movers = simulation_movers(config);
    if (config.movers.num_movers > 0) {
        // Movers are placed in the simulation's frame, like the reference mesh's vertices.
        const MovingScene moving(caster, movers);
        sequence_internal::simulate_and_write_scans(
            moving, config.lidar, poses, noise_seed, config.origin_offset_world_m,
            config.show_progress, out_dir, scene.mesh, summary, sweep_motion);
    } else {
        sequence_internal::simulate_and_write_scans(
            caster, config.lidar, poses, noise_seed, config.origin_offset_world_m,
            config.show_progress, out_dir, scene.mesh, summary, sweep_motion);
    }
    write_ply_mesh(out_dir / "gt_mesh.ply", scene.mesh);

    // Parameters, for people (README.txt) and programs (simulation.json).
    const auto& l = config.lidar;
    const auto& t = config.trajectory;
    const auto& s = scene_config;
    std::ostringstream json;
    sequence_internal::write_simulation_json_head(json, "shine simulate", config.seed,
                                                  config.num_frames, config.origin_offset_world_m,
                                                  l, t, config.motion_distortion);
    json << "  \"scene\": {\"start_x_m\": " << json_number(s.start_x_m)
         << ", \"length_m\": " << json_number(s.length_m)
         << ", \"road_width_m\": " << json_number(s.road_width_m)
         << ", \"sidewalk_width_m\": " << json_number(s.sidewalk_width_m)
         << ", \"curb_height_m\": " << json_number(s.curb_height_m)
         << ", \"lot_depth_m\": " << json_number(s.lot_depth_m)
         << ", \"max_edge_length_m\": " << json_number(s.max_edge_length_m) << ",\n"
         << "            \"objects\": {";
    std::string extra =
        movers.movers.empty() ? "" : "  \"movers\": " + mover_tracks_to_json(movers) + ",\n";
    if (config.motion_distortion) {
        extra += "  \"motion_distortion\": {\"frame_period_s\": " +
                 json_number(config.movers.frame_period_s) +
                 ", \"sweep_s\": " + json_number(config.movers.sweep_s) + ", \"speed_m_s\": " +
                 json_number(t.frame_spacing_m / config.movers.frame_period_s) +
                 ", \"point_time\": \"t, seconds after the scan's pose (the sweep's start)\"},\n";
    }
    sequence_internal::write_simulation_json_tail(json, scene, summary, extra);
    write_stream_atomically(out_dir / "simulation.json",
                            [&](std::ostream& out) { out << json.str(); });
    write_stream_atomically(out_dir / "README.txt", [&](std::ostream& out) {
        out << "Simulated LiDAR sequence written by `shine simulate` (ShineVDB).\n\n"
            << "Scene: a procedural street (seed " << config.seed << ") along world +x, z up, "
            << "road surface at z = 0,\nx in [" << s.start_x_m << ", " << s.start_x_m + s.length_m
            << "] m; " << summary.num_triangles << " triangles, no edge longer than "
            << s.max_edge_length_m << " m.\n"
            << "Sensor: " << l.num_beams << " beams from " << l.elevation_max_deg << " to "
            << l.elevation_min_deg << " deg, " << l.azimuth_steps << " azimuth steps, range "
            << l.min_range_m << " - " << l.max_range_m << " m, Gaussian range noise sigma "
            << l.range_noise_sigma_m << " m,\nmounted " << t.sensor_height_m
            << " m above the road on a car driving " << config.num_frames << " frames, "
            << t.frame_spacing_m << " m apart.\n\n";
        if (!movers.movers.empty()) {
            out << "Movers: " << movers.movers.size()
                << " cars, cyclists and pedestrians move along the street (simulation.json, "
                   "\"movers\");\nscan k starts at k * "
                << movers.frame_period_s << " s and its rays are spread over " << movers.sweep_s
                << " s by azimuth.\ngt_mesh.ply holds the static scene only; points on movers "
                   "are in the scans.\n\n";
        }
        if (config.motion_distortion) {
            out << "Motion distortion: the sensor keeps moving during each "
                << config.movers.sweep_s << " s sweep at "
                << t.frame_spacing_m / config.movers.frame_period_s
                << " m/s; scan k's pose is the sweep's start (k * " << config.movers.frame_period_s
                << " s) and each point\ncarries t, the seconds after it at which its ray was "
                   "fired; its coordinates are in the sensor frame at that time.\n\n";
        }
        sequence_internal::write_readme_file_list(out, summary.num_observed_triangles,
                                                  config.motion_distortion);
    });
    summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return summary;
}

}  // namespace shine::sim
