// A spinning multi-beam LiDAR (Velodyne HDL-64E-like) ray-cast against a triangle mesh, and the
// whole example-sequence simulation: street scene -> drive -> scans in the KITTI layout.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "shine/geometry/ray_caster.hpp"
#include "shine/sim/block_ray_caster.hpp"
#include "shine/sim/drive_trajectory.hpp"
#include "shine/sim/moving_scene.hpp"
#include "shine/sim/street_movers.hpp"
#include "shine/sim/street_scene.hpp"

namespace shine::sim {

/// Sensor model. Beams are evenly spaced in elevation from elevation_max_deg (beam 0) down to
/// elevation_min_deg; azimuths are evenly spaced over a full turn starting at +x (counter-
/// clockwise seen from above), or, with azimuth_fov_deg < 360 (a scanner with a narrow field of
/// view), from -fov/2 to +fov/2 about +x, both ends included. Sensor frame: x forward, y left,
/// z up.
struct LidarConfig {
    int num_beams = 64;
    double elevation_max_deg = 2.0;
    double elevation_min_deg = -24.8;
    int azimuth_steps = 1800;          ///< 0.2 deg resolution
    double azimuth_fov_deg = 360.0;    ///< 360: a spinning LiDAR; less: a narrow field of view
    double min_range_m = 1.0;          ///< closer returns are dropped
    double max_range_m = 80.0;         ///< farther surfaces give no return
    double range_noise_sigma_m = 0.0;  ///< Gaussian noise added to each range
};

/// Throws ConfigError naming the field if a value is out of range.
void validate(const LidarConfig& config);

/// Unit direction of ray (beam, azimuth_step) in the sensor frame.
Eigen::Vector3d lidar_ray_direction(const LidarConfig& config, int beam, int azimuth_step);

/// One simulated scan. Points are in the sensor frame, in ray order (beam-major: all azimuths of
/// beam 0, then beam 1, ...), misses and out-of-range returns omitted.
struct LidarScan {
    std::vector<Eigen::Vector3f> points_sensor;
    std::vector<std::int32_t> triangle_ids;  ///< the triangle each point's ray hit (with a
                                             ///< MovingScene: >= num_static_triangles() for a
                                             ///< mover, see MovingScene::cast)
    /// With a SweepMotion: each point's time, seconds after the scan's pose (empty otherwise).
    std::vector<double> point_time_s;
};

/// The sensor moving during one sweep (motion distortion): the ray at azimuth step j is fired at
/// sweep_s * j / azimuth_steps seconds after the scan's pose, from T_world_sensor[j], and its
/// point is measured in that sensor frame -- as a spinning LiDAR on a moving car measures.
struct SweepMotion {
    std::vector<Eigen::Isometry3d> T_world_sensor;  ///< one per azimuth step
    double sweep_s = 0.1;
};

/// Casts all rays of one scan from pose T_world_sensor, in parallel. The range noise of ray i is
/// drawn from a generator seeded by (noise_seed, i), so the scan is identical for any thread
/// count and schedule.
LidarScan simulate_scan(const RayCaster& caster, const LidarConfig& config,
                        const Eigen::Isometry3d& T_world_sensor, std::uint64_t noise_seed);

/// Same for a scene in blocks (a city): each ray is cast against the blocks within max_range_m of
/// the sensor only. Gives the scan one RayCaster over the whole mesh would give.
LidarScan simulate_scan(const BlockRayCaster& caster, const LidarConfig& config,
                        const Eigen::Isometry3d& T_world_sensor, std::uint64_t noise_seed);

/// Same against a static scene with movers: the ray at azimuth step j is cast at time
/// scan_time_s + sweep_s * j / azimuth_steps (sweep_s from the scene's tracks), so each point sees
/// the movers where they were when its ray was fired; the sensor pose stays T_world_sensor.
LidarScan simulate_scan(const MovingScene& scene, const LidarConfig& config,
                        const Eigen::Isometry3d& T_world_sensor, std::uint64_t noise_seed,
                        double scan_time_s);

/// Same with the sensor moving during the sweep (SweepMotion; the scan's points carry their
/// times). Throws ConfigError if `motion` has not one pose per azimuth step.
LidarScan simulate_scan(const RayCaster& caster, const LidarConfig& config,
                        const SweepMotion& motion, std::uint64_t noise_seed);

/// Same against a static scene with movers, the sweep starting at scan_time_s.
LidarScan simulate_scan(const MovingScene& scene, const LidarConfig& config,
                        const SweepMotion& motion, std::uint64_t noise_seed, double scan_time_s);

/// Everything `shine simulate` does.
struct SimulationConfig {
    std::uint64_t seed = 1;  ///< scene layout, trajectory phases and noise all derive from it
    int num_frames = 50;
    double scene_margin_m = 70.0;  ///< street continues this far before the first / after the
                                   ///< last pose, so every scan sees buildings ahead and behind
    StreetSceneConfig scene;       ///< seed, start_x_m and length_m are set by simulate_sequence
    DriveTrajectoryConfig trajectory;
    LidarConfig lidar;
    StreetMoversConfig movers;  ///< num_movers > 0: cars, cyclists, pedestrians on the street
    /// World position of the simulation's frame: added to every pose, and written as the
    /// reference mesh's origin_world_m (e.g. (500000, 5000000, 0) for UTM-like coordinates). The
    /// scans (sensor frame) do not change with it.
    Eigen::Vector3d origin_offset_world_m = Eigen::Vector3d::Zero();
    /// The sensor keeps moving during each sweep (`shine simulate --motion-distortion`): scan k's
    /// pose is the drive's at k * frame_spacing_m as always, and the ray fired t seconds later
    /// (t in [0, movers.sweep_s), by azimuth) leaves from the drive's pose t /
    /// movers.frame_period_s frames further on (speed = frame_spacing_m / frame_period_s: 10 m/s at
    /// the defaults). Each point carries t, so the scans are written as scans/NNNNNN.ply (float x y
    /// z t) instead of velodyne/NNNNNN.bin.
    bool motion_distortion = false;
    bool show_progress = true;
};

/// Throws ConfigError naming the field if any value (including nested configs) is out of range.
void validate(const SimulationConfig& config);

/// The street simulate_sequence builds for `config`: config.scene with the seed, start_x_m and
/// length_m that cover the drive and its margins.
StreetSceneConfig simulation_scene_config(const SimulationConfig& config);

/// The drive's sensor poses T_world_sensor, one per scan, in the simulation's frame (the frame of
/// the reference mesh's vertices: without origin_offset_world_m).
std::vector<Eigen::Isometry3d> simulation_poses(const SimulationConfig& config);

/// The movers the scans see (no movers without movers.num_movers > 0), in the simulation's frame.
MoverTracks simulation_movers(const SimulationConfig& config);

/// What simulate_sequence produced.
struct SimulationSummary {
    int num_frames = 0;
    std::size_t total_points = 0;
    std::size_t min_points_per_scan = 0;
    std::size_t max_points_per_scan = 0;
    std::size_t num_triangles = 0;
    std::size_t num_observed_triangles = 0;
    double seconds = 0.0;
};

/// Builds the street, drives the sensor down it and writes, in the KITTI odometry layout:
///   out_dir/velodyne/NNNNNN.bin   float32 x y z intensity(0), sensor frame
///   out_dir/poses.txt             T_world_sensor per frame, 3x4 row-major (with the offset)
///   out_dir/gt_mesh.ply           the whole scene; face property `observed` = 1 for every
///                                 triangle hit by at least one ray of any frame; vertices in the
///                                 simulation's frame, origin_world_m = origin_offset_world_m
///   out_dir/simulation.json, README.txt   the parameters
/// With movers.num_movers > 0, the scans also see the movers (street_movers.hpp), scan k at time
/// k * frame_period_s; gt_mesh.ply stays the static scene (observed = hit by a ray before any
/// mover) and simulation.json gains "movers" (io/mover_tracks.hpp). Without movers the files are
/// byte-identical to a simulation that knows nothing of them. With motion_distortion the scans are
/// out_dir/scans/NNNNNN.ply (float x y z t, t in seconds after the scan's pose) and velodyne/ is
/// emptied of scans; without it every file is the same as before that option existed.
/// Stale velodyne/NNNNNN.bin files beyond num_frames (from an earlier, longer run) are removed so
/// that scans and poses stay consistent. Throws ConfigError for invalid configs and IoError when a
/// file cannot be written.
SimulationSummary simulate_sequence(const SimulationConfig& config,
                                    const std::filesystem::path& out_dir);

}  // namespace shine::sim
