// Helpers for writing a simulated sequence in the KITTI layout (private header), shared by the
// street (lidar_simulator.cpp) and the city route (route_simulation.cpp).
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <ostream>
#include <regex>
#include <string>
#include <system_error>
#include <type_traits>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/ply.hpp"
#include "shine/sim/drive_trajectory.hpp"
#include "shine/sim/lidar_simulator.hpp"
#include "shine/sim/street_scene.hpp"

namespace shine::sim::sequence_internal {

/// A number for simulation.json with 10 significant digits.
inline std::string json_number(double value) {
    char buffer[64];
    std::snprintf(buffer, sizeof(buffer), "%.10g", value);
    return buffer;
}

/// A double that reads back exactly (offsets of 5e6 m with millimetres need 10+ digits).
inline std::string json_number_exact(double value) {
    char buffer[64];
    std::snprintf(buffer, sizeof(buffer), "%.17g", value);
    return buffer;
}

/// File name of scan `frame` in velodyne/: NNNNNN.bin.
inline std::string format_frame(int frame) {
    char buffer[32];
    std::snprintf(buffer, sizeof(buffer), "%06d.bin", frame);
    return buffer;
}

/// File name of a timed scan in scans/: NNNNNN.ply.
inline std::string format_timed_frame(int frame) {
    char buffer[32];
    std::snprintf(buffer, sizeof(buffer), "%06d.ply", frame);
    return buffer;
}

/// Removes velodyne_dir/NNNNNN.bin files (NNNNNN.`extension`) with NNNNNN >= num_frames (from an
/// earlier, longer run) so that scans and poses.txt stay consistent. Throws IoError naming a file
/// it cannot remove.
inline void remove_stale_scans(const std::filesystem::path& velodyne_dir, int num_frames,
                               const std::string& extension = "bin") {
    namespace fs = std::filesystem;
    if (!fs::is_directory(velodyne_dir)) return;
    const std::regex scan_name(R"(\d{6}\.)" + extension);
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(velodyne_dir)) {
        const std::string name = entry.path().filename().string();
        if (std::regex_match(name, scan_name) && std::stoi(name.substr(0, 6)) >= num_frames) {
            if (!fs::remove(entry.path(), ec) && ec) {
                throw IoError("cannot remove stale scan " + entry.path().string() + ": " +
                              ec.message() + "; delete it or choose another output directory");
            }
        }
    }
}

/// The end of simulation.json that the street and the route share, after the caller's
/// `"objects": {`: the scene's object counts, `extra` (whole lines, e.g. the movers), the
/// results, the closing braces.
inline void write_simulation_json_tail(std::ostream& json, const StreetScene& scene,
                                       const SimulationSummary& summary,
                                       const std::string& extra = "") {
    const SceneObjectKind kinds[] = {SceneObjectKind::kBuilding, SceneObjectKind::kTree,
                                     SceneObjectKind::kCar, SceneObjectKind::kPole,
                                     SceneObjectKind::kPedestrian};
    for (std::size_t i = 0; i < std::size(kinds); ++i) {
        json << (i ? ", " : "") << '"' << to_string(kinds[i])
             << "s\": " << scene.count_objects(kinds[i]);
    }
    json << "}},\n"
         << extra << "  \"results\": {\"num_triangles\": " << summary.num_triangles
         << ", \"num_observed_triangles\": " << summary.num_observed_triangles
         << ", \"total_points\": " << summary.total_points
         << ", \"min_points_per_scan\": " << summary.min_points_per_scan
         << ", \"max_points_per_scan\": " << summary.max_points_per_scan << "}\n"
         << "}\n";
}

/// The opening of simulation.json that every simulated sequence shares, up to and including the
/// lidar object ("  \"lidar\": {...},\n"); the field of view only for a narrow one.
inline void write_simulation_json_opening(std::ostream& json, const char* generator,
                                          std::uint64_t seed, int num_frames,
                                          const Eigen::Vector3d& origin_offset_world_m,
                                          const LidarConfig& l, bool timed_scans = false) {
    json << "{\n"
         << "  \"generator\": \"" << generator << "\",\n"
         << "  \"seed\": " << seed << ",\n"
         << "  \"num_frames\": " << num_frames << ",\n"
         << "  \"origin_offset_world_m\": [" << json_number_exact(origin_offset_world_m.x()) << ", "
         << json_number_exact(origin_offset_world_m.y()) << ", "
         << json_number_exact(origin_offset_world_m.z()) << "],\n"
         << "  \"frames\": {\"points\": \""
         << (timed_scans ? "scans/NNNNNN.ply, float32 x y z t (s after the scan's pose), sensor "
                           "frame at each point's time"
                         : "velodyne/NNNNNN.bin, float32 x y z intensity(0), sensor frame")
         << "\", \"poses\": \"poses.txt, T_world_sensor, KITTI 3x4 row-major\", "
            "\"reference\": \"gt_mesh.ply, world frame, face property observed\"},\n"
         << "  \"lidar\": {\"num_beams\": " << l.num_beams
         << ", \"elevation_max_deg\": " << json_number(l.elevation_max_deg)
         << ", \"elevation_min_deg\": " << json_number(l.elevation_min_deg)
         << ", \"azimuth_steps\": " << l.azimuth_steps;
    if (l.azimuth_fov_deg < 360.0) {
        json << ", \"azimuth_fov_deg\": " << json_number(l.azimuth_fov_deg);
    }
    json << ", \"min_range_m\": " << json_number(l.min_range_m)
         << ", \"max_range_m\": " << json_number(l.max_range_m)
         << ", \"range_noise_sigma_m\": " << json_number(l.range_noise_sigma_m) << "},\n";
}

