// Scan sequence: layout detection, pose loading and calibration, lazy scan loading.
#include "shine/io/scan_sequence.hpp"

#include <algorithm>
#include <cctype>
#include <fstream>
#include <mutex>
#include <string>

#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/pcd.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/point_cloud2.hpp"
#include "shine/io/pose_interpolation.hpp"
#include "shine/io/recording.hpp"
#include "shine/io/tum.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace scan_sequence_internal {
namespace {

constexpr const char* kExpectedLayout =
    "expected either the KITTI odometry layout (velodyne/NNNNNN.bin, poses.txt, optional "
    "calib.txt) or a folder of .ply/.pcd scans (in the directory or its scans/ subfolder) with "
    "poses.txt (KITTI format) or poses_tum.txt / *.tum (TUM format), or a recording (a ROS 1 "
    ".bag, an .mcap or .db3 file, or a ROS 2 bag folder with metadata.yaml)";

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

/// The indices selected by first_frame / last_frame / frame_step out of `n` scans or messages;
/// `what` names the sequence in messages.
std::vector<std::size_t> select_frames(std::size_t count, const ScanSequenceOptions& options,
                                       const std::string& what, const char* unit) {
    const int n = static_cast<int>(count);
    if (options.frame_step < 1) {
        throw ConfigError("frame_step " + std::to_string(options.frame_step) + " must be >= 1");
    }
    if (options.first_frame < 0 || options.first_frame >= n) {
        throw ConfigError("first_frame " + std::to_string(options.first_frame) +
                          " is outside the sequence '" + what + "' of " + std::to_string(n) + " " +
                          unit + " (valid: 0.." + std::to_string(n - 1) + ")");
    }
    if (options.last_frame < -1 || options.last_frame >= n ||
        (options.last_frame != -1 && options.last_frame < options.first_frame)) {
        throw ConfigError("last_frame " + std::to_string(options.last_frame) +
                          " must be -1 (all) or between first_frame " +
                          std::to_string(options.first_frame) + " and " + std::to_string(n - 1) +
                          " for the sequence '" + what + "'");
    }
    const int last = options.last_frame == -1 ? n - 1 : options.last_frame;
    std::vector<std::size_t> selected;
    for (int i = options.first_frame; i <= last; i += options.frame_step) {
        selected.push_back(static_cast<std::size_t>(i));
    }
    return selected;
}

}  // namespace
}  // namespace scan_sequence_internal

struct ScanSequence::RecordingState {
    std::unique_ptr<RecordingReader> reader;
    RecordingTopic topic;
    std::vector<RecordingMessage> messages;    ///< the selected messages, in scan order
    std::vector<std::size_t> message_numbers;  ///< their positions among the topic's messages
    std::mutex mutex;                          ///< readers keep a chunk cache
};

bool ScanSequence::is_recording(const fs::path& path) { return is_recording_path(path); }

