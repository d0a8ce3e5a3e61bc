#include "saved_map.hpp"

#include "shine/core/error.hpp"
#include "shine/io/kitti.hpp"

namespace shine::cli {
namespace fs = std::filesystem;

fs::path saved_map_file(const std::string& given, const std::string& label) {
    std::error_code ec;
    const fs::path path(given);
    if (fs::is_directory(path, ec)) {
        const fs::path file = path / "map.vdb";
        if (!fs::exists(file, ec)) {
            throw IoError(label + " '" + given +
                          "' holds no map.vdb: give a `shine map` output folder or its map.vdb");
        }
        return file;
    }
    if (!fs::exists(path, ec)) {
        throw IoError(label + " '" + given +
                      "' does not exist: give a `shine map` output folder or its map.vdb");
    }
    return path;
}

std::vector<Eigen::Isometry3d> saved_map_trajectory(const fs::path& map_file, std::string& source) {
    for (const char* name : {"poses_refined.txt", "poses.txt"}) {
        const fs::path path = map_file.parent_path() / name;
        std::error_code ec;
        if (fs::exists(path, ec)) {
            source = path.string();
            return read_kitti_poses(path);
        }
    }
    source.clear();
    return {};
}

std::optional<PoseFrameCorrection> saved_map_frame_correction(const fs::path& map_file,
                                                              std::string& note) {
    note.clear();
    const fs::path given_path = map_file.parent_path() / "poses_given.txt";
    const fs::path refined_path = map_file.parent_path() / "poses_refined.txt";
    std::error_code ec;
    if (!fs::exists(given_path, ec) || !fs::exists(refined_path, ec)) return std::nullopt;
    try {
        return PoseFrameCorrection(read_kitti_poses(given_path), read_kitti_poses(refined_path));
    } catch (const Error& e) {
        note = std::string("poses stay in the map's frame: ") + e.what();
        return std::nullopt;
    }
}

}  // namespace shine::cli
