// TUM trajectory files: "timestamp tx ty tz qx qy qz qw" per line, '#' comments.
#include "shine/io/tum.hpp"

#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <string_view>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/io/file_contents.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace tum_internal {
namespace {

[[noreturn]] void fail(const fs::path& path, const std::string& where, const std::string& what) {
    throw IoError("TUM trajectory '" + path.string() + "'" + (where.empty() ? "" : ", " + where) +
                  ": " + what);
}

}  // namespace
}  // namespace tum_internal

std::vector<StampedPose> read_tum_poses(const fs::path& path) {
    return parse_tum_poses(read_file_contents(path, "TUM trajectory", "a trajectory file"), path);
}

std::vector<StampedPose> parse_tum_poses(std::string_view data, const fs::path& path) {
    using namespace tum_internal;
    std::vector<StampedPose> poses;
    std::size_t pos = 0;
    std::size_t line_no = 0;
    double v[8];
    while (pos < data.size()) {
        std::size_t eol = data.find('\n', pos);
        if (eol == std::string_view::npos) eol = data.size();
        const std::string_view line = data.substr(pos, eol - pos);
        pos = eol + 1;
        ++line_no;
        const std::string where = "line " + std::to_string(line_no);
        std::size_t i = 0;
        std::size_t count = 0;
        bool comment = false;
        while (i < line.size()) {
            while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
            if (i == line.size()) break;
            if (line[i] == '#') {
                if (count != 0) fail(path, where, "comment after data");
                comment = true;
                break;
            }
            const std::size_t start = i;
            // TUM files written by some tools separate fields with commas.
            while (i < line.size() && !std::isspace(static_cast<unsigned char>(line[i])) &&
                   line[i] != ',') {
                ++i;
            }
            const std::string_view word = line.substr(start, i - start);
            if (i < line.size() && line[i] == ',') ++i;
            if (word.empty()) continue;
            const char* first = word.data();
            const char* last = word.data() + word.size();
            if (*first == '+') ++first;
            // Fields past the 8th are parsed too, so that the message can count them.
            double extra = 0.0;
            const auto r = std::from_chars(first, last, count < 8 ? v[count] : extra);
            if (first == last || r.ec != std::errc() || r.ptr != last) {
                fail(path, where, "'" + printable_excerpt(word) + "' is not a number");
            }
            ++count;
        }
        if (comment || count == 0) continue;
        if (count != 8) {
            fail(path, where,
                 "expected 8 fields (t x y z qx qy qz qw), found " + std::to_string(count) +
                     (count == 12 ? " (a KITTI pose file? use pose_format kitti)" : ""));
        }
        for (double x : v) {
            if (!std::isfinite(x)) fail(path, where, "contains a non-finite value");
        }
        // TUM order is qx qy qz qw; Eigen's constructor takes w first.
        Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
        const double norm = q.norm();
        if (norm < 1e-9) fail(path, where, "quaternion is zero");
        q.coeffs() /= norm;
        StampedPose p;
        p.timestamp_s = v[0];
        p.T_world_sensor.linear() = q.toRotationMatrix();
        p.T_world_sensor.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
        poses.push_back(p);
    }
    if (poses.empty()) {
        fail(path, "",
             "contains no poses (" + std::to_string(line_no) + " comment or blank lines)");
    }
    return poses;
}

void write_tum_poses(const fs::path& path, const std::vector<StampedPose>& poses) {
    std::string text = "# timestamp tx ty tz qx qy qz qw\n";
    char line[512];
    for (const auto& p : poses) {
        const Eigen::Quaterniond q(p.T_world_sensor.rotation());
        const Eigen::Vector3d t = p.T_world_sensor.translation();
        std::snprintf(line, sizeof(line), "%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
                      p.timestamp_s, t.x(), t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
        text += line;
    }
    write_stream_atomically(path, [&](std::ostream& stream) {
        stream.write(text.data(), static_cast<std::streamsize>(text.size()));
    });
}

}  // namespace shine
