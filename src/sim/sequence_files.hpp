// Helpers for writing a simulated sequence in the KITTI layout (private header), shared by the
// street (lidar_simulator.cpp) and the city route (route_simulation.cpp).
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <regex>
#include <string>
#include <system_error>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/kitti.hpp"
#include "shine/sim/lidar_simulator.hpp"

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

/// Removes velodyne_dir/NNNNNN.bin files with NNNNNN >= num_frames (from an earlier, longer run)
/// so that scans and poses.txt stay consistent. Throws IoError naming a file it cannot remove.
inline void remove_stale_scans(const std::filesystem::path& velodyne_dir, int num_frames) {
    namespace fs = std::filesystem;
    const std::regex scan_name(R"(\d{6}\.bin)");
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

/// Simulates the scan at every pose with `caster` (RayCaster or BlockRayCaster), seeding each
/// scan's noise with noise_seed(frame), and writes it to velodyne_dir/NNNNNN.bin as it is made;
/// then writes out_dir/poses.txt (poses moved by origin_offset_world_m). Marks the triangles the
/// scans hit in mesh.face_observed, sets mesh.origin_world_m and fills summary's point counts.
template <class Caster, class NoiseSeed>
void simulate_and_write_scans(const Caster& caster, const LidarConfig& lidar,
                              const std::vector<Eigen::Isometry3d>& poses, NoiseSeed noise_seed,
                              const Eigen::Vector3d& origin_offset_world_m, bool show_progress,
                              const std::filesystem::path& out_dir, TriangleMesh& mesh,
                              SimulationSummary& summary) {
    const std::filesystem::path velodyne_dir = out_dir / "velodyne";
    const int num_frames = static_cast<int>(poses.size());
    summary.min_points_per_scan = static_cast<std::size_t>(-1);
    std::vector<std::uint8_t> observed(mesh.triangles.size(), 0);
    Progress progress("simulate", static_cast<std::size_t>(num_frames), show_progress);
    for (int frame = 0; frame < num_frames; ++frame) {
        const LidarScan scan = simulate_scan(caster, lidar, poses[frame], noise_seed(frame));
        write_kitti_bin(velodyne_dir / format_frame(frame), scan.points_sensor);
        for (const std::int32_t id : scan.triangle_ids) observed[id] = 1;
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
