// KITTI odometry files: velodyne .bin scans, poses.txt, calib.txt.
#include "shine/io/kitti.hpp"

#include <Eigen/LU>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <string>
#include <string_view>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/io/file_contents.hpp"
#include "shine/io/point_intensity.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace kitti_internal {
namespace {

[[noreturn]] void fail(const fs::path& path, const std::string& where, const std::string& what) {
    throw IoError("KITTI file '" + path.string() + "'" + (where.empty() ? "" : ", " + where) +
                  ": " + what);
}

/// Builds [R|t] from 12 row-major numbers, checking finiteness and orthonormality of R.
Eigen::Isometry3d pose_from_row_major(const std::vector<double>& v, const fs::path& path,
                                      const std::string& where) {
    for (double x : v) {
        if (!std::isfinite(x)) fail(path, where, "contains a non-finite value");
    }
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) R(r, c) = v[4 * r + c];
        t[r] = v[4 * r + 3];
    }
    // KITTI rotations are stored with about 1e-6 error; 1e-3 catches transposed or scaled data.
    constexpr double kOrthonormalTolerance = 1e-3;
    const double error = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    if (error > kOrthonormalTolerance || R.determinant() < 0.0) {
        char text[96];
        std::snprintf(text, sizeof(text), "max |R^T R - I| = %.3g, det(R) = %.3g", error,
                      R.determinant());
        fail(path, where,
             std::string("rotation is not orthonormal (") + text +
                 "); expected 12 numbers per line, row-major 3x4 [R|t]");
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = R;
    T.translation() = t;
    return T;
}

/// Calls `f(line, line_number)` for every line of `data` with the '\r' of CRLF removed.
template <typename F>
void for_each_line(std::string_view data, F&& f) {
    std::size_t pos = 0;
    std::size_t line_no = 0;
    while (pos < data.size()) {
        std::size_t eol = data.find('\n', pos);
        if (eol == std::string_view::npos) eol = data.size();
        std::string_view line = data.substr(pos, eol - pos);
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        f(line, ++line_no);
        pos = eol + 1;
    }
}

bool is_blank(std::string_view line) {
    for (char c : line) {
        if (!std::isspace(static_cast<unsigned char>(c))) return false;
    }
    return true;
}

std::string format_row_major(const Eigen::Isometry3d& T) {
    std::string line;
    char text[32];
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) {
            std::snprintf(text, sizeof(text), "%.17g", T.matrix()(r, c));
            if (!line.empty()) line += ' ';
            line += text;
        }
    }
    return line;
}

}  // namespace
}  // namespace kitti_internal

std::vector<Eigen::Vector3f> read_kitti_bin(const fs::path& path, std::vector<float>* intensity) {
    // A sensor may return nothing (e.g. blocked or still spinning up): an empty scan is valid.
    return parse_kitti_bin(read_file_contents(path, "KITTI file", "a .bin file", EmptyFile::kAllow),
                           path, intensity);
}

std::vector<Eigen::Vector3f> parse_kitti_bin(std::string_view data, const fs::path& path,
                                             std::vector<float>* intensity) {
    using namespace kitti_internal;
    constexpr std::size_t kPointBytes = 4 * sizeof(float);
    if (data.size() % kPointBytes != 0) {
        const std::size_t partial = data.size() - data.size() % kPointBytes;
        fail(path, "byte offset " + std::to_string(partial),
             "size " + std::to_string(data.size()) +
                 " bytes is not a multiple of 16 (float32 x y z intensity per point): the last "
                 "record has only " +
                 std::to_string(data.size() - partial) + " bytes; truncated or not a KITTI scan");
    }
    const std::size_t n = data.size() / kPointBytes;
    std::vector<Eigen::Vector3f> points(n);
    if (intensity != nullptr) intensity->resize(n);
    for (std::size_t i = 0; i < n; ++i) {
        float record[4];
        std::memcpy(record, data.data() + i * kPointBytes, sizeof(record));
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
        for (float& f : record) {
            char* b = reinterpret_cast<char*>(&f);
            std::swap(b[0], b[3]);
            std::swap(b[1], b[2]);
        }
#endif
        points[i] = Eigen::Vector3f(record[0], record[1], record[2]);
        if (intensity != nullptr) (*intensity)[i] = record[3];
    }
    if (intensity != nullptr) drop_unmeasured_intensity(*intensity);
    return points;
}

