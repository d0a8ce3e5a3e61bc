// `shine simulate --scene object`: a small object on a turntable (object_scene.hpp) scanned by a
// dense, narrow-field scanner from about 1 m, written in the same KITTI layout as the street so
// that `shine map`, `shine tsdf` and `shine eval` read it unchanged.
//
// A turntable turns the object in front of a fixed scanner; equivalently (and so written here)
// the scanner circles the object: `scans_per_ring` poses evenly spaced in azimuth on each of the
// rings (a height above the plate each), all at `distance_m` from the object's centre axis, the
// sensor's x axis aimed at a point `aim_height_m` above the plate's centre, z up as far as
// possible. The scanner is LidarConfig with a narrow azimuth field of view (azimuth_fov_deg).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "shine/sim/lidar_simulator.hpp"
#include "shine/sim/object_scene.hpp"

namespace shine::sim {

/// The circle(s) of scanner poses around the object. Lengths in metres.
struct TurntableConfig {
    int scans_per_ring = 12;                           ///< poses per ring, evenly spaced in azimuth
    std::vector<double> ring_heights_m = {0.25, 0.6};  ///< sensor heights above the plate's top
    double distance_m = 1.0;                           ///< horizontal distance from the centre axis
    double aim_height_m = 0.05;                        ///< the sensor's x axis passes through this
    double ring_phase_deg = 15.0;  ///< each ring's azimuths are turned this much from the last's
};

/// Throws ConfigError naming the field for fewer than 1 scan per ring, no ring, a non-positive
/// distance or a ring height of 0 or below (the scanner would look along the plate).
void validate(const TurntableConfig& config);

/// Poses T_world_sensor, ring by ring (x forward at the aim point, y left, z up-ish).
std::vector<Eigen::Isometry3d> make_turntable_poses(const TurntableConfig& config);

/// The dense scanner: 200 beams over +-10 deg of elevation and 360 azimuth steps over 30 deg
/// (both ~0.09 deg, ~1.6 mm at 1 m), ranges 0.1 - 3 m, no noise.
LidarConfig object_scanner_defaults();

/// Everything `shine simulate --scene object` does.
struct ObjectSimulationConfig {
    std::uint64_t seed = 1;  ///< the object's layout and the range noise derive from it
    ObjectSceneConfig scene;
    TurntableConfig turntable;
    LidarConfig lidar = object_scanner_defaults();
    bool show_progress = true;
};

/// Throws ConfigError naming the field if any value (including nested configs) is out of range.
void validate(const ObjectSimulationConfig& config);

/// Builds the object scene, scans it from every turntable pose and writes, as simulate_sequence
/// does: out_dir/velodyne/NNNNNN.bin (sensor frame), poses.txt, gt_mesh.ply (observed faces
/// marked), simulation.json and README.txt; stale scans beyond the new count are removed. Throws
/// ConfigError for invalid configs and IoError when a file cannot be written.
SimulationSummary simulate_object_sequence(const ObjectSimulationConfig& config,
                                           const std::filesystem::path& out_dir);

}  // namespace shine::sim
