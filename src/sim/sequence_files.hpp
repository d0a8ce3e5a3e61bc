// Helpers for writing a simulated sequence in the KITTI layout (private header), shared by the
// street (lidar_simulator.cpp) and the city route (route_simulation.cpp).
#pragma once

#include <cstdio>
#include <filesystem>
#include <regex>
#include <string>
#include <system_error>

#include "shine/core/error.hpp"

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

}  // namespace shine::sim::sequence_internal
