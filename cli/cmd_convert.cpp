// `shine convert RECORDING -o DIR`: a recording's PointCloud2 messages -> the KITTI odometry layout
// (velodyne/NNNNNN.bin with the intensity in the 4th column, times.txt, and poses.txt when a pose
// file is given), so that other tools can read the scans too (any sequence `shine map` reads is
// accepted; it also reports the read speed, opening included, in scans per second). The output
// appears only when complete: it is written into DIR.partial and renamed at the end, and removed
// on any error.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "cli_common.hpp"
#include "command_registry.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/per_point_values.hpp"
#include "shine/core/progress.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/point_cloud2.hpp"
#include "shine/io/recording.hpp"
#include "shine/io/scan_sequence.hpp"

namespace shine::cli {
namespace {
namespace fs = std::filesystem;

struct ConvertOptions {
    std::string recording;
    std::string out;
    std::string topic;
    std::string poses_path;
    int first_frame = 0, last_frame = -1, frame_step = 1;
    bool quiet = false;
};

/// One converted scan: finite points only (KITTI readers elsewhere do not expect NaN), each
/// with its intensity when the scan has one (NaN intensities of finite points are kept).
void write_finite_scan(const fs::path& path, std::vector<Eigen::Vector3f> points,
                       std::vector<float> intensity) {
    std::vector<std::uint8_t> non_finite(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) non_finite[i] = !points[i].allFinite();
    drop_flagged(non_finite, points, intensity);
    write_kitti_bin(path, points, intensity);
}

/// Which fields the intensities came from, for the summary line.
struct IntensityTally {
    std::size_t scans = 0;  ///< scans with an intensity
    std::string fields;     ///< the distinct fields, space-separated

