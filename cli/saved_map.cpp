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

}  // namespace shine::cli
