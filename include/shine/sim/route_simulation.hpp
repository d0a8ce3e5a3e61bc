// `shine simulate --route-km`: a long drive through a procedural city (city_route.hpp) scanned by
// the simulated LiDAR and written in the KITTI layout, scan by scan.
//
// Memory: the city's mesh and its per-block BVHs are held for the whole run (measured: 2.1 GB peak
// for 4 km, 24.5 M triangles at the default 0.3 m edges); scans are written as they are made and
// never held.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <filesystem>

#include "shine/sim/city_route.hpp"
#include "shine/sim/drive_trajectory.hpp"
#include "shine/sim/lidar_simulator.hpp"
#include "shine/sim/street_movers.hpp"

namespace shine::sim {

/// Everything `shine simulate --route-km` does.
struct RouteSimulationConfig {
    std::uint64_t seed = 1;  ///< city layout, street layouts, drive phases and noise derive from it
    CityRouteConfig city;    ///< route_length_m; city.street sets curb height and max edge
    DriveTrajectoryConfig trajectory = default_route_trajectory();
    LidarConfig lidar;
    /// num_movers > 0: that many movers per 100 m of straight drive (route_movers.hpp)
    StreetMoversConfig movers;
    /// Added to every pose and written as the reference mesh's origin_world_m (see
    /// SimulationConfig::origin_offset_world_m).
    Eigen::Vector3d origin_offset_world_m = Eigen::Vector3d::Zero();
    bool show_progress = true;
};

/// Throws ConfigError naming the field if any value (including nested configs) is out of range.
void validate(const RouteSimulationConfig& config);

/// What simulate_route_sequence produced.
struct RouteSimulationSummary {
    SimulationSummary sequence;   ///< scans, points, triangles, seconds
    double route_length_m = 0.0;  ///< the drive's length (arc length of the path)
    double loop_length_m = 0.0;   ///< the loop; the rest retraces the first street
    int num_rungs = 0;            ///< cross streets of the ladder
    std::size_t num_streets = 0;  ///< street blocks
    std::size_t num_junctions = 0;
    double scene_seconds = 0.0;  ///< building the city
    double index_seconds = 0.0;  ///< building its BVHs
    std::size_t num_movers = 0;
};

/// Builds the city, drives through it and writes out_dir/velodyne/NNNNNN.bin, poses.txt,
/// gt_mesh.ply (the whole city, observed faces marked; movers are not in it), simulation.json
/// (with the movers' paths) and README.txt as simulate_sequence does, removing stale scans beyond
/// the route's. Throws ConfigError for invalid configs (a route too short for the smallest city
/// names its length) and IoError when a file cannot be written.
RouteSimulationSummary simulate_route_sequence(const RouteSimulationConfig& config,
                                               const std::filesystem::path& out_dir);

}  // namespace shine::sim