void write_kitti_bin(const fs::path& path, const std::vector<Eigen::Vector3f>& points,
                     const std::vector<float>& intensity) {
    if (!intensity.empty() && intensity.size() != points.size()) {
        throw DataError("cannot write '" + path.string() + "': " + std::to_string(points.size()) +
                        " points but " + std::to_string(intensity.size()) +
                        " intensities (must be one per point, or none)");
    }
    std::string buffer(points.size() * 16, '\0');
    char* out = buffer.data();
    for (std::size_t i = 0; i < points.size(); ++i) {
        const Eigen::Vector3f& p = points[i];
        const float record[4] = {p.x(), p.y(), p.z(), intensity.empty() ? 0.0f : intensity[i]};
        std::memcpy(out, record, sizeof(record));
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
        for (int k = 0; k < 4; ++k) {
            std::swap(out[4 * k], out[4 * k + 3]);
            std::swap(out[4 * k + 1], out[4 * k + 2]);
        }
#endif
        out += sizeof(record);
    }
    write_stream_atomically(path, [&](std::ostream& stream) {
        stream.write(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    });
}

std::vector<Eigen::Isometry3d> read_kitti_poses(const fs::path& path) {
    return parse_kitti_poses(read_file_contents(path, "KITTI file", "a pose file"), path);
}

std::vector<Eigen::Isometry3d> parse_kitti_poses(std::string_view data, const fs::path& path) {
    using namespace kitti_internal;
    std::vector<Eigen::Isometry3d> poses;
    std::vector<double> values;
    std::string bad;
    std::size_t lines = 0;
    for_each_line(data, [&](std::string_view line, std::size_t line_no) {
        lines = line_no;
        if (is_blank(line)) return;
        const std::string where = "line " + std::to_string(line_no);
        if (!parse_number_words(line, &values, &bad)) {
            fail(path, where, "'" + bad + "' is not a number");
        }
        if (values.size() != 12) {
            fail(path, where,
                 "expected 12 numbers (row-major 3x4 [R|t]), found " +
                     std::to_string(values.size()) +
                     (values.size() == 8 ? " (a TUM trajectory? use pose_format tum)" : ""));
        }
        poses.push_back(pose_from_row_major(values, path, where));
    });
    if (poses.empty()) {
        fail(path, "", "contains no poses (" + std::to_string(lines) + " blank lines)");
    }
    return poses;
}

void write_kitti_poses(const fs::path& path, const std::vector<Eigen::Isometry3d>& poses) {
    std::string text;
    text.reserve(poses.size() * 12 * 24);
    for (const auto& T : poses) {
        text += kitti_internal::format_row_major(T);
        text += '\n';
    }
    write_stream_atomically(path, [&](std::ostream& stream) {
        stream.write(text.data(), static_cast<std::streamsize>(text.size()));
    });
}

Eigen::Isometry3d read_kitti_calib_tr(const fs::path& path) {
    return parse_kitti_calib_tr(read_file_contents(path, "KITTI file", "a calib.txt file"), path);
}

Eigen::Isometry3d parse_kitti_calib_tr(std::string_view data, const fs::path& path) {
    using namespace kitti_internal;
    std::vector<double> values;
    std::string bad;
    bool found = false;
    Eigen::Isometry3d Tr = Eigen::Isometry3d::Identity();
    std::size_t lines = 0;
    for_each_line(data, [&](std::string_view line, std::size_t line_no) {
        lines = line_no;
        const std::size_t colon = line.find(':');
        if (colon == std::string_view::npos) return;
        std::string_view key = line.substr(0, colon);
        while (!key.empty() && std::isspace(static_cast<unsigned char>(key.front()))) {
            key.remove_prefix(1);
        }
        while (!key.empty() && std::isspace(static_cast<unsigned char>(key.back()))) {
            key.remove_suffix(1);
        }
        // KITTI odometry calls it "Tr", the raw-data calib_velo_to_cam files "Tr_velo_to_cam".
        if (key != "Tr" && key != "Tr_velo_to_cam") return;
        const std::string where = "line " + std::to_string(line_no);
        if (found) fail(path, where, "second Tr line");
        if (!parse_number_words(line.substr(colon + 1), &values, &bad)) {
            fail(path, where, "'" + bad + "' is not a number");
        }
        if (values.size() != 12) {
            fail(path, where,
                 "Tr needs 12 numbers (row-major 3x4), found " + std::to_string(values.size()));
        }
        Tr = pose_from_row_major(values, path, where);
        found = true;
    });
    if (!found) {
        fail(path, "",
             "has no 'Tr:' line among its " + std::to_string(lines) +
                 " lines (expected 'Tr: r11 r12 r13 t1 ... r33 t3', the LiDAR-to-camera "
                 "transform)");
    }
    return Tr;
}

}  // namespace shine
