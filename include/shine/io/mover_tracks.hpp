// Moving objects of a simulated sequence (cars, cyclists, pedestrians): a box-shaped body moving
// rigidly along timed waypoints, as `shine simulate --movers N` writes them into simulation.json
// and as `shine eval --movers` reads them back to find the volume they swept.
//
// The layout, under simulation.json's top-level key "movers":
//   {"frame_period_s": 0.1, "sweep_s": 0.1, "num_frames": 50,
//    "list": [{"kind": "car", "size_m": [4.5, 1.8, 1.5],
//              "waypoints": [{"t_s": 0, "position_m": [x, y, z], "yaw_rad": 0}, ...]}, ...]}
// Scan k starts at time k * frame_period_s; its rays are spread over the sweep [start, start +
// sweep_s) by azimuth. A body's box spans [-l/2, l/2] x [-w/2, w/2] x [0, h] (size_m = l, w, h) in
// its own frame: x forward, z up, the origin at the middle of its footprint. Its pose at time t is
// translation(position_m) * rotation_z(yaw_rad), both interpolated linearly between the waypoints
// around t (times strictly increasing), and held at the first / last waypoint outside them. The
// body is in the scene only from its first waypoint's time to its last's: the simulator casts no
// ray against it outside them (the city's movers appear and leave with the sensor's pass).
// Positions are in the frame of the reference mesh's vertices (gt_mesh.ply).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace shine {

/// What a mover is; only its box and path matter to the simulator and the evaluation.
enum class MoverKind { kCar, kCyclist, kPedestrian };

/// "car", "cyclist" or "pedestrian".
std::string to_string(MoverKind kind);

/// One timed pose of a mover's path.
struct MoverWaypoint {
    double time_s = 0.0;
    Eigen::Vector3d position_m = Eigen::Vector3d::Zero();  ///< footprint centre, ground level
    double yaw_rad = 0.0;                                  ///< heading about +z
};

/// A box-shaped body on a piecewise-linear path.
struct MoverTrack {
    MoverKind kind = MoverKind::kCar;
    Eigen::Vector3d size_m = Eigen::Vector3d(4.5, 1.8, 1.5);  ///< length, width, height
    std::vector<MoverWaypoint> waypoints;                     ///< times strictly increasing

    /// Pose of the body at `time_s` (see the file comment).
    Eigen::Isometry3d T_world_body(double time_s) const;
    /// Whether the body is in the scene at `time_s`: from its first waypoint's time to its last's.
    bool present(double time_s) const;
    /// The body's box in its own frame.
    Eigen::AlignedBox3d box_body() const;
};

/// The movers of one sequence and its clock.
struct MoverTracks {
    double frame_period_s = 0.1;  ///< scan k starts at k * frame_period_s
    double sweep_s = 0.1;         ///< one scan's rays are spread over this time
    int num_frames = 0;
    std::vector<MoverTrack> movers;
};

/// Parses the "movers" object of a simulation.json whose whole text is `json_text`. Throws
/// DataError naming `source` and the offending key: no "movers" key (the sequence was simulated
/// without --movers), a missing or mistyped field, an unknown kind, a non-positive size or
/// period, a non-finite number, an empty path or waypoint times that do not increase.
MoverTracks parse_mover_tracks(std::string_view json_text, const std::filesystem::path& source);

/// parse_mover_tracks on a file (simulation.json); IoError if it cannot be read.
MoverTracks read_mover_tracks(const std::filesystem::path& path);

/// The "movers" object (one line per mover, two-space indent) that parse_mover_tracks reads back
/// exactly (each number with 15 significant digits, or 17 where
/// 15 would not read back).
std::string mover_tracks_to_json(const MoverTracks& tracks);

}  // namespace shine
