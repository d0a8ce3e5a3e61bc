// The simulated car's path down the street: sensor poses T_world_sensor, one per frame.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace shine::sim {

/// A smooth drive along world +x starting at x = 0: a gentle lane weave (so the heading changes)
/// plus small pitch and roll oscillations of the car body. Lengths in metres, angles in degrees.
struct DriveTrajectoryConfig {
    double frame_spacing_m = 1.0;    ///< distance travelled between frames (along x)
    double sensor_height_m = 1.73;   ///< above the road surface (KITTI's Velodyne height)
    double weave_amplitude_m = 1.0;  ///< lateral offset amplitude
    /// The weave's centre line to the left (+y) of the street's centre: another lane.
    double lane_offset_m = 0.0;
    double weave_wavelength_m = 45.0;  ///< distance of one full weave; heading up to ~8 deg
    double pitch_amplitude_deg = 0.5;  ///< body pitch oscillation
    double roll_amplitude_deg = 0.4;   ///< body roll oscillation
};

/// Throws ConfigError naming the field for a non-positive spacing, height or wavelength, a
/// negative amplitude, or a lane offset that leaves the road (|offset| + amplitude > 4 m).
void validate(const DriveTrajectoryConfig& config);

/// Poses T_world_sensor of `num_frames` frames (x forward, y left, z up in both frames). The
/// phases of the weave and the oscillations come from `seed`.
std::vector<Eigen::Isometry3d> make_drive_trajectory(const DriveTrajectoryConfig& config,
                                                     int num_frames, std::uint64_t seed);

/// The pose of the same drive at distance `x_m` along +x (frame i of make_drive_trajectory with
/// the same config and seed is x_m = i * frame_spacing_m, bit for bit): where the sensor is
/// between frames, for scans taken while driving (motion distortion).
Eigen::Isometry3d drive_pose_at(const DriveTrajectoryConfig& config, std::uint64_t seed,
                                double x_m);

}  // namespace shine::sim
