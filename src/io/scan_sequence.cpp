// Scan sequence: layout detection, pose loading and calibration, lazy scan loading.
#include "shine/io/scan_sequence.hpp"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <string>

#include "shine/core/error.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/pcd.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/tum.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace scan_sequence_internal {
namespace {

constexpr const char* kExpectedLayout =
    "expected either the KITTI odometry layout (velodyne/NNNNNN.bin, poses.txt, optional "
    "calib.txt) or a folder of .ply/.pcd scans (in the directory or its scans/ subfolder) with "
    "poses.txt (KITTI format) or poses_tum.txt / *.tum (TUM format)";

std::string lower_extension(const fs::path& p) {
    std::string ext = p.extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return ext;
}

bool all_digits(const std::string& s) {
    return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) {
        return std::isdigit(static_cast<unsigned char>(c)) != 0;
    });
}

/// Orders scan files by name, numerically when both names are plain numbers, so "10.ply" comes
/// after "9.ply" even without zero padding.
bool scan_name_less(const fs::path& a, const fs::path& b) {
    const std::string sa = a.stem().string();
    const std::string sb = b.stem().string();
    if (all_digits(sa) && all_digits(sb)) {
        const auto strip = [](const std::string& s) {
            const std::size_t nz = s.find_first_not_of('0');
            return nz == std::string::npos ? std::string("0") : s.substr(nz);
        };
        const std::string na = strip(sa), nb = strip(sb);
        if (na.size() != nb.size()) return na.size() < nb.size();
        if (na != nb) return na < nb;
    }
    return a.filename().string() < b.filename().string();
}

/// Regular, non-hidden files in `dir` whose extension is one of `extensions`, in scan order.
std::vector<fs::path> list_scans(const fs::path& dir, const std::vector<std::string>& extensions) {
    std::vector<fs::path> files;
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) return files;
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const fs::path& p = it->path();
        if (p.filename().string().rfind('.', 0) == 0) continue;  // hidden or temporary files
        std::error_code type_ec;
        if (!it->is_regular_file(type_ec)) continue;
        const std::string ext = lower_extension(p);
        if (std::find(extensions.begin(), extensions.end(), ext) != extensions.end()) {
            files.push_back(p);
        }
    }
    if (ec) throw IoError("cannot list directory '" + dir.string() + "': " + ec.message());
    std::sort(files.begin(), files.end(), scan_name_less);
    return files;
}

/// The pose file of the directory: poses.txt, then poses_tum.txt, then the first *.tum.
fs::path find_pose_file(const fs::path& dir) {
    for (const char* name : {"poses.txt", "poses_tum.txt"}) {
        if (fs::is_regular_file(dir / name)) return dir / name;
    }
    const auto tum = list_scans(dir, {".tum"});
    if (!tum.empty()) return tum.front();
    return {};
}

/// Guesses the pose format from the name and the first data line: KITTI lines have 12 numbers
/// and no comments, TUM lines 8 numbers and possibly '#' comments.
std::string detect_pose_format(const fs::path& path) {
    if (lower_extension(path) == ".tum" || path.filename() == "poses_tum.txt") return "tum";
    std::ifstream in(path);
    std::string line;
    while (std::getline(in, line)) {
        std::size_t i = line.find_first_not_of(" \t\r");
        if (i == std::string::npos) continue;
        if (line[i] == '#') return "tum";
        std::size_t words = 0;
        bool in_word = false;
        for (char c : line) {
            const bool space = std::isspace(static_cast<unsigned char>(c)) || c == ',';
            if (!space && !in_word) ++words;
            in_word = !space;
        }
        return words == 8 ? "tum" : "kitti";
    }
    return "kitti";  // empty file: the KITTI reader reports it
}

}  // namespace
}  // namespace scan_sequence_internal

