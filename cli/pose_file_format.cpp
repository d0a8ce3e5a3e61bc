#include "pose_file_format.hpp"

#include <sstream>

#include "shine/core/error.hpp"
#include "shine/io/file_contents.hpp"

namespace shine::cli {

const char* to_string(PoseFileFormat format) {
    return format == PoseFileFormat::kKitti ? "kitti" : "tum";
}

PoseFileFormat detect_pose_file_format(const std::string& path, const std::string& what,
                                       const std::string& hint) {
    const std::string text = read_file_contents(path, what, "a KITTI or TUM pose file");
    std::istringstream lines(text);
    std::string line;
    int line_number = 0;
    while (std::getline(lines, line)) {
        ++line_number;
        const std::size_t start = line.find_first_not_of(" \t\r");
        if (start == std::string::npos || line[start] == '#') continue;
        std::istringstream fields(line);
        std::string field;
        int count = 0;
        while (fields >> field) ++count;
        if (count == 12) return PoseFileFormat::kKitti;
        if (count == 8) return PoseFileFormat::kTum;
        throw IoError(what + " '" + path + "' line " + std::to_string(line_number) + " has " +
                      std::to_string(count) +
                      " fields: expected 12 (KITTI: a row-major 3x4 [R|t]) or 8 (TUM: time tx ty "
                      "tz qx qy qz qw)" +
                      hint);
    }
    throw IoError(what + " '" + path + "' has no poses");
}

}  // namespace shine::cli