/// The opening of simulation.json that the street and the route share, up to and including the
/// trajectory object ("  \"trajectory\": {...},\n"); the caller adds its scene and closes it.
inline void write_simulation_json_head(std::ostream& json, const char* generator,
                                       std::uint64_t seed, int num_frames,
                                       const Eigen::Vector3d& origin_offset_world_m,
                                       const LidarConfig& l, const DriveTrajectoryConfig& t,
                                       bool timed_scans = false) {
    write_simulation_json_opening(json, generator, seed, num_frames, origin_offset_world_m, l,
                                  timed_scans);
    json << "  \"trajectory\": {\"frame_spacing_m\": " << json_number(t.frame_spacing_m)
         << ", \"sensor_height_m\": " << json_number(t.sensor_height_m)
         << ", \"weave_amplitude_m\": " << json_number(t.weave_amplitude_m)
         << ", \"weave_wavelength_m\": " << json_number(t.weave_wavelength_m)
         << ", \"pitch_amplitude_deg\": " << json_number(t.pitch_amplitude_deg)
         << ", \"roll_amplitude_deg\": " << json_number(t.roll_amplitude_deg) << "},\n";
}

/// The file list of a simulated sequence's README.txt.
inline void write_readme_file_list(std::ostream& out, std::size_t num_observed_triangles,
                                   bool timed_scans = false) {
    out << (timed_scans ? "scans/NNNNNN.ply     float32 x y z t per point, sensor frame at time t "
                          "(s after the scan's pose)\n"
                        : "velodyne/NNNNNN.bin  float32 x y z intensity (0) per point, sensor "
                          "frame\n")
        << "poses.txt            T_world_sensor per frame, 12 numbers (3x4 row-major)\n"
        << "gt_mesh.ply          reference mesh in the world frame; face property "
           "`observed` = 1\n"
        << "                     for the " << num_observed_triangles
        << " triangles that at least one ray hit\n"
        << "simulation.json      all parameters and counts\n";
}

/// Simulates the scan at every pose with `caster` (RayCaster, BlockRayCaster or MovingScene, scan k
/// at time k * frame_period_s), seeding each
/// scan's noise with noise_seed(frame), and writes it to velodyne_dir/NNNNNN.bin as it is made;
/// then writes out_dir/poses.txt (poses moved by origin_offset_world_m). Marks the triangles the
/// scans hit in mesh.face_observed, sets mesh.origin_world_m and fills summary's point counts.
///
/// With `sweep_motion` (the sensor's poses during scan k's sweep: motion distortion) the rays
/// leave from those poses and the scans, whose points carry times, are written to
/// out_dir/scans/NNNNNN.ply (write_ply_scan) instead.
template <class Caster, class NoiseSeed>
void simulate_and_write_scans(const Caster& caster, const LidarConfig& lidar,
                              const std::vector<Eigen::Isometry3d>& poses, NoiseSeed noise_seed,
                              const Eigen::Vector3d& origin_offset_world_m, bool show_progress,
                              const std::filesystem::path& out_dir, TriangleMesh& mesh,
                              SimulationSummary& summary,
                              const std::function<SweepMotion(int frame)>& sweep_motion = {}) {
    const std::filesystem::path velodyne_dir = out_dir / "velodyne";
    const int num_frames = static_cast<int>(poses.size());
    summary.min_points_per_scan = static_cast<std::size_t>(-1);
    std::vector<std::uint8_t> observed(mesh.triangles.size(), 0);
    Progress progress("simulate", static_cast<std::size_t>(num_frames), show_progress);
    for (int frame = 0; frame < num_frames; ++frame) {
        LidarScan scan;
        if (sweep_motion) {
            const SweepMotion motion = sweep_motion(frame);
            if constexpr (std::is_same_v<Caster, MovingScene>) {
                scan = simulate_scan(caster, lidar, motion, noise_seed(frame),
                                     frame * caster.tracks().frame_period_s);
            } else if constexpr (std::is_same_v<Caster, RayCaster>) {
                scan = simulate_scan(caster, lidar, motion, noise_seed(frame));
            } else {
                throw ConfigError("motion distortion is simulated on the street only");
            }
            write_ply_scan(out_dir / "scans" / format_timed_frame(frame), scan.points_sensor,
                           scan.point_time_s);
        } else {
            if constexpr (std::is_same_v<Caster, MovingScene>) {
                scan = simulate_scan(caster, lidar, poses[frame], noise_seed(frame),
                                     frame * caster.tracks().frame_period_s);
            } else {
                scan = simulate_scan(caster, lidar, poses[frame], noise_seed(frame));
            }
            write_kitti_bin(velodyne_dir / format_frame(frame), scan.points_sensor);
        }
        // Ids past the static mesh are movers (MovingScene::cast): not part of the reference.
        for (const std::int32_t id : scan.triangle_ids) {
            if (static_cast<std::size_t>(id) < observed.size()) observed[id] = 1;
        }
        const std::size_t n = scan.points_sensor.size();
        summary.total_points += n;
        summary.min_points_per_scan = std::min(summary.min_points_per_scan, n);
        summary.max_points_per_scan = std::max(summary.max_points_per_scan, n);
        progress.update(static_cast<std::size_t>(frame + 1), std::to_string(n) + " points");
    }
    progress.finish(std::to_string(summary.total_points) + " points");
    std::vector<Eigen::Isometry3d> poses_world = poses;
    for (Eigen::Isometry3d& T_world_sensor : poses_world) {
        T_world_sensor.translation() += origin_offset_world_m;
    }
    write_kitti_poses(out_dir / "poses.txt", poses_world);
    for (const std::uint8_t o : observed) summary.num_observed_triangles += o;
    mesh.face_observed = std::move(observed);
    mesh.origin_world_m = origin_offset_world_m;
}

}  // namespace shine::sim::sequence_internal