ScanSequence ScanSequence::open_recording(const fs::path& path,
                                          const ScanSequenceOptions& options) {
    using namespace scan_sequence_internal;
    auto state = std::make_shared<RecordingState>();
    state->reader = shine::open_recording(path);
    RecordingReader& reader = *state->reader;
    state->topic = select_point_cloud_topic(reader, options.topic);
    const std::vector<RecordingMessage> all = reader.messages(state->topic.name);
    const std::string name = reader.kind() + " '" + path.string() + "', topic " + state->topic.name;
    const std::vector<std::size_t> selected =
        select_frames(all.size(), options, path.string(), "messages");

    const bool no_poses = options.poses == PoseFileUse::kIfPresent && options.poses_path.empty();
    if (options.poses_path.empty() && !no_poses) {
        throw ConfigError(
            "recording '" + path.string() +
            "' carries no poses ShineVDB can use yet: pass a TUM trajectory with --poses FILE "
            "(lines 't x y z qx qy qz qw'; t in seconds, matched to each scan's header stamp "
            "and interpolated between poses)");
    }
    if (!no_poses && options.pose_format != "auto" && options.pose_format != "tum") {
        throw ConfigError("recording '" + path.string() + "': pose_format '" + options.pose_format +
                          "' cannot be matched by time; give a TUM trajectory (pose_format tum "
                          "or auto)");
    }
    if (!no_poses && options.pose_format == "auto" && fs::exists(options.poses_path) &&
        detect_pose_format(options.poses_path) != "tum") {
        throw ConfigError("pose file '" + options.poses_path.string() +
                          "' looks like KITTI poses (12 numbers a line, no timestamps); a "
                          "recording's scans are matched to poses by time: give a TUM "
                          "trajectory (t x y z qx qy qz qw)");
    }
    std::vector<StampedPose> poses;
    if (!no_poses) {
        poses = read_tum_poses(options.poses_path);
        check_pose_times(poses, options.poses_path.string());
    }
    Eigen::Isometry3d calib = Eigen::Isometry3d::Identity();
    const bool calibrated = !options.calib_path.empty();
    if (calibrated) calib = read_kitti_calib_tr(options.calib_path);

    ScanSequence seq;
    seq.dir_ = path;
    seq.has_poses_ = !no_poses;
    // The header stamps decide the poses; reading them is one pass over the selected messages
    // (for SQLite only their first bytes), one message in memory at a time.
    Progress progress("index " + state->topic.name, selected.size());
    constexpr std::size_t kStampPrefixBytes = 16;
    for (std::size_t k = 0; k < selected.size(); ++k) {
        const RecordingMessage& m = all[selected[k]];
        const std::string where = name + ", message " + std::to_string(selected[k]);
        const double stamp_s = decode_header_stamp_s(reader.read_prefix(m, kStampPrefixBytes),
                                                     state->topic.encoding, where);
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        if (!no_poses) {
            T = interpolate_pose(poses, stamp_s, options.poses_path.string());
            if (calibrated) T = calib.inverse() * T * calib;
        }
        seq.poses_.push_back(T);
        seq.stamps_s_.push_back(stamp_s);
        seq.scan_paths_.push_back(path);
        seq.frame_numbers_.push_back(selected[k]);
        state->messages.push_back(m);
        state->message_numbers.push_back(selected[k]);
        progress.update(k + 1);
    }
    progress.finish(std::to_string(selected.size()) + " messages of " + std::to_string(all.size()));
    // The first message decoded in full, so that a cloud without x/y/z, a big-endian cloud or
    // another layout problem stops the run before any output is written.
    decode_point_cloud2(reader.read(state->messages.front()), state->topic.encoding,
                        name + ", message " + std::to_string(state->message_numbers.front()));
    seq.recording_ = std::move(state);
    return seq;
}

ScanSequence ScanSequence::open(const fs::path& dir, const ScanSequenceOptions& options) {
    using namespace scan_sequence_internal;
    std::error_code ec;
    if (is_recording(dir)) return open_recording(dir, options);
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
    if (options.poses == PoseFileUse::kIfPresent && options.poses_path.empty() &&
        find_pose_file(dir).empty()) {
        ScanSequence seq;
        seq.dir_ = dir;
        seq.has_poses_ = false;
        for (std::size_t i : select_frames(all_scans.size(), options, dir.string(), "scans")) {
            seq.scan_paths_.push_back(all_scans[i]);
            seq.poses_.push_back(Eigen::Isometry3d::Identity());
            seq.frame_numbers_.push_back(i);
        }
        return seq;
    }
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
    ScanSequence seq;
    seq.dir_ = dir;
    for (std::size_t i : select_frames(all_scans.size(), options, dir.string(), "scans")) {
        seq.scan_paths_.push_back(all_scans[i]);
        seq.poses_.push_back(all_poses[i]);
        seq.frame_numbers_.push_back(i);
    }
    return seq;
}