ScanSequence ScanSequence::open(const fs::path& dir, const ScanSequenceOptions& options) {
    using namespace scan_sequence_internal;
    std::error_code ec;
    if (!fs::exists(dir, ec)) {
        throw IoError("scan directory '" + dir.string() + "' does not exist; " + kExpectedLayout);
    }
    if (!fs::is_directory(dir, ec)) {
        throw IoError("'" + dir.string() + "' is not a directory; " + kExpectedLayout);
    }

    // Layout detection, most specific first.
    std::vector<fs::path> all_scans = list_scans(dir / "velodyne", {".bin"});
    if (all_scans.empty()) all_scans = list_scans(dir / "scans", {".ply", ".pcd"});
    if (all_scans.empty()) all_scans = list_scans(dir, {".ply", ".pcd"});
    if (all_scans.empty()) {
        throw IoError("no scans found in '" + dir.string() + "'; " + kExpectedLayout);
    }

    // Poses.
    const fs::path pose_path =
        options.poses_path.empty() ? find_pose_file(dir) : options.poses_path;
    if (pose_path.empty()) {
        throw IoError("no pose file in '" + dir.string() +
                      "': put poses.txt (KITTI, 12 numbers a line) or poses_tum.txt (TUM) there, "
                      "or pass the pose file explicitly");
    }
    std::string format = options.pose_format;
    if (format == "auto") {
        if (!fs::exists(pose_path, ec)) {
            throw IoError("pose file '" + pose_path.string() + "' does not exist");
        }
        format = detect_pose_format(pose_path);
    }
    std::vector<Eigen::Isometry3d> all_poses;
    if (format == "kitti") {
        all_poses = read_kitti_poses(pose_path);
    } else if (format == "tum") {
        // Matched to scans by index: the i-th pose belongs to the i-th scan, timestamps unused.
        for (const StampedPose& p : read_tum_poses(pose_path))
            all_poses.push_back(p.T_world_sensor);
    } else {
        throw ConfigError("pose_format '" + options.pose_format +
                          "' is not one of auto, kitti, tum");
    }
    if (all_poses.size() < all_scans.size()) {
        throw DataError("pose file '" + pose_path.string() + "' has " +
                        std::to_string(all_poses.size()) + " poses but '" + dir.string() +
                        "' has " + std::to_string(all_scans.size()) +
                        " scans: every scan needs a pose (extra poses are ignored); check that "
                        "the pose file belongs to this sequence");
    }

    // Calibration: KITTI poses are camera poses; T_world_lidar = Tr^-1 * T_world_camera * Tr.
    fs::path calib_path = options.calib_path;
    if (calib_path.empty() && format == "kitti" && fs::is_regular_file(dir / "calib.txt", ec)) {
        calib_path = dir / "calib.txt";
    }
    if (!calib_path.empty()) {
        const Eigen::Isometry3d Tr = read_kitti_calib_tr(calib_path);
        const Eigen::Isometry3d Tr_inv = Tr.inverse();
        for (auto& P : all_poses) P = Tr_inv * P * Tr;
    }

    // Frame selection.
    const int n = static_cast<int>(all_scans.size());
    if (options.frame_step < 1) {
        throw ConfigError("frame_step " + std::to_string(options.frame_step) + " must be >= 1");
    }
    if (options.first_frame < 0 || options.first_frame >= n) {
        throw ConfigError("first_frame " + std::to_string(options.first_frame) +
                          " is outside the sequence '" + dir.string() + "' of " +
                          std::to_string(n) + " scans (valid: 0.." + std::to_string(n - 1) + ")");
    }
    if (options.last_frame < -1 || options.last_frame >= n ||
        (options.last_frame != -1 && options.last_frame < options.first_frame)) {
        throw ConfigError("last_frame " + std::to_string(options.last_frame) +
                          " must be -1 (all) or between first_frame " +
                          std::to_string(options.first_frame) + " and " + std::to_string(n - 1) +
                          " for the sequence '" + dir.string() + "'");
    }
    const int last = options.last_frame == -1 ? n - 1 : options.last_frame;

    ScanSequence seq;
    seq.dir_ = dir;
    for (int i = options.first_frame; i <= last; i += options.frame_step) {
        seq.scan_paths_.push_back(all_scans[static_cast<std::size_t>(i)]);
        seq.poses_.push_back(all_poses[static_cast<std::size_t>(i)]);
    }
    return seq;
}

Scan ScanSequence::load(std::size_t i) const {
    using namespace scan_sequence_internal;
    Scan scan;
    scan.source = scan_paths_.at(i);
    scan.T_world_sensor = poses_.at(i);
    const std::string ext = lower_extension(scan.source);
    if (ext == ".bin") {
        scan.points_sensor = read_kitti_bin(scan.source);
    } else if (ext == ".ply") {
        scan.points_sensor = read_ply_points(scan.source);
    } else if (ext == ".pcd") {
        scan.points_sensor = read_pcd_points(scan.source);
    } else {
        throw IoError("scan '" + scan.source.string() + "' has an unsupported extension");
    }
    return scan;
}

ScanSequence ScanSequence::subset(const std::vector<std::size_t>& indices) const {
    ScanSequence part;
    part.dir_ = dir_;
    for (const std::size_t i : indices) {
        if (i >= scan_paths_.size()) {
            throw ConfigError("scan " + std::to_string(i) + " is outside the sequence '" +
                              dir_.string() + "' of " + std::to_string(scan_paths_.size()) +
                              " scans");
        }
        part.scan_paths_.push_back(scan_paths_[i]);
        part.poses_.push_back(poses_[i]);
    }
    return part;
}

}  // namespace shine