    void add(const std::string& field) {
        if (field.empty()) return;
        ++scans;
        const std::string quoted = "'" + field + "'";
        if (fields.find(quoted) == std::string::npos)
            fields += (fields.empty() ? "" : " ") + quoted;
    }
};

std::string scan_name(std::size_t i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06zu.bin", i);
    return name;
}

/// Writes the scans and times into `dir`; returns the number of scans. `read_seconds` gets the
/// time spent opening the input and reading and decoding its scans (not writing them).
std::size_t write_scans(const ConvertOptions& opt, const fs::path& dir, std::string& times,
                        std::vector<Eigen::Isometry3d>& poses, double& read_seconds,
                        IntensityTally& intensity) {
    const fs::path velodyne = dir / "velodyne";
    fs::create_directories(velodyne);
    char line[64];
    auto t0 = std::chrono::steady_clock::now();
    if (!opt.poses_path.empty() || !ScanSequence::is_recording(opt.recording)) {
        // With poses: the scan sequence matches them to the scans by time.
        ScanSequenceOptions seq_options;
        seq_options.first_frame = opt.first_frame;
        seq_options.last_frame = opt.last_frame;
        seq_options.frame_step = opt.frame_step;
        seq_options.poses_path = opt.poses_path;
        seq_options.topic = opt.topic;
        const ScanSequence sequence = ScanSequence::open(opt.recording, seq_options);
        read_seconds += seconds_since(t0);
        Progress progress("convert", sequence.size());
        for (std::size_t i = 0; i < sequence.size(); ++i) {
            t0 = std::chrono::steady_clock::now();
            Scan scan = sequence.load(i);
            read_seconds += seconds_since(t0);
            intensity.add(scan.intensity_field);
            write_finite_scan(velodyne / scan_name(i), std::move(scan.points_sensor),
                              std::move(scan.intensity));
            std::snprintf(line, sizeof(line), "%.9f\n", scan.stamp_s);
            times += line;
            poses.push_back(scan.T_world_sensor);
            progress.update(i + 1);
        }
        progress.finish();
        return sequence.size();
    }
    // Without poses: the messages of the topic, selected as ScanSequence selects them.
    const std::unique_ptr<RecordingReader> reader = open_recording(opt.recording);
    const RecordingTopic topic = select_point_cloud_topic(*reader, opt.topic);
    const std::vector<RecordingMessage> messages = reader->messages(topic.name);
    const int n = static_cast<int>(messages.size());
    if (opt.frame_step < 1 || opt.first_frame < 0 || opt.first_frame >= n || opt.last_frame < -1 ||
        opt.last_frame >= n || (opt.last_frame != -1 && opt.last_frame < opt.first_frame)) {
        throw ConfigError("--first-frame " + std::to_string(opt.first_frame) + ", --last-frame " +
                          std::to_string(opt.last_frame) + ", --frame-step " +
                          std::to_string(opt.frame_step) + " do not select messages of topic " +
                          topic.name + " in '" + opt.recording + "', which has " +
                          std::to_string(n) + " (valid indices 0.." + std::to_string(n - 1) +
                          ", step >= 1)");
    }
    const int last = opt.last_frame == -1 ? n - 1 : opt.last_frame;
    read_seconds += seconds_since(t0);
    Progress progress("convert",
                      static_cast<std::size_t>((last - opt.first_frame) / opt.frame_step + 1));
    std::size_t count = 0;
    for (int m = opt.first_frame; m <= last; m += opt.frame_step) {
        const std::string where = reader->kind() + " '" + opt.recording + "', topic " + topic.name +
                                  ", message " + std::to_string(m);
        t0 = std::chrono::steady_clock::now();
        PointCloud2Scan cloud = decode_point_cloud2(
            reader->read(messages[static_cast<std::size_t>(m)]), topic.encoding, where);
        read_seconds += seconds_since(t0);
        intensity.add(cloud.intensity_field);
        write_finite_scan(velodyne / scan_name(count), std::move(cloud.points_sensor),
                          std::move(cloud.intensity));
        std::snprintf(line, sizeof(line), "%.9f\n", cloud.stamp_s);
        times += line;
        progress.update(++count);
    }
    progress.finish();
    return count;
}

int run_convert(const ConvertOptions& opt) {
    Progress::set_globally_enabled(!opt.quiet);
    const bool recording = ScanSequence::is_recording(opt.recording);
    const fs::path out = opt.out;
    std::error_code ec;
    if (fs::exists(out, ec) && !(fs::is_directory(out, ec) && fs::is_empty(out, ec))) {
        throw ConfigError("output '" + out.string() +
                          "' already exists and is not an empty directory: choose a new -o DIR");
    }
    const fs::path partial = out.string() + ".partial";
    fs::remove_all(partial, ec);
    std::string times;
    std::vector<Eigen::Isometry3d> poses;
    std::size_t count = 0;
    double read_seconds = 0.0;
    IntensityTally intensity;
    try {
        count = write_scans(opt, partial, times, poses, read_seconds, intensity);
        // Scan files carry no stamps: times.txt only for recordings.
        if (recording)
            write_stream_atomically(partial / "times.txt", [&](std::ostream& stream) {
                stream.write(times.data(), static_cast<std::streamsize>(times.size()));
            });
        if (!poses.empty()) write_kitti_poses(partial / "poses.txt", poses);
    } catch (...) {
        fs::remove_all(partial, ec);
        throw;
    }
    fs::remove(out, ec);  // an empty directory, if any
    fs::rename(partial, out);
    std::printf("read %zu scans in %.2f s (%.1f scans/s, opening included)\n", count, read_seconds,
                read_seconds > 0.0 ? static_cast<double>(count) / read_seconds : 0.0);
    std::printf("wrote %zu scans to %s (velodyne/%s%s)\n", count, out.c_str(),
                recording ? ", times.txt" : "",
                poses.empty() ? "; no poses.txt: give --poses FILE to write one" : ", poses.txt");
    if (intensity.scans > 0) {
        std::printf("intensity of %zu of %zu scans (field %s) in the 4th column, as stored\n",
                    intensity.scans, count, intensity.fields.c_str());
    } else {
        std::printf("no intensity in the input: the 4th column is 0\n");
    }
    return 0;
}

const RegisterCommand kRegisterConvert(15, [](CLI::App& app, Action& action) {
    auto opt = std::make_shared<ConvertOptions>();
    CLI::App* cmd = app.add_subcommand(
        "convert",
        "Convert a recording (ROS 1 bag, ROS 2 bag, .mcap, .db3) to the KITTI layout: "
        "OUT/velodyne/NNNNNN.bin, OUT/times.txt (header stamps, s), OUT/poses.txt with --poses");
    cmd->add_option("recording", opt->recording,
                    "The recording (or any sequence directory `shine map` reads)")
        ->required();
    cmd->add_option("-o,--output", opt->out, "Output directory (new or empty)")->required();
    add_scan_selection_options(cmd, opt->first_frame, opt->last_frame, opt->frame_step,
                               opt->poses_path);
    add_topic_option(cmd, opt->topic);
    cmd->add_flag("-q,--quiet", opt->quiet, "No progress output");
    cmd->callback([opt, &action] { action = [opt] { return run_convert(*opt); }; });
});

}  // namespace
}  // namespace shine::cli