Scan ScanSequence::load(std::size_t i) const {
    Scan scan = load_as_stored(i);
    if (sweep_times_ && scan.point_time_s.empty() && !scan.points_sensor.empty()) {
        scan.point_time_s = sweep_point_times_s(scan.points_sensor, *sweep_times_);
        scan.point_time_format = PointTimeFormat{};
        scan.point_time_format.field = "azimuth";
        scan.point_time_format.type = sweep_times_->describe();
    }
    return scan;
}

ScanSequence ScanSequence::with_sweep_times(const SweepTimeModel& model) const {
    ScanSequence result = *this;
    result.sweep_times_ = model;
    return result;
}

Scan ScanSequence::load_as_stored(std::size_t i) const {
    using namespace scan_sequence_internal;
    Scan scan;
    scan.source = scan_paths_.at(i);
    scan.T_world_sensor = poses_.at(i);
    if (recording_) {
        RecordingState& state = *recording_;
        const std::size_t m = recording_index_.empty() ? i : recording_index_.at(i);
        const std::string where = state.reader->kind() + " '" + dir_.string() + "', topic " +
                                  state.topic.name + ", message " +
                                  std::to_string(state.message_numbers.at(m));
        std::string bytes;
        {
            const std::lock_guard<std::mutex> lock(state.mutex);
            bytes = state.reader->read(state.messages.at(m));
        }
        PointCloud2Scan cloud = decode_point_cloud2(bytes, state.topic.encoding, where);
        scan.points_sensor = std::move(cloud.points_sensor);
        scan.point_time_s = std::move(cloud.point_time_s);
        scan.point_time_format = std::move(cloud.time_format);
        scan.intensity = std::move(cloud.intensity);
        scan.intensity_field = std::move(cloud.intensity_field);
        scan.stamp_s = stamps_s_.at(i);
        return scan;
    }
    const std::string ext = lower_extension(scan.source);
    if (ext == ".bin") {
        scan.points_sensor = read_kitti_bin(scan.source, &scan.intensity);
        if (!scan.intensity.empty()) scan.intensity_field = "4th column";
    } else if (ext == ".ply" || ext == ".pcd") {
        TimedPoints points =
            ext == ".ply" ? read_ply_scan(scan.source) : read_pcd_scan(scan.source);
        scan.points_sensor = std::move(points.points_sensor);
        scan.point_time_s = std::move(points.point_time_s);
        scan.point_time_format = std::move(points.time_format);
        scan.intensity = std::move(points.intensity);
        scan.intensity_field = std::move(points.intensity_field);
    } else {
        throw IoError("scan '" + scan.source.string() + "' has an unsupported extension");
    }
    return scan;
}

ScanSequence ScanSequence::with_poses(const std::vector<Eigen::Isometry3d>& poses) const {
    if (poses.size() != poses_.size()) {
        throw DataError("sequence '" + dir_.string() + "' has " + std::to_string(poses_.size()) +
                        " scans, but " + std::to_string(poses.size()) + " poses were given");
    }
    ScanSequence result = *this;
    result.poses_ = poses;
    result.has_poses_ = true;
    return result;
}

ScanSequence ScanSequence::subset(const std::vector<std::size_t>& indices) const {
    ScanSequence part;
    part.dir_ = dir_;
    part.has_poses_ = has_poses_;
    part.sweep_times_ = sweep_times_;
    part.recording_ = recording_;  // shared: the parts read through one reader, under its lock
    for (const std::size_t i : indices) {
        if (i >= scan_paths_.size()) {
            throw ConfigError("scan " + std::to_string(i) + " is outside the sequence '" +
                              dir_.string() + "' of " + std::to_string(scan_paths_.size()) +
                              " scans");
        }
        part.scan_paths_.push_back(scan_paths_[i]);
        part.poses_.push_back(poses_[i]);
        part.frame_numbers_.push_back(frame_number(i));
        if (i < stamps_s_.size()) part.stamps_s_.push_back(stamps_s_[i]);
        if (recording_) {
            part.recording_index_.push_back(recording_index_.empty() ? i : recording_index_[i]);
        }
    }
    return part;
}

}  // namespace shine
